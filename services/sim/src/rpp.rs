//! Regulated Pure Pursuit (Macenski, Singh, Martín, Ginés, "Regulated Pure Pursuit for Robot
//! Path Tracking", Autonomous Robots 2023; Nav2's `nav2_regulated_pure_pursuit_controller`),
//! written from the paper and Nav2's parameter page (docs.nav2.org "Regulated Pure Pursuit"),
//! not from its code.
//!
//! Each control cycle: the path is pruned to the part ahead of the robot
//! ([`PathTrack::update`]); the look-ahead distance is the current speed times
//! `lookahead_time`, clamped to [`min_lookahead_dist`, `max_lookahead_dist`] (adaptive
//! look-ahead); the carrot is the path point that far away; when the carrot lies more than
//! `rotate_to_heading_min_angle` off the heading the robot turns on the spot towards it
//! (rotate-to-heading only where needed); otherwise it drives the pure-pursuit arc of
//! curvature `2 y / L²` to the carrot at the desired speed, regulated by
//! - curvature: below `regulated_linear_scaling_min_radius` the speed falls in proportion to
//!   the arc's radius,
//! - proximity: closer than `cost_scaling_dist` to an obstacle, in proportion to the distance
//!   (times `cost_scaling_gain`),
//!   both floored at `regulated_linear_scaling_min_speed`, and
//! - approach: within `approach_velocity_scaling_dist` of the path's end (the goal, never an
//!   intermediate vertex) in proportion to the remaining distance, floored at
//!   `min_approach_linear_velocity`.
//!
//! The robot's angular limit (0.5 rad/s, far below the 1.8 rad/s of the robots Nav2's defaults
//! are tuned for) would otherwise bend the arc: the speed is also capped so that the arc's
//! angular velocity stays within it, keeping the curvature pure pursuit asked for.

use crate::track::PathTrack;
use crate::{Action, Pose2};

/// Settings of Regulated Pure Pursuit. [`RppParams::for_robot`] gives Nav2's defaults (its
/// parameter page) scaled to a robot; each field names its source.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RppParams {
    /// Cruise speed, m/s (Nav2 `desired_linear_vel`, default 0.5 for a 0.5 m/s robot: the
    /// robot's top speed).
    pub desired_linear_vel: f64,
    /// Look-ahead time, s (Nav2 `lookahead_time`, default 1.5).
    pub lookahead_time: f64,
    /// Shortest look-ahead, m (Nav2 `min_lookahead_dist`, default 0.3).
    pub min_lookahead_dist: f64,
    /// Longest look-ahead, m (Nav2 `max_lookahead_dist`, default 0.9).
    pub max_lookahead_dist: f64,
    /// Turn-in-place speed, rad/s (Nav2 `rotate_to_heading_angular_vel`, default 1.8; capped at
    /// the robot's angular limit).
    pub rotate_to_heading_angular_vel: f64,
    /// Heading error to the carrot beyond which the robot turns on the spot, rad (Nav2
    /// `rotate_to_heading_min_angle`, default 0.785).
    pub rotate_to_heading_min_angle: f64,
    /// Radius below which curvature regulation slows the robot, m (Nav2
    /// `regulated_linear_scaling_min_radius`, default 0.9).
    pub regulated_linear_scaling_min_radius: f64,
    /// Slowest regulated speed, m/s (Nav2 `regulated_linear_scaling_min_speed`, default 0.25).
    pub regulated_linear_scaling_min_speed: f64,
    /// Distance from the robot's centre to an obstacle under which proximity regulation slows
    /// the robot, m (Nav2 `cost_scaling_dist`, default 0.6 for its default 0.22 m robot radius:
    /// 0.38 m beyond the footprint, kept beyond this robot's footprint).
    pub cost_scaling_dist: f64,
    /// Gain of proximity regulation (Nav2 `cost_scaling_gain`, default 1.0).
    pub cost_scaling_gain: f64,
    /// Distance to the path's end under which the robot slows to arrive, m (Nav2
    /// `approach_velocity_scaling_dist`, default 0.6).
    pub approach_velocity_scaling_dist: f64,
    /// Slowest approach speed, m/s (Nav2 `min_approach_linear_velocity`, default 0.05).
    pub min_approach_linear_velocity: f64,
    /// How far ahead along the path the robot's closest point is searched for, m (Nav2
    /// `max_robot_pose_search_dist`, default: the local costmap's half width; 1.5 m for Nav2's
    /// default 3 m local costmap).
    pub max_robot_pose_search_dist: f64,
    /// The robot's angular limit, rad/s.
    pub angular_max: f64,
}

