//! `mentalsim bench navigation`: the paper's Table 3 (§5.3, long-range navigation) in the mental
//! simulation, on every ROS map under a directory.
//!
//! Per map, one long mission: about `mission_length_m` (140 m, the paper's) of roadmap path
//! where the map allows, otherwise the longest roadmap route among pairs of far-apart points of
//! the largest free region (pairs of `candidates` sampled points, the longest or the one closest
//! to the target length kept). Each method then runs the mission `runs` times (the paper: 10),
//! each run with its own roadmap seed and simulation noise:
//!
//! - `hybrid_prm_rl`: the policy through the roadmap's waypoints with the executor of
//!   `rehearsal` (15 s waypoint timer, replanning), counted on its **first** attempt only:
//!   one drive, as the paper's robot drove once. This is the row to compare with Table 3.
//! - `hybrid_prm_rl_resampled`: the same call as the plan endpoint makes it, with up to
//!   `max_attempts` roadmap re-samples after a collision or stall; a success is a validated
//!   plan, its distance and time those of the validating drive. This is what the service
//!   delivers, not a like-for-like figure.
//! - `pure_rl`: the policy driven straight at the final goal, no waypoints, with a generous
//!   timer (`pure_rl_seconds_per_10m` per 10 m of roadmap path).
//! - `classical_prm`: the classical rotate-then-go follower on the roadmap's waypoints, first
//!   attempt (the same executor with [`rehearsal::ClassicalFollower`]).
//!
//! Without a policy only `classical_prm` runs, and the summary says so.
//!
//! Outputs: `navigation.csv` (method, map, run, success, distance_m, time_s) and
//! `navigation.md` (Table 3 per map and over all maps, plus the plan latency: the wall time of
//! one `rehearsal::validate` call for the long mission, p50 and p99 over runs).

use std::fmt::Write as _;
use std::path::PathBuf;

mod report;
pub use report::{Stats, to_csv};
use report::{fallback_line, fmt_opt, to_markdown};
use std::sync::Arc;
use std::time::Instant;

use grid::seed::mix;
use learning::Policy;
use planning::{Point2, PrmParams, QueryOptions};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rehearsal::{
    AttemptDetails, AttemptOutcome, AttemptReport, ClassicalFollower, Controller, DriveLimits,
    MppiController, MppiCycles, PlanError, PlanOptions, PlanRequest, PolicyController,
    RoadmapCache, RppController,
};
use sim::{Action, Pose2, World};

use crate::error::{BenchError, io_err};
use crate::maps::{find_yamls, map_names};

/// What `mentalsim bench navigation` runs.
#[derive(Debug, Clone, PartialEq)]
pub struct NavigationBenchOptions {
    /// Directory searched recursively for ROS map_server `.yaml` files.
    pub maps_dir: PathBuf,
    /// Runs per method and map (the paper: 10).
    pub runs: usize,
    /// An exported policy directory (`policy.safetensors` + `policy.json`); without one only
    /// the classical follower runs.
    pub policy: Option<PathBuf>,
    /// Where `navigation.csv` and `navigation.md` go (created if missing).
    pub out_dir: PathBuf,
    /// Roadmap path length of the mission where the map allows, metres (the paper: ~140).
    pub mission_length_m: f64,
    /// Points sampled in the largest free region to choose the mission from (all pairs tried).
    pub candidates: usize,
    /// Attempts of the resampled hybrid (the plan endpoint's default: 5).
    pub max_attempts: u32,
    /// The waypoint timer, simulated seconds (the paper: 15).
    pub waypoint_timeout_s: f64,
    /// Pure RL's timer: simulated seconds per 10 m of roadmap path.
    pub pure_rl_seconds_per_10m: f64,
    /// Clearance kept beyond the robot's radius by the roadmap, metres.
    pub safety_margin_m: f64,
    /// Furniture placed in each map (a mix of library models and placeholders); 0 for the bare
    /// building, as the paper's Table 3.
    pub objects: usize,
    /// Base seed of missions, roadmaps and noise.
    pub seed: u64,
    /// The robot's TOSM description.
    pub robot_ttl: PathBuf,
    /// The robot's IRI in that file.
    pub robot_iri: String,
    /// Progress lines on stderr.
    pub verbose: bool,
    /// People walking about in every rehearsal, per 100 m² of free region (0: the empty
    /// building). Each run and attempt draws them afresh.
    pub people: f64,
}

impl Default for NavigationBenchOptions {
    fn default() -> Self {
        Self {
            maps_dir: PathBuf::from("../shared/maps/ros"),
            runs: 10,
            policy: None,
            out_dir: PathBuf::from("target/bench/navigation"),
            mission_length_m: 140.0,
            candidates: 24,
            max_attempts: 5,
            waypoint_timeout_s: 15.0,
            pure_rl_seconds_per_10m: 15.0,
            safety_margin_m: 0.1,
            objects: 0,
            seed: 1,
            robot_ttl: crate::bench_dir().join("../../ontologies/robots/differential-robot.ttl"),
            robot_iri: "https://mentalsim.dev/data/robots/differential-robot".to_owned(),
            verbose: false,
            people: 0.0,
        }
    }
}

