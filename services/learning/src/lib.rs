//! TD3 training with tch (libtorch), checkpoints and policy export.
