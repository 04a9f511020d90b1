//! Nav2's classical controllers in the rehearsal, the baselines a learnt policy must beat:
//! Regulated Pure Pursuit ([`RppController`]) and MPPI ([`MppiController`]), each following the
//! roadmap path smoothed as Nav2's Simple Smoother smooths a planner's path
//! ([`sim::smoother`]), passing through the roadmap's vertices without stopping, and each behind
//! the same collision shield as the policy and the shielded follower (what a Nav2 robot with
//! its collision monitor does). Their algorithms and parameters are in [`sim::rpp`] and
//! [`sim::mppi`]; every parameter is Nav2's documented default scaled to the robot.
//!
//! [`ControllerChoice`] names every controller a rehearsal can drive with, so a planner (or a
//! benchmark) picks one from a plain value.

use std::sync::Arc;
use std::time::Instant;

use grid::seed::mix;
use learning::Policy;
use prm::Point2;
use sim::{
    Action, Mppi, MppiParams, MppiWorld, Observation, PathTrack, Pose2, RppParams, SmootherParams,
    World,
};

use crate::controller::{
    ClassicalFollower, Controller, PolicyController, Shield, ShieldedFollower, observe,
    shield_description,
};
use crate::types::ControllerKind;

/// Goal tolerance of the path trackers, metres (Nav2's `SimpleGoalChecker`
/// `xy_goal_tolerance`, default 0.25).
pub const NAV2_GOAL_TOLERANCE_M: f64 = 0.25;

/// Nav2's velocity smoother between a controller and the collision monitor
/// (`nav2_velocity_smoother`, open loop): each command moves at most `max_accel` (speeding up)
/// or `max_decel` (slowing down) times the period from the last one sent. As a Nav2 robot is
/// configured, those are the robot's own limits ([`VelocitySmoother::for_drive`]: its model's
/// acceleration and deceleration), and Nav2's defaults (`max_accel: [2.5, 0.0, 3.2]`,
/// `max_decel: [-2.5, 0.0, -3.2]`) where the model gives none. Without it a controller whose
/// look-ahead follows the measured speed (RPP) flips between short and long look-aheads from
/// one cycle to the next.
#[derive(Clone, Copy, Debug, PartialEq)]
struct VelocitySmoother {
    last: Action,
    /// `max_accel` (linear, angular), m/s² and rad/s².
    max_accel: (f64, f64),
    /// `max_decel` (linear, angular), as magnitudes.
    max_decel: (f64, f64),
}

/// Nav2 velocity smoother default: linear acceleration limit, m/s².
const MAX_ACCEL_LINEAR: f64 = 2.5;
/// Nav2 velocity smoother default: angular acceleration limit, rad/s².
const MAX_ACCEL_ANGULAR: f64 = 3.2;
/// The rehearsal's control period, seconds.
const DT: f64 = 0.1;

impl Default for VelocitySmoother {
    fn default() -> Self {
        Self {
            last: Action::default(),
            max_accel: (MAX_ACCEL_LINEAR, MAX_ACCEL_ANGULAR),
            max_decel: (MAX_ACCEL_LINEAR, MAX_ACCEL_ANGULAR),
        }
    }
}

impl VelocitySmoother {
    /// The smoother configured with the robot model's limits (Nav2's defaults where it has
    /// none).
    fn for_drive(drive: &sim::spec::DiffDriveSpec) -> Self {
        let linear = drive.max_linear_acceleration.unwrap_or(MAX_ACCEL_LINEAR);
        let angular = drive.max_angular_acceleration.unwrap_or(MAX_ACCEL_ANGULAR);
        Self {
            last: Action::default(),
            max_accel: (linear, angular),
            max_decel: (
                drive.max_linear_deceleration.unwrap_or(linear),
                drive.max_angular_deceleration.unwrap_or(angular),
            ),
        }
    }

