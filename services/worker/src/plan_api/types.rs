//! Request and report of a plan validation: the wire types of `POST /v1/plan` and of `validate`
//! jobs (serde, OpenAPI schemas). The executor (`rehearsal`) takes and returns its own core types
//! (`rehearsal::types`, over `sim::Pose2` and `planning::Point2`); they are converted here, on
//! purpose, field by field, and never exposed on the wire.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// A point in the map frame, metres.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Point {
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
}

impl Point {
    /// A point from its coordinates.
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }
}

impl From<planning::Point2> for Point {
    fn from(p: planning::Point2) -> Self {
        Self { x: p.x, y: p.y }
    }
}

impl From<Point> for planning::Point2 {
    fn from(p: Point) -> Self {
        planning::Point2::new(p.x, p.y)
    }
}

/// A pose in the map frame: position in metres, heading in radians (counter-clockwise from +x).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
    /// Heading, radians; 0 when not given.
    #[serde(default)]
    pub yaw: f64,
}

impl Pose {
    /// A pose from its coordinates.
    pub const fn new(x: f64, y: f64, yaw: f64) -> Self {
        Self { x, y, yaw }
    }
}

impl From<sim::Pose2> for Pose {
    fn from(p: sim::Pose2) -> Self {
        Self {
            x: p.x,
            y: p.y,
            yaw: p.yaw,
        }
    }
}

impl From<Pose> for sim::Pose2 {
    fn from(p: Pose) -> Self {
        sim::Pose2::new(p.x, p.y, p.yaw)
    }
}

/// How a plan is validated. Every field has a default.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PlanOptions {
    /// Simulated runs at most, each on a roadmap re-sampled with a new seed (default 5).
    pub max_attempts: u32,
    /// The waypoint timer of the paper's §4.2.2: simulated seconds to reach one waypoint before
    /// the planner replans from where the robot is (default 15).
    pub waypoint_timeout_s: f64,
    /// Replans allowed within one attempt before it counts as stalled (default 5).
    pub max_replans: u32,
    /// Remove detours from the roadmap path (each waypoint joined to the farthest one in
    /// straight sight). The paper's planner does not; default false.
    pub shortcut: bool,
    /// Clearance kept beyond the robot's radius when sampling the roadmap, metres (default 0.1).
    pub safety_margin_m: f64,
    /// PRM samples n; `null` for the paper's n* = ceil(0.05 · free area + 84) (Eq. 19).
    pub samples: Option<usize>,
    /// Seed of the roadmaps and the simulation: the same request gives the same report.
    pub seed: u64,
    /// Gaussian noise on observations and executed commands, as in training (default true).
    pub noise: bool,
    /// Keep every n-th pose of the simulated trajectory in the report (default 1: all; 0: none).
    pub trajectory_stride: u32,
}

impl Default for PlanOptions {
    /// The executor's defaults.
    fn default() -> Self {
        rehearsal::PlanOptions::default().into()
    }
}

impl From<rehearsal::PlanOptions> for PlanOptions {
    fn from(o: rehearsal::PlanOptions) -> Self {
        let rehearsal::PlanOptions {
            max_attempts,
            waypoint_timeout_s,
            max_replans,
            shortcut,
            safety_margin_m,
            samples,
            seed,
            noise,
            trajectory_stride,
        } = o;
        Self {
            max_attempts,
            waypoint_timeout_s,
            max_replans,
            shortcut,
            safety_margin_m,
            samples,
            seed,
            noise,
            trajectory_stride,
        }
    }
}

impl From<PlanOptions> for rehearsal::PlanOptions {
    fn from(o: PlanOptions) -> Self {
        let PlanOptions {
            max_attempts,
            waypoint_timeout_s,
            max_replans,
            shortcut,
            safety_margin_m,
            samples,
            seed,
            noise,
            trajectory_stride,
        } = o;
        Self {
            max_attempts,
            waypoint_timeout_s,
            max_replans,
            shortcut,
            safety_margin_m,
            samples,
            seed,
            noise,
            trajectory_stride,
        }
    }
}

/// What to plan: from the robot's pose through one goal or a sequence of goals.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PlanRequest {
    /// The robot's current pose.
    pub start: Pose,
    /// Goals, visited in order; at least one.
    pub goals: Vec<Point>,
    /// Validation settings.
    #[serde(default)]
    pub options: PlanOptions,
}

impl From<PlanRequest> for rehearsal::PlanRequest {
    fn from(r: PlanRequest) -> Self {
        Self {
            start: r.start.into(),
            goals: r.goals.into_iter().map(Into::into).collect(),
            options: r.options.into(),
        }
    }
}

/// Which controller drove the simulated robot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ControllerKind {
    /// The exported TD3 policy (hybrid PRM-RL, the paper's §4.2.2).
    Policy,
    /// The classical path follower (rotate towards the waypoint, then drive while steering),
    /// used when no policy is given.
    Classical,
}

impl From<rehearsal::ControllerKind> for ControllerKind {
    fn from(k: rehearsal::ControllerKind) -> Self {
        match k {
            rehearsal::ControllerKind::Policy => ControllerKind::Policy,
            rehearsal::ControllerKind::Classical => ControllerKind::Classical,
        }
    }
}

