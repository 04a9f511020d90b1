//! People in the simulation: deterministic for a seed, seen by the laser, a collision when
//! touched, apart from each other and off the walls, and walking the routes knowledge names.

use std::sync::Arc;

use sim::shield::Shield;
use sim::{
    Action, EnvConfig, NavEnv, NoiseConfig, Observation, Outcome, PeopleConfig, PeopleSpec, Pose2,
    RouteSpec, World, WorldSpec,
};

use crate::common::room;

fn people(count: usize) -> PeopleConfig {
    PeopleConfig {
        count: Some(count),
        ..PeopleConfig::default()
    }
}

fn env_in(spec: WorldSpec, people: PeopleConfig, seed: u64) -> NavEnv {
    env_on(World::build(spec).expect("the room builds"), people, seed)
}

fn env_on(world: Arc<World>, people: PeopleConfig, seed: u64) -> NavEnv {
    let config = EnvConfig {
        noise: NoiseConfig::none(),
        max_steps: 100_000,
        people,
        ..EnvConfig::default()
    };
    NavEnv::new(world, config, seed).expect("the environment is valid")
}

fn positions(env: &NavEnv) -> Vec<(f64, f64)> {
    env.people().iter().map(|p| p.position).collect()
}

#[test]
fn people_are_the_same_for_a_seed_and_differ_across_seeds() {
    let run = |seed: u64| {
        let mut env = env_in(room(12.0, 8.0), people(8), seed);
        env.reset(Pose2::new(1.0, 1.0, 0.0), (10.0, 6.0)).unwrap();
        let mut trace = vec![positions(&env)];
        let mut ranges = Vec::new();
        for _ in 0..200 {
            let r = env.step(Action::new(0.0, 0.3));
            trace.push(positions(&env));
            ranges.push(r.observation.ranges);
        }
        (trace, ranges)
    };
    let (a, ra) = run(7);
    assert_eq!(a[0].len(), 8, "eight people fit a 12 x 8 m room");
    assert_eq!((a.clone(), ra.clone()), run(7));
    assert_ne!(a, run(8).0);
    // They walk: everyone covers ground in the 20 s.
    for k in 0..8 {
        let walked: f64 = a
            .windows(2)
            .map(|w| (w[1][k].0 - w[0][k].0).hypot(w[1][k].1 - w[0][k].1))
            .sum();
        assert!(walked > 5.0, "person {k} walked {walked:.2} m in 20 s");
    }
}

#[test]
fn the_laser_sees_people_and_nothing_else_changes() {
    let spec = room(12.0, 8.0);
    let world = World::build(spec.clone()).unwrap();
    let mut env = env_in(spec, people(10), 3);
    let angles = env.beam_angles();
    env.reset(Pose2::new(1.0, 4.0, 0.0), (11.0, 4.0)).unwrap();
    let mut shortened = 0;
    for _ in 0..300 {
        let r = env.step(Action::new(0.0, 0.2));
        let pose = env.pose();
        let mut empty = vec![0.0; angles.len()];
        world.scan(pose, &angles, &mut empty);
        let (lx, ly, heading) = world.laser_origin(pose);
        for ((a, seen), wall) in angles.iter().zip(&r.observation.ranges).zip(&empty) {
            let (s, c) = (heading + a).sin_cos();
            // The nearest person along the beam, by brute force along the ray.
            let mut expected = *wall;
            for p in env.people() {
                let mut t = 0.0;
                while t < expected {
                    if (lx + c * t - p.position.0).hypot(ly + s * t - p.position.1) <= p.radius {
                        expected = t;
                        break;
                    }
                    t += 0.001;
                }
            }
            assert!(
                (f64::from(*seen) - expected).abs() < 2e-3,
                "beam {a}: saw {seen}, expected {expected}"
            );
            if expected < wall - 0.01 {
                shortened += 1;
            }
        }
    }
    assert!(
        shortened > 50,
        "people crossed the beams only {shortened} times"
    );
}

#[test]
fn touching_a_person_is_a_collision() {
    // People who do not give way, a robot that drives on: it runs into someone in the open.
    let config = PeopleConfig {
        yield_to_robot: 0.0,
        ..people(12)
    };
    let spec = room(12.0, 8.0);
    let world = World::build(spec.clone()).unwrap();
    let mut env = env_in(spec, config, 11);
    let mut person_hits = 0;
    for episode in 0..40 {
        let start = Pose2::new(1.5, 1.0 + f64::from(episode % 6), 0.0);
        env.reset(start, (10.5, 4.0)).unwrap();
        loop {
            let r = env.step(Action::new(0.5, 0.0));
            if r.info.outcome == Outcome::Collision {
                assert!(r.info.min_clearance < env.config().collision_clearance);
                let p = r.info.pose;
                if r.info.person_clearance < env.config().collision_clearance {
                    assert!(world.clearance(p.x, p.y) > env.config().collision_clearance);
                    person_hits += 1;
                }
            }
            if r.done {
                break;
            }
        }
    }
    assert!(person_hits > 0, "no drive ran into a person");
}

