//! What drives the simulated robot towards a waypoint: the exported policy (hybrid PRM-RL, and
//! pure RL when the "waypoint" is the final goal) or a classical path follower. One trait, so
//! every method runs through the same executor and is measured the same way.

use std::sync::Arc;

use learning::Policy;
use prm::Point2;
pub use sim::FollowerParams;
pub use sim::shield::{PERSON_MARGIN_M, SHIELD_HORIZON_S, SHIELD_MARGIN_M, Shield};
use sim::{Action, Observation, Pose2, World};

use crate::types::ControllerKind;

/// A controller: one velocity command per control period.
pub trait Controller {
    /// The command for the current observation (laser ranges and the waypoint as (r, θ), as the
    /// policy sees it), the robot's true pose, and the waypoint it is driving to.
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action;

    /// Which kind of controller this is, for reports.
    fn kind(&self) -> ControllerKind;

    /// One line saying what the controller is.
    fn description(&self) -> String;

    /// Laser beams the controller reads, when it needs a particular number (a policy does).
    fn beams(&self) -> Option<usize> {
        None
    }

    /// Distance at which a waypoint counts as reached, metres, when the controller needs its
    /// own (the environment's default, 0.3 m, is what the policy was trained with).
    fn goal_tolerance(&self) -> Option<f64> {
        None
    }

    /// Whether the last command came from a fallback inside the controller (the classical
    /// follower a policy handed over to) rather than from the controller itself.
    fn handed_over(&self) -> bool {
        false
    }

    /// Called before each simulated attempt (1-based), so stateful controllers start afresh.
    fn start_attempt(&mut self, _attempt: u32) {}

    /// Called once before the first attempt with the world it will drive in and the beams it
    /// reads, so a controller can learn the robot's geometry (footprint, laser mounting) and
    /// the map (what its laser should see).
    fn attach(&mut self, _world: &Arc<World>, _beams: usize) {}

    /// Called with the robot's pose and the rest of the current leg (the waypoint it drives to
    /// first, the leg's goal last) at the start of a drive, of each leg, after every replan and
    /// after a recovery. Path trackers (Regulated Pure Pursuit, MPPI) follow that whole path;
    /// controllers that drive waypoint to waypoint ignore it.
    fn start_path(&mut self, _pose: Pose2, _path: &[Point2]) {}

    /// Whether the robot at `pose` has driven past `waypoint`, an intermediate waypoint of the
    /// path given to [`Controller::start_path`]: the executor then counts it as reached, so a
    /// path tracker passes through the roadmap's vertices instead of stopping at each.
    fn passed(&self, _pose: Pose2, _waypoint: Point2) -> bool {
        false
    }

    /// How many times the controller's collision shield, since it was attached, was blocked
    /// while the robot moved too fast to stop short of its margins ([`Shield::could_not_stop`]);
    /// 0 for a controller without one.
    fn short_stops(&self) -> u32 {
        0
    }
}

impl<C: Controller + ?Sized> Controller for Box<C> {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        (**self).command(obs, pose, waypoint)
    }
    fn kind(&self) -> ControllerKind {
        (**self).kind()
    }
    fn description(&self) -> String {
        (**self).description()
    }
    fn beams(&self) -> Option<usize> {
        (**self).beams()
    }
    fn goal_tolerance(&self) -> Option<f64> {
        (**self).goal_tolerance()
    }
    fn handed_over(&self) -> bool {
        (**self).handed_over()
    }
    fn start_attempt(&mut self, attempt: u32) {
        (**self).start_attempt(attempt);
    }
    fn attach(&mut self, world: &Arc<World>, beams: usize) {
        (**self).attach(world, beams);
    }
    fn start_path(&mut self, pose: Pose2, path: &[Point2]) {
        (**self).start_path(pose, path);
    }
    fn passed(&self, pose: Pose2, waypoint: Point2) -> bool {
        (**self).passed(pose, waypoint)
    }
    fn short_stops(&self) -> u32 {
        (**self).short_stops()
    }
}

