//! The queue's vocabulary: a job and where it is in its life ([`Job`], [`JobState`]), what is
//! enqueued ([`NewJob`]) and saved ([`Checkpoint`]), the right to write to a running job
//! ([`Lease`], [`Claimed`], [`WriteAck`]), its event log ([`JobEvent`]), outcomes
//! ([`FailOutcome`], [`Backoff`]) and errors ([`QueueError`]).

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;
use std::time::Duration;

use serde::{Deserialize, Serialize};
use serde_json::Value;
use uuid::Uuid;

use crate::database::DatabaseError;

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

/// The right to write to one attempt of a job: returned by [`Queue::claim`](super::Queue::claim), required by every
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

/// What [`Queue::fail`](super::Queue::fail) did with the job.
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