#[test]
fn people_keep_apart_and_off_the_walls() {
    let spec = room(10.0, 10.0);
    let world = World::build(spec.clone()).unwrap();
    let robot_radius = spec.robot.footprint_radius;
    let mut env = env_in(spec, people(20), 5);
    env.reset(Pose2::new(1.0, 1.0, 0.0), (9.0, 9.0)).unwrap();
    let mut worst_gap = f64::INFINITY;
    for _ in 0..600 {
        env.step(Action::new(0.0, 0.0));
        let people = env.people();
        for (i, p) in people.iter().enumerate() {
            let room = world.clearance(p.position.0, p.position.1) + robot_radius;
            assert!(
                room >= p.radius - 1e-9,
                "a person in a wall at {:?}",
                p.position
            );
            for q in &people[i + 1..] {
                let gap = (p.position.0 - q.position.0).hypot(p.position.1 - q.position.1)
                    - p.radius
                    - q.radius;
                worst_gap = worst_gap.min(gap);
            }
        }
    }
    assert_eq!(env.people().len(), 20);
    assert!(
        worst_gap > -0.05,
        "two people overlapped by {:.3} m",
        -worst_gap
    );
}

#[test]
fn people_walk_the_routes_knowledge_names() {
    let mut spec = room(14.0, 6.0);
    spec.people = PeopleSpec {
        routes: vec![RouteSpec {
            id: "corridor".into(),
            points: vec![[1.0, 3.0], [13.0, 3.0]],
        }],
        ..PeopleSpec::default()
    };
    let mut env = env_in(spec, people(2), 1);
    env.reset(Pose2::new(7.0, 0.8, 0.0), (7.0, 5.0)).unwrap();
    // Person 0 walks the route: both ends within a minute and a half, and near its line.
    let (mut west, mut east) = (false, false);
    for _ in 0..900 {
        env.step(Action::new(0.0, 0.0));
        let p = env.people()[0].position;
        west |= (p.0 - 1.0).hypot(p.1 - 3.0) < 0.6;
        east |= (p.0 - 13.0).hypot(p.1 - 3.0) < 0.6;
    }
    assert!(
        west && east,
        "the route walker reached west {west}, east {east}"
    );
}

#[test]
fn without_people_nothing_walks() {
    let mut env = env_in(room(6.0, 6.0), PeopleConfig::default(), 1);
    env.reset(Pose2::new(1.0, 1.0, 0.0), (5.0, 5.0)).unwrap();
    let r = env.step(Action::new(0.3, 0.0));
    assert!(env.people().is_empty());
    assert_eq!(r.info.person_clearance, f64::INFINITY);
    let bad = EnvConfig {
        people: PeopleConfig {
            speed: (1.0, 0.5),
            ..PeopleConfig::default()
        },
        ..EnvConfig::default()
    };
    let err = NavEnv::new(Arc::clone(env.world()), bad, 1).unwrap_err();
    assert!(err.to_string().contains("people.speed"), "{err}");
}

#[test]
fn someone_a_standing_robot_blocks_in_a_corridor_turns_back() {
    // A corridor 1 m wide: a person (0.4-0.6 m across) cannot pass a 0.4 m robot and the
    // personal space they keep from it.
    let mut spec = room(16.0, 1.1);
    spec.people = PeopleSpec {
        routes: vec![RouteSpec {
            id: "corridor".into(),
            points: vec![[1.0, 0.55], [15.0, 0.55]],
        }],
        ..PeopleSpec::default()
    };
    let mut env = env_in(spec, people(1), 3);
    env.reset(Pose2::new(8.0, 0.55, 0.0), (14.0, 0.55)).unwrap();
    let side = (env.people()[0].position.0 - 8.0).signum();
    let mut walked_late = 0.0;
    let mut last = env.people()[0].position;
    for step in 0..1200 {
        let r = env.step(Action::new(0.0, 0.0));
        assert_ne!(
            r.info.outcome,
            Outcome::Collision,
            "someone walked into the robot"
        );
        let p = env.people()[0].position;
        assert_eq!(
            (p.0 - 8.0).signum(),
            side,
            "the person got past a robot that fills the corridor"
        );
        if step >= 600 {
            walked_late += (p.0 - last.0).hypot(p.1 - last.1);
        }
        last = p;
    }
    // Blocked, they turn back and walk the route the other way (and come back, and turn
    // again) rather than shuffle in front of the robot for ever.
    assert!(
        walked_late > 10.0,
        "the person walked {walked_late:.1} m in the last minute"
    );
}