/// The methods, in table order. `hybrid_prm_rl` is what `POST /v1/plan` runs: the policy
/// behind the collision shield (`rehearsal::Shield`), the classical follower taking over to the
/// next waypoint near obstacles (`rehearsal::HANDOVER_MARGIN_M`);
/// `hybrid_prm_rl_no_handover` is the same policy behind the shield alone (the ablation, first
/// attempt); `hybrid_unshielded` is the paper's
/// hybrid, the policy's commands sent to the wheels unchanged; `*_resampled` is the same with
/// the roadmap re-sampled after a failed attempt; `plan_endpoint` is exactly what `POST /v1/plan`
/// answers with `options.controller: auto`: the controller the map's controller trial picks
/// (`planner::controllers`; a hybrid on the policy-aware roadmap), re-sampled, then the
/// classical follower (also re-sampled) for a leg the pick validated in no attempt. `hybrid_policy_roadmap*` are the shielded policy on the
/// policy-aware roadmap as `options.roadmap: auto` plans on it (PRM-RL: the map's geometric
/// roadmap with every edge direction driven 10 times by the policy, weighted by length and
/// risk; directions under 90% success only where the kept ones join no route, at 100 m more),
/// first attempt and with re-tries (same roadmap, new noise). `pure_rl` is the policy behind
/// the shield driving straight at the goal (no handover: the follower's segment would cross
/// walls). `classical_prm_shielded` is the classical follower behind the same shield: what a
/// robot with a path follower and a collision monitor would do, the fair baseline among people.
/// `classical_rpp_shielded` and `classical_mppi_shielded` are Nav2's Regulated Pure Pursuit
/// and MPPI on the smoothed roadmap path behind the same shield (`rehearsal::nav2`), the
/// strongest classical baselines; `hybrid_policy_roadmap_rpp` is `hybrid_policy_roadmap` with
/// Regulated Pure Pursuit as the follower the policy hands over to.
/// With people the ablations (`hybrid_prm_rl_no_handover`, `hybrid_unshielded*`) do not run.
pub const METHODS: [&str; 14] = [
    "hybrid_policy_roadmap",
    "hybrid_policy_roadmap_rpp",
    "hybrid_policy_roadmap_resampled",
    "hybrid_prm_rl",
    "hybrid_prm_rl_resampled",
    "hybrid_prm_rl_no_handover",
    "plan_endpoint",
    "hybrid_unshielded",
    "hybrid_unshielded_resampled",
    "pure_rl",
    "classical_prm",
    "classical_prm_shielded",
    "classical_rpp_shielded",
    "classical_mppi_shielded",
];

/// One run of one method (one CSV row).
#[derive(Debug, Clone, PartialEq)]
pub struct NavigationRow {
    /// One of [`METHODS`].
    pub method: &'static str,
    /// The map's short name.
    pub map: String,
    /// 0-based run.
    pub run: usize,
    /// Whether the final goal was reached without a collision.
    pub success: bool,
    /// Distance driven, metres (up to the failure on a failure).
    pub distance_m: f64,
    /// Simulated time, seconds.
    pub time_s: f64,
    /// How the run ended, in words.
    pub reason: String,
    /// `plan_endpoint` only: legs the classical follower validated because the policy did not.
    pub fallback_legs: usize,
    /// Whether the run ended by touching a person.
    pub person_collision: bool,
    /// Closest approach of the footprint to a person, metres (`None` without people).
    pub min_person_clearance_m: Option<f64>,
    /// Entries into a person's intimate space (0.45 m), once per approach.
    pub intimate_intrusions: u32,
    /// Entries into a person's personal space (1.2 m), once per approach.
    pub personal_intrusions: u32,
    /// Length of the path driven, metres (the drive's distance).
    pub path_length_m: f64,
    /// Time the robot stood still (linear speed under 1 cm/s), seconds.
    pub time_not_moving_s: f64,
    /// Recovery behaviours tried.
    pub recoveries: usize,
}

/// MPPI's cost per control cycle on one map, over all its runs.
#[derive(Debug, Clone, PartialEq)]
pub struct MppiCost {
    /// The map.
    pub map: String,
    /// Cycles, wall time and the optimal rollouts' cost.
    pub cycles: MppiCycles,
}

/// The mission chosen on one map.
#[derive(Debug, Clone, PartialEq)]
pub struct Mission {
    /// The map's short name.
    pub map: String,
    /// Start.
    pub start: Point2,
    /// Goal.
    pub goal: Point2,
    /// Roadmap path length on the selection roadmap, metres.
    pub prm_length_m: f64,
    /// Straight-line distance, metres.
    pub straight_m: f64,
    /// Free area of the map (uninflated), m².
    pub free_area_m2: f64,
    /// Whether the map allowed a mission of the target length.
    pub full_length: bool,
    /// Wall time of building the world from the on-demand database, ms.
    pub world_build_ms: f64,
}

