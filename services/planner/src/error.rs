//! Why no plan was answered ([`PlanFailure`]): typed causes, which each caller maps once to its
//! own errors (the HTTP edge to a status, a code and the field at fault; a job to fatal or
//! retryable). Where a lower layer failed, its error is the [`source`](std::error::Error::source).

use std::sync::Arc;

use rehearsal::PlanError;

use crate::fleet::NoFit;
use crate::floor::{SourceError, WorldError};

/// Any error, boxed: what a port's adapter failed with.
pub type BoxError = Box<dyn std::error::Error + Send + Sync>;

/// Why no plan was answered. Callers map each to their own error (the HTTP edge to a status).
#[derive(Debug, thiserror::Error)]
pub enum PlanFailure {
    /// A value of the query out of its range (the caller's to fix).
    #[error(transparent)]
    BadRequest(InvalidField),
    /// The robot, place or policy does not exist.
    #[error(transparent)]
    NotFound(Missing),
    /// They exist but make no plan (a place on no floor, a map or policy that cannot be used,
    /// a time that has passed, a full schedule).
    #[error(transparent)]
    Unprocessable(Unusable),
    /// The knowledge service, the job database or the schedule cannot answer now (retry).
    #[error(transparent)]
    Unavailable(Unavailable),
    /// `roadmap: policy` and the policy-aware roadmap is not built yet, or cannot be read.
    #[error(transparent)]
    RoadmapNotReady(RoadmapPending),
    /// The plan conflicts with other robots' committed plans and no wait within the budget
    /// resolves it.
    #[error("{}", .0.message)]
    FleetConflict(NoFit),
    /// `roadmap: policy` and no edge the policy drives joins a leg.
    #[error(
        "on the policy-aware roadmap: {0} (no edge the policy drives joins them; `options.roadmap`: `auto` falls back to the geometric roadmap)"
    )]
    PolicyRoadmapUnreachable(#[source] PlanError),
    /// The executor refused the plan (blocked or unreachable goals, every attempt failed, ...).
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// Something broke on our side: what, and the error underneath when there is one.
    #[error("{what}")]
    Internal {
        /// What broke.
        what: String,
        /// The error underneath.
        #[source]
        source: Option<BoxError>,
    },
}

impl PlanFailure {
    /// An internal failure with no error underneath.
    pub fn internal(what: impl Into<String>) -> Self {
        Self::Internal {
            what: what.into(),
            source: None,
        }
    }

    /// The request field at fault (a dotted path such as `options.people_hour`), when one is.
    pub fn field(&self) -> Option<&str> {
        match self {
            Self::BadRequest(f) | Self::Unprocessable(Unusable::Field(f)) => Some(&f.field),
            Self::Plan(PlanError::InvalidInput { field, .. }) => Some(field),
            _ => None,
        }
    }
}

/// A value of the request that cannot be used: the field (a dotted path), and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct InvalidField {
    /// The field, as the request spells it (`options.tolerance_s`, `time_ms`).
    pub field: String,
    /// Why it cannot be used, naming the field and the value.
    pub message: String,
}

impl InvalidField {
    /// `field` is at fault, `message` says why.
    pub fn new(field: impl Into<String>, message: impl Into<String>) -> Self {
        Self {
            field: field.into(),
            message: message.into(),
        }
    }
}

/// What does not exist.
#[derive(Debug, Clone, thiserror::Error)]
pub enum Missing {
    /// No policy of this id.
    #[error("no policy `{0}`")]
    Policy(String),
    /// The knowledge has no such robot or place (its own words).
    #[error("{0}")]
    Knowledge(String),
}

