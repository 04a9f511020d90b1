//! Benchmark harnesses behind `mentalsim bench ...`.

pub mod learner;
pub mod movingai;
pub mod navigation;
pub mod prm;
pub mod sim;