    fn smooth(&self, wanted: Action) -> Action {
        let limit = |last: f64, want: f64, accel: f64, decel: f64| {
            let speeding_up =
                want.abs() > last.abs() && (last == 0.0 || want.signum() == last.signum());
            let step = if speeding_up { accel } else { decel } * DT;
            want.clamp(last - step, last + step)
        };
        Action::new(
            limit(
                self.last.linear,
                wanted.linear,
                self.max_accel.0,
                self.max_decel.0,
            ),
            limit(
                self.last.angular,
                wanted.angular,
                self.max_accel.1,
                self.max_decel.1,
            ),
        )
    }

    /// Forgets the last command (a new drive), keeping the limits.
    fn reset(&mut self) {
        self.last = Action::default();
    }
}

/// A laser return farther than this from everything the map knows is something the map does
/// not know (a person), metres: as the shield tells them apart.
const UNKNOWN_M: f64 = 0.15;

/// The roadmap path as a path tracker follows it: smoothed and dense, with the point of the
/// smoothed path that stands for each roadmap waypoint.
#[derive(Clone, Debug, Default)]
struct SmoothedPath {
    track: PathTrack,
    /// Each waypoint of the path and the index of its point on the smoothed path.
    marks: Vec<(Point2, usize)>,
}

impl SmoothedPath {
    /// The path from `pose` through `path`, smoothed in `world`.
    fn new(world: &World, pose: Pose2, path: &[Point2], smoother: &SmootherParams) -> Self {
        let mut raw = vec![(pose.x, pose.y)];
        raw.extend(path.iter().map(|p| (p.x, p.y)));
        let smooth = sim::smooth_path(world, &raw, smoother);
        let track = PathTrack::new(smooth);
        // Each waypoint's point: the nearest one after the previous waypoint's.
        let mut marks = Vec::with_capacity(path.len());
        let mut from = 0;
        for w in path {
            let rest = track.window(from, usize::MAX);
            let i = from
                + rest
                    .iter()
                    .enumerate()
                    .min_by(|a, b| {
                        // Squared distances: the same order, without a root per point of the
                        // rest of the path for every waypoint.
                        let d2 = |p: &(f64, f64)| (p.0 - w.x).powi(2) + (p.1 - w.y).powi(2);
                        d2(a.1).total_cmp(&d2(b.1))
                    })
                    .map_or(0, |(i, _)| i);
            marks.push((*w, i));
            from = i;
        }
        Self { track, marks }
    }

    /// Whether the robot's progress along the path has reached `waypoint`'s point.
    fn passed(&self, waypoint: Point2) -> bool {
        self.marks
            .iter()
            .find(|(w, _)| w.x == waypoint.x && w.y == waypoint.y)
            .is_some_and(|&(_, i)| self.track.progress() >= i)
    }
}

/// Where the laser's beams point, in the robot frame, to turn returns into points.
#[derive(Clone, Debug)]
struct Laser {
    origin: (f64, f64),
    dirs: Vec<(f64, f64)>,
    range_max: f64,
}

impl Laser {
    fn new(world: &World, beams: usize) -> Option<Self> {
        let laser = &world.spec().robot.laser;
        let dirs = laser
            .beam_angles(beams)?
            .into_iter()
            .map(|a| ((a + laser.mount.yaw).cos(), (a + laser.mount.yaw).sin()))
            .collect();
        Some(Self {
            origin: (laser.mount.x, laser.mount.y),
            dirs,
            range_max: laser.range_max,
        })
    }

    /// The returns of `obs` in the robot frame.
    fn returns<'a>(&'a self, obs: &'a Observation) -> impl Iterator<Item = (f64, f64)> + 'a {
        obs.ranges
            .iter()
            .zip(&self.dirs)
            .filter(|(r, _)| f64::from(**r) < self.range_max - 1e-3)
            .map(|(r, (c, s))| {
                let r = f64::from(*r);
                (self.origin.0 + r * c, self.origin.1 + r * s)
            })
    }

    /// Distance from the robot's centre to the nearest return of `obs`, metres (infinite for
    /// none).
    fn nearest(&self, obs: &Observation) -> f64 {
        self.returns(obs)
            .map(|p| sim::norm(p.0, p.1))
            .fold(f64::INFINITY, f64::min)
    }