/// What the robot's laser sees at `pose` in `world` with a person of radius 0.25 m at each of
/// `people` (no noise).
#[allow(clippy::cast_possible_truncation, reason = "ranges are small")]
fn scan_with(
    world: &World,
    env: &NavEnv,
    pose: Pose2,
    people: &[(f64, f64)],
    v: f32,
) -> Observation {
    let angles = env.beam_angles();
    let mut ranges = vec![0.0; angles.len()];
    world.scan(pose, &angles, &mut ranges);
    let (lx, ly, heading) = world.laser_origin(pose);
    for (a, range) in angles.iter().zip(ranges.iter_mut()) {
        let (s, c) = (heading + a).sin_cos();
        for &(px, py) in people {
            // Ray-circle: |o + t d - p| = r.
            let (ox, oy) = (lx - px, ly - py);
            let b = ox * c + oy * s;
            let disc = b * b - (ox * ox + oy * oy - 0.25 * 0.25);
            if disc >= 0.0 {
                let t = -b - disc.sqrt();
                if t > 0.0 {
                    *range = range.min(t);
                }
            }
        }
    }
    Observation {
        ranges: ranges.iter().map(|r| *r as f32).collect(),
        goal_distance: 3.0,
        goal_angle: 0.0,
        velocity: [v, 0.0],
    }
}

#[test]
fn the_shield_on_a_map_holds_a_follower_back_for_people_and_for_walls_only_at_the_last_moment() {
    let spec = room(12.0, 8.0);
    let world = World::build(spec.clone()).unwrap();
    let env = env_in(spec, PeopleConfig::default(), 1);
    let beams = env.beam_angles().len();
    let go = Action::new(0.5, 0.0);
    let fresh = || Shield::new(&world, beams).expect("the laser gives the beams");

    // A wall 0.35 m ahead of the footprint: the full shield slows, the people's shield not.
    let at_wall = Pose2::new(11.4, 4.0, 0.0);
    let obs = scan_with(&world, &env, at_wall, &[], 0.0);
    let mut s = fresh();
    s.observe_on_map(&obs, 0.1, at_wall, &world);
    assert!(s.filter(go, &obs, 0.5).linear < go.linear);
    assert_eq!(s.filter_follower(go, &obs, at_wall, &world), go);
    assert!(!s.sees_motion());
    // At the last moment (5 cm from the wall) it stops the follower too, turning as wanted.
    let touching = Pose2::new(11.7, 4.0, 0.0);
    let obs = scan_with(&world, &env, touching, &[], 0.0);
    let mut s = fresh();
    s.observe_on_map(&obs, 0.1, touching, &world);
    let turn = Action::new(0.5, 0.3);
    assert_eq!(
        s.filter_follower(turn, &obs, touching, &world),
        Action::new(0.0, 0.3)
    );
    // Beside a wall (3.5 cm off, facing along it): on along it, but not curving into it.
    let beside = Pose2::new(11.715, 4.0, std::f64::consts::FRAC_PI_2);
    let obs = scan_with(&world, &env, beside, &[], 0.0);
    let mut s = fresh();
    s.observe_on_map(&obs, 0.1, beside, &world);
    assert_eq!(s.filter_follower(go, &obs, beside, &world), go);
    let into = Action::new(0.5, -0.5);
    assert_eq!(
        s.filter_follower(into, &obs, beside, &world),
        Action::new(0.0, -0.5)
    );

    // A person standing 0.25 m ahead of the footprint in the open: held back, and without a
    // map nothing counts as a person.
    let open = Pose2::new(6.0, 4.0, 0.0);
    let obs = scan_with(&world, &env, open, &[(6.7, 4.0)], 0.0);
    let mut s = fresh();
    s.observe_on_map(&obs, 0.1, open, &world);
    assert!(s.filter_follower(go, &obs, open, &world).linear < go.linear);
    let mut blind = fresh();
    blind.observe(&obs, 0.1);
    assert_eq!(blind.filter_follower(go, &obs, open, &world), go);

    // Someone against the wall the robot drives along, 2 m ahead, stepping off it: the laser
    // alone sees them merge with the wall at that grazing angle, one wide thing that never
    // moves; on the map they are a person, tracked as they step out.
    let near_wall = Pose2::new(4.0, 7.4, 0.0);
    let (mut s, mut blind) = (fresh(), fresh());
    for k in 0..4 {
        let person = (6.0, 7.68 - 0.1 * f64::from(k));
        let obs = scan_with(&world, &env, near_wall, &[person], 0.0);
        s.observe_on_map(&obs, 0.1, near_wall, &world);
        blind.observe(&obs, 0.1);
    }
    assert!(
        s.sees_motion(),
        "the person stepping off the wall is seen to move"
    );
    assert!(
        !blind.sees_motion(),
        "the laser alone tells them from the wall"
    );
}

