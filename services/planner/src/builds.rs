//! The port through which plans ask for a policy-aware roadmap to be built in the background
//! (the job engine's `roadmap` job, in the process that assembles the planner).

use std::future::Future;
use std::pin::Pin;

use crate::{PolicyRoadmapKey, PortError};

/// A boxed future for [`RoadmapBuilds`].
pub type BuildFuture<'a> = Pin<Box<dyn Future<Output = Result<String, PortError>> + Send + 'a>>;

/// Starts the background build of a policy-aware roadmap (the job engine's `roadmap` job).
pub trait RoadmapBuilds: Send + Sync {
    /// Makes sure a build of `key` (for `robot` on `floor`, with `margin`) is under way, once
    /// per key however many plans ask; answers what is building it (a job id).
    fn ensure<'a>(
        &'a self,
        key: &'a PolicyRoadmapKey,
        floor: &'a str,
        robot: &'a str,
        margin: f64,
    ) -> BuildFuture<'a>;
}
