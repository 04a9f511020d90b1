//! Grid algorithms and the small stable primitives the simulator, the planner and the
//! benchmarks share. No IO, no allocation beyond the outputs.
//!
//! - [`seed`]: SplitMix64, the seed mixer behind every derived seed (environments in a batch,
//!   re-sampled roadmaps, benchmark runs);
//! - [`hash`]: 64-bit FNV-1a, content fingerprints stable across platforms and Rust versions.

pub mod hash;
pub mod seed;
