//! `mentalsim train` and `mentalsim eval` on real shared maps, through the real binary.

use std::path::PathBuf;

use super::mentalsim;

fn shared_map(folder: &str, yaml: &str) -> Option<PathBuf> {
    // Fails under CI (or MENTALSIM_REQUIRE_ALL=1); by hand, says why the test returns.
    fixtures::shared_fixture(format!("maps/ros/{folder}/{yaml}"), "the shared map")
}

fn json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

#[test]
fn train_writes_policy_curves_and_eval_and_eval_runs_it_on_another_map() {
    let (Some(map), Some(other)) = (
        shared_map("strands_tum_kitchen", "tum_kitchen.yaml"),
        shared_map("aws_bookstore", "map.yaml"),
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    // A short run with small networks: the interface, not the policy's quality.
    let config = dir.path().join("config.json");
    std::fs::write(
        &config,
        r#"{"td3": {"hidden": [32, 32], "batch_size": 64}, "envs": 4, "random_steps": 200,
            "eval_every": 400, "eval_episodes": 5, "max_episode_steps": 100}"#,
    )
    .unwrap();
    let output = mentalsim()
        .args(["train", "--minutes", "0.1", "--eval-episodes", "5", "--map"])
        .arg(&map)
        .arg("--out")
        .arg(&out)
        .arg("--config")
        .arg(&config)
        .args(["--learners", "1"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
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
    let eval = json(&out.join("eval.json"));
    for key in [
        "success_rate",
        "collision_rate",
        "episodes",
        "env_steps",
        "wall_s",
    ] {
        assert!(eval[key].is_number(), "eval.json lacks {key}: {eval}");
    }
    assert!(eval["env_steps"].as_u64().unwrap() > 0);
    assert!((0.0..=1.0).contains(&eval["success_rate"].as_f64().unwrap()));
    assert!(eval["wall_s"].as_f64().unwrap() >= 6.0);

    // Running again with the same budget resumes and finds it already spent.
    let again = mentalsim()
        .args(["train", "--minutes", "0.1", "--eval-episodes", "5", "--map"])
        .arg(&map)
        .arg("--out")
        .arg(&out)
        .arg("--config")
        .arg(&config)
        .args(["--learners", "1"])
        .output()
        .unwrap();
    assert!(again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("resuming"));
    let eval2 = json(&out.join("eval.json"));
    assert_eq!(eval2["sessions"], 2);
    assert_eq!(eval2["env_steps"], eval["env_steps"]);

    let report = dir.path().join("eval-other.json");
    let output = mentalsim()
        .args(["eval", "--episodes", "6", "--policy"])
        .arg(&out)
        .arg("--map")
        .arg(&other)
        .arg("--json")
        .arg(&report)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let e = json(&report);
    assert_eq!(e["episodes"], 6);
    for key in [
        "success_rate",
        "collision_rate",
        "env_steps",
        "wall_s",
        "control_command_us",
    ] {
        assert!(e[key].is_number(), "{key}: {e}");
    }
    // The headline is about goals in view; the same missions' other kind is reported beside.
    assert_eq!(e["goals"], "in-view");
    assert_eq!(e["goals_anywhere"]["episodes"], 6);
    assert!(e["goals_anywhere"]["success_rate"].is_number(), "{e}");
    assert_eq!(eval["goals"], "in-view");
    assert!(eval["goals_anywhere"]["success_rate"].is_number(), "{eval}");
    let anywhere = mentalsim()
        .args(["eval", "--episodes", "6", "--goals", "anywhere", "--policy"])
        .arg(&out)
        .arg("--map")
        .arg(&other)
        .output()
        .unwrap();
    assert!(anywhere.status.success());
    let a: serde_json::Value = serde_json::from_slice(&anywhere.stdout).unwrap();
    assert_eq!(a["goals"], "anywhere");
    assert_eq!(a["success_rate"], e["goals_anywhere"]["success_rate"]);
    assert_eq!(a["goals_in_view"]["success_rate"], e["success_rate"]);

    // Every roadmap edge of the other map, both directions, driven by the policy.
    let edges = mentalsim()
        .args([
            "eval",
            "--episodes",
            "6",
            "--goals",
            "edges",
            "--rollouts",
            "2",
        ])
        .arg("--policy")
        .arg(&out)
        .arg("--map")
        .arg(&other)
        .output()
        .unwrap();
    assert!(
        edges.status.success(),
        "{}",
        String::from_utf8_lossy(&edges.stderr)
    );
    let g: serde_json::Value = serde_json::from_slice(&edges.stdout).unwrap();
    let n = g["edges"].as_u64().unwrap();
    let kept = g["edges_kept"].as_u64().unwrap();
    assert!(n > 10 && kept <= n, "{g}");
    let rate = g["edge_success_rate"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&rate), "{g}");
    assert_eq!(g["edge_rollouts"], 2);
    assert!(g["edges_dropped_worst"].is_array(), "{g}");
    // Beside the in-view figures of the same policy and missions.
    assert_eq!(g["success_rate"], e["success_rate"]);
    assert!(
        (0.0..=1.0).contains(&g["edge_handover_share"].as_f64().unwrap()),
        "{g}"
    );

    // The same policy in `bench edges`: as plans drive it, behind the shield alone, and the
    // follower, on every edge of every map under the directory; tables and edge maps. A
    // sample of the edges: MPPI's sampled rollouts (about 4 ms a control step) make the map's
    // few hundred edges half a minute.
    let bench = dir.path().join("bench-edges");
    let output = mentalsim()
        .args([
            "bench",
            "edges",
            "--rollouts",
            "1",
            "--edges",
            "40",
            "--maps",
        ])
        .arg(other.parent().unwrap())
        .arg("--policy")
        .arg(&out)
        .arg("--out")
        .arg(&bench)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let csv = std::fs::read_to_string(bench.join("edges.csv")).unwrap();
    let controllers: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap())
        .collect();
    assert_eq!(
        controllers,
        [
            "run",
            "run (shield only)",
            "run (RPP handover)",
            "follower",
            "rpp",
            "mppi"
        ],
        "{csv}"
    );
    // Every row drove the same 40 edges, both directions.
    assert!(
        csv.lines()
            .skip(1)
            .all(|l| l.split(',').nth(2) == Some("80")),
        "{csv}"
    );
    let md = std::fs::read_to_string(bench.join("edges.md")).unwrap();
    assert!(
        md.contains("| handover |")
            && md.contains("## Pooled")
            && md.contains("A sample of at most 40 roadmap edges per map"),
        "{md}"
    );
    for name in ["run", "run-shield-only", "follower"] {
        let png = bench.join(format!("aws_bookstore-{name}.png"));
        let img = image::open(&png)
            .unwrap_or_else(|e| panic!("{}: {e}", png.display()))
            .to_rgb8();
        // Kept edges are drawn green.
        assert!(
            img.pixels().any(|p| p.0 == [40, 160, 70]),
            "{} has no kept edge",
            png.display()
        );
    }
}

