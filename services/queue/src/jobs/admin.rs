//! What operators and the API do to jobs: look them up and list them, ask one to stop, expire
//! a dead worker's lease, purge finished jobs past retention and count jobs by state.

use std::time::Duration;

use serde_json::json;
use uuid::Uuid;

use super::rows::{COLUMNS, JobRow};
use super::types::{Job, JobState, QueueError, QueueStats};
use super::{Queue, insert_event, on_pool, to_text};
use crate::clock::duration_ms;

impl Queue {
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
