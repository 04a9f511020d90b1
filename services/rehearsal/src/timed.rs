//! A route timed among other robots' plans (the fleet's schedule): the roadmap search of
//! [`prm::Roadmap::query_among`] asks, for each edge it would take, how long the robot
//! must wait at the edge's first node before driving it clear of every other robot's track
//! ([`Reserved`]), and takes the route that arrives first: a wait at a node, a detour, or the
//! shortest way when nothing is in it. As safe-interval path planning (Phillips and Likhachev,
//! 2011) does on a graph, with the robot's times estimated from its speed, and each other
//! robot anywhere on its track within the slack of its time.
//!
//! The route is still driven and its waits fitted afterwards (the planner's fleet fit): this
//! only keeps a route from running into what is reserved, where the fit could only make the
//! robot wait for it.

use prm::Point2;

/// Other robots' plans a route is timed among.
#[derive(Clone, Debug, PartialEq)]
pub struct Reserved {
    /// Their tracks, on the clock of the plan's start (seconds after it).
    pub robots: sim::OtherRobots,
    /// Gap kept between the robot's footprint and theirs, metres.
    pub gap_m: f64,
    /// How early or late either robot may be on its track, seconds.
    pub slack_s: f64,
    /// Longest wait at one node of the route, seconds.
    pub max_wait_s: f64,
}

/// Waits tried at a node before an edge, seconds: fine first, coarser later.
const WAITS_S: [f64; 17] = [
    0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0, 13.0, 16.0, 20.0, 25.0, 30.0, 40.0, 50.0, 60.0,
];

/// Longest piece of another robot's track checked as one segment, seconds.
const PIECE_S: f64 = 0.25;

/// [`Reserved`] as one robot's route search sees it.
pub(crate) struct TimedAmong<'a> {
    pub(crate) reserved: &'a Reserved,
    /// The robot's footprint radius, metres.
    pub(crate) radius_m: f64,
    /// The speed it covers the route at, m/s.
    pub(crate) speed_m_s: f64,
    /// When the leg sets off, seconds after the plan's start.
    pub(crate) t0_s: f64,
}

impl TimedAmong<'_> {
    /// Whether the robot, moving from `a` (at `t_a`) to `b` (at `t_b`) at a steady pace, keeps
    /// the gap from every other robot, either of them early or late by the slack.
    fn clear(&self, a: Point2, b: Point2, t_a: f64, t_b: f64) -> bool {
        let slack = self.reserved.slack_s;
        let (lo, hi) = (t_a - slack, t_b + slack);
        let span = (t_b - t_a).max(1e-9);
        // Where the robot may be while another one is where its track puts it at `t`: the part
        // of its own segment it covers within the slack of `t`.
        let own = |t: f64| {
            let f0 = ((t - slack - t_a) / span).clamp(0.0, 1.0);
            let f1 = ((t + slack - t_a) / span).clamp(0.0, 1.0);
            (a.lerp(b, f0), a.lerp(b, f1))
        };
        self.reserved.robots.robots().iter().all(|other| {
            let reach = self.radius_m + other.radius + self.reserved.gap_m;
            let track = &other.track;
            let first = track.partition_point(|s| s.0 < lo).saturating_sub(1);
            let mut k = first;
            while k + 1 < track.len() && track[k].0 <= hi {
                let (p, q) = (track[k], track[k + 1]);
                k += 1;
                if q.0 < lo {
                    continue;
                }
                // The other robot from p to q (in pieces short enough that its position is
                // known to a step), against the part of its own segment the robot covers within
                // the slack of those times. Standing still, it is one piece.
                let (from, to) = (p.0.max(lo), q.0.min(hi));
                let moving = (q.1 - p.1).hypot(q.2 - p.2) > 0.0;
                let pieces: u32 = if moving {
                    // Within a window of seconds: far below u32's range.
                    #[allow(
                        clippy::cast_possible_truncation,
                        clippy::cast_sign_loss,
                        reason = "a positive count of quarter seconds within the window"
                    )]
                    let n = ((to - from) / PIECE_S).ceil().max(1.0) as u32;
                    n
                } else {
                    1
                };
                let step = (to - from) / f64::from(pieces);
                let at = |t: f64| {
                    let f = if q.0 > p.0 {
                        (t - p.0) / (q.0 - p.0)
                    } else {
                        1.0
                    };
                    Point2::new(p.1, p.2).lerp(Point2::new(q.1, q.2), f.clamp(0.0, 1.0))
                };
                let mut t = from;
                for _ in 0..pieces {
                    let (o0, o1) = (own(t), own(t + step));
                    if segment_distance(o0.0, o1.1, at(t), at(t + step)) < reach {
                        return false;
                    }
                    t += step;
                }
            }
            true
        })
    }
}