/// Many buildings by default: generated floors (one held out for the evaluation) and every map
/// under `--maps`, searched recursively.
#[test]
fn train_spreads_over_a_directory_of_maps_and_generated_floors() {
    let Some(map) = shared_map("strands_tum_kitchen", "tum_kitchen.yaml") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let maps = dir.path().join("maps").join("nested").join("kitchen");
    std::fs::create_dir_all(&maps).unwrap();
    for file in ["tum_kitchen.yaml", "tum_kitchen.pgm"] {
        std::fs::copy(map.with_file_name(file), maps.join(file)).unwrap();
    }
    let out = dir.path().join("run");
    let config = dir.path().join("config.json");
    std::fs::write(
        &config,
        r#"{"td3": {"hidden": [32, 32], "batch_size": 64}, "envs": 4, "demo_steps": 2000,
            "bc_steps": 50, "eval_every": 400, "eval_episodes": 5, "max_episode_steps": 100}"#,
    )
    .unwrap();
    let output = mentalsim()
        .args([
            "train",
            "--minutes",
            "0.05",
            "--eval-episodes",
            "5",
            "--generated",
            "2",
        ])
        .arg("--maps")
        .arg(dir.path().join("maps"))
        .arg("--out")
        .arg(&out)
        .arg("--config")
        .arg(&config)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let eval = json(&out.join("eval.json"));
    // One learner per core by default (at most 4), each in its own directory; the best one's
    // policy is the run's.
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get().min(4));
    assert_eq!(eval["learners"], cores, "{eval}");
    if cores > 1 {
        let chosen = eval["chosen_learner"].as_u64().expect("chosen") as usize;
        assert_eq!(eval["learner_selection"].as_array().unwrap().len(), cores);
        assert_eq!(
            std::fs::read(out.join("policy.safetensors")).unwrap(),
            std::fs::read(out.join(format!("learners/{chosen}/policy.safetensors"))).unwrap()
        );
        assert!(out.join("learners/0/checkpoint/state.json").is_file());
    }
    let trained: Vec<&str> = eval["extra_maps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_str().unwrap())
        .collect();
    assert_eq!(trained.len(), 3, "{eval}");
    assert!(
        trained[0].ends_with("nested/kitchen/tum_kitchen.yaml"),
        "{trained:?}"
    );
    assert!(trained[1].ends_with("floors/floor_000.yaml"), "{trained:?}");
    // The held-out evaluation ran on a generated floor training never saw.
    let held_out = eval["map"].as_str().unwrap();
    assert!(held_out.ends_with("floors/floor_002.yaml"), "{eval}");
    assert!(!trained.contains(&held_out));
    for i in 0..3 {
        for ext in ["png", "yaml"] {
            assert!(out.join(format!("floors/floor_00{i}.{ext}")).is_file());
        }
    }
    // The same seed generates the same floors.
    let again = dir.path().join("again");
    let output = mentalsim()
        .args([
            "train",
            "--minutes",
            "0.01",
            "--eval-episodes",
            "1",
            "--generated",
            "2",
        ])
        .arg("--out")
        .arg(&again)
        .arg("--config")
        .arg(&config)
        .output()
        .unwrap();
    assert!(output.status.success());
    assert_eq!(
        std::fs::read(out.join("floors/floor_001.png")).unwrap(),
        std::fs::read(again.join("floors/floor_001.png")).unwrap()
    );
}

