//! Execution by precedence: where a plan meets another (their footprints' paths overlap, at
//! whatever times), the order the schedule gives them there ([`passings`]). A robot that keeps
//! these orders never meets another, however late either is: it waits before a meeting place
//! until the robot that passes first has passed it ([`Passing::passed`], from that robot's
//! progress reports).

use crate::itinerary::{Itinerary, add_seconds};
use crate::revision::Planned;

/// Where plan `of` meets another plan and passes after it.
#[derive(Debug, Clone, PartialEq)]
pub struct Passing {
    /// The plan passing first.
    pub plan_id: String,
    /// Its robot.
    pub robot: String,
    /// Where the paths first overlap, metres (a pose of this plan).
    pub x: f64,
    /// Where the paths first overlap, metres.
    pub y: f64,
    /// This plan's trajectory time there (before its delay), seconds: it goes no further than
    /// the pose before it until the other has passed.
    pub t_s: f64,
    /// The other plan's trajectory time when it has left the place, seconds.
    pub their_exit_t_s: f64,
    /// Whether the other robot has passed: its progress reports matched it beyond
    /// `their_exit_t_s`.
    pub passed: bool,
}

/// The places `of` meets each of `others` (paths within both radii and `gap_m`) where the
/// other one is scheduled there first, in `of`'s order along its trajectory. Robots standing
/// (one pose) are not passed but routed around, and are left out.
pub fn passings(of: &Itinerary, others: &[Planned], gap_m: f64) -> Vec<Passing> {
    let mut out = Vec::new();
    for other in others {
        let o = &other.itinerary;
        if o.plan_id == of.plan_id || o.trajectory.len() < 2 || of.trajectory.len() < 2 {
            continue;
        }
        let reach = of.radius_m + o.radius_m + gap_m;
        if !boxes_meet(bounds(of), bounds(o), reach) {
            continue;
        }
        let near = |x: f64, y: f64| {
            o.trajectory
                .iter()
                .position(|p| (p.x - x).hypot(p.y - y) < reach)
        };
        let mut i = 0;
        while i < of.trajectory.len() {
            let p = of.trajectory[i];
            let Some(j) = near(p.x, p.y) else {
                i += 1;
                continue;
            };
            // The meeting: this plan's poses near the other's path from here on.
            let mut end = i;
            while end + 1 < of.trajectory.len() {
                let q = of.trajectory[end + 1];
                if near(q.x, q.y).is_none() {
                    break;
                }
                end += 1;
            }
            // The order is the committed schedule's, delays aside: a late robot keeps its turn,
            // and the robots after it wait for it.
            let mine = add_seconds(of.start_unix_ms, p.t_s);
            let theirs = add_seconds(o.start_unix_ms, o.trajectory[j].t_s);
            if theirs < mine {
                let exit = last_near(o, &of.trajectory[i..=end], reach);
                out.push(Passing {
                    plan_id: o.plan_id.clone(),
                    robot: o.robot.clone(),
                    x: p.x,
                    y: p.y,
                    t_s: p.t_s,
                    their_exit_t_s: exit,
                    passed: other.progress_t_s.is_some_and(|t| t >= exit),
                });
            }
            i = end + 1;
        }
    }
    out.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    out
}

/// A trajectory's bounding box: (min x, min y, max x, max y).
fn bounds(it: &Itinerary) -> [f64; 4] {
    it.trajectory.iter().fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |[a, b, c, d], p| [a.min(p.x), b.min(p.y), c.max(p.x), d.max(p.y)],
    )
}

fn boxes_meet(a: [f64; 4], b: [f64; 4], reach: f64) -> bool {
    a[0] - reach <= b[2] && b[0] - reach <= a[2] && a[1] - reach <= b[3] && b[1] - reach <= a[3]
}

/// The other plan's last trajectory time near any of `poses`.
fn last_near(o: &Itinerary, poses: &[crate::TimedPose], reach: f64) -> f64 {
    o.trajectory
        .iter()
        .rev()
        .find(|q| poses.iter().any(|p| (p.x - q.x).hypot(p.y - q.y) < reach))
        .map_or(0.0, |q| q.t_s)
}

/// How far along its trajectory the robot of `of` may go now, seconds of trajectory time:
/// up to the first meeting whose other robot has not passed yet (`None`: to its goal).
pub fn may_go_until_s(passings: &[Passing]) -> Option<f64> {
    passings.iter().find(|p| !p.passed).map(|p| p.t_s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TimedPose;

    fn line(id: &str, from: (f64, f64), to: (f64, f64), start_ms: i64) -> Itinerary {
        let trajectory = (0..=80)
            .map(|k| {
                let u = f64::from(k) / 80.0;
                TimedPose {
                    t_s: f64::from(k) * 0.25,
                    x: from.0 + u * (to.0 - from.0),
                    y: from.1 + u * (to.1 - from.1),
                    yaw: 0.0,
                }
            })
            .collect();
        Itinerary {
            plan_id: id.into(),
            robot: format!("robot-{id}"),
            floor: "f".into(),
            start_unix_ms: start_ms,
            trajectory,
            radius_m: 0.3,
            tolerance_s: 1.0,
            expires_unix_ms: start_ms + 60_000,
            delay_s: 0.0,
            revision: 1,
        }
    }

    fn planned(it: Itinerary, progress_t_s: Option<f64>) -> Planned {
        Planned {
            itinerary: it,
            acknowledged: 1,
            progress_t_s,
        }
    }

    #[test]
    fn a_crossing_is_passed_in_the_order_of_the_schedule_and_released_by_progress() {
        // Two robots crossing at (10, 0): A there at 10 s, B (starting 5 s later) at 15 s.
        let a = line("a", (0.0, 0.0), (20.0, 0.0), 0);
        let b = line("b", (10.0, -10.0), (10.0, 10.0), 5_000);
        let of_b = passings(&b, &[planned(a.clone(), None)], 0.1);
        assert_eq!(of_b.len(), 1, "{of_b:?}");
        let p = &of_b[0];
        assert_eq!((p.plan_id.as_str(), p.passed), ("a", false));
        assert!((p.x - 10.0).abs() < 1.5 && p.y < 0.0, "{p:?}");
        assert!(p.their_exit_t_s > 10.0 && p.their_exit_t_s < 12.0, "{p:?}");
        assert_eq!(may_go_until_s(&of_b), Some(p.t_s));
        // A passes first: nothing holds it.
        assert!(passings(&a, &[planned(b.clone(), None)], 0.1).is_empty());
        // A reported past the crossing: B may go on to its goal.
        let released = passings(&b, &[planned(a.clone(), Some(12.0))], 0.1);
        assert!(released[0].passed);
        assert_eq!(may_go_until_s(&released), None);
        // A delayed by 10 s (its progress): B still passes after it, and waits for it.
        let late_a = Itinerary { delay_s: 10.0, ..a };
        let waits = passings(&b, &[planned(late_a, Some(2.0))], 0.1);
        assert_eq!(may_go_until_s(&waits), Some(waits[0].t_s));
        // Paths that never come near: no passing.
        let far = line("c", (0.0, 5.0), (20.0, 5.0), 0);
        assert!(passings(&far, &[planned(b, None)], 0.1).is_empty());
    }
}
