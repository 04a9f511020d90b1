//! The fit, margins and commits of [`super`].

use super::*;

fn straight(from: (f64, f64), to: (f64, f64), speed: f64, dt: f64) -> Vec<Pose2> {
    let len = (to.0 - from.0).hypot(to.1 - from.1);
    let n = (len / (speed * dt)).ceil() as usize;
    let yaw = (to.1 - from.1).atan2(to.0 - from.0);
    (0..=n)
        .map(|k| {
            let s = k as f64 / n as f64;
            Pose2::new(
                from.0 + s * (to.0 - from.0),
                from.1 + s * (to.1 - from.1),
                yaw,
            )
        })
        .collect()
}

fn template(robot: &str, start_ms: i64) -> Itinerary {
    Itinerary {
        plan_id: format!("p-{robot}"),
        robot: robot.to_owned(),
        floor: "F".to_owned(),
        start_unix_ms: start_ms,
        trajectory: Vec::new(),
        radius_m: 0.2,
        tolerance_s: 1.0,
        expires_unix_ms: start_ms + 5_000,
        delay_s: 0.0,
        revision: 1,
    }
}

fn committed(robot: &str, steps: &[Pose2], dt: f64, start_ms: i64) -> Itinerary {
    Draft {
        steps,
        dt,
        waits: Vec::new(),
    }
    .itinerary(&template(robot, start_ms))
}

/// Robot B's [`fit`] from `start_ms` along `steps` (one every 0.1 s) past `waypoints` among
/// `others`, waiting up to `max_wait_s`, set off `start_wait_s` late.
fn fit_b(
    start_ms: i64,
    steps: &[Pose2],
    waypoints: &[Point2],
    others: &[Itinerary],
    max_wait_s: f64,
    start_wait_s: f64,
) -> Result<Fitted, NoFit> {
    fit(
        &template("B", start_ms),
        steps,
        0.1,
        waypoints,
        others,
        max_wait_s,
        start_wait_s,
    )
}

/// [`fit_b`] with up to 120 s of waits, set off on time: it fits, and keeps the margins from
/// every one of `others`.
fn fits_b(start_ms: i64, steps: &[Pose2], waypoints: &[Point2], others: &[Itinerary]) -> Fitted {
    let fitted = fit_b(start_ms, steps, waypoints, others, 120.0, 0.0).expect("a fit");
    assert!(first_conflict(&fitted.itinerary, others).is_none());
    fitted
}

#[test]
fn a_robot_crossing_anothers_path_waits_before_the_crossing() {
    let dt = 0.1;
    // A drives along y = 0 from x = -5 to 5; B crosses along x = 0 from y = -5 to 5,
    // both setting off at once at 1 m/s: they would meet at the origin after 5 s.
    let a = committed("A", &straight((-5.0, 0.0), (5.0, 0.0), 1.0, dt), dt, 0);
    let b_steps = straight((0.0, -5.0), (0.0, 5.0), 1.0, dt);
    let waypoints = [Point2::new(0.0, -3.0), Point2::new(0.0, 5.0)];
    let Fitted {
        waypoint_steps: at,
        waits,
        ..
    } = fits_b(0, &b_steps, &waypoints, std::slice::from_ref(&a));
    assert_eq!(at.len(), 2);
    assert_eq!(waits.len(), 1, "{waits:?}");
    // At the waypoint 2 m before the crossing, for A.
    assert_eq!(waits[0].step, at[0]);
    assert_eq!(waits[0].for_robots, vec!["A".to_owned()]);
    assert!(
        waits[0].wait_s >= 1.0 && waits[0].wait_s <= 10.0,
        "{waits:?}"
    );
}

#[test]
fn robots_sent_down_one_corridor_from_both_ends_do_not_meet_in_it() {
    let dt = 0.1;
    // A drives the corridor y = 0 from x = 0 to 10. B comes the other way, from a side
    // room at (12, 3) to the corridor's far end (10, 0) and on to x = 0.
    let a = committed("A", &straight((0.0, 0.0), (10.0, 0.0), 1.0, dt), dt, 0);
    let mut b_steps = straight((12.0, 3.0), (10.0, 0.0), 1.0, dt);
    b_steps.extend(
        straight((10.0, 0.0), (0.0, 0.0), 1.0, dt)
            .into_iter()
            .skip(1),
    );
    let waypoints = [Point2::new(10.0, 0.0), Point2::new(0.0, 0.0)];
    let Fitted { waits, .. } = fits_b(0, &b_steps, &waypoints, std::slice::from_ref(&a));
    // The corridor's end is in A's way (A arrives there): B waits at its start instead.
    assert_eq!(waits.len(), 1, "{waits:?}");
    assert_eq!(waits[0].step, 0, "a later start: {waits:?}");
}

