//! The fleet's HTTP routes: plans (`POST /v1/plan`, which translates the wire request, calls
//! the planner and translates its outcome back), roadmaps, the fleet's traffic schedule, jobs
//! (create, list, read, cancel, events as server-sent events, curves) and exported policies,
//! with their OpenAPI document ([`FleetApi`]).
//!
//! Each area's routes have a state of their own ([`PlanRoutes`], [`TrafficRoutes`],
//! [`JobRoutes`], [`PolicyRoutes`]) holding what its handlers use; the process that serves
//! them assembles it ([`FleetServices`]). Handlers receive their caller from an extractor
//! (`edge::RobotCaller`, ...), translate the wire types, call one use case (the planner, the
//! job engine, the schedule) and translate back.

pub mod jobs;
#[allow(
    unused_qualifications,
    reason = "utoipa's path macro expands the query extractor's type with its span"
)]
pub mod plan;
pub mod policies;
pub mod streams;
#[allow(
    unused_qualifications,
    reason = "utoipa's path macro expands the query extractor's type with its span"
)]
pub mod traffic;

use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use edge::Tokens;
use tokio_util::sync::CancellationToken;

pub use self::jobs::{FleetApi, JobRoutes};
pub use self::plan::PlanRoutes;
pub use self::policies::PolicyRoutes;
pub use self::streams::StreamLimits;
pub use self::traffic::TrafficRoutes;

/// What the fleet's routes are given by the process that serves them.
pub struct FleetServices {
    /// Who may do what.
    pub tokens: Tokens,
    /// The job database (opened lazily).
    pub queue: Arc<queue::LazyQueue>,
    /// The plan use case.
    pub planner: Arc<planner::Planner>,
    /// The job kinds (what a new job is checked against) and their files.
    pub kinds: Arc<::jobs::JobEnv>,
    /// The fleet's traffic schedule.
    pub fleet: Arc<::jobs::QueueFleet>,
    /// Fires when the process shuts down: event streams end.
    pub shutdown: CancellationToken,
    /// How often an event stream polls for new events.
    pub event_poll: Duration,
    /// Event streams open at once, in all and per token.
    pub streams: Arc<StreamLimits>,
}

/// Every fleet route: plans and roadmaps, traffic, jobs, policies.
pub fn router(s: FleetServices) -> Router {
    let plans = PlanRoutes {
        tokens: s.tokens.clone(),
        planner: Arc::clone(&s.planner),
    };
    let traffic = TrafficRoutes {
        tokens: s.tokens.clone(),
        fleet: s.fleet,
        planner: s.planner,
        shutdown: s.shutdown.clone(),
        streams: Arc::clone(&s.streams),
    };
    let policies = PolicyRoutes {
        tokens: s.tokens.clone(),
        policies: s.kinds.policies.clone(),
    };
    let jobs = JobRoutes {
        queue: s.queue,
        tokens: s.tokens,
        kinds: s.kinds,
        shutdown: s.shutdown,
        event_poll: s.event_poll,
        streams: s.streams,
    };
    Router::new()
        .merge(plan::router(Arc::new(plans)))
        .merge(traffic::router(Arc::new(traffic)))
        .merge(policies::router(Arc::new(policies)))
        .merge(jobs::router(Arc::new(jobs)))
}
