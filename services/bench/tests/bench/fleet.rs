//! The fleet benchmark end to end on its generated floors: robots sent through a corridor, a
//! four-way crossing and a doorway, each one robot wide, ask the service's planner at once; each
//! is fitted around the others, and the committed plans are driven together.

use bench::fleet::{FleetBenchOptions, Scenario, markdown, run_fleet_bench};

const ROBOT_IRI: &str = "https://mentalsim.dev/data/robots/differential-robot";

fn options(robots: usize) -> FleetBenchOptions {
    scenario(Scenario::Corridor, robots)
}

fn scenario(scenario: Scenario, robots: usize) -> FleetBenchOptions {
    let ttl = knowledge::bundled::BUNDLED
        .iter()
        .find(|b| b.file.starts_with("robots/"))
        .expect("the bundled robot")
        .turtle;
    FleetBenchOptions {
        maps: std::path::PathBuf::from("unused"),
        robots,
        people: 0.0,
        scenario,
        seed: 7,
        robot_ttl: ttl.as_bytes().to_vec(),
        robot_iri: ROBOT_IRI.to_owned(),
        max_wait_s: 600.0,
        order_seed: None,
        same_seed: false,
        orders: 0,
        improve_s: 0.0,
        processes: 1,
    }
}

#[test]
fn two_robots_swap_through_a_corridor_one_robot_wide() {
    let rows = run_fleet_bench(&options(2)).expect("runs");
    assert_eq!(rows.len(), 1);
    let r = &rows[0];
    assert_eq!(
        (r.map.as_str(), r.scenario.as_str(), r.robots),
        ("corridor", "corridor", 2)
    );
    // Both are answered; they cannot pass in the corridor, so one waits for the other.
    assert_eq!(r.planned, 2, "{r:?}");
    assert!(r.waits_s > 0.0, "{r:?}");
    assert!(
        r.makespan_alone_s > 0.0 && r.sum_alone_s >= r.makespan_alone_s,
        "{r:?}"
    );
    assert!(
        r.latency_p50_ms > 0.0 && r.latency_p95_ms >= r.latency_p50_ms,
        "{r:?}"
    );
    // The joint run's figures are consistent with each other.
    let arrived = (r.joint_success_rate * 2.0).round() as usize;
    assert_eq!(arrived + r.joint_failures.len(), 2, "{r:?}");
    assert!(
        r.robot_collisions + r.stalls <= r.joint_failures.len(),
        "{r:?}"
    );
    if arrived == 2 {
        assert!(
            r.makespan_ratio >= 1.0,
            "waiting cannot make the last arrival earlier: {r:?}"
        );
    }
    assert!(markdown(&rows).contains("| corridor | corridor | 2 |"));
    // The JSON rows carry the fields the issue names.
    let json = serde_json::to_value(&rows).expect("json");
    for key in [
        "map",
        "scenario",
        "robots",
        "people",
        "joint_success_rate",
        "joint_success_starts_held_rate",
        "robot_collisions",
        "deadlocks",
        "makespan_ratio",
        "latency_p95_ms",
    ] {
        assert!(json[0].get(key).is_some(), "no {key} in {json}");
    }
}

#[test]
fn bad_options_are_refused_naming_them() {
    let err = run_fleet_bench(&options(0)).unwrap_err().to_string();
    assert!(err.contains("--robots"), "{err}");
    let mut o = options(2);
    o.people = -1.0;
    assert!(
        run_fleet_bench(&o)
            .unwrap_err()
            .to_string()
            .contains("--people")
    );
    let mut o = options(2);
    o.max_wait_s = f64::NAN;
    assert!(
        run_fleet_bench(&o)
            .unwrap_err()
            .to_string()
            .contains("--max-wait-s")
    );
    let mut o = options(2);
    o.orders = bench::fleet::MAX_ORDERS + 1;
    let err = run_fleet_bench(&o).unwrap_err().to_string();
    assert!(err.contains("--orders must lie in [0, 24]"), "{err}");
    let mut o = options(2);
    o.improve_s = -1.0;
    let err = run_fleet_bench(&o).unwrap_err().to_string();
    assert!(err.contains("--improve-s"), "{err}");
}

