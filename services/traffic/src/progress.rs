//! Where a progress report puts a robot on its own schedule, and so how late it is.
//!
//! The reported position is matched to the trajectory searched forward from the last match
//! (a path that passes the same place twice is not matched to a pass the robot already made).
//! Positions near the reported one form "passes" (consecutive pieces of the trajectory within
//! the robot's radius of the closest distance); of each pass its closest point counts, and of
//! those the one whose time is nearest to where the current delay expects the robot wins, so an
//! out-and-back corridor is matched on the right leg. A robot standing where its schedule has it
//! wait (before its start, at a wait, after its end) is on time anywhere within the wait: the
//! delay changes only if it is still there after the wait should have ended. One pass over the
//! poses: O(n).

use crate::itinerary::{Itinerary, seconds_between};

/// The closest distance below which a matched position counts as on the path, metres, for
/// robots whose radius is smaller.
const MIN_SLACK_M: f64 = 0.05;
/// Two distances closer than this are equal, metres.
const SAME_M: f64 = 1e-9;

/// Where a report matched the schedule.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Matched {
    /// The trajectory time matched, seconds after the start (before the delay).
    pub t_s: f64,
    /// The observed delay: the report's time minus the matched time, seconds.
    pub delay_s: f64,
}

/// A candidate: a piece of the trajectory, its distance to the report and the time matched.
#[derive(Debug, Clone, Copy)]
struct Candidate {
    distance: f64,
    t_s: f64,
}

