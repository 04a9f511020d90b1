//! A validated plan driven again among other robots ([`rehearsal::drive_among`]): robots
//! moving along their schedules in the same simulation, seen by the laser; waits held at the
//! start and at waypoints. Real worlds (`sim`), roadmaps (`planning`) and controllers.

#![allow(clippy::unwrap_used, reason = "a test fails loudly")]

use std::sync::Arc;

use prm::Point2;
use rehearsal::{
    AttemptOutcome, ClassicalFollower, PlanOptions, PlanReport, PlanRequest, RoadmapCache,
    drive_among, validate,
};
use sim::{OtherRobot, OtherRobots, Pose2, World};

fn room() -> Arc<World> {
    fixtures::worlds::walled_room()
}

fn plan(world: &Arc<World>) -> (PlanRequest, PlanReport) {
    let request = PlanRequest {
        start: Pose2::new(2.0, 2.0, 0.0),
        goals: vec![Point2::new(7.0, 2.0)],
        options: PlanOptions::default(),
        stop: rehearsal::Stop::default(),
    };
    let report = validate(world, &RoadmapCache::default(), "room", &request, None).unwrap();
    (request, report)
}

/// `report` (validated for `request`) driven again by the classical follower among `others`
/// with `holds`.
fn among(
    world: &Arc<World>,
    (request, report): &(PlanRequest, PlanReport),
    others: &OtherRobots,
    holds: &[f64],
) -> rehearsal::AmongReport {
    drive_among(
        world,
        request,
        report,
        &mut ClassicalFollower::default(),
        None,
        others,
        holds,
        0,
    )
    .unwrap()
}

/// A robot standing at `(x, y)` from `from_s` to `to_s`.
fn standing(name: &str, (x, y): (f64, f64), from_s: f64, to_s: f64) -> OtherRobot {
    OtherRobot {
        name: name.into(),
        radius: 0.2,
        track: vec![(from_s, x, y), (to_s, x, y)],
    }
}

#[test]
fn alone_the_plan_arrives_as_rehearsed() {
    let world = room();
    let planned = plan(&world);
    let among = among(&world, &planned, &OtherRobots::default(), &[]);
    assert_eq!(among.outcome, AttemptOutcome::Reached, "{among:?}");
    assert_eq!(among.min_robot_clearance_m, None);
    assert_eq!(among.robots, 0);
    assert!(planned.1.drives_again_alike(), "{:?}", planned.1.legs);
    assert_eq!(
        among.steps, planned.1.steps,
        "driven again alone, step for step"
    );
    assert_eq!(among.time_s, planned.1.simulated_time_s);
}

/// What lets the planner commit a plan alone on its floor without driving it again: driven
/// among no robot and with no hold, a validated plan is its validating drive, step for step,
/// whichever controller and attempt validated each leg, among people and under noise.
#[test]
fn alone_every_controller_drives_its_validated_legs_again_step_for_step() {
    let world = room();
    for people in [0, 3] {
        let mut options = PlanOptions {
            seed: 11 + people as u64,
            ..PlanOptions::default()
        };
        options.people = sim::PeopleConfig {
            count: (people > 0).then_some(people),
            ..sim::PeopleConfig::default()
        };
        let request = PlanRequest {
            start: Pose2::new(2.0, 2.0, 0.0),
            goals: vec![
                Point2::new(7.5, 6.0),
                Point2::new(2.5, 6.5),
                Point2::new(7.0, 2.0),
            ],
            options,
            stop: rehearsal::Stop::default(),
        };
        let controllers: [fn() -> Box<dyn rehearsal::Controller>; 3] = [
            || Box::new(ClassicalFollower::default()),
            || Box::new(rehearsal::RppController::new()),
            || Box::new(rehearsal::MppiController::new(5)),
        ];
        for make in controllers {
            let (mut primary, mut follower) = (make(), rehearsal::follower_for(&request.options));
            let report = rehearsal::validate_with_fallback(
                &world,
                &RoadmapCache::default(),
                "room",
                &request,
                &mut *primary,
                Some(&mut *follower),
                None,
            )
            .unwrap();
            let kind = primary.kind();
            assert!(report.drives_again_alike(), "{kind:?}: {:?}", report.legs);
            let (mut primary, mut follower) = (make(), rehearsal::follower_for(&request.options));
            let again = drive_among(
                &world,
                &request,
                &report,
                &mut *primary,
                Some(&mut *follower),
                &OtherRobots::default(),
                &[],
                0,
            )
            .unwrap();
            assert_eq!(
                again.outcome,
                AttemptOutcome::Reached,
                "{kind:?}: {again:?}"
            );
            assert_eq!(
                again.steps.len(),
                report.steps.len(),
                "{kind:?}, {people} people"
            );
            assert_eq!(again.steps, report.steps, "{kind:?}, {people} people");
        }
    }
}

