//! The job engine: a durable job queue and the runner that drains it. It knows no job kind:
//! kinds are names, payloads and results JSON; the fleet's job kinds live in `jobs`.
//!
//! - [`JobDatabase`]: connection and migrations, SQLite (default) or PostgreSQL by URL.
//! - [`Queue`]: enqueue, claim (leases with fencing tokens), heartbeats, progress events,
//!   checkpoints, outcomes with capped exponential backoff, cancellation, retention.
//! - [`Worker`]: claims jobs for the [`JobHandler`]s registered by kind name and runs them with
//!   heartbeats, cooperative cancellation and graceful shutdown; [`run_workers`] waits for a
//!   lazily opened queue ([`LazyQueue`]) first.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod clock;
pub mod database;
pub mod jobs;
pub mod lazy;
pub mod runner;

use std::sync::Arc;
use std::time::Duration;

use tokio_util::sync::CancellationToken;

pub use clock::{Clock, ManualClock, SystemClock};
pub use database::{Backend, DatabaseError, DatabaseStatus, JobDatabase, PoolSize};
pub use jobs::{
    Backoff, Checkpoint, Claimed, FailOutcome, Job, JobEvent, JobState, Lease, NewJob, Queue,
    QueueError, QueueStats, WriteAck,
};
pub use lazy::LazyQueue;
pub use runner::{
    FnHandler, JobContext, JobError, JobHandler, StopReason, Worker, WorkerConfig, WorkerReport,
    handler_fn,
};

/// Waits until the queue opens (retrying every few seconds), then claims and runs jobs of
/// every kind `register` adds until `shutdown` fires (see [`Worker::run`]). Returns what the
/// worker did.
pub async fn run_workers(
    queue: Arc<LazyQueue>,
    register: impl FnOnce(Worker) -> Worker,
    config: WorkerConfig,
    shutdown: CancellationToken,
) -> WorkerReport {
    let mut warned = false;
    let queue = loop {
        match queue.get().await {
            Ok(q) => break q.clone(),
            Err(reason) => {
                if !warned {
                    tracing::warn!(%reason, "job database unavailable; workers wait for it");
                    warned = true;
                }
                tokio::select! {
                    () = shutdown.cancelled() => return WorkerReport::default(),
                    () = tokio::time::sleep(Duration::from_secs(2)) => {}
                }
            }
        }
    };
    register(Worker::new(queue, config)).run(shutdown).await
}
