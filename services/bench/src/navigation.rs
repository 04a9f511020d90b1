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
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use grid::seed::mix;
use learning::Policy;
use planning::{Point2, PrmParams, QueryOptions};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rehearsal::{
    AttemptOutcome, AttemptReport, ClassicalFollower, Controller, DriveLimits, PlanError,
    PlanOptions, PlanRequest, PolicyController, RoadmapCache,
};
use sim::{Action, Pose2, World};

use crate::error::BenchError;
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
/// answers: `hybrid_prm_rl_resampled`, then the classical follower (also re-sampled) for a leg
/// the policy validated in no attempt. `hybrid_policy_roadmap*` are the shielded policy on the
/// policy-aware roadmap as `options.roadmap: auto` plans on it (PRM-RL: the map's geometric
/// roadmap with every edge direction driven 10 times by the policy, weighted by length and
/// risk; directions under 90% success only where the kept ones join no route, at 100 m more),
/// first attempt and with re-tries (same roadmap, new noise). `pure_rl` is the policy behind
/// the shield driving straight at the goal (no handover: the follower's segment would cross
/// walls). `classical_prm_shielded` is the classical follower behind the same shield: what a
/// robot with a path follower and a collision monitor would do, the fair baseline among people.
/// With people the ablations (`hybrid_prm_rl_no_handover`, `hybrid_unshielded*`) do not run.
pub const METHODS: [&str; 11] = [
    "hybrid_policy_roadmap",
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

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> BenchError + '_ {
    move |source| BenchError::Io {
        path: path.to_path_buf(),
        source,
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
        missions.push(mission);
    }

    let csv_path = opts.out_dir.join("navigation.csv");
    std::fs::write(&csv_path, to_csv(&rows)).map_err(io_err(&csv_path))?;
    let markdown = to_markdown(&opts, &missions, &rows, &latency, &skipped, &edges);
    let markdown_path = opts.out_dir.join("navigation.md");
    std::fs::write(&markdown_path, &markdown).map_err(io_err(&markdown_path))?;
    Ok(NavigationBenchReport {
        rows,
        missions,
        skipped,
        latency,
        edges,
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
            let edges = PolicyEdges {
                map: name.to_owned(),
                directions: report.edges.len(),
                kept: report.kept().count(),
                edge_success_rate: report.edge_success_rate(),
                rollouts: rollout.rollouts,
                steps: report.steps,
                build_s: t.elapsed().as_secs_f64(),
            };
            if opts.verbose {
                eprintln!(
                    "  policy-aware roadmap: {} of {} edge directions kept, edge success {:.1}%, {:.1} s",
                    edges.kept,
                    edges.directions,
                    100.0 * edges.edge_success_rate,
                    edges.build_s
                );
            }
            Some((roadmap, edges))
        }
        None => None,
    };
    for run in 0..opts.runs {
        // Seeds far apart so the re-samples of one run never reuse another run's roadmap.
        let seed = opts.seed.wrapping_add(1000 * (run as u64 + 1));
        let request = PlanRequest {
            start,
            goals: vec![mission.goal],
            options: PlanOptions {
                max_attempts: opts.max_attempts,
                waypoint_timeout_s: opts.waypoint_timeout_s,
                safety_margin_m: opts.safety_margin_m,
                seed,
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
            seed,
            ..PrmParams::default()
        };
        cache
            .roadmap(name, &space, &params)
            .map_err(|e| plan_err(name, &e))?;
        build_ms.push(ms(t));

        let mut classical = ClassicalFollower::default();
        let (first, last, elapsed) = timed_validate(world, cache, name, &request, &mut classical)?;
        validate_ms[1].push(elapsed);
        rows.push(row("classical_prm", name, run, &first));
        if opts.verbose {
            eprintln!(
                "  run {run}: classical {} {:.1} m {:.1} s ({:.0} ms)",
                first.outcome.as_str(),
                first.distance_m,
                first.simulated_time_s,
                elapsed
            );
        }
        drop(last);
        let mut shielded = rehearsal::ShieldedFollower::default();
        let (first, _, _) = timed_validate(world, cache, name, &request, &mut shielded)?;
        rows.push(row("classical_prm_shielded", name, run, &first));

        let Some(policy) = policy else {
            continue;
        };
        let mut controller = PolicyController::new(Arc::clone(policy));
        let (first, last, elapsed) = timed_validate(world, cache, name, &request, &mut controller)?;
        validate_ms[0].push(elapsed);
        rows.push(row("hybrid_prm_rl", name, run, &first));
        rows.push(row("hybrid_prm_rl_resampled", name, run, &last));
        rows.push(endpoint_row(world, cache, name, run, &request, policy)?);
        if let Some((roadmap, _)) = &policy_map {
            let mut controller = PolicyController::new(Arc::clone(policy));
            let (first, last) = match rehearsal::validate_with_fallback(
                world,
                cache,
                name,
                &request,
                &mut controller,
                None,
                Some(roadmap),
            ) {
                Ok(report) => first_last(name, report.attempts)?,
                Err(PlanError::NotValidated { attempts }) => first_last(name, attempts)?,
                // No kept edges join start and goal: a failure of the method, not of the bench.
                Err(e @ (PlanError::Unreachable { .. } | PlanError::Map(_))) => {
                    let failed = NavigationRow {
                        method: "hybrid_policy_roadmap",
                        map: name.to_owned(),
                        run,
                        success: false,
                        distance_m: 0.0,
                        time_s: 0.0,
                        reason: e.to_string(),
                        fallback_legs: 0,
                        person_collision: false,
                        min_person_clearance_m: None,
                    };
                    rows.push(failed.clone());
                    rows.push(NavigationRow {
                        method: "hybrid_policy_roadmap_resampled",
                        ..failed
                    });
                    continue;
                }
                Err(e) => return Err(plan_err(name, &e)),
            };
            rows.push(row("hybrid_policy_roadmap", name, run, &first));
            rows.push(row("hybrid_policy_roadmap_resampled", name, run, &last));
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
        });
        if opts.verbose {
            eprintln!(
                "  run {run}: hybrid first {} / resampled {} ({:.0} ms), pure RL {}",
                first.outcome.as_str(),
                last.outcome.as_str(),
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
    })
}

fn plan_err(name: &str, e: &PlanError) -> BenchError {
    BenchError::BadOption(format!("{name}: {e}"))
}

/// One validate call: its first attempt, its last attempt (the validating one on success), and
/// its wall time in ms. A plan that no attempt validated is a result here, not an error.
fn timed_validate(
    world: &Arc<World>,
    cache: &RoadmapCache,
    name: &str,
    request: &PlanRequest,
    controller: &mut dyn Controller,
) -> Result<(AttemptReport, AttemptReport, f64), BenchError> {
    let t = Instant::now();
    let result = rehearsal::validate_with(world, cache, name, request, controller);
    let elapsed = ms(t);
    let attempts = match result {
        Ok(report) => report.attempts,
        Err(PlanError::NotValidated { attempts }) => attempts,
        Err(e) => return Err(plan_err(name, &e)),
    };
    let (first, last) = first_last(name, attempts)?;
    Ok((first, last, elapsed))
}

/// The first and the last attempt of a validation.
fn first_last(
    name: &str,
    attempts: Vec<AttemptReport>,
) -> Result<(AttemptReport, AttemptReport), BenchError> {
    match (attempts.first(), attempts.last()) {
        (Some(f), Some(l)) => Ok((f.clone(), l.clone())),
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
) -> Result<NavigationRow, BenchError> {
    let mut controller = PolicyController::new(Arc::clone(policy));
    let mut follower = ClassicalFollower::default();
    let result = rehearsal::validate_with_fallback(
        world,
        cache,
        name,
        request,
        &mut controller,
        Some(&mut follower),
        None,
    );
    Ok(match result {
        Ok(report) => {
            let fallback_legs = report
                .legs
                .iter()
                .filter(|l| l.controller != report.controller)
                .count();
            NavigationRow {
                method: "plan_endpoint",
                map: name.to_owned(),
                run,
                success: true,
                distance_m: report.distance_m,
                time_s: report.simulated_time_s,
                reason: format!(
                    "validated; {fallback_legs} of {} legs by the classical follower",
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
            }
        }
        Err(PlanError::NotValidated { attempts }) => {
            let last = attempts
                .last()
                .ok_or_else(|| BenchError::BadOption(format!("{name}: no attempt ran")))?;
            NavigationRow {
                fallback_legs: 0,
                ..row("plan_endpoint", name, run, last)
            }
        }
        Err(e) => return Err(plan_err(name, &e)),
    })
}

fn row(method: &'static str, map: &str, run: usize, a: &AttemptReport) -> NavigationRow {
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

/// `navigation.csv`: method, map, run, success, distance_m, time_s, person_collision,
/// min_person_clearance_m (empty without people).
pub fn to_csv(rows: &[NavigationRow]) -> String {
    let mut s = String::from(
        "method,map,run,success,distance_m,time_s,person_collision,min_person_clearance_m\n",
    );
    for r in rows {
        let map = if r.map.contains([',', '"', '\n']) {
            format!("\"{}\"", r.map.replace('"', "\"\""))
        } else {
            r.map.clone()
        };
        let _ = writeln!(
            s,
            "{},{},{},{},{:.3},{:.3},{},{}",
            r.method,
            map,
            r.run,
            r.success,
            r.distance_m,
            r.time_s,
            r.person_collision,
            r.min_person_clearance_m
                .map_or_else(String::new, |c| format!("{c:.3}"))
        );
    }
    s
}

/// Success rate and means of a set of runs.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stats {
    /// Runs.
    pub runs: usize,
    /// Successful runs.
    pub successes: usize,
    /// Mean distance over successes, metres.
    pub success_distance: Option<f64>,
    /// Mean time over successes, seconds.
    pub success_time: Option<f64>,
    /// Mean distance over failures, metres.
    pub failure_distance: Option<f64>,
    /// Runs that ended by touching a person.
    pub person_collisions: usize,
    /// Runs that came within [`rehearsal::NEAR_MISS_M`] of a person without touching one.
    pub person_near_misses: usize,
}

impl Stats {
    /// The statistics of `rows`.
    pub fn of<'a>(rows: impl Iterator<Item = &'a NavigationRow>) -> Stats {
        let (mut n, mut ok) = (0usize, 0usize);
        let (mut sd, mut st, mut fd) = (0.0, 0.0, 0.0);
        let (mut hit, mut near) = (0usize, 0usize);
        for r in rows {
            n += 1;
            if r.person_collision {
                hit += 1;
            } else if r
                .min_person_clearance_m
                .is_some_and(|c| c < rehearsal::NEAR_MISS_M)
            {
                near += 1;
            }
            if r.success {
                ok += 1;
                sd += r.distance_m;
                st += r.time_s;
            } else {
                fd += r.distance_m;
            }
        }
        let mean = |sum: f64, k: usize| (k > 0).then(|| sum / k as f64);
        Stats {
            runs: n,
            successes: ok,
            success_distance: mean(sd, ok),
            success_time: mean(st, ok),
            failure_distance: mean(fd, n - ok),
            person_collisions: hit,
            person_near_misses: near,
        }
    }

    /// Share of successes.
    pub fn rate(&self) -> f64 {
        if self.runs == 0 {
            0.0
        } else {
            self.successes as f64 / self.runs as f64
        }
    }
}

/// How often the plan endpoint needed the classical follower, when it ran.
fn fallback_line(rows: &[NavigationRow]) -> Option<String> {
    let endpoint: Vec<&NavigationRow> = rows
        .iter()
        .filter(|r| r.method == "plan_endpoint")
        .collect();
    if endpoint.is_empty() {
        return None;
    }
    let with = endpoint.iter().filter(|r| r.fallback_legs > 0).count();
    let legs: usize = endpoint.iter().map(|r| r.fallback_legs).sum();
    Some(format!(
        "plan_endpoint: the classical follower validated {legs} leg(s) the policy could not, in {with} of {} runs ({:.0}%)",
        endpoint.len(),
        100.0 * with as f64 / endpoint.len() as f64
    ))
}

fn fmt_opt(v: Option<f64>, unit: &str) -> String {
    v.map_or_else(|| "—".to_owned(), |v| format!("{v:.2} {unit}"))
}

fn cell(v: Option<f64>) -> String {
    v.map_or_else(|| "—".to_owned(), |v| format!("{v:.2}"))
}

fn table(out: &mut String, rows: &[&NavigationRow], people: bool) {
    out.push_str("| Method | Success: avg distance (m) | Success: avg time (s) | Failure: avg distance (m) | Success rate |");
    out.push_str(if people {
        " Collisions with people | Near misses (< 10 cm of a person) |\n|---|---|---|---|---|---|---|\n"
    } else {
        "\n|---|---|---|---|---|\n"
    });
    for m in METHODS {
        let st = Stats::of(rows.iter().copied().filter(|r| r.method == m));
        if st.runs == 0 {
            continue;
        }
        let _ = write!(
            out,
            "| {m} | {} | {} | {} | {:.0}% ({}/{}) |",
            cell(st.success_distance),
            cell(st.success_time),
            cell(st.failure_distance),
            100.0 * st.rate(),
            st.successes,
            st.runs
        );
        if people {
            let _ = write!(
                out,
                " {} | {} |",
                st.person_collisions, st.person_near_misses
            );
        }
        out.push('\n');
    }
}

fn to_markdown(
    opts: &NavigationBenchOptions,
    missions: &[Mission],
    rows: &[NavigationRow],
    latency: &[Latency],
    skipped: &[(String, String)],
    edges: &[PolicyEdges],
) -> String {
    let mut s =
        String::from("# Long-range navigation (paper Table 3) in the mental simulation\n\n");
    let _ = writeln!(
        s,
        "{} runs per method and map; one mission per map of about {} m of roadmap path where the map allows (otherwise the longest route among {} sampled points of the largest free region); waypoint timer {} s; safety margin {} m; {} furniture objects; {} people per 100 m² of free region (drawn afresh per run and attempt; radius 0.2–0.3 m, 0.6–1.3 m/s, ORCA sharing the avoidance with the robot); seed {}.\n",
        opts.runs,
        opts.mission_length_m,
        opts.candidates,
        opts.waypoint_timeout_s,
        opts.safety_margin_m,
        opts.objects,
        opts.people,
        opts.seed
    );
    match &opts.policy {
        Some(p) => {
            let _ = writeln!(s, "Policy: `{}`.\n", p.display());
        }
        None => s.push_str(
            "**No policy given: only the classical follower (`classical_prm`, `classical_prm_shielded`) ran.** Pass an exported policy directory to run hybrid PRM-RL and pure RL.\n\n",
        ),
    }
    s.push_str(
        "Methods: `hybrid_prm_rl` = the policy through the roadmap's waypoints (15 s timer, replanning) behind the collision shield, the classical follower taking over to the next waypoint where the policy would come within 0.3 m of what the laser sees, first attempt only — the paper's measure; `hybrid_prm_rl_no_handover` = the same without the follower's handover (the shield alone); `hybrid_policy_roadmap` = the same controller on the policy-aware roadmap (PRM-RL, below), first attempt, and `_resampled` with re-tries; `hybrid_unshielded` = the paper's hybrid, the policy's commands unchanged; `hybrid_prm_rl_resampled` = the plan endpoint's behaviour, up to ",
    );
    let _ = write!(s, "{}", opts.max_attempts);
    s.push_str(
        " roadmap re-samples after a collision or stall, success = a validated plan, distance and time of the validating drive; `plan_endpoint` = what `POST /v1/plan` answers: the same, then the classical follower (re-sampled too) when no policy attempt validated the mission, so it is never worse than `classical_prm`; `pure_rl` = the policy behind the shield straight at the final goal; `classical_prm` = rotate-then-go follower on the roadmap's waypoints, first attempt. Distances are driven distances; failures count the distance driven before the collision or stall.\n\n",
    );
    s.push_str("The paper's Table 3 (Gazebo, one building, ~140 m): Move Base 141.04 m / 123.31 s / 100%; Constrained Move Base 140.21 m / 125.19 s, failure 26.87 m / 60%; Pure RL failure 14.7 m / 0%; Hybrid PRM-RL 149.71 m / 160.45 s, failure 102.4 m / 90%.\n\n");

    s.push_str("## All maps\n\n");
    let all: Vec<&NavigationRow> = rows.iter().collect();
    table(&mut s, &all, opts.people > 0.0);
    if let Some(line) = fallback_line(rows) {
        let _ = writeln!(s, "\n{line}.");
    }

    s.push_str("\n## Missions\n\n| Map | Start | Goal | Roadmap path (m) | Straight line (m) | Full length | Free area (m²) | World build (ms) |\n|---|---|---|---|---|---|---|---|\n");
    for m in missions {
        let _ = writeln!(
            s,
            "| {} | ({:.2}, {:.2}) | ({:.2}, {:.2}) | {:.1} | {:.1} | {} | {:.0} | {:.0} |",
            m.map,
            m.start.x,
            m.start.y,
            m.goal.x,
            m.goal.y,
            m.prm_length_m,
            m.straight_m,
            if m.full_length { "yes" } else { "no" },
            m.free_area_m2,
            m.world_build_ms
        );
    }

    if !edges.is_empty() {
        s.push_str("\n## The policy on the roadmap edges\n\nEvery edge of the map's geometric roadmap driven by the policy as plans drive it (shield and handover), both directions, 10 rollouts each (heading as if arriving over a neighbouring edge, at rest in even rollouts and at half the top speed in odd ones, noise on); kept where at least 90% succeed. Build = the rollouts and the reweighting, wall time on this machine's cores.\n\n| Map | Edge directions | Kept | Edge success rate | Simulated steps | Build (s) |\n|---|---|---|---|---|---|\n");
        for e in edges {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.2}% | {} | {:.1} |",
                e.map,
                e.directions,
                e.kept,
                100.0 * e.edge_success_rate,
                e.steps,
                e.build_s
            );
        }
    }

    s.push_str("\n## Plan latency\n\nWall time of one `rehearsal::validate` call for the map's long mission (roadmap of the first attempt cached, as the service keeps it per map version; re-samples build theirs inside the call), and of building that roadmap once.\n\n| Map | Controller | p50 (ms) | p99 (ms) | Calls | Roadmap build p50 (ms) |\n|---|---|---|---|---|---|\n");
    for l in latency {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {} | {:.1} |",
            l.map, l.controller, l.p50_ms, l.p99_ms, l.samples, l.roadmap_build_p50_ms
        );
    }

    for m in missions {
        let _ = writeln!(
            s,
            "\n## {} ({:.1} m of roadmap path)\n",
            m.map, m.prm_length_m
        );
        let mine: Vec<&NavigationRow> = rows.iter().filter(|r| r.map == m.map).collect();
        table(&mut s, &mine, opts.people > 0.0);
        let failures: Vec<&&NavigationRow> = mine.iter().filter(|r| !r.success).collect();
        if !failures.is_empty() {
            // Up to a few per method, so no method's failures hide another's.
            s.push_str("\nFailures (at most 5 per method):\n\n");
            let mut shown: Vec<(&str, usize)> = Vec::new();
            for r in failures {
                let n = match shown.iter_mut().find(|(m, _)| *m == r.method) {
                    Some((_, n)) => n,
                    None => {
                        shown.push((r.method, 0));
                        &mut shown.last_mut().expect("just pushed").1
                    }
                };
                *n += 1;
                if *n <= 5 {
                    let _ = writeln!(s, "- {} run {}: {}", r.method, r.run, r.reason);
                }
            }
        }
    }
    if !skipped.is_empty() {
        s.push_str("\n## Skipped maps\n\n");
        for (m, why) in skipped {
            let _ = writeln!(s, "- {m}: {why}");
        }
    }
    s
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
        };
        let rows = [r(true, 10.0), r(true, 20.0), r(false, 4.0)];
        let st = Stats::of(rows.iter());
        assert_eq!(st.successes, 2);
        assert_eq!(st.success_distance, Some(15.0));
        assert_eq!(st.success_time, Some(30.0));
        assert_eq!((st.person_collisions, st.person_near_misses), (1, 2));
        assert_eq!(st.failure_distance, Some(4.0));
        assert!(to_csv(&rows).starts_with(
            "method,map,run,success,distance_m,time_s,person_collision,min_person_clearance_m\n\
             pure_rl,m,0,true,10.000,20.000,false,0.050\n"
        ));
    }
}
