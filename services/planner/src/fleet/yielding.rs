//! Making way. Robots standing with no plan, each in the only way of another's plan (a
//! cycle: A's plan waits for B's, B's for A's), would wait for each other until both are
//! refused, and every robot whose way either of them stands in after them. The plans of this
//! process that wait for standing robots say so here ([`Waits`]) and in the schedule, where
//! the plans of other processes sharing it are seen; where the waits close a
//! cycle, one robot of it (the first by IRI that has not already failed to) makes way: its
//! plan goes first to a place near its start off the routes of the plans waiting for it
//! ([`spot_off_routes`]), and that first leg is committed ([`prefix`]) so the others' plans can
//! be fitted; its whole plan then waits there for them, as any plan waits.

use std::collections::{HashMap, HashSet};
use std::sync::{Arc, Mutex, PoisonError};

use prm::Point2;

use crate::fleet;

/// How far from its start a robot looks for a place to make way at, metres.
pub(crate) const MAKE_WAY_WITHIN_M: f64 = 6.0;
/// Spacing of the places tried, metres.
const SPOT_STEP_M: f64 = 0.2;

/// The plans of this process waiting for standing robots, by robot. The schedule holds them
/// too ([`crate::FleetSchedule::post_wait`]), so those of other processes sharing it are seen.
#[derive(Debug, Default)]
pub(crate) struct Waits(Mutex<HashMap<String, traffic::Wait>>);

/// Removes its robot's entry from [`Waits`] when dropped.
pub(crate) struct Entered {
    waits: Arc<Waits>,
    robot: String,
}

impl Drop for Entered {
    fn drop(&mut self) {
        self.waits.lock().remove(&self.robot);
    }
}

/// Another plan's route the robot making way keeps clear of: its points and radius.
pub(crate) type Route = (Vec<(f64, f64)>, f64);

impl Waits {
    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<String, traffic::Wait>> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// `wait.robot`'s plan waits as `wait` until the returned guard is dropped.
    pub(crate) fn enter(self: &Arc<Self>, wait: traffic::Wait) -> Entered {
        let robot = wait.robot.clone();
        self.lock().insert(robot.clone(), wait);
        Entered {
            waits: Arc::clone(self),
            robot,
        }
    }

    /// `robot` found no place to make way at: another robot of its cycle takes its turn. Its
    /// wait as it is now, to be said to the schedule.
    pub(crate) fn cannot_make_way(&self, robot: &str) -> Option<traffic::Wait> {
        let mut waits = self.lock();
        let w = waits.get_mut(robot)?;
        w.cannot_make_way = true;
        Some(w.clone())
    }

    /// Where `robot`'s wait closes a cycle of waits (this process's, and `shared`: those the
    /// schedule holds, of every process) and it is the robot of the cycle to make way: the
    /// routes of the plans waiting for it (with the waiting robots' names), which the place it
    /// makes way at keeps clear of. `None` otherwise.
    pub(crate) fn turn_to_make_way(
        &self,
        robot: &str,
        shared: &[traffic::Wait],
    ) -> Option<(Vec<Route>, Vec<String>)> {
        let mut waits: HashMap<String, traffic::Wait> = shared
            .iter()
            .map(|w| (w.robot.clone(), w.clone()))
            .collect();
        // This process's own are the newest word on its plans.
        waits.extend(self.lock().iter().map(|(k, w)| (k.clone(), w.clone())));
        let me = waits.get(robot)?;
        let floor = &me.floor;
        let edges = |r: &str| -> Vec<String> {
            waits
                .get(r)
                .filter(|w| &w.floor == floor)
                .map(|w| w.by.clone())
                .unwrap_or_default()
        };
        // The cycle through `robot`: those it reaches through waits that reach it back.
        let reach = |from: &str, forward: bool| -> HashSet<String> {
            let mut seen = HashSet::new();
            let mut todo = vec![from.to_owned()];
            while let Some(r) = todo.pop() {
                let next: Vec<String> = if forward {
                    edges(&r)
                } else {
                    waits
                        .iter()
                        .filter(|(_, w)| &w.floor == floor && w.by.contains(&r))
                        .map(|(k, _)| k.clone())
                        .collect()
                };
                for n in next {
                    if seen.insert(n.clone()) {
                        todo.push(n);
                    }
                }
            }
            seen
        };
        let ahead = reach(robot, true);
        if !ahead.contains(robot) {
            return None;
        }
        let behind = reach(robot, false);
        let first = ahead
            .intersection(&behind)
            .filter(|r| waits.get(r.as_str()).is_some_and(|w| !w.cannot_make_way))
            .min()?;
        if first != robot {
            return None;
        }
        let mut waiting_for_me: Vec<(&String, &traffic::Wait)> = waits
            .iter()
            .filter(|(k, w)| *k != robot && &w.floor == floor && w.by.iter().any(|b| b == robot))
            .collect();
        waiting_for_me.sort_by(|a, b| a.0.cmp(b.0));
        Some((
            waiting_for_me
                .iter()
                .map(|(_, w)| (w.route.clone(), w.radius_m))
                .collect(),
            waiting_for_me.iter().map(|(k, _)| (*k).clone()).collect(),
        ))
    }
}

