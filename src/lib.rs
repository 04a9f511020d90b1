//! The `mentalsim` binary's library: configuration, process assembly and the command line.
//! The services themselves live in the crates under `services/`.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
// (`planning` and `bench` do not yet; `cast_precision_loss` stays off everywhere: counts far
// below 2^52 convert to f64 exactly.)
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod assembly;
pub mod cli;
pub mod config;
pub mod console;
mod health;
pub mod startup;
pub mod telemetry;
mod tokens;
pub mod train;
pub mod worker_process;
