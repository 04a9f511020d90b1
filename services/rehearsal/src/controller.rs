//! What drives the simulated robot towards a waypoint: the exported policy (hybrid PRM-RL, and
//! pure RL when the "waypoint" is the final goal) or a classical path follower. One trait, so
//! every method runs through the same executor and is measured the same way.

use std::sync::Arc;

use learning::Policy;
pub use sim::FollowerParams;
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

    /// Called before each simulated attempt (1-based), so stateful controllers start afresh.
    fn start_attempt(&mut self, _attempt: u32) {}

    /// Called once before the first attempt with the world it will drive in and the beams it
    /// reads, so a controller can learn the robot's geometry (footprint, laser mounting).
    fn attach(&mut self, _world: &World, _beams: usize) {}
}

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
/// towards open space. [`PolicyController::without_shield`] drives with the policy alone.
#[derive(Clone, Debug)]
pub struct PolicyController {
    policy: Arc<Policy>,
    /// Turning towards the waypoint: the direction (+1 left, -1 right), kept until aligned.
    aligning: Option<f64>,
    /// Whether to run the shield, and the shield once the robot is known.
    shielded: bool,
    shield: Option<Shield>,
}

impl PolicyController {
    /// A controller running `policy` behind the collision shield.
    pub fn new(policy: Arc<Policy>) -> Self {
        Self {
            policy,
            aligning: None,
            shielded: true,
            shield: None,
        }
    }

    /// A controller running `policy` alone: its commands reach the wheels unchanged.
    pub fn without_shield(policy: Arc<Policy>) -> Self {
        Self {
            shielded: false,
            ..Self::new(policy)
        }
    }

    /// The policy.
    pub fn policy(&self) -> &Arc<Policy> {
        &self.policy
    }
}

impl Controller for PolicyController {
    fn command(&mut self, obs: &Observation, _pose: Pose2, _waypoint: (f64, f64)) -> Action {
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
                angular: dir * f64::from(self.policy.scaling().angular_max),
            };
        }
        // The executor checks the beam count before it starts, so this cannot fail; should it,
        // stopping is the safe command.
        let wanted = self.policy.act(obs).unwrap_or_default();
        match &self.shield {
            Some(shield) => {
                shield.filter(wanted, obs, f64::from(self.policy.scaling().angular_max))
            }
            None => wanted,
        }
    }

    fn start_attempt(&mut self, _attempt: u32) {
        self.aligning = None;
    }

    fn attach(&mut self, world: &World, beams: usize) {
        self.shield = self.shielded.then(|| Shield::new(world, beams)).flatten();
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::Policy
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
        let shield = if self.shielded {
            format!(
                ", behind a collision shield (forward speed limited to keep {SHIELD_MARGIN_M} m \
                 from what the laser sees within {SHIELD_HORIZON_S} s)"
            )
        } else {
            String::new()
        };
        format!(
            "TD3 actor ({} beams, hidden {:?}{steps}){shield}",
            m.scaling.beams, m.hidden
        )
    }
}

/// Closest the shield lets the footprint come to a laser return, metres (the simulation counts
/// a collision below 0.02 m).
pub const SHIELD_MARGIN_M: f64 = 0.06;
/// How far ahead the shield looks, seconds of the commanded motion.
pub const SHIELD_HORIZON_S: f64 = 1.5;
/// Forward speeds the shield tries, as shares of the wanted one, fastest first.
const SHIELD_SCALES: [f64; 6] = [1.0, 0.7, 0.45, 0.25, 0.1, 0.0];
/// Time step of the shield's look-ahead, seconds.
const SHIELD_STEP_S: f64 = 0.1;

/// A collision monitor for a differential robot with a round footprint: it rolls the wanted
/// command forward for [`SHIELD_HORIZON_S`] against the current laser returns and keeps the
/// fastest share of its forward speed that never brings the footprint closer than
/// [`SHIELD_MARGIN_M`] to a return it is approaching (moving along a wall, or away from it,
/// stays allowed). When even a crawl is unsafe the robot stops and turns on the spot (a
/// round robot cannot hit anything turning in place): towards the waypoint when it is off to
/// one side, else towards the side the laser sees more room on.
#[derive(Clone, Debug)]
pub struct Shield {
    /// The laser's origin in the robot frame, metres.
    origin: (f64, f64),
    /// Unit directions of the beams in the robot frame.
    dirs: Vec<(f64, f64)>,
    /// Returns at or beyond this range hit nothing.
    range_max: f64,
    /// The footprint's radius, metres.
    radius: f64,
}

impl Shield {
    /// The shield for the robot of `world` reading `beams` beams; `None` when its laser cannot
    /// give them.
    pub fn new(world: &World, beams: usize) -> Option<Self> {
        let robot = &world.spec().robot;
        let laser = &robot.laser;
        let dirs = laser
            .beam_angles(beams)?
            .into_iter()
            .map(|a| ((a + laser.mount.yaw).cos(), (a + laser.mount.yaw).sin()))
            .collect();
        Some(Self {
            origin: (laser.mount.x, laser.mount.y),
            dirs,
            range_max: laser.range_max,
            radius: robot.footprint_radius,
        })
    }