/// The nearest place to `from` (within [`MAKE_WAY_WITHIN_M`], by steps of [`SPOT_STEP_M`]
/// the robot of `radius_m` fits along: `fits` is the footprint's clearance from walls and
/// objects at a point) that keeps the robots' moving margin from every point of `routes` and
/// the standing margin from every robot of `standing` (centre, radius); `None` where there is
/// none.
pub(crate) fn spot_off_routes(
    from: (f64, f64),
    radius_m: f64,
    fits: impl Fn(f64, f64) -> f64,
    routes: &[Route],
    standing: &[((f64, f64), f64)],
) -> Option<Point2> {
    let clear_of_standing = |x: f64, y: f64| {
        standing
            .iter()
            .all(|((sx, sy), r)| (x - sx).hypot(y - sy) >= radius_m + r + fleet::STILL_MARGIN_M)
    };
    let off_routes = |x: f64, y: f64| {
        routes.iter().all(|(points, r)| {
            let keep = radius_m + r + fleet::ROBOT_MARGIN_M;
            points.iter().all(|(px, py)| (x - px).hypot(y - py) >= keep)
        })
    };
    // Breadth first over a lattice around `from`, through places the robot fits at.
    let k = (MAKE_WAY_WITHIN_M / SPOT_STEP_M).ceil() as i64;
    let side = (2 * k + 1) as usize;
    let at = |i: i64, j: i64| {
        (
            from.0 + i as f64 * SPOT_STEP_M,
            from.1 + j as f64 * SPOT_STEP_M,
        )
    };
    let mut seen = vec![false; side * side];
    let index = |i: i64, j: i64| ((i + k) as usize) * side + (j + k) as usize;
    seen[index(0, 0)] = true;
    let mut queue = std::collections::VecDeque::from([(0i64, 0i64)]);
    while let Some((i, j)) = queue.pop_front() {
        let (x, y) = at(i, j);
        // Room around it to stand and turn, besides the footprint.
        if (i, j) != (0, 0) && fits(x, y) > fleet::STILL_MARGIN_M && off_routes(x, y) {
            return Some(Point2::new(x, y));
        }
        for (di, dj) in [
            (1, 0),
            (-1, 0),
            (0, 1),
            (0, -1),
            (1, 1),
            (1, -1),
            (-1, 1),
            (-1, -1),
        ] {
            let (ni, nj) = (i + di, j + dj);
            if ni.abs() > k || nj.abs() > k || seen[index(ni, nj)] {
                continue;
            }
            seen[index(ni, nj)] = true;
            let (nx, ny) = at(ni, nj);
            if (nx - from.0).hypot(ny - from.1) <= MAKE_WAY_WITHIN_M
                && fits(nx, ny) > 0.0
                && clear_of_standing(nx, ny)
            {
                queue.push_back((ni, nj));
            }
        }
    }
    None
}

