//! Why no plan was answered ([`PlanFailure`]): typed causes, which each caller maps once to its
//! own errors (the HTTP edge to a status and code, a job to fatal or retryable).

use rehearsal::PlanError;

use crate::fleet::NoFit;
use crate::floor::SourceError;

/// Why no plan was answered. Callers map each to their own error (the HTTP edge to a status).
#[derive(Debug, thiserror::Error)]
pub enum PlanFailure {
    /// A malformed query (a value out of range); the message names the field.
    #[error("{0}")]
    BadRequest(String),
    /// The robot, place or policy does not exist.
    #[error("{0}")]
    NotFound(String),
    /// They exist but make no plan (a place on no floor, a map or policy that cannot be used).
    #[error("{0}")]
    Unprocessable(String),
    /// The knowledge service or the job database cannot answer now.
    #[error("{0}")]
    Unavailable(String),
    /// `roadmap: policy` and the policy-aware roadmap is not built yet, or cannot be read.
    #[error("{0}")]
    RoadmapNotReady(String),
    /// The plan conflicts with other robots' committed plans and no wait within the budget
    /// resolves it.
    #[error("{}", .0.message)]
    FleetConflict(NoFit),
    /// `roadmap: policy` and no edge the policy drives joins a leg.
    #[error(
        "on the policy-aware roadmap: {0} (no edge the policy drives joins them; `options.roadmap`: `auto` falls back to the geometric roadmap)"
    )]
    PolicyRoadmapUnreachable(PlanError),
    /// The executor refused the plan (blocked or unreachable goals, every attempt failed, ...).
    #[error("{0}")]
    Plan(PlanError),
    /// Something broke on our side.
    #[error("{0}")]
    Internal(String),
}

impl From<SourceError> for PlanFailure {
    fn from(e: SourceError) -> Self {
        match e {
            SourceError::NotFound(m) => PlanFailure::NotFound(m),
            SourceError::Unprocessable(m) => PlanFailure::Unprocessable(m),
            SourceError::Unavailable(m) => PlanFailure::Unavailable(m),
        }
    }
}