    /// The returns of `obs` for a robot at `pose`, in the world frame.
    fn world_returns<'a>(
        &'a self,
        obs: &'a Observation,
        pose: Pose2,
    ) -> impl Iterator<Item = (f64, f64)> + 'a {
        let (s, c) = pose.yaw.sin_cos();
        self.returns(obs)
            .map(move |(x, y)| (pose.x + c * x - s * y, pose.y + s * x + c * y))
    }
}

/// What both path trackers share: the map, the shield, the laser and the smoothed path.
#[derive(Clone, Debug, Default)]
struct Tracker {
    smoother: SmootherParams,
    world: Option<Arc<World>>,
    shield: Option<Shield>,
    laser: Option<Laser>,
    path: Option<SmoothedPath>,
    /// Whether the shield filters the commands.
    shielded: bool,
    smoother_out: VelocitySmoother,
}

impl Tracker {
    fn new(shielded: bool) -> Self {
        Self {
            shielded,
            ..Self::default()
        }
    }

    fn attach(&mut self, world: &Arc<World>, beams: usize) {
        self.shield = if self.shielded {
            Shield::new(world, beams)
        } else {
            None
        };
        self.laser = Laser::new(world, beams);
        self.smoother_out = VelocitySmoother::for_drive(&world.spec().robot.drive);
        self.world = Some(Arc::clone(world));
    }

    fn start_path(&mut self, pose: Pose2, path: &[Point2]) {
        if let Some(world) = &self.world {
            self.path = Some(SmoothedPath::new(world, pose, path, &self.smoother));
        }
    }

    /// The path, made from `pose` to `waypoint` when the executor gave none.
    fn ensure_path(&mut self, pose: Pose2, waypoint: (f64, f64)) {
        let stale = self.path.as_ref().is_none_or(|p| {
            p.track.end().is_none_or(|e| {
                e != waypoint && !p.marks.iter().any(|(w, _)| (w.x, w.y) == waypoint)
            })
        });
        if stale {
            self.start_path(pose, &[Point2::new(waypoint.0, waypoint.1)]);
        }
    }

    fn observe(&mut self, obs: &Observation, pose: Pose2) {
        if let Some(shield) = &mut self.shield {
            observe(shield, obs, pose, self.world.as_deref());
        }
    }

    /// `wanted` through the velocity smoother, then the shield.
    fn filter(&mut self, wanted: Action, obs: &Observation, angular_max: f64) -> Action {
        let smooth = self.smoother_out.smooth(wanted);
        let sent = match &self.shield {
            Some(s) => s.filter(smooth, obs, angular_max),
            None => smooth,
        };
        self.smoother_out.last = sent;
        sent
    }

    fn passed(&self, waypoint: Point2) -> bool {
        self.path.as_ref().is_some_and(|p| p.passed(waypoint))
    }

    fn reset(&mut self) {
        self.path = None;
        self.smoother_out.reset();
        if let Some(s) = &mut self.shield {
            s.reset_motion();
        }
    }

    fn radius(&self) -> f64 {
        self.world
            .as_ref()
            .map_or(0.3, |w| w.spec().robot.footprint_radius)
    }
}

/// Regulated Pure Pursuit on the smoothed roadmap path behind the collision shield
/// ([`sim::rpp`]): what a Nav2 robot with RPP and the collision monitor drives. Proximity
/// regulation measures the nearest obstacle from the map and from the laser (people).
#[derive(Clone, Debug)]
pub struct RppController {
    params: RppParams,
    tracker: Tracker,
}

impl Default for RppController {
    fn default() -> Self {
        Self::new()
    }
}

impl RppController {
    /// RPP with Nav2's defaults for the paper's robot, behind the shield.
    pub fn new() -> Self {
        Self {
            params: RppParams::default(),
            tracker: Tracker::new(true),
        }
    }

    /// RPP with its commands sent unchanged (for a controller that filters them itself).
    pub fn without_shield() -> Self {
        Self {
            tracker: Tracker::new(false),
            ..Self::new()
        }
    }

    /// The point `lookahead_m` ahead of the robot's progress on the smoothed path (its end
    /// when nearer), once a path is known.
    pub fn carrot(&self, pose: Pose2, lookahead_m: f64) -> Option<(f64, f64)> {
        self.tracker.path.as_ref()?.track.carrot(pose, lookahead_m)
    }