/// Points along `steps` about every `every_m` metres, the last one always kept.
pub(crate) fn route_points(steps: &[sim::Pose2], every_m: f64) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (k, p) in steps.iter().enumerate() {
        let far = out
            .last()
            .is_none_or(|(x, y)| (p.x - x).hypot(p.y - y) >= every_m);
        if far || k + 1 == steps.len() {
            out.push((p.x, p.y));
        }
    }
    out
}

/// The first leg of a plan making way, as the schedule holds it until the whole plan is
/// committed: `template`'s robot standing at its start for `set_off_s` seconds, then driving
/// `steps` up to the step `at_step` where it reached the place, then standing there until
/// `for_s` seconds after it set off.
pub(crate) fn prefix(
    template: &traffic::Itinerary,
    steps: &[sim::Pose2],
    at_step: usize,
    control_period_s: f64,
    set_off_s: f64,
    for_s: f64,
) -> traffic::Itinerary {
    let end = at_step.min(steps.len().saturating_sub(1));
    let mut driven = fleet::driven(
        template,
        template.start_unix_ms,
        &steps[..=end],
        control_period_s,
    );
    if set_off_s > 0.0 {
        for p in &mut driven.trajectory {
            p.t_s += set_off_s;
        }
        if let Some(first) = driven.trajectory.first() {
            let stand = traffic::TimedPose { t_s: 0.0, ..*first };
            driven.trajectory.insert(0, stand);
        }
    }
    traffic::Itinerary {
        expires_unix_ms: template.start_unix_ms
            + ((set_off_s + end as f64 * control_period_s + for_s) * 1000.0).round() as i64,
        ..driven
    }
}

/// The delays, seconds, a first leg making way is tried with before it is given up: it meets
/// a plan committed meanwhile, or one whose route its own crosses.
pub(crate) const SET_OFF_DELAYS_S: [f64; 7] = [0.0, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0];

#[cfg(test)]
mod tests {
    use super::*;

    fn waiting(robot: &str, by: &[&str], route: Vec<(f64, f64)>) -> traffic::Wait {
        traffic::Wait {
            robot: robot.to_owned(),
            floor: "F".to_owned(),
            by: by.iter().map(|s| (*s).to_owned()).collect(),
            route,
            radius_m: 0.3,
            cannot_make_way: false,
            until_unix_ms: i64::MAX,
        }
    }

    /// In a cycle of waits the first robot by IRI makes way, and only it; a robot merely
    /// waiting behind the cycle does not; once it cannot, the next one of the cycle does.
    #[test]
    fn one_robot_of_a_cycle_of_waits_makes_way() {
        let waits = Arc::new(Waits::default());
        let _a = waits.enter(waiting("a", &["b"], vec![(1.0, 0.0)]));
        assert!(waits.turn_to_make_way("a", &[]).is_none(), "no cycle yet");
        let _b = waits.enter(waiting("b", &["a"], vec![(2.0, 0.0)]));
        let _c = waits.enter(waiting("c", &["a"], vec![(3.0, 0.0)]));
        let (routes, names) = waits.turn_to_make_way("a", &[]).expect("a makes way");
        assert_eq!(names, vec!["b".to_owned(), "c".to_owned()]);
        assert_eq!(routes.len(), 2);
        assert!(waits.turn_to_make_way("b", &[]).is_none(), "b waits for a");
        assert!(
            waits.turn_to_make_way("c", &[]).is_none(),
            "c is behind the cycle"
        );
        waits.cannot_make_way("a");
        assert!(waits.turn_to_make_way("a", &[]).is_none());
        let (_, names) = waits.turn_to_make_way("b", &[]).expect("now b makes way");
        assert_eq!(names, vec!["a".to_owned()]);
        drop(_b);
        assert!(
            waits.turn_to_make_way("a", &[]).is_none(),
            "b left: no cycle"
        );
    }

