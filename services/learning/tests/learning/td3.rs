//! The TD3 learner and trainer through their public interface, with real libtorch: gradients
//! reach every parameter, the pure-Rust runtime matches tch, and a checkpointed run resumes.
#![allow(clippy::unwrap_used, clippy::expect_used, reason = "tests")]

use std::sync::Arc;

use learning::observation::Residual;
use learning::policy::{Policy, PolicyMetadata, write_policy};
use learning::replay::{Batch, ReplayBuffer};
use learning::td3::Learner;
use learning::trainer::{Budget, TrainOptions, Trainer};
use learning::{Scaling, Td3Config, TrainConfig};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sim::{FloorMap, Occupancy, OccupancyGrid, Pose2, RobotSpec, World, WorldSpec};

/// A 10 m × 8 m room with a pillar in the middle.
fn room() -> Arc<World> {
    let (w, h) = (100, 80);
    let mut grid = OccupancyGrid::filled(w, h, 0.1, Pose2::new(0.0, 0.0, 0.0), Occupancy::Free);
    for r in 0..h {
        for c in 0..w {
            let border = r == 0 || c == 0 || r == h - 1 || c == w - 1;
            let pillar = (45..55).contains(&c) && (35..45).contains(&r);
            if border || pillar {
                grid.cells[r * w + c] = Occupancy::Occupied;
            }
        }
    }
    World::build(WorldSpec {
        id: "room".into(),
        floor: Some(FloorMap {
            id: "room".into(),
            grid,
            wall_height: 2.0,
            frame_id: "map".into(),
        }),
        walls: vec![],
        objects: vec![],
        robot: RobotSpec::example_differential(),
        people: Default::default(),
        notes: vec![],
    })
    .expect("the room builds")
}

fn random_batch(rng: &mut ChaCha8Rng, dim: usize, size: usize) -> Batch {
    let mut buffer = ReplayBuffer::new(dim, 4 * size);
    for _ in 0..4 * size {
        let s: Vec<f32> = (0..dim).map(|_| rng.random()).collect();
        let s2: Vec<f32> = (0..dim).map(|_| rng.random()).collect();
        let a = [rng.random(), rng.random::<f32>() * 2.0 - 1.0];
        buffer.push(&s, a, a, rng.random(), &s2, rng.random::<f32>() < 0.1);
    }
    let mut batch = Batch::default();
    buffer.sample_into(rng, size, &mut batch);
    batch
}

#[test]
fn every_parameter_of_the_actor_and_both_critics_receives_a_gradient() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let config = Td3Config {
        hidden: vec![32, 32],
        ..Td3Config::default()
    };
    let mut learner = Learner::new(config, 25, tch::Device::Cpu, 3);
    let batch = random_batch(&mut rng, 25, 64);
    let report = learner.gradient_report(&batch, &mut rng);
    // Actor: 3 layers × (weight, bias); critics: 2 × 3 × 2.
    assert_eq!(report.len(), 6 + 12, "{report:?}");
    let starved: Vec<_> = report.iter().filter(|(_, ok)| !ok).collect();
    assert!(
        starved.is_empty(),
        "parameters without gradient: {starved:?}"
    );
}

#[test]
fn the_critic_loss_falls_on_a_fixed_batch() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let config = Td3Config {
        hidden: vec![64, 64],
        critic_lr: 1e-3,
        gamma: 0.0, // targets are the rewards: a plain regression
        ..Td3Config::default()
    };
    let mut learner = Learner::new(config, 25, tch::Device::Cpu, 4);
    let batch = random_batch(&mut rng, 25, 128);
    let first = learner.update(&batch, &mut rng).critic_loss;
    let mut last = first;
    for _ in 0..300 {
        last = learner.update(&batch, &mut rng).critic_loss;
    }
    assert!(last < 0.2 * first, "critic loss {first} -> {last}");
}

