//! Request and report of a plan validation: the wire types of `POST /v1/plan` and of `validate`
//! jobs (serde, OpenAPI schemas). The executor (`rehearsal`) takes and returns its own core types
//! (`rehearsal::types`, over `sim::Pose2` and `prm::Point2`); they are converted here, on
//! purpose, field by field, and never exposed on the wire.

pub use super::ros::{
    RosHeader, RosPath, RosPoint, RosPose, RosPoseStamped, RosQuaternion, RosTime,
};
pub use super::schedule::{PlanAmongFleet, PlanSchedule, PlanWait};

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

impl From<prm::Point2> for Point {
    fn from(p: prm::Point2) -> Self {
        Self { x: p.x, y: p.y }
    }
}

impl From<Point> for prm::Point2 {
    fn from(p: Point) -> Self {
        prm::Point2::new(p.x, p.y)
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
    /// Simulated runs at most, each on a roadmap re-sampled with a new seed, 1-50 (default 5).
    #[schema(minimum = 1, maximum = 50)]
    pub max_attempts: u32,
    /// The waypoint timer of the paper's §4.2.2: simulated seconds to reach one waypoint before
    /// the planner replans from where the robot is, in (0, 600] (default 15). Among people,
    /// counted from the robot's last 0.5 m approach to the waypoint (Nav2's progress checker).
    #[schema(exclusive_minimum = 0, maximum = 600)]
    pub waypoint_timeout_s: f64,
    /// Replans allowed within one attempt before it counts as stalled, at most 1000
    /// (default 5).
    #[schema(maximum = 1000)]
    pub max_replans: u32,
    /// Remove detours from the roadmap path (each waypoint joined to the farthest one in
    /// straight sight). The paper's planner does not; default false.
    pub shortcut: bool,
    /// Clearance kept beyond the robot's radius when sampling the roadmap, metres, in [0, 5]
    /// (default 0.1).
    #[schema(minimum = 0, maximum = 5)]
    pub safety_margin_m: f64,
    /// PRM samples n, 1-10 000 000 (`prm::MAX_SAMPLES`); `null` for the paper's
    /// n* = ceil(0.05 · free area + 84) (Eq. 19).
    #[schema(minimum = 1, maximum = 10_000_000)]
    pub samples: Option<usize>,
    /// Seed of the roadmaps and the simulation: the same request gives the same report.
    pub seed: u64,
    /// Gaussian noise on observations and executed commands, as in training (default true).
    pub noise: bool,
    /// Keep every n-th pose of the simulated trajectory in the report (default 1: all; 0: none).
    pub trajectory_stride: u32,
    /// Which roadmap the policy plans on: `auto` (default: the policy-aware roadmap of this
    /// floor state and policy once it is built, else the geometric one; the report says which),
    /// `policy` (only the policy-aware one: 409 while it is being built, or when no kept edge
    /// joins a leg) or `geometric`.
    pub roadmap: RoadmapChoice,
    /// Answer every attempt's drive step by step (`attempts[].trace`: poses, the laser ranges
    /// the controller saw, the planned path; thinned by `trajectory_stride`) and the laser's
    /// beam angles (`laser`), to replay the rehearsal (default false).
    pub trace: bool,
    /// People walking about in the rehearsal: `auto` (default: as many as the knowledge
    /// expects on the floor, walking its routes and attractors; none where it says nothing),
    /// `none` (the empty building), or a number of people per 100 m² of free region, 0-50.
    /// Each attempt draws them afresh, so attempts are different draws of the same crowd.
    pub people: PeopleChoice,
    /// With `people`: `auto`, the hour of day (0-23, the building's local time) whose expected
    /// numbers to use where the knowledge has them by hour (places without count all day);
    /// `null` (default) for the all-day figures.
    #[schema(minimum = 0, maximum = 23)]
    pub people_hour: Option<u8>,
    /// Once validated, drive the plan's waypoints again among this many fresh draws of the
    /// people (each leg with the controller that validated it, without replanning), to say how
    /// robust it is across crowds (`people.draws`); 0-20, default 0. Ignored without people.
    #[schema(minimum = 0, maximum = 20)]
    pub people_draws: u32,
    /// The controller that drives the rehearsal: `auto` (default: Regulated Pure Pursuit,
    /// unless the floor state's trial measured another doing measurably better than it there;
    /// RPP until the robot's policy has been measured there), `hybrid` (the policy, the
    /// classical follower taking over near obstacles), `hybrid_rpp` (the policy, Regulated
    /// Pure Pursuit taking over), `hybrid_path` (the same, the policy steering to a carrot on
    /// the smoothed path instead of to each waypoint), `rpp` (Nav2's Regulated Pure Pursuit), `mppi` (Nav2's MPPI),
    /// `follower` (the thesis's rotate-then-go follower) or `shielded_follower`. The answer's
    /// `controller_choice` says which drove and why.
    pub controller: ControllerOption,
    /// Commit the plan to the floor's traffic schedule, replacing the robot's previous plan
    /// (default true); false only checks it against the other robots' committed plans.
    pub commit: bool,
    /// When the robot sets off, ms since the Unix epoch, up to 2100-01-01 [default: now].
    #[schema(minimum = 0, maximum = 4_102_444_800_000_i64)]
    pub start_time_ms: Option<i64>,
    /// How early or late the robot may be on its schedule, seconds, in [0, 3600] (default 2):
    /// other plans keep clear of it over that window.
    #[schema(minimum = 0, maximum = 3600)]
    pub tolerance_s: f64,
    /// Most waiting, in total, the plan may take to let other robots pass, seconds, in
    /// [0, 3600] (default 120); beyond it the answer is a 409 naming the robots in the way
    /// and the earliest start that fits.
    #[schema(minimum = 0, maximum = 3600)]
    pub max_wait_s: f64,
    /// How long the robot is held at its last goal after arriving, seconds, in [0, 3600]
    /// (default 30).
    #[schema(minimum = 0, maximum = 3600)]
    pub hold_s: f64,
}

/// A controller by name, or `auto`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ControllerOption {
    /// The one measured best on the floor state.
    #[default]
    Auto,
    /// The policy behind the shield, the classical follower taking over near obstacles.
    Hybrid,
    /// The policy behind the shield, Regulated Pure Pursuit taking over near obstacles.
    HybridRpp,
    /// The same with the policy steering to a carrot on the smoothed roadmap path.
    HybridPath,
    /// Nav2's Regulated Pure Pursuit on the smoothed roadmap path, behind the shield.
    Rpp,
    /// Nav2's MPPI on the smoothed roadmap path, behind the shield.
    Mppi,
    /// The thesis's rotate-then-go follower (behind the shield among people).
    Follower,
    /// The rotate-then-go follower behind the shield.
    ShieldedFollower,
}

