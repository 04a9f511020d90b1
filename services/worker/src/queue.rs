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

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;
use std::sync::Arc;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use uuid::Uuid;

use crate::clock::{Clock, SystemClock, duration_ms};
use crate::database::{DatabaseError, JobDatabase, Pool};

/// Where a job is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JobState {
    /// Waiting to be claimed (possibly not before `run_after`).
    Queued,
    /// Claimed by a worker holding a lease.
    Running,
    /// Finished with a result.
    Succeeded,
    /// Finished with an error.
    Failed,
    /// Stopped on request.
    Cancelled,
}

impl JobState {
    /// The name stored in the database and shown in the API.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Queued => "queued",
            Self::Running => "running",
            Self::Succeeded => "succeeded",
            Self::Failed => "failed",
            Self::Cancelled => "cancelled",
        }
    }

    /// Whether the job will not change any more.
    pub fn is_finished(self) -> bool {
        matches!(self, Self::Succeeded | Self::Failed | Self::Cancelled)
    }
}

impl fmt::Display for JobState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for JobState {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Ok(match s {
            "queued" => Self::Queued,
            "running" => Self::Running,
            "succeeded" => Self::Succeeded,
            "failed" => Self::Failed,
            "cancelled" => Self::Cancelled,
            other => return Err(format!("unknown job state {other:?}")),
        })
    }
}

/// A job to enqueue.
#[derive(Debug, Clone, PartialEq)]
pub struct NewJob {
    /// Which handler runs it (`train`, `evaluate`, `validate`, ...).
    pub kind: String,
    /// Its parameters.
    pub payload: Value,
    /// Attempts before it fails for good (at least 1).
    pub max_attempts: u32,
    /// Higher runs first.
    pub priority: i32,
    /// Not claimable before now + this.
    pub delay: Duration,
}

impl NewJob {
    /// A job of `kind` with `payload`, 3 attempts, priority 0, no delay.
    pub fn new(kind: impl Into<String>, payload: Value) -> Self {
        Self {
            kind: kind.into(),
            payload,
            max_attempts: 3,
            priority: 0,
            delay: Duration::ZERO,
        }
    }

    /// Sets the number of attempts.
    pub fn max_attempts(mut self, n: u32) -> Self {
        self.max_attempts = n;
        self
    }

    /// Sets the priority (higher first).
    pub fn priority(mut self, p: i32) -> Self {
        self.priority = p;
        self
    }

    /// Makes the job claimable only after `d`.
    pub fn delay(mut self, d: Duration) -> Self {
        self.delay = d;
        self
    }
}

/// What a job saved to resume from: a reference (a path, a step number, ...) and optionally
/// the bytes themselves.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Checkpoint {
    /// The reference, as JSON.
    pub data: Value,
    /// Bytes stored with it in the database (small states; large ones go to files).
    pub blob: Option<Vec<u8>>,
}

impl Checkpoint {
    /// A checkpoint that is only a JSON reference.
    pub fn new(data: Value) -> Self {
        Self { data, blob: None }
    }
}

/// A job as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct Job {
    /// UUIDv7, time-ordered.
    pub id: Uuid,
    /// Which handler runs it.
    pub kind: String,
    /// Where it is in its life.
    pub state: JobState,
    /// Its parameters.
    pub payload: Value,
    /// Higher runs first.
    pub priority: i64,
    /// Attempts counted so far (the running one included).
    pub attempt: u32,
    /// Attempts allowed.
    pub max_attempts: u32,
    /// The fencing token of the latest claim.
    pub lease_token: i64,
    /// Not claimable before (Unix ms).
    pub run_after_ms: i64,
    /// The worker holding the lease.
    pub lease_owner: Option<String>,
    /// When the lease runs out unless renewed (Unix ms).
    pub lease_expires_ms: Option<i64>,
    /// The last heartbeat (Unix ms).
    pub heartbeat_ms: Option<i64>,
    /// Someone asked to cancel it.
    pub cancel_requested: bool,
    /// The latest progress report.
    pub progress: Option<Value>,
    /// The latest checkpoint.
    pub checkpoint: Option<Checkpoint>,
    /// When the checkpoint was saved (Unix ms).
    pub checkpoint_ms: Option<i64>,
    /// The result, once succeeded.
    pub result: Option<Value>,
    /// The latest error.
    pub last_error: Option<String>,
    /// Enqueued (Unix ms).
    pub created_ms: i64,
    /// Last changed (Unix ms).
    pub updated_ms: i64,
    /// First claimed (Unix ms).
    pub started_ms: Option<i64>,
    /// Reached a finished state (Unix ms).
    pub finished_ms: Option<i64>,
}

