//! The `traffic` crate's integration tests in one binary (one build and link, one copy of
//! what they share); each module's docs say what it covers.

#![allow(clippy::unwrap_used)] // reason: tests panic on failure

mod common;
mod geometry;
mod killed;
mod schedule;
mod waits;