#[test]
fn the_shield_lets_a_walker_stop_anywhere_on_their_way() {
    let spec = room(12.0, 8.0);
    let world = World::build(spec.clone()).unwrap();
    let env = env_in(spec, PeopleConfig::default(), 1);
    let beams = env.beam_angles().len();
    let go = Action::new(0.8, 0.0);
    let pose = Pose2::new(4.0, 4.0, 0.0);
    let mut s = Shield::new(&world, beams).unwrap();
    // Someone 1.2 m ahead and 0.7 m to the right, walking across the robot's way at 1 m/s:
    // rolled forward alone, they would be gone from the way by the time the robot got there;
    // but they may stop in it, so the robot slows.
    let mut y = 3.0;
    for _ in 0..4 {
        let obs = scan_with(&world, &env, pose, &[(5.2, y)], 0.0);
        s.observe_on_map(&obs, 0.1, pose, &world);
        y += 0.1;
    }
    let obs = scan_with(&world, &env, pose, &[(5.2, y)], 0.0);
    s.observe_on_map(&obs, 0.1, pose, &world);
    assert!(s.sees_motion());
    assert!(s.filter_follower(go, &obs, pose, &world).linear < go.linear);
    // Once across and walking away, the way is free again.
    let mut s = Shield::new(&world, beams).unwrap();
    let mut obs = scan_with(&world, &env, pose, &[(5.2, 5.0)], 0.0);
    for k in 0..6 {
        obs = scan_with(&world, &env, pose, &[(5.2, 5.0 + 0.1 * f64::from(k))], 0.0);
        s.observe_on_map(&obs, 0.1, pose, &world);
    }
    assert!(s.sees_motion());
    assert_eq!(s.filter_follower(go, &obs, pose, &world), go);
}

/// The worlds of robots of one model on one floor (the service builds one per robot) share
/// where people walk and the path fields to there; a world that differs in its geometry or in
/// its knowledge of people has its own, and a crowd walks the same either way.
#[test]
fn worlds_alike_share_their_people_targets() {
    let a = World::build(room(12.0, 8.0)).expect("builds");
    let b = World::build(room(12.0, 8.0)).expect("builds");
    assert!(Arc::ptr_eq(a.people_targets(), b.people_targets()));
    let mut routed = room(12.0, 8.0);
    routed.people = PeopleSpec {
        routes: vec![RouteSpec {
            id: "along".into(),
            points: vec![[1.0, 4.0], [11.0, 4.0]],
        }],
        ..PeopleSpec::default()
    };
    let c = World::build(routed).expect("builds");
    assert!(!Arc::ptr_eq(a.people_targets(), c.people_targets()));
    assert!(c.people_targets().points().len() > a.people_targets().points().len());
    let mut wider = room(12.0, 8.0);
    wider.robot.footprint_radius += 0.1;
    let d = World::build(wider).expect("builds");
    assert!(!Arc::ptr_eq(a.people_targets(), d.people_targets()));
    // Shared or not, a seed walks the same crowd.
    let walk = |world: Arc<World>| {
        let mut env = env_on(world, people(4), 3);
        env.reset(Pose2::new(1.0, 1.0, 0.0), (10.0, 6.0))
            .expect("resets");
        (0..100)
            .map(|_| {
                env.step(Action::new(0.0, 0.0));
                positions(&env)
            })
            .collect::<Vec<_>>()
    };
    let first = walk(Arc::clone(&a));
    drop((a, b));
    // With every world alike gone, the next one makes its targets afresh.
    assert_eq!(first, walk(World::build(room(12.0, 8.0)).expect("builds")));
}

#[test]
fn people_sliding_along_a_wall_do_not_slide_into_a_standing_robot() {
    // A corridor 1.1 m wide, the robot standing against one wall and six people walking a
    // route along that wall: pressed between wall, robot and each other, a person's avoiding
    // step often touches the wall, and the slide along the wall that is left must not carry
    // them into the robot (before it did, in 8 of these 10 seeds).
    for seed in 0..10 {
        let mut spec = room(16.0, 1.1);
        spec.people = PeopleSpec {
            routes: vec![RouteSpec {
                id: "along the wall".into(),
                points: vec![[1.0, 0.35], [15.0, 0.35]],
            }],
            ..PeopleSpec::default()
        };
        let mut env = env_in(spec, people(6), seed);
        env.reset(Pose2::new(8.0, 0.32, 0.0), (14.0, 0.32)).unwrap();
        for step in 0..900 {
            let r = env.step(Action::new(0.0, 0.0));
            assert_ne!(
                r.info.outcome,
                Outcome::Collision,
                "seed {seed}, step {step}: someone walked into the standing robot"
            );
        }
    }
}
