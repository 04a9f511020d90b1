//! The navigation benchmark end to end on a small generated ROS map, with a hand-made policy.

use std::path::Path;

use bench::navigation::{NavigationBenchOptions, run_navigation_bench};
use learning::policy::write_goal_seeking_policy;

/// A 12 m x 6 m room at 0.05 m/px with an inner wall at x = 6 open at the top, as map_server
/// files (PGM rows top first).
fn write_map(dir: &Path) {
    let (w, h) = (240usize, 120usize);
    let mut pixels = vec![254u8; w * h];
    for row in 0..h {
        // Image row 0 is the top of the map: y = (h - 1 - row) * 0.05.
        let y = (h - 1 - row) as f64 * 0.05;
        for col in 0..w {
            let x = col as f64 * 0.05;
            let border = col < 2 || row < 2 || col >= w - 2 || row >= h - 2;
            let inner = (5.9..6.1).contains(&x) && y < 4.2;
            if border || inner {
                pixels[row * w + col] = 0;
            }
        }
    }
    let mut pgm = format!("P5\n{w} {h}\n255\n").into_bytes();
    pgm.extend_from_slice(&pixels);
    std::fs::create_dir_all(dir.join("room")).expect("dir");
    std::fs::write(dir.join("room/room.pgm"), pgm).expect("pgm");
    std::fs::write(
        dir.join("room/room.yaml"),
        "image: room.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n",
    )
    .expect("yaml");
}

/// A scratch directory with a map under `maps/` and a goal-seeking policy in `policy/`.
fn map_and_policy() -> tempfile::TempDir {
    let tmp = tempfile::tempdir().expect("tmp");
    write_map(&tmp.path().join("maps"));
    write_goal_seeking_policy(
        &tmp.path().join("policy"),
        23,
        serde_json::json!({"test": true}),
    )
    .expect("policy");
    tmp
}

#[test]
fn the_benchmark_writes_table_3_for_every_method() {
    let tmp = map_and_policy();
    let report = run_navigation_bench(NavigationBenchOptions {
        maps_dir: tmp.path().join("maps"),
        runs: 2,
        policy: Some(tmp.path().join("policy")),
        out_dir: tmp.path().join("out"),
        candidates: 8,
        ..NavigationBenchOptions::default()
    })
    .expect("runs");
    assert_eq!(report.missions.len(), 1, "{:?}", report.skipped);
    let m = &report.missions[0];
    assert!(!m.full_length && m.prm_length_m > 5.0, "{m:?}");
    // Sixteen methods (the policy-aware roadmap, the shielded and unshielded hybrids, each
    // first attempt and re-tried; the policy-aware roadmap with RPP as the handover follower,
    // and with the policy on the smoothed path; that on the geometric roadmap; the shielded
    // hybrid without the handover; the plan endpoint; pure RL; classical, bare and shielded;
    // Nav2's RPP and MPPI, shielded), two runs each.
    assert_eq!(report.rows.len(), 32);
    for method in bench::navigation::METHODS {
        assert_eq!(
            report.rows.iter().filter(|r| r.method == method).count(),
            2,
            "{method}"
        );
    }
    // The plan endpoint is never worse than the classical follower.
    let successes = |m: &str| {
        report
            .rows
            .iter()
            .filter(|r| r.method == m && r.success)
            .count()
    };
    assert!(successes("plan_endpoint") >= successes("classical_prm"));
    // The policy on the map's roadmap edges, with what building the roadmap cost.
    assert_eq!(report.edges.len(), 1);
    let e = &report.edges[0];
    assert!(
        e.directions > 0 && e.kept <= e.directions && e.build_s > 0.0,
        "{e:?}"
    );
    assert!((0.0..=1.0).contains(&e.edge_success_rate));
    assert!(report.markdown.contains("The policy on the roadmap edges"));
    let csv = std::fs::read_to_string(&report.csv_path).expect("csv");
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some(
            "method,map,run,success,distance_m,time_s,person_collision,min_person_clearance_m,\
             intimate_intrusions,personal_intrusions,path_length_m,time_not_moving_s,recoveries,\
             limit_time_s"
        )
    );
    assert_eq!(lines.count(), 32);
    // Nav2's controllers reach the goal of this small room, behind the shield, and MPPI says
    // what a control cycle cost.
    for method in ["classical_rpp_shielded", "classical_mppi_shielded"] {
        assert!(
            report
                .rows
                .iter()
                .filter(|r| r.method == method)
                .all(|r| r.success && r.path_length_m >= m.straight_m),
            "{method}: {:?}",
            report.rows
        );
    }
    assert_eq!(report.mppi.len(), 1);
    let c = &report.mppi[0].cycles;
    assert!(
        c.cycles > 0 && c.mean_ms() > 0.0 && c.batch_size == 1000,
        "{c:?}"
    );
    assert!(report.markdown.contains("MPPI's cost per control cycle"));
    assert!(report.markdown.contains("Who wins"));
    // The classical follower on the roadmap path reaches the goal.
    assert!(
        report
            .rows
            .iter()
            .filter(|r| r.method == "classical_prm")
            .all(|r| r.success && r.distance_m >= m.straight_m),
        "{:?}",
        report.rows
    );
    let md = std::fs::read_to_string(&report.markdown_path).expect("md");
    for needle in [
        "hybrid_prm_rl",
        "hybrid_unshielded",
        "pure_rl",
        "classical_prm",
        "Plan latency",
        "Table 3",
    ] {
        assert!(md.contains(needle), "{needle} missing from\n{md}");
    }
    assert_eq!(report.latency.len(), 2);
    assert!(report.summary().contains("plan latency"));

    // Without a policy only the classical follower runs (bare and shielded), and the summary
    // says so.
    let report = run_navigation_bench(NavigationBenchOptions {
        maps_dir: tmp.path().join("maps"),
        runs: 1,
        out_dir: tmp.path().join("out2"),
        candidates: 6,
        ..NavigationBenchOptions::default()
    })
    .expect("runs");
    assert!(
        report
            .rows
            .iter()
            .all(|r| r.method.starts_with("classical_"))
    );
    assert_eq!(report.rows.len(), 4);
    assert!(report.markdown.contains("No policy given"));
    assert!(report.summary().contains("no policy given"));

    // `--methods` runs only those named, and names the methods when one is unknown.
    let only = |methods: &[&str]| NavigationBenchOptions {
        maps_dir: tmp.path().join("maps"),
        runs: 1,
        policy: Some(tmp.path().join("policy")),
        out_dir: tmp.path().join("out3"),
        candidates: 6,
        methods: methods.iter().map(|m| (*m).to_owned()).collect(),
        ..NavigationBenchOptions::default()
    };
    let report = run_navigation_bench(only(&["hybrid_policy_path", "classical_rpp_shielded"]))
        .expect("runs");
    let mut ran: Vec<&str> = report.rows.iter().map(|r| r.method).collect();
    ran.sort_unstable();
    assert_eq!(ran, ["classical_rpp_shielded", "hybrid_policy_path"]);
    assert!(report.markdown.contains("`hybrid_policy_path`:"));
    assert!(!report.markdown.contains("MPPI's cost per control cycle"));
    // `--shortcut`: every method's roadmap path without its detours, and the header says so.
    let long = run_navigation_bench(only(&["classical_rpp_shielded"])).expect("runs");
    let short = run_navigation_bench(NavigationBenchOptions {
        shortcut: true,
        ..only(&["classical_rpp_shielded"])
    })
    .expect("runs");
    assert!(short.markdown.contains("`--shortcut`"));
    assert!(!long.markdown.contains("`--shortcut`"));
    let driven = |r: &bench::navigation::NavigationBenchReport| r.rows[0].path_length_m;
    assert!(
        driven(&short) <= driven(&long) + 0.05,
        "{} against {}",
        driven(&short),
        driven(&long)
    );
    // `--policy-roadmap-per-run`: the hybrids plan on each run's own policy-aware roadmap.
    let per_run = run_navigation_bench(NavigationBenchOptions {
        runs: 2,
        policy_roadmap_per_run: true,
        ..only(&["hybrid_policy_path", "classical_rpp_shielded"])
    })
    .expect("runs");
    assert!(per_run.markdown.contains("`--policy-roadmap-per-run`"));
    assert_eq!(per_run.rows.len(), 4);
    let e = run_navigation_bench(only(&["hybrid", "rpp"])).expect_err("unknown");
    assert!(
        e.to_string().contains("\"hybrid\"") && e.to_string().contains("hybrid_policy_path"),
        "{e}"
    );
}

