//! Benchmark harnesses behind `mentalsim bench ...`.

pub mod knowledge;
pub mod learner;
pub mod movingai;
pub mod prm;
pub mod sim;