/// The reference beside a run (`--orders`): four robots through the corridor, planned at
/// once, then first-come in three orders; the best of those is one of them and no later than
/// any that brought every robot through, the run is read against it, and the lower bound
/// (the makespan alone) is below both.
#[test]
fn the_first_come_reference_is_read_beside_the_run() {
    let mut o = options(4);
    o.orders = 3;
    let rows = run_fleet_bench(&o).expect("runs");
    let r = &rows[0];
    assert_eq!(r.first_come_orders, 3);
    assert_eq!(r.first_come_makespans_s.len(), 3, "{r:?}");
    assert_eq!(r.first_come_arrived.len(), 3, "{r:?}");
    assert!(r.first_come_arrived.iter().all(|&a| a <= 4), "{r:?}");
    let best = r
        .best_first_come_makespan_s
        .expect("an order that brought every robot through");
    let through: Vec<f64> = r
        .first_come_makespans_s
        .iter()
        .zip(&r.first_come_arrived)
        .filter(|(_, a)| **a == 4)
        .map(|(m, _)| *m)
        .collect();
    assert!(through.contains(&best), "{r:?}");
    assert!(through.iter().all(|&m| best <= m), "{r:?}");
    let vs = r.makespan_vs_best_first_come.expect("a ratio");
    assert!((vs - r.makespan_s / best).abs() < 1e-12, "{r:?}");
    assert_eq!(r.makespan_lower_bound_s, r.makespan_alone_s);
    assert!(r.makespan_lower_bound_s > 0.0, "{r:?}");
    assert!(r.makespan_lower_bound_s <= best, "{r:?}");
    if r.joint_success_rate == 1.0 {
        assert!(r.makespan_lower_bound_s <= r.makespan_s, "{r:?}");
    }
    let md = markdown(&rows);
    assert!(md.contains("first-come in 3 orders"), "{md}");
    let json = serde_json::to_value(&rows).expect("json");
    for key in [
        "first_come_orders",
        "first_come_makespans_s",
        "best_first_come_makespan_s",
        "makespan_vs_best_first_come",
        "makespan_lower_bound_s",
    ] {
        assert!(json[0].get(key).is_some(), "no {key} in {json}");
    }
    // Without orders there is no reference, and the table says so.
    let rows = run_fleet_bench(&options(2)).expect("runs");
    assert_eq!(rows[0].first_come_orders, 0);
    assert!(rows[0].best_first_come_makespan_s.is_none());
    assert!(rows[0].makespan_vs_best_first_come.is_none());
}

/// The idle-time improver on the corridor, six robots planned at once: first-come commits
/// leave them crossing the lane in an order that costs the floor, and the improver revises
/// neighbourhoods of plans before anyone sets off. Every revision was driven among the others,
/// so the joint run of the revised plans brings every robot through, none touching another,
/// and no later than the first-come plans' joint run.
#[test]
fn the_improver_revises_the_corridor_and_the_fleet_still_comes_through() {
    let mut o = options(6);
    o.improve_s = 60.0;
    let rows = run_fleet_bench(&o).expect("runs");
    let r = &rows[0];
    assert_eq!(r.planned, 6, "{r:?}");
    assert!(r.revisions >= 1, "nothing revised: {r:?}");
    assert!(r.neighbourhoods_tried >= r.revisions, "{r:?}");
    assert_eq!(
        (r.joint_success_rate, r.robot_collisions, r.stalls),
        (1.0, 0, 0),
        "{r:?}"
    );
    let first_come = r.makespan_first_come_s.expect("the first-come joint run");
    assert!(r.makespan_s <= first_come + 1e-9, "{r:?}");
    assert!(markdown(&rows).contains("the improver, 60 s"));
    // Without the improver there is nothing before it to report.
    assert_eq!(
        run_fleet_bench(&options(2)).expect("runs")[0].makespan_first_come_s,
        None
    );
}

/// The outcome for a generated floor: every robot planned and arrived in the joint
/// run, none touching another, none blocked.
fn all_through(scenario: Scenario, robots: usize) {
    all_through_in(scenario, robots, None);
}

/// [`all_through`], the robots planned in the order `order_seed` shuffles them into (`None`:
/// all at once).
fn all_through_in(scenario: Scenario, robots: usize, order_seed: Option<u64>) {
    let opts = FleetBenchOptions {
        order_seed,
        same_seed: false,
        ..self::scenario(scenario, robots)
    };
    let rows = run_fleet_bench(&opts).expect("runs");
    assert_eq!(rows.len(), 1);
    let r = &rows[0];
    let name = scenario.as_str();
    assert_eq!(
        (r.map.as_str(), r.scenario.as_str(), r.robots),
        (name, name, robots)
    );
    assert_eq!(r.planned, robots, "refused: {r:?}");
    assert_eq!(
        (r.robot_collisions, r.stalls, r.deadlocks),
        (0, 0, 0),
        "{r:?}"
    );
    assert!(r.joint_failures.is_empty(), "{r:?}");
    assert_eq!(r.joint_success_rate, 1.0, "{r:?}");
    // They meet in a passage one robot wide: someone waits.
    assert!(r.waits_s > 0.0, "{r:?}");
    assert!(r.makespan_ratio >= 1.0, "{r:?}");
    // The joint run as the console replays it: every robot's drive, a valid itinerary on the
    // floor, ending where its plan's goal is, and its outcome.
    let replay = &r.replay;
    assert_eq!(replay.plans.len(), robots);
    assert_eq!(replay.joint.len(), robots);
    assert!(
        replay.joint.iter().all(|j| j.outcome == "reached"),
        "{:?}",
        replay.joint
    );
    for it in &replay.plans {
        it.check().expect("a valid itinerary");
        assert_eq!(it.floor, replay.floor);
        let outcome = replay
            .joint
            .iter()
            .find(|j| j.robot == it.robot)
            .expect("its outcome");
        let end = it.trajectory.last().expect("poses").t_s;
        assert!(
            (end - outcome.time_s).abs() < 0.5,
            "{end} against {}",
            outcome.time_s
        );
    }
    let json = serde_json::to_value(replay).expect("serialises");
    assert!(
        json["plans"][0]["trajectory"][0]["t_s"].is_number(),
        "{json}"
    );
}

