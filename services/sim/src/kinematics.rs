//! Differential-drive kinematics: command limits, wheel-speed and acceleration limits, and exact
//! integration of a constant (linear, angular) velocity over one control period.

use crate::spec::{DiffDriveSpec, Pose2};

/// A velocity command: linear (m/s, forward) and angular (rad/s, counter-clockwise).
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct Action {
    /// Linear velocity, m/s.
    pub linear: f64,
    /// Angular velocity, rad/s.
    pub angular: f64,
}

impl Action {
    /// A command of `linear` m/s and `angular` rad/s.
    pub fn new(linear: f64, angular: f64) -> Self {
        Self { linear, angular }
    }
}

/// The range of commands a policy may give (the paper's: linear in [0, 0.8] m/s, angular in
/// [-0.5, 0.5] rad/s).
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct CommandLimits {
    /// Smallest linear velocity, m/s.
    pub linear_min: f64,
    /// Largest linear velocity, m/s.
    pub linear_max: f64,
    /// Largest angular speed either way, rad/s.
    pub angular_max: f64,
}

impl Default for CommandLimits {
    fn default() -> Self {
        Self {
            linear_min: 0.0,
            linear_max: 0.8,
            angular_max: 0.5,
        }
    }
}

impl CommandLimits {
    /// `action` clamped into the limits; a non-finite component becomes 0 (a policy emitting NaN
    /// stops the robot rather than poisoning the episode).
    pub fn clamp(&self, action: Action) -> Action {
        let fin = |v: f64| if v.is_finite() { v } else { 0.0 };
        Action {
            linear: fin(action.linear).clamp(self.linear_min, self.linear_max),
            angular: fin(action.angular).clamp(-self.angular_max, self.angular_max),
        }
    }
}

/// Differential-drive model from the robot's active wheels.
#[derive(Clone, Debug, PartialEq)]
pub struct DiffDrive {
    spec: DiffDriveSpec,
}

impl DiffDrive {
    /// The model for a drive description (validated by [`crate::WorldSpec::validate`]).
    pub fn new(spec: DiffDriveSpec) -> Self {
        Self { spec }
    }

    /// Left and right wheel angular speeds, rad/s, for a body velocity.
    pub fn wheel_speeds(&self, a: Action) -> (f64, f64) {
        let half = self.spec.wheel_separation / 2.0;
        let r = self.spec.wheel_radius;
        (
            (a.linear - a.angular * half) / r,
            (a.linear + a.angular * half) / r,
        )
    }

    /// Body velocity for left and right wheel angular speeds, rad/s.
    pub fn body_velocity(&self, left: f64, right: f64) -> Action {
        let r = self.spec.wheel_radius;
        Action {
            linear: r * (left + right) / 2.0,
            angular: r * (right - left) / self.spec.wheel_separation,
        }
    }

    /// What the drive executes when commanded `wanted` after executing `previous` for the last
    /// period of `dt` seconds: the robot's top speeds, then acceleration limits, then wheel-speed
    /// saturation, which scales both wheels together so the turning radius is kept.
    pub fn execute(&self, previous: Action, wanted: Action, dt: f64) -> Action {
        let top = |v: f64, max: Option<f64>| match max {
            Some(m) => v.clamp(-m, m),
            None => v,
        };
        // Speeding up (away from zero) is bounded by the acceleration, slowing down (towards
        // zero, or through it) by the deceleration, as a velocity smoother bounds them.
        let limit = |prev: f64, want: f64, accel: Option<f64>, decel: Option<f64>| {
            let decel = decel.or(accel);
            let (up, down) = if prev > 0.0 {
                (accel, decel)
            } else if prev < 0.0 {
                (decel, accel)
            } else {
                (accel, accel)
            };
            let hi = up.map_or(f64::INFINITY, |a| prev + a * dt);
            let lo = down.map_or(f64::NEG_INFINITY, |a| prev - a * dt);
            want.clamp(lo, hi)
        };
        let wanted = Action {
            linear: top(wanted.linear, self.spec.max_linear_speed),
            angular: top(wanted.angular, self.spec.max_angular_speed),
        };
        let mut a = Action {
            linear: limit(
                previous.linear,
                wanted.linear,
                self.spec.max_linear_acceleration,
                self.spec.max_linear_deceleration,
            ),
            angular: limit(
                previous.angular,
                wanted.angular,
                self.spec.max_angular_acceleration,
                self.spec.max_angular_deceleration,
            ),
        };
        if let Some(max) = self.spec.max_wheel_speed {
            let (l, r) = self.wheel_speeds(a);
            let top = l.abs().max(r.abs());
            if top > max {
                let k = max / top;
                a = self.body_velocity(l * k, r * k);
            }
        }
        a
    }
}

/// The pose after moving at constant body velocity `a` for `dt` seconds from `pose`: the exact
/// arc of a unicycle (a straight line when the angular velocity is zero).
pub fn integrate(pose: Pose2, a: Action, dt: f64) -> Pose2 {
    let dtheta = a.angular * dt;
    let yaw = pose.yaw + dtheta;
    if dtheta.abs() < 1e-9 {
        // Second-order term keeps the tiny-turn case continuous with the arc formula.
        let d = a.linear * dt;
        let (sm, cm) = (pose.yaw + dtheta / 2.0).sin_cos();
        return Pose2 {
            x: pose.x + d * cm,
            y: pose.y + d * sm,
            yaw: wrap_angle(yaw),
        };
    }
    let (s0, c0) = pose.yaw.sin_cos();
    let (s1, c1) = yaw.sin_cos();
    let r = a.linear / a.angular;
    Pose2 {
        x: pose.x + r * (s1 - s0),
        y: pose.y - r * (c1 - c0),
        yaw: wrap_angle(yaw),
    }
}

