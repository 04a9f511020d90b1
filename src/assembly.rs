//! Process assembly: the planner over its ports (the knowledge source, roadmap builds as
//! `roadmap` jobs, the traffic schedule in the job database) and the job kinds' environment
//! over the same planner, as `serve` and `worker` both build them.

use std::sync::Arc;

use jobs::{JobDirs, JobEnv, KnowledgeSource, QueueFleet, QueueRoadmapBuilds};
use planner::{Planner, PolicyStore, RoadmapStore};
use queue::LazyQueue;

/// What a process plans and runs jobs with.
#[derive(Clone)]
pub struct Fleet {
    /// The plan use case.
    pub planner: Arc<Planner>,
    /// The job kinds' environment (the same planner inside).
    pub kinds: Arc<JobEnv>,
    /// The traffic schedule the planner commits plans to.
    pub schedule: Arc<QueueFleet>,
}

impl std::fmt::Debug for Fleet {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fleet")
            .field("kinds", &self.kinds)
            .finish_non_exhaustive()
    }
}

/// The planner and the job kinds over `knowledge`, the files in `dirs` and the job database
/// `queue` (roadmap builds and the traffic schedule).
pub fn fleet(
    knowledge: Arc<dyn KnowledgeSource>,
    dirs: JobDirs,
    queue: &Arc<LazyQueue>,
    disk: Option<edge::disk::DiskWatch>,
) -> Fleet {
    let schedule = Arc::new(QueueFleet::new(Arc::clone(queue)));
    let planner = Arc::new(
        Planner::new(
            Arc::clone(&knowledge),
            PolicyStore::new(dirs.policies),
            Arc::new(rehearsal::RoadmapCache::default()),
            RoadmapStore::new(dirs.roadmaps),
            Arc::new(QueueRoadmapBuilds::new(Arc::clone(queue))),
        )
        .with_fleet(Arc::clone(&schedule) as Arc<dyn planner::FleetSchedule>),
    );
    let kinds = Arc::new(JobEnv::new(
        knowledge,
        Arc::clone(&planner),
        dirs.checkpoints,
        disk,
    ));
    Fleet {
        planner,
        kinds,
        schedule,
    }
}

/// How long one round of the idle-time improver works on one floor, at most.
const IMPROVE_ROUND: std::time::Duration = std::time::Duration::from_secs(2);

/// The idle-time improver (`planner::Planner::improve`): every `every`, each floor this
/// process planned on, for at most [`IMPROVE_ROUND`]; until `stopping`. It waits behind every
/// plan for the cores and gives way to them.
pub async fn improve_fleet(
    planner: Arc<Planner>,
    every: std::time::Duration,
    stopping: tokio_util::sync::CancellationToken,
) {
    loop {
        tokio::select! {
            () = stopping.cancelled() => return,
            () = tokio::time::sleep(every) => {}
        }
        for floor in planner.revisable_floors() {
            match planner.improve(&floor, IMPROVE_ROUND).await {
                Ok(done) if done.kept > 0 => tracing::debug!(
                    floor,
                    revisions = done.kept,
                    tried = done.tried,
                    "idle-time improver"
                ),
                Ok(_) => {}
                Err(e) => tracing::warn!(floor, error = %e, "the idle-time improver failed"),
            }
        }
    }
}
