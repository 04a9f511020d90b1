//! The learning environment: Eq. 1, collisions, determinism and batches.

use std::sync::Arc;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::{
    Action, EnvBatch, EnvConfig, EnvError, NavEnv, NoiseConfig, Outcome, Pose2, Pose3, Shape,
    Size3, World, env_seed,
};

use crate::common::{object, room};

fn furnished() -> Arc<World> {
    let mut spec = room(12.0, 8.0);
    spec.objects.push(object(
        "t",
        Some("Table"),
        Shape::Box,
        Size3::new(1.2, 0.8, 0.75),
        Pose3::new(4.0, 4.0, 0.375, 0.3),
    ));
    spec.objects.push(object(
        "v",
        Some("VendingMachine"),
        Shape::Box,
        Size3::new(0.8, 0.7, 1.8),
        Pose3::new(8.0, 2.0, 0.9, 0.0),
    ));
    spec.objects.push(object(
        "s",
        Some("Shelf"),
        Shape::Box,
        Size3::new(0.4, 1.5, 1.8),
        Pose3::new(9.0, 6.5, 0.9, 1.0),
    ));
    World::build(spec).expect("builds")
}

fn quiet() -> EnvConfig {
    EnvConfig {
        noise: NoiseConfig::none(),
        ..EnvConfig::default()
    }
}

#[test]
fn reaching_the_goal_pays_completion_minus_time() {
    let world = World::build(room(12.0, 8.0)).expect("builds");
    let mut env = NavEnv::new(world, quiet(), 1).expect("env");
    let obs = env
        .reset(Pose2::new(2.0, 4.0, 0.0), (4.0, 4.0))
        .expect("reset");
    assert_eq!(obs.ranges.len(), 23);
    assert!((obs.goal_distance - 2.0).abs() < 1e-6 && obs.goal_angle.abs() < 1e-6);
    let mut last = None;
    for _ in 0..100 {
        let r = env.step(Action::new(0.8, 0.0));
        if r.done {
            last = Some(r);
            break;
        }
        // Each step gets closer: r_closer.
        assert_eq!(r.reward, 0.5);
    }
    let r = last.expect("reached the goal");
    assert_eq!(r.info.outcome, Outcome::ReachedGoal);
    // 2 m at 0.8 m/s to within 0.3 m: 1.7 m takes 22 steps of 0.08 m, 2.2 s.
    assert_eq!(r.info.steps, 22);
    assert!((r.reward - (100.0 - 2.2)).abs() < 1e-9, "{}", r.reward);
    // Stepping an ended episode changes nothing.
    let again = env.step(Action::new(0.8, 0.0));
    assert!(again.done && again.reward == 0.0 && again.info.pose == r.info.pose);
}

#[test]
fn driving_into_a_wall_is_a_collision() {
    let world = World::build(room(12.0, 8.0)).expect("builds");
    let mut env = NavEnv::new(world, quiet(), 1).expect("env");
    env.reset(Pose2::new(10.0, 4.0, 0.0), (2.0, 4.0))
        .expect("reset");
    let mut steps = 0;
    let r = loop {
        let r = env.step(Action::new(0.8, 0.0));
        steps += 1;
        if r.done {
            break r;
        }
        assert_eq!(r.reward, 0.0, "moving away from the goal earns nothing");
    };
    assert_eq!(r.info.outcome, Outcome::Collision);
    assert_eq!(r.reward, -100.0);
    // The wall's free side is at 11.95 and the robot moves 0.08 m per step from x = 10: at
    // x = 11.68 its clearance is 0.07 m, at 11.76 it is -0.01 m, below the 0.02 m threshold.
    assert_eq!(steps, 22);
    assert!((r.info.pose.x - 11.76).abs() < 1e-9, "{:?}", r.info.pose);
    assert!(
        (r.info.min_clearance + 0.01).abs() < 1e-9,
        "{}",
        r.info.min_clearance
    );
}

