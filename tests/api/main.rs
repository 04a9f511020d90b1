//! HTTP API tests against the real app started in-process on port 0.

#![allow(
    clippy::unwrap_used,
    reason = "a test that cannot set itself up should fail loudly"
)]

mod bounds;
mod console;
mod fleet;
mod health;
mod helpers;
mod jobs;
mod knowledge;
mod people;
mod plan;
mod remote_store;
mod revisions;