/// The rehearsal's control period, seconds: the time between the scans a shield sees.
const CONTROL_PERIOD_S: f64 = 0.1;

/// Bearing of the waypoint beyond which the policy controller turns on the spot first, radians
/// (100°).
pub const ALIGN_START_RAD: f64 = 1.75;
/// Bearing below which it hands over to the policy again, radians (20°).
pub const ALIGN_DONE_RAD: f64 = 0.35;

/// The exported TD3 actor: it sees only the observation (23 ranges, the waypoint's (r, θ),
/// odometry), never the true pose, exactly as on the robot.
///
/// A waypoint far behind the robot is first faced by turning on the spot (from a bearing of
/// [`ALIGN_START_RAD`] down to [`ALIGN_DONE_RAD`]; a round robot turning in place cannot
/// collide), then the policy drives. Reactive policies whose laser sees only ahead dither
/// there: with a wall in front and the goal behind, turning left and turning right look alike,
/// and a policy trained with TD3 flips between them (the failure of most hybrid attempts
/// before this). Plans hand the policy waypoints in every direction, so the hybrid aligns first
/// as the classical follower does.
///
/// Between the policy and the wheels sits a [`Shield`] (a collision monitor, as robots run
/// one under their planners): it slows or stops a forward motion that would bring the
/// footprint within a few centimetres of what the laser sees, and turns a robot it stopped
/// towards open space.
///
/// Behind the shield, the classical follower takes over where the policy is about to be
/// close to what it sees (the handover): when the policy's command, rolled forward for the
/// shield's horizon, would bring the footprint within the handover margin
/// ([`HANDOVER_MARGIN_M`]) of a return it approaches, or when the shield changes the
/// command, the follower drives the rest of the way to that waypoint along the roadmap's
/// segment (which the roadmap checked to be clear), and the policy gets the next waypoint
/// again. A shield that only slows a policy pressing on a wall turns a tight spot into a
/// stall (the policy's failures on unseen buildings were such stalls, not collisions); the
/// follower tracks the segment through it, held back only by what the map does not know
/// ([`Shield::filter_follower`]: a person on the segment stops it, a wall only at the last
/// moment, on the map). The executor counts the steps each drove
/// ([`Controller::handed_over`]), so a report says how much of a drive was the policy's.
///
/// [`PolicyController::without_handover`] runs the policy behind the shield alone,
/// [`PolicyController::without_shield`] the policy alone.
#[derive(Clone, Debug)]
pub struct PolicyController {
    policy: Arc<Policy>,
    /// Turning towards the waypoint: the direction (+1 left, -1 right), kept until aligned.
    aligning: Option<f64>,
    /// Whether to run the shield, and the shield once the robot is known.
    shielded: bool,
    shield: Option<Shield>,
    /// The map the shield tells known returns from unknown ones (people) by.
    world: Option<Arc<World>>,
    /// The follower that takes over near obstacles, and the margin that decides it.
    handover: Option<Handover>,
    /// Whether the last command was the follower's.
    handed_over: bool,
    /// Steering the policy to a point this far ahead on the smoothed roadmap path instead of
    /// to the waypoint, metres ([`PolicyController::on_smoothed_path`]).
    carrot_m: Option<f64>,
    /// The policy's progress to its waypoint: the waypoint, the nearest it has come, and the
    /// policy's steps since it came nearer by [`POLICY_PROGRESS_M`].
    progress: Option<((f64, f64), f64, u32)>,
}

/// What the policy must gain on its waypoint within [`POLICY_STALL_STEPS`] steps, metres, or
/// the follower takes over to that waypoint: a policy that dithers in place (turning left and
/// right with no speed, as a reactive policy can where its goal is to one side) never comes
/// near anything, so no other handover rule frees it.
pub const POLICY_PROGRESS_M: f64 = 0.25;
/// Control steps (0.1 s each) the policy has to gain [`POLICY_PROGRESS_M`]: 3 s, in which the
/// robot at its top speed (0.8 m/s) covers 2.4 m. Set from the robot's speed, not measured on a
/// map.
pub const POLICY_STALL_STEPS: u32 = 30;