/// The right to write to one attempt of a job: returned by [`Queue::claim`], required by every
/// write a worker makes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Lease {
    /// The job.
    pub job_id: Uuid,
    /// The fencing token: the job's `lease_token` at the claim.
    pub token: i64,
    /// The attempt this lease runs (1-based).
    pub attempt: u32,
    /// The worker that holds it.
    pub owner: String,
}

/// A claimed job and the lease to write to it.
#[derive(Debug, Clone, PartialEq)]
pub struct Claimed {
    /// The job, as it was at the claim.
    pub job: Job,
    /// The lease.
    pub lease: Lease,
}

/// One entry of a job's event log.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JobEvent {
    /// Monotonic id (per job; global order on SQLite).
    pub id: i64,
    /// The job.
    pub job_id: Uuid,
    /// `state`, `progress`, `checkpoint` or `cancel_requested`.
    pub kind: String,
    /// What happened.
    pub data: Value,
    /// When (Unix ms).
    pub created_ms: i64,
}

/// What [`Queue::fail`] did with the job.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FailOutcome {
    /// Queued again, claimable from `run_after_ms`.
    Retrying {
        /// Unix ms.
        run_after_ms: i64,
    },
    /// Failed for good.
    Failed,
    /// Cancelled, because a cancel was requested meanwhile.
    Cancelled,
}

/// What a worker learns when a write is accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WriteAck {
    /// A cancel was requested: the handler should stop.
    pub cancel_requested: bool,
}

/// Capped exponential backoff between attempts: `min(cap, base · 2^(attempt−1))`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Backoff {
    /// The delay after the first failed attempt.
    pub base: Duration,
    /// The longest delay.
    pub cap: Duration,
}

impl Default for Backoff {
    fn default() -> Self {
        Self {
            base: Duration::from_secs(5),
            cap: Duration::from_secs(600),
        }
    }
}

impl Backoff {
    /// The delay after failed attempt number `attempt` (1-based).
    pub fn delay(&self, attempt: u32) -> Duration {
        let factor = 1u32
            .checked_shl(attempt.saturating_sub(1))
            .unwrap_or(u32::MAX);
        self.base.saturating_mul(factor).min(self.cap)
    }
}

/// Why a queue operation failed.
#[derive(Debug, thiserror::Error)]
pub enum QueueError {
    /// The write carried a lease that is no longer current: the lease expired and another
    /// worker claimed the job, or the job finished. Nothing was written.
    #[error(
        "job {job_id}: lease token {token} is no longer current (the job was reclaimed or finished); write rejected"
    )]
    LeaseLost {
        /// The job.
        job_id: Uuid,
        /// The stale token.
        token: i64,
    },
    /// No job has this id.
    #[error("job {0} not found")]
    NotFound(Uuid),
    /// The job to enqueue is invalid.
    #[error("invalid job: {0}")]
    Invalid(String),
    /// A stored row could not be read back.
    #[error("job {id}: corrupt row: {message}")]
    Corrupt {
        /// The job id as stored.
        id: String,
        /// What is wrong.
        message: String,
    },
    /// The database failed.
    #[error(transparent)]
    Database(#[from] DatabaseError),
}

/// Counts of jobs by state.
pub type QueueStats = BTreeMap<JobState, u64>;

/// The job queue. Cheap to clone; share one per process.
#[derive(Debug, Clone)]
pub struct Queue {
    db: JobDatabase,
    backoff: Backoff,
    clock: Arc<dyn Clock>,
}

const COLUMNS: &str = "id, kind, state, payload, priority, attempt, max_attempts, lease_token, \
    run_after_ms, lease_owner, lease_expires_ms, heartbeat_ms, cancel_requested, progress, \
    checkpoint, checkpoint_blob, checkpoint_ms, result, last_error, created_ms, updated_ms, \
    started_ms, finished_ms";

const INSERT_EVENT: &str =
    "INSERT INTO job_events (job_id, kind, data, created_ms) VALUES ($1, $2, $3, $4) RETURNING id";

const FENCE: &str = "id = $1 AND lease_token = $2 AND state = 'running'";

#[derive(sqlx::FromRow)]
struct JobRow {
    id: String,
    kind: String,
    state: String,
    payload: String,
    priority: i64,
    attempt: i64,
    max_attempts: i64,
    lease_token: i64,
    run_after_ms: i64,
    lease_owner: Option<String>,
    lease_expires_ms: Option<i64>,
    heartbeat_ms: Option<i64>,
    cancel_requested: bool,
    progress: Option<String>,
    checkpoint: Option<String>,
    checkpoint_blob: Option<Vec<u8>>,
    checkpoint_ms: Option<i64>,
    result: Option<String>,
    last_error: Option<String>,
    created_ms: i64,
    updated_ms: i64,
    started_ms: Option<i64>,
    finished_ms: Option<i64>,
}

#[derive(sqlx::FromRow)]
struct EventRow {
    id: i64,
    job_id: String,
    kind: String,
    data: String,
    created_ms: i64,
}

