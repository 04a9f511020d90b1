//! The fleet's HTTP routes at the binary's edge: jobs (create, list, read, cancel, events as
//! server-sent events, curves), exported policies, plans (`POST /v1/plan`, which translates and
//! calls the planner), roadmaps and the fleet's traffic schedule (`traffic`), with their OpenAPI document ([`WorkerApi`]).
//!
//! Handlers receive their caller from an extractor (`edge::RobotCaller`, ...), translate the
//! wire types, call one use case (the job engine, the planner) and translate back.

pub mod jobs;
#[allow(
    unused_qualifications,
    reason = "utoipa's path macro expands the query extractor's type with its span"
)]
pub mod plan;
pub mod policies;
#[allow(
    unused_qualifications,
    reason = "utoipa's path macro expands the query extractor's type with its span"
)]
pub mod traffic;

pub use jobs::{JobsApi, StreamLimits, WorkerApi, router};