    /// RPP's own command, before any shield.
    pub fn wanted(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        self.tracker.ensure_path(pose, waypoint);
        let centre_to_obstacle = {
            let map = self.tracker.world.as_ref().map_or(f64::INFINITY, |w| {
                w.clearance(pose.x, pose.y) + self.tracker.radius()
            });
            let seen = self
                .tracker
                .laser
                .as_ref()
                .map_or(f64::INFINITY, |l| l.nearest(obs));
            map.min(seen)
        };
        let speed = f64::from(obs.velocity[0]);
        let Some(path) = &mut self.tracker.path else {
            return Action::default();
        };
        sim::rpp_step(
            &self.params,
            &mut path.track,
            pose,
            speed,
            centre_to_obstacle,
        )
        .map_or_else(Action::default, |s| s.action)
    }
}

impl Controller for RppController {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        self.tracker.observe(obs, pose);
        let wanted = self.wanted(obs, pose, waypoint);
        self.tracker.filter(wanted, obs, self.params.angular_max)
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::Classical
    }

    fn description(&self) -> String {
        let p = &self.params;
        let mut s = format!(
            "Nav2 Regulated Pure Pursuit on the roadmap path smoothed as Nav2's Simple Smoother does (look-ahead {:.2} s of speed within [{}, {}] m, up to {} m/s, curvature regulation below {} m radius, proximity regulation within {:.2} m of the robot's centre, turning on the spot beyond {} rad, passing through the roadmap's vertices)",
            p.lookahead_time,
            p.min_lookahead_dist,
            p.max_lookahead_dist,
            p.desired_linear_vel,
            p.regulated_linear_scaling_min_radius,
            p.cost_scaling_dist,
            p.rotate_to_heading_min_angle
        );
        if self.tracker.shielded {
            s.push_str(&format!(", behind {}", shield_description()));
        }
        s
    }

    fn goal_tolerance(&self) -> Option<f64> {
        Some(NAV2_GOAL_TOLERANCE_M)
    }

    fn start_attempt(&mut self, _attempt: u32) {
        self.tracker.reset();
    }

    fn attach(&mut self, world: &Arc<World>, beams: usize) {
        let r = world.spec().robot.footprint_radius;
        let lim = crate::executor::command_limits(world);
        self.params = RppParams::for_robot(r, lim.linear_max, lim.angular_max);
        self.tracker.attach(world, beams);
    }

    fn start_path(&mut self, pose: Pose2, path: &[Point2]) {
        self.tracker.start_path(pose, path);
    }

    fn passed(&self, _pose: Pose2, waypoint: Point2) -> bool {
        self.tracker.passed(waypoint)
    }

    fn short_stops(&self) -> u32 {
        self.tracker
            .shield
            .as_ref()
            .map_or(0, Shield::could_not_stop)
    }
}

/// Wall time MPPI spent per control cycle, and the cost of its optimal rollouts.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MppiCycles {
    /// Control cycles.
    pub cycles: u64,
    /// Wall time over all cycles, seconds.
    pub total_s: f64,
    /// Longest cycle, seconds.
    pub max_s: f64,
    /// Sum of the optimal rollout's critic cost over all cycles.
    pub cost_sum: f64,
    /// Rollouts per cycle.
    pub batch_size: usize,
    /// Steps per rollout.
    pub time_steps: usize,
}

impl MppiCycles {
    /// Mean wall time per cycle, milliseconds (0 without cycles).
    pub fn mean_ms(&self) -> f64 {
        if self.cycles == 0 {
            0.0
        } else {
            1e3 * self.total_s / self.cycles as f64
        }
    }

    /// Mean optimal-rollout cost per cycle (0 without cycles).
    pub fn mean_cost(&self) -> f64 {
        if self.cycles == 0 {
            0.0
        } else {
            self.cost_sum / self.cycles as f64
        }
    }

