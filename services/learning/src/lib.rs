//! TD3 training with tch (libtorch), checkpoints and policy export.
//!
//! Only this crate knows tch: everything else sees plain values and exported policies.

use tch::Device;

/// The device training runs on: the first CUDA device when libtorch sees one, else the CPU.
pub fn training_device() -> Device {
    Device::cuda_if_available()
}

/// The libtorch build this crate runs against, for logs and `/readyz`.
pub fn libtorch_summary() -> String {
    let device = training_device();
    format!(
        "libtorch (tch {}), device {:?}, {} CPU threads",
        env!("CARGO_PKG_VERSION"),
        device,
        tch::get_num_threads()
    )
}
