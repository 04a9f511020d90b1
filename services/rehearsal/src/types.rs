//! What the executor takes and returns: plain values in the map frame (`sim::Pose2`,
//! `prm::Point2`), no serde. An HTTP edge keeps its own wire types and converts them.

use prm::Point2;
use sim::Pose2;

/// How a plan is validated. [`PlanOptions::default`] gives the defaults of the plan endpoint.
#[derive(Clone, Debug, PartialEq)]
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
    /// PRM samples n; `None` for the paper's n* = ceil(0.05 · free area + 84) (Eq. 19).
    pub samples: Option<usize>,
    /// Seed of the roadmaps and the simulation: the same request gives the same report.
    pub seed: u64,
    /// Gaussian noise on observations and executed commands, as in training (default true).
    pub noise: bool,
    /// Keep every n-th pose of the simulated trajectory in the report (default 1: all; 0: none).
    pub trajectory_stride: u32,
    /// Which roadmap the policy plans on when a policy-aware one is given (default `Auto`).
    pub roadmap: RoadmapChoice,
    /// Record every attempt's drive (poses, the laser ranges the controller saw, the planned
    /// path) in its report, for replaying the rehearsal (default false).
    pub trace: bool,
    /// People walking about in the rehearsal (default none). Each attempt draws them afresh
    /// (its own simulation seed), so attempts are different draws of the same crowd.
    pub people: sim::PeopleConfig,
    /// Once validated, drive the plan's waypoints again among this many fresh draws of the
    /// people (each leg with the controller that validated it, without replanning), to say how
    /// robust the plan is across crowds ([`PlanReport::people_draws`]); 0 (default) for none,
    /// at most [`crate::MAX_PEOPLE_DRAWS`]. Ignored without people.
    pub people_draws: u32,
    /// Other robots standing still on the floor for as long as is known (the fleet's robots
    /// with no plan yet), each a centre and a footprint radius: the roadmap route keeps clear
    /// of them (no edge passes closer than their radius plus the robot's plus
    /// `safety_margin_m`), or pays `standing_pass_m` to pass one. Default none.
    pub standing: Vec<(Point2, f64)>,
    /// What passing a robot of `standing` costs a route, metres: infinite (the default) keeps
    /// clear of them; a finite cost passes one where going around is longer by more (a robot
    /// with no plan yet that is expected to get one and leave).
    pub standing_pass_m: f64,
    /// Other robots' plans on the floor (the fleet's schedule): the roadmap route is the one
    /// that arrives first among them ([`crate::timed`]: waits at its nodes, detours), not
    /// merely the shortest. Default none.
    pub reserved: Option<std::sync::Arc<crate::Reserved>>,
    /// Mixed into the roadmap's seed (not the simulation's): the planner gives each robot of a
    /// fleet its own, so robots sent the same way do not all queue in the same roadmap lanes.
    /// Default 0.
    pub roadmap_salt: u64,
}

/// Which roadmap the policy plans on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum RoadmapChoice {
    /// The policy-aware roadmap when there is one, else the geometric one; a leg no kept edge
    /// joins is planned on the geometric roadmap by the fallback.
    #[default]
    Auto,
    /// Only the policy-aware roadmap: a leg no kept edge joins is unreachable.
    Policy,
    /// Only the geometric roadmap.
    Geometric,
}

impl Default for PlanOptions {
    fn default() -> Self {
        Self {
            max_attempts: 5,
            waypoint_timeout_s: 15.0,
            max_replans: 5,
            shortcut: false,
            safety_margin_m: 0.1,
            samples: None,
            seed: 0,
            noise: true,
            trajectory_stride: 1,
            roadmap: RoadmapChoice::Auto,
            trace: false,
            people: sim::PeopleConfig::default(),
            people_draws: 0,
            standing: Vec::new(),
            standing_pass_m: f64::INFINITY,
            reserved: None,
            roadmap_salt: 0,
        }
    }
}

/// What to plan: from the robot's pose through one goal or a sequence of goals.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanRequest {
    /// The robot's current pose.
    pub start: Pose2,
    /// Goals, visited in order; at least one.
    pub goals: Vec<Point2>,
    /// Validation settings.
    pub options: PlanOptions,
    /// Polled between attempts, while roadmaps are built and while the simulated robot drives:
    /// once requested, the validation ends with [`crate::PlanError::Stopped`].
    pub stop: grid::Stop,
}

