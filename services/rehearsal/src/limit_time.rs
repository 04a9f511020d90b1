//! The time a driven line takes at the robot's limits: its top speeds *and* its acceleration
//! limits, from the speed the drive started at (at rest, for a plan's first leg) to the speed it
//! ended at (as the drive, which reaches a goal within its tolerance, not necessarily at rest).
//! What any controller would need to drive the same line, so the rest of a drive's time is how
//! it drove, not where.
//!
//! The line is the drive's control steps, each a short arc (a distance and a turn). Along it the
//! robot's linear speed is capped by its top speed and, on an arc, by its top turn rate
//! (`v ≤ ω_max · d / θ`); between those caps it speeds up by at most the linear acceleration and
//! slows down by at most the deceleration, a forward and a backward pass over the steps' ends as
//! time-optimal path parameterisation does (Bobrow et al. 1985, for a point on a path with
//! bounded acceleration). A turn on the spot is a stop: the robot turns from rest to rest with its
//! angular acceleration and deceleration. The angular acceleration an arc's changing curvature
//! asks for is not bounded (the line is what was driven, its curvature changes step by step);
//! without acceleration limits this is each step at whichever top speed binds.

/// The limits a line is timed at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineLimits {
    /// Top linear speed, m/s.
    pub linear_max: f64,
    /// Top angular speed, rad/s.
    pub angular_max: f64,
    /// Largest linear acceleration, m/s² (`None`: none).
    pub linear_acceleration: Option<f64>,
    /// Largest linear deceleration, m/s² (`None`: the acceleration).
    pub linear_deceleration: Option<f64>,
    /// Largest angular acceleration, rad/s² (`None`: none).
    pub angular_acceleration: Option<f64>,
    /// Largest angular deceleration, rad/s² (`None`: the acceleration).
    pub angular_deceleration: Option<f64>,
}

impl LineLimits {
    /// Top speeds only.
    pub fn speeds(linear_max: f64, angular_max: f64) -> LineLimits {
        LineLimits {
            linear_max,
            angular_max,
            linear_acceleration: None,
            linear_deceleration: None,
            angular_acceleration: None,
            angular_deceleration: None,
        }
    }

    /// The drive limits of a robot model, with `linear_max` and `angular_max` as the commands
    /// allow.
    pub fn of(drive: &sim::spec::DiffDriveSpec, linear_max: f64, angular_max: f64) -> LineLimits {
        LineLimits {
            linear_max,
            angular_max,
            linear_acceleration: drive.max_linear_acceleration,
            linear_deceleration: drive.max_linear_deceleration,
            angular_acceleration: drive.max_angular_acceleration,
            angular_deceleration: drive.max_angular_deceleration,
        }
    }

    fn pair(accel: Option<f64>, decel: Option<f64>) -> (f64, f64) {
        let a = accel.filter(|a| *a > 0.0).unwrap_or(f64::INFINITY);
        let b = decel.filter(|b| *b > 0.0).unwrap_or(a);
        (a, b)
    }
}

/// Below this distance a step is a turn on the spot, metres.
const ON_THE_SPOT_M: f64 = 1e-6;

/// Time to move `d` from speed `u` to speed `w` with at most speed `c`, acceleration `a` and
/// deceleration `b` (infinite: instant), where `u`, `w` ≤ `c` and `w² ≤ u² + 2ad`, `u² ≤ w² + 2bd`
/// (the passes guarantee it): speed up, hold, slow down.
fn segment_time(d: f64, u: f64, w: f64, c: f64, a: f64, b: f64) -> f64 {
    if d <= 0.0 {
        return 0.0;
    }
    // The highest speed reachable inside the segment.
    let peak = if a.is_finite() && b.is_finite() {
        ((2.0 * a * b * d + b * u * u + a * w * w) / (a + b))
            .sqrt()
            .min(c)
    } else if a.is_finite() {
        (u * u + 2.0 * a * d).sqrt().min(c)
    } else if b.is_finite() {
        (w * w + 2.0 * b * d).sqrt().min(c)
    } else {
        c
    };
    let peak = peak.max(u).max(w);
    if peak <= 0.0 {
        return f64::INFINITY;
    }
    let (up_d, up_t) = if a.is_finite() {
        ((peak * peak - u * u) / (2.0 * a), (peak - u) / a)
    } else {
        (0.0, 0.0)
    };
    let (down_d, down_t) = if b.is_finite() {
        ((peak * peak - w * w) / (2.0 * b), (peak - w) / b)
    } else {
        (0.0, 0.0)
    };
    let cruise = (d - up_d - down_d).max(0.0);
    up_t + down_t + cruise / peak
}