/// What the collision shield of both controllers does, in words.
pub(crate) fn shield_description() -> String {
    format!(
        "a collision shield (forward speed limited to keep {SHIELD_MARGIN_M} m from what the \
         laser sees and the map knows, {PERSON_MARGIN_M} m from what it does not, people, within \
         {SHIELD_HORIZON_S} s)"
    )
}

/// Shows `shield` the scan of a robot at `pose`, on the map when there is one.
pub(crate) fn observe(shield: &mut Shield, obs: &Observation, pose: Pose2, world: Option<&World>) {
    match world {
        Some(w) => shield.observe_on_map(obs, CONTROL_PERIOD_S, pose, w),
        None => shield.observe(obs, CONTROL_PERIOD_S),
    }
}

/// Closest the policy may plan to bring the footprint to a laser return it approaches before
/// the classical follower takes over, metres. Chosen on 25 generated floors (seed 99, none of
/// the shared maps): success on every roadmap edge rises with the margin (no handover 99.31%,
/// on shield interventions only 99.77%, 0.1 m 99.78%, 0.3 m 99.82%, 0.6 m 99.89%; the
/// follower alone 99.80%) while the time per edge rises slowly (5.95 s, 6.06 s, 6.08 s,
/// 6.18 s, 6.28 s; the follower 8.46 s); 0.3 m is the smallest margin whose success and near
/// misses both match the follower's there.
pub const HANDOVER_MARGIN_M: f64 = 0.3;

/// Revision of what [`PolicyController`] does with a policy's commands: stored measurements of
/// a policy's edges (policy-aware roadmaps) name it, so that those driven by an older
/// controller are rebuilt. 2: the handover to the follower. 3: the shield rolls returns that
/// move forward with their velocity (from consecutive scans). 4: the shield tells what the map
/// knows from what it does not (people), keeps further from the latter and lets them stop
/// anywhere on their way, and the follower a policy hands over to stops for them (and for walls
/// at the last moment). 5: Regulated Pure Pursuit, when it is the follower handed over to, is
/// held by the shield as it is on its own (it turns away from a wall it was left facing), and
/// the policy may steer to a carrot on the smoothed path. 6: the policy drives again once its
/// own command has kept the handover margin for [`HAND_BACK_STEPS`] (it waited for the next
/// waypoint).
pub const POLICY_CONTROLLER_REVISION: u32 = 6;

/// How far ahead on the smoothed path [`PolicyController::on_smoothed_path`] puts the policy's
/// goal, metres: the distance the robot covers at its top speed (0.8 m/s) in Nav2 RPP's
/// look-ahead time (1.5 s). Set once from those two, not measured on any map.
pub const POLICY_CARROT_M: f64 = 1.2;

/// The classical follower a [`PolicyController`] hands over to.
#[derive(Clone, Debug)]
struct Handover {
    follower: ClassicalFollower,
    /// Regulated Pure Pursuit on the smoothed path instead of the follower, when set.
    rpp: Option<Box<crate::nav2::RppController>>,
    margin_m: f64,
    /// The waypoint the follower drives to since it took over.
    until: Option<(f64, f64)>,
    /// Whether it took over because the policy came too near what the laser sees (rather
    /// than because the policy made no progress), and for how many steps since then the
    /// policy's own command has kept the margin ([`HAND_BACK_STEPS`]).
    near: bool,
    clear_steps: u32,
}

/// Control steps (0.1 s each) the policy's own command must keep the handover margin, while
/// the follower drives after a handover near something and no person is within personal space
/// ([`crate::social::PERSONAL_M`]), before the policy drives again: one second, so that the
/// policy does not take back a wall it was just turned away from. Before, the follower kept
/// the robot to the waypoint, so on a long roadmap edge down a corridor it drove most of the
/// way.
pub const HAND_BACK_STEPS: u32 = 10;