#[test]
fn the_pure_rust_policy_matches_tch_within_1e_5() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let config = Td3Config::default(); // 256-256, as exported by default
    let dim = Scaling::default().input_len();
    let mut learner = Learner::new(config.clone(), dim, tch::Device::Cpu, 6);
    // Move the weights away from their initialisation.
    let batch = random_batch(&mut rng, dim, 256);
    for _ in 0..20 {
        learner.update(&batch, &mut rng);
    }
    let dir = tempfile::tempdir().unwrap();
    let meta = PolicyMetadata::new(
        Scaling::default(),
        config.hidden.clone(),
        serde_json::json!({}),
    );
    write_policy(dir.path(), &meta, &learner.actor_layers()).unwrap();
    let policy = Policy::load(dir.path()).unwrap();
    let n = 1000;
    // Inputs in and beyond the encoder's range.
    let inputs: Vec<f32> = (0..n * dim)
        .map(|_| rng.random::<f32>() * 3.0 - 1.0)
        .collect();
    let mut expected = Vec::new();
    learner.act(&inputs, n, &mut expected);
    let mut worst = 0.0f32;
    for (row, want) in inputs.chunks_exact(dim).zip(expected.chunks_exact(2)) {
        let got = policy.forward(row).unwrap();
        worst = worst
            .max((got[0] - want[0]).abs())
            .max((got[1] - want[1]).abs());
    }
    assert!(worst <= 1e-5, "largest difference {worst}");
}

#[test]
fn a_residual_actor_starts_as_the_follower_and_the_runtime_matches_it() {
    starts_as_its_base(Residual::follower(&sim::follower::FollowerParams::default()));
}

#[test]
fn a_residual_actor_over_regulated_pure_pursuit_starts_as_it() {
    starts_as_its_base(Residual::rpp(&sim::RppParams::default()));
}

/// An untrained residual actor drives as `residual`, and the exported policy, base included,
/// acts as tch does.
fn starts_as_its_base(residual: Residual) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let scaling = Scaling::default();
    let dim = scaling.input_len();
    let config = Td3Config {
        hidden: vec![64, 64],
        residual: true,
        ..Td3Config::default()
    };
    let mut learner = Learner::new(config.clone(), dim, tch::Device::Cpu, 8);
    learner.set_residual(residual, scaling);
    // Encoded observations: goals all around, near and far.
    let n = 400;
    let mut inputs = Vec::with_capacity(n * dim);
    for _ in 0..n {
        let obs = sim::Observation {
            ranges: (0..scaling.beams)
                .map(|_| rng.random::<f32>() * 6.0)
                .collect(),
            goal_distance: rng.random::<f32>() * 8.0,
            goal_angle: (rng.random::<f32>() * 2.0 - 1.0) * std::f32::consts::PI,
            velocity: [rng.random::<f32>() * 0.8, rng.random::<f32>() - 0.5],
        };
        inputs.extend(scaling.encode(&obs).unwrap());
    }
    let mut acted = Vec::new();
    learner.act(&inputs, n, &mut acted);
    let mut worst = 0.0f32;
    for (row, got) in inputs.chunks_exact(dim).zip(acted.chunks_exact(2)) {
        let want = residual.output(&scaling, row);
        worst = worst
            .max((got[0] - want[0]).abs())
            .max((got[1] - want[1]).abs());
    }
    assert!(
        worst < 0.05,
        "the untrained residual actor is {worst} from its base"
    );
    // After some updates the exported policy (with its base) still acts as tch does.
    let batch = random_batch(&mut rng, dim, 256);
    for _ in 0..20 {
        learner.update(&batch, &mut rng);
    }
    let dir = tempfile::tempdir().unwrap();
    let mut meta = PolicyMetadata::new(scaling, config.hidden.clone(), serde_json::json!({}));
    meta.residual = learner.residual();
    write_policy(dir.path(), &meta, &learner.actor_layers()).unwrap();
    let policy = Policy::load(dir.path()).unwrap();
    learner.act(&inputs, n, &mut acted);
    let mut worst = 0.0f32;
    for (row, want) in inputs.chunks_exact(dim).zip(acted.chunks_exact(2)) {
        let got = policy.forward(row).unwrap();
        worst = worst
            .max((got[0] - want[0]).abs())
            .max((got[1] - want[1]).abs());
    }
    assert!(worst <= 1e-5, "largest difference {worst}");
}

