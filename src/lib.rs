//! The `mentalsim` binary's library: configuration, process assembly and the command line.
//! The services themselves live in the crates under `services/`.

pub mod cli;
pub mod config;
mod health;
pub mod startup;
pub mod telemetry;
mod tokens;
pub mod train;
pub mod worker_process;
