//! The durable job queue: one API over SQLite and PostgreSQL.
//!
//! A job is `queued` until a worker claims it; the claim makes it `running`, counts an attempt,
//! gives the worker a lease (owner + expiry, renewed by heartbeats) and a fencing token
//! (`lease_token`, +1 on every claim and never reused). Every write a worker makes — progress,
//! checkpoint, heartbeat, the outcome — carries its [`Lease`] and is applied only if the job is
//! still `running` under that token; otherwise it fails with [`QueueError::LeaseLost`]. A
//! worker whose lease expired and was reclaimed can therefore never overwrite the new owner's
//! work.
//!
//! Outcomes: `succeeded` (with a result), `failed` (an error after the last attempt, or a fatal
//! error), `cancelled` (cancel requested), or back to `queued`: a retryable failure waits
//! `run_after` (capped exponential backoff), a graceful release (worker shutdown) is claimable
//! at once and gives its attempt back. An expired lease is reclaimed by the next claim and
//! counts as an attempt; on the last attempt it fails the job instead.
//!
//! Every state change, progress report and checkpoint appends to `job_events`, whose ids grow
//! monotonically per job (an SSE stream resumes from `Last-Event-ID` with [`Queue::events`]).
//!
//! SQLite note: every transaction here starts with a write, so it takes the write lock before
//! reading and never fails on a lock upgrade; the busy timeout queues writers.
//!
//! The module's parts: [`types`] (jobs, leases, events, errors), `claim` (enqueue, claim and
//! the reaping of expired leases), `fenced` (the writes a worker makes under its lease:
//! heartbeats, progress, checkpoints and outcomes), `events` (the event log) and `admin`
//! (what operators and the API do: look up, list, cancel, expire a lease, purge, count).
//! [`Queue`] is one type; each part adds its methods.

mod admin;
mod claim;
mod events;
mod fenced;
mod rows;
pub mod types;

use std::sync::Arc;

use serde_json::Value;

use crate::clock::{Clock, SystemClock};
use crate::database::JobDatabase;

pub use types::{
    Backoff, Checkpoint, Claimed, FailOutcome, Job, JobEvent, JobState, Lease, NewJob, QueueError,
    QueueStats, WriteAck,
};

/// The job queue. Cheap to clone; share one per process.
#[derive(Debug, Clone)]
pub struct Queue {
    db: JobDatabase,
    backoff: Backoff,
    clock: Arc<dyn Clock>,
}

/// Appends an event and returns its id: job id, kind, data (JSON text), time.
const INSERT_EVENT: &str =
    "INSERT INTO job_events (job_id, kind, data, created_ms) VALUES ($1, $2, $3, $4) RETURNING id";

/// Runs `$body` with `$pool` bound to the backend's pool (SQLite or PostgreSQL) and `$pg` to
/// whether it is PostgreSQL. The body is compiled once per backend, so the same statements
/// are type-checked against both drivers.
macro_rules! on_pool {
    ($queue:expr, |$pool:ident, $pg:ident| $body:expr) => {
        match &$queue.db.pool {
            $crate::database::Pool::Sqlite($pool) => {
                #[allow(unused_variables)]
                let $pg = false;
                $body
            }
            $crate::database::Pool::Postgres($pool) => {
                #[allow(unused_variables)]
                let $pg = true;
                $body
            }
        }
    };
}
use on_pool;

/// Appends a `job_events` row in transaction `tx` (inside an [`on_pool!`] arm, where `tx` has
/// its backend's type): job id, kind, data as JSON text, time.
macro_rules! insert_event {
    ($queue:expr, $tx:ident, $id:expr, $kind:expr, $data:expr, $now:expr) => {
        sqlx::query($crate::jobs::INSERT_EVENT)
            .bind($id)
            .bind($kind)
            .bind($data)
            .bind($now)
            .execute(&mut *$tx)
            .await
            .map_err(|e| $queue.db_err(e))?
    };
}
use insert_event;

/// JSON as the TEXT the database stores.
fn to_text(value: &Value) -> String {
    // Serialising a `Value` to a string cannot fail.
    value.to_string()
}

impl Queue {
    /// A queue over `db` with the default backoff and the system clock.
    pub fn new(db: JobDatabase) -> Self {
        Self {
            db,
            backoff: Backoff::default(),
            clock: Arc::new(SystemClock),
        }
    }

    /// Sets the retry backoff.
    pub fn with_backoff(mut self, backoff: Backoff) -> Self {
        self.backoff = backoff;
        self
    }

    /// Sets the clock (tests use [`crate::ManualClock`]).
    pub fn with_clock(mut self, clock: Arc<dyn Clock>) -> Self {
        self.clock = clock;
        self
    }

    /// The database.
    pub fn database(&self) -> &JobDatabase {
        &self.db
    }

    /// The retry backoff.
    pub fn backoff(&self) -> Backoff {
        self.backoff
    }

    /// Now, by the queue's clock (Unix ms).
    pub fn now_ms(&self) -> i64 {
        self.clock.now_ms()
    }

    fn db_err(&self, e: sqlx::Error) -> QueueError {
        QueueError::Database(self.db.error(e))
    }
}