#[test]
fn turning_in_place_keeps_the_position() {
    let world = World::build(room(12.0, 8.0)).expect("builds");
    let mut env = NavEnv::new(world, quiet(), 1).expect("env");
    env.reset(Pose2::new(6.0, 4.0, 0.0), (2.0, 4.0))
        .expect("reset");
    for _ in 0..10 {
        let r = env.step(Action::new(0.0, 0.5));
        assert_eq!(r.info.outcome, Outcome::Running);
    }
    let p = env.pose();
    assert!((p.x - 6.0).abs() < 1e-12 && (p.y - 4.0).abs() < 1e-12);
    assert!((p.yaw - 0.5).abs() < 1e-9);
}

#[test]
fn blocked_starts_and_goals_are_refused_with_a_free_point() {
    let world = World::build(room(12.0, 8.0)).expect("builds");
    let mut env = NavEnv::new(world, quiet(), 1).expect("env");
    match env.reset(Pose2::new(0.1, 4.0, 0.0), (6.0, 4.0)) {
        Err(EnvError::StartBlocked {
            nearest_free: Some((x, _)),
            ..
        }) => assert!(x > 0.3),
        other => panic!("{other:?}"),
    }
    match env.reset(Pose2::new(6.0, 4.0, 0.0), (11.99, 4.0)) {
        Err(EnvError::GoalBlocked {
            nearest_free: Some((x, _)),
            ..
        }) => assert!(x < 11.7),
        other => panic!("{other:?}"),
    }
    assert!(matches!(
        env.reset(Pose2::new(f64::NAN, 4.0, 0.0), (6.0, 4.0)),
        Err(EnvError::StartBlocked { .. })
    ));
}

#[test]
fn random_resets_respect_the_distance_range() {
    let world = furnished();
    let config = EnvConfig {
        goal_distance: (2.0, 6.0),
        ..EnvConfig::default()
    };
    let mut env = NavEnv::new(Arc::clone(&world), config, 7).expect("env");
    for _ in 0..200 {
        let (s, g) = env.sample_start_goal().expect("sample");
        let d = (g.0 - s.x).hypot(g.1 - s.y);
        assert!((2.0..=6.0).contains(&d), "{d}");
        assert!(world.clearance(s.x, s.y) >= 0.1 - 1e-9, "start clearance");
        assert!(world.clearance(g.0, g.1) > 0.0);
    }
}

#[test]
fn goals_in_view_can_be_driven_to_in_a_straight_line() {
    let world = furnished();
    // Through the table, and past it along the free lower half of the room.
    assert!(world.segment_clearance((2.0, 4.0), (6.0, 4.0)) <= 0.0);
    let open = world.segment_clearance((2.0, 1.5), (6.0, 1.5));
    assert!(open > 0.3, "{open}");
    let sample = |in_view| {
        let config = EnvConfig {
            goal_distance: (3.0, 8.0),
            goals_in_view: in_view,
            ..EnvConfig::default()
        };
        let mut env = NavEnv::new(Arc::clone(&world), config, 11).expect("env");
        (0..300)
            .map(|_| {
                let (s, g) = env.sample_start_goal().expect("sample");
                world.segment_clearance((s.x, s.y), g)
            })
            .collect::<Vec<_>>()
    };
    let threshold = EnvConfig::default().collision_clearance;
    assert!(sample(true).iter().all(|&c| c > threshold));
    // Without the condition some goals lie behind the furniture.
    assert!(sample(false).iter().any(|&c| c <= threshold));
}

/// Steps `env` with actions from its own stream and returns everything observed.
fn roll(env: &mut NavEnv, actions: &mut ChaCha8Rng, steps: usize) -> Vec<(Vec<f32>, f64, bool)> {
    let mut out = vec![];
    let obs = env.reset_random().expect("reset");
    out.push((obs.to_vec(), 0.0, false));
    for _ in 0..steps {
        let a = Action::new(
            actions.random_range(0.0..0.8),
            actions.random_range(-0.5..0.5),
        );
        let r = env.step(a);
        out.push((r.observation.to_vec(), r.reward, r.done));
        if r.done {
            let obs = env.reset_random().expect("reset");
            out.push((obs.to_vec(), 0.0, false));
        }
    }
    out
}

