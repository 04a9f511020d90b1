//! A `jobs` row as the drivers read it, and its conversion into a [`Job`] (a row that does not
//! convert is [`QueueError::Corrupt`], naming the job and the field).

use serde_json::Value;
use uuid::Uuid;

use super::types::{Checkpoint, Job, QueueError};

/// Every column of `jobs`, in [`JobRow`]'s order.
pub(super) const COLUMNS: &str = "id, kind, state, payload, priority, attempt, max_attempts, lease_token, \
    run_after_ms, lease_owner, lease_expires_ms, heartbeat_ms, cancel_requested, progress, \
    checkpoint, checkpoint_blob, checkpoint_ms, result, last_error, created_ms, updated_ms, \
    started_ms, finished_ms";

/// A `jobs` row.
#[derive(sqlx::FromRow)]
pub(super) struct JobRow {
    pub(super) id: String,
    pub(super) kind: String,
    pub(super) state: String,
    pub(super) payload: String,
    pub(super) priority: i64,
    pub(super) attempt: i64,
    pub(super) max_attempts: i64,
    pub(super) lease_token: i64,
    pub(super) run_after_ms: i64,
    pub(super) lease_owner: Option<String>,
    pub(super) lease_expires_ms: Option<i64>,
    pub(super) heartbeat_ms: Option<i64>,
    pub(super) cancel_requested: bool,
    pub(super) progress: Option<String>,
    pub(super) checkpoint: Option<String>,
    pub(super) checkpoint_blob: Option<Vec<u8>>,
    pub(super) checkpoint_ms: Option<i64>,
    pub(super) result: Option<String>,
    pub(super) last_error: Option<String>,
    pub(super) created_ms: i64,
    pub(super) updated_ms: i64,
    pub(super) started_ms: Option<i64>,
    pub(super) finished_ms: Option<i64>,
}

impl JobRow {
    /// The job this row holds.
    pub(super) fn into_job(self) -> Result<Job, QueueError> {
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