    /// Waits of another process, read from the schedule, close a cycle as this process's own
    /// do; this process's word on its own plan wins over what the schedule still says.
    #[test]
    fn waits_of_other_processes_close_cycles_too() {
        let here = Arc::new(Waits::default());
        let _a = here.enter(waiting("a", &["b"], vec![(1.0, 0.0)]));
        let elsewhere = [waiting("b", &["a"], vec![(2.0, 0.0)])];
        let (routes, names) = here.turn_to_make_way("a", &elsewhere).expect("a makes way");
        assert_eq!((names, routes.len()), (vec!["b".to_owned()], 1));
        // The schedule still holds a's wait as it was posted; here it found no place.
        let posted = [elsewhere[0].clone(), waiting("a", &["b"], vec![(1.0, 0.0)])];
        let told = here.cannot_make_way("a").expect("a waits");
        assert!(told.cannot_make_way);
        assert!(here.turn_to_make_way("a", &posted).is_none());
        // b's process finds it is b's turn, from the schedule alone.
        let there = Waits::default();
        let shared = [told, elsewhere[0].clone()];
        assert!(there.turn_to_make_way("b", &shared).is_some());
    }

    /// The place made way at is the nearest one off the route the robot reaches through places
    /// it fits at, clear of robots standing; none where walls leave no such place.
    #[test]
    fn the_place_to_make_way_is_the_nearest_off_the_routes() {
        // A corridor along x, 1 m wide (|y| < 0.5), with an alcove at x in [2, 3] up to y = 2.
        let fits = |x: f64, y: f64| {
            let half = if (2.0..=3.0).contains(&x) && y > 0.0 {
                2.0
            } else {
                0.5
            };
            let wall = if y > 0.0 { half - y } else { 0.5 + y };
            wall - 0.3
        };
        // The route runs the corridor's length, beyond where the robot looks.
        let route: Vec<(f64, f64)> = (-50..=50).map(|i| (i as f64 * 0.2, 0.0)).collect();
        let spot = spot_off_routes((1.0, 0.0), 0.3, fits, &[(route.clone(), 0.3)], &[])
            .expect("the alcove");
        assert!((2.0..=3.0).contains(&spot.x), "{spot:?}");
        let keep = 0.6 + fleet::ROBOT_MARGIN_M;
        assert!(spot.y >= keep - 1e-9, "{spot:?}");
        // A robot standing in the alcove's mouth: it cannot get in.
        let standing = [((2.5, 0.2), 0.3)];
        assert!(
            spot_off_routes((1.0, 0.0), 0.3, fits, &[(route.clone(), 0.3)], &standing).is_none()
        );
        // Without the alcove there is no place off the route.
        let narrow = |_: f64, y: f64| 0.2 - y.abs();
        assert!(spot_off_routes((1.0, 0.0), 0.3, narrow, &[(route, 0.3)], &[]).is_none());
    }

    /// The first leg is driven up to the place and held there until it expires.
    #[test]
    fn the_first_leg_is_held_at_the_place() {
        let template = traffic::Itinerary {
            plan_id: "p".to_owned(),
            robot: "a".to_owned(),
            floor: "F".to_owned(),
            start_unix_ms: 1_000,
            trajectory: Vec::new(),
            radius_m: 0.3,
            tolerance_s: 2.0,
            expires_unix_ms: 0,
            delay_s: 0.0,
            revision: 1,
        };
        let steps: Vec<sim::Pose2> = (0..=20)
            .map(|k| sim::Pose2::new(0.1 * k as f64, 0.0, 0.0))
            .collect();
        let it = prefix(&template, &steps, 10, 0.1, 0.0, 30.0);
        let last = it.trajectory.last().expect("poses");
        assert!((last.x - 1.0).abs() < 1e-9 && (last.t_s - 1.0).abs() < 1e-9);
        assert_eq!(it.expires_unix_ms, 1_000 + 31_000);
        assert!(!fleet::stands_only(&it));
        // Set off 4 s late: at its start until then.
        let late = prefix(&template, &steps, 10, 0.1, 4.0, 30.0);
        assert_eq!(late.pose_at(1_000 + 3_900), Some((0.0, 0.0)));
        let last = late.trajectory.last().expect("poses");
        assert!((last.x - 1.0).abs() < 1e-9 && (last.t_s - 5.0).abs() < 1e-9);
        assert_eq!(late.expires_unix_ms, 1_000 + 35_000);
    }
}