/// Matches a report at `(x, y)` at `at_unix_ms` to `itinerary`, searching from trajectory time
/// `from_t_s` (the last match) on. `None` for an empty trajectory.
pub(crate) fn match_progress(
    itinerary: &Itinerary,
    from_t_s: Option<f64>,
    at_unix_ms: i64,
    x: f64,
    y: f64,
) -> Option<Matched> {
    let poses = &itinerary.trajectory;
    let first = poses.first()?;
    let last = poses.last()?;
    let elapsed = seconds_between(itinerary.start_unix_ms, at_unix_ms);
    let expected = elapsed - itinerary.delay_s;
    let from = from_t_s
        .filter(|t| t.is_finite())
        .unwrap_or(f64::NEG_INFINITY);
    let distance_to = |px: f64, py: f64| (px - x).hypot(py - y);

    // Pieces in time order: waiting at the first pose before the start, each segment (from
    // `from` on), parked at the last pose after the end.
    let mut candidates = Vec::with_capacity(poses.len() + 1);
    if from <= first.t_s {
        candidates.push(Candidate {
            distance: distance_to(first.x, first.y),
            t_s: expected.min(first.t_s),
        });
    }
    for pair in poses.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        if b.t_s < from {
            continue;
        }
        let span = b.t_s - a.t_s;
        // The part of the segment at or after `from`.
        let u0 = if from > a.t_s && span > 0.0 {
            ((from - a.t_s) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (ax, ay) = (a.x + u0 * (b.x - a.x), a.y + u0 * (b.y - a.y));
        let t0 = a.t_s + u0 * span;
        let (dx, dy) = (b.x - ax, b.y - ay);
        let length2 = dx * dx + dy * dy;
        let candidate = if length2 <= SAME_M * SAME_M {
            // A wait: on time anywhere within it.
            Candidate {
                distance: distance_to(b.x, b.y),
                t_s: expected.clamp(t0.min(b.t_s), b.t_s),
            }
        } else {
            let u = (((x - ax) * dx + (y - ay) * dy) / length2).clamp(0.0, 1.0);
            Candidate {
                distance: distance_to(ax + u * dx, ay + u * dy),
                t_s: t0 + u * (b.t_s - t0),
            }
        };
        candidates.push(candidate);
    }
    candidates.push(Candidate {
        distance: distance_to(last.x, last.y),
        t_s: expected.max(last.t_s),
    });

    let closest = candidates
        .iter()
        .map(|c| c.distance)
        .filter(|d| !d.is_nan())
        .fold(f64::INFINITY, f64::min);
    let slack = if itinerary.radius_m.is_finite() {
        itinerary.radius_m.max(MIN_SLACK_M)
    } else {
        MIN_SLACK_M
    };
    let near = closest + slack;
    // Of a pass, the closest point (on a tie, the time nearest the expected one); of the
    // passes, the one nearest the expected time (on a tie, the earlier).
    let off_time = |c: &Candidate| (c.t_s - expected).abs();
    let better_in_pass = |c: &Candidate, best: &Candidate| {
        c.distance < best.distance - SAME_M
            || (c.distance <= best.distance + SAME_M && off_time(c) < off_time(best))
    };
    let mut chosen: Option<Candidate> = None;
    let mut pass: Option<Candidate> = None;
    let close_pass = |pass: Candidate, chosen: &mut Option<Candidate>| {
        if chosen.is_none_or(|best| off_time(&pass) < off_time(&best)) {
            *chosen = Some(pass);
        }
    };
    for c in &candidates {
        if c.distance <= near {
            pass = match pass {
                Some(best) if !better_in_pass(c, &best) => Some(best),
                _ => Some(*c),
            };
        } else if let Some(done) = pass.take() {
            close_pass(done, &mut chosen);
        }
    }
    if let Some(done) = pass.take() {
        close_pass(done, &mut chosen);
    }
    // Every distance NaN (a NaN report): keep the schedule where it expects the robot.
    let t_s = chosen.map_or(expected, |c| c.t_s);
    let t_s = if t_s.is_finite() { t_s } else { first.t_s };
    Some(Matched {
        t_s,
        delay_s: elapsed - t_s,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)] // reason: tests panic on failure

    use super::*;
    use crate::itinerary::TimedPose;

    const START: i64 = 1_000_000;

    /// A corridor along x from 0 to 10 m at 1 m/s, then back to 0 (out and back), radius 0.3 m.
    fn out_and_back() -> Itinerary {
        let mut trajectory: Vec<TimedPose> = (0..=10)
            .map(|i| TimedPose {
                t_s: f64::from(i),
                x: f64::from(i),
                y: 0.0,
                yaw: 0.0,
            })
            .collect();
        trajectory.extend((1..=10).map(|i| TimedPose {
            t_s: f64::from(10 + i),
            x: f64::from(10 - i),
            y: 0.0,
            yaw: std::f64::consts::PI,
        }));
        Itinerary {
            plan_id: "p".into(),
            robot: "r".into(),
            floor: "f".into(),
            start_unix_ms: START,
            trajectory,
            radius_m: 0.3,
            tolerance_s: 1.0,
            expires_unix_ms: START + 60_000,
            delay_s: 0.0,
            revision: 1,
        }
    }

    fn at(seconds: f64) -> i64 {
        crate::itinerary::add_seconds(START, seconds)
    }

    #[test]
    fn a_late_robot_is_matched_on_the_leg_it_drives() {
        let it = out_and_back();
        // At x = 3 m at 5 s: on the way out (scheduled 3 s), 2 s late; not the way back (17 s).
        let m = match_progress(&it, None, at(5.0), 3.0, 0.02).unwrap();
        assert!((m.t_s - 3.0).abs() < 1e-9, "{m:?}");
        assert!((m.delay_s - 2.0).abs() < 1e-9, "{m:?}");
        // At x = 3 m again at 18 s, searched on from the last match: the way back, 1 s late.
        let m = match_progress(&it, Some(m.t_s), at(18.0), 3.0, -0.02).unwrap();
        assert!((m.t_s - 17.0).abs() < 1e-9, "{m:?}");
        assert!((m.delay_s - 1.0).abs() < 1e-9, "{m:?}");
    }

    #[test]
    fn a_robot_waiting_at_its_start_is_not_early() {
        let it = out_and_back();
        let m = match_progress(&it, None, at(-30.0), 0.0, 0.0).unwrap();
        assert_eq!(m.delay_s, 0.0, "{m:?}");
        // Still at the start 4 s after it: 4 s late.
        let m = match_progress(&it, None, at(4.0), 0.0, 0.0).unwrap();
        assert!((m.delay_s - 4.0).abs() < 1e-9, "{m:?}");
    }

    #[test]
    fn a_robot_parked_at_its_goal_keeps_its_delay() {
        let mut it = out_and_back();
        it.delay_s = 1.5;
        let m = match_progress(&it, Some(20.0), at(40.0), 0.0, 0.0).unwrap();
        assert!((m.delay_s - 1.5).abs() < 1e-9, "{m:?}");
    }

    #[test]
    fn a_nan_report_changes_nothing() {
        let it = out_and_back();
        let m = match_progress(&it, None, at(5.0), f64::NAN, 0.0).unwrap();
        assert!(m.delay_s.is_finite(), "{m:?}");
        assert!(
            match_progress(
                &Itinerary {
                    trajectory: vec![],
                    ..it
                },
                None,
                0,
                0.0,
                0.0
            )
            .is_none()
        );
    }
}