impl ControllerOption {
    /// The controller asked for; `None` for `auto`.
    pub fn choice(self) -> Option<rehearsal::ControllerChoice> {
        use rehearsal::ControllerChoice as C;
        Some(match self {
            ControllerOption::Auto => return None,
            ControllerOption::Hybrid => C::Hybrid,
            ControllerOption::HybridRpp => C::HybridRpp,
            ControllerOption::HybridPath => C::HybridPath,
            ControllerOption::Rpp => C::Rpp,
            ControllerOption::Mppi => C::Mppi,
            ControllerOption::Follower => C::Follower,
            ControllerOption::ShieldedFollower => C::ShieldedFollower,
        })
    }
}

impl From<rehearsal::ControllerChoice> for ControllerOption {
    fn from(c: rehearsal::ControllerChoice) -> Self {
        use rehearsal::ControllerChoice as C;
        match c {
            C::Hybrid => ControllerOption::Hybrid,
            C::HybridRpp => ControllerOption::HybridRpp,
            C::HybridPath => ControllerOption::HybridPath,
            C::Rpp => ControllerOption::Rpp,
            C::Mppi => ControllerOption::Mppi,
            C::Follower => ControllerOption::Follower,
            C::ShieldedFollower => ControllerOption::ShieldedFollower,
        }
    }
}