/// Wall-clock latency of the plan on one map.
#[derive(Debug, Clone, PartialEq)]
pub struct Latency {
    /// The map.
    pub map: String,
    /// `policy` or `classical`.
    pub controller: &'static str,
    /// Median of one `validate` call over runs (roadmap cached), ms.
    pub p50_ms: f64,
    /// 99th percentile, ms.
    pub p99_ms: f64,
    /// Median roadmap build (a cache miss, paid once per map version and seed), ms.
    pub roadmap_build_p50_ms: f64,
    /// Calls measured.
    pub samples: usize,
}

/// What the benchmark found.
#[derive(Debug, Clone, PartialEq)]
pub struct NavigationBenchReport {
    /// Every run.
    pub rows: Vec<NavigationRow>,
    /// The mission per map.
    pub missions: Vec<Mission>,
    /// Maps skipped and why (no free space for the robot, a map that does not load).
    pub skipped: Vec<(String, String)>,
    /// Plan latency per map and controller.
    pub latency: Vec<Latency>,
    /// The policy on each map's roadmap edges (with a policy).
    pub edges: Vec<PolicyEdges>,
    /// MPPI's cost per control cycle per map.
    pub mppi: Vec<MppiCost>,
    /// The policy used, if any.
    pub policy: Option<PathBuf>,
    /// `navigation.csv`.
    pub csv_path: PathBuf,
    /// `navigation.md`.
    pub markdown_path: PathBuf,
    /// The Markdown summary.
    pub markdown: String,
}

impl NavigationBenchReport {
    /// Lines for a terminal: success rates per method over all maps and the plan latency.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        if self.policy.is_none() {
            s.push_str("no policy given: only the classical follower ran\n");
        }
        for m in METHODS {
            let st = Stats::of(self.rows.iter().filter(|r| r.method == m));
            if st.runs > 0 {
                let _ = writeln!(
                    s,
                    "{m}: success {:.0}% ({}/{}), mean distance on success {}, time {}",
                    100.0 * st.rate(),
                    st.successes,
                    st.runs,
                    fmt_opt(st.success_distance, "m"),
                    fmt_opt(st.success_time, "s"),
                );
            }
        }
        if let Some(line) = fallback_line(&self.rows) {
            s.push_str(&line);
            s.push('\n');
        }
        for m in &self.mppi {
            let _ = writeln!(
                s,
                "MPPI on {}: {:.2} ms per control cycle (max {:.2} ms) over {} cycles of {} rollouts x {} steps",
                m.map,
                m.cycles.mean_ms(),
                1e3 * m.cycles.max_s,
                m.cycles.cycles,
                m.cycles.batch_size,
                m.cycles.time_steps
            );
        }
        for e in &self.edges {
            let _ = writeln!(
                s,
                "policy on the roadmap edges of {}: {:.2}% of rollouts succeed, {} of {} edge directions kept, built in {:.1} s",
                e.map,
                100.0 * e.edge_success_rate,
                e.kept,
                e.directions,
                e.build_s
            );
        }
        for l in &self.latency {
            let _ = writeln!(
                s,
                "plan latency {} ({}): p50 {:.1} ms, p99 {:.1} ms over {} calls (roadmap build p50 {:.1} ms)",
                l.map, l.controller, l.p50_ms, l.p99_ms, l.samples, l.roadmap_build_p50_ms
            );
        }
        let _ = writeln!(
            s,
            "{} and {}",
            self.csv_path.display(),
            self.markdown_path.display()
        );
        s
    }
}