    /// Both together.
    pub fn plus(self, o: MppiCycles) -> MppiCycles {
        MppiCycles {
            cycles: self.cycles + o.cycles,
            total_s: self.total_s + o.total_s,
            max_s: self.max_s.max(o.max_s),
            cost_sum: self.cost_sum + o.cost_sum,
            batch_size: self.batch_size.max(o.batch_size),
            time_steps: self.time_steps.max(o.time_steps),
        }
    }
}

/// MPPI on the smoothed roadmap path behind the collision shield ([`sim::mppi`]): what a Nav2
/// robot with MPPI and the collision monitor drives. Its costmap is the simulation's map (the
/// footprint clearance it knows) and the laser's returns the map does not explain (people).
#[derive(Clone, Debug)]
pub struct MppiController {
    mppi: Mppi,
    tracker: Tracker,
    seed: u64,
    cycles: MppiCycles,
    /// Whether its parameters are Nav2's defaults scaled to the robot it is attached to
    /// ([`MppiController::new`]) rather than given ([`MppiController::with_params`]).
    scaled: bool,
}

impl Default for MppiController {
    fn default() -> Self {
        Self::new(0)
    }
}

impl MppiController {
    /// MPPI with Nav2's defaults for the paper's robot at the simulator's control period, its
    /// sampling seeded with `seed` (and the attempt), behind the shield.
    pub fn new(seed: u64) -> Self {
        Self {
            scaled: true,
            ..Self::with_params(MppiParams::default(), seed)
        }
    }

    /// MPPI with `params`.
    pub fn with_params(params: MppiParams, seed: u64) -> Self {
        Self {
            mppi: Mppi::new(params, seed),
            tracker: Tracker::new(true),
            seed,
            cycles: MppiCycles {
                batch_size: params.batch_size,
                time_steps: params.time_steps,
                ..MppiCycles::default()
            },
            scaled: false,
        }
    }

    /// Wall time per control cycle and the optimal rollouts' cost so far.
    pub fn cycles(&self) -> MppiCycles {
        self.cycles
    }
}

impl Controller for MppiController {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        self.tracker.observe(obs, pose);
        self.tracker.ensure_path(pose, waypoint);
        let (Some(world), Some(path)) = (self.tracker.world.clone(), &mut self.tracker.path) else {
            return Action::default();
        };
        let radius = world.spec().robot.footprint_radius;
        let unknown: Vec<(f64, f64)> = self
            .tracker
            .laser
            .as_ref()
            .map(|l| {
                l.world_returns(obs, pose)
                    .filter(|p| !world.knows_within(p.0, p.1, UNKNOWN_M))
                    .collect()
            })
            .unwrap_or_default();
        let clearance = |x: f64, y: f64| world.clearance(x, y);
        let view = MppiWorld {
            clearance: &clearance,
            unknown: &unknown,
            radius,
        };
        let t = Instant::now();
        let wanted = self.mppi.command(pose, &mut path.track, &view);
        let took = t.elapsed().as_secs_f64();
        self.cycles.cycles += 1;
        self.cycles.total_s += took;
        self.cycles.max_s = self.cycles.max_s.max(took);
        self.cycles.cost_sum += self.mppi.last_cost();
        self.tracker.filter(wanted, obs, self.mppi.params().wz_max)
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::Classical
    }

    fn description(&self) -> String {
        let p = self.mppi.params();
        let mut s = format!(
            "Nav2 MPPI on the roadmap path smoothed as Nav2's Simple Smoother does ({} rollouts of {} steps of {} s per cycle, noise {:.2} m/s and {:.2} rad/s, temperature {}, critics obstacles, path align, path follow, path angle, goal and prefer forward at Nav2's default weights; speeds {}..{} m/s, {} rad/s)",
            p.batch_size,
            p.time_steps,
            p.model_dt,
            p.vx_std,
            p.wz_std,
            p.temperature,
            p.vx_min,
            p.vx_max,
            p.wz_max
        );
        if self.tracker.shielded {
            s.push_str(&format!(", behind {}", shield_description()));
        }
        s
    }

    fn goal_tolerance(&self) -> Option<f64> {
        Some(NAV2_GOAL_TOLERANCE_M)
    }

    fn start_attempt(&mut self, attempt: u32) {
        self.tracker.reset();
        self.mppi.reset(mix(self.seed, u64::from(attempt)));
    }

    fn attach(&mut self, world: &Arc<World>, beams: usize) {
        if self.scaled {
            let lim = crate::executor::command_limits(world);
            let params = MppiParams::for_robot(lim.linear_max, lim.angular_max, DT);
            if params != MppiParams::default() {
                self.mppi = Mppi::new(params, self.seed);
            }
        }
        self.tracker.attach(world, beams);
    }

    fn start_path(&mut self, pose: Pose2, path: &[Point2]) {
        self.tracker.start_path(pose, path);
    }

    fn passed(&self, _pose: Pose2, waypoint: Point2) -> bool {
        self.tracker.passed(waypoint)
    }

    fn short_stops(&self) -> u32 {
        self.tracker
            .shield
            .as_ref()
            .map_or(0, Shield::could_not_stop)
    }
}