impl PolicyController {
    /// A controller running `policy` behind the collision shield, the classical follower
    /// taking over within [`HANDOVER_MARGIN_M`] of what the laser sees.
    pub fn new(policy: Arc<Policy>) -> Self {
        Self::with_handover_margin(policy, HANDOVER_MARGIN_M)
    }

    /// [`PolicyController::new`] with another handover margin, metres.
    pub fn with_handover_margin(policy: Arc<Policy>, margin_m: f64) -> Self {
        Self {
            policy,
            aligning: None,
            shielded: true,
            shield: None,
            world: None,
            handover: Some(Handover {
                follower: ClassicalFollower::default(),
                rpp: None,
                margin_m,
                until: None,
                near: false,
                clear_steps: 0,
            }),
            handed_over: false,
            carrot_m: None,
            progress: None,
        }
    }

    /// [`PolicyController::with_rpp_handover`] with the policy steering to the point
    /// [`POLICY_CARROT_M`] ahead on the smoothed roadmap path (the carrot a path tracker
    /// steers to) instead of to the next roadmap vertex: the policy never arrives at an
    /// intermediate vertex, so it does not slow down or turn on the spot there, and a vertex
    /// counts as reached once the robot's progress on the path passes it, as for RPP.
    pub fn on_smoothed_path(policy: Arc<Policy>) -> Self {
        Self {
            carrot_m: Some(POLICY_CARROT_M),
            ..Self::with_rpp_handover(policy)
        }
    }

    /// [`PolicyController::new`] with Nav2's Regulated Pure Pursuit on the smoothed roadmap
    /// path as the follower it hands over to ([`crate::nav2::RppController`]), instead of the
    /// rotate-then-go follower on the segment.
    pub fn with_rpp_handover(policy: Arc<Policy>) -> Self {
        let mut c = Self::new(policy);
        if let Some(h) = &mut c.handover {
            h.rpp = Some(Box::new(crate::nav2::RppController::without_shield()));
        }
        c
    }

    /// A controller running `policy` behind the collision shield, without the follower.
    pub fn without_handover(policy: Arc<Policy>) -> Self {
        Self {
            handover: None,
            ..Self::new(policy)
        }
    }

    /// A controller running `policy` alone: its commands reach the wheels unchanged.
    pub fn without_shield(policy: Arc<Policy>) -> Self {
        Self {
            shielded: false,
            handover: None,
            ..Self::new(policy)
        }
    }

    /// The policy.
    pub fn policy(&self) -> &Arc<Policy> {
        &self.policy
    }
}