/// Runs the benchmark.
pub fn run_navigation_bench(
    opts: NavigationBenchOptions,
) -> Result<NavigationBenchReport, BenchError> {
    if opts.runs == 0 || opts.candidates < 2 || opts.max_attempts == 0 {
        return Err(BenchError::BadOption(
            "runs and max_attempts must be at least 1, candidates at least 2".into(),
        ));
    }
    if !(opts.mission_length_m > 0.0 && opts.pure_rl_seconds_per_10m > 0.0) {
        return Err(BenchError::BadOption(
            "mission length and pure RL timer must be positive".into(),
        ));
    }
    let policy = match &opts.policy {
        Some(dir) => Some(Arc::new(Policy::load(dir).map_err(|e| {
            BenchError::Format {
                path: dir.clone(),
                message: e.to_string(),
            }
        })?)),
        None => None,
    };
    let yamls = find_yamls(&opts.maps_dir)?;
    if yamls.is_empty() {
        return Err(BenchError::NoMaps(opts.maps_dir.clone()));
    }
    let names = map_names(&opts.maps_dir, &yamls);
    let robot_ttl = std::fs::read(&opts.robot_ttl).map_err(io_err(&opts.robot_ttl))?;
    std::fs::create_dir_all(&opts.out_dir).map_err(io_err(&opts.out_dir))?;

    let mut rows = Vec::new();
    let mut missions = Vec::new();
    let mut skipped = Vec::new();
    let mut latency = Vec::new();
    let mut edges = Vec::new();
    let mut mppi = Vec::new();
    for (yaml, name) in yamls.iter().zip(&names) {
        if opts.verbose {
            eprintln!("navigation: {name}");
        }
        let t = Instant::now();
        let world = match crate::sim::world_from_map(
            yaml,
            &robot_ttl,
            &opts.robot_iri,
            opts.objects,
            opts.seed,
        ) {
            Ok(w) => w,
            Err(e) => {
                skipped.push((name.clone(), e.to_string()));
                continue;
            }
        };
        let world_build_ms = ms(t);
        // One cache per map: the benchmark measures each map from a cold start.
        let cache = RoadmapCache::default();
        let mission = match choose_mission(&world, &cache, name, &opts) {
            Ok(Some(mut m)) => {
                m.world_build_ms = world_build_ms;
                m
            }
            Ok(None) => {
                skipped.push((name.clone(), "no two far-apart free points".into()));
                continue;
            }
            Err(e) => {
                skipped.push((name.clone(), e.to_string()));
                continue;
            }
        };
        if opts.verbose {
            eprintln!(
                "  mission ({:.1}, {:.1}) -> ({:.1}, {:.1}): roadmap path {:.1} m",
                mission.start.x,
                mission.start.y,
                mission.goal.x,
                mission.goal.y,
                mission.prm_length_m
            );
        }
        let out = run_map(&world, &cache, name, &mission, policy.as_ref(), &opts)?;
        rows.extend(out.rows);
        latency.extend(out.latency);
        edges.extend(out.edges);
        mppi.push(MppiCost {
            map: name.clone(),
            cycles: out.mppi,
        });
        missions.push(mission);
    }

    let csv_path = opts.out_dir.join("navigation.csv");
    std::fs::write(&csv_path, to_csv(&rows)).map_err(io_err(&csv_path))?;
    let markdown = to_markdown(&opts, &missions, &rows, &latency, &skipped, &edges, &mppi);
    let markdown_path = opts.out_dir.join("navigation.md");
    std::fs::write(&markdown_path, &markdown).map_err(io_err(&markdown_path))?;
    Ok(NavigationBenchReport {
        rows,
        missions,
        skipped,
        latency,
        edges,
        mppi,
        policy: opts.policy.clone(),
        csv_path,
        markdown_path,
        markdown,
    })
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// The long mission of a map: among all pairs of `candidates` points sampled in the largest free
/// region, the one whose roadmap path is closest to the target length when some reach it, else
/// the longest.
fn choose_mission(
    world: &World,
    cache: &RoadmapCache,
    name: &str,
    opts: &NavigationBenchOptions,
) -> Result<Option<Mission>, PlanError> {
    let space = rehearsal::config_space(world, cache, name, opts.safety_margin_m)?;
    let cs = &space.cspace;
    let Some(region) = cs.largest_region() else {
        return Ok(None);
    };
    let params = PrmParams {
        samples: planning::optimal_samples(space.free_area_m2),
        seed: opts.seed,
        ..PrmParams::default()
    };
    let (roadmap, _) = cache.roadmap(name, &space, &params)?;
    let mut rng = ChaCha8Rng::seed_from_u64(mix(opts.seed, 0x6d15_5104));
    let points: Vec<Point2> = (0..opts.candidates)
        .filter_map(|_| cs.sample_free(&mut rng, Some(region)))
        .collect();
    let mut best: Option<(f64, Point2, Point2)> = None;
    let target = opts.mission_length_m;
    let score = |len: f64| {
        if len >= target {
            // Reaching the target beats any shorter route; among those, closest wins.
            1e9 - (len - target)
        } else {
            len
        }
    };
    for (i, &a) in points.iter().enumerate() {
        for &b in &points[i + 1..] {
            if let Ok(plan) = roadmap.query(a, b, QueryOptions::default())
                && best.is_none_or(|(l, _, _)| score(plan.length_m) > score(l))
            {
                best = Some((plan.length_m, a, b));
            }
        }
    }
    Ok(best.map(|(len, a, b)| Mission {
        map: name.to_owned(),
        start: a,
        goal: b,
        prm_length_m: len,
        straight_m: a.distance(b),
        free_area_m2: space.free_area_m2,
        full_length: len >= target,
        world_build_ms: 0.0,
    }))
}

struct MapOutcome {
    rows: Vec<NavigationRow>,
    latency: Vec<Latency>,
    edges: Option<PolicyEdges>,
    mppi: MppiCycles,
}

/// The policy on one map's roadmap edges, and what building the policy-aware roadmap cost.
#[derive(Debug, Clone, PartialEq)]
pub struct PolicyEdges {
    /// The map.
    pub map: String,
    /// Edge directions driven.
    pub directions: usize,
    /// Directions kept (success rate at least the threshold).
    pub kept: usize,
    /// Successful rollouts over all rollouts.
    pub edge_success_rate: f64,
    /// Rollouts per direction.
    pub rollouts: u32,
    /// Simulated control steps.
    pub steps: u64,
    /// Wall time of the rollouts and the reweighting, seconds.
    pub build_s: f64,
    /// What `options.controller: auto` picks on this map from the controller trial, and why.
    pub auto: planner::ControllerPick,
    /// Wall time of the controller trial, seconds.
    pub trial_s: f64,
}

fn run_map(
    world: &Arc<World>,
    cache: &RoadmapCache,
    name: &str,
    mission: &Mission,
    policy: Option<&Arc<Policy>>,
    opts: &NavigationBenchOptions,
) -> Result<MapOutcome, BenchError> {
    let yaw = (mission.goal.y - mission.start.y).atan2(mission.goal.x - mission.start.x);
    let start = Pose2::new(mission.start.x, mission.start.y, yaw);
    let space = rehearsal::config_space(world, cache, name, opts.safety_margin_m)
        .map_err(|e| plan_err(name, &e))?;
    let people = sim::PeopleConfig {
        density: opts.people,
        ..sim::PeopleConfig::default()
    };
    let mut rows = Vec::new();
    let mut validate_ms: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    let mut mppi_cycles = MppiCycles::default();
    let mut build_ms = Vec::new();
    // One policy-aware roadmap per map (on the first run's geometric roadmap): its rollouts are
    // the expensive part, built once per (floor, policy) as the service would.
    let policy_map = match policy {
        Some(p) => {
            let t = Instant::now();
            let params = PrmParams {
                samples: planning::optimal_samples(space.free_area_m2),
                seed: opts.seed.wrapping_add(1000),
                ..PrmParams::default()
            };
            let (geometric, _) = cache
                .roadmap(name, &space, &params)
                .map_err(|e| plan_err(name, &e))?;
            let rollout = rehearsal::EdgeRolloutParams {
                waypoint_timeout_s: opts.waypoint_timeout_s,
                seed: opts.seed,
                ..rehearsal::EdgeRolloutParams::default()
            };
            let (_, report) = rehearsal::policy_roadmap(world, &geometric, p, &rollout)
                .map_err(|e| plan_err(name, &e))?;
            // What the plan endpoint's `auto` plans on: every measured direction, the unkept
            // ones only where the kept ones join no route.
            let roadmap = rehearsal::reweight_with_unkept(&geometric, &report)
                .map_err(|e| plan_err(name, &e))?;
            let build_s = t.elapsed().as_secs_f64();
            // The controller trial the `roadmap` job drives after the edges, here among the
            // bench's people: what `plan_endpoint` (`options.controller: auto`) validates with.
            let t = Instant::now();
            let missions = planner::controllers::trial_missions(
                &geometric,
                planner::controllers::DEFAULT_TRIAL_MISSIONS as usize,
                opts.seed,
            );
            let trial = planner::controllers::run_trial(
                &planner::controllers::TrialFloor {
                    world,
                    roadmaps: cache,
                    version: name,
                    policy: Some(p),
                    policy_roadmap: Some(&roadmap),
                },
                &missions,
                &people,
                opts.seed,
            )
            .map_err(|e| plan_err(name, &e))?;
            let auto = trial.pick(|_| true).unwrap_or_else(|| {
                planner::controllers::unmeasured("the map's trial drove no controller")
            });
            let edges = PolicyEdges {
                map: name.to_owned(),
                directions: report.edges.len(),
                kept: report.kept().count(),
                edge_success_rate: report.edge_success_rate(),
                rollouts: rollout.rollouts,
                steps: report.steps,
                build_s,
                auto,
                trial_s: t.elapsed().as_secs_f64(),
            };
            if opts.verbose {
                eprintln!(
                    "  policy-aware roadmap: {} of {} edge directions kept, edge success {:.1}%, {:.1} s",
                    edges.kept,
                    edges.directions,
                    100.0 * edges.edge_success_rate,
                    edges.build_s
                );
                eprintln!("  {} ({:.1} s)", edges.auto.why, edges.trial_s);
            }
            Some((roadmap, edges))
        }
        None => None,
    };
    for run in 0..opts.runs {
        // Seeds far apart so the re-samples of one run never reuse another run's roadmap.
        let seed = opts.seed.wrapping_add(1000 * (run as u64 + 1));
        // The roadmap `POST /v1/plan` gives this robot (its salt), for every method alike.
        let salt = planner::roadmap_salt(&opts.robot_iri);
        let request = PlanRequest {
            start,
            goals: vec![mission.goal],
            options: PlanOptions {
                max_attempts: opts.max_attempts,
                waypoint_timeout_s: opts.waypoint_timeout_s,
                safety_margin_m: opts.safety_margin_m,
                seed,
                roadmap_salt: salt,
                trajectory_stride: 0,
                people: people.clone(),
                ..PlanOptions::default()
            },
            stop: rehearsal::Stop::default(),
        };
        // The roadmap of the first attempt, built outside the timed call (the service builds it
        // once per map version and seed).
        let t = Instant::now();
        let params = PrmParams {
            samples: planning::optimal_samples(space.free_area_m2),
            seed: seed ^ salt,
            ..PrmParams::default()
        };
        cache
            .roadmap(name, &space, &params)
            .map_err(|e| plan_err(name, &e))?;
        build_ms.push(ms(t));

        let mut classical = ClassicalFollower::default();
        let (first, last, elapsed) = timed_validate(world, cache, name, &request, &mut classical)?;
        let first_report = &first.0;
        validate_ms[1].push(elapsed);
        rows.push(row("classical_prm", name, run, &first));
        if opts.verbose {
            eprintln!(
                "  run {run}: classical {} {:.1} m {:.1} s ({:.0} ms)",
                first_report.outcome.as_str(),
                first_report.distance_m,
                first_report.simulated_time_s,
                elapsed
            );
        }
        drop(last);
        let mut shielded = rehearsal::ShieldedFollower::default();
        let (first, _, _) = timed_validate(world, cache, name, &request, &mut shielded)?;
        rows.push(row("classical_prm_shielded", name, run, &first));
        let mut rpp = RppController::new();
        let (first, _, _) = timed_validate(world, cache, name, &request, &mut rpp)?;
        rows.push(row("classical_rpp_shielded", name, run, &first));
        let mut mppi = MppiController::new(seed);
        let (first, _, _) = timed_validate(world, cache, name, &request, &mut mppi)?;
        mppi_cycles = mppi_cycles.plus(mppi.cycles());
        rows.push(row("classical_mppi_shielded", name, run, &first));
        if opts.verbose {
            eprintln!(
                "  run {run}: rpp {} / mppi {} ({:.2} ms per cycle)",
                rows[rows.len() - 2].success,
                rows[rows.len() - 1].success,
                mppi.cycles().mean_ms()
            );
        }

        let Some(policy) = policy else {
            continue;
        };
        let mut controller = PolicyController::new(Arc::clone(policy));
        let (first, last, elapsed) = timed_validate(world, cache, name, &request, &mut controller)?;
        validate_ms[0].push(elapsed);
        rows.push(row("hybrid_prm_rl", name, run, &first));
        rows.push(row("hybrid_prm_rl_resampled", name, run, &last));
        if let Some((roadmap, edges)) = &policy_map {
            rows.push(endpoint_row(
                world,
                cache,
                name,
                run,
                &request,
                policy,
                (edges.auto.choice, roadmap),
            )?);
        }
        if let Some((roadmap, _)) = &policy_map {
            let mut controller = PolicyController::new(Arc::clone(policy));
            let mut with_rpp = PolicyController::with_rpp_handover(Arc::clone(policy));
            for (c, methods) in [
                (
                    &mut controller,
                    &["hybrid_policy_roadmap", "hybrid_policy_roadmap_resampled"][..],
                ),
                (&mut with_rpp, &["hybrid_policy_roadmap_rpp"][..]),
            ] {
                let d = rehearsal::validate_detailed(
                    world,
                    cache,
                    name,
                    &request,
                    c,
                    None,
                    Some(roadmap),
                );
                let (first, last) = match d.result {
                    Ok(report) => first_last(name, report.attempts, d.attempts)?,
                    Err(PlanError::NotValidated { attempts }) => {
                        first_last(name, attempts, d.attempts)?
                    }
                    // No kept edges join start and goal: a failure of the method, not of the
                    // bench.
                    Err(e @ (PlanError::Unreachable { .. } | PlanError::Map(_))) => {
                        for &method in methods {
                            rows.push(NavigationRow {
                                method,
                                map: name.to_owned(),
                                run,
                                success: false,
                                distance_m: 0.0,
                                time_s: 0.0,
                                reason: e.to_string(),
                                fallback_legs: 0,
                                person_collision: false,
                                min_person_clearance_m: None,
                                intimate_intrusions: 0,
                                personal_intrusions: 0,
                                path_length_m: 0.0,
                                time_not_moving_s: 0.0,
                                recoveries: 0,
                            });
                        }
                        continue;
                    }
                    Err(e) => return Err(plan_err(name, &e)),
                };
                rows.push(row(methods[0], name, run, &first));
                if let Some(&m) = methods.get(1) {
                    rows.push(row(m, name, run, &last));
                }
            }
        }
        let mut shield_only = PolicyController::without_handover(Arc::clone(policy));
        if !people.any() {
            let (first_s, _, _) = timed_validate(world, cache, name, &request, &mut shield_only)?;
            rows.push(row("hybrid_prm_rl_no_handover", name, run, &first_s));
            let mut unshielded = PolicyController::without_shield(Arc::clone(policy));
            let (first_u, last_u, _) =
                timed_validate(world, cache, name, &request, &mut unshielded)?;
            rows.push(row("hybrid_unshielded", name, run, &first_u));
            rows.push(row("hybrid_unshielded_resampled", name, run, &last_u));
        }

        // Pure RL: the policy straight at the final goal.
        let timeout = (opts.pure_rl_seconds_per_10m * mission.prm_length_m / 10.0)
            .max(opts.pure_rl_seconds_per_10m);
        let env = sim::EnvConfig {
            people: people.clone(),
            ..rehearsal::env_config(policy.scaling().beams, true)
        };
        let pure = rehearsal::drive(
            world,
            &env,
            start,
            &[vec![mission.goal]],
            &mut shield_only,
            DriveLimits {
                waypoint_timeout_s: timeout,
                max_replans: 0,
                sim_seed: mix(seed, 0x0707),
                initial_velocity: Action::default(),
                stop: rehearsal::Stop::default(),
                trace: false,
                recoveries: rehearsal::recoveries_for(&request.options),
                others: None,
                holds: Vec::new(),
            },
            None,
        )
        .map_err(|e| plan_err(name, &e))?;
        rows.push(NavigationRow {
            method: "pure_rl",
            map: name.to_owned(),
            run,
            success: pure.outcome == AttemptOutcome::Reached,
            distance_m: pure.distance_m,
            time_s: pure.time_s,
            person_collision: rehearsal::hit_person(&pure.reason),
            reason: pure.reason,
            fallback_legs: 0,
            min_person_clearance_m: pure.min_person_clearance_m,
            intimate_intrusions: pure.social.intimate_intrusions,
            personal_intrusions: pure.social.personal_intrusions,
            path_length_m: pure.distance_m,
            time_not_moving_s: pure.social.time_not_moving_s,
            recoveries: pure.recoveries.len(),
        });
        if opts.verbose {
            eprintln!(
                "  run {run}: hybrid first {} / resampled {} ({:.0} ms), pure RL {}",
                first.0.outcome.as_str(),
                last.0.outcome.as_str(),
                elapsed,
                if rows.last().is_some_and(|r| r.success) {
                    "reached"
                } else {
                    "failed"
                }
            );
        }
    }
    let mut latency = Vec::new();
    for (i, controller) in ["policy", "classical"].into_iter().enumerate() {
        let v = &mut validate_ms[i];
        if v.is_empty() {
            continue;
        }
        latency.push(Latency {
            map: name.to_owned(),
            controller,
            p50_ms: percentile(v, 0.5),
            p99_ms: percentile(v, 0.99),
            roadmap_build_p50_ms: percentile(&mut build_ms.clone(), 0.5),
            samples: v.len(),
        });
    }
    Ok(MapOutcome {
        rows,
        latency,
        edges: policy_map.map(|(_, e)| e),
        mppi: mppi_cycles,
    })
}

fn plan_err(name: &str, e: &PlanError) -> BenchError {
    BenchError::BadOption(format!("{name}: {e}"))
}

/// An attempt's report and what it measured beyond it.
type Attempt = (AttemptReport, Option<AttemptDetails>);

/// One validate call: its first attempt, its last attempt (the validating one on success), and
/// its wall time in ms. A plan that no attempt validated is a result here, not an error.
fn timed_validate(
    world: &Arc<World>,
    cache: &RoadmapCache,
    name: &str,
    request: &PlanRequest,
    controller: &mut dyn Controller,
) -> Result<(Attempt, Attempt, f64), BenchError> {
    let t = Instant::now();
    let d = rehearsal::validate_detailed(world, cache, name, request, controller, None, None);
    let elapsed = ms(t);
    let attempts = match d.result {
        Ok(report) => report.attempts,
        Err(PlanError::NotValidated { attempts }) => attempts,
        Err(e) => return Err(plan_err(name, &e)),
    };
    let (first, last) = first_last(name, attempts, d.attempts)?;
    Ok((first, last, elapsed))
}

/// The first and the last attempt of a validation, with their details.
fn first_last(
    name: &str,
    attempts: Vec<AttemptReport>,
    details: Vec<AttemptDetails>,
) -> Result<(Attempt, Attempt), BenchError> {
    match (attempts.first(), attempts.last()) {
        (Some(f), Some(l)) => Ok((
            (f.clone(), details.first().cloned()),
            (l.clone(), details.get(attempts.len() - 1).cloned()),
        )),
        _ => Err(BenchError::BadOption(format!("{name}: no attempt ran"))),
    }
}

/// What the plan endpoint answers for `request`: the policy, and the follower for legs the
/// policy validated in no attempt.
fn endpoint_row(
    world: &Arc<World>,
    cache: &RoadmapCache,
    name: &str,
    run: usize,
    request: &PlanRequest,
    policy: &Arc<Policy>,
    (auto, policy_roadmap): (rehearsal::ControllerChoice, &Arc<planning::Roadmap>),
) -> Result<NavigationRow, BenchError> {
    // As the planner validates with `auto`'s pick: the policy-aware roadmap for a hybrid, the
    // classical follower (shielded among people) for a leg the pick validates in no attempt.
    let mut controller = auto
        .build(Some(policy), request.options.seed)
        .ok_or_else(|| {
            BenchError::BadOption(format!("{name}: {} needs a policy", auto.as_str()))
        })?;
    let mut follower = rehearsal::follower_for(&request.options);
    let d = rehearsal::validate_detailed(
        world,
        cache,
        name,
        request,
        &mut *controller,
        Some(&mut *follower),
        auto.needs_policy().then_some(policy_roadmap),
    );
    Ok(match d.result {
        Ok(report) => {
            let fallback_legs = report
                .legs
                .iter()
                .filter(|l| l.controller != report.controller)
                .count();
            // The validating attempts' social metrics, summed over the legs.
            let validating: Vec<&AttemptDetails> = report
                .attempts
                .iter()
                .zip(&d.attempts)
                .filter(|(a, _)| a.outcome == AttemptOutcome::Reached)
                .map(|(_, x)| x)
                .collect();
            let social = validating
                .iter()
                .fold(rehearsal::SocialMetrics::default(), |s, x| s.plus(x.social));
            NavigationRow {
                method: "plan_endpoint",
                map: name.to_owned(),
                run,
                success: true,
                distance_m: report.distance_m,
                time_s: report.simulated_time_s,
                reason: format!(
                    "validated with {}; {fallback_legs} of {} legs by the classical follower",
                    auto.as_str(),
                    report.legs.len()
                ),
                fallback_legs,
                person_collision: false,
                min_person_clearance_m: report
                    .attempts
                    .iter()
                    .filter(|a| a.outcome == AttemptOutcome::Reached)
                    .filter_map(|a| a.min_person_clearance_m)
                    .reduce(f64::min),
                intimate_intrusions: social.intimate_intrusions,
                personal_intrusions: social.personal_intrusions,
                path_length_m: report.distance_m,
                time_not_moving_s: social.time_not_moving_s,
                recoveries: validating.iter().map(|x| x.recoveries.len()).sum(),
            }
        }
        Err(PlanError::NotValidated { attempts }) => {
            let last = attempts
                .last()
                .ok_or_else(|| BenchError::BadOption(format!("{name}: no attempt ran")))?;
            let details = d.attempts.get(attempts.len() - 1).cloned();
            NavigationRow {
                fallback_legs: 0,
                ..row("plan_endpoint", name, run, &(last.clone(), details))
            }
        }
        Err(e) => return Err(plan_err(name, &e)),
    })
}

fn row(method: &'static str, map: &str, run: usize, (a, d): &Attempt) -> NavigationRow {
    let social = d.as_ref().map(|d| d.social).unwrap_or_default();
    NavigationRow {
        person_collision: rehearsal::hit_person(&a.reason),
        min_person_clearance_m: a.min_person_clearance_m,
        method,
        map: map.to_owned(),
        run,
        success: a.outcome == AttemptOutcome::Reached,
        distance_m: a.distance_m,
        time_s: a.simulated_time_s,
        reason: a.reason.clone(),
        fallback_legs: 0,
        intimate_intrusions: social.intimate_intrusions,
        personal_intrusions: social.personal_intrusions,
        path_length_m: a.distance_m,
        time_not_moving_s: social.time_not_moving_s,
        recoveries: d.as_ref().map_or(0, |d| d.recoveries.len()),
    }
}

/// The `q` quantile (nearest rank) of `v`, sorted in place; 0 for an empty slice.
pub fn percentile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a rank within the slice"
    )]
    let rank = ((q * v.len() as f64).ceil() as usize).clamp(1, v.len());
    v[rank - 1]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_and_stats() {
        let mut v = vec![5.0, 1.0, 3.0, 2.0, 4.0];
        assert_eq!(percentile(&mut v, 0.5), 3.0);
        assert_eq!(percentile(&mut v, 0.99), 5.0);
        assert_eq!(percentile(&mut [], 0.5), 0.0);
        let r = |success, d| NavigationRow {
            method: "pure_rl",
            map: "m".into(),
            run: 0,
            success,
            distance_m: d,
            time_s: 2.0 * d,
            reason: String::new(),
            fallback_legs: 0,
            person_collision: !success,
            min_person_clearance_m: Some(0.05),
            intimate_intrusions: 1,
            personal_intrusions: 3,
            path_length_m: d,
            time_not_moving_s: 1.5,
            recoveries: 2,
        };
        let rows = [r(true, 10.0), r(true, 20.0), r(false, 4.0)];
        let st = Stats::of(rows.iter());
        assert_eq!(st.successes, 2);
        assert_eq!(st.success_distance, Some(15.0));
        assert_eq!(st.success_time, Some(30.0));
        assert_eq!((st.person_collisions, st.person_near_misses), (1, 2));
        assert_eq!(st.failure_distance, Some(4.0));
        assert!(to_csv(&rows).starts_with(
            "method,map,run,success,distance_m,time_s,person_collision,min_person_clearance_m,\
             intimate_intrusions,personal_intrusions,path_length_m,time_not_moving_s,recoveries\n\
             pure_rl,m,0,true,10.000,20.000,false,0.050,1,3,10.000,1.5,2\n"
        ));
        // Per 100 m driven: 34 m over three runs, 3 intimate and 9 personal intrusions.
        assert_eq!((st.intimate, st.personal, st.recoveries), (3, 9, 6));
        let per = st.per_100m(st.personal as f64).expect("driven");
        assert!((per - 900.0 / 34.0).abs() < 1e-9, "{per}");
    }
}