/// B must let C cross its way ahead; waiting at its start it would stand in A's way, who
/// passes through B's start meanwhile. So B leaves at once and lets C pass at its first
/// waypoint.
#[test]
fn a_robot_waits_ahead_rather_than_at_a_start_another_robot_passes_through() {
    let dt = 0.1;
    let b_steps = straight((0.0, 0.0), (10.0, 0.0), 1.0, dt);
    let waypoints = [Point2::new(4.0, 0.0), Point2::new(10.0, 0.0)];
    let c = committed("C", &straight((6.0, -5.0), (6.0, 5.0), 1.0, dt), dt, 0);
    let a = committed("A", &straight((0.0, -3.5), (0.0, 5.0), 1.0, dt), dt, 0);
    // C alone: B waits at its start.
    let Fitted { waits, .. } = fit_b(
        0,
        &b_steps,
        &waypoints,
        std::slice::from_ref(&c),
        120.0,
        0.0,
    )
    .unwrap();
    assert_eq!(waits.first().map(|w| w.step), Some(0), "{waits:?}");
    // With A through its start: B waits at the first waypoint, and nowhere else.
    let others = [c.clone(), a.clone()];
    let Fitted {
        waypoint_steps: at,
        waits,
        ..
    } = fits_b(0, &b_steps, &waypoints, &others);
    assert_eq!(
        waits.iter().map(|w| w.step).collect::<Vec<_>>(),
        vec![at[0]],
        "{waits:?}"
    );
    assert!(waits[0].for_robots.contains(&"C".to_owned()), "{waits:?}");
    // Told to stand at its start until A has passed through it, B has no fit: the
    // schedule holds a robot at its start while it waits there, and A meets it.
    let e = fit_b(0, &b_steps, &waypoints, &others, 120.0, 3.0).unwrap_err();
    assert!(e.robots.contains(&"A".to_owned()), "{e:?}");
    assert_eq!(e.earliest_start_unix_ms, None, "{e:?}");
    // Among C alone, a start 6 s later is standing at the start from the plan's start.
    let Fitted {
        itinerary: it,
        waits,
        ..
    } = fit_b(
        0,
        &b_steps,
        &waypoints,
        std::slice::from_ref(&c),
        120.0,
        6.0,
    )
    .unwrap();
    assert!(waits[0].step == 0 && waits[0].wait_s >= 6.0, "{waits:?}");
    assert_eq!(it.start_unix_ms, 0);
    assert_eq!(it.pose_at(5_000), Some((0.0, 0.0)));
    assert!(first_conflict(&it, std::slice::from_ref(&c)).is_none());
}

#[test]
fn without_enough_time_the_plan_is_refused_with_the_earliest_start_that_fits() {
    let dt = 0.1;
    let a = committed("A", &straight((-5.0, 0.0), (5.0, 0.0), 1.0, dt), dt, 0);
    let b_steps = straight((0.0, -5.0), (0.0, 5.0), 1.0, dt);
    let e = fit_b(
        0,
        &b_steps,
        &[Point2::new(0.0, 5.0)],
        std::slice::from_ref(&a),
        0.0,
        0.0,
    )
    .unwrap_err();
    assert_eq!(e.robots, vec!["A".to_owned()]);
    let t = e.earliest_start_unix_ms.expect("A's itinerary expires");
    assert!(t > 0);
    assert!(e.message.contains("earliest start"), "{}", e.message);
}

#[test]
fn a_robot_following_another_to_its_goal_waits_before_the_goal_until_it_is_free() {
    let dt = 0.1;
    // A drives to (10, 0) and is held there 5 s (its template's hold); B takes the same
    // path 3 s later.
    let path = straight((0.0, 0.0), (10.0, 0.0), 1.0, dt);
    let a = committed("A", &path, dt, 0);
    let waypoints = [Point2::new(5.0, 0.0), Point2::new(10.0, 0.0)];
    let Fitted {
        waypoint_steps: at,
        waits,
        ..
    } = fits_b(3_000, &path, &waypoints, std::slice::from_ref(&a));
    assert!(!waits.is_empty());
    assert!(
        waits.iter().all(|w| w.step != at[1]),
        "never at the goal: {waits:?}"
    );
}

#[test]
fn a_start_inside_a_robot_held_there_is_refused_naming_it_with_no_later_start() {
    let dt = 0.1;
    // A ends at (0, 0) and is held there; B would set off from (0, 0) meanwhile.
    let a = committed("A", &straight((-5.0, 0.0), (0.0, 0.0), 1.0, dt), dt, 0);
    let b_steps = straight((0.0, 0.0), (0.0, 5.0), 1.0, dt);
    let e = fit_b(
        6_000,
        &b_steps,
        &[Point2::new(0.0, 5.0)],
        std::slice::from_ref(&a),
        3.0,
        0.0,
    )
    .unwrap_err();
    assert_eq!(e.robots, vec!["A".to_owned()]);
    // B stands at its start until it sets off, where A is held: no later start helps.
    assert_eq!(e.earliest_start_unix_ms, None, "{e:?}");
}