fn small_options(out: &std::path::Path) -> TrainOptions {
    let mut options = TrainOptions::new(out);
    options.config = TrainConfig {
        td3: Td3Config {
            hidden: vec![32, 32],
            batch_size: 64,
            ..Td3Config::default()
        },
        envs: 4,
        random_steps: 300,
        updates_per_step: 0.25,
        eval_every: 1000,
        eval_episodes: 8,
        checkpoint_every_s: 0.0,
        max_episode_steps: 100,
        ..TrainConfig::default()
    };
    options
}

#[test]
fn a_checkpointed_run_resumes_where_it_stopped() {
    let world = room();
    let dir = tempfile::tempdir().unwrap();
    let options = small_options(dir.path());
    let mut trainer = Trainer::new(Arc::clone(&world), options.clone()).unwrap();
    let budget = Budget {
        wall_s: None,
        env_steps: Some(1200),
    };
    trainer.run(budget, &mut |_| true).unwrap();
    let counters = trainer.counters().clone();
    assert!(counters.env_steps >= 1200 && counters.grad_steps > 0 && counters.episodes > 0);
    assert_eq!(trainer.evals().len(), 1, "one evaluation at 1000 steps");
    let weights = trainer.learner().actor_layers();
    assert!(Trainer::has_checkpoint(dir.path()));
    drop(trainer);

    let mut resumed = Trainer::resume(Arc::clone(&world), options.clone()).unwrap();
    assert_eq!(
        resumed.learner().actor_layers(),
        weights,
        "networks restored"
    );
    assert_eq!(resumed.learner().updates(), counters.grad_steps);
    let c = resumed.counters();
    assert_eq!(
        (c.env_steps, c.episodes, c.grad_steps, c.sessions),
        (
            counters.env_steps,
            counters.episodes,
            counters.grad_steps,
            2
        )
    );
    assert_eq!(resumed.episodes().len() as u64, counters.episodes);
    resumed
        .run(
            Budget {
                wall_s: None,
                env_steps: Some(2400),
            },
            &mut |_| true,
        )
        .unwrap();
    let c = resumed.counters();
    assert!(c.env_steps >= 2400 && c.grad_steps > counters.grad_steps);
    assert_eq!(
        resumed.evals().len(),
        2,
        "the evaluation schedule continued"
    );

    // A different configuration does not silently continue the old run.
    let mut other = options.clone();
    other.config.td3.beta1 = 5.0;
    let e = Trainer::resume(world, other).unwrap_err();
    assert!(
        e.to_string().contains("another training configuration"),
        "{e}"
    );
}

#[test]
fn a_stop_request_ends_the_run_with_a_checkpoint_and_an_exportable_policy() {
    let world = room();
    let dir = tempfile::tempdir().unwrap();
    let mut trainer = Trainer::new(world, small_options(dir.path())).unwrap();
    let mut calls = 0;
    trainer
        .run(Budget::default(), &mut |p| {
            calls += 1;
            // Stop once some experience has been gathered.
            p.counters.env_steps < 400
        })
        .unwrap();
    assert!(calls >= 2);
    assert!(Trainer::has_checkpoint(dir.path()));
    let export = dir.path().join("policy");
    trainer
        .export(&export, serde_json::json!({"test": true}))
        .unwrap();
    let policy = Policy::load(&export).unwrap();
    assert_eq!(policy.metadata().hidden, vec![32, 32]);
    assert_eq!(policy.metadata().training["summary"]["test"], true);
}