impl Controller for PolicyController {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        // The shield sees every scan, so it knows what moves and what the map does not know.
        if let Some(shield) = &mut self.shield {
            observe(shield, obs, pose, self.world.as_deref());
        }
        // The follower sees every step, so its segment starts where the last waypoint was.
        let follow = self.handover.as_mut().map(|h| {
            let segment = h.follower.command(obs, pose, waypoint);
            match &mut h.rpp {
                Some(rpp) => rpp.wanted(obs, pose, waypoint),
                None => segment,
            }
        });
        self.handed_over = false;
        let angular_max = f64::from(self.policy.scaling().angular_max);
        // What holds the follower back (seeing the waypoint, not the carrot): Regulated Pure
        // Pursuit is held as it is behind the shield on its own (it may have to turn away from
        // a wall it was left facing); the segment follower keeps to the roadmap, so only the
        // last moment holds it.
        let rpp = self.handover.as_ref().is_some_and(|h| h.rpp.is_some());
        let hold = |shield: &Shield, world: Option<&World>, fc: Action| match (rpp, world) {
            (true, _) => shield.filter(fc, obs, angular_max),
            (false, Some(w)) => shield.filter_follower(fc, obs, pose, w),
            (false, None) => fc,
        };
        // On the smoothed path, the policy's goal is the carrot, not the vertex (the
        // observation's goal is f32, as the environment's). Where the path doubles back
        // within the look-ahead, the carrot lies behind the robot on the way back while the
        // vertex is still ahead: the vertex is then the goal, as without the carrot.
        let carrot_obs;
        let carrot = match (
            self.carrot_m,
            self.handover.as_ref().and_then(|h| h.rpp.as_ref()),
        ) {
            (Some(l), Some(rpp)) => rpp.carrot(pose, l),
            _ => None,
        };
        let towards = |p: (f64, f64)| (p.1 - pose.y).atan2(p.0 - pose.x);
        let ahead = |p: (f64, f64)| {
            sim::kinematics::wrap_angle(towards(p) - pose.yaw).abs() < std::f64::consts::FRAC_PI_2
        };
        let obs = match carrot {
            Some(c) if !ahead(waypoint) || ahead(c) => {
                carrot_obs = Observation {
                    #[allow(clippy::cast_possible_truncation, reason = "f32 observations")]
                    goal_distance: sim::norm(c.0 - pose.x, c.1 - pose.y) as f32,
                    #[allow(clippy::cast_possible_truncation, reason = "f32 observations")]
                    goal_angle: sim::kinematics::wrap_angle(towards(c) - pose.yaw) as f32,
                    ..obs.clone()
                };
                &carrot_obs
            }
            _ => obs,
        };
        if let (Some(h), Some(fc)) = (&mut self.handover, follow) {
            if h.until == Some(waypoint) {
                // Taken over near something: the policy drives again once its own command has
                // kept the margin for a second, with no person within personal space (it is
                // not the policy's turn when it stalled).
                let clear = h.near
                    && self.shield.as_ref().is_some_and(|s| {
                        if s.sees_unknown_within(obs, crate::social::PERSONAL_M) {
                            return false;
                        }
                        let wanted = self.policy.act(obs).unwrap_or_default();
                        s.filter(wanted, obs, angular_max) == wanted
                            && s.keeps_margin(wanted, obs, h.margin_m)
                    });
                h.clear_steps = if clear { h.clear_steps + 1 } else { 0 };
                if h.clear_steps < HAND_BACK_STEPS {
                    self.handed_over = true;
                    return match &self.shield {
                        Some(s) => hold(s, self.world.as_deref(), fc),
                        None => fc,
                    };
                }
                self.aligning = None;
            }
            h.until = None;
        }
        let bearing = f64::from(obs.goal_angle);
        let turn = match self.aligning {
            Some(dir) if bearing.abs() > ALIGN_DONE_RAD => Some(dir),
            Some(_) => None,
            None if bearing.abs() > ALIGN_START_RAD => Some(bearing.signum()),
            None => None,
        };
        self.aligning = turn;
        if let Some(dir) = turn {
            return Action {
                linear: 0.0,
                angular: dir * angular_max,
            };
        }
        // Progress while the policy drives: none for too long, and the follower takes over.
        let d = sim::norm(waypoint.0 - pose.x, waypoint.1 - pose.y);
        let stalled = match &mut self.progress {
            Some((w, best, steps)) if *w == waypoint => {
                if d < *best - POLICY_PROGRESS_M {
                    (*best, *steps) = (d, 0);
                } else {
                    *steps += 1;
                }
                *steps >= POLICY_STALL_STEPS
            }
            _ => {
                self.progress = Some((waypoint, d, 0));
                false
            }
        };
        if stalled
            && let (Some(h), Some(fc), Some(shield)) = (&mut self.handover, follow, &self.shield)
        {
            (h.until, h.near, h.clear_steps) = (Some(waypoint), false, 0);
            self.handed_over = true;
            return hold(shield, self.world.as_deref(), fc);
        }
        // The executor checks the beam count before it starts, so this cannot fail; should it,
        // stopping is the safe command.
        let wanted = self.policy.act(obs).unwrap_or_default();
        let Some(shield) = &self.shield else {
            return wanted;
        };
        let filtered = shield.filter(wanted, obs, angular_max);
        if let (Some(h), Some(fc)) = (&mut self.handover, follow)
            && (filtered != wanted || !shield.keeps_margin(wanted, obs, h.margin_m))
        {
            (h.until, h.near, h.clear_steps) = (Some(waypoint), true, 0);
            self.handed_over = true;
            return hold(shield, self.world.as_deref(), fc);
        }
        filtered
    }

    fn handed_over(&self) -> bool {
        self.handed_over
    }

    fn start_attempt(&mut self, attempt: u32) {
        self.progress = None;
        self.aligning = None;
        self.handed_over = false;
        if let Some(shield) = &mut self.shield {
            shield.reset_motion();
        }
        if let Some(h) = &mut self.handover {
            h.follower.start_attempt(attempt);
            if let Some(rpp) = &mut h.rpp {
                rpp.start_attempt(attempt);
            }
            h.until = None;
        }
    }

    fn attach(&mut self, world: &Arc<World>, beams: usize) {
        self.shield = self.shielded.then(|| Shield::new(world, beams)).flatten();
        self.world = Some(Arc::clone(world));
        if let Some(rpp) = self.handover.as_mut().and_then(|h| h.rpp.as_mut()) {
            rpp.attach(world, beams);
        }
    }

    fn start_path(&mut self, pose: Pose2, path: &[Point2]) {
        if let Some(rpp) = self.handover.as_mut().and_then(|h| h.rpp.as_mut()) {
            rpp.start_path(pose, path);
        }
    }

    fn passed(&self, pose: Pose2, waypoint: Point2) -> bool {
        (self.handed_over || self.carrot_m.is_some())
            && self
                .handover
                .as_ref()
                .and_then(|h| h.rpp.as_ref())
                .is_some_and(|rpp| rpp.passed(pose, waypoint))
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::Policy
    }

    fn short_stops(&self) -> u32 {
        let own = self.shield.as_ref().map_or(0, Shield::could_not_stop);
        let rpp = self
            .handover
            .as_ref()
            .and_then(|h| h.rpp.as_ref())
            .map_or(0, |r| r.short_stops());
        own + rpp
    }

    fn beams(&self) -> Option<usize> {
        Some(self.policy.scaling().beams)
    }

    fn description(&self) -> String {
        let m = self.policy.metadata();
        let steps = m
            .training
            .pointer("/counters/env_steps")
            .and_then(|v| v.as_u64())
            .map_or_else(String::new, |s| format!(", {s} training steps"));
        let mut shield = if self.shielded {
            format!(", behind {}", shield_description())
        } else {
            String::new()
        };
        if let Some(h) = &self.handover {
            let who = if h.rpp.is_some() {
                "Nav2 Regulated Pure Pursuit on the smoothed roadmap path"
            } else {
                "the classical follower"
            };
            shield.push_str(&format!(
                ", {who} taking over where the policy would come within {} m of \
                 what the laser sees, until the policy's own command has kept that margin for \
                 {} s with no person within {} m, or the next waypoint",
                h.margin_m,
                f64::from(HAND_BACK_STEPS) * CONTROL_PERIOD_S,
                crate::social::PERSONAL_M
            ));
        }
        let goal = self.carrot_m.map_or_else(String::new, |l| {
            format!(" steering to the point {l} m ahead on the smoothed roadmap path")
        });
        format!(
            "TD3 actor ({} beams, hidden {:?}{steps}){goal}{shield}",
            m.scaling.beams, m.hidden
        )
    }
}

