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
mod run;
pub use report::{Stats, to_csv};
use report::{fallback_line, fmt_opt, to_markdown};
use run::run_map;
use std::sync::Arc;
use std::time::Instant;

use grid::seed::mix;
use learning::Policy;
use prm::{Point2, PrmParams, QueryOptions};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rehearsal::{MppiCycles, PlanError, RoadmapCache};
use sim::World;

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
    /// The methods to run (names from [`METHODS`]); empty for all of them.
    pub methods: Vec<String>,
    /// Every method's roadmap path with its detours removed (`PlanOptions::shortcut`).
    pub shortcut: bool,
    /// Build the policy-aware roadmap again in every run, on that run's geometric roadmap (the
    /// one the classical methods drive), instead of once per map: the hybrids' routes then
    /// differ from the classical ones' only where the policy's edge measurements send them
    /// elsewhere, not by another draw of samples. The controller trial stays once per map.
    pub policy_roadmap_per_run: bool,
}

impl NavigationBenchOptions {
    /// Whether `method` runs.
    pub fn wants(&self, method: &str) -> bool {
        self.methods.is_empty() || self.methods.iter().any(|m| m == method)
    }
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
            methods: Vec::new(),
            shortcut: false,
            policy_roadmap_per_run: false,
        }
    }
}

/// The methods, in table order. `hybrid_prm_rl` is what `POST /v1/plan` runs: the policy
/// behind the collision shield (`rehearsal::Shield`), the classical follower taking over near
/// obstacles (`rehearsal::HANDOVER_MARGIN_M`) until the policy keeps the margin again
/// (`rehearsal::HAND_BACK_STEPS`) or the next waypoint;
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
/// Regulated Pure Pursuit as the follower the policy hands over to, and `hybrid_policy_path` the
/// same with the policy steering to a carrot on the smoothed path instead of to each vertex
/// (`rehearsal::PolicyController::on_smoothed_path`); `hybrid_prm_rl_path` is that on the map's
/// geometric roadmap, the one the classical methods drive, first attempt.
/// With people the ablations (`hybrid_prm_rl_no_handover`, `hybrid_unshielded*`) do not run.
pub const METHODS: [&str; 16] = [
    "hybrid_policy_roadmap",
    "hybrid_policy_roadmap_rpp",
    "hybrid_policy_path",
    "hybrid_policy_roadmap_resampled",
    "hybrid_prm_rl",
    "hybrid_prm_rl_resampled",
    "hybrid_prm_rl_path",
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
    /// The time the same driven line takes at the robot's top speeds, seconds
    /// ([`rehearsal::SocialMetrics::limit_time_s`]).
    pub limit_time_s: f64,
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
    if let Some(m) = opts.methods.iter().find(|m| !METHODS.contains(&m.as_str())) {
        return Err(BenchError::BadOption(format!(
            "unknown method {m:?}; the methods are {}",
            METHODS.join(", ")
        )));
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
        samples: prm::optimal_samples(space.free_area_m2),
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
            limit_time_s: 0.75 * d,
            recoveries: 2,
        };
        let rows = [r(true, 10.0), r(true, 20.0), r(false, 4.0)];
        let st = Stats::of(rows.iter());
        assert_eq!(st.successes, 2);
        assert_eq!(st.success_distance, Some(15.0));
        assert_eq!(st.success_time, Some(30.0));
        assert_eq!(st.success_limit_time, Some(11.25));
        assert_eq!((st.person_collisions, st.person_near_misses), (1, 2));
        assert_eq!(st.failure_distance, Some(4.0));
        assert!(to_csv(&rows).starts_with(
            "method,map,run,success,distance_m,time_s,person_collision,min_person_clearance_m,\
             intimate_intrusions,personal_intrusions,path_length_m,time_not_moving_s,recoveries,\
             limit_time_s\n\
             pure_rl,m,0,true,10.000,20.000,false,0.050,1,3,10.000,1.5,2,7.500\n"
        ));
        // Per 100 m driven: 34 m over three runs, 3 intimate and 9 personal intrusions.
        assert_eq!((st.intimate, st.personal, st.recoveries), (3, 9, 6));
        let per = st.per_100m(st.personal as f64).expect("driven");
        assert!((per - 900.0 / 34.0).abs() < 1e-9, "{per}");
    }
}