/// The controller that validated a plan, and why it was the one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ControllerChoiceReport {
    /// The controller (never `auto`; legs its fallback validated say so in `legs`).
    pub controller: ControllerOption,
    /// What `auto` measured the controller against on this floor state (Regulated Pure
    /// Pursuit, unless the robot cannot run it); absent when the controller was asked for or
    /// nothing was measured.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compared_with: Option<ControllerOption>,
    /// Why: asked for, or `auto`'s figures and verdict on this floor state.
    pub why: String,
}

impl From<planner::ControllerPick> for ControllerChoiceReport {
    fn from(p: planner::ControllerPick) -> Self {
        Self {
            controller: p.choice.into(),
            compared_with: p.compared_with.map(Into::into),
            why: p.why,
        }
    }
}

/// Who walks about in a rehearsal: `"auto"`, `"none"` or people per 100 m² of free region.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(untagged, try_from = "serde_json::Value")]
pub enum PeopleChoice {
    /// `auto` or `none`.
    Named(PeopleMode),
    /// People per 100 m² of the floor's free region, 0-50.
    Density(f64),
}

/// `auto`: the knowledge's expected people; `none`: nobody.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum PeopleMode {
    /// As many as the knowledge expects.
    Auto,
    /// Nobody.
    None,
}

impl Default for PeopleChoice {
    fn default() -> Self {
        PeopleChoice::Named(PeopleMode::Auto)
    }
}

/// Densest crowd a rehearsal takes, people per 100 m².
pub const MAX_PEOPLE_DENSITY: f64 = 50.0;

impl TryFrom<serde_json::Value> for PeopleChoice {
    type Error = String;

    fn try_from(v: serde_json::Value) -> Result<Self, String> {
        match &v {
            serde_json::Value::String(s) if s == "auto" => {
                Ok(PeopleChoice::Named(PeopleMode::Auto))
            }
            serde_json::Value::String(s) if s == "none" => {
                Ok(PeopleChoice::Named(PeopleMode::None))
            }
            serde_json::Value::Number(n) => match n.as_f64() {
                Some(d) if (0.0..=MAX_PEOPLE_DENSITY).contains(&d) => Ok(PeopleChoice::Density(d)),
                _ => Err(format!(
                    "`people` as a density must lie in [0, {MAX_PEOPLE_DENSITY}] people per 100 m², got {n}"
                )),
            },
            other => Err(format!(
                "`people` is `auto`, `none` or a number of people per 100 m², got {other}"
            )),
        }
    }
}

impl PlanOptions {
    /// How the plan takes part in the floor's traffic schedule.
    pub fn fleet(&self) -> planner::FleetOptions {
        planner::FleetOptions {
            commit: self.commit,
            start_unix_ms: self.start_time_ms,
            tolerance_s: self.tolerance_s,
            max_wait_s: self.max_wait_s,
            hold_s: self.hold_s,
            ..planner::FleetOptions::default()
        }
    }
}

impl PeopleChoice {
    /// The simulation's people for an explicit choice; `auto` and `none` give nobody (the plan
    /// handler resolves `auto` from the floor's knowledge).
    pub fn config(self) -> sim::PeopleConfig {
        match self {
            PeopleChoice::Density(d) => sim::PeopleConfig {
                density: d,
                ..sim::PeopleConfig::default()
            },
            PeopleChoice::Named(_) => sim::PeopleConfig::default(),
        }
    }
}

/// Who walked about in a plan's rehearsal, and how the plan fared among them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PeopleReport {
    /// `knowledge` (`options.people`: `auto`) or `density`.
    pub source: String,
    /// People drawn in each attempt.
    pub people: usize,
    /// Closest approach of the footprint to a person in the validating runs, metres.
    pub min_person_clearance_m: Option<f64>,
    /// Attempts run, each with its own draw of people.
    pub attempts: usize,
    /// Of those, the attempts whose drive reached its leg's goal: how robust the plan was
    /// across draws.
    pub attempts_reached: usize,
    /// Attempts that ended touching a person.
    pub attempts_hit_person: usize,
    /// Attempts that came within 10 cm of a person without touching one (near misses).
    pub attempts_near_miss: usize,
    /// The validated plan driven again among fresh draws of the people, with
    /// `options.people_draws`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub draws: Option<PeopleDraws>,
}