/// The classical path follower: rotate-then-go along the straight segments between waypoints,
/// steering to a carrot on the segment (pure pursuit).
///
/// The segment runs from the previous waypoint (or from where the robot stood when it got a
/// waypoint far from the last one, after a replan) to the current one. The robot steers to the
/// point `lookahead_m` ahead of its projection on the segment. With the heading error `e` to
/// that point: when `|e|` exceeds `rotate_threshold` it turns on the spot at `heading_gain · e`
/// (clamped to the angular limit); otherwise it drives at a speed falling linearly from
/// `linear_max` (aligned) to `linear_min` (at the threshold), and in proportion to the distance
/// within `slow_down_m` of the waypoint, while steering at `heading_gain · e`. Waypoints count
/// as reached within `tolerance_m`. It tracks the roadmap's segments to within a few
/// centimetres, so its result says whether the path is safe, not whether a learnt policy can
/// follow it. It ignores the laser: obstacles the roadmap does not know about (none, in a
/// simulation generated from the same knowledge) would stop it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClassicalFollower {
    params: FollowerParams,
    from: Option<(f64, f64)>,
    to: Option<(f64, f64)>,
}

impl ClassicalFollower {
    /// A follower with these settings.
    pub fn new(params: FollowerParams) -> Self {
        Self {
            params,
            from: None,
            to: None,
        }
    }
}