#[test]
fn a_shielded_training_drives_random_actions_without_a_collision() {
    // Random actions only (no actor yet): unshielded they run into the walls and the pillar;
    // behind the shield the environment never sees a collision.
    let collisions = |shielded: bool| {
        let dir = tempfile::tempdir().unwrap();
        let mut options = small_options(dir.path());
        options.config.random_steps = 100_000;
        options.config.shielded = shielded;
        let mut trainer = Trainer::new(room(), options).unwrap();
        trainer
            .run(
                Budget {
                    wall_s: None,
                    env_steps: Some(4_000),
                },
                &mut |_| true,
            )
            .unwrap();
        let episodes = trainer.episodes();
        assert!(episodes.len() > 10, "{} episodes", episodes.len());
        // Its policy is measured as it will drive: behind the shield when trained behind it.
        assert_eq!(trainer.evaluate(&[]).unwrap().shielded, shielded);
        let export = dir.path().join("policy");
        trainer.export(&export, serde_json::json!({})).unwrap();
        let policy = Policy::load(&export).unwrap();
        let held_out = learning::evaluate_held_out(&policy, &room(), 4, 1, true).unwrap();
        assert_eq!(held_out.shielded, shielded);
        episodes.iter().filter(|e| e.outcome == "collision").count()
    };
    assert!(
        collisions(false) > 0,
        "random driving should hit something unshielded"
    );
    assert_eq!(collisions(true), 0);
}

#[test]
fn bad_settings_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let mut options = small_options(dir.path());
    options.config.td3.gamma = 1.5;
    let e = Trainer::new(room(), options).unwrap_err();
    assert!(e.to_string().contains("td3.gamma"), "{e}");
    let missing = tempfile::tempdir().unwrap();
    assert!(Trainer::resume(room(), small_options(missing.path())).is_err());
}

