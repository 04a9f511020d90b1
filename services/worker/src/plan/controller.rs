//! What drives the simulated robot towards a waypoint: the exported policy (hybrid PRM-RL, and
//! pure RL when the "waypoint" is the final goal) or a classical path follower. One trait, so
//! every method runs through the same executor and is measured the same way.

use std::f64::consts::PI;
use std::sync::Arc;

use learning::Policy;
use sim::{Action, Observation, Pose2};

use super::types::ControllerKind;

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
#[derive(Clone, Debug)]
pub struct PolicyController {
    policy: Arc<Policy>,
    /// Turning towards the waypoint: the direction (+1 left, -1 right), kept until aligned.
    aligning: Option<f64>,
}

impl PolicyController {
    /// A controller running `policy`.
    pub fn new(policy: Arc<Policy>) -> Self {
        Self {
            policy,
            aligning: None,
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
        self.policy.act(obs).unwrap_or_default()
    }

    fn start_attempt(&mut self, _attempt: u32) {
        self.aligning = None;
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
            .and_then(serde_json::Value::as_u64)
            .map_or_else(String::new, |s| format!(", {s} training steps"));
        format!(
            "TD3 actor ({} beams, hidden {:?}{steps})",
            m.scaling.beams, m.hidden
        )
    }
}

/// Settings of the classical follower.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FollowerParams {
    /// Top linear speed, m/s (the paper's limit: 0.8).
    pub linear_max: f64,
    /// Top angular speed, rad/s (the paper's limit: 0.5).
    pub angular_max: f64,
    /// Heading error beyond which the robot turns on the spot, radians.
    pub rotate_threshold: f64,
    /// Proportional gain of the steering, (rad/s) per rad of heading error.
    pub heading_gain: f64,
    /// Slowest forward speed while driving, m/s.
    pub linear_min: f64,
    /// Distance ahead of the robot's projection on the segment that it steers to, metres.
    pub lookahead_m: f64,
    /// Within this distance of the waypoint the speed falls in proportion, metres.
    pub slow_down_m: f64,
    /// A waypoint is reached within this distance, metres: small, so the robot turns at the
    /// roadmap's vertices rather than cutting corners by the policy's 0.3 m tolerance.
    pub tolerance_m: f64,
}

impl Default for FollowerParams {
    fn default() -> Self {
        Self {
            linear_max: 0.8,
            angular_max: 0.5,
            rotate_threshold: 0.35,
            heading_gain: 2.0,
            linear_min: 0.1,
            lookahead_m: 0.4,
            slow_down_m: 0.8,
            tolerance_m: 0.05,
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

    /// The point on the current segment the robot steers to.
    fn carrot(&self, pose: Pose2) -> (f64, f64) {
        let (Some(a), Some(b)) = (self.from, self.to) else {
            return (pose.x, pose.y);
        };
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len = dx.hypot(dy);
        if len < 1e-9 {
            return b;
        }
        let (ux, uy) = (dx / len, dy / len);
        let t = ((pose.x - a.0) * ux + (pose.y - a.1) * uy).clamp(0.0, len);
        let s = (t + self.params.lookahead_m).min(len);
        (a.0 + s * ux, a.1 + s * uy)
    }
}

impl Controller for ClassicalFollower {
    fn command(&mut self, _obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        let p = self.params;
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
        let c = self.carrot(pose);
        let d = (waypoint.0 - pose.x).hypot(waypoint.1 - pose.y);
        let target = if (c.0 - pose.x).hypot(c.1 - pose.y) < 1e-6 {
            waypoint
        } else {
            c
        };
        let bearing = (target.1 - pose.y).atan2(target.0 - pose.x);
        let e = wrap(bearing - pose.yaw);
        let angular = (p.heading_gain * e).clamp(-p.angular_max, p.angular_max);
        if e.abs() > p.rotate_threshold {
            return Action::new(0.0, angular);
        }
        let share = 1.0 - e.abs() / p.rotate_threshold;
        let approach = (d / p.slow_down_m).min(1.0);
        let linear = (p.linear_min + (p.linear_max - p.linear_min) * share) * approach;
        Action::new(linear.max(p.linear_min.min(d)), angular)
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

/// An angle in (-π, π].
fn wrap(a: f64) -> f64 {
    let mut a = a % (2.0 * PI);
    if a <= -PI {
        a += 2.0 * PI;
    } else if a > PI {
        a -= 2.0 * PI;
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert!((wrap(3.0 * PI).abs() - PI).abs() < 1e-9);
        assert!((wrap(-0.5) + 0.5).abs() < 1e-12);
    }
}