/// Time to turn `theta` on the spot from rest to rest with top rate `w`, angular acceleration
/// `a` and deceleration `b`.
fn spot_turn_time(theta: f64, w: f64, a: f64, b: f64) -> f64 {
    segment_time(theta.abs(), 0.0, 0.0, w, a, b)
}

/// The time `steps` (each a distance, metres, and a turn either way, radians) take at `limits`,
/// from rest to rest; infinite when a limit is not positive.
pub fn limit_time(steps: &[(f64, f64)], limits: &LineLimits) -> f64 {
    limit_time_between(steps, limits, 0.0, Some(0.0))
}

/// [`limit_time`] starting at speed `start` (m/s, capped by the first step's) and ending at
/// `end` (`None`: as fast as the line allows).
pub fn limit_time_between(
    steps: &[(f64, f64)],
    limits: &LineLimits,
    start: f64,
    end: Option<f64>,
) -> f64 {
    let (vmax, wmax) = (limits.linear_max, limits.angular_max);
    if !(vmax > 0.0 && wmax > 0.0) {
        return f64::INFINITY;
    }
    let (a, b) = LineLimits::pair(limits.linear_acceleration, limits.linear_deceleration);
    let (aa, ab) = LineLimits::pair(limits.angular_acceleration, limits.angular_deceleration);
    // Each step's speed cap; a turn on the spot caps at zero (a stop).
    let caps: Vec<f64> = steps
        .iter()
        .map(|&(d, theta)| {
            let d = d.abs();
            if d < ON_THE_SPOT_M {
                0.0
            } else if theta.abs() > 0.0 {
                vmax.min(wmax * d / theta.abs())
            } else {
                vmax
            }
        })
        .collect();
    let n = steps.len();
    // Speeds at the steps' ends: node i is between step i-1 and step i; at rest at both ends.
    let mut v = vec![0.0f64; n + 1];
    for i in 1..n {
        v[i] = caps[i - 1].min(caps[i]);
    }
    if n > 0 {
        v[0] = start.abs().min(caps[0]);
        v[n] = end.map_or(caps[n - 1], |e| e.abs().min(caps[n - 1]));
    }
    // Forward: no faster than the acceleration allows from the node before.
    for i in 0..n {
        let d = steps[i].0.abs();
        v[i + 1] = v[i + 1].min((v[i] * v[i] + 2.0 * a * d).sqrt());
    }
    // Backward: no faster than the deceleration can stop from by the node after.
    for i in (0..n).rev() {
        let d = steps[i].0.abs();
        v[i] = v[i].min((v[i + 1] * v[i + 1] + 2.0 * b * d).sqrt());
    }
    // Consecutive steps on the spot turning the same way are one turn, from rest to rest.
    let mut total = 0.0;
    let mut turn = 0.0f64;
    for (i, &(d, theta)) in steps.iter().enumerate() {
        let d = d.abs();
        if d < ON_THE_SPOT_M {
            if turn != 0.0 && theta != 0.0 && theta.signum() != turn.signum() {
                total += spot_turn_time(turn, wmax, aa, ab);
                turn = 0.0;
            }
            turn += theta;
            continue;
        }
        if turn != 0.0 {
            total += spot_turn_time(turn, wmax, aa, ab);
            turn = 0.0;
        }
        total += segment_time(d, v[i], v[i + 1], caps[i], a, b);
    }
    if turn != 0.0 {
        total += spot_turn_time(turn, wmax, aa, ab);
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn without_acceleration_limits_each_step_takes_whichever_top_speed_binds() {
        // Straight: 0.8 m at 0.8 m/s. Arc of radius 0.4 m turning 0.5 rad (0.2 m): the turn
        // binds, 1 s. Turning on the spot by 0.25 rad: 0.5 s.
        let t = limit_time(
            &[(0.8, 0.0), (0.2, -0.5), (0.0, 0.25)],
            &LineLimits::speeds(0.8, 0.5),
        );
        assert!(close(t, 2.5), "{t}");
    }

    #[test]
    fn a_straight_line_speeds_up_holds_and_brakes() {
        // 10 m at 1.0 m/s, 0.5 m/s² up and down: 2 s and 1 m each way, 8 m held: 12 s.
        let limits = LineLimits {
            linear_acceleration: Some(0.5),
            ..LineLimits::speeds(1.0, 1.0)
        };
        let steps = vec![(0.1, 0.0); 100];
        let t = limit_time(&steps, &limits);
        assert!(close(t, 12.0), "{t}");
        // Too short to reach the top speed: 1 m is a triangle, up to √(2 · 0.5 · 0.5) m/s
        // half-way, 2·√2 s in all.
        let t = limit_time(&[(0.5, 0.0), (0.5, 0.0)], &limits);
        assert!(close(t, 2.0 * 2.0f64.sqrt()), "{t}");
        // Braking twice as hard: 1 s and 0.5 m of braking, 8.5 m held: 11.5 s.
        let harder = LineLimits {
            linear_deceleration: Some(1.0),
            ..limits
        };
        let t = limit_time(&steps, &harder);
        assert!(close(t, 2.0 + 1.0 + 8.5), "{t}");
    }

    #[test]
    fn a_turn_on_the_spot_stops_the_robot_and_turns_from_rest_to_rest() {
        let limits = LineLimits {
            linear_acceleration: Some(0.5),
            angular_acceleration: Some(1.0),
            ..LineLimits::speeds(1.0, 1.0)
        };
        // 2 m, a quarter turn on the spot, 2 m: each leg a triangle up to 1 m/s (4 s); the
        // turn 1 s up to 1 rad/s, π/2 − 1 rad held, 1 s down.
        let t = limit_time(
            &[
                (1.0, 0.0),
                (1.0, 0.0),
                (0.0, std::f64::consts::FRAC_PI_2),
                (1.0, 0.0),
                (1.0, 0.0),
            ],
            &limits,
        );
        let leg = 4.0;
        let turn = 2.0 + std::f64::consts::FRAC_PI_2 - 1.0;
        assert!(close(t, 2.0 * leg + turn), "{t}");
        // The same quarter turn in ten control steps is one turn, not ten.
        let mut split = vec![(1.0, 0.0), (1.0, 0.0)];
        split.extend(vec![(0.0, std::f64::consts::FRAC_PI_2 / 10.0); 10]);
        split.extend([(1.0, 0.0), (1.0, 0.0)]);
        let t = limit_time(&split, &limits);
        assert!(close(t, 2.0 * leg + turn), "{t}");
        // The same line without limits: 4 s and π/2 s.
        let t = limit_time(
            &[
                (1.0, 0.0),
                (1.0, 0.0),
                (0.0, std::f64::consts::FRAC_PI_2),
                (1.0, 0.0),
                (1.0, 0.0),
            ],
            &LineLimits::speeds(1.0, 1.0),
        );
        assert!(close(t, 4.0 + std::f64::consts::FRAC_PI_2), "{t}");
    }

    #[test]
    fn a_tight_arc_ahead_is_braked_for_in_time() {
        // 5 m straight, then an arc whose turn rate caps the speed at 0.2 m/s: the robot must
        // be down to 0.2 m/s where the arc begins, so the straight costs more than at the top
        // speed alone, and the whole is no faster than the parts at their caps.
        let limits = LineLimits {
            linear_acceleration: Some(0.5),
            ..LineLimits::speeds(1.0, 0.5)
        };
        let mut steps = vec![(0.1, 0.0); 50];
        steps.extend(vec![(0.1, 0.25); 10]);
        let t = limit_time(&steps, &limits);
        let at_caps = 5.0 / 1.0 + 1.0 / 0.2;
        assert!(t > at_caps + 1.0, "{t}");
        // Starting at the top speed (a later leg) saves the speeding up: 2 s for 1 m at
        // 0.5 m/s², 1 s of it spent covering the metre at the top speed; ending free saves the
        // braking the same.
        let straight = vec![(0.1, 0.0); 100];
        let rest_to_rest = limit_time(&straight, &limits);
        let flying = limit_time_between(&straight, &limits, 1.0, None);
        assert!(close(rest_to_rest - flying, 2.0), "{rest_to_rest} {flying}");
        // No limit: infinite.
        assert!(limit_time(&steps, &LineLimits::speeds(0.0, 0.5)).is_infinite());
    }
}
