//! Social navigation metrics of a drive among people, as Francis et al. 2023 ("Principles and
//! Guidelines for Evaluating Social Robot Navigation Algorithms") and HuNavSim's evaluator
//! define them: entries into a person's intimate (0.45 m) and personal (1.2 m) space, counted
//! once per approach, and the time the robot does not move. Distances are between the robot's
//! footprint and the person's body (both circles), as the simulation measures a person's
//! clearance. Measured from the simulation's ground truth, not from what the robot sees.

/// Intimate space: closer than this to a person, metres (Hall's proxemics, as HuNavSim).
pub const INTIMATE_M: f64 = 0.45;
/// Personal space, metres.
pub const PERSONAL_M: f64 = 1.2;
/// An approach ends when the robot is this much farther than the threshold again, metres (so
/// the laser's and the walkers' jitter at the boundary is not counted as many approaches).
pub const HYSTERESIS_M: f64 = 0.05;
use crate::limit_time::{LineLimits, limit_time_between};

/// The robot does not move below this linear speed, m/s.
pub const NOT_MOVING_M_S: f64 = 0.01;

/// The social metrics of a drive.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SocialMetrics {
    /// Entries into a person's intimate space ([`INTIMATE_M`]), once per approach.
    pub intimate_intrusions: u32,
    /// Entries into a person's personal space ([`PERSONAL_M`]), once per approach.
    pub personal_intrusions: u32,
    /// Simulated time the robot's linear speed was below [`NOT_MOVING_M_S`], s.
    pub time_not_moving_s: f64,
    /// The time the same driven line takes at the robot's limits, s: its top speeds and its
    /// acceleration limits, from the speed the drive began at ([`crate::limit_time`]). What any controller would
    /// need to drive the same line; the rest of the drive's time is how it drove, not where.
    pub limit_time_s: f64,
}

impl SocialMetrics {
    /// The sum of two drives' metrics.
    pub fn plus(self, other: SocialMetrics) -> SocialMetrics {
        SocialMetrics {
            intimate_intrusions: self.intimate_intrusions + other.intimate_intrusions,
            personal_intrusions: self.personal_intrusions + other.personal_intrusions,
            time_not_moving_s: self.time_not_moving_s + other.time_not_moving_s,
            limit_time_s: self.limit_time_s + other.limit_time_s,
        }
    }
}

/// Counts [`SocialMetrics`] step by step.
#[derive(Clone, Debug, Default)]
pub struct SocialTracker {
    metrics: SocialMetrics,
    /// Each step's distance and turn, for [`SocialMetrics::limit_time_s`].
    line: Vec<(f64, f64)>,
    /// The limits the line is timed at (the last step's).
    limits: Option<LineLimits>,
    /// The robot's speed when the drive began, m/s.
    start_speed: f64,
    /// Per person (by index): inside intimate space, inside personal space.
    inside: Vec<(bool, bool)>,
}

impl SocialTracker {
    /// A tracker for a drive that begins at `speed` m/s (a later leg of a plan starts moving).
    pub fn starting_at(speed: f64) -> Self {
        Self {
            start_speed: speed,
            ..Self::default()
        }
    }

    /// After a step of `dt` seconds: the robot at `(x, y)` with footprint `radius`, driving at
    /// `linear` m/s, among `people` (each position and radius, in the same order every step).
    pub fn step(
        &mut self,
        (x, y): (f64, f64),
        radius: f64,
        linear: f64,
        dt: f64,
        people: &[((f64, f64), f64)],
    ) {
        if linear.abs() < NOT_MOVING_M_S {
            self.metrics.time_not_moving_s += dt;
        }
        if self.inside.len() < people.len() {
            self.inside.resize(people.len(), (false, false));
        }
        for (q, inside) in people.iter().zip(&mut self.inside) {
            let gap = sim::norm(q.0.0 - x, q.0.1 - y) - q.1 - radius;
            let update = |flag: &mut bool, threshold: f64, count: &mut u32| {
                if !*flag && gap < threshold {
                    *flag = true;
                    *count += 1;
                } else if *flag && gap > threshold + HYSTERESIS_M {
                    *flag = false;
                }
            };
            update(
                &mut inside.0,
                INTIMATE_M,
                &mut self.metrics.intimate_intrusions,
            );
            update(
                &mut inside.1,
                PERSONAL_M,
                &mut self.metrics.personal_intrusions,
            );
        }
    }

    /// After a step that moved the robot `distance_m` and turned it `turn_rad` (either way),
    /// under the robot's `limits`: the line [`SocialMetrics::limit_time_s`] times.
    pub fn moved(&mut self, distance_m: f64, turn_rad: f64, limits: LineLimits) {
        if distance_m.is_finite() && turn_rad.is_finite() {
            self.line.push((distance_m, turn_rad));
            self.limits = Some(limits);
        }
    }

    /// The metrics so far.
    pub fn metrics(&self) -> SocialMetrics {
        let limit_time_s = self
            .limits
            .map(|l| limit_time_between(&self.line, &l, self.start_speed, None))
            .filter(|t| t.is_finite())
            .unwrap_or(0.0);
        SocialMetrics {
            limit_time_s,
            ..self.metrics
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn person(x: f64) -> ((f64, f64), f64) {
        ((x, 0.0), 0.25)
    }

    #[test]
    fn an_approach_counts_once_and_a_second_approach_again() {
        let mut t = SocialTracker::default();
        // Robot (radius 0.3) at the origin, a person walking in and out twice.
        for x in [3.0, 1.5, 1.0, 0.9, 1.01, 0.95, 2.5, 1.0, 3.0] {
            t.step((0.0, 0.0), 0.3, 0.5, 0.1, &[person(x)]);
        }
        let m = t.metrics();
        // Gaps: 2.45, 0.95, 0.45, 0.35 (intimate), 0.46 (still inside: hysteresis), 0.40,
        // 1.95 (out of both), 0.45, 2.45.
        assert_eq!(m.intimate_intrusions, 1, "{m:?}");
        assert_eq!(m.personal_intrusions, 2, "{m:?}");
        assert!(m.time_not_moving_s.abs() < 1e-12);
        t.step((0.0, 0.0), 0.3, 0.0, 0.1, &[person(3.0)]);
        assert!((t.metrics().time_not_moving_s - 0.1).abs() < 1e-12);
    }
}
