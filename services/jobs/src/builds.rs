//! The planner's background builds of policy-aware roadmaps, as `roadmap` jobs on the queue.

use std::collections::HashMap;
use std::sync::Arc;

use planner::{BuildFuture, PolicyRoadmapKey, PortError, RoadmapBuilds};
use queue::LazyQueue;

/// Roadmap jobs remembered at most (the oldest are forgotten, not cancelled).
const REMEMBERED: usize = 16;

/// Enqueues one `roadmap` job per key, however many plans ask while it is pending.
#[derive(Debug)]
pub struct QueueRoadmapBuilds {
    queue: Arc<LazyQueue>,
    /// The roadmap job enqueued per key by this process.
    jobs: tokio::sync::Mutex<HashMap<PolicyRoadmapKey, uuid::Uuid>>,
}

impl QueueRoadmapBuilds {
    /// Builds on `queue`.
    pub fn new(queue: Arc<LazyQueue>) -> Self {
        Self {
            queue,
            jobs: tokio::sync::Mutex::new(HashMap::new()),
        }
    }
}

impl RoadmapBuilds for QueueRoadmapBuilds {
    fn ensure<'a>(
        &'a self,
        key: &'a PolicyRoadmapKey,
        floor: &'a str,
        robot: &'a str,
        margin: f64,
    ) -> BuildFuture<'a> {
        Box::pin(async move {
            let queue = self
                .queue
                .get()
                .await
                .map_err(|reason| PortError::new("opening the job database", reason))?;
            let mut jobs = self.jobs.lock().await;
            if let Some(id) = jobs.get(key).copied() {
                let pending = queue
                    .get(id)
                    .await
                    .ok()
                    .flatten()
                    .is_some_and(|j| !j.state.is_finished());
                if pending {
                    return Ok(id.to_string());
                }
            }
            let job = super::roadmap::request(&key.policy, floor, robot, margin).to_job();
            let id = queue
                .enqueue(job)
                .await
                .map_err(|e| PortError::new("enqueueing the roadmap job", e))?;
            if jobs.len() >= REMEMBERED {
                jobs.clear();
            }
            jobs.insert(key.clone(), id);
            Ok(id.to_string())
        })
    }
}
