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

    /// Called before each simulated attempt (1-based), so stateful controllers start afresh.
    fn start_attempt(&mut self, _attempt: u32) {}
}

/// The exported TD3 actor: it sees only the observation (23 ranges and the waypoint's (r, θ)),
/// never the true pose, exactly as on the robot.
#[derive(Clone, Debug)]
pub struct PolicyController {
    policy: Arc<Policy>,
}

impl PolicyController {
    /// A controller running `policy`.
    pub fn new(policy: Arc<Policy>) -> Self {
        Self { policy }
    }

    /// The policy.
    pub fn policy(&self) -> &Arc<Policy> {
        &self.policy
    }
}

impl Controller for PolicyController {
    fn command(&mut self, obs: &Observation, _pose: Pose2, _waypoint: (f64, f64)) -> Action {
        // The executor checks the beam count before it starts, so this cannot fail; should it,
        // stopping is the safe command.
        self.policy.act(obs).unwrap_or_default()
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
    /// Slowest forward speed while steering within the threshold, m/s.
    pub linear_min: f64,
}

impl Default for FollowerParams {
    fn default() -> Self {
        Self {
            linear_max: 0.8,
            angular_max: 0.5,
            rotate_threshold: 0.35,
            heading_gain: 2.0,
            linear_min: 0.1,
        }
    }
}

/// The classical path follower: rotate-then-go on the straight segments between waypoints.
///
/// With the heading error `e` to the waypoint (from the true pose): when `|e|` exceeds
/// `rotate_threshold` the robot turns on the spot at `heading_gain · e` (clamped to the angular
/// limit); otherwise it drives at a speed falling linearly from `linear_max` (aligned) to
/// `linear_min` (at the threshold) while steering at `heading_gain · e`. It tracks the roadmap's
/// segments to within a few centimetres, so its result says whether the path is safe, not
/// whether a learnt policy can follow it. It ignores the laser: obstacles the roadmap does not
/// know about (nothing, in a simulation generated from the same knowledge) would stop it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClassicalFollower {
    params: FollowerParams,
}

impl ClassicalFollower {
    /// A follower with these settings.
    pub fn new(params: FollowerParams) -> Self {
        Self { params }
    }
}

impl Controller for ClassicalFollower {
    fn command(&mut self, _obs: &Observation, pose: Pose2, waypoint: (f64, f64)) -> Action {
        let p = &self.params;
        let bearing = (waypoint.1 - pose.y).atan2(waypoint.0 - pose.x);
        let e = wrap(bearing - pose.yaw);
        let angular = (p.heading_gain * e).clamp(-p.angular_max, p.angular_max);
        if e.abs() > p.rotate_threshold {
            return Action::new(0.0, angular);
        }
        let share = 1.0 - e.abs() / p.rotate_threshold;
        let linear = p.linear_min + (p.linear_max - p.linear_min) * share;
        Action::new(linear, angular)
    }

    fn kind(&self) -> ControllerKind {
        ControllerKind::Classical
    }

    fn description(&self) -> String {
        let p = &self.params;
        format!(
            "classical rotate-then-go follower (turn on the spot beyond {:.2} rad of heading error, then drive at up to {} m/s steering at {} rad/s per rad, angular limit {} rad/s)",
            p.rotate_threshold, p.linear_max, p.heading_gain, p.angular_max
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
        }
    }

    #[test]
    fn the_follower_turns_on_the_spot_then_drives() {
        let mut f = ClassicalFollower::default();
        let behind = f.command(&obs(), Pose2::new(0.0, 0.0, 0.0), (-1.0, 0.1));
        assert_eq!(behind.linear, 0.0);
        assert!(behind.angular.abs() <= 0.5 + 1e-12 && behind.angular != 0.0);
        let ahead = f.command(&obs(), Pose2::new(0.0, 0.0, 0.0), (3.0, 0.0));
        assert!((ahead.linear - 0.8).abs() < 1e-12 && ahead.angular.abs() < 1e-12);
        let left = f.command(&obs(), Pose2::new(0.0, 0.0, 0.0), (3.0, 0.3));
        assert!(left.angular > 0.0 && left.linear < 0.8 && left.linear >= 0.1);
        assert!((wrap(3.0 * PI).abs() - PI).abs() < 1e-9);
        assert!((wrap(-0.5) + 0.5).abs() < 1e-12);
    }
}