/// The validated plan driven again among fresh draws of the people.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PeopleDraws {
    /// Draws driven.
    pub draws: u32,
    /// Of those, the draws in which every goal was reached.
    pub reached: u32,
    /// Draws that ended touching a person.
    pub hit_person: u32,
    /// Draws that came within 10 cm of a person without touching one.
    pub near_miss: u32,
    /// Closest approach of the footprint to a person over all draws, metres.
    pub min_person_clearance_m: Option<f64>,
    /// Why each failed draw failed (`draw K, leg L: …`), in draw order.
    pub failures: Vec<String>,
}

impl From<rehearsal::DrawsReport> for PeopleDraws {
    fn from(d: rehearsal::DrawsReport) -> Self {
        let rehearsal::DrawsReport {
            draws,
            reached,
            hit_person,
            near_miss,
            min_person_clearance_m,
            failures,
        } = d;
        Self {
            draws,
            reached,
            hit_person,
            near_miss,
            min_person_clearance_m,
            failures,
        }
    }
}

/// Which roadmap the policy plans on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum RoadmapChoice {
    /// The policy-aware roadmap when it exists, else the geometric one.
    #[default]
    Auto,
    /// Only the policy-aware roadmap.
    Policy,
    /// Only the geometric roadmap.
    Geometric,
}

impl From<RoadmapChoice> for rehearsal::RoadmapChoice {
    fn from(c: RoadmapChoice) -> Self {
        match c {
            RoadmapChoice::Auto => rehearsal::RoadmapChoice::Auto,
            RoadmapChoice::Policy => rehearsal::RoadmapChoice::Policy,
            RoadmapChoice::Geometric => rehearsal::RoadmapChoice::Geometric,
        }
    }
}

impl From<rehearsal::RoadmapChoice> for RoadmapChoice {
    fn from(c: rehearsal::RoadmapChoice) -> Self {
        match c {
            rehearsal::RoadmapChoice::Auto => RoadmapChoice::Auto,
            rehearsal::RoadmapChoice::Policy => RoadmapChoice::Policy,
            rehearsal::RoadmapChoice::Geometric => RoadmapChoice::Geometric,
        }
    }
}

impl Default for PlanOptions {
    /// The executor's defaults.
    fn default() -> Self {
        rehearsal::PlanOptions::default().into()
    }
}

impl From<rehearsal::PlanOptions> for PlanOptions {
    fn from(o: rehearsal::PlanOptions) -> Self {
        let fleet = planner::FleetOptions::default();
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
            roadmap,
            trace,
            people,
            people_draws,
            // The fleet's standing robots and plans are the planner's to read from the schedule.
            standing: _,
            standing_pass_m: _,
            reserved: _,
            roadmap_salt: _,
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
            roadmap: roadmap.into(),
            trace,
            people_hour: None,
            people_draws,
            controller: ControllerOption::Auto,
            commit: fleet.commit,
            start_time_ms: fleet.start_unix_ms,
            tolerance_s: fleet.tolerance_s,
            max_wait_s: fleet.max_wait_s,
            hold_s: fleet.hold_s,
            // Nobody by the executor's default is the API's `auto` (the knowledge's people).
            people: if people.any() {
                PeopleChoice::Density(people.density)
            } else {
                PeopleChoice::default()
            },
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
            roadmap,
            trace,
            people,
            people_hour: _,
            people_draws,
            controller: _,
            commit: _,
            start_time_ms: _,
            tolerance_s: _,
            max_wait_s: _,
            hold_s: _,
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
            roadmap: roadmap.into(),
            trace,
            people: people.config(),
            people_draws,
            standing: Vec::new(),
            standing_pass_m: f64::INFINITY,
            reserved: None,
            roadmap_salt: 0,
        }
    }
}