/// `angle` wrapped into (-π, π].
pub fn wrap_angle(angle: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if angle > -PI && angle <= PI {
        return angle;
    }
    let a = (angle + PI).rem_euclid(TAU) - PI;
    if a <= -PI { a + TAU } else { a }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::{FRAC_PI_2, PI};

    fn drive() -> DiffDrive {
        DiffDrive::new(DiffDriveSpec {
            wheel_separation: 0.4,
            wheel_radius: 0.1,
            max_wheel_speed: None,
            max_linear_speed: None,
            max_angular_speed: None,
            max_linear_acceleration: None,
            max_angular_acceleration: None,
            max_linear_deceleration: None,
            max_angular_deceleration: None,
            control_latency: None,
        })
    }

    #[test]
    fn straight_line_moves_along_heading() {
        let p = integrate(Pose2::new(1.0, 2.0, FRAC_PI_2), Action::new(0.5, 0.0), 2.0);
        assert!((p.x - 1.0).abs() < 1e-12 && (p.y - 3.0).abs() < 1e-12);
        assert!((p.yaw - FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn quarter_circle_ends_on_the_arc() {
        // v = 0.5, w = 0.5: radius 1 m; a quarter turn takes π seconds.
        let p = integrate(Pose2::new(0.0, 0.0, 0.0), Action::new(0.5, 0.5), PI);
        assert!((p.x - 1.0).abs() < 1e-12, "{p:?}");
        assert!((p.y - 1.0).abs() < 1e-12, "{p:?}");
        assert!((p.yaw - FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn many_small_steps_equal_one_big_step() {
        let a = Action::new(0.7, -0.3);
        let mut p = Pose2::new(0.3, -0.2, 1.0);
        for _ in 0..100 {
            p = integrate(p, a, 0.01);
        }
        let q = integrate(Pose2::new(0.3, -0.2, 1.0), a, 1.0);
        assert!(
            (p.x - q.x).abs() < 1e-9 && (p.y - q.y).abs() < 1e-9 && (p.yaw - q.yaw).abs() < 1e-9
        );
    }

    #[test]
    fn tiny_turn_is_continuous_with_the_arc() {
        let a = integrate(Pose2::new(0.0, 0.0, 0.3), Action::new(0.8, 1e-12), 0.1);
        let b = integrate(Pose2::new(0.0, 0.0, 0.3), Action::new(0.8, 1e-6), 0.1);
        assert!((a.x - b.x).abs() < 1e-8 && (a.y - b.y).abs() < 1e-8);
    }

    #[test]
    fn wheel_speeds_round_trip() {
        let d = drive();
        let a = Action::new(0.6, 0.4);
        let (l, r) = d.wheel_speeds(a);
        assert!((l - (0.6 - 0.08) / 0.1).abs() < 1e-12);
        assert!((r - (0.6 + 0.08) / 0.1).abs() < 1e-12);
        let b = d.body_velocity(l, r);
        assert!((b.linear - 0.6).abs() < 1e-12 && (b.angular - 0.4).abs() < 1e-12);
    }

    #[test]
    fn limits_clamp_and_reject_nan() {
        let l = CommandLimits::default();
        assert_eq!(l.clamp(Action::new(2.0, -3.0)), Action::new(0.8, -0.5));
        assert_eq!(l.clamp(Action::new(-1.0, 0.2)), Action::new(0.0, 0.2));
        assert_eq!(
            l.clamp(Action::new(f64::NAN, f64::INFINITY)),
            Action::new(0.0, 0.0)
        );
    }

    #[test]
    fn acceleration_and_wheel_limits_apply() {
        let d = DiffDrive::new(DiffDriveSpec {
            max_linear_acceleration: Some(1.0),
            max_angular_acceleration: Some(2.0),
            max_linear_deceleration: None,
            max_angular_deceleration: None,
            control_latency: None,
            max_wheel_speed: Some(5.0),
            ..drive().spec
        });
        let a = d.execute(Action::default(), Action::new(0.8, 0.5), 0.1);
        assert!((a.linear - 0.1).abs() < 1e-12 && (a.angular - 0.2).abs() < 1e-12);
        // 0.8 m/s straight needs 8 rad/s per wheel: scaled to 5 rad/s, 0.5 m/s.
        let fast = DiffDrive::new(DiffDriveSpec {
            max_wheel_speed: Some(5.0),
            ..drive().spec
        });
        let b = fast.execute(Action::new(0.8, 0.0), Action::new(0.8, 0.0), 0.1);
        assert!((b.linear - 0.5).abs() < 1e-12 && b.angular.abs() < 1e-12);
    }

    #[test]
    fn wrap_angle_range() {
        for a in [-7.0, -PI, -3.0, 0.0, 3.0, PI, 7.0, 100.0] {
            let w = wrap_angle(a);
            assert!(w > -PI - 1e-12 && w <= PI + 1e-12, "{a} -> {w}");
            assert!(
                ((w - a) / std::f64::consts::TAU).round() * std::f64::consts::TAU - (w - a) < 1e-9
            );
        }
    }
}
