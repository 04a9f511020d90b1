//! The event log: every state change, progress report and checkpoint appends to `job_events`
//! in the transaction that changes the job, with ids that grow monotonically per job;
//! [`Queue::events`] reads it from any id on (an SSE stream resumes from `Last-Event-ID`).

use uuid::Uuid;

use super::types::{JobEvent, QueueError};
use super::{Queue, on_pool};

/// A `job_events` row.
#[derive(sqlx::FromRow)]
struct EventRow {
    id: i64,
    job_id: String,
    kind: String,
    data: String,
    created_ms: i64,
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

impl Queue {
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
}
