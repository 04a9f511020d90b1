//! Validation names the item and field of every problem and never panics.

use sim::{Occupancy, Pose3, Severity, Shape, Size3, World, WorldSpec};

use crate::common::{object, room};

fn problems_of(spec: &WorldSpec) -> Vec<(Severity, String, String)> {
    spec.validate()
        .0
        .into_iter()
        .map(|p| (p.severity, p.item, p.field))
        .collect()
}

fn has(problems: &[(Severity, String, String)], sev: Severity, item: &str, field: &str) -> bool {
    problems
        .iter()
        .any(|(s, i, f)| *s == sev && i == item && f == field)
}

#[test]
fn a_good_room_has_no_problems() {
    assert!(room(5.0, 5.0).validate().is_empty());
}

#[test]
fn bad_objects_are_named_with_their_fields() {
    let mut spec = room(5.0, 5.0);
    spec.objects.push(object(
        "neg",
        None,
        Shape::Box,
        Size3::new(-1.0, 1.0, 1.0),
        Pose3::new(1.0, 1.0, 0.5, 0.0),
    ));
    spec.objects.push(object(
        "nan",
        None,
        Shape::Box,
        Size3::new(1.0, 1.0, 1.0),
        Pose3::new(f64::NAN, 1.0, 0.5, 0.0),
    ));
    spec.objects.push(object(
        "nan",
        None,
        Shape::Box,
        Size3::new(1.0, 1.0, 1.0),
        Pose3::new(2.0, 1.0, 0.5, 0.0),
    ));
    let mut tilted = object(
        "tilt",
        None,
        Shape::Box,
        Size3::new(1.0, 1.0, 1.0),
        Pose3::new(2.0, 2.0, 0.0, 0.0),
    );
    tilted.pose.roll = 0.3;
    spec.objects.push(tilted);
    spec.objects.push(object(
        "egg",
        None,
        Shape::Sphere,
        Size3::new(1.0, 1.0, 2.0),
        Pose3::new(3.0, 3.0, 1.0, 0.0),
    ));
    let p = problems_of(&spec);
    assert!(has(&p, Severity::Error, "neg", "size.x"), "{p:?}");
    assert!(has(&p, Severity::Error, "nan", "pose"), "{p:?}");
    assert!(has(&p, Severity::Error, "nan", "id"), "duplicate: {p:?}");
    assert!(has(&p, Severity::Warning, "tilt", "pose"), "{p:?}");
    assert!(
        has(&p, Severity::Warning, "tilt", "pose.z"),
        "below the floor: {p:?}"
    );
    assert!(has(&p, Severity::Warning, "egg", "size"), "{p:?}");
    let err = World::build(spec).expect_err("errors stop the build");
    assert!(err.has_errors());
    assert!(err.to_string().contains("neg size.x"), "{err}");
}

#[test]
fn bad_robots_and_maps_are_named_with_their_fields() {
    let mut spec = room(5.0, 5.0);
    spec.robot.footprint_radius = 0.0;
    spec.robot.drive.wheel_separation = f64::INFINITY;
    spec.robot.laser.range_max = 0.01;
    spec.robot.laser.samples = 0;
    spec.robot.laser.mount.z = -1.0;
    if let Some(f) = spec.floor.as_mut() {
        f.grid.resolution = 0.0;
        f.grid.cells.pop();
    }
    let p = problems_of(&spec);
    assert!(
        has(&p, Severity::Error, "example_robot", "footprint_radius"),
        "{p:?}"
    );
    assert!(
        has(
            &p,
            Severity::Error,
            "example_robot",
            "drive.wheel_separation"
        ),
        "{p:?}"
    );
    assert!(has(&p, Severity::Error, "laser", "range_max"), "{p:?}");
    assert!(has(&p, Severity::Error, "laser", "samples"), "{p:?}");
    assert!(has(&p, Severity::Error, "laser", "mount.z"), "{p:?}");
    assert!(has(&p, Severity::Error, "room", "resolution"), "{p:?}");
    assert!(has(&p, Severity::Error, "room", "cells"), "{p:?}");
    assert!(World::build(spec).is_err());
}

#[test]
fn a_map_with_no_free_cell_is_an_error() {
    let mut spec = room(2.0, 2.0);
    if let Some(f) = spec.floor.as_mut() {
        f.grid.cells.fill(Occupancy::Unknown);
    }
    assert!(has(&problems_of(&spec), Severity::Error, "room", "cells"));
}

