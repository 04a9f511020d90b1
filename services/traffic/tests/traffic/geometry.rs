//! Conflicts between timed trajectories, and where an itinerary puts its robot.

#![allow(clippy::unwrap_used)] // reason: tests panic on failure

use traffic::{Conflict, Itinerary, TimedPose, conflicts, first_conflict};

const START: i64 = 1_700_000_000_000;
const MARGIN: f64 = 0.1;

/// `robot` from `from` to `to` at 1 m/s, a pose every 0.25 s, starting `start_s` after
/// `START`, radius 0.3 m, no tolerance, expiring when it arrives.
fn drive(robot: &str, from: [f64; 2], to: [f64; 2], start_s: f64) -> Itinerary {
    let length = (to[0] - from[0]).hypot(to[1] - from[1]);
    let steps = (length / 0.25).ceil();
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // reason: small counts
    let n = steps as usize;
    let trajectory = (0..=n)
        .map(|i| {
            #[allow(clippy::cast_precision_loss)] // reason: small counts
            let u = i as f64 / steps;
            TimedPose {
                t_s: u * length,
                x: from[0] + u * (to[0] - from[0]),
                y: from[1] + u * (to[1] - from[1]),
                yaw: 0.0,
            }
        })
        .collect();
    let start = ms(START, start_s);
    Itinerary {
        plan_id: format!("plan-{robot}"),
        robot: robot.to_owned(),
        floor: "f1".to_owned(),
        start_unix_ms: start,
        trajectory,
        radius_m: 0.3,
        tolerance_s: 0.0,
        expires_unix_ms: ms(start, length),
        delay_s: 0.0,
        revision: 1,
    }
}

fn ms(base: i64, seconds: f64) -> i64 {
    #[allow(clippy::cast_possible_truncation)] // reason: test times
    let delta = (seconds * 1000.0).round() as i64;
    base + delta
}

/// Seconds after `START` of a conflict.
fn when(conflict: &Conflict) -> f64 {
    #[allow(clippy::cast_precision_loss)] // reason: test times
    let s = (conflict.at_unix_ms - START) as f64 / 1000.0;
    s
}

/// Checks that `a` and `b` conflict between `from_s` and `to_s` after `START` (both ways
/// round), or not at all when `expected` is `None`.
fn check(a: &Itinerary, b: &Itinerary, expected: Option<(f64, f64)>) {
    for (x, y) in [(a, b), (b, a)] {
        let found = first_conflict(x, y, MARGIN);
        match (expected, &found) {
            (None, None) => {}
            (Some((from_s, to_s)), Some(c)) => {
                let t = when(c);
                assert!(
                    from_s <= t && t <= to_s,
                    "conflict at {t} s, expected in [{from_s}, {to_s}]: {c:?}"
                );
                assert!(c.distance_m < x.radius_m + y.radius_m + MARGIN, "{c:?}");
                assert_eq!(
                    (c.a_robot.as_str(), c.b_robot.as_str()),
                    (x.robot.as_str(), y.robot.as_str())
                );
            }
            _ => panic!("expected {expected:?}, found {found:?}"),
        }
    }
}

/// Head-on down a corridor, 10 m, 1 m/s each: the centres close at 2 m/s and are 0.7 m apart
/// (two radii and the margin) at 4.65 s.
#[test]
fn head_on_robots_in_a_corridor_conflict_when_they_meet() {
    let a = drive("a", [0.0, 0.0], [10.0, 0.0], 0.0);
    let b = drive("b", [10.0, 0.0], [0.0, 0.0], 0.0);
    check(&a, &b, Some((4.5, 4.7)));
}

/// The same corridor used one after the other: the second robot leaving the far end 1 s after
/// the first arrived there, or following 3 m behind, meets nothing. Entering from 2 m beyond
/// the far end 2 s before the first arrives, it meets the first at 9.65 s.
#[test]
fn the_same_paths_apart_in_time_do_not_conflict() {
    let a = drive("a", [0.0, 0.0], [10.0, 0.0], 0.0);
    check(&a, &drive("b", [10.0, 0.0], [0.0, 0.0], 11.0), None);
    check(&a, &drive("b", [0.0, 0.0], [10.0, 0.0], 3.0), None);
    check(
        &a,
        &drive("b", [12.0, 0.0], [0.0, 0.0], 8.0),
        Some((9.5, 9.75)),
    );
}