/// [`PlanApiRequest`](super::PlanApiRequest) as the OpenAPI document describes it: one of its
/// two forms, `goal` or `goals`. Documentation only: the handler reads
/// [`PlanApiRequest`](super::PlanApiRequest), whose fields these repeat (keep them in step),
/// and answers 400 to a request with neither or both.
#[derive(ToSchema)]
#[serde(untagged)]
#[schema(
    as = PlanApiRequest,
    description = "What a robot asks: its pose on a floor, and one goal (`goal`) or a non-empty sequence of goals (`goals`, at most 1000), never both."
)]
#[allow(
    dead_code,
    reason = "documentation only: the handler reads `PlanApiRequest`"
)]
pub enum PlanApiRequestDoc {
    /// One goal.
    #[serde(deny_unknown_fields)]
    Goal {
        /// The robot: identifier or IRI.
        robot: String,
        /// Where the robot is: its floor, or a place on that floor (identifier or IRI).
        place: String,
        /// The robot's pose on that floor (map frame).
        start: Pose,
        /// The goal.
        goal: Point,
        /// Validation settings.
        #[serde(default)]
        options: PlanOptions,
        /// The policy to drive with [default: the robot's newest trained policy].
        policy: Option<String>,
    },
    /// Goals visited in order.
    #[serde(deny_unknown_fields)]
    Goals {
        /// The robot: identifier or IRI.
        robot: String,
        /// Where the robot is: its floor, or a place on that floor (identifier or IRI).
        place: String,
        /// The robot's pose on that floor (map frame).
        start: Pose,
        /// The goals, visited in order: 1-1000 (`rehearsal::MAX_GOALS`).
        #[schema(min_items = 1, max_items = 1000)]
        goals: Vec<Point>,
        /// Validation settings.
        #[serde(default)]
        options: PlanOptions,
        /// The policy to drive with [default: the robot's newest trained policy].
        policy: Option<String>,
    },
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
    pub end_pose: Pose,
    /// Share of the attempt's control steps that the classical follower drove inside the
    /// policy controller: it takes over to the next waypoint where the policy would come within
    /// 0.3 m of what the laser sees. 0 for the follower's own attempts.
    #[serde(default)]
    #[schema(minimum = 0.0, maximum = 1.0)]
    pub handover_share: f64,
    /// Closest approach of the footprint to a person in this attempt, metres; absent without
    /// people in the rehearsal.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_person_clearance_m: Option<f64>,
    /// The drive step by step, with `options.trace`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trace: Option<AttemptTrace>,
}

/// One attempt's drive step by step (every `trajectory_stride`-th step, and the last).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct AttemptTrace {
    /// The roadmap path planned at the start of the attempt: its waypoints.
    pub path: Vec<Point>,
    /// Simulated time of each recorded step, seconds.
    pub times_s: Vec<f64>,
    /// The robot's pose at each recorded step.
    pub poses: Vec<Pose>,
    /// The laser ranges the controller saw at each recorded step (with the simulation's
    /// noise), metres, in the order of `laser.angles_rad`.
    pub ranges: Vec<Vec<f32>>,
}

impl From<rehearsal::AttemptTrace> for AttemptTrace {
    fn from(t: rehearsal::AttemptTrace) -> Self {
        Self {
            path: t.path.into_iter().map(Into::into).collect(),
            times_s: t.times_s,
            poses: t.poses.into_iter().map(Into::into).collect(),
            ranges: t.ranges,
        }
    }
}

/// The laser as the traces' ranges read it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct LaserTrace {
    /// Angle of each beam in the robot frame, radians (counter-clockwise, 0 ahead).
    pub angles_rad: Vec<f64>,
    /// Longest range, metres: a beam that hits nothing reads it.
    pub max_range_m: f64,
    /// Simulated seconds per step.
    pub control_period_s: f64,
}

impl From<rehearsal::LaserTrace> for LaserTrace {
    fn from(l: rehearsal::LaserTrace) -> Self {
        Self {
            angles_rad: l.angles_rad,
            max_range_m: l.max_range_m,
            control_period_s: l.control_period_s,
        }
    }
}