/// Which controller drove the simulated robot.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ControllerKind {
    /// The exported TD3 policy (hybrid PRM-RL, the paper's §4.2.2).
    Policy,
    /// The classical path follower (rotate towards the waypoint, then drive while steering),
    /// used when no policy is given.
    Classical,
}

impl ControllerKind {
    /// The name in reports and benchmark tables: `policy` or `classical`.
    pub fn as_str(self) -> &'static str {
        match self {
            ControllerKind::Policy => "policy",
            ControllerKind::Classical => "classical",
        }
    }
}

/// How one simulated attempt ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AttemptOutcome {
    /// Every goal reached without a collision: the plan is validated.
    Reached,
    /// The robot came too close to an obstacle.
    Collision,
    /// The waypoint timer ran out more often than replanning allows, or replanning found no
    /// way on from where the robot stood.
    Stalled,
}

impl AttemptOutcome {
    /// The name in reports and benchmark tables: `reached`, `collision` or `stalled`.
    pub fn as_str(self) -> &'static str {
        match self {
            AttemptOutcome::Reached => "reached",
            AttemptOutcome::Collision => "collision",
            AttemptOutcome::Stalled => "stalled",
        }
    }
}

/// One simulated run of the plan on one roadmap.
#[derive(Clone, Debug, PartialEq)]
pub struct AttemptReport {
    /// 1-based, per leg and controller.
    pub attempt: u32,
    /// The leg this attempt drove: 0 from the start to goal 0, `i` from goal `i - 1` to goal `i`.
    pub leg: usize,
    /// The controller that drove it.
    pub controller: ControllerKind,
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
    /// Waypoints reached in the plan so far (earlier legs' validating runs included).
    pub waypoints_reached: usize,
    /// Goals reached in the plan so far.
    pub goals_reached: usize,
    /// Length of the roadmap path planned at the start of the attempt, metres.
    pub prm_path_length_m: f64,
    /// Where the robot ended.
    pub end_pose: Pose2,
    /// Share of the control steps the classical follower drove inside a policy controller
    /// (its handover near obstacles); 0 for the follower's own attempts.
    pub handover_share: f64,
    /// Closest approach of the footprint to a person, metres (`None` without people).
    pub min_person_clearance_m: Option<f64>,
    /// The drive step by step, when [`PlanOptions::trace`] asked for it.
    pub trace: Option<AttemptTrace>,
}

/// One attempt's drive, step by step (every `trajectory_stride`-th step, and the last).
#[derive(Clone, Debug, PartialEq)]
pub struct AttemptTrace {
    /// The roadmap path planned at the start of the attempt (its waypoints).
    pub path: Vec<Point2>,
    /// Simulated time of each recorded step, seconds.
    pub times_s: Vec<f64>,
    /// The robot's pose at each recorded step.
    pub poses: Vec<Pose2>,
    /// The laser ranges the controller saw at each recorded step, metres, rightmost beam first.
    pub ranges: Vec<Vec<f32>>,
}

/// The laser as a trace's ranges read it.
#[derive(Clone, Debug, PartialEq)]
pub struct LaserTrace {
    /// Angle of each beam in the robot frame, radians, rightmost first.
    pub angles_rad: Vec<f64>,
    /// Longest range, metres (a beam that hits nothing reads it).
    pub max_range_m: f64,
    /// Simulated seconds per step.
    pub control_period_s: f64,
}

/// A plan validated in the mental simulation.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanReport {
    /// The waypoints to follow, in order, as the simulated robot reached them (replanned ones
    /// included), ending with the last goal. The start is not repeated.
    pub waypoints: Vec<Point2>,
    /// Index into `waypoints` of each goal.
    pub goal_indices: Vec<usize>,
    /// The controller the plan was asked of: the policy when the robot has one. Each leg says
    /// which controller validated it ([`PlanReport::legs`]).
    pub controller: ControllerKind,
    /// What that controller is (a policy's training summary or the follower's rule).
    pub controller_description: String,
    /// Each leg as validated, in order.
    pub legs: Vec<LegReport>,
    /// Every attempt of every leg, each leg's validating one included.
    pub attempts: Vec<AttemptReport>,
    /// Simulated time of the validating runs of every leg, seconds.
    pub simulated_time_s: f64,
    /// Distance driven in the validating runs, metres.
    pub distance_m: f64,
    /// Smallest footprint clearance in the validating runs, metres.
    pub min_clearance_m: f64,
    /// Length of the roadmap path of each leg's validating run as first planned, summed, metres.
    pub prm_path_length_m: f64,
    /// Length of the returned waypoint polyline from the start, metres.
    pub waypoint_path_length_m: f64,
    /// Replans in the validating runs.
    pub replans: u32,
    /// Poses of the validating runs, leg after leg (every `trajectory_stride`-th, and the last).
    pub trajectory: Vec<Pose2>,
    /// The roadmap of the first leg's validating run.
    pub roadmap: RoadmapInfo,
    /// The laser as the attempts' traces read it, when [`PlanOptions::trace`] asked for them.
    pub laser: Option<LaserTrace>,
    /// The validated plan driven again among fresh draws of people, when
    /// [`PlanOptions::people_draws`] asked for it.
    pub people_draws: Option<DrawsReport>,
    /// The validating runs' poses at every control step, leg after leg, from the start at
    /// 0 s: pose `k` is where the simulated robot was at `k · control_period_s` (what a
    /// traffic schedule commits), whatever `trajectory_stride` thins `trajectory` to.
    pub steps: Vec<Pose2>,
    /// The control period of `steps`, seconds.
    pub control_period_s: f64,
}