impl Controller for ClassicalFollower {
    fn command(&mut self, _obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        if self.to != Some(waypoint) {
            // A new waypoint: the segment starts at the last one when the robot is there, else
            // (first waypoint, replanned path) where the robot stands.
            let here = (pose.x, pose.y);
            self.from = match self.to {
                Some(last) if (last.0 - here.0).hypot(last.1 - here.1) < 0.5 => Some(last),
                _ => Some(here),
            };
            self.to = Some(waypoint);
        }
        let from = self.from.unwrap_or((pose.x, pose.y));
        sim::follow(&self.params, from, waypoint, pose)
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::Classical
    }

    fn goal_tolerance(&self) -> Option<f64> {
        Some(self.params.tolerance_m)
    }

    fn start_attempt(&mut self, _attempt: u32) {
        self.from = None;
        self.to = None;
    }

    fn description(&self) -> String {
        let p = &self.params;
        format!(
            "classical rotate-then-go follower with pure pursuit on the roadmap's segments (turn on the spot beyond {:.2} rad of heading error, lookahead {} m, up to {} m/s and {} rad/s, waypoints reached within {} m)",
            p.rotate_threshold, p.lookahead_m, p.linear_max, p.angular_max, p.tolerance_m
        )
    }
}

/// The classical follower behind the same collision shield as the policy: what a robot with
/// a path follower and a collision monitor (nav2's, say) would do. The fair baseline among
/// moving people, where the bare follower, blind to them, drives on.
#[derive(Clone, Debug, Default)]
pub struct ShieldedFollower {
    follower: ClassicalFollower,
    shield: Option<Shield>,
    world: Option<Arc<World>>,
}

impl ShieldedFollower {
    /// The follower with `params` behind the shield.
    pub fn new(params: FollowerParams) -> Self {
        Self {
            follower: ClassicalFollower::new(params),
            shield: None,
            world: None,
        }
    }
}

impl Controller for ShieldedFollower {
    fn command(&mut self, obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        let wanted = self.follower.command(obs, pose, waypoint);
        match &mut self.shield {
            Some(shield) => {
                observe(shield, obs, pose, self.world.as_deref());
                shield.filter(wanted, obs, self.follower.params.angular_max)
            }
            None => wanted,
        }
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::Classical
    }

    fn goal_tolerance(&self) -> Option<f64> {
        self.follower.goal_tolerance()
    }

    fn start_attempt(&mut self, attempt: u32) {
        self.follower.start_attempt(attempt);
        if let Some(shield) = &mut self.shield {
            shield.reset_motion();
        }
    }

    fn attach(&mut self, world: &Arc<World>, beams: usize) {
        self.shield = Shield::new(world, beams);
        self.world = Some(Arc::clone(world));
    }

    fn short_stops(&self) -> u32 {
        self.shield.as_ref().map_or(0, Shield::could_not_stop)
    }

    fn description(&self) -> String {
        format!(
            "{}, behind {}",
            self.follower.description(),
            shield_description()
        )
    }
}

#[cfg(test)]
#[allow(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap,
    reason = "test grids and values are small"
)]
mod tests {
    use super::*;