impl prm::Reservations for TimedAmong<'_> {
    fn wait_before(&self, a: Point2, b: Point2, t_s: f64) -> Option<f64> {
        let t = self.t0_s + t_s;
        let drive = a.distance(b) / self.speed_m_s;
        let mut waited = 0.0;
        for &w in WAITS_S
            .iter()
            .take_while(|&&w| w <= self.reserved.max_wait_s)
        {
            // Standing at `a` until then must be clear too.
            if w > waited && !self.clear(a, a, t + waited, t + w) {
                return None;
            }
            waited = w;
            if self.clear(a, b, t + w, t + w + drive) {
                return Some(w);
            }
        }
        None
    }

    fn speed_m_s(&self) -> f64 {
        self.speed_m_s
    }
}

/// Distance between the segments `a`–`b` and `c`–`d` (0 where they cross).
fn segment_distance(a: Point2, b: Point2, c: Point2, d: Point2) -> f64 {
    let cross =
        |o: Point2, p: Point2, q: Point2| (p.x - o.x) * (q.y - o.y) - (p.y - o.y) * (q.x - o.x);
    let (d1, d2) = (cross(a, b, c), cross(a, b, d));
    let (d3, d4) = (cross(c, d, a), cross(c, d, b));
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return 0.0;
    }
    a.distance_to_segment(c, d)
        .min(b.distance_to_segment(c, d))
        .min(c.distance_to_segment(a, b))
        .min(d.distance_to_segment(a, b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use prm::Reservations;

    fn crossing(at_t: f64) -> Reserved {
        // Another robot crossing x = 5 from y = -5 to y = 5 over 10 s, centred at `at_t`.
        Reserved {
            robots: sim::OtherRobots::new(vec![sim::OtherRobot {
                name: "b".to_owned(),
                radius: 0.3,
                track: vec![(at_t - 5.0, 5.0, -5.0), (at_t + 5.0, 5.0, 5.0)],
            }])
            .expect("track"),
            gap_m: 0.2,
            slack_s: 1.0,
            max_wait_s: 60.0,
        }
    }

    fn among(r: &Reserved) -> TimedAmong<'_> {
        TimedAmong {
            reserved: r,
            radius_m: 0.3,
            speed_m_s: 1.0,
            t0_s: 0.0,
        }
    }

    #[test]
    fn a_robot_waits_until_the_crossing_one_has_passed() {
        // Driving (0,0) → (10,0) at 1 m/s reaches x = 5 at t = 5, when the other is there.
        let r = crossing(5.0);
        let wait = among(&r)
            .wait_before(Point2::new(0.0, 0.0), Point2::new(10.0, 0.0), 0.0)
            .expect("a wait lets it pass");
        // It must pass x = 5 after the other has gone by (1.6 m beyond y = 0, 1 s of slack):
        // at the earliest about 2.6 s later.
        assert!(wait >= 2.0, "waited {wait} s");
        assert!(wait <= 4.0, "waited {wait} s");
        // Long after, nothing is in the way.
        let later = crossing(-100.0);
        assert_eq!(
            among(&later).wait_before(Point2::new(0.0, 0.0), Point2::new(10.0, 0.0), 0.0),
            Some(0.0)
        );
    }

    #[test]
    fn no_wait_at_a_node_the_other_robot_drives_through() {
        // Waiting at (5, 0), where the other passes at t = 5: from t = 0 no wait is clear.
        let r = crossing(5.0);
        assert_eq!(
            among(&r).wait_before(Point2::new(5.0, 0.0), Point2::new(6.0, 0.0), 4.0),
            None
        );
    }

    #[test]
    fn segments_that_cross_are_at_distance_zero() {
        let p = |x, y| Point2::new(x, y);
        assert_eq!(
            segment_distance(p(0.0, 0.0), p(2.0, 2.0), p(0.0, 2.0), p(2.0, 0.0)),
            0.0
        );
        let d = segment_distance(p(0.0, 0.0), p(1.0, 0.0), p(0.0, 1.0), p(1.0, 1.0));
        assert!((d - 1.0).abs() < 1e-12);
        let d = segment_distance(p(0.0, 0.0), p(0.0, 0.0), p(3.0, 4.0), p(3.0, 4.0));
        assert!((d - 5.0).abs() < 1e-12);
    }
}
