//! Rehearsal: a plan driven in the mental simulation before the robot moves — the hybrid PRM-RL
//! executor of the paper's §4.2.2. No IO, no async, no libtorch: callers (the plan endpoint and
//! the `validate` jobs of `worker`, the navigation benchmark) call [`validate`] on a blocking
//! thread with the mission's world, a shared [`RoadmapCache`] and, when the robot has one, its
//! exported policy (`learning::Policy`, pure Rust).
//!
//! - [`types`]: what the executor takes and returns ([`PlanRequest`], [`PlanReport`]), plain
//!   values without serde; the HTTP edge converts its wire types;
//! - [`error`]: [`PlanError`], one variant per cause, the point concerned an [`Endpoint`];
//! - [`controller`]: the [`Controller`] trait, the policy behind its [`Shield`], and the
//!   classical follower;
//! - [`executor`]: roadmap query, waypoint timer, replanning, re-sampling on failure;
//! - [`cache`]: roadmaps per (map version, robot inflation, parameters);
//! - [`planning_grid`](mod@planning_grid): the planning grid of a built world.

pub mod cache;
pub mod controller;
pub mod error;
pub mod executor;
pub mod planning_grid;
pub mod types;

pub use cache::{CacheStats, RoadmapCache, SpaceEntry};
pub use controller::{ClassicalFollower, Controller, FollowerParams, PolicyController, Shield};
pub use error::{BlockedReason, Endpoint, PlanError};
pub use executor::{
    DriveLimits, DriveRun, Replanner, config_space, drive, env_config, validate, validate_with,
};
pub use planning_grid::planning_grid;
pub use types::{
    AttemptOutcome, AttemptReport, ControllerKind, PlanOptions, PlanReport, PlanRequest,
    RoadmapInfo,
};