/// Learning, not just running: in an open room the success rate on held-out missions must beat
/// the untrained policy's by a wide margin. Minutes of CPU in release; run by hand:
/// `cargo test --release -p learning --test learning learns_an_open_room -- --ignored --nocapture`.
#[test]
#[ignore = "minutes of training; run in release by hand"]
fn learns_an_open_room() {
    let world = room();
    let dir = tempfile::tempdir().unwrap();
    let mut options = TrainOptions::new(dir.path());
    options.config = TrainConfig {
        td3: Td3Config {
            hidden: vec![64, 64],
            actor_lr: 1e-3,
            critic_lr: 1e-3,
            ..Td3Config::default()
        },
        goal_distance: (1.0, 5.0),
        eval_every: 10_000,
        eval_episodes: 100,
        checkpoint_every_s: 0.0,
        ..TrainConfig::default()
    };
    let mut trainer = Trainer::new(world, options).unwrap();
    let before = trainer.evaluate_and_record(0.0).unwrap().success_rate;
    let steps: u64 = std::env::var("LEARN_STEPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(60_000);
    trainer
        .run(
            Budget {
                wall_s: None,
                env_steps: Some(steps),
            },
            &mut |p| {
                if p.counters.episodes % 50 == 0 {
                    eprintln!(
                        "{} steps, {} episodes, success {:.2}",
                        p.counters.env_steps, p.counters.episodes, p.success_rate_100
                    );
                }
                true
            },
        )
        .unwrap();
    for e in trainer.evals() {
        println!(
            "{} steps: success {:.2} collision {:.2} timeout {:.2}",
            e.env_steps, e.report.success_rate, e.report.collision_rate, e.report.timeout_rate
        );
    }
    let after = trainer.evals().last().unwrap().report.success_rate;
    assert!(after >= before + 0.3, "success {before} -> {after}");
}

/// Turns towards the goal, then drives: a controller that needs no learning.
struct Heuristic;
impl learning::BatchActor for Heuristic {
    fn act_batch(&self, inputs: &[f32], n: usize, out: &mut Vec<f32>) {
        out.clear();
        for row in inputs.chunks_exact(28).take(n) {
            // Extended layout: 23 ranges, distance, sin, cos, odometry.
            let angle = row[24].atan2(row[25]) / std::f32::consts::PI; // goal angle / pi
            out.push(if angle.abs() < 0.2 { 1.0 } else { 0.2 });
            out.push((angle * 4.0).clamp(-1.0, 1.0));
        }
    }
}

/// The evaluation plumbing (missions, encoding, commands, outcomes) with a known controller:
/// in an open room turning to the goal and driving reaches most goals.
#[test]
fn evaluation_measures_a_known_controller() {
    let world = room();
    let env = sim::EnvConfig {
        goal_distance: (1.0, 5.0),
        ..sim::EnvConfig::default()
    };
    let missions = learning::mission_set(&world, &env, 100, 3).unwrap();
    assert_eq!(
        missions,
        learning::mission_set(&world, &env, 100, 3).unwrap(),
        "a seed gives one set"
    );
    let r =
        learning::evaluate(&Heuristic, &world, &env, &Scaling::default(), &missions, 3).unwrap();
    assert_eq!(r.episodes, 100);
    assert!(r.success_rate >= 0.8, "{r:?}");
    assert!((r.success_rate + r.collision_rate + r.timeout_rate - 1.0).abs() < 1e-9);
    assert!(r.mean_time_to_goal_s > 0.0 && r.env_steps > 100);
}

/// A one-step problem whose best action is known: the actor must find it.
#[test]
fn the_actor_climbs_the_critic_to_the_best_action() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let config = Td3Config {
        hidden: vec![64, 64],
        actor_lr: 1e-3,
        critic_lr: 1e-3,
        beta1: 0.0,
        beta2: 0.0,
        batch_size: 128,
        ..Td3Config::default()
    };
    let dim = 4;
    let mut learner = Learner::new(config, dim, tch::Device::Cpu, 10);
    let mut buffer = ReplayBuffer::new(dim, 100_000);
    let reward = |a: [f32; 2]| -((a[0] - 0.7).powi(2) + (a[1] + 0.3).powi(2));
    let mut batch = Batch::default();
    let mut out = Vec::new();
    for step in 0..3000 {
        let s: Vec<f32> = (0..dim).map(|_| rng.random()).collect();
        learner.act(&s, 1, &mut out);
        let a = if step < 500 {
            [rng.random::<f32>(), rng.random::<f32>() * 2.0 - 1.0]
        } else {
            [
                (out[0] + 0.2 * (rng.random::<f32>() - 0.5)).clamp(0.0, 1.0),
                (out[1] + 0.2 * (rng.random::<f32>() - 0.5)).clamp(-1.0, 1.0),
            ]
        };
        buffer.push(&s, a, a, reward(a), &s, true);
        if buffer.len() >= 128 {
            buffer.sample_into(&mut rng, 128, &mut batch);
            learner.update(&batch, &mut rng);
        }
    }
    let s: Vec<f32> = (0..dim).map(|_| rng.random()).collect();
    learner.act(&s, 1, &mut out);
    assert!(
        (out[0] - 0.7).abs() < 0.1 && (out[1] + 0.3).abs() < 0.1,
        "actor says {out:?}"
    );
}

/// A short run in the room into `out` with `learners` learners.
fn run_spec(out: &std::path::Path, learners: usize) -> learning::run::TrainRun {
    learning::run::TrainRun {
        world: room(),
        extra_worlds: Vec::new(),
        hold_out: false,
        map: "maps/room/map.yaml".into(),
        extra_maps: Vec::new(),
        config: small_options(out).config,
        out: out.to_path_buf(),
        minutes: 0.03,
        fresh: false,
        eval_episodes: 4,
        goals: learning::Goals::InView,
        learners,
        selector: None,
    }
}