/// Following 2 m behind is safe on time; a tolerance of 1 s each makes it a conflict (either
/// may be a metre off), and tolerances make a head-on conflict earlier: the centres may meet
/// 0.7 m apart when `10 − 2t − 2` (each a metre closer) reaches 0.7, at 3.65 s.
#[test]
fn a_tolerance_widens_the_window() {
    let mut a = drive("a", [0.0, 0.0], [10.0, 0.0], 0.0);
    let mut b = drive("b", [0.0, 0.0], [10.0, 0.0], 2.0);
    check(&a, &b, None);
    a.tolerance_s = 1.0;
    b.tolerance_s = 1.0;
    assert!(first_conflict(&a, &b, MARGIN).is_some());
    let mut c = drive("c", [10.0, 0.0], [0.0, 0.0], 0.0);
    c.tolerance_s = 1.0;
    check(&a, &c, Some((3.5, 3.75)));
    // One robot's tolerance is enough to widen it (to 4.15 s here).
    a.tolerance_s = 0.0;
    check(&a, &c, Some((4.0, 4.25)));
}

/// A delay shifts a robot's whole schedule: the head-on meeting moves from 4.65 s to 5.65 s
/// when the second robot is 2 s late (it is 2 m further back, they close at 2 m/s).
#[test]
fn a_delay_shifts_the_conflict() {
    let a = drive("a", [0.0, 0.0], [10.0, 0.0], 0.0);
    let mut b = drive("b", [10.0, 0.0], [0.0, 0.0], 0.0);
    b.delay_s = 2.0;
    b.expires_unix_ms += 2_000;
    check(&a, &b, Some((5.5, 5.75)));
    // Enough delay and the first robot has left the corridor (and its expiry passed).
    b.delay_s = 11.0;
    b.expires_unix_ms += 9_000;
    check(&a, &b, None);
}

/// A robot parked at its goal until its expiry blocks the robot that drives through.
#[test]
fn a_parked_robot_blocks_its_goal_until_it_expires() {
    let mut parked = drive("a", [0.0, 0.0], [5.0, 0.0], 0.0);
    parked.expires_unix_ms = ms(START, 60.0);
    // Through the goal at 5 m, 20 s after the start (arriving there at 25 s).
    let through = drive("b", [0.0, 0.0], [10.0, 0.0], 20.0);
    check(&parked, &through, Some((24.2, 24.45)));
    let later = drive("b", [0.0, 0.0], [10.0, 0.0], 60.0);
    check(&parked, &later, None);
}

/// Crossing paths conflict only if the robots are at the crossing together.
#[test]
fn crossing_paths_conflict_only_at_the_same_time() {
    let a = drive("a", [0.0, 0.0], [10.0, 0.0], 0.0);
    let b = drive("b", [5.0, -5.0], [5.0, 5.0], 0.0);
    // Both at (5, 0) at 5 s; 0.7 m apart, diagonally, about 0.5 s before.
    check(&a, &b, Some((4.4, 4.7)));
    check(&a, &drive("b", [5.0, -5.0], [5.0, 5.0], 2.0), None);
}

#[test]
fn same_robot_and_other_floors_never_conflict() {
    let a = drive("a", [0.0, 0.0], [10.0, 0.0], 0.0);
    let same = drive("a", [10.0, 0.0], [0.0, 0.0], 0.0);
    assert_eq!(first_conflict(&a, &same, MARGIN), None);
    let mut upstairs = drive("b", [10.0, 0.0], [0.0, 0.0], 0.0);
    upstairs.floor = "f2".into();
    assert_eq!(first_conflict(&a, &upstairs, MARGIN), None);
}