/// The robot radius Nav2's default parameters are set for (`robot_radius: 0.22` in
/// `nav2_params.yaml`, a TurtleBot3), metres.
pub const NAV2_DEFAULT_ROBOT_RADIUS_M: f64 = 0.22;

impl RppParams {
    /// Nav2's defaults for a robot of footprint radius `radius_m` with top speeds
    /// `linear_max` (m/s) and `angular_max` (rad/s).
    pub fn for_robot(radius_m: f64, linear_max: f64, angular_max: f64) -> Self {
        Self {
            desired_linear_vel: linear_max,
            lookahead_time: 1.5,
            min_lookahead_dist: 0.3,
            max_lookahead_dist: 0.9,
            rotate_to_heading_angular_vel: 1.8_f64.min(angular_max),
            rotate_to_heading_min_angle: 0.785,
            regulated_linear_scaling_min_radius: 0.9,
            regulated_linear_scaling_min_speed: 0.25,
            cost_scaling_dist: 0.6 - NAV2_DEFAULT_ROBOT_RADIUS_M + radius_m,
            cost_scaling_gain: 1.0,
            approach_velocity_scaling_dist: 0.6,
            min_approach_linear_velocity: 0.05,
            max_robot_pose_search_dist: 1.5,
            angular_max,
        }
    }
}

impl Default for RppParams {
    /// The paper's robot: 0.8 m/s, 0.5 rad/s, and the example robot's footprint.
    fn default() -> Self {
        Self::for_robot(0.355, 0.8, 0.5)
    }
}

/// What one cycle of Regulated Pure Pursuit decided, for tests and reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RppStep {
    /// The command.
    pub action: Action,
    /// The look-ahead distance used, m.
    pub lookahead_m: f64,
    /// The carrot.
    pub carrot: (f64, f64),
    /// Whether the robot turns on the spot towards the carrot.
    pub rotating: bool,
}

/// One control cycle of Regulated Pure Pursuit for a robot at `pose` moving at `speed` m/s
/// (forward), `obstacle_m` from the nearest obstacle (robot centre to obstacle, metres), on
/// `track` (whose progress this updates). `None` for an empty track.
pub fn rpp_step(
    p: &RppParams,
    track: &mut PathTrack,
    pose: Pose2,
    speed: f64,
    obstacle_m: f64,
) -> Option<RppStep> {
    track.update(pose, p.max_robot_pose_search_dist);
    let lookahead_m =
        (speed.abs() * p.lookahead_time).clamp(p.min_lookahead_dist, p.max_lookahead_dist);
    let carrot = track.carrot(pose, lookahead_m)?;
    let (dx, dy) = (carrot.0 - pose.x, carrot.1 - pose.y);
    let (s, c) = pose.yaw.sin_cos();
    let remaining = track.remaining_from(track.progress());
    let (action, rotating) = rpp_command(
        p,
        (c * dx + s * dy, -s * dx + c * dy),
        remaining,
        obstacle_m,
    );
    Some(RppStep {
        action,
        lookahead_m,
        carrot,
        rotating,
    })
}