/// A whole run into a directory (what `mentalsim train` does): curves, the exported policy
/// and `eval.json`, whose figures are the returned summary's; a second run resumes.
#[test]
fn a_run_writes_curves_policy_and_an_eval_json_that_is_its_summary() {
    use learning::run::run;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let spec = run_spec(&out, 1);
    assert!(!spec.resumes());
    let summary = run(spec.clone(), &mut |_| true).unwrap();
    for file in [
        "policy.safetensors",
        "policy.json",
        "curves.csv",
        "curves.png",
        "evals.csv",
        "eval.json",
        "checkpoint/state.json",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    let eval: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("eval.json")).unwrap()).unwrap();
    assert_eq!(eval, serde_json::to_value(&summary).unwrap());
    assert_eq!(eval["goals"], "in-view");
    assert_eq!(eval["eval_episodes"], 4);
    assert_eq!(eval["goals_anywhere"]["episodes"], 4);
    assert_eq!(eval["map"], "maps/room/map.yaml");
    assert!(summary.env_steps > 0 && summary.wall_s >= 1.8 && !summary.interrupted);
    assert_eq!(summary.sessions, 1);
    assert_eq!(learning::run::map_name(&spec.map), "room");

    // The budget is spent: a second run resumes, trains no further and reports again.
    assert!(spec.resumes());
    let again = run(spec, &mut |_| true).unwrap();
    assert_eq!(again.sessions, 2);
    assert_eq!(again.env_steps, summary.env_steps);
}

/// Two learners side by side (one per core): each trains in its own directory with its own
/// seed, the one whose policy does best on the selection missions is the run's policy (its
/// files in `out`), `eval.json` says which and how each did, and a second run resumes both.
#[test]
fn learners_side_by_side_train_their_own_seeds_and_the_better_policy_is_the_runs() {
    use learning::run::{TrainRun, run};
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let spec = run_spec(&out, 2);
    assert!(!spec.resumes());
    let summary = run(spec.clone(), &mut |_| true).unwrap();
    assert_eq!(summary.learners, 2);
    assert_eq!(summary.learner_selection.len(), 2);
    let chosen = summary.chosen_learner.expect("a chosen learner");
    let best = summary
        .learner_selection
        .iter()
        .map(|s| s.score)
        .fold(0.0, f64::max);
    assert_eq!(summary.learner_selection[chosen].score, best);
    assert_eq!(summary.seed, spec.config.seed + chosen as u64);
    for k in 0..2 {
        let d = out.join("learners").join(k.to_string());
        assert!(d.join("checkpoint/state.json").is_file(), "learner {k}");
        assert!(d.join("policy.safetensors").is_file(), "learner {k}");
    }
    // The run's policy is the chosen learner's, byte for byte; the learners differ.
    let weights = |d: &std::path::Path| std::fs::read(d.join("policy.safetensors")).unwrap();
    let learner = |k: usize| out.join("learners").join(k.to_string());
    assert_eq!(weights(&out), weights(&learner(chosen)));
    assert_ne!(weights(&learner(0)), weights(&learner(1)));
    let eval: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("eval.json")).unwrap()).unwrap();
    assert_eq!(eval, serde_json::to_value(&summary).unwrap());
    assert_eq!(eval["learners"], 2);
    // A second run resumes both learners.
    assert!(spec.resumes());
    let again = run(spec.clone(), &mut |_| true).unwrap();
    assert_eq!(again.sessions, 2);
    // Out of range is refused by name.
    let e = run(
        TrainRun {
            learners: 0,
            ..spec
        },
        &mut |_| true,
    )
    .unwrap_err();
    assert!(e.to_string().contains("learners"), "{e}");
}