    #[test]
    fn the_training_preset_shows_the_carrot_plans_steer_to() {
        assert_eq!(learning::TrainConfig::fast().carrot_m, POLICY_CARROT_M);
    }

    fn obs() -> Observation {
        Observation {
            ranges: vec![5.0; 23],
            goal_distance: 1.0,
            goal_angle: 0.0,
            velocity: [0.0; 2],
        }
    }

    /// A policy whose every output is sigmoid(0) = 0.5 linear, tanh(0) = 0 angular.
    fn constant_policy() -> Arc<Policy> {
        let dir = tempfile::tempdir().expect("tmp");
        let scaling = learning::Scaling::default();
        let inputs = scaling.input_len();
        let meta = learning::policy::PolicyMetadata::new(scaling, vec![2], serde_json::json!({}));
        let layers = [
            (vec![0.0f32; 2 * inputs], vec![0.0f32; 2]),
            (vec![0.0f32; 4], vec![0.0f32; 2]),
        ];
        learning::policy::write_policy(dir.path(), &meta, &layers).expect("written");
        Arc::new(Policy::load(dir.path()).expect("loads"))
    }

    #[test]
    fn the_policy_controller_faces_a_waypoint_behind_before_the_policy_drives() {
        let mut c = PolicyController::new(constant_policy());
        let at = |angle: f32| Observation {
            goal_angle: angle,
            ..obs()
        };
        let here = Pose2::new(0.0, 0.0, 0.0);
        // Ahead: the policy's own command.
        let a = c.command(&at(0.5), here, (1.0, 0.0));
        assert!(
            (a.linear - 0.4).abs() < 1e-6 && a.angular.abs() < 1e-9,
            "{a:?}"
        );
        // Behind on the right: turn right on the spot, and keep turning below the start angle.
        let a = c.command(&at(-2.5), here, (1.0, 0.0));
        assert_eq!((a.linear, a.angular), (0.0, -0.5));
        let a = c.command(&at(-1.0), here, (1.0, 0.0));
        assert_eq!((a.linear, a.angular), (0.0, -0.5));
        // Aligned: the policy again.
        let a = c.command(&at(-0.2), here, (1.0, 0.0));
        assert!((a.linear - 0.4).abs() < 1e-6, "{a:?}");
        // A new attempt forgets a turn in progress.
        c.command(&at(2.5), here, (1.0, 0.0));
        c.start_attempt(2);
        let a = c.command(&at(1.0), here, (1.0, 0.0));
        assert!((a.linear - 0.4).abs() < 1e-6, "{a:?}");
    }

    #[test]
    fn the_follower_turns_on_the_spot_then_drives() {
        let mut f = ClassicalFollower::default();
        let behind = f.command(&obs(), Pose2::new(0.0, 0.0, 0.0), (-1.0, 0.1));
        assert_eq!(behind.linear, 0.0);
        assert!(behind.angular.abs() <= 0.5 + 1e-12 && behind.angular != 0.0);
        let mut f = ClassicalFollower::default();
        let ahead = f.command(&obs(), Pose2::new(0.0, 0.0, 0.0), (3.0, 0.0));
        assert!((ahead.linear - 0.8).abs() < 1e-12 && ahead.angular.abs() < 1e-12);
        let mut f = ClassicalFollower::default();
        let left = f.command(&obs(), Pose2::new(0.0, 0.0, 0.0), (3.0, 0.3));
        assert!(left.angular > 0.0 && left.linear < 0.8 && left.linear >= 0.1);
        // Off the segment, it steers back onto it rather than straight at the waypoint.
        let mut f = ClassicalFollower::default();
        f.command(&obs(), Pose2::new(0.0, 0.0, 0.0), (4.0, 0.0));
        let back = f.command(&obs(), Pose2::new(1.0, 0.1, 0.0), (4.0, 0.0));
        assert!(back.angular < 0.0, "{back:?}");
    }
}