/// Regulated Pure Pursuit's command for a carrot at `(x, y)` in the robot frame (x ahead, y
/// left), `remaining_m` of path left to its end and `obstacle_m` from the robot's centre to the
/// nearest obstacle; and whether it turns on the spot. The arc through the carrot, with its
/// speed regulated by curvature, proximity and the approach to the end, and kept within the
/// angular limit.
pub fn rpp_command(
    p: &RppParams,
    (x, y): (f64, f64),
    remaining_m: f64,
    obstacle_m: f64,
) -> (Action, bool) {
    let angle = y.atan2(x);
    if angle.abs() > p.rotate_to_heading_min_angle {
        return (
            Action::new(0.0, angle.signum() * p.rotate_to_heading_angular_vel),
            true,
        );
    }
    let l2 = (x * x + y * y).max(1e-9);
    let curvature = 2.0 * y / l2;
    // Curvature regulation.
    let mut curvature_vel = p.desired_linear_vel;
    let radius = 1.0 / curvature.abs().max(1e-9);
    if radius < p.regulated_linear_scaling_min_radius {
        curvature_vel *= radius / p.regulated_linear_scaling_min_radius;
    }
    // Proximity regulation.
    let mut cost_vel = p.desired_linear_vel;
    if obstacle_m < p.cost_scaling_dist {
        cost_vel *= p.cost_scaling_gain * obstacle_m.max(0.0) / p.cost_scaling_dist;
    }
    let mut linear = curvature_vel
        .min(cost_vel)
        .max(p.regulated_linear_scaling_min_speed)
        .min(p.desired_linear_vel);
    // Approach to the path's end.
    if remaining_m < p.approach_velocity_scaling_dist {
        let approach = p.desired_linear_vel * remaining_m / p.approach_velocity_scaling_dist;
        linear = linear.min(approach.max(p.min_approach_linear_velocity));
    }
    // Keep the arc within the angular limit.
    if curvature.abs() > 1e-9 {
        linear = linear.min(p.angular_max / curvature.abs());
    }
    (
        Action::new(
            linear,
            (linear * curvature).clamp(-p.angular_max, p.angular_max),
        ),
        false,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(len: f64) -> PathTrack {
        PathTrack::new(crate::smoother::densify(&[(0.0, 0.0), (len, 0.0)], 0.05))
    }

    #[test]
    fn drives_at_the_desired_speed_on_a_straight_path_far_from_obstacles() {
        let p = RppParams::default();
        let mut t = straight(10.0);
        let s = rpp_step(&p, &mut t, Pose2::new(1.0, 0.0, 0.0), 0.8, 10.0).expect("step");
        assert!((s.action.linear - 0.8).abs() < 1e-9, "{s:?}");
        assert!(s.action.angular.abs() < 1e-9);
        // Adaptive look-ahead: 0.8 m/s x 1.5 s = 1.2, clamped to 0.9; at rest the shortest.
        assert!((s.lookahead_m - 0.9).abs() < 1e-9);
        let s = rpp_step(&p, &mut t, Pose2::new(1.0, 0.0, 0.0), 0.0, 10.0).expect("step");
        assert!((s.lookahead_m - 0.3).abs() < 1e-9);
    }

    #[test]
    fn regulates_speed_near_obstacles_in_proportion_and_turns_only_when_needed() {
        let p = RppParams::default();
        let mut t = straight(10.0);
        let at = Pose2::new(1.0, 0.0, 0.0);
        let half = rpp_step(&p, &mut t, at, 0.8, p.cost_scaling_dist / 2.0).expect("step");
        assert!((half.action.linear - 0.4).abs() < 1e-9, "{half:?}");
        let close = rpp_step(&p, &mut t, at, 0.8, 0.01).expect("step");
        assert!((close.action.linear - p.regulated_linear_scaling_min_speed).abs() < 1e-9);
        // The path behind: turn on the spot.
        let back = rpp_step(&p, &mut t, Pose2::new(1.0, 0.0, 3.0), 0.0, 10.0).expect("step");
        assert!(back.rotating && back.action.linear == 0.0);
        // Slightly off heading: drive an arc, no turning on the spot.
        let arc = rpp_step(&p, &mut t, Pose2::new(1.0, 0.0, 0.3), 0.8, 10.0).expect("step");
        assert!(!arc.rotating && arc.action.linear > 0.0 && arc.action.angular < 0.0);
        // Near the end: approach speed.
        let end = rpp_step(&p, &mut t, Pose2::new(9.8, 0.0, 0.0), 0.3, 10.0).expect("step");
        assert!(end.action.linear < 0.3, "{end:?}");
    }
}
