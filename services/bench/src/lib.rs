//! Benchmark harnesses behind `mentalsim bench ...`.