impl JobRow {
    fn into_job(self) -> Result<Job, QueueError> {
        let corrupt = |message: String| QueueError::Corrupt {
            id: self.id.clone(),
            message,
        };
        let json = |field: &str, text: &str| {
            serde_json::from_str::<Value>(text).map_err(|e| corrupt(format!("{field}: {e}")))
        };
        let opt_json = |field: &str, text: &Option<String>| {
            text.as_deref().map(|t| json(field, t)).transpose()
        };
        let count = |field: &str, n: i64| {
            u32::try_from(n).map_err(|_| corrupt(format!("{field} out of range: {n}")))
        };
        let checkpoint = match opt_json("checkpoint", &self.checkpoint)? {
            Some(data) => Some(Checkpoint {
                data,
                blob: self.checkpoint_blob.clone(),
            }),
            None => None,
        };
        Ok(Job {
            id: Uuid::parse_str(&self.id).map_err(|e| corrupt(format!("id: {e}")))?,
            state: self.state.parse().map_err(corrupt)?,
            payload: json("payload", &self.payload)?,
            attempt: count("attempt", self.attempt)?,
            max_attempts: count("max_attempts", self.max_attempts)?,
            progress: opt_json("progress", &self.progress)?,
            checkpoint,
            result: opt_json("result", &self.result)?,
            kind: self.kind,
            priority: self.priority,
            lease_token: self.lease_token,
            run_after_ms: self.run_after_ms,
            lease_owner: self.lease_owner,
            lease_expires_ms: self.lease_expires_ms,
            heartbeat_ms: self.heartbeat_ms,
            cancel_requested: self.cancel_requested,
            checkpoint_ms: self.checkpoint_ms,
            last_error: self.last_error,
            created_ms: self.created_ms,
            updated_ms: self.updated_ms,
            started_ms: self.started_ms,
            finished_ms: self.finished_ms,
        })
    }
}

impl EventRow {
    fn into_event(self) -> Result<JobEvent, QueueError> {
        let corrupt = |message: String| QueueError::Corrupt {
            id: self.job_id.clone(),
            message,
        };
        Ok(JobEvent {
            id: self.id,
            job_id: Uuid::parse_str(&self.job_id).map_err(|e| corrupt(format!("id: {e}")))?,
            data: serde_json::from_str(&self.data)
                .map_err(|e| corrupt(format!("event {}: {e}", self.id)))?,
            kind: self.kind,
            created_ms: self.created_ms,
        })
    }
}

/// Runs `$body` with `$pool` bound to the backend's pool (SQLite or PostgreSQL) and `$pg` to
/// whether it is PostgreSQL. The body is compiled once per backend, so the same statements
/// are type-checked against both drivers.
macro_rules! on_pool {
    ($queue:expr, |$pool:ident, $pg:ident| $body:expr) => {
        match &$queue.db.pool {
            Pool::Sqlite($pool) => {
                #[allow(unused_variables)]
                let $pg = false;
                $body
            }
            Pool::Postgres($pool) => {
                #[allow(unused_variables)]
                let $pg = true;
                $body
            }
        }
    };
}

/// Appends a `job_events` row in transaction `tx` (inside an [`on_pool!`] arm, where `tx` has
/// its backend's type): job id, kind, data as JSON text, time.
macro_rules! insert_event {
    ($queue:expr, $tx:ident, $id:expr, $kind:expr, $data:expr, $now:expr) => {
        sqlx::query(INSERT_EVENT)
            .bind($id)
            .bind($kind)
            .bind($data)
            .bind($now)
            .execute(&mut *$tx)
            .await
            .map_err(|e| $queue.db_err(e))?
    };
}

fn to_text(value: &Value) -> String {
    // Serialising a `Value` to a string cannot fail.
    value.to_string()
}

