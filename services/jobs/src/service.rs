//! The worker side of a process: runners for every job kind over a lazily opened queue, and
//! the periodic purge of finished jobs (and of checkpoint files no job will resume from).

use std::sync::Arc;
use std::time::Duration;

use queue::{LazyQueue, Queue, WorkerConfig, WorkerReport};
use tokio_util::sync::CancellationToken;
use uuid::Uuid;

use crate::JobEnv;

/// Claims and runs jobs of every kind until `shutdown` fires ([`queue::run_workers`]).
pub async fn run_workers(
    queue: Arc<LazyQueue>,
    env: Arc<JobEnv>,
    config: WorkerConfig,
    shutdown: CancellationToken,
) -> WorkerReport {
    queue::run_workers(queue, |worker| env.register(worker), config, shutdown).await
}

/// Deletes finished jobs older than `retention`, and checkpoint directories of jobs that are
/// finished or gone, now and every `every`, until `shutdown` fires.
pub async fn purge_loop(
    queue: Arc<LazyQueue>,
    env: Arc<JobEnv>,
    retention: Duration,
    every: Duration,
    shutdown: CancellationToken,
) {
    loop {
        if let Ok(q) = queue.get().await {
            match q.purge_finished(retention).await {
                Ok(0) => {}
                Ok(n) => tracing::info!(jobs = n, "purged finished jobs past retention"),
                Err(e) => tracing::warn!(error = %e, "purging finished jobs failed"),
            }
            sweep_checkpoints(q, &env).await;
        }
        tokio::select! {
            () = shutdown.cancelled() => return,
            () = tokio::time::sleep(every) => {}
        }
    }
}

/// Removes `<checkpoints_dir>/<job id>` of jobs that finished or no longer exist.
pub async fn sweep_checkpoints(queue: &Queue, env: &JobEnv) {
    let Ok(mut entries) = tokio::fs::read_dir(&env.checkpoints_dir).await else {
        return;
    };
    while let Ok(Some(entry)) = entries.next_entry().await {
        let Some(id) = entry
            .file_name()
            .to_str()
            .and_then(|n| Uuid::parse_str(n).ok())
        else {
            continue;
        };
        let stale = match queue.get(id).await {
            Ok(None) => true,
            Ok(Some(job)) => job.state.is_finished(),
            Err(_) => false,
        };
        if stale {
            match tokio::fs::remove_dir_all(entry.path()).await {
                Ok(()) => tracing::info!(job = %id, "removed the checkpoint of a finished job"),
                Err(e) => {
                    tracing::warn!(job = %id, error = %e, "removing a stale checkpoint failed")
                }
            }
        }
    }
}