impl PlanReport {
    /// The attempt (1-based, as [`AttemptReport::attempt`] numbers it) whose run validated
    /// `leg`; 1 for a leg the report holds no such run of.
    pub fn validating_attempt(&self, leg: usize) -> u32 {
        self.attempts
            .iter()
            .find(|a| a.leg == leg && a.outcome == AttemptOutcome::Reached)
            .map_or(1, |a| a.attempt)
    }

    /// Whether [`crate::drive_among`] with no other robot and no hold drives exactly
    /// [`PlanReport::steps`] again: it does when no validating run replanned (a drive among
    /// the fleet follows the waypoints reached, without replanning or re-routing).
    pub fn drives_again_alike(&self) -> bool {
        self.legs.iter().all(|l| l.replans == 0 && !l.rerouted)
    }
}

/// The validated plan driven again among fresh draws of people.
#[derive(Clone, Debug, PartialEq)]
pub struct DrawsReport {
    /// Draws driven.
    pub draws: u32,
    /// Of those, the draws in which every goal was reached.
    pub reached: u32,
    /// Draws that ended touching a person.
    pub hit_person: u32,
    /// Draws that came within [`crate::NEAR_MISS_M`] of a person without touching one.
    pub near_miss: u32,
    /// Closest approach of the footprint to a person over all draws, metres.
    pub min_person_clearance_m: Option<f64>,
    /// Why each failed draw failed, in draw order.
    pub failures: Vec<String>,
}

/// One leg of a validated plan: from the start (leg 0) or the previous goal to goal
/// `goal_index`.
#[derive(Clone, Debug, PartialEq)]
pub struct LegReport {
    /// The goal this leg ends at.
    pub goal_index: usize,
    /// The controller whose run validated the leg: the classical follower when the policy
    /// validated it in no attempt.
    pub controller: ControllerKind,
    /// Whether the fallback controller validated it (the primary, a policy or a classical
    /// controller other than the follower, validated it in no attempt). `controller` cannot
    /// say so when both are classical.
    pub by_fallback: bool,
    /// The roadmap the validating run planned on.
    pub roadmap: RoadmapKind,
    /// Attempts spent on the leg, every controller's, the validating one included.
    pub attempts: usize,
    /// Seed of the roadmap of the validating run.
    pub roadmap_seed: u64,
    /// Simulated time of the validating run, seconds.
    pub simulated_time_s: f64,
    /// Distance driven in the validating run, metres.
    pub distance_m: f64,
    /// Smallest footprint clearance in the validating run, metres.
    pub min_clearance_m: f64,
    /// Replans in the validating run.
    pub replans: u32,
    /// Whether the validating run re-routed around a blocked stretch (a recovery).
    pub rerouted: bool,
}

/// The roadmap a report planned on.
#[derive(Clone, Debug, PartialEq)]
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
    /// Geometric, or policy-aware (edges the policy was seen to drive).
    pub kind: RoadmapKind,
}

/// Which roadmap a run planned on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RoadmapKind {
    /// The PRM built from free space alone.
    Geometric,
    /// The geometric roadmap's edges the policy drove in the mental simulation, weighted by
    /// length and risk (PRM-RL).
    Policy,
}

impl RoadmapKind {
    /// `geometric` or `policy`.
    pub fn as_str(self) -> &'static str {
        match self {
            RoadmapKind::Geometric => "geometric",
            RoadmapKind::Policy => "policy",
        }
    }
}