fn i64_of(n: u32) -> i64 {
    i64::from(n)
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

    /// Adds a job; it is durable when this returns.
    pub async fn enqueue(&self, job: NewJob) -> Result<Uuid, QueueError> {
        if job.kind.is_empty() {
            return Err(QueueError::Invalid("kind is empty".to_owned()));
        }
        if job.max_attempts == 0 {
            return Err(QueueError::Invalid(
                "max_attempts must be at least 1".to_owned(),
            ));
        }
        let id = Uuid::now_v7();
        let now = self.now_ms();
        let run_after = now.saturating_add(duration_ms(job.delay));
        let payload = to_text(&job.payload);
        let event = to_text(&json!({"state": "queued", "attempt": 0}));
        on_pool!(self, |pool, pg| {
            let mut tx = pool.begin().await.map_err(|e| self.db_err(e))?;
            sqlx::query(
                "INSERT INTO jobs (id, kind, state, payload, priority, max_attempts, run_after_ms, created_ms, updated_ms)
                 VALUES ($1, $2, 'queued', $3, $4, $5, $6, $7, $7)",
            )
            .bind(id.to_string())
            .bind(&job.kind)
            .bind(&payload)
            .bind(i64::from(job.priority))
            .bind(i64_of(job.max_attempts))
            .bind(run_after)
            .bind(now)
            .execute(&mut *tx)
            .await
            .map_err(|e| self.db_err(e))?;
            insert_event!(self, tx, id.to_string(), "state", &event, now);
            tx.commit().await.map_err(|e| self.db_err(e))?;
        });
        Ok(id)
    }

    /// Claims the next job of one of `kinds` for `owner`, leasing it for `lease`.
    ///
    /// Before claiming it finishes jobs whose lease expired on their last attempt (failed) or
    /// with a cancel requested (cancelled). Then it reclaims an expired lease if there is one
    /// (a worker died: counted as an attempt), else claims the queued job with the highest
    /// priority, then the earliest `run_after`, then the oldest id.
    pub async fn claim(
        &self,
        owner: &str,
        kinds: &[&str],
        lease: Duration,
    ) -> Result<Option<Claimed>, QueueError> {
        if kinds.is_empty() {
            return Ok(None);
        }
        self.reap().await?;
        let now = self.now_ms();
        let expires = now.saturating_add(duration_ms(lease));
        let kinds_json = to_text(&json!(kinds));
        let set = "state = 'running', attempt = attempt + 1, lease_token = lease_token + 1, \
                   lease_owner = $1, lease_expires_ms = $2, heartbeat_ms = $3, \
                   started_ms = COALESCE(started_ms, $3), updated_ms = $3";
        let expired_pg = format!(
            "UPDATE jobs SET {set} WHERE id = (SELECT id FROM jobs WHERE state = 'running' \
             AND lease_expires_ms < $3 AND attempt < max_attempts AND NOT cancel_requested \
             AND kind IN (SELECT jsonb_array_elements_text($4::jsonb)) ORDER BY lease_expires_ms, id LIMIT 1 FOR UPDATE SKIP LOCKED) \
             RETURNING {COLUMNS}"
        );
        let queued_pg = format!(
            "UPDATE jobs SET {set} WHERE id = (SELECT id FROM jobs WHERE state = 'queued' \
             AND run_after_ms <= $3 AND kind IN (SELECT jsonb_array_elements_text($4::jsonb)) \
             ORDER BY priority DESC, run_after_ms, id LIMIT 1 FOR UPDATE SKIP LOCKED) \
             RETURNING {COLUMNS}"
        );
        let expired_sqlite = format!(
            "UPDATE jobs SET {set} WHERE id = (SELECT id FROM jobs WHERE state = 'running' \
             AND lease_expires_ms < $3 AND attempt < max_attempts AND NOT cancel_requested \
             AND kind IN (SELECT value FROM json_each($4)) ORDER BY lease_expires_ms, id LIMIT 1) \
             RETURNING {COLUMNS}"
        );
        let queued_sqlite = format!(
            "UPDATE jobs SET {set} WHERE id = (SELECT id FROM jobs WHERE state = 'queued' \
             AND run_after_ms <= $3 AND kind IN (SELECT value FROM json_each($4)) \
             ORDER BY priority DESC, run_after_ms, id LIMIT 1) \
             RETURNING {COLUMNS}"
        );
        let row: Option<JobRow> = on_pool!(self, |pool, pg| {
            let mut tx = pool.begin().await.map_err(|e| self.db_err(e))?;
            let mut found = None;
            for sql in if pg {
                [&expired_pg, &queued_pg]
            } else {
                [&expired_sqlite, &queued_sqlite]
            } {
                found = sqlx::query_as::<_, JobRow>(sql)
                    .bind(owner)
                    .bind(expires)
                    .bind(now)
                    .bind(&kinds_json)
                    .fetch_optional(&mut *tx)
                    .await
                    .map_err(|e| self.db_err(e))?;
                if found.is_some() {
                    break;
                }
            }
            if let Some(row) = &found {
                let event = to_text(&json!({
                    "state": "running", "attempt": row.attempt, "owner": owner,
                }));
                insert_event!(self, tx, &row.id, "state", &event, now);
            }
            tx.commit().await.map_err(|e| self.db_err(e))?;
            found
        });
        let Some(row) = row else {
            return Ok(None);
        };
        let job = row.into_job()?;
        let lease = Lease {
            job_id: job.id,
            token: job.lease_token,
            attempt: job.attempt,
            owner: owner.to_owned(),
        };
        Ok(Some(Claimed { job, lease }))
    }

    /// Finishes running jobs whose lease expired and that may not be reclaimed: on their last
    /// attempt (failed) or with a cancel requested (cancelled). Returns how many. [`claim`]
    /// calls it; a supervisor may call it on its own.
    ///
    /// [`claim`]: Queue::claim
    pub async fn reap(&self) -> Result<u64, QueueError> {
        let now = self.now_ms();
        let set = "state = CASE WHEN cancel_requested THEN 'cancelled' ELSE 'failed' END, \
                   last_error = CASE WHEN cancel_requested THEN last_error \
                     ELSE 'lease expired on the last attempt (the worker stopped heartbeating)' END, \
                   lease_owner = NULL, lease_expires_ms = NULL, finished_ms = $1, updated_ms = $1";
        let cond = "state = 'running' AND lease_expires_ms < $1 \
                    AND (attempt >= max_attempts OR cancel_requested)";
        let sql_pg = format!(
            "UPDATE jobs SET {set} WHERE id IN (SELECT id FROM jobs WHERE {cond} \
             FOR UPDATE SKIP LOCKED) RETURNING id, state, attempt"
        );
        let sql_sqlite = format!("UPDATE jobs SET {set} WHERE {cond} RETURNING id, state, attempt");
        let reaped = on_pool!(self, |pool, pg| {
            let mut tx = pool.begin().await.map_err(|e| self.db_err(e))?;
            let rows: Vec<(String, String, i64)> =
                sqlx::query_as(if pg { &sql_pg } else { &sql_sqlite })
                    .bind(now)
                    .fetch_all(&mut *tx)
                    .await
                    .map_err(|e| self.db_err(e))?;
            for (id, state, attempt) in &rows {
                let event = to_text(&json!({
                    "state": state, "attempt": attempt, "error": "lease expired",
                }));
                insert_event!(self, tx, id, "state", &event, now);
            }
            tx.commit().await.map_err(|e| self.db_err(e))?;
            rows.len()
        });
        Ok(u64::try_from(reaped).unwrap_or(u64::MAX))
    }

    /// Renews the lease until now + `lease`. Tells whether a cancel was requested.
    pub async fn heartbeat(&self, lease: &Lease, extend: Duration) -> Result<WriteAck, QueueError> {
        let now = self.now_ms();
        let expires = now.saturating_add(duration_ms(extend));
        let sql = format!(
            "UPDATE jobs SET lease_expires_ms = $3, heartbeat_ms = $4 WHERE {FENCE} RETURNING cancel_requested"
        );
        let row: Option<bool> = on_pool!(self, |pool, pg| {
            sqlx::query_scalar(&sql)
                .bind(lease.job_id.to_string())
                .bind(lease.token)
                .bind(expires)
                .bind(now)
                .fetch_optional(pool)
                .await
                .map_err(|e| self.db_err(e))?
        });
        self.ack(lease, row)
    }

    fn ack(&self, lease: &Lease, row: Option<bool>) -> Result<WriteAck, QueueError> {
        match row {
            Some(cancel_requested) => Ok(WriteAck { cancel_requested }),
            None => Err(QueueError::LeaseLost {
                job_id: lease.job_id,
                token: lease.token,
            }),
        }
    }

    /// A fenced update of the job's row (`set` uses `$3` for `value`, `$4` for now) followed
    /// by an event, in one transaction.
    async fn fenced_write(
        &self,
        lease: &Lease,
        set: &str,
        value: Option<String>,
        blob: Option<Vec<u8>>,
        event_kind: &str,
        event: &Value,
    ) -> Result<(WriteAck, i64), QueueError> {
        let now = self.now_ms();
        let sql = if blob.is_some() {
            format!(
                "UPDATE jobs SET {set}, checkpoint_blob = $5 WHERE {FENCE} RETURNING cancel_requested"
            )
        } else {
            format!("UPDATE jobs SET {set} WHERE {FENCE} RETURNING cancel_requested")
        };
        let event = to_text(event);
        let (row, event_id): (Option<bool>, i64) = on_pool!(self, |pool, pg| {
            let mut tx = pool.begin().await.map_err(|e| self.db_err(e))?;
            let mut query = sqlx::query_scalar(&sql)
                .bind(lease.job_id.to_string())
                .bind(lease.token)
                .bind(value.clone())
                .bind(now);
            if let Some(blob) = &blob {
                query = query.bind(blob.clone());
            }
            let row: Option<bool> = query
                .fetch_optional(&mut *tx)
                .await
                .map_err(|e| self.db_err(e))?;
            let mut event_id = 0;
            if row.is_some() {
                event_id = sqlx::query_scalar(INSERT_EVENT)
                    .bind(lease.job_id.to_string())
                    .bind(event_kind)
                    .bind(&event)
                    .bind(now)
                    .fetch_one(&mut *tx)
                    .await
                    .map_err(|e| self.db_err(e))?;
                tx.commit().await.map_err(|e| self.db_err(e))?;
            } else {
                tx.rollback().await.map_err(|e| self.db_err(e))?;
            }
            (row, event_id)
        });
        Ok((self.ack(lease, row)?, event_id))
    }

    /// Records progress (opaque JSON: steps, episodes, success rate, reward, ETA, ...) and
    /// appends it to the event log. Returns the event id.
    pub async fn report_progress(
        &self,
        lease: &Lease,
        progress: &Value,
    ) -> Result<(WriteAck, i64), QueueError> {
        self.fenced_write(
            lease,
            "progress = $3, updated_ms = $4",
            Some(to_text(progress)),
            None,
            "progress",
            progress,
        )
        .await
    }

    /// Stores a checkpoint durably: a worker that takes the job over resumes from it.
    pub async fn save_checkpoint(
        &self,
        lease: &Lease,
        checkpoint: &Checkpoint,
    ) -> Result<WriteAck, QueueError> {
        let set = if checkpoint.blob.is_some() {
            "checkpoint = $3, checkpoint_ms = $4, updated_ms = $4"
        } else {
            "checkpoint = $3, checkpoint_blob = NULL, checkpoint_ms = $4, updated_ms = $4"
        };
        let event = json!({
            "checkpoint": checkpoint.data,
            "blob_bytes": checkpoint.blob.as_ref().map(Vec::len),
        });
        self.fenced_write(
            lease,
            set,
            Some(to_text(&checkpoint.data)),
            checkpoint.blob.clone(),
            "checkpoint",
            &event,
        )
        .await
        .map(|(ack, _)| ack)
    }

    /// Marks the job succeeded with `result`.
    pub async fn complete(&self, lease: &Lease, result: &Value) -> Result<(), QueueError> {
        self.fenced_write(
            lease,
            "state = 'succeeded', result = $3, lease_owner = NULL, lease_expires_ms = NULL, \
             finished_ms = $4, updated_ms = $4",
            Some(to_text(result)),
            None,
            "state",
            &json!({"state": "succeeded", "attempt": lease.attempt}),
        )
        .await
        .map(|_| ())
    }

    /// Records a failed attempt. A `retryable` failure with attempts left goes back to the
    /// queue after the backoff; otherwise the job fails. A job with a cancel requested is
    /// cancelled instead.
    pub async fn fail(
        &self,
        lease: &Lease,
        error: &str,
        retryable: bool,
    ) -> Result<FailOutcome, QueueError> {
        let now = self.now_ms();
        let retry_at = now.saturating_add(duration_ms(self.backoff.delay(lease.attempt)));
        let sql = format!(
            "UPDATE jobs SET \
               state = CASE WHEN cancel_requested THEN 'cancelled' \
                 WHEN $5 AND attempt < max_attempts THEN 'queued' ELSE 'failed' END, \
               run_after_ms = CASE WHEN NOT cancel_requested AND $5 AND attempt < max_attempts \
                 THEN $6 ELSE run_after_ms END, \
               finished_ms = CASE WHEN NOT cancel_requested AND $5 AND attempt < max_attempts \
                 THEN NULL ELSE $4 END, \
               last_error = $3, lease_owner = NULL, lease_expires_ms = NULL, updated_ms = $4 \
             WHERE {FENCE} RETURNING state, run_after_ms"
        );
        let row: Option<(String, i64)> = on_pool!(self, |pool, pg| {
            let mut tx = pool.begin().await.map_err(|e| self.db_err(e))?;
            let row: Option<(String, i64)> = sqlx::query_as(&sql)
                .bind(lease.job_id.to_string())
                .bind(lease.token)
                .bind(error)
                .bind(now)
                .bind(retryable)
                .bind(retry_at)
                .fetch_optional(&mut *tx)
                .await
                .map_err(|e| self.db_err(e))?;
            if let Some((state, run_after)) = &row {
                let event = to_text(&json!({
                    "state": state, "attempt": lease.attempt, "error": error,
                    "run_after_ms": (state == "queued").then_some(*run_after),
                }));
                insert_event!(self, tx, lease.job_id.to_string(), "state", &event, now);
            }
            tx.commit().await.map_err(|e| self.db_err(e))?;
            row
        });
        match row {
            None => Err(QueueError::LeaseLost {
                job_id: lease.job_id,
                token: lease.token,
            }),
            Some((state, run_after_ms)) => match state.as_str() {
                "queued" => Ok(FailOutcome::Retrying { run_after_ms }),
                "cancelled" => Ok(FailOutcome::Cancelled),
                _ => Ok(FailOutcome::Failed),
            },
        }
    }

    /// Marks the job cancelled: its handler stopped because a cancel was requested.
    pub async fn mark_cancelled(&self, lease: &Lease) -> Result<(), QueueError> {
        self.fenced_write(
            lease,
            "state = 'cancelled', lease_owner = NULL, lease_expires_ms = NULL, \
             finished_ms = $4, updated_ms = $4, last_error = COALESCE($3, last_error)",
            None,
            None,
            "state",
            &json!({"state": "cancelled", "attempt": lease.attempt}),
        )
        .await
        .map(|_| ())
    }

    /// Gives the job back to the queue without counting the attempt (the worker is shutting
    /// down): claimable at once, by any worker, resuming from its last checkpoint. A job with a
    /// cancel requested is cancelled instead.
    pub async fn release(&self, lease: &Lease) -> Result<JobState, QueueError> {
        let now = self.now_ms();
        let sql = format!(
            "UPDATE jobs SET \
               state = CASE WHEN cancel_requested THEN 'cancelled' ELSE 'queued' END, \
               attempt = CASE WHEN cancel_requested THEN attempt ELSE attempt - 1 END, \
               finished_ms = CASE WHEN cancel_requested THEN $3 ELSE NULL END, \
               run_after_ms = $3, lease_owner = NULL, lease_expires_ms = NULL, updated_ms = $3 \
             WHERE {FENCE} RETURNING state"
        );
        let state: Option<String> = on_pool!(self, |pool, pg| {
            let mut tx = pool.begin().await.map_err(|e| self.db_err(e))?;
            let state: Option<String> = sqlx::query_scalar(&sql)
                .bind(lease.job_id.to_string())
                .bind(lease.token)
                .bind(now)
                .fetch_optional(&mut *tx)
                .await
                .map_err(|e| self.db_err(e))?;
            if let Some(state) = &state {
                let event = to_text(&json!({
                    "state": state, "attempt": lease.attempt, "released": true,
                }));
                insert_event!(self, tx, lease.job_id.to_string(), "state", &event, now);
            }
            tx.commit().await.map_err(|e| self.db_err(e))?;
            state
        });
        match state {
            None => Err(QueueError::LeaseLost {
                job_id: lease.job_id,
                token: lease.token,
            }),
            Some(s) => s.parse().map_err(|message| QueueError::Corrupt {
                id: lease.job_id.to_string(),
                message,
            }),
        }
    }

    /// Asks for a job to stop. A queued job is cancelled at once; a running one gets
    /// `cancel_requested`, which its worker sees at the next heartbeat or write and stops
    /// cooperatively. A finished job is left as it is. Returns the job's state afterwards.
    pub async fn request_cancel(&self, id: Uuid) -> Result<JobState, QueueError> {
        let now = self.now_ms();
        let sql = "UPDATE jobs SET \
               state = CASE WHEN state = 'queued' THEN 'cancelled' ELSE state END, \
               cancel_requested = CASE WHEN state IN ('queued', 'running') THEN TRUE \
                 ELSE cancel_requested END, \
               finished_ms = CASE WHEN state = 'queued' THEN $2 ELSE finished_ms END, \
               updated_ms = CASE WHEN state IN ('queued', 'running') THEN $2 ELSE updated_ms END \
             WHERE id = $1 RETURNING state";
        let state: Option<String> = on_pool!(self, |pool, pg| {
            let mut tx = pool.begin().await.map_err(|e| self.db_err(e))?;
            let state: Option<String> = sqlx::query_scalar(sql)
                .bind(id.to_string())
                .bind(now)
                .fetch_optional(&mut *tx)
                .await
                .map_err(|e| self.db_err(e))?;
            let event = match state.as_deref() {
                Some("cancelled") => Some(("state", json!({"state": "cancelled"}))),
                Some("running") => Some(("cancel_requested", json!({"cancel_requested": true}))),
                _ => None,
            };
            if let Some((kind, data)) = event {
                insert_event!(self, tx, id.to_string(), kind, to_text(&data), now);
            }
            tx.commit().await.map_err(|e| self.db_err(e))?;
            state
        });
        match state {
            None => Err(QueueError::NotFound(id)),
            Some(s) => s.parse().map_err(|message| QueueError::Corrupt {
                id: id.to_string(),
                message,
            }),
        }
    }

    /// Makes a running job's lease expire now, so the next claim takes it over (an operator
    /// who knows its worker is dead need not wait for the lease). Returns whether a running
    /// job was found. The old token stays valid until the job is reclaimed.
    pub async fn expire_lease(&self, id: Uuid) -> Result<bool, QueueError> {
        let past = self.now_ms().saturating_sub(1);
        let done = on_pool!(self, |pool, pg| {
            sqlx::query("UPDATE jobs SET lease_expires_ms = $2 WHERE id = $1 AND state = 'running'")
                .bind(id.to_string())
                .bind(past)
                .execute(pool)
                .await
                .map_err(|e| self.db_err(e))?
                .rows_affected()
        });
        Ok(done > 0)
    }

    /// The job with this id.
    pub async fn get(&self, id: Uuid) -> Result<Option<Job>, QueueError> {
        let sql = format!("SELECT {COLUMNS} FROM jobs WHERE id = $1");
        let row: Option<JobRow> = on_pool!(self, |pool, pg| {
            sqlx::query_as(&sql)
                .bind(id.to_string())
                .fetch_optional(pool)
                .await
                .map_err(|e| self.db_err(e))?
        });
        row.map(JobRow::into_job).transpose()
    }

    /// Jobs, newest first, optionally of one state; at most `limit`. Checkpoint bytes are not
    /// loaded (use [`Queue::get`]).
    pub async fn list(&self, state: Option<JobState>, limit: u32) -> Result<Vec<Job>, QueueError> {
        self.list_by(state, None, limit).await
    }

    /// Jobs, newest first, optionally of one state and one kind; at most `limit`. Checkpoint
    /// bytes are not loaded.
    pub async fn list_by(
        &self,
        state: Option<JobState>,
        kind: Option<&str>,
        limit: u32,
    ) -> Result<Vec<Job>, QueueError> {
        let columns = COLUMNS.replace("checkpoint_blob", "NULL AS checkpoint_blob");
        let sql = format!(
            "SELECT {columns} FROM jobs WHERE ($1 IS NULL OR state = $1) \
             AND ($2 IS NULL OR kind = $2) ORDER BY id DESC LIMIT $3"
        );
        let state = state.map(|s| s.as_str().to_owned());
        let kind = kind.map(str::to_owned);
        let rows: Vec<JobRow> = on_pool!(self, |pool, pg| {
            sqlx::query_as(&sql)
                .bind(state.clone())
                .bind(kind.clone())
                .bind(i64::from(limit))
                .fetch_all(pool)
                .await
                .map_err(|e| self.db_err(e))?
        });
        rows.into_iter().map(JobRow::into_job).collect()
    }

    /// The job's events with id greater than `after` (0: from the start), oldest first, at
    /// most `limit`.
    pub async fn events(
        &self,
        job_id: Uuid,
        after: i64,
        limit: u32,
    ) -> Result<Vec<JobEvent>, QueueError> {
        let sql = "SELECT id, job_id, kind, data, created_ms FROM job_events \
                   WHERE job_id = $1 AND id > $2 ORDER BY id LIMIT $3";
        let rows: Vec<EventRow> = on_pool!(self, |pool, pg| {
            sqlx::query_as(sql)
                .bind(job_id.to_string())
                .bind(after)
                .bind(i64::from(limit))
                .fetch_all(pool)
                .await
                .map_err(|e| self.db_err(e))?
        });
        rows.into_iter().map(EventRow::into_event).collect()
    }

    /// Deletes finished jobs (and their events) that finished more than `older_than` ago.
    /// Returns how many jobs were deleted.
    pub async fn purge_finished(&self, older_than: Duration) -> Result<u64, QueueError> {
        let before = self.now_ms().saturating_sub(duration_ms(older_than));
        let deleted = on_pool!(self, |pool, pg| {
            sqlx::query(
                "DELETE FROM jobs WHERE state IN ('succeeded', 'failed', 'cancelled') \
                 AND finished_ms < $1",
            )
            .bind(before)
            .execute(pool)
            .await
            .map_err(|e| self.db_err(e))?
            .rows_affected()
        });
        Ok(deleted)
    }

    /// How many jobs are in each state.
    pub async fn stats(&self) -> Result<QueueStats, QueueError> {
        let rows: Vec<(String, i64)> = on_pool!(self, |pool, pg| {
            sqlx::query_as("SELECT state, COUNT(*) FROM jobs GROUP BY state")
                .fetch_all(pool)
                .await
                .map_err(|e| self.db_err(e))?
        });
        let mut stats = QueueStats::new();
        for (state, n) in rows {
            let state: JobState = state.parse().map_err(|message| QueueError::Corrupt {
                id: String::new(),
                message,
            })?;
            stats.insert(state, u64::try_from(n).unwrap_or(0));
        }
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backoff_doubles_up_to_the_cap() {
        let b = Backoff {
            base: Duration::from_secs(2),
            cap: Duration::from_secs(30),
        };
        let delays: Vec<u64> = (1..=6).map(|a| b.delay(a).as_secs()).collect();
        assert_eq!(delays, [2, 4, 8, 16, 30, 30]);
        assert_eq!(b.delay(200), Duration::from_secs(30));
        assert_eq!(b.delay(0), Duration::from_secs(2));
    }

    #[test]
    fn states_round_trip() {
        for s in [
            JobState::Queued,
            JobState::Running,
            JobState::Succeeded,
            JobState::Failed,
            JobState::Cancelled,
        ] {
            assert_eq!(s.as_str().parse::<JobState>().unwrap(), s);
        }
        assert!("done".parse::<JobState>().is_err());
    }
}
