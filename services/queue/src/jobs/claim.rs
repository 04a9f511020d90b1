//! Into the queue and out of it: [`Queue::enqueue`], [`Queue::claim`] (an attempt, a lease and a
//! fencing token) and [`Queue::reap`] (leases that expired where no retry is left).
//!
//! Only the claim differs between the backends: PostgreSQL picks the row with `FOR UPDATE SKIP
//! LOCKED`, so concurrent claimers skip each other's rows; on SQLite the claim is a single
//! write statement, serialised by the database's write lock.

use std::time::Duration;

use serde_json::json;
use uuid::Uuid;

use super::rows::{COLUMNS, JobRow};
use super::types::{Claimed, Lease, NewJob, QueueError};
use super::{Queue, insert_event, on_pool, to_text};
use crate::clock::duration_ms;

impl Queue {
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
            .bind(i64::from(job.max_attempts))
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
}