/// A robot standing with no plan is not waited out (when it leaves is not known): the fit
/// names it at once. One standing beside the way is passed with the still margin.
#[test]
fn a_robot_standing_in_the_way_with_no_plan_is_named_at_once() {
    let dt = 0.1;
    let steps = straight((0.0, 0.0), (10.0, 0.0), 1.0, dt);
    let standing = |y: f64| Itinerary {
        trajectory: vec![TimedPose {
            t_s: 0.0,
            x: 5.0,
            y,
            yaw: 0.0,
        }],
        expires_unix_ms: 30_000,
        ..template("S", 0)
    };
    assert!(stands_only(&standing(0.3)));
    let e = fit_b(
        0,
        &steps,
        &[Point2::new(10.0, 0.0)],
        &[standing(0.3)],
        120.0,
        0.0,
    )
    .unwrap_err();
    assert_eq!(e.robots, vec!["S".to_owned()]);
    assert_eq!(e.earliest_start_unix_ms, None);
    assert!(e.message.contains("no plan of its own"), "{}", e.message);
    // 0.6 m between centres of 0.2 m robots: a 0.2 m gap, more than STILL_MARGIN_M and
    // less than ROBOT_MARGIN_M.
    let Fitted { waits, .. } = fits_b(0, &steps, &[Point2::new(10.0, 0.0)], &[standing(0.6)]);
    assert!(waits.is_empty(), "{waits:?}");
}

#[test]
fn waypoints_are_found_along_the_steps_in_order() {
    let steps = straight((0.0, 0.0), (10.0, 0.0), 1.0, 0.1);
    let at = waypoint_steps(&steps, &[Point2::new(3.0, 0.2), Point2::new(10.0, 0.0)]);
    assert_eq!(at, vec![30, steps.len() - 1]);
}

/// A plan's set-off is the end of its stay at its first pose, on the clock of the start asked
/// for: so a later start tried after a refused drive goes past the start the fit already gave.
#[test]
fn set_off_is_the_end_of_the_first_stay() {
    let steps = straight((0.0, 0.0), (2.0, 0.0), 0.5, 0.1);
    let moving_at_once = committed("A", &steps, 0.1, 10_000);
    assert_eq!(set_off_s(&moving_at_once, 10_000), 0.0);
    // Committed to start 3 s after the start asked for, waiting 4.5 s there first.
    let waiting = Draft {
        steps: &steps,
        dt: 0.1,
        waits: vec![(0, 4.5)],
    }
    .itinerary(&template("A", 13_000));
    assert!((set_off_s(&waiting, 10_000) - 7.5).abs() < 1e-9);
    // A start asked for after the itinerary's own is never before 0.
    assert_eq!(set_off_s(&moving_at_once, 20_000), 0.0);
}

/// Fitted again on a drive that held at its start and at waypoint 1, with new waits at the
/// start, at waypoint 1 and at waypoint 2: each old hold ends later by the new waits at or
/// before it, and waits at one point are one wait.
#[test]
fn waits_fitted_on_a_drive_join_the_holds_it_was_driven_with() {
    let wait = |waypoint: Option<usize>, wait_s: f64, not_before_unix_ms: i64, robot: &str| Wait {
        waypoint,
        wait_s,
        not_before_unix_ms,
        for_robots: vec![robot.to_owned()],
    };
    let old = [wait(None, 2.0, 2_000, "A"), wait(Some(1), 5.0, 20_000, "B")];
    // Waypoints 0, 1 and 2 reached at steps 50, 150 and 300 of the drive.
    let at_steps = [50, 150, 300];
    let new = vec![
        wait(None, 1.0, 1_000, "C"),
        wait(Some(1), 3.0, 19_000, "B"),
        wait(Some(2), 4.0, 40_000, "D"),
    ];
    let merged = merge_waits(&old, new, &at_steps);
    assert_eq!(
        merged,
        vec![
            Wait {
                for_robots: vec!["A".to_owned(), "C".to_owned()],
                ..wait(None, 3.0, 3_000, "")
            },
            wait(Some(1), 8.0, 24_000, "B"),
            wait(Some(2), 4.0, 40_000, "D"),
        ]
    );
    // Nothing new: the holds as driven.
    assert_eq!(merge_waits(&old, Vec::new(), &at_steps), old.to_vec());
}
