//! Simulation worker service: durable job queue, job runners, plan endpoint, jobs API.
//!
//! Only this crate knows the job database.

pub mod database;
pub mod plan;

pub use database::{DatabaseError, JobDatabase};