/// Every controller a rehearsal can drive with, by name: what a planner or a benchmark picks
/// from a plain value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ControllerChoice {
    /// The classical rotate-then-go follower on the roadmap's segments (the thesis's
    /// baseline).
    Follower,
    /// The same behind the collision shield.
    ShieldedFollower,
    /// Nav2 Regulated Pure Pursuit on the smoothed path, behind the shield.
    Rpp,
    /// Nav2 MPPI on the smoothed path, behind the shield.
    Mppi,
    /// The policy behind the shield, the follower taking over near obstacles (the hybrid).
    Hybrid,
    /// The policy behind the shield, Regulated Pure Pursuit taking over near obstacles.
    HybridRpp,
    /// The same with the policy steering to a carrot on the smoothed path
    /// ([`PolicyController::on_smoothed_path`]).
    HybridPath,
}

impl ControllerChoice {
    /// Every choice.
    pub const ALL: [ControllerChoice; 7] = [
        ControllerChoice::Follower,
        ControllerChoice::ShieldedFollower,
        ControllerChoice::Rpp,
        ControllerChoice::Mppi,
        ControllerChoice::Hybrid,
        ControllerChoice::HybridRpp,
        ControllerChoice::HybridPath,
    ];

    /// The name: `follower`, `shielded_follower`, `rpp`, `mppi`, `hybrid`, `hybrid_rpp`,
    /// `hybrid_path`.
    pub fn as_str(self) -> &'static str {
        match self {
            ControllerChoice::Follower => "follower",
            ControllerChoice::ShieldedFollower => "shielded_follower",
            ControllerChoice::Rpp => "rpp",
            ControllerChoice::Mppi => "mppi",
            ControllerChoice::Hybrid => "hybrid",
            ControllerChoice::HybridRpp => "hybrid_rpp",
            ControllerChoice::HybridPath => "hybrid_path",
        }
    }

    /// The choice of a name, `None` for an unknown one.
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.as_str() == name)
    }

    /// Whether it drives a policy.
    pub fn needs_policy(self) -> bool {
        matches!(
            self,
            ControllerChoice::Hybrid | ControllerChoice::HybridRpp | ControllerChoice::HybridPath
        )
    }

    /// The controller, `None` when it needs a policy and none is given; `seed` seeds MPPI's
    /// sampling.
    pub fn build(
        self,
        policy: Option<&Arc<Policy>>,
        seed: u64,
    ) -> Option<Box<dyn Controller + Send>> {
        Some(match self {
            ControllerChoice::Follower => Box::new(ClassicalFollower::default()),
            ControllerChoice::ShieldedFollower => Box::new(ShieldedFollower::default()),
            ControllerChoice::Rpp => Box::new(RppController::new()),
            ControllerChoice::Mppi => Box::new(MppiController::new(seed)),
            ControllerChoice::Hybrid => Box::new(PolicyController::new(Arc::clone(policy?))),
            ControllerChoice::HybridRpp => {
                Box::new(PolicyController::with_rpp_handover(Arc::clone(policy?)))
            }
            ControllerChoice::HybridPath => {
                Box::new(PolicyController::on_smoothed_path(Arc::clone(policy?)))
            }
        })
    }
}