#[test]
fn a_world_without_a_map_is_bounded_around_its_items() {
    let mut spec = room(5.0, 5.0);
    spec.floor = None;
    spec.walls.push(sim::WallSpec {
        id: "b1".into(),
        start: [0.0, 0.0],
        end: [6.0, 0.0],
        thickness: 0.1,
        height: 2.0,
    });
    spec.objects.push(object(
        "box",
        None,
        Shape::Box,
        Size3::new(1.0, 1.0, 1.0),
        Pose3::new(3.0, 3.0, 0.5, 0.0),
    ));
    let world = World::build(spec.clone()).expect("builds");
    // The wall along y = 0 (0.05 m either side, rasterised by cell centres) is seen from above.
    let d = world.cast_ray(3.0, 1.0, -std::f64::consts::FRAC_PI_2, 10.0);
    assert!((d - 0.95).abs() < 0.051, "{d}");
    spec.walls.clear();
    spec.objects.clear();
    let err = World::build(spec).expect_err("nothing to bound");
    assert!(has(
        &err.0
            .iter()
            .map(|p| (p.severity, p.item.clone(), p.field.clone()))
            .collect::<Vec<_>>(),
        Severity::Error,
        "test-room",
        "floor"
    ));
}

#[test]
fn bad_people_knowledge_is_named_with_its_fields() {
    use sim::{AttractorSpec, PeoplePlaceSpec, RouteSpec};
    let mut spec = room(5.0, 5.0);
    let place = |id: &str| PeoplePlaceSpec {
        id: id.into(),
        expected: 1.0,
        by_hour: vec![(9, 2.0)],
        boundary: vec![[1.0, 1.0], [4.0, 1.0], [4.0, 4.0]],
    };
    let fine = place("fine");
    let mut counts = place("counts");
    counts.expected = f64::NAN;
    counts.by_hour = vec![(24, 1.0), (9, -1.0), (9, 2.0)];
    counts.boundary = vec![[1.0, 1.0], [f64::INFINITY, 2.0]];
    spec.people.places = vec![fine.clone(), counts, fine];
    spec.people.routes = vec![
        RouteSpec {
            id: "short".into(),
            points: vec![[1.0, 1.0]],
        },
        RouteSpec {
            id: "wild".into(),
            points: vec![[1.0, 1.0], [f64::NAN, 2.0], [40.0, 2.0]],
        },
    ];
    spec.people.attractors = vec![
        AttractorSpec {
            id: "idle".into(),
            position: [2.0, 2.0],
            dwell_s: -3.0,
        },
        AttractorSpec {
            id: "lost".into(),
            position: [-7.0, 2.0],
            dwell_s: 10.0,
        },
    ];
    let p = problems_of(&spec);
    assert!(has(&p, Severity::Error, "fine", "id"), "duplicate: {p:?}");
    assert!(has(&p, Severity::Error, "counts", "expected"), "{p:?}");
    assert!(
        has(&p, Severity::Error, "counts", "by_hour[0].hour"),
        "{p:?}"
    );
    assert!(
        has(&p, Severity::Error, "counts", "by_hour[1].people"),
        "{p:?}"
    );
    assert!(
        has(&p, Severity::Error, "counts", "by_hour[2].hour"),
        "hour twice: {p:?}"
    );
    assert!(has(&p, Severity::Error, "counts", "boundary"), "{p:?}");
    assert!(has(&p, Severity::Error, "counts", "boundary[1]"), "{p:?}");
    assert!(has(&p, Severity::Error, "short", "points"), "{p:?}");
    assert!(has(&p, Severity::Error, "wild", "points[1]"), "{p:?}");
    assert!(
        has(&p, Severity::Warning, "wild", "points[2]"),
        "off the map: {p:?}"
    );
    assert!(has(&p, Severity::Error, "idle", "dwell_s"), "{p:?}");
    assert!(
        has(&p, Severity::Warning, "lost", "position"),
        "off the map: {p:?}"
    );
    assert!(!has(&p, Severity::Error, "lost", "dwell_s"), "{p:?}");
    let err = World::build(spec).expect_err("errors stop the build");
    assert!(err.to_string().contains("counts by_hour[0].hour"), "{err}");

    // Knowledge that says nothing, or says it well, is no problem.
    let mut spec = room(5.0, 5.0);
    spec.people.places = vec![place("fine")];
    spec.people.routes = vec![RouteSpec {
        id: "along".into(),
        points: vec![[1.0, 1.0], [4.0, 4.0]],
    }];
    assert!(spec.validate().is_empty(), "{}", spec.validate());
}
