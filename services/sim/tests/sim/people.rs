//! People in the simulation: deterministic for a seed, seen by the laser, a collision when
//! touched, apart from each other and off the walls, and walking the routes knowledge names.

use std::sync::Arc;

use sim::{
    Action, EnvConfig, NavEnv, NoiseConfig, Outcome, PeopleConfig, PeopleSpec, Pose2, RouteSpec,
    World, WorldSpec,
};

use crate::common::room;

fn people(count: usize) -> PeopleConfig {
    PeopleConfig {
        count: Some(count),
        ..PeopleConfig::default()
    }
}

fn env_in(spec: WorldSpec, people: PeopleConfig, seed: u64) -> NavEnv {
    let config = EnvConfig {
        noise: NoiseConfig::none(),
        max_steps: 100_000,
        people,
        ..EnvConfig::default()
    };
    NavEnv::new(World::build(spec).expect("the room builds"), config, seed)
        .expect("the environment is valid")
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
        if std::env::var("DBG").is_ok() {
            eprintln!("{:?}", env.people()[0]);
        }
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