#[test]
fn the_same_seed_gives_the_same_episode() {
    let world = furnished();
    let run = |seed| {
        let mut env = NavEnv::new(Arc::clone(&world), EnvConfig::default(), seed).expect("env");
        roll(&mut env, &mut ChaCha8Rng::seed_from_u64(99), 300)
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}

#[test]
fn a_batch_equals_its_environments_stepped_one_by_one() {
    let world = furnished();
    let n = 6;
    let mut batch =
        EnvBatch::new(Arc::clone(&world), EnvConfig::default(), n, 42, true).expect("batch");
    let first = batch.reset_random().expect("reset");
    let mut singles: Vec<NavEnv> = (0..n)
        .map(|i| {
            NavEnv::new(Arc::clone(&world), EnvConfig::default(), env_seed(42, i)).expect("env")
        })
        .collect();
    for (env, obs) in singles.iter_mut().zip(&first) {
        assert_eq!(&env.reset_random().expect("reset"), obs);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut ended = 0;
    for _ in 0..200 {
        let actions: Vec<Action> = (0..n)
            .map(|_| Action::new(rng.random_range(0.0..0.8), rng.random_range(-0.5..0.5)))
            .collect();
        let results = batch.step(&actions).expect("step");
        for ((env, a), r) in singles.iter_mut().zip(&actions).zip(&results) {
            let mut want = env.step(*a);
            if want.done {
                ended += 1;
                want.reset_observation = Some(env.reset_random().expect("reset"));
            }
            assert_eq!(&want, r);
        }
    }
    assert!(ended > 0, "some episodes ended and were reset");
    assert!(matches!(
        batch.step(&[Action::default()]),
        Err(EnvError::Config {
            field: "actions",
            ..
        })
    ));
}

#[test]
fn with_a_carrot_the_policy_sees_the_point_ahead_on_the_path_then_the_goal() {
    let world = World::build(room(12.0, 8.0)).expect("builds");
    let mut config = quiet();
    config.reward.progress = true;
    config.reward.geodesic = true;
    config.carrot_m = Some(1.2);
    let mut env = NavEnv::new(world, config, 1).expect("env");
    // The goal 8 m straight ahead: the carrot 1.2 m ahead, straight on (to within a cell).
    let obs = env
        .reset(Pose2::new(2.0, 4.0, 0.0), (10.0, 4.0))
        .expect("reset");
    assert!((obs.goal_distance - 1.2).abs() < 0.05, "{obs:?}");
    assert!(obs.goal_angle.abs() < 0.1, "{obs:?}");
    // Driving on, the carrot stays ahead until the goal is nearer; the episode still ends at
    // the goal, not at the carrot.
    let mut seen = Vec::new();
    for _ in 0..200 {
        let r = env.step(Action::new(0.8, 0.0));
        seen.push(r.observation.goal_distance);
        if r.done {
            assert_eq!(r.info.outcome, Outcome::ReachedGoal);
            break;
        }
    }
    assert!(seen.len() > 80, "{} steps", seen.len());
    assert!(
        seen[..60].iter().all(|d| (d - 1.2).abs() < 0.05),
        "{seen:?}"
    );
    assert!(seen.last().is_some_and(|d| *d < 0.35), "{seen:?}");
}

#[test]
fn bad_settings_are_refused() {
    let world = World::build(room(6.0, 6.0)).expect("builds");
    let cases: Vec<(EnvConfig, &str)> = vec![
        (
            EnvConfig {
                beams: 0,
                ..EnvConfig::default()
            },
            "beams",
        ),
        (
            EnvConfig {
                beams: 10_000,
                ..EnvConfig::default()
            },
            "beams",
        ),
        (
            EnvConfig {
                control_period: 0.0,
                ..EnvConfig::default()
            },
            "control_period",
        ),
        (
            EnvConfig {
                goal_distance: (5.0, 2.0),
                ..EnvConfig::default()
            },
            "goal_distance",
        ),
        (
            EnvConfig {
                noise: NoiseConfig {
                    range: -1.0,
                    ..NoiseConfig::default()
                },
                ..EnvConfig::default()
            },
            "noise.range",
        ),
        (
            // A carrot needs the geodesic reward's path field (off by default).
            EnvConfig {
                carrot_m: Some(1.2),
                ..EnvConfig::default()
            },
            "carrot_m",
        ),
    ];
    for (config, want) in cases {
        match NavEnv::new(Arc::clone(&world), config, 0) {
            Err(EnvError::Config { field, .. }) => assert_eq!(field, want),
            other => panic!("{want}: {other:?}"),
        }
    }
}

#[test]
fn a_plan_is_followed_waypoint_by_waypoint() {
    let world = World::build(room(12.0, 8.0)).expect("builds");
    let config = EnvConfig {
        record_trajectory: true,
        ..quiet()
    };
    let mut env = NavEnv::new(world, config, 1).expect("env");
    let mut obs = env
        .reset(Pose2::new(2.0, 2.0, 0.0), (5.0, 2.0))
        .expect("reset");
    let waypoints = [(5.0, 2.0), (5.0, 5.0), (9.0, 6.0)];
    for (k, w) in waypoints.iter().enumerate() {
        if k > 0 {
            obs = env.set_goal(*w).expect("free waypoint");
        }
        let reached = loop {
            let b = f64::from(obs.goal_angle);
            let r = env.step(Action::new(
                0.6 * b.cos().max(0.0),
                (1.5 * b).clamp(-0.5, 0.5),
            ));
            obs = r.observation;
            if r.done {
                break r.info.outcome;
            }
        };
        assert_eq!(reached, Outcome::ReachedGoal, "waypoint {k}");
    }
    assert!(env.trajectory().len() > 20);
    assert!(matches!(
        env.set_goal((0.0, 0.0)),
        Err(EnvError::GoalBlocked { .. })
    ));
}

#[test]
fn the_progress_reward_pays_for_distance_gained_and_charges_for_distance_lost() {
    let world = World::build(room(12.0, 8.0)).expect("builds");
    let mut config = quiet();
    config.reward.progress = true;
    let mut env = NavEnv::new(world, config, 1).expect("env");
    env.reset(Pose2::new(6.0, 4.0, 0.0), (9.0, 4.0))
        .expect("reset");
    let mut toward = Vec::new();
    for _ in 0..10 {
        toward.push(env.step(Action::new(0.8, 0.0)).reward);
    }
    assert!(
        toward.iter().all(|r| *r > 0.0 && *r <= 0.5 + 1e-9),
        "{toward:?}"
    );
    // At top speed straight at the goal a step earns the full r_closer.
    assert!((toward[9] - 0.5).abs() < 1e-6, "{toward:?}");
    env.reset(Pose2::new(6.0, 4.0, std::f64::consts::PI), (9.0, 4.0))
        .expect("reset");
    let mut away = Vec::new();
    for _ in 0..10 {
        away.push(env.step(Action::new(0.8, 0.0)).reward);
    }
    assert!(
        away.iter().all(|r| *r < 0.0 && *r >= -0.5 - 1e-9),
        "{away:?}"
    );
}

#[test]
fn the_clearance_charge_applies_only_close_to_obstacles() {
    let world = World::build(room(12.0, 8.0)).expect("builds");
    // A lane along the bottom wall 5 cm from it, and one down the middle of the room.
    let near_y = (0..400)
        .map(|k| 0.1 + f64::from(k) * 0.002)
        .find(|&y| world.clearance(6.0, y) >= 0.05)
        .expect("a lane 5 cm from the wall");
    let rewards = |clearance: f64, y: f64| {
        let mut config = quiet();
        config.reward.progress = true;
        config.reward.clearance = clearance;
        let mut env = NavEnv::new(Arc::clone(&world), config, 1).expect("env");
        env.reset(Pose2::new(4.0, y, 0.0), (9.0, y)).expect("reset");
        (0..5)
            .map(|_| env.step(Action::new(0.4, 0.0)))
            .map(|r| (r.reward, r.info.min_clearance))
            .collect::<Vec<_>>()
    };
    let dt = quiet().control_period;
    for ((charged, c), (free, _)) in rewards(2.0, near_y).into_iter().zip(rewards(0.0, near_y)) {
        let expected = 2.0 * dt * (sim::CLEARANCE_BAND_M - c) / sim::CLEARANCE_BAND_M;
        assert!(c < sim::CLEARANCE_BAND_M, "{c}");
        assert!(
            (free - charged - expected).abs() < 1e-9,
            "{free} {charged} {expected}"
        );
    }
    assert_eq!(
        rewards(2.0, 4.0),
        rewards(0.0, 4.0),
        "nothing is charged mid-room"
    );
}

/// After a goal, `continue_random` starts the next episode where the robot is, moving as it
/// was, with a new goal in range; after anything else it is a random reset.
#[test]
fn a_reached_goal_can_be_followed_by_the_next_from_the_same_pose() {
    let world = World::build(room(12.0, 8.0)).expect("builds");
    let config = EnvConfig {
        goal_distance: (1.0, 3.0),
        ..quiet()
    };
    let mut env = NavEnv::new(world, config, 3).expect("env");
    env.reset(Pose2::new(2.0, 4.0, 0.0), (4.0, 4.0))
        .expect("reset");
    let mut end = None;
    for _ in 0..100 {
        let r = env.step(Action::new(0.8, 0.0));
        if r.done {
            end = Some(r);
            break;
        }
    }
    let end = end.expect("reached");
    assert_eq!(end.info.outcome, Outcome::ReachedGoal);
    let obs = env.continue_random().expect("next goal");
    assert_eq!(env.pose(), end.info.pose, "same pose");
    assert!(
        (obs.velocity[0] - 0.8).abs() < 1e-6,
        "still moving: {:?}",
        obs.velocity
    );
    let g = env.goal();
    let d = (g.0 - env.pose().x).hypot(g.1 - env.pose().y);
    assert!((1.0..=3.0).contains(&d), "goal {d} m away");
    let r = env.step(Action::new(0.8, 0.0));
    assert_eq!(r.info.steps, 1, "a new episode");

    // After a collision it starts elsewhere, from rest.
    env.reset(Pose2::new(1.0, 4.0, std::f64::consts::PI), (3.0, 4.0))
        .expect("reset");
    let mut r = env.step(Action::new(0.8, 0.0));
    while !r.done {
        r = env.step(Action::new(0.8, 0.0));
    }
    assert_eq!(r.info.outcome, Outcome::Collision);
    let obs = env.continue_random().expect("a random reset");
    assert_eq!(obs.velocity, [0.0, 0.0]);
}

#[test]
fn a_robot_told_to_stand_still_stands_still_and_a_moving_one_slips() {
    let world = World::build(room(12.0, 8.0)).expect("builds");
    let config = EnvConfig {
        max_steps: 10_000,
        ..EnvConfig::default()
    };
    let start = Pose2::new(6.0, 4.0, 0.3);
    let mut env = NavEnv::new(Arc::clone(&world), config.clone(), 3).expect("env");
    env.reset(start, (10.0, 4.0)).expect("reset");
    for _ in 0..300 {
        env.step(Action::new(0.0, 0.0));
    }
    assert_eq!(env.pose(), start, "noise moved a robot told to stand still");
    // Turning on the spot: the heading changes, the position does not.
    for _ in 0..20 {
        env.step(Action::new(0.0, 0.3));
    }
    let turned = env.pose();
    assert!((turned.x, turned.y) == (start.x, start.y) && turned.yaw != start.yaw);
    // Driving: the noise shows against the same drive without it.
    let drive = |noise: NoiseConfig| {
        let mut env = NavEnv::new(
            Arc::clone(&world),
            EnvConfig {
                noise,
                ..config.clone()
            },
            3,
        )
        .expect("env");
        env.reset(start, (10.0, 4.0)).expect("reset");
        for _ in 0..20 {
            env.step(Action::new(0.5, 0.1));
        }
        env.pose()
    };
    let (noisy, exact) = (drive(NoiseConfig::default()), drive(NoiseConfig::none()));
    assert!(
        (noisy.x - exact.x).hypot(noisy.y - exact.y) > 1e-4,
        "{noisy:?} {exact:?}"
    );
}
