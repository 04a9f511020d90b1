//! Laser ray casts and clearance against cases with known answers.

use std::f64::consts::{FRAC_PI_2, PI};

use sim::{Pose2, Pose3, Shape, Size3, World};

use crate::common::{RES, box_exit, object, room, room_at};

#[test]
fn ray_to_a_wall_at_a_known_distance() {
    let world = World::build(room(10.0, 6.0)).expect("room builds");
    // Inside the ring of wall cells, the free interior ends at x = 9.95.
    let d = world.cast_ray(2.0, 3.0, 0.0, 20.0);
    assert!((d - 7.95).abs() < 1e-9, "{d}");
    let d = world.cast_ray(2.0, 3.0, PI, 20.0);
    assert!((d - 1.95).abs() < 1e-9, "{d}");
    let d = world.cast_ray(2.0, 3.0, FRAC_PI_2, 20.0);
    assert!((d - 2.95).abs() < 1e-9, "{d}");
    // Capped at the range.
    assert_eq!(world.cast_ray(2.0, 3.0, 0.0, 5.0), 5.0);
}

#[test]
fn rays_in_every_direction_match_the_analytic_box() {
    let world = World::build(room(12.0, 7.0)).expect("room builds");
    let inner = [RES, RES, 12.0 - RES, 7.0 - RES];
    let origins = [
        (2.0, 3.0),
        (6.123, 0.4567),
        (11.9, 6.9),
        (0.06, 0.06),
        (5.5, 3.5),
    ];
    for (x, y) in origins {
        for k in 0..720 {
            let a = k as f64 * PI / 360.0 + 1e-3;
            let want = box_exit(x, y, a, inner);
            let got = world.cast_ray(x, y, a, 100.0);
            assert!(
                (got - want).abs() < 1e-9,
                "from ({x}, {y}) at {a}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn a_rotated_and_shifted_map_is_cast_in_its_own_frame() {
    let origin = Pose2::new(-3.2, 7.7, 0.4);
    let world = World::build(room_at(8.0, 5.0, origin)).expect("room builds");
    let (s, c) = origin.yaw.sin_cos();
    let inner = [RES, RES, 8.0 - RES, 5.0 - RES];
    for (lx, ly) in [(1.0, 1.0), (4.0, 2.5), (7.5, 4.5)] {
        let (x, y) = (origin.x + c * lx - s * ly, origin.y + s * lx + c * ly);
        for k in 0..90 {
            let local = k as f64 * PI / 45.0 + 0.01;
            let want = box_exit(lx, ly, local, inner);
            let got = world.cast_ray(x, y, local + origin.yaw, 100.0);
            assert!((got - want).abs() < 1e-9, "{got} vs {want}");
        }
        let clear = world.wall_clearance(x, y) + world.spec().robot.footprint_radius;
        let want = (lx - RES)
            .min(ly - RES)
            .min(8.0 - RES - lx)
            .min(5.0 - RES - ly);
        assert!((clear - want).abs() < 1e-9, "{clear} vs {want}");
    }
}

#[test]
fn a_ray_starting_in_a_wall_or_outside_the_map_reads_zero() {
    let world = World::build(room(5.0, 5.0)).expect("room builds");
    assert_eq!(world.cast_ray(0.01, 2.0, 0.0, 10.0), 0.0);
    assert_eq!(world.cast_ray(-3.0, 2.0, 0.0, 10.0), 0.0);
    assert_eq!(world.cast_ray(f64::NAN, 2.0, 0.0, 10.0), 0.0);
}

#[test]
fn a_table_is_seen_through_its_legs_not_its_top() {
    // Table 1.2 x 0.8 x 0.75 m centred at (5, 3); the laser is at 0.3 m, under the top.
    let mut spec = room(10.0, 6.0);
    spec.objects.push(object(
        "table1",
        Some("http://example.org/tosm#Table"),
        Shape::Box,
        Size3::new(1.2, 0.8, 0.75),
        Pose3::new(5.0, 3.0, 0.375, 0.0),
    ));
    let world = World::build(spec.clone()).expect("builds");
    // Between the legs the ray passes under the top to the far wall.
    assert!((world.cast_ray(2.0, 3.0, 0.0, 20.0) - 7.95).abs() < 1e-9);
    // Towards a leg: legs are 0.05 m square in the corners, so the near leg's face is at
    // x = 5 - 0.6 = 4.4 and spans y in [3.35, 3.4].
    let d = world.cast_ray(2.0, 3.375, 0.0, 20.0);
    assert!((d - 2.4).abs() < 1e-9, "{d}");
    // The same table as a placeholder box (unknown class) is solid at laser height.
    let mut solid = spec.clone();
    solid.objects[0].class = Some("tosm:VendingMachine".into());
    let w2 = World::build(solid).expect("builds");
    assert!((w2.cast_ray(2.0, 3.0, 0.0, 20.0) - 2.4).abs() < 1e-9);
    // A laser above the top sees the top.
    let mut high = spec.clone();
    high.robot.laser.mount.z = 0.8;
    high.robot.height = 1.0;
    let w3 = World::build(high).expect("builds");
    assert!(
        (w3.cast_ray(2.0, 3.0, 0.0, 20.0) - 7.95).abs() < 1e-9,
        "nothing at 0.8 m"
    );
    let mut top = spec;
    top.robot.laser.mount.z = 0.74;
    top.robot.height = 1.0;
    let w4 = World::build(top).expect("builds");
    assert!(
        (w4.cast_ray(2.0, 3.0, 0.0, 20.0) - 2.4).abs() < 1e-9,
        "the top at 0.74 m"
    );
}

#[test]
fn the_robot_collides_with_what_is_lower_than_itself() {
    let mut spec = room(10.0, 6.0);
    spec.objects.push(object(
        "table1",
        Some("Table"),
        Shape::Box,
        Size3::new(1.2, 0.8, 0.75),
        Pose3::new(5.0, 3.0, 0.375, 0.0),
    ));
    let low = World::build(spec.clone()).expect("builds");
    // A 0.4 m robot fits under the 0.71 m-high top, between the legs.
    let c = low.clearance(5.0, 3.0);
    assert!(c > 0.1, "under the table: {c}");
    // Next to a leg: the leg at x in [5.55, 5.6], y in [3.35, 3.4]; the robot centred 0.3 m to
    // its right (x = 5.9) has 0.1 m of clearance.
    let c = low.clearance(5.9, 3.375);
    assert!((c - 0.1).abs() < 1e-6, "{c}");
    // A robot taller than the table hits the top.
    spec.robot.height = 1.0;
    let tall = World::build(spec).expect("builds");
    assert!(tall.clearance(5.0, 3.0) <= 0.0);
}

#[test]
fn clearance_to_walls_is_exact() {
    let world = World::build(room(10.0, 6.0)).expect("builds");
    // The wall's free side is at x = 9.95; the robot's radius is 0.2.
    let c = world.clearance(9.70, 3.0);
    assert!((c - 0.05).abs() < 1e-9, "{c}");
    let c = world.clearance(9.5, 5.5);
    let want = 0.45f64.min(0.45) - 0.2;
    assert!((c - want).abs() < 1e-9, "{c}");
    assert!(world.clearance(9.99, 3.0) < 0.0);
}

#[test]
fn knows_within_answers_as_the_clearance_does() {
    let mut spec = room(10.0, 6.0);
    spec.objects.push(object(
        "pillar",
        Some("Pillar"),
        Shape::Cylinder,
        Size3::new(0.6, 0.6, 2.0),
        Pose3::new(5.0, 3.0, 1.0, 0.0),
    ));
    let world = World::build(spec).expect("builds");
    let radius = world.spec().robot.footprint_radius;
    let mut checked = 0;
    // A grid of points over the room and beyond it, near walls, near the pillar, in the open.
    for i in -10..=210 {
        for j in -10..=130 {
            let (x, y) = (f64::from(i) * 0.0497, f64::from(j) * 0.0503);
            let seen = world.clearance(x, y) + radius;
            for d in [0.0, 0.05, 0.15, 0.5] {
                if (seen - d).abs() < 1e-9 {
                    continue;
                }
                assert_eq!(
                    world.knows_within(x, y, d),
                    seen <= d,
                    "({x}, {y}) within {d}"
                );
                checked += 1;
            }
        }
    }
    assert!(checked > 100_000, "{checked}");
    // The pillar counts: 0.1 m off its side, nothing the walls explain.
    assert!(world.knows_within(5.4, 3.0, 0.15));
    assert!(!world.knows_within(5.6, 3.0, 0.15));
}

#[test]
fn cylinders_spheres_and_rotated_boxes_are_hit_exactly() {
    let mut spec = room(10.0, 10.0);
    spec.objects.push(object(
        "pillar",
        Some("Pillar"),
        Shape::Cylinder,
        Size3::new(0.6, 0.6, 2.0),
        Pose3::new(5.0, 5.0, 1.0, 0.0),
    ));
    spec.objects.push(object(
        "ball",
        None,
        Shape::Sphere,
        Size3::new(1.0, 1.0, 1.0),
        Pose3::new(2.0, 8.0, 0.3, 0.0),
    ));
    spec.objects.push(object(
        "crate",
        None,
        Shape::Box,
        Size3::new(1.0, 1.0, 1.0),
        Pose3::new(8.0, 2.0, 0.5, PI / 4.0),
    ));
    let world = World::build(spec).expect("builds");
    // Ray along y = 5 from x = 1 meets the pillar's surface at x = 4.7.
    assert!((world.cast_ray(1.0, 5.0, 0.0, 20.0) - 3.7).abs() < 1e-9);
    // The sphere's centre is at the laser's height: a 0.5 m circle.
    assert!((world.cast_ray(0.5, 8.0, 0.0, 20.0) - 1.0).abs() < 1e-9);
    // A box turned 45°: its corner points at the ray, 0.5·√2 from the centre.
    let d = world.cast_ray(4.0, 2.0, 0.0, 20.0);
    assert!((d - (4.0 - 0.5 * 2f64.sqrt())).abs() < 1e-9, "{d}");
}

#[test]
fn scans_use_the_mounting_pose_and_clamp_to_the_range() {
    let world = World::build(room(30.0, 6.0)).expect("builds");
    let laser = world.spec().robot.laser.clone();
    let angles = laser.beam_angles(23).expect("23 of 690 samples");
    assert_eq!(angles.len(), 23);
    assert!((angles[0] + PI / 2.0).abs() < 1e-12 && (angles[22] - PI / 2.0).abs() < 1e-12);
    let mut out = vec![0.0; 23];
    // Facing +x from (2, 3): the middle beam starts at x = 2.1 (mount) and is capped at 10 m.
    world.scan(Pose2::new(2.0, 3.0, 0.0), &angles, &mut out);
    assert_eq!(out[11], laser.range_max);
    // Facing -x: the middle beam (sample 345 of 690, just left of straight ahead) ends on the
    // wall at x = 0.05, from the laser at x = 1.9.
    world.scan(Pose2::new(2.0, 3.0, PI), &angles, &mut out);
    let want = box_exit(1.9, 3.0, PI + angles[11], [RES, RES, 30.0 - RES, 6.0 - RES]);
    assert!(
        (out[11] - want).abs() < 1e-9 && (want - 1.85).abs() < 1e-4,
        "{}",
        out[11]
    );
    // Rightmost beam (-90°) facing -x points to +y: wall at 5.95.
    assert!((out[0] - 2.95).abs() < 1e-9, "{}", out[0]);
}

/// Two robots of one model on one floor share a geometry key (and so configuration spaces and
/// roadmaps) whatever their names; the robot's size, a cell of the floor or an object changes it.
#[test]
fn the_geometry_key_names_the_floor_and_the_robots_size_not_the_robot() {
    let key = |spec: sim::WorldSpec| World::build(spec).unwrap().geometry_key().to_owned();
    let base = key(room(6.0, 4.0));
    let mut renamed = room(6.0, 4.0);
    renamed.robot.id = "https://example.org/robots/another".into();
    renamed.id = "another mission".into();
    assert_eq!(key(renamed), base);
    let mut wider = room(6.0, 4.0);
    wider.robot.footprint_radius += 0.05;
    assert_ne!(key(wider), base);
    let mut blocked = room(6.0, 4.0);
    if let Some(f) = blocked.floor.as_mut() {
        f.grid.cells[f.grid.width * 20 + 30] = sim::Occupancy::Occupied;
    }
    assert_ne!(key(blocked), base);
    let mut furnished = room(6.0, 4.0);
    furnished.objects.push(object(
        "box",
        None,
        Shape::Box,
        Size3::new(0.5, 0.5, 0.5),
        Pose3::new(3.0, 2.0, 0.25, 0.0),
    ));
    assert_ne!(key(furnished), base);
}
