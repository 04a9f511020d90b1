//! The classical path follower's control law, as a pure function: rotate-then-go along a
//! straight segment, steering to a carrot on it (pure pursuit). The rehearsal executor drives
//! plans with it (`rehearsal::ClassicalFollower` keeps the segment between calls), and training
//! uses it as the demonstrator whose actions a policy is warm-started from and regularised
//! towards (TD3+BC).

use crate::{Action, Pose2};

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

/// The point `lookahead_m` ahead of the robot's projection on the segment `from → to`.
fn carrot(p: &FollowerParams, from: (f64, f64), to: (f64, f64), pose: Pose2) -> (f64, f64) {
    let (dx, dy) = (to.0 - from.0, to.1 - from.1);
    let len = dx.hypot(dy);
    if len < 1e-9 {
        return to;
    }
    let (ux, uy) = (dx / len, dy / len);
    let t = ((pose.x - from.0) * ux + (pose.y - from.1) * uy).clamp(0.0, len);
    let s = (t + p.lookahead_m).min(len);
    (from.0 + s * ux, from.1 + s * uy)
}

/// The follower's command at `pose` on the segment `from → to`.
///
/// With the heading error `e` to the carrot: beyond `rotate_threshold` the robot turns on the
/// spot at `heading_gain · e` (clamped to the angular limit); otherwise it drives at a speed
/// falling linearly from `linear_max` (aligned) to `linear_min` (at the threshold), and in
/// proportion to the distance within `slow_down_m` of `to`, while steering at `heading_gain · e`.
pub fn follow(p: &FollowerParams, from: (f64, f64), to: (f64, f64), pose: Pose2) -> Action {
    let c = carrot(p, from, to, pose);
    let d = (to.0 - pose.x).hypot(to.1 - pose.y);
    let target = if (c.0 - pose.x).hypot(c.1 - pose.y) < 1e-6 {
        to
    } else {
        c
    };
    let bearing = (target.1 - pose.y).atan2(target.0 - pose.x);
    let e = crate::kinematics::wrap_angle(bearing - pose.yaw);
    let angular = (p.heading_gain * e).clamp(-p.angular_max, p.angular_max);
    if e.abs() > p.rotate_threshold {
        return Action::new(0.0, angular);
    }
    let share = 1.0 - e.abs() / p.rotate_threshold;
    let approach = (d / p.slow_down_m).min(1.0);
    let linear = (p.linear_min + (p.linear_max - p.linear_min) * share) * approach;
    Action::new(linear.max(p.linear_min.min(d)), angular)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turns_on_the_spot_then_drives_along_the_segment() {
        let p = FollowerParams::default();
        // Goal behind: turn in place, at the angular limit.
        let a = follow(&p, (0.0, 0.0), (-2.0, 0.0), Pose2::new(0.0, 0.0, 0.0));
        assert_eq!(a.linear, 0.0);
        assert!((a.angular.abs() - p.angular_max).abs() < 1e-12);
        // Aligned and far: full speed, no steering.
        let a = follow(&p, (0.0, 0.0), (5.0, 0.0), Pose2::new(1.0, 0.0, 0.0));
        assert!((a.linear - p.linear_max).abs() < 1e-12 && a.angular.abs() < 1e-12);
        // Beside the segment: steer back towards it.
        let a = follow(&p, (0.0, 0.0), (5.0, 0.0), Pose2::new(1.0, 0.1, 0.0));
        assert!(a.angular < 0.0 && a.linear > 0.0);
        // Close to the goal: slow.
        let a = follow(&p, (0.0, 0.0), (5.0, 0.0), Pose2::new(4.8, 0.0, 0.0));
        assert!(a.linear <= 0.25 * p.linear_max + 1e-9, "{a:?}");
    }
}