/// One new itinerary against several committed: the conflicting ones, earliest first.
#[test]
fn conflicts_lists_every_robot_in_the_way_earliest_first() {
    let new = drive("n", [0.0, 0.0], [20.0, 0.0], 0.0);
    let others = vec![
        drive("late", [20.0, 0.0], [10.0, 0.0], 5.0), // meet near 12.5 m at ~12.2 s
        drive("far", [0.0, 10.0], [20.0, 10.0], 0.0), // a parallel corridor
        drive("early", [8.0, 0.0], [0.0, 0.0], 0.0),  // meet near 4 m at ~3.65 s
        drive("n", [20.0, 0.0], [0.0, 0.0], 0.0),     // the same robot's old plan
    ];
    let found = conflicts(&new, &others, MARGIN);
    let robots: Vec<&str> = found.iter().map(|c| c.b_robot.as_str()).collect();
    assert_eq!(robots, ["early", "late"], "{found:?}");
    assert!(found.iter().all(|c| c.a_robot == "n"));
    assert_eq!(found[0], first_conflict(&new, &others[2], MARGIN).unwrap());
}

#[test]
fn pose_at_interpolates_parks_and_shifts_by_the_delay() {
    let mut a = drive("a", [0.0, 0.0], [10.0, 0.0], 0.0);
    a.expires_unix_ms = ms(START, 20.0);
    assert_eq!(a.pose_at(START - 1), None);
    assert_eq!(a.pose_at(START), Some((0.0, 0.0)));
    let (x, y) = a.pose_at(ms(START, 2.6)).unwrap();
    assert!((x - 2.6).abs() < 1e-9 && y == 0.0, "{x}");
    assert_eq!(a.pose_at(ms(START, 15.0)), Some((10.0, 0.0)));
    assert_eq!(a.pose_at(ms(START, 20.0)), Some((10.0, 0.0)));
    assert_eq!(a.pose_at(ms(START, 20.001)), None);
    a.delay_s = 1.5;
    assert_eq!(a.pose_at(ms(START, 1.0)), None);
    let (x, _) = a.pose_at(ms(START, 4.0)).unwrap();
    assert!((x - 2.5).abs() < 1e-9, "{x}");
    assert_eq!(a.end_unix_ms(), ms(START, 11.5));
    // Bad input gives no position rather than a panic.
    a.trajectory.clear();
    assert_eq!(a.pose_at(START), None);
    let mut nan = drive("a", [0.0, 0.0], [1.0, 0.0], 0.0);
    nan.delay_s = f64::NAN;
    assert_eq!(nan.pose_at(START), None);
    let _ = first_conflict(&nan, &drive("b", [1.0, 0.0], [0.0, 0.0], 0.0), f64::NAN);
}

/// Fifty committed robots of 2,000 poses each against a new one: every robot finishes its
/// drive on the same floor, so every pair overlaps in time.
#[test]
fn fifty_long_itineraries_are_checked_against_a_new_one() {
    let lane = |i: u32| {
        let y = 3.0 * f64::from(i);
        let mut it = drive(&format!("r{i}"), [0.0, y], [500.0, y], 0.0);
        it.tolerance_s = 2.0;
        it
    };
    let others: Vec<Itinerary> = (1..=50).map(lane).collect();
    assert!(others.iter().all(|it| it.trajectory.len() == 2_001));
    // Up the floor across every lane at 45°: it crosses lane i near x = 3i, where that lane's
    // robot has already passed (it is at x ≈ 4.2·i), except in the first lanes.
    let mut new = drive("new", [0.0, -1.0], [155.0, 154.0], 0.0);
    new.tolerance_s = 2.0;
    let found = conflicts(&new, &others, MARGIN);
    assert!(!found.is_empty());
    assert!(found.windows(2).all(|w| w[0].at_unix_ms <= w[1].at_unix_ms));
    // Each one agrees with the pairwise search.
    for c in &found {
        let other = others.iter().find(|o| o.robot == c.b_robot).unwrap();
        assert_eq!(Some(c), first_conflict(&new, other, MARGIN).as_ref());
    }
}