/// A fresh draw (`draw` ≥ 1) drives among other people and noise than the validating one, and
/// the same draw drives alike every time: the planner commits a fresh draw's drive when people
/// stopped the validating one, and a joint run drives it again from its draw.
#[test]
fn a_fresh_draw_meets_other_people_and_drives_alike_again() {
    let world = room();
    let mut options = PlanOptions {
        seed: 5,
        ..PlanOptions::default()
    };
    options.people = sim::PeopleConfig {
        count: Some(4),
        ..sim::PeopleConfig::default()
    };
    let request = PlanRequest {
        start: Pose2::new(2.0, 2.0, 0.0),
        goals: vec![Point2::new(7.5, 6.0), Point2::new(2.5, 6.5)],
        options,
        stop: rehearsal::Stop::default(),
    };
    let report = validate(&world, &RoadmapCache::default(), "room", &request, None).unwrap();
    // `validate` without a policy drives the follower behind the shield among people.
    let drive = |draw: u32| {
        let mut follower = rehearsal::follower_for(&request.options);
        drive_among(
            &world,
            &request,
            &report,
            &mut *follower,
            None,
            &OtherRobots::default(),
            &[],
            draw,
        )
        .unwrap()
    };
    let (validating, fresh, again) = (drive(0), drive(1), drive(1));
    assert_eq!(validating.people_draw, 0);
    assert_eq!(fresh.people_draw, 1);
    assert_eq!(
        validating.steps, report.steps,
        "draw 0 is the validating drive"
    );
    assert_ne!(
        fresh.steps, validating.steps,
        "a fresh draw: other people, other noise"
    );
    assert_eq!(fresh.steps, again.steps, "the same draw drives alike");
    assert_eq!(drive(2).people_draw, 2);
}

/// A robot parked on the route the whole time is met, and named; the same robot leaving
/// before the plan gets there is not.
#[test]
fn a_robot_in_the_way_is_met_and_named_and_one_gone_is_not() {
    let world = room();
    let planned = plan(&world);
    // Where the validated run passed halfway.
    let trajectory = &planned.1.trajectory;
    let mid = trajectory[trajectory.len() / 2];
    let drive = |others: OtherRobots| among(&world, &planned, &others, &[]);
    let parked = OtherRobots::new(vec![standing(
        "urn:robot:parked",
        (mid.x, mid.y),
        0.0,
        600.0,
    )])
    .unwrap();
    let met = drive(parked);
    // The classical follower has no shield: it drives into it.
    assert_eq!(met.outcome, AttemptOutcome::Collision, "{met:?}");
    assert_eq!(met.met_robot(), Some("urn:robot:parked"), "{met:?}");
    assert!(
        met.reason.contains("collision with robot urn:robot:parked"),
        "{met:?}"
    );
    let gone =
        OtherRobots::new(vec![standing("urn:robot:gone", (mid.x, mid.y), 0.0, 0.5)]).unwrap();
    let clear = drive(gone);
    assert_eq!(clear.outcome, AttemptOutcome::Reached, "{clear:?}");
    assert_eq!(clear.met_robot(), None);
}

/// A wait at the start holds the robot: it sets off after the other robot has left the route,
/// and arrives; the drive's time includes the wait.
#[test]
fn a_wait_at_the_start_lets_a_robot_pass() {
    let world = room();
    let planned = plan(&world);
    let trajectory = &planned.1.trajectory;
    let mid = trajectory[trajectory.len() / 2];
    let others = OtherRobots::new(vec![standing(
        "urn:robot:passing",
        (mid.x, mid.y),
        0.0,
        20.0,
    )])
    .unwrap();
    let run = |holds: &[f64]| among(&world, &planned, &others, holds);
    let waited = run(&[21.0]);
    assert_eq!(waited.outcome, AttemptOutcome::Reached, "{waited:?}");
    assert!(
        waited.time_s >= 21.0 + 0.5 * planned.1.simulated_time_s,
        "{waited:?}"
    );
    assert!(waited.min_robot_clearance_m.unwrap() > 0.0, "{waited:?}");
    assert_ne!(run(&[]).outcome, AttemptOutcome::Reached);
}

