//! Plan validation: the hybrid PRM-RL executor of the paper's §4.2.2 run in the mental
//! simulation, behind `POST /v1/plan`. No IO, no async: the HTTP handler calls [`validate`] on a
//! blocking thread with the mission's world, the shared [`RoadmapCache`] and, when the robot has
//! one, its exported policy.
//!
//! - [`types`]: request and report (serde, OpenAPI schemas);
//! - [`error`]: [`PlanError`], one variant per cause, each with its API code;
//! - [`controller`]: the [`Controller`] trait, the policy and the classical follower;
//! - [`executor`]: roadmap query, waypoint timer, replanning, re-sampling on failure;
//! - [`cache`]: roadmaps per (map version, robot inflation, parameters);
//! - [`grid`]: the planning grid of a built world.

pub mod cache;
pub mod controller;
pub mod error;
pub mod executor;
pub mod grid;
pub mod types;

pub use cache::{CacheStats, RoadmapCache, SpaceEntry};
pub use controller::{ClassicalFollower, Controller, FollowerParams, PolicyController, Shield};
pub use error::{BlockedReason, PlanError};
pub use executor::{
    DriveLimits, DriveRun, Replanner, config_space, drive, env_config, validate, validate_with,
};
pub use grid::planning_grid;
pub use types::{
    AttemptOutcome, AttemptReport, ControllerKind, PlanOptions, PlanReport, PlanRequest, Point,
    Pose, RoadmapInfo,
};