    /// The laser returns in the robot frame.
    fn returns(&self, obs: &Observation) -> Vec<(f64, f64)> {
        obs.ranges
            .iter()
            .zip(&self.dirs)
            .filter(|(r, _)| f64::from(**r) < self.range_max - 1e-3)
            .map(|(r, (c, s))| {
                let r = f64::from(*r);
                (self.origin.0 + r * c, self.origin.1 + r * s)
            })
            .collect()
    }

    /// Whether driving `command` for the horizon keeps the footprint clear of `points`.
    fn safe(&self, command: Action, points: &[(f64, f64)]) -> bool {
        let gap = |x: f64, y: f64| {
            points
                .iter()
                .map(|(px, py)| (px - x).hypot(py - y))
                .fold(f64::INFINITY, f64::min)
                - self.radius
        };
        let now = gap(0.0, 0.0);
        let (mut x, mut y, mut yaw) = (0.0_f64, 0.0_f64, 0.0_f64);
        let mut t = 0.0;
        while t < SHIELD_HORIZON_S {
            x += command.linear * yaw.cos() * SHIELD_STEP_S;
            y += command.linear * yaw.sin() * SHIELD_STEP_S;
            yaw += command.angular * SHIELD_STEP_S;
            t += SHIELD_STEP_S;
            let g = gap(x, y);
            if g < SHIELD_MARGIN_M && g < now - 1e-3 {
                return false;
            }
        }
        true
    }

    /// The command to send instead of `wanted`, given the observation and the angular limit.
    pub fn filter(&self, wanted: Action, obs: &Observation, angular_max: f64) -> Action {
        if wanted.linear <= 0.0 {
            return wanted;
        }
        let points = self.returns(obs);
        if points.is_empty() {
            return wanted;
        }
        for scale in SHIELD_SCALES {
            let command = Action {
                linear: wanted.linear * scale,
                angular: wanted.angular,
            };
            if scale > 0.0 && self.safe(command, &points) {
                return command;
            }
        }
        // Blocked: turn in place, towards the waypoint when it is to one side, else towards
        // the side with more room.
        let bearing = f64::from(obs.goal_angle);
        let side = if bearing.abs() > 0.2 {
            bearing.signum()
        } else {
            let room = |left: bool| -> f64 {
                obs.ranges
                    .iter()
                    .zip(&self.dirs)
                    .filter(|(_, (_, s))| (*s > 0.0) == left)
                    .map(|(r, _)| f64::from(*r))
                    .sum()
            };
            if room(true) >= room(false) { 1.0 } else { -1.0 }
        };
        Action {
            linear: 0.0,
            angular: side * angular_max,
        }
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

#[cfg(test)]
#[allow(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap,
    reason = "test grids and values are small"
)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

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

    /// A shield for a 0.2 m robot with 23 beams over the front half, laser at the centre.
    fn shield() -> Shield {
        Shield {
            origin: (0.0, 0.0),
            dirs: (0..23)
                .map(|i| {
                    let a = -PI / 2.0 + PI * f64::from(i) / 22.0;
                    (a.cos(), a.sin())
                })
                .collect(),
            range_max: 10.0,
            radius: 0.2,
        }
    }

    /// The ranges a laser at the origin sees with a wall `ahead` metres in front (x = ahead)
    /// and one `left` metres to the left (y = left), each `None` for no wall.
    fn scan(s: &Shield, ahead: Option<f64>, left: Option<f64>) -> Observation {
        let ranges = s
            .dirs
            .iter()
            .map(|&(c, sn)| {
                let hit_ahead = ahead.filter(|_| c > 1e-9).map(|d| d / c);
                let hit_left = left.filter(|_| sn > 1e-9).map(|d| d / sn);
                [hit_ahead, hit_left]
                    .into_iter()
                    .flatten()
                    .fold(10.0_f64, f64::min) as f32
            })
            .collect();
        Observation { ranges, ..obs() }
    }

    #[test]
    fn the_shield_slows_and_stops_before_a_wall_but_not_along_one() {
        let s = shield();
        let go = Action::new(0.8, 0.0);
        // Open space: unchanged.
        assert_eq!(s.filter(go, &scan(&s, None, None), 0.5), go);
        // A wall 3 m ahead: 0.8 m/s for 1.5 s stays 1.6 m short of it.
        assert_eq!(s.filter(go, &scan(&s, Some(3.0), None), 0.5), go);
        // 1 m ahead: slower, still forward.
        let slowed = s.filter(go, &scan(&s, Some(1.0), None), 0.5);
        assert!(slowed.linear > 0.0 && slowed.linear < 0.8, "{slowed:?}");
        // 0.25 m ahead (5 cm from the footprint): stop and turn in place.
        let stopped = s.filter(go, &scan(&s, Some(0.25), None), 0.5);
        assert_eq!(stopped.linear, 0.0);
        assert_eq!(stopped.angular.abs(), 0.5);
        // Along a wall 4 cm from the footprint: driving parallel does not approach it.
        assert_eq!(s.filter(go, &scan(&s, None, Some(0.24)), 0.5), go);
        // Turning in place and reversing pass untouched.
        let turn = Action::new(0.0, 0.5);
        assert_eq!(s.filter(turn, &scan(&s, Some(0.25), None), 0.5), turn);
        // Blocked with the waypoint to the right: turns right.
        let right = Observation {
            goal_angle: -1.0,
            ..scan(&s, Some(0.25), None)
        };
        assert_eq!(s.filter(go, &right, 0.5).angular, -0.5);
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