/// A wait at the start holds even when the route's first waypoint lies within reach of the
/// start (reached while the robot stands there): the robot still sets off only after it.
#[test]
fn a_wait_at_the_start_holds_when_the_first_waypoint_is_at_the_start() {
    let world = room();
    let (request, mut report) = plan(&world);
    report
        .waypoints
        .insert(0, Point2::new(request.start.x, request.start.y));
    for g in &mut report.goal_indices {
        *g += 1;
    }
    let planned = (request, report);
    let waited = among(&world, &planned, &OtherRobots::default(), &[21.0]);
    assert_eq!(waited.outcome, AttemptOutcome::Reached, "{waited:?}");
    let start = waited.steps[0];
    let left = waited
        .steps
        .iter()
        .position(|p| (p.x - start.x).hypot(p.y - start.y) > 0.05)
        .unwrap();
    assert!(
        left as f64 * waited.control_period_s >= 21.0 - 1e-6,
        "left the start after {} s",
        left as f64 * waited.control_period_s
    );
}

/// RPP validates the plan with the follower behind it (both classical): driven again alone,
/// the leg goes to RPP again, not to the follower, and takes about the rehearsal's time (the
/// follower stops and turns at every waypoint; it took half as long again before).
#[test]
fn alone_a_plan_rpp_validated_is_driven_by_rpp_in_about_its_time() {
    let world = room();
    let request = PlanRequest {
        start: Pose2::new(2.0, 2.0, 0.0),
        goals: vec![Point2::new(7.5, 6.0)],
        options: PlanOptions::default(),
        stop: rehearsal::Stop::default(),
    };
    let mut rpp = rehearsal::RppController::new();
    let mut follower = rehearsal::follower_for(&request.options);
    let report = rehearsal::validate_with_fallback(
        &world,
        &RoadmapCache::default(),
        "room",
        &request,
        &mut rpp,
        Some(&mut *follower),
        None,
    )
    .unwrap();
    assert!(!report.legs[0].by_fallback, "{:?}", report.legs);
    let mut rpp = rehearsal::RppController::new();
    let mut follower = rehearsal::follower_for(&request.options);
    let again = drive_among(
        &world,
        &request,
        &report,
        &mut rpp,
        Some(&mut *follower),
        &OtherRobots::default(),
        &[],
        0,
    )
    .unwrap();
    assert_eq!(again.outcome, AttemptOutcome::Reached, "{again:?}");
    let ratio = again.time_s / report.simulated_time_s;
    assert!(
        (0.8..1.2).contains(&ratio),
        "driven again in {:.1} s, rehearsed in {:.1} s",
        again.time_s,
        report.simulated_time_s
    );
}

/// Robots standing with no plan (`PlanOptions::standing`) are kept clear of by the roadmap
/// route: one in the open beside the way is driven around, one filling the only gap in the
/// inner wall leaves the goal unreachable. With a price for passing one
/// (`PlanOptions::standing_pass_m`), the short detour is still taken, and the gap is gone
/// through.
#[test]
fn the_route_keeps_clear_of_robots_standing_on_the_floor() {
    let world = room();
    let (request, alone) = plan(&world);
    let radius = world.spec().robot.footprint_radius;
    // Where the route alone passes, away from the start, the goal and the walls.
    let on_route = alone
        .waypoints
        .iter()
        .copied()
        .find(|w| w.x > 5.8 && w.y > 3.0 && w.y < 5.5)
        .expect("the route alone comes down from the gap towards the goal");
    let mut around = request.clone();
    around.options.standing = vec![(on_route, 0.2)];
    let closest_to = |report: &PlanReport, at: Point2| {
        std::iter::once(Point2::new(2.0, 2.0))
            .chain(report.waypoints.iter().copied())
            .collect::<Vec<_>>()
            .windows(2)
            .map(|w| at.distance_to_segment(w[0], w[1]))
            .fold(f64::INFINITY, f64::min)
    };
    let reach = 0.2 + radius + request.options.safety_margin_m - 1e-9;
    for pass in [f64::INFINITY, 1000.0] {
        around.options.standing_pass_m = pass;
        let report = validate(&world, &RoadmapCache::default(), "room", &around, None).unwrap();
        let closest = closest_to(&report, on_route);
        assert!(
            closest >= reach,
            "the route passes {closest:.2} m from the standing robot: {:?}",
            report.waypoints
        );
    }
    // The gap above the inner wall (x = 5, y in [6, 7.9]) held by a standing robot.
    let gap = Point2::new(5.0, 6.95);
    let mut blocked = request.clone();
    blocked.options.standing = vec![(gap, 0.2)];
    let e = validate(&world, &RoadmapCache::default(), "room", &blocked, None).unwrap_err();
    assert!(
        matches!(e, rehearsal::PlanError::Unreachable { .. }),
        "{e:?}"
    );
    // Priced, not forbidden: the route goes through the gap, past the robot standing there.
    blocked.options.standing_pass_m = 1000.0;
    let report = validate(&world, &RoadmapCache::default(), "room", &blocked, None).unwrap();
    assert!(closest_to(&report, gap) < reach, "{:?}", report.waypoints);
}
