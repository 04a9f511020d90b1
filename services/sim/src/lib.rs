//! Simulation parser (TOSM -> world, SDF/URDF) and the headless simulator; no IO.
//!
//! The crate takes values and returns values: it opens no files, starts no threads of its own
//! beyond rayon's pool for batches, and knows nothing of async runtimes.
//!
//! - [`spec`]: [`WorldSpec`], the typed and validated description of a world;
//! - [`library`]: the model library and placeholders;
//! - [`world`]: [`World`], the built world with exact laser casts and clearance queries;
//! - [`kinematics`]: differential drive;
//! - [`env`](mod@crate::env) and [`batch`]: the reinforcement-learning environment of the
//!   paper's §4.1.1;
//! - [`crowd`]: people walking about, avoiding each other and the robot (ORCA);
//! - [`field`]: path distances to a goal (the shaped reward's navigation function);
//! - [`render`]: top-down PNG and SVG pictures;
//! - [`smoother`], [`track`], [`rpp`], [`mppi`]: Nav2's classical path smoothing and tracking
//!   (Simple Smoother, Regulated Pure Pursuit, MPPI), the baselines a learnt policy must beat;
//! - [`parse`]: the simulation parser, on-demand database (RDF) to [`WorldSpec`];
//! - [`export`]: SDF 1.9 worlds and URDF robots for Gazebo and ROS.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
// (`planning` and `bench` do not yet; `cast_precision_loss` stays off everywhere: counts far
// below 2^52 convert to f64 exactly.)
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod batch;
pub mod crowd;
pub mod env;
pub mod export;
pub mod field;
pub mod floors;
pub mod follower;
pub mod kinematics;
pub mod library;
pub mod mppi;
pub mod others;
pub mod parse;
pub mod render;
pub mod rpp;
pub mod shield;
pub mod smoother;
pub mod spec;
pub mod track;
pub mod world;

pub use batch::{EnvBatch, env_seed};
pub use crowd::{Crowd, PeopleConfig, Person};
pub use env::{
    CLEARANCE_BAND_M, EnvConfig, EnvError, NavEnv, NoiseConfig, Observation, Outcome, RewardConfig,
    StepInfo, StepResult,
};
pub use field::PathField;
pub use floors::{FloorParams, generate_floor};
pub use follower::{FollowerParams, follow};
pub use kinematics::{Action, CommandLimits, DiffDrive};
pub use library::{LibraryModel, Model};
pub use mppi::{Mppi, MppiParams, MppiWorld};
pub use others::{OtherRobot, OtherRobots};
pub use parse::{parse_floor, parse_on_demand, parse_robot};
pub use rpp::{RppParams, RppStep, rpp_command, rpp_step};
pub use smoother::{SmootherParams, smooth_path};
pub use spec::{
    AttractorSpec, CameraSpec, Colour, DiffDriveSpec, FloorMap, LaserSpec, ObjectSpec, Occupancy,
    OccupancyGrid, PeoplePlaceSpec, PeopleSpec, Pose2, Pose3, RobotPartSpec, RobotSpec, RouteSpec,
    Severity, Shape, Size3, SpecProblem, SpecProblems, WallSpec, WheelSpec, WorldSpec,
};
pub use track::PathTrack;
pub use world::{BuildOptions, FreeRegion, World};

/// The length of `(dx, dy)`, for distances in a building: `f64::hypot` guards against overflow
/// and underflow no floor's metres come near, at several times the cost, in loops that run per
/// laser return and per control step.
#[inline]
#[must_use]
pub fn norm(dx: f64, dy: f64) -> f64 {
    (dx * dx + dy * dy).sqrt()
}