#[test]
fn eight_robots_cross_a_four_way_intersection_one_robot_wide() {
    // Two per arm, each sent to the opposite arm: they all meet at the intersection.
    all_through(Scenario::Crossing, 8);
}

/// Whoever is planned first is planned alone and the later robots are fitted around it; the
/// crossing holds in whatever order they ask. (A robot planned after several others, told to
/// wait at its start, once set off at once in the joint run because its route's first waypoint
/// was within reach of its start, and one of these orders stalled it beside a robot parked at
/// its goal.)
#[test]
fn the_crossing_holds_whatever_order_the_robots_are_planned_in() {
    for seed in 1..=6 {
        all_through_in(Scenario::Crossing, 8, Some(seed));
    }
}

#[test]
fn six_robots_swap_rooms_through_one_doorway() {
    all_through(Scenario::Doorway, 6);
}

#[test]
fn scenarios_parse_by_their_names() {
    for s in Scenario::ALL {
        assert_eq!(s.as_str().parse::<Scenario>(), Ok(s));
    }
    assert!("roundabout".parse::<Scenario>().is_err());
}

#[test]
fn more_robots_than_the_rooms_park_are_refused() {
    let err = run_fleet_bench(&scenario(Scenario::Doorway, 24))
        .unwrap_err()
        .to_string();
    assert!(err.contains("--robots 24"), "{err}");
}

/// Runs of [`robots_standing_in_each_others_way_make_way`], and how many of them must bring
/// every robot through.
const MAKE_WAY_RUNS: usize = 8;
const MAKE_WAY_THROUGH_AT_LEAST: usize = 4;

/// Ten robots standing at random in the small shared bookstore, several in each other's only
/// way with no plan yet: one of each such pair makes way (its route goes first to a place
/// off the other's), instead of both waiting for the other's plan until refused, and every
/// robot waiting behind them with them. Before, 1 of 10 was planned with this seed, in every
/// run.
///
/// Since, all 10 in most runs but not in every one, and no order or seed makes a run repeat:
/// making way resolves a cycle of robots asking *at once* (asked one at a time, in any order,
/// the robot standing in the first plan's way is refused and 1 of 10 is planned, as before),
/// and the plans wait for each other on the wall clock (`standing_wait_s`), so where a
/// cycle's robots are still trying routes around each other when the others' waits run out,
/// some are refused as before. So the test states a rate: of 8 runs, at least half plan
/// every robot and bring at least 9 of 10 through; measured, 48 of 56 runs did (86%, seven
/// runs of this test, alone and beside the crate's other tests), where this fails about once
/// in 500 (binomial, 8 runs at 86%), and without making way none would. No run, good or bad,
/// may bring two robots into contact.
#[test]
fn robots_standing_in_each_others_way_make_way() {
    make_way_runs(1);
}

/// [`robots_standing_in_each_others_way_make_way`] with the robots asking two planners, as
/// two API processes sharing a job database: the plans of one see the waits of the other's
/// through the schedule ([`planner::FleetSchedule::waits`]), so the cycles across them are
/// found and made way in as often as within one.
#[test]
fn robots_of_two_processes_standing_in_each_others_way_make_way() {
    make_way_runs(2);
}

/// [`MAKE_WAY_RUNS`] runs of ten robots on the shared bookstore asking `processes` planners.
fn make_way_runs(processes: usize) {
    let Some(yaml) = fixtures::shared_fixture(
        "maps/ros/aws_bookstore/map.yaml",
        "the shared bookstore map",
    ) else {
        return;
    };
    let mut o = scenario(Scenario::Random, 10);
    o.maps = yaml.parent().expect("the map's directory").to_path_buf();
    o.people = 2.0;
    o.seed = 2;
    o.processes = processes;
    let runs: Vec<_> = (0..MAKE_WAY_RUNS)
        .map(|_| {
            let r = run_fleet_bench(&o).expect("runs").remove(0);
            assert_eq!(r.robots, 10, "{r:?}");
            assert_eq!(r.robot_collisions, 0, "{r:?}");
            (r.planned, r.joint_success_rate, r.refusals)
        })
        .collect();
    let through = runs
        .iter()
        .filter(|(planned, arrived, _)| *planned == 10 && *arrived >= 0.9)
        .count();
    eprintln!(
        "{processes} process(es): {through} of {MAKE_WAY_RUNS} runs planned every robot: {:?}",
        runs.iter().map(|r| (r.0, r.1)).collect::<Vec<_>>()
    );
    assert!(
        through >= MAKE_WAY_THROUGH_AT_LEAST,
        "{through} of {MAKE_WAY_RUNS} runs planned every robot and brought 9 of 10 through, \
         fewer than {MAKE_WAY_THROUGH_AT_LEAST} (planned, arrived, refusals): {runs:?}"
    );
}
