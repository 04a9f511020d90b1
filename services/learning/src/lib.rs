//! Navigation policies: TD3 training with tch (libtorch) in the mental simulation, checkpoints,
//! and the exported policy with its pure-Rust runtime.
//!
//! Only this crate knows tch, and only behind the `train` feature (default). Without it the
//! crate is what a robot or a validation worker embeds: [`policy::Policy`] (safetensors weights
//! and JSON metadata, a forward pass in plain Rust), [`observation::Scaling`] and
//! [`evaluation`].
//!
//! - [`config`]: every hyperparameter, with the TD3 reference defaults;
//! - [`observation`]: network input from an observation, command from the network output;
//! - [`replay`]: the experience buffer;
//! - [`td3`]: the learner (Algorithm 1), with Adam state a checkpoint can hold;
//! - [`trainer`]: the loop, evaluation, checkpoints, export;
//! - [`curves`]: training curves as CSV and PNG (Figure 10);
//! - [`policy`]: the exported policy and its runtime;
//! - [`evaluation`]: success and collision rates on a fixed mission set;
//! - [`summary`]: what a run reports ([`TrainSummary`], `eval.json`) and the held-out
//!   evaluation on both kinds of goals;
//! - [`run`] (feature `train`): a whole training run into a directory — train, curves,
//!   export, held-out evaluation, `eval.json` — as `mentalsim train` and `bench beta` make it.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
// (`planning` and `bench` do not yet; `cast_precision_loss` stays off everywhere: counts far
// below 2^52 convert to f64 exactly.)
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod config;
#[cfg(feature = "train")]
pub mod curves;
pub mod evaluation;
pub mod observation;
pub mod policy;
pub mod replay;
#[cfg(feature = "train")]
pub mod run;
pub mod summary;
#[cfg(feature = "train")]
pub mod td3;
#[cfg(feature = "train")]
pub mod trainer;

pub use config::{ConfigFileError, Td3Config, TrainConfig};
pub use evaluation::{
    BatchActor, DetourBucket, EvalReport, HELD_OUT_MAX_STEPS, Mission, evaluate, evaluate_held_out,
    evaluate_shielded, mission_set,
};
pub use observation::{InputLayout, Scaling};
pub use policy::{Policy, PolicyError, PolicyMetadata};
pub use summary::{Goals, GoalsSummary, HeldOut, TrainSummary, held_out};

/// libtorch's device type, for callers that pick one (the learner benchmark runs on the CPU):
/// only this crate names tch.
#[cfg(feature = "train")]
pub use tch::Device;

/// Sets the threads libtorch's operators use in this process.
#[cfg(feature = "train")]
pub fn set_torch_threads(threads: i32) {
    tch::set_num_threads(threads);
}

/// The device training runs on: the first CUDA device when libtorch sees one, else the CPU.
#[cfg(feature = "train")]
pub fn training_device() -> Device {
    Device::cuda_if_available()
}

/// The libtorch build this crate runs against, for logs and `/readyz`.
#[cfg(feature = "train")]
pub fn libtorch_summary() -> String {
    let device = training_device();
    format!(
        "libtorch (tch {}), device {:?}, {} CPU threads",
        env!("CARGO_PKG_VERSION"),
        device,
        tch::get_num_threads()
    )
}
