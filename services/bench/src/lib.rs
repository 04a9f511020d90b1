//! Benchmark harnesses behind `mentalsim bench ...`.

pub mod movingai;
pub mod prm;
pub mod sim;