/// The warm start: behaviour cloning moves the actor onto the demonstrator's actions, and the
/// TD3+BC objective keeps it near them while the critic (which here prefers another action)
/// pulls; without the BC term the critic wins.
#[test]
fn behaviour_cloning_and_the_td3_bc_term_pull_the_actor_to_the_demonstrator() {
    let dim = 8;
    let expert = [0.3f32, -0.6];
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut buffer = ReplayBuffer::new(dim, 10_000);
    // The reward prefers (0.9, 0.5): far from the demonstrator.
    let reward = |a: [f32; 2]| -((a[0] - 0.9).powi(2) + (a[1] - 0.5).powi(2));
    for _ in 0..5000 {
        let s: Vec<f32> = (0..dim).map(|_| rng.random()).collect();
        let a = [rng.random::<f32>(), rng.random::<f32>() * 2.0 - 1.0];
        buffer.push(&s, a, expert, reward(a), &s, true);
    }
    let mut batch = Batch::default();
    let mean_action = |learner: &Learner, rng: &mut ChaCha8Rng| {
        let mut out = Vec::new();
        let n = 64;
        let s: Vec<f32> = (0..n * dim).map(|_| rng.random()).collect();
        learner.act(&s, n, &mut out);
        let lin = out.iter().step_by(2).sum::<f32>() / n as f32;
        let ang = out.iter().skip(1).step_by(2).sum::<f32>() / n as f32;
        [lin, ang]
    };
    let config = Td3Config {
        hidden: vec![32, 32],
        batch_size: 64,
        ..Td3Config::default()
    };
    let mut learner = Learner::new(config.clone(), dim, tch::Device::Cpu, 3);
    let mut loss = f64::INFINITY;
    for _ in 0..600 {
        buffer.sample_into(&mut rng, 64, &mut batch);
        loss = learner.clone_step(&batch);
    }
    let cloned = mean_action(&learner, &mut rng);
    assert!(loss < 0.01, "cloning loss {loss}");
    assert!(
        (cloned[0] - expert[0]).abs() < 0.1 && (cloned[1] - expert[1]).abs() < 0.1,
        "{cloned:?}"
    );
    learner.sync_targets();
    let train = |alpha: f64, rng: &mut ChaCha8Rng| {
        let mut l = Learner::new(
            Td3Config {
                bc_alpha: alpha,
                beta1: 0.0,
                beta2: 0.0,
                ..config.clone()
            },
            dim,
            tch::Device::Cpu,
            3,
        );
        let mut b = Batch::default();
        for _ in 0..1500 {
            buffer.sample_into(rng, 64, &mut b);
            l.update(&b, rng);
        }
        mean_action(&l, rng)
    };
    let with_bc = train(0.05, &mut rng);
    let without = train(0.0, &mut rng);
    let dist = |a: [f32; 2]| ((a[0] - expert[0]).powi(2) + (a[1] - expert[1]).powi(2)).sqrt();
    assert!(
        dist(with_bc) < dist(without) - 0.2,
        "with the BC term {with_bc:?}, without {without:?}"
    );
}

/// With `export_best`, the exported actor is the best evaluated one: the best periodic
/// evaluation's, unless the final actor does at least as well on the same missions.
#[test]
fn the_exported_actor_is_the_best_evaluated_one() {
    let world = room();
    let dir = tempfile::tempdir().unwrap();
    let mut options = small_options(dir.path());
    options.config.export_best = true;
    let mut trainer = Trainer::new(world, options).unwrap();
    trainer
        .run(
            Budget {
                env_steps: Some(5000),
                ..Budget::default()
            },
            &mut |_| true,
        )
        .unwrap();
    let evals: Vec<f64> = trainer
        .evals()
        .iter()
        .map(|e| e.report.success_rate)
        .collect();
    assert!(evals.len() >= 4, "{evals:?}");
    let export = dir.path().join("policy");
    trainer.export(&export, serde_json::json!({})).unwrap();
    let policy = Policy::load(&export).unwrap();
    let exported = &policy.metadata().training["exported"];
    let best = evals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    match exported["actor"].as_str().unwrap() {
        "best evaluation" => {
            assert_eq!(
                exported["success_rate"].as_f64().unwrap(),
                best,
                "{exported}"
            );
            assert!(
                exported["final_success_rate"].as_f64().unwrap() <= best,
                "{exported}"
            );
        }
        "final" => {}
        other => panic!("exported {other}"),
    }
    // Without it, the final actor.
    let mut options = small_options(dir.path());
    options.config.export_best = false;
    options.out_dir = dir.path().join("plain");
    let mut trainer = Trainer::new(room(), options).unwrap();
    trainer
        .run(
            Budget {
                env_steps: Some(1500),
                ..Budget::default()
            },
            &mut |_| true,
        )
        .unwrap();
    trainer.export(&export, serde_json::json!({})).unwrap();
    let policy = Policy::load(&export).unwrap();
    assert_eq!(policy.metadata().training["exported"]["actor"], "final");
}