/// How one simulated attempt ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum AttemptOutcome {
    /// Every goal reached without a collision: the plan is validated.
    Reached,
    /// The robot came too close to an obstacle.
    Collision,
    /// The waypoint timer ran out more often than replanning allows, or replanning found no
    /// way on from where the robot stood.
    Stalled,
}

impl From<rehearsal::AttemptOutcome> for AttemptOutcome {
    fn from(o: rehearsal::AttemptOutcome) -> Self {
        match o {
            rehearsal::AttemptOutcome::Reached => AttemptOutcome::Reached,
            rehearsal::AttemptOutcome::Collision => AttemptOutcome::Collision,
            rehearsal::AttemptOutcome::Stalled => AttemptOutcome::Stalled,
        }
    }
}

/// One simulated run of the plan on one roadmap.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct AttemptReport {
    /// 1-based.
    pub attempt: u32,
    /// Seed of the roadmap this attempt planned on.
    pub roadmap_seed: u64,
    /// How it ended.
    pub outcome: AttemptOutcome,
    /// Why, in words (where a collision happened, which waypoint timed out).
    pub reason: String,
    /// Simulated time, seconds.
    pub simulated_time_s: f64,
    /// Distance driven, metres.
    pub distance_m: f64,
    /// Smallest footprint clearance seen, metres.
    pub min_clearance_m: f64,
    /// Times the waypoint timer ran out and the planner replanned.
    pub replans: u32,
    /// Waypoints reached.
    pub waypoints_reached: usize,
    /// Goals reached.
    pub goals_reached: usize,
    /// Length of the roadmap path planned at the start of the attempt, metres.
    pub prm_path_length_m: f64,
    /// Where the robot ended.
    pub end_pose: Pose,
}

impl From<rehearsal::AttemptReport> for AttemptReport {
    fn from(a: rehearsal::AttemptReport) -> Self {
        let rehearsal::AttemptReport {
            attempt,
            roadmap_seed,
            outcome,
            reason,
            simulated_time_s,
            distance_m,
            min_clearance_m,
            replans,
            waypoints_reached,
            goals_reached,
            prm_path_length_m,
            end_pose,
        } = a;
        Self {
            attempt,
            roadmap_seed,
            outcome: outcome.into(),
            reason,
            simulated_time_s,
            distance_m,
            min_clearance_m,
            replans,
            waypoints_reached,
            goals_reached,
            prm_path_length_m,
            end_pose: end_pose.into(),
        }
    }
}

/// A plan validated in the mental simulation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PlanReport {
    /// The waypoints to follow, in order, as the simulated robot reached them (replanned ones
    /// included), ending with the last goal. The start is not repeated.
    pub waypoints: Vec<Point>,
    /// Index into `waypoints` of each goal.
    pub goal_indices: Vec<usize>,
    /// The controller that drove the simulated robot.
    pub controller: ControllerKind,
    /// What that controller is (a policy's training summary or the follower's rule).
    pub controller_description: String,
    /// Every attempt, the successful last one included.
    pub attempts: Vec<AttemptReport>,
    /// Simulated time of the validating run, seconds.
    pub simulated_time_s: f64,
    /// Distance driven in the validating run, metres.
    pub distance_m: f64,
    /// Smallest footprint clearance in the validating run, metres.
    pub min_clearance_m: f64,
    /// Length of the roadmap path of the validating run as first planned, metres.
    pub prm_path_length_m: f64,
    /// Length of the returned waypoint polyline from the start, metres.
    pub waypoint_path_length_m: f64,
    /// Replans in the validating run.
    pub replans: u32,
    /// Poses of the validating run (every `trajectory_stride`-th, and the last).
    pub trajectory: Vec<Pose>,
    /// The roadmap of the validating run.
    pub roadmap: RoadmapInfo,
}

impl From<rehearsal::PlanReport> for PlanReport {
    fn from(r: rehearsal::PlanReport) -> Self {
        let rehearsal::PlanReport {
            waypoints,
            goal_indices,
            controller,
            controller_description,
            attempts,
            simulated_time_s,
            distance_m,
            min_clearance_m,
            prm_path_length_m,
            waypoint_path_length_m,
            replans,
            trajectory,
            roadmap,
        } = r;
        Self {
            waypoints: waypoints.into_iter().map(Into::into).collect(),
            goal_indices,
            controller: controller.into(),
            controller_description,
            attempts: attempts.into_iter().map(Into::into).collect(),
            simulated_time_s,
            distance_m,
            min_clearance_m,
            prm_path_length_m,
            waypoint_path_length_m,
            replans,
            trajectory: trajectory.into_iter().map(Into::into).collect(),
            roadmap: roadmap.into(),
        }
    }
}

/// The roadmap a report planned on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RoadmapInfo {
    /// Samples n.
    pub samples: usize,
    /// Nodes in the graph (bridging and absorbed nodes included).
    pub nodes: usize,
    /// Seed.
    pub seed: u64,
    /// Robot radius plus safety margin the free space was inflated by, metres.
    pub inflation_m: f64,
    /// Whether the roadmap came from the cache.
    pub cached: bool,
}

impl From<rehearsal::RoadmapInfo> for RoadmapInfo {
    fn from(r: rehearsal::RoadmapInfo) -> Self {
        let rehearsal::RoadmapInfo {
            samples,
            nodes,
            seed,
            inflation_m,
            cached,
        } = r;
        Self {
            samples,
            nodes,
            seed,
            inflation_m,
            cached,
        }
    }
}
