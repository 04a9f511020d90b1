//! Grid algorithms and the small stable primitives the simulator, the planner and the
//! benchmarks share. No IO; the distance transforms use rayon's pool for their row pass.
//!
//! - [`distance`]: exact Euclidean distance and feature transforms (nearest blocked cell);
//! - [`regions`]: 4-connected region labelling;
//! - [`seed`]: SplitMix64, the seed mixer behind every derived seed (environments in a batch,
//!   re-sampled roadmaps, benchmark runs);
//! - [`hash`]: 64-bit FNV-1a, content fingerprints stable across platforms and Rust versions;
//! - [`stop`]: the flag long computations poll to stop early.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
// (`planning` and `bench` do not yet; `cast_precision_loss` stays off everywhere: counts far
// below 2^52 convert to f64 exactly.)
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod distance;
pub mod hash;
pub mod regions;
pub mod seed;
pub mod stop;

pub use stop::{Stop, StopOnDrop};
