//! Simulation worker service: durable job queue, job runners, plan endpoint, jobs API.
//!
//! Only this crate knows the job database.
//!
//! - [`JobDatabase`]: connection and migrations, SQLite (default) or PostgreSQL by URL.
//! - [`Queue`]: enqueue, claim (leases with fencing tokens), heartbeats, progress events,
//!   checkpoints, outcomes with capped exponential backoff, cancellation, retention.
//! - [`Worker`]: claims jobs for the [`JobHandler`]s registered by kind and runs them with
//!   heartbeats, cooperative cancellation and graceful shutdown.
//! - [`jobs`]: the job kinds (`train`, `evaluate`, `validate`), their payloads and handlers,
//!   the knowledge source they take worlds from, and the exported policies on disk.
//! - [`api`]: the jobs and policies REST API (with server-sent events) and its OpenAPI document.
//! - [`service`]: runners over a lazily opened queue ([`LazyQueue`]) and the retention purge.
//! - `bench` (feature `bench`, off by default): the queue throughput benchmark behind
//!   `mentalsim bench queue`.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
// (`planning` and `bench` do not yet; `cast_precision_loss` stays off everywhere: counts far
// below 2^52 convert to f64 exactly.)
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod api;
#[cfg(feature = "bench")]
pub mod bench;
pub mod clock;
pub mod database;
pub mod jobs;
pub mod lazy;
pub mod plan_api;
pub mod queue;
pub mod runner;
pub mod service;

pub use clock::{Clock, ManualClock, SystemClock};
pub use database::{Backend, DatabaseError, DatabaseStatus, JobDatabase, PoolSize};
pub use lazy::LazyQueue;
pub use queue::{
    Backoff, Checkpoint, Claimed, FailOutcome, Job, JobEvent, JobState, Lease, NewJob, Queue,
    QueueError, QueueStats, WriteAck,
};
pub use runner::{
    FnHandler, JobContext, JobError, JobHandler, StopReason, Worker, WorkerConfig, WorkerReport,
    handler_fn,
};