#[test]
fn train_and_eval_refuse_bad_input_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [(&[&str], &str); 10] = [
        (
            &["train", "--learners", "0", "--map", "x.yaml", "--out"],
            "--learners must be between 1 and 16, got 0",
        ),
        (
            &["train", "--maps", "/nonexistent/maps", "--out"],
            "not a directory",
        ),
        (
            &["train", "--generated", "0", "--out"],
            "nothing to train in",
        ),
        (
            &["train", "--map", "/nonexistent/map.yaml", "--out"],
            "does not exist",
        ),
        (
            &["train", "--minutes=-1", "--map", "x.yaml", "--out"],
            "--minutes",
        ),
        (
            &["eval", "--map", "x.yaml", "--policy"],
            "cannot load the policy",
        ),
        (
            &[
                "train",
                "--map",
                "x.yaml",
                "--config",
                "/nonexistent.json",
                "--out",
            ],
            "cannot read the training configuration",
        ),
        (
            &["eval", "--episodes", "0", "--map", "x.yaml", "--policy"],
            "--episodes",
        ),
        (
            &[
                "eval",
                "--goals",
                "edges",
                "--rollouts",
                "0",
                "--map",
                "x.yaml",
                "--policy",
            ],
            "--rollouts",
        ),
        (
            &["bench", "edges", "--edges", "0", "--maps", "x", "--out"],
            "--edges must be at least 1",
        ),
    ];
    for (args, expected) in cases {
        let output = mentalsim()
            .args(args)
            .arg(dir.path().join("out"))
            .output()
            .unwrap();
        assert!(!output.status.success(), "{args:?} succeeded");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(stderr.contains(expected), "{args:?}: {stderr}");
    }
    // An unknown key in the configuration is named.
    let config = dir.path().join("bad.json");
    std::fs::write(&config, r#"{"td3": {"gama": 0.9}}"#).unwrap();
    let output = mentalsim()
        .args(["train", "--map", "x.yaml", "--out", "o", "--config"])
        .arg(&config)
        .output()
        .unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("gama"));
}

#[test]
fn bench_beta_trains_one_policy_per_beta_and_seed_and_tabulates_their_evaluations() {
    let Some(map) = shared_map("strands_tum_kitchen", "tum_kitchen.yaml") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("beta");
    let config = dir.path().join("config.json");
    std::fs::write(
        &config,
        r#"{"td3": {"hidden": [32, 32], "batch_size": 64}, "envs": 4, "random_steps": 200,
            "eval_every": 400, "eval_episodes": 5, "max_episode_steps": 100}"#,
    )
    .unwrap();
    let output = mentalsim()
        .args([
            "bench",
            "beta",
            "--minutes",
            "0.03",
            "--betas",
            "0,5",
            "--seeds",
            "1",
            "--eval-episodes",
            "10",
            "--map",
        ])
        .arg(&map)
        .arg("--out")
        .arg(&out)
        .arg("--config")
        .arg(&config)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(out.join("beta.png").is_file());
    let table = std::fs::read_to_string(out.join("beta.md")).unwrap();
    // Each run's row carries what that run's own eval.json says, both kinds of goals.
    for beta in ["0", "5"] {
        let eval = json(&out.join(format!("beta-{beta}/seed-1/eval.json")));
        assert_eq!(eval["beta"].as_f64().unwrap(), beta.parse::<f64>().unwrap());
        let row = format!(
            "| {beta} | 1 | {:.1}% | {:.1}% | {:.1}% | {} |",
            eval["success_rate"].as_f64().unwrap() * 100.0,
            eval["collision_rate"].as_f64().unwrap() * 100.0,
            eval["goals_anywhere"]["success_rate"].as_f64().unwrap() * 100.0,
            eval["episodes"],
        );
        assert!(table.contains(&row), "{row} not in\n{table}");
    }
    // A negative β is refused, naming the flag.
    let output = mentalsim()
        .args(["bench", "beta", "--betas=-1", "--map"])
        .arg(&map)
        .arg("--out")
        .arg(dir.path().join("bad"))
        .output()
        .unwrap();
    assert!(!output.status.success());
    assert!(String::from_utf8_lossy(&output.stderr).contains("--betas"));
}