#[test]
fn with_people_the_table_counts_collisions_and_near_misses_with_them() {
    let tmp = map_and_policy();
    let report = run_navigation_bench(NavigationBenchOptions {
        maps_dir: tmp.path().join("maps"),
        runs: 2,
        policy: Some(tmp.path().join("policy")),
        out_dir: tmp.path().join("out"),
        candidates: 8,
        people: 4.0,
        ..NavigationBenchOptions::default()
    })
    .expect("runs");
    // The ablations do not run among people; everything else does, two runs each.
    for method in bench::navigation::METHODS {
        let expected = if method.starts_with("hybrid_unshielded") || method.ends_with("no_handover")
        {
            0
        } else {
            2
        };
        assert_eq!(
            report.rows.iter().filter(|r| r.method == method).count(),
            expected,
            "{method}"
        );
    }
    // Every drive had people about: each row knows its closest approach to one.
    assert!(
        report
            .rows
            .iter()
            .filter(|r| r.method != "hybrid_policy_roadmap" || r.distance_m > 0.0)
            .all(|r| r.min_person_clearance_m.is_some()),
        "{:?}",
        report.rows
    );
    for row in &report.rows {
        if row.person_collision {
            assert!(!row.success && rehearsal::hit_person(&row.reason));
        }
    }
    assert!(report.markdown.contains("Collisions with people"));
    assert!(report.markdown.contains("4 people per 100 m²"));
    assert!(report.markdown.contains("Personal intrusions per 100 m"));
    // The social metrics are filled from the drives: among 4 people per 100 m² in a 60 m²
    // room, some run comes within a person's personal space, every run's path length is its
    // distance, and standing still is never longer than the run.
    assert!(
        report.rows.iter().any(|r| r.personal_intrusions > 0),
        "{:?}",
        report.rows
    );
    for r in &report.rows {
        assert_eq!(r.path_length_m, r.distance_m);
        assert!(
            r.time_not_moving_s >= 0.0 && r.time_not_moving_s <= r.time_s + 1e-9,
            "{r:?}"
        );
        // The driven line at the top speeds takes some time, never more than the drive did.
        assert!(
            r.limit_time_s <= r.time_s + 1e-6 && (r.distance_m < 0.1 || r.limit_time_s > 0.0),
            "{r:?}"
        );
    }
    let csv = std::fs::read_to_string(&report.csv_path).expect("csv");
    let filled = csv
        .lines()
        .skip(1)
        .filter(|l| {
            l.split(',')
                .nth(9)
                .is_some_and(|p| p.parse::<u32>().is_ok_and(|n| n > 0))
        })
        .count();
    assert!(filled > 0, "{csv}");
}