impl From<rehearsal::AttemptReport> for AttemptReport {
    fn from(a: rehearsal::AttemptReport) -> Self {
        let rehearsal::AttemptReport {
            attempt,
            leg,
            controller,
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
            handover_share,
            min_person_clearance_m,
            trace,
        } = a;
        Self {
            attempt,
            leg,
            controller: controller.into(),
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
            handover_share,
            min_person_clearance_m,
            trace: trace.map(Into::into),
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
    /// The controller the plan was asked of: the policy when the robot has one. Each leg says
    /// which controller validated it (`legs`).
    pub controller: ControllerKind,
    /// What that controller is (a policy's training summary or the follower's rule).
    pub controller_description: String,
    /// Each leg as validated, in order: with the policy, or with the classical follower where
    /// no attempt with the policy validated it (a plan is never worse than the follower's).
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
    pub trajectory: Vec<Pose>,
    /// The roadmap of the first leg's validating run.
    pub roadmap: RoadmapInfo,
    /// The laser as `attempts[].trace` reads it, with `options.trace`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub laser: Option<LaserTrace>,
    /// Who walked about in the rehearsal; absent when nobody did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub people: Option<PeopleReport>,
}

impl From<rehearsal::PlanReport> for PlanReport {
    fn from(r: rehearsal::PlanReport) -> Self {
        let rehearsal::PlanReport {
            waypoints,
            goal_indices,
            controller,
            controller_description,
            legs,
            attempts,
            simulated_time_s,
            distance_m,
            min_clearance_m,
            prm_path_length_m,
            waypoint_path_length_m,
            replans,
            trajectory,
            roadmap,
            laser,
            people_draws: _,
            steps: _,
            control_period_s: _,
        } = r;
        Self {
            waypoints: waypoints.into_iter().map(Into::into).collect(),
            goal_indices,
            controller: controller.into(),
            controller_description,
            legs: legs.into_iter().map(Into::into).collect(),
            attempts: attempts.into_iter().map(Into::into).collect(),
            simulated_time_s,
            distance_m,
            min_clearance_m,
            prm_path_length_m,
            waypoint_path_length_m,
            replans,
            trajectory: trajectory.into_iter().map(Into::into).collect(),
            roadmap: roadmap.into(),
            laser: laser.map(Into::into),
            people: None,
        }
    }
}

/// One leg of a validated plan: from the start (leg 0) or the previous goal to goal
/// `goal_index`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct LegReport {
    /// The goal this leg ends at.
    pub goal_index: usize,
    /// The controller whose run validated the leg: `classical` when the policy validated it in
    /// no attempt.
    pub controller: ControllerKind,
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
}

impl From<rehearsal::LegReport> for LegReport {
    fn from(l: rehearsal::LegReport) -> Self {
        let rehearsal::LegReport {
            goal_index,
            controller,
            by_fallback: _,
            roadmap,
            attempts,
            roadmap_seed,
            simulated_time_s,
            distance_m,
            min_clearance_m,
            replans,
            rerouted: _,
        } = l;
        Self {
            goal_index,
            controller: controller.into(),
            roadmap: roadmap.into(),
            attempts,
            roadmap_seed,
            simulated_time_s,
            distance_m,
            min_clearance_m,
            replans,
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
    /// `geometric`, or `policy` (edges the policy was seen to drive).
    pub kind: RoadmapKind,
}

/// Which roadmap a run planned on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum RoadmapKind {
    /// The PRM built from free space alone.
    Geometric,
    /// The geometric roadmap's edges the policy drove in the mental simulation, weighted by
    /// length and risk (PRM-RL).
    Policy,
}

impl From<rehearsal::RoadmapKind> for RoadmapKind {
    fn from(k: rehearsal::RoadmapKind) -> Self {
        match k {
            rehearsal::RoadmapKind::Geometric => RoadmapKind::Geometric,
            rehearsal::RoadmapKind::Policy => RoadmapKind::Policy,
        }
    }
}

impl From<rehearsal::RoadmapInfo> for RoadmapInfo {
    fn from(r: rehearsal::RoadmapInfo) -> Self {
        let rehearsal::RoadmapInfo {
            samples,
            nodes,
            seed,
            inflation_m,
            cached,
            kind,
        } = r;
        Self {
            samples,
            nodes,
            seed,
            inflation_m,
            cached,
            kind: kind.into(),
        }
    }
}
