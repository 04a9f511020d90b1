//! Rehearsal: a plan driven in the mental simulation before the robot moves — the hybrid PRM-RL
//! executor of the paper's §4.2.2. No IO, no async, no libtorch: the planner
//! (`planner::Planner::plan`, behind `POST /v1/plan` and the `validate` jobs alike) calls
//! [`validate_with_fallback`] on a blocking thread with the mission's world, a shared
//! [`RoadmapCache`] and the controller it picked (a policy is a `learning::Policy`, pure Rust)
//! with the follower as fallback, then drives the plan among the fleet with [`drive_among`]; the
//! benchmarks call [`validate_detailed`] and [`drive_edges`].
//!
//! - [`types`]: what the executor takes and returns ([`PlanRequest`], [`PlanReport`]), plain
//!   values without serde; the `wire` crate converts the HTTP edge's types;
//! - [`error`]: [`PlanError`], one variant per cause, the point concerned an [`Endpoint`];
//! - [`controller`]: the [`Controller`] trait, the policy behind its [`Shield`], and the
//!   classical follower;
//! - [`executor`]: the validation leg by leg (attempts on re-sampled roadmaps, the fallback,
//!   draws of people), its checks of a request and its roadmap paths and replans (private
//!   modules `checks` and `paths`); [`drive`](mod@drive): one simulated drive (waypoint timer,
//!   replanning, recoveries, social metrics);
//! - [`among`]: a validated plan driven again among other robots moving on their schedules;
//! - [`nav2`]: Nav2's Regulated Pure Pursuit and MPPI on the smoothed roadmap path, behind the
//!   shield, and [`ControllerChoice`], every controller by name;
//! - [`recovery`]: Nav2's recovery behaviours for a robot that stalls; [`social`]: intrusions
//!   into people's space;
//! - [`edges`]: every roadmap edge driven by a controller (PRM-RL): the per-edge success rate
//!   and the costs of a policy-aware roadmap;
//! - [`timed`]: a route timed among other robots' plans (waits at nodes, detours);
//! - [`cache`]: roadmaps per (map version, robot inflation, parameters);
//! - [`planning_grid`](mod@planning_grid): the planning grid of a built world.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
// (Not every crate warns of them yet; `cast_precision_loss` stays off everywhere: counts far
// below 2^52 convert to f64 exactly.)
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod among;
pub mod cache;
mod checks;
pub mod controller;
pub mod drive;
pub mod edges;
pub mod error;
pub mod executor;
pub mod limit_time;
pub mod nav2;
mod paths;
pub mod planning_grid;
pub mod recovery;
pub mod social;
pub mod timed;
pub mod types;

pub use among::{AmongReport, drive_among};
pub use cache::{CacheStats, RoadmapCache, SpaceEntry};
pub use controller::{
    ClassicalFollower, Controller, FollowerParams, HAND_BACK_STEPS, HANDOVER_MARGIN_M,
    POLICY_CARROT_M, POLICY_CONTROLLER_REVISION, POLICY_PROGRESS_M, POLICY_STALL_STEPS,
    PolicyController, Shield, ShieldedFollower,
};
pub use edges::{
    EdgeIndex, EdgeReport, EdgeRolloutParams, EdgeStat, EdgeSummary, NEAR_MISS_M, UNKEPT_PENALTY_M,
    drive_edges, drive_some_edges, first_attempt_roadmap, policy_roadmap, reweight,
    reweight_with_unkept,
};
pub use error::{BlockedReason, Endpoint, PlanError};
pub use executor::{
    AttemptDetails, Detailed, DriveLimits, DriveRun, MAX_PEOPLE_DRAWS, PERSON_COLLISION,
    ROBOT_COLLISION, Replanner, check_endpoints, check_request, command_limits, config_space,
    drive, env_config, env_config_for, follower_for, hit_person, recoveries_for, validate,
    validate_detailed, validate_with, validate_with_fallback,
};
pub use limit_time::LineLimits;
pub use nav2::{ControllerChoice, MppiController, MppiCycles, RppController};
pub use planning_grid::planning_grid;
pub use recovery::{RecoveryEvent, RecoveryKind, RecoveryParams};
pub use social::SocialMetrics;
pub use timed::Reserved;
pub use types::{
    AttemptOutcome, AttemptReport, AttemptTrace, ControllerKind, DrawsReport, LaserTrace,
    LegReport, PlanOptions, PlanReport, PlanRequest, RoadmapChoice, RoadmapInfo, RoadmapKind,
};

pub use grid::{Stop, StopOnDrop};
