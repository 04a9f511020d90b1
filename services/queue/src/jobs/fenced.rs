//! The writes a worker makes under its [`Lease`]: heartbeats, progress, checkpoints and the
//! outcome (complete, fail, cancelled, release). Each applies only while the job is `running`
//! under the lease's token (`FENCE`); otherwise nothing is written and the call fails with
//! [`QueueError::LeaseLost`]. A write and its event commit in one transaction.

use std::time::Duration;

use serde_json::{Value, json};

use super::types::{Checkpoint, FailOutcome, JobState, Lease, QueueError, WriteAck};
use super::{INSERT_EVENT, Queue, insert_event, on_pool, to_text};
use crate::clock::duration_ms;

/// The fence of every worker write: the job is running under the lease's token.
const FENCE: &str = "id = $1 AND lease_token = $2 AND state = 'running'";

impl Queue {
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
        self.give_back(lease, 0, None).await
    }

    /// Gives the job back to the queue without counting the attempt, claimable after the
    /// retry backoff's first delay, with `error` as its last error: the attempt could not go
    /// on for a reason that is not the job's (its disk is full) and that time may cure.
    pub async fn defer(&self, lease: &Lease, error: &str) -> Result<JobState, QueueError> {
        let delay = duration_ms(self.backoff.delay(1));
        self.give_back(lease, delay, Some(error)).await
    }

    async fn give_back(
        &self,
        lease: &Lease,
        delay_ms: i64,
        error: Option<&str>,
    ) -> Result<JobState, QueueError> {
        let now = self.now_ms();
        let sql = format!(
            "UPDATE jobs SET \
               state = CASE WHEN cancel_requested THEN 'cancelled' ELSE 'queued' END, \
               attempt = CASE WHEN cancel_requested THEN attempt ELSE attempt - 1 END, \
               finished_ms = CASE WHEN cancel_requested THEN $3 ELSE NULL END, \
               run_after_ms = $4, last_error = COALESCE($5, last_error), \
               lease_owner = NULL, lease_expires_ms = NULL, updated_ms = $3 \
             WHERE {FENCE} RETURNING state"
        );
        let run_after = now.saturating_add(delay_ms);
        let state: Option<String> = on_pool!(self, |pool, pg| {
            let mut tx = pool.begin().await.map_err(|e| self.db_err(e))?;
            let state: Option<String> = sqlx::query_scalar(&sql)
                .bind(lease.job_id.to_string())
                .bind(lease.token)
                .bind(now)
                .bind(run_after)
                .bind(error)
                .fetch_optional(&mut *tx)
                .await
                .map_err(|e| self.db_err(e))?;
            if let Some(state) = &state {
                let event = to_text(&match error {
                    None => json!({"state": state, "attempt": lease.attempt, "released": true}),
                    Some(error) => json!({
                        "state": state, "attempt": lease.attempt, "deferred": true,
                        "error": error, "run_after_ms": (state == "queued").then_some(run_after),
                    }),
                });
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
}