/// Why what exists makes no plan.
#[derive(Debug, Clone, thiserror::Error)]
pub enum Unusable {
    /// A value that is well-formed but impossible now (a start time that has passed).
    #[error(transparent)]
    Field(InvalidField),
    /// The knowledge does not make a floor database for this robot and place (its own words).
    #[error("{0}")]
    Knowledge(String),
    /// The floor's knowledge does not make a mental simulation.
    #[error(transparent)]
    World(#[from] WorldError),
    /// The stored policy cannot be loaded.
    #[error("policy `{id}` cannot be loaded: {source}")]
    Policy {
        /// The policy.
        id: String,
        /// Why.
        #[source]
        source: Arc<dyn std::error::Error + Send + Sync>,
    },
    /// The controller asked for needs what the robot has not (a trained policy).
    #[error(
        "`options.controller`: `{controller}` drives a trained policy, and this robot has none yet; ask for `auto`, `rpp`, `mppi` or `follower`"
    )]
    NoPolicyFor {
        /// The controller asked for.
        controller: &'static str,
    },
    /// The robot does not fit on the floor where it says it stands.
    #[error("the robot does not fit at ({x:.2}, {y:.2}): it would touch a wall or an object")]
    DoesNotFit {
        /// Where, metres.
        x: f64,
        /// Where, metres.
        y: f64,
    },
    /// The floor's schedule holds the most robots it takes.
    #[error(
        "the floor's traffic schedule holds the most robots it takes ({0}); cancel some plans or wait for them to expire"
    )]
    ScheduleFull(usize),
    /// The schedule refuses the itinerary (a value out of its range; its own words).
    #[error("{0}")]
    Refused(String),
}

/// What cannot answer now.
#[derive(Debug, thiserror::Error)]
pub enum Unavailable {
    /// A port failed: what it was asked, and the error underneath.
    #[error("{doing}: {source}")]
    Port {
        /// What the port was asked (`reading the floor's schedule`).
        doing: &'static str,
        /// The adapter's error.
        #[source]
        source: BoxError,
    },
    /// The knowledge service cannot answer now (its own words).
    #[error("{0}")]
    Knowledge(String),
    /// This service keeps no traffic schedule.
    #[error("this service keeps no traffic schedule")]
    NoSchedule,
    /// The floor's schedule kept changing under a commit.
    #[error("the floor's traffic schedule kept changing while {0}; retry")]
    ScheduleBusy(&'static str),
}

/// Why the policy-aware roadmap asked for is not there.
#[derive(Debug, thiserror::Error)]
pub enum RoadmapPending {
    /// A `roadmap` job is building it.
    #[error(
        "no policy-aware roadmap of this floor state and policy yet: the `roadmap` job {job} is building it (every edge driven by the policy); retry when it has finished, or ask for `options.roadmap`: `auto`"
    )]
    Building {
        /// The job's id.
        job: String,
    },
    /// No job could be enqueued to build it.
    #[error(
        "no policy-aware roadmap of this floor state and policy yet, and no job could be enqueued to build it ({0}); ask for `options.roadmap`: `auto`"
    )]
    NotEnqueued(#[source] PortError),
    /// It is stored but cannot be read.
    #[error(
        "the stored policy-aware roadmap of this floor state and policy cannot be read; ask for `options.roadmap`: `auto`"
    )]
    Unreadable,
}

/// What a port's adapter failed with, and what it was asked.
#[derive(Debug, thiserror::Error)]
#[error("{doing}: {source}")]
pub struct PortError {
    /// What the port was asked.
    pub doing: &'static str,
    /// The adapter's error.
    #[source]
    pub source: BoxError,
}

impl PortError {
    /// `doing` failed with `source`.
    pub fn new(doing: &'static str, source: impl Into<BoxError>) -> Self {
        Self {
            doing,
            source: source.into(),
        }
    }
}

impl From<PortError> for PlanFailure {
    fn from(e: PortError) -> Self {
        PlanFailure::Unavailable(Unavailable::Port {
            doing: e.doing,
            source: e.source,
        })
    }
}

impl From<InvalidField> for PlanFailure {
    fn from(e: InvalidField) -> Self {
        PlanFailure::BadRequest(e)
    }
}

impl From<WorldError> for PlanFailure {
    fn from(e: WorldError) -> Self {
        PlanFailure::Unprocessable(Unusable::World(e))
    }
}

impl From<SourceError> for PlanFailure {
    fn from(e: SourceError) -> Self {
        match e {
            SourceError::NotFound(m) => PlanFailure::NotFound(Missing::Knowledge(m)),
            SourceError::Unprocessable(m) => PlanFailure::Unprocessable(Unusable::Knowledge(m)),
            SourceError::Unavailable(m) => PlanFailure::Unavailable(Unavailable::Knowledge(m)),
        }
    }
}
