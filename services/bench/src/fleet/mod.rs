//! `mentalsim bench fleet`: N robots on one floor ask the planner for plans at once, each
//! fitted among the plans already committed to the floor's traffic schedule (waits, refusals)
//! and driven again among them, as `POST /v1/plan` does; then every committed plan is driven
//! once more among all the others (the joint run: every robot in one simulation, the others'
//! footprints moving along their schedules, with people), to see whether the plans hold
//! together. Reported per map and scenario: joint success, robot–robot collisions, stalls,
//! makespan and sum of times against the same robots planned alone, plan latency under the
//! concurrent requests.
//!
//! The planner is the service's (`planner::Planner`), its knowledge the on-demand database an
//! import of the map makes, its schedule an in-memory one (the service keeps it in the job
//! database: add its commit, two round trips, to the latency).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Instant, SystemTime};

use planner::fleet::{Committed, FleetFuture};
use planner::{
    FleetSchedule, FloorDatabase, KnowledgeSource, PlanOutcome, PlanQuery, Planner, SourceError,
    SourceFuture,
};
use rayon::prelude::*;
use rehearsal::AttemptOutcome;
use sim::{Pose2, World};
use tosm::OccupancyGrid;
use traffic::Itinerary;

use crate::error::BenchError;

mod floors;
mod prepared;
mod reference;

use prepared::{Prepared, prepare};

pub use floors::{CORRIDOR_WIDTH_M, CROSSING_ARM_M, DOOR_WALL_M};

/// Which missions the robots get.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Scenario {
    /// Random missions across the floor's roadmap (start and goal at least a quarter of its
    /// extent apart), on every map under `--maps`.
    Random,
    /// A generated floor: two rooms joined by a corridor one robot wide (12 m), half the
    /// robots in each room sent to the other.
    Corridor,
    /// A generated floor: a four-way crossing of two corridors one robot wide, a room at the
    /// end of each arm; the robots split over the four rooms, each sent to the opposite one.
    Crossing,
    /// A generated floor: two rooms joined by one door a robot wide in the wall between them,
    /// half the robots in each room sent to the other.
    Doorway,
}

impl Scenario {
    /// Every scenario, in the order of the command line's help.
    pub const ALL: [Scenario; 4] = [
        Scenario::Random,
        Scenario::Corridor,
        Scenario::Crossing,
        Scenario::Doorway,
    ];

    /// Its name on the command line and in the report.
    pub fn as_str(self) -> &'static str {
        match self {
            Scenario::Random => "random",
            Scenario::Corridor => "corridor",
            Scenario::Crossing => "crossing",
            Scenario::Doorway => "doorway",
        }
    }
}

impl std::str::FromStr for Scenario {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Scenario::ALL
            .into_iter()
            .find(|c| c.as_str() == s)
            .ok_or_else(|| format!("no scenario `{s}`"))
    }
}

/// What `bench fleet` runs.
#[derive(Debug, Clone)]
pub struct FleetBenchOptions {
    /// Directory searched recursively for ROS map_server YAML files (random missions).
    pub maps: PathBuf,
    /// Robots at once.
    pub robots: usize,
    /// People per 100 m² of free region.
    pub people: f64,
    /// The missions.
    pub scenario: Scenario,
    /// Seed of the missions and simulations.
    pub seed: u64,
    /// The robot's TOSM description (Turtle); robot `k` is it under the IRI `robot_iri-k`.
    pub robot_ttl: Vec<u8>,
    /// The robot's IRI in it.
    pub robot_iri: String,
    /// Most waiting a plan may take (`options.max_wait_s`), seconds.
    pub max_wait_s: f64,
    /// `None`: every robot asks at once (the plan order is the scheduler's). `Some(seed)`:
    /// one after another, in an order shuffled by `seed`, so a run that depends on the order
    /// can be repeated.
    pub order_seed: Option<u64>,
    /// Every robot asks with the same `options.seed` (as robots sending the default options
    /// do: one roadmap, the same draws), not one seed each.
    pub same_seed: bool,
    /// The reference beside the run: the same missions planned first-come, one robot after
    /// another, in this many orders (0: none), each on a fresh schedule and driven jointly as
    /// the run is. At most [`MAX_ORDERS`].
    pub orders: usize,
    /// Seconds the planner's idle-time improver ([`Planner::improve`]) works on the floor's
    /// schedule after every robot has asked, before the joint run (0: none): the joint run
    /// then drives the plans as revised, and the row reports the first-come joint run beside.
    pub improve_s: f64,
    /// Planners the robots ask, robot `k` the planner `k % processes`: each with its own
    /// locks, waits and improver over the one schedule, as API processes sharing a job
    /// database are (1: one process). At most [`MAX_PROCESSES`].
    pub processes: usize,
}

/// Most planners (`--processes`) a run spreads its robots over.
pub const MAX_PROCESSES: usize = 8;

pub use reference::MAX_ORDERS;

/// One map and scenario.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FleetRow {
    /// The map's short name.
    pub map: String,
    /// `random`, `corridor`, `crossing` or `doorway`.
    pub scenario: String,
    /// Robots that asked: `--robots`, or fewer where the floor has room for fewer missions
    /// (starts and goals a robot's width apart).
    pub robots: usize,
    /// People per 100 m².
    pub people: f64,
    /// Plans answered (the others were refused: 409 or another error).
    pub planned: usize,
    /// Why plans were refused, one line each.
    pub refusals: Vec<String>,
    /// Why robots did not arrive in the joint run, one line each.
    pub joint_failures: Vec<String>,
    /// Share of the robots that arrived in the joint run (a refused plan counts as not).
    pub joint_success_rate: f64,
    /// [`Self::joint_success_rate`] with every robot standing at its start until its plan
    /// starts, which the schedule does not hold for a robot told to start later
    /// (docs/benchmarks.md, `bench fleet`).
    pub joint_success_starts_held_rate: f64,
    /// Robots whose joint drive ended touching another robot.
    pub robot_collisions: usize,
    /// Robots whose joint drive stalled (a waypoint not reached in time: blocked).
    pub stalls: usize,
    /// Stalls with another robot within a robot's width: robots blocking each other.
    pub deadlocks: usize,
    /// When the last robot arrived in the joint run, seconds after the common start.
    pub makespan_s: f64,
    /// The same robots' missions planned alone (nobody else on the floor, no waits, no detour
    /// around other robots): the longest, seconds.
    pub makespan_alone_s: f64,
    /// `makespan_s / makespan_alone_s`.
    pub makespan_ratio: f64,
    /// Sum of the arrived robots' times in the joint run, seconds.
    pub sum_of_times_s: f64,
    /// Sum of the same robots' times alone, seconds.
    pub sum_alone_s: f64,
    /// Total waiting the schedule gave the robots, seconds.
    pub waits_s: f64,
    /// A lower bound on the makespan: [`Self::makespan_alone_s`] (docs/benchmarks.md, `bench
    /// fleet`, on what it bounds).
    pub makespan_lower_bound_s: f64,
    /// Orders the same missions were planned in first-come (`--orders`).
    pub first_come_orders: usize,
    /// Each order's makespan (its arrived robots' last arrival), seconds: order 0 by robot
    /// index, the others shuffled by seeds derived from `--seed`.
    pub first_come_makespans_s: Vec<f64>,
    /// Each order's robots that arrived in its joint run.
    pub first_come_arrived: Vec<usize>,
    /// The least makespan among the orders in which every robot was planned and arrived;
    /// `None` where no order brought every robot through (or no orders were run).
    pub best_first_come_makespan_s: Option<f64>,
    /// `makespan_s / best_first_come_makespan_s`, where there is a best.
    pub makespan_vs_best_first_come: Option<f64>,
    /// Seconds the idle-time improver worked on the schedule before the joint run.
    pub improve_s: f64,
    /// Revisions it made (each a neighbourhood of plans revised at once).
    pub revisions: u32,
    /// Neighbourhood orders it re-planned.
    pub neighbourhoods_tried: u32,
    /// The joint run's makespan as first-come commits left the plans, before any revision,
    /// seconds (`None`: the improver did not run).
    pub makespan_first_come_s: Option<f64>,
    /// Drives among the fleet the plans took, refused ones included (each plan at least one
    /// unless alone on the floor): what a plan costs beyond its validating rehearsal.
    pub drives_among_fleet: u32,
    /// Plan latency under the concurrent requests, ms.
    pub latency_p50_ms: f64,
    /// Plan latency under the concurrent requests, ms.
    pub latency_p95_ms: f64,
    /// Each robot that was planned: how long it took alone and among the fleet, and why it
    /// waited.
    pub per_robot: Vec<FleetRobotRow>,
    /// The joint run as the console's Traffic page replays it (`--replay DIR`).
    #[serde(skip)]
    pub replay: crate::fleet_replay::JointReplay,
}

/// One robot of a [`FleetRow`].
#[derive(Debug, Clone, serde::Serialize)]
pub struct FleetRobotRow {
    /// The robot's IRI.
    pub robot: String,
    /// Its mission planned alone, seconds (`None`: refused alone).
    pub alone_s: Option<f64>,
    /// Its time in the joint run, seconds, where it arrived.
    pub joint_s: Option<f64>,
    /// The path it drove alone, metres.
    pub alone_path_m: Option<f64>,
    /// The path it drove in the joint run, metres.
    pub joint_path_m: f64,
    /// Its plan's latency under the concurrent requests, ms (both requests where it asked
    /// twice).
    pub latency_ms: f64,
    /// Its plan's waits: (waypoint, `None` for the start; seconds; the robots it let pass).
    pub waits: Vec<(Option<usize>, f64, Vec<String>)>,
    /// Drives among the fleet its plan took.
    pub drives: u32,
}

/// The knowledge of one floor: one on-demand database per robot.
struct Floor(HashMap<String, Arc<FloorDatabase>>);

impl KnowledgeSource for Floor {
    fn floor_database<'a>(&'a self, _place: &'a str, robot: &'a str) -> SourceFuture<'a> {
        Box::pin(async move {
            self.0
                .get(robot)
                .cloned()
                .ok_or_else(|| SourceError::NotFound(format!("no robot `{robot}`")))
        })
    }
}

/// No policy-aware roadmap builds: the bench plans without a policy or with its stored
/// roadmap absent (the geometric roadmap).
struct NoBuilds;

impl planner::RoadmapBuilds for NoBuilds {
    fn ensure<'a>(
        &'a self,
        _key: &'a planner::PolicyRoadmapKey,
        _floor: &'a str,
        _robot: &'a str,
        _margin: f64,
    ) -> planner::BuildFuture<'a> {
        Box::pin(async {
            Err(planner::PortError::new(
                "building a policy-aware roadmap",
                "the fleet benchmark builds none",
            ))
        })
    }
}

/// The floor's traffic schedule in memory: a version and the committed itineraries, and the
/// plans waiting for standing robots ([`FleetSchedule::post_wait`]), shared by every planner of
/// the run as the job database is by API processes.
#[derive(Default)]
struct MemorySchedule(
    Mutex<(i64, Vec<Itinerary>)>,
    Mutex<HashMap<String, traffic::Wait>>,
);

impl MemorySchedule {
    fn all(&self) -> Vec<Itinerary> {
        self.0
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .1
            .clone()
    }
}

impl FleetSchedule for MemorySchedule {
    fn snapshot<'a>(&'a self, floor: &'a str) -> FleetFuture<'a, (i64, Vec<Itinerary>)> {
        let g = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        let now = self.now_ms();
        let found =
            g.1.iter()
                .filter(|i| i.floor == floor && i.expires_unix_ms >= now)
                .cloned()
                .collect();
        let version = g.0;
        Box::pin(async move { Ok((version, found)) })
    }

    fn version<'a>(&'a self, _floor: &'a str) -> FleetFuture<'a, i64> {
        let version = self.0.lock().unwrap_or_else(PoisonError::into_inner).0;
        Box::pin(async move { Ok(version) })
    }

    fn commit(&self, itinerary: Itinerary, expected_version: i64) -> FleetFuture<'_, Committed> {
        let mut g = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        let answer = if g.0 == expected_version {
            g.1.retain(|i| i.robot != itinerary.robot);
            g.1.push(itinerary);
            g.0 += 1;
            Committed::Yes(g.0)
        } else {
            Committed::VersionChanged
        };
        Box::pin(async move { Ok(answer) })
    }

    fn revise(&self, plans: Vec<Itinerary>, expected_version: i64) -> FleetFuture<'_, Committed> {
        let mut g = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        let known = plans
            .iter()
            .all(|p| g.1.iter().any(|i| i.plan_id == p.plan_id));
        let answer = if g.0 != expected_version {
            Committed::VersionChanged
        } else if !known {
            Committed::Refused("a revised plan is not in the schedule".to_owned())
        } else {
            for p in plans {
                if let Some(i) = g.1.iter_mut().find(|i| i.plan_id == p.plan_id) {
                    let revision = i.revision + 1;
                    *i = Itinerary { revision, ..p };
                }
            }
            g.0 += 1;
            Committed::Yes(g.0)
        };
        Box::pin(async move { Ok(answer) })
    }

    fn post_wait(&self, wait: traffic::Wait) -> FleetFuture<'_, ()> {
        let mut g = self.1.lock().unwrap_or_else(PoisonError::into_inner);
        g.insert(wait.robot.clone(), wait);
        Box::pin(async { Ok(()) })
    }

    fn clear_wait<'a>(&'a self, robot: &'a str) -> FleetFuture<'a, ()> {
        self.1
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .remove(robot);
        Box::pin(async { Ok(()) })
    }

    fn waits<'a>(&'a self, floor: &'a str) -> FleetFuture<'a, Vec<traffic::Wait>> {
        let now = self.now_ms();
        let found = self
            .1
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .values()
            .filter(|w| w.floor == floor && w.until_unix_ms >= now)
            .cloned()
            .collect();
        Box::pin(async move { Ok(found) })
    }

    fn now_ms(&self) -> i64 {
        now_ms()
    }
}

fn now_ms() -> i64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

/// Runs the benchmark: every map under `maps` (random missions) or the generated floor.
pub fn run_fleet_bench(opts: &FleetBenchOptions) -> Result<Vec<FleetRow>, BenchError> {
    if !(1..=planner::fleet::MAX_ROBOTS_PER_FLOOR).contains(&opts.robots) {
        return Err(BenchError::BadOption(format!(
            "--robots must lie in [1, {}], got {}",
            planner::fleet::MAX_ROBOTS_PER_FLOOR,
            opts.robots
        )));
    }
    if !(opts.improve_s.is_finite() && (0.0..=3600.0).contains(&opts.improve_s)) {
        return Err(BenchError::BadOption(format!(
            "--improve-s must lie in [0, 3600] seconds, got {}",
            opts.improve_s
        )));
    }
    if !(opts.max_wait_s.is_finite()
        && (0.0..=planner::fleet::MAX_FLEET_S).contains(&opts.max_wait_s))
    {
        return Err(BenchError::BadOption(format!(
            "--max-wait-s must lie in [0, {}] s, got {}",
            planner::fleet::MAX_FLEET_S,
            opts.max_wait_s
        )));
    }
    if !(opts.people.is_finite() && (0.0..=50.0).contains(&opts.people)) {
        return Err(BenchError::BadOption(format!(
            "--people must lie in [0, 50] people per 100 m², got {}",
            opts.people
        )));
    }
    if !(1..=MAX_PROCESSES).contains(&opts.processes) {
        return Err(BenchError::BadOption(format!(
            "--processes must lie in [1, {MAX_PROCESSES}], got {}",
            opts.processes
        )));
    }
    reference::check(opts)?;
    let floors: Vec<(String, PathBuf, OccupancyGrid, Option<floors::Layout>)> =
        match floors::generated(opts.scenario) {
            Some((grid, layout)) => {
                let name = opts.scenario.as_str();
                vec![(
                    name.to_owned(),
                    PathBuf::from(format!("{name}/{name}.yaml")),
                    grid,
                    Some(layout),
                )]
            }
            None => {
                let yamls = crate::maps::find_yamls(&opts.maps)?;
                if yamls.is_empty() {
                    return Err(BenchError::NoMaps(opts.maps.clone()));
                }
                yamls
                    .into_iter()
                    .map(|y| {
                        let grid = knowledge::maps::read_ros_map(&y)?;
                        Ok((learning::run::map_name(&y), y, grid, None))
                    })
                    .collect::<Result<_, BenchError>>()?
            }
        };
    floors
        .into_iter()
        .map(|(name, yaml, grid, layout)| run_floor(opts, &name, &yaml, grid, layout.as_ref()))
        .collect()
}

/// `n` missions: the generated floor's (see [`floors::missions`]), or random ones across the
/// roadmap's largest component with starts and goals kept a robot's width apart.
fn missions(
    scenario: Scenario,
    layout: Option<&floors::Layout>,
    world: &Arc<World>,
    n: usize,
    seed: u64,
) -> Result<Vec<(Pose2, prm::Point2)>, BenchError> {
    let radius = world.spec().robot.footprint_radius;
    if let Some(layout) = layout {
        return floors::missions(scenario, layout, radius, n);
    }
    let apart = 2.0 * radius + 0.4;
    let roadmap =
        rehearsal::first_attempt_roadmap(world, seed).map_err(|source| BenchError::Rehearsal {
            map: "missions".into(),
            source,
        })?;
    let far = |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).hypot(a.1 - b.1) >= apart;
    let mut out: Vec<(Pose2, prm::Point2)> = Vec::new();
    for (s, g) in planner::controllers::trial_missions(&roadmap, 40 * n, seed) {
        if out.len() == n {
            break;
        }
        let ok = out.iter().all(|(s2, g2)| {
            far((s.x, s.y), (s2.x, s2.y))
                && far((g.x, g.y), (g2.x, g2.y))
                && far((s.x, s.y), (g2.x, g2.y))
                && far((g.x, g.y), (s2.x, s2.y))
        });
        if ok {
            out.push((s, g));
        }
    }
    Ok(out)
}

/// `more` (an improver's work after `into`'s) added to `into`.
fn absorb(into: &mut planner::Improvement, more: planner::Improvement) {
    into.tried += more.tried;
    into.kept += more.kept;
    into.revised.extend(more.revised);
    into.drives += more.drives;
    into.before = into.before.take().or(more.before);
    into.after = more.after.or(into.after.take());
}

/// A plan's latency (ms) and outcome.
type Answer = (f64, Result<PlanOutcome, String>);

/// Every query asked at once, as robots of a fleet do, query `k` of planner `k % len`;
/// answers in the queries' order.
async fn plan_at_once(planners: &[Arc<Planner>], queries: Vec<PlanQuery>) -> Vec<Answer> {
    let tasks: Vec<_> = queries
        .into_iter()
        .enumerate()
        .map(|(k, q)| {
            let planner = Arc::clone(&planners[k % planners.len()]);
            tokio::spawn(async move { timed_plan(&planner, q).await })
        })
        .collect();
    let mut out = Vec::new();
    for t in tasks {
        out.push(
            t.await
                .unwrap_or_else(|e| (f64::NAN, Err(format!("the plan task failed: {e}")))),
        );
    }
    out
}

/// [`plan_at_once`], then the robots refused asked again, all at once (as robots told that
/// others stand in their way ask again once those have their plans); a robot's latency the
/// time of both its requests.
async fn plan_at_once_again(planners: &[Arc<Planner>], queries: Vec<PlanQuery>) -> Vec<Answer> {
    let mut answers = plan_at_once(planners, queries.clone()).await;
    let refused: Vec<usize> = (0..answers.len())
        .filter(|&k| answers[k].1.is_err())
        .collect();
    // Each robot asks its own planner again.
    let tasks: Vec<_> = refused
        .iter()
        .map(|&k| {
            let planner = Arc::clone(&planners[k % planners.len()]);
            let q = queries[k].clone();
            tokio::spawn(async move { timed_plan(&planner, q).await })
        })
        .collect();
    let mut again = Vec::new();
    for t in tasks {
        again.push(t.await);
    }
    for (k, joined) in refused.into_iter().zip(again) {
        let (ms, r) =
            joined.unwrap_or_else(|e| (f64::NAN, Err(format!("the plan task failed: {e}"))));
        answers[k] = (answers[k].0 + ms, r);
    }
    answers
}

/// The queries asked one after another in an order shuffled by `seed` (Fisher–Yates), each
/// one refused asked again once after all the others (as a robot told that another stands in
/// its way asks again later); answers in the queries' order, a robot's latency the time of
/// both its requests.
async fn plan_in_turn(
    planners: &[Arc<Planner>],
    queries: Vec<PlanQuery>,
    seed: u64,
) -> Vec<Answer> {
    let order = shuffled(queries.len(), seed);
    plan_in_order(planners, queries, order).await
}

/// `0..n` shuffled by `seed` (Fisher–Yates).
fn shuffled(n: usize, seed: u64) -> Vec<usize> {
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..order.len()).rev() {
        let j = (grid::seed::nth(seed, i as u64) % (i as u64 + 1)) as usize;
        order.swap(i, j);
    }
    order
}

/// The queries asked one after another in `order` (indices into `queries`), each one refused
/// asked again once after all the others; answers in the queries' order.
async fn plan_in_order(
    planners: &[Arc<Planner>],
    queries: Vec<PlanQuery>,
    order: Vec<usize>,
) -> Vec<Answer> {
    let planner = |k: usize| &planners[k % planners.len()];
    let mut queries: Vec<Option<PlanQuery>> = queries.into_iter().map(Some).collect();
    let mut answers: Vec<Option<Answer>> = (0..queries.len()).map(|_| None).collect();
    let mut again = Vec::new();
    for k in order {
        if let Some(q) = queries[k].take() {
            let answer = timed_plan(planner(k), q.clone()).await;
            if answer.1.is_err() {
                again.push((k, q, answer.0));
            }
            answers[k] = Some(answer);
        }
    }
    for (k, q, first_ms) in again {
        let (ms, r) = timed_plan(planner(k), q).await;
        answers[k] = Some((first_ms + ms, r));
    }
    answers.into_iter().flatten().collect()
}

/// One plan and how long it took, ms.
async fn timed_plan(planner: &Planner, q: PlanQuery) -> Answer {
    let t = Instant::now();
    let r = planner.plan(q, rehearsal::Stop::default()).await;
    (
        t.elapsed().as_secs_f64() * 1e3,
        r.map_err(|e| e.to_string()),
    )
}

/// `it` with its robot standing at its first pose from `t0` until its itinerary starts: a robot
/// told to start later than `t0` is at its start meanwhile, which the schedule does not hold,
/// and the joint run with starts held drives the others past it there.
fn standing_from(it: &Itinerary, t0: i64) -> Itinerary {
    let before_s = (it.start_unix_ms - t0) as f64 / 1000.0;
    let Some(first) = it.trajectory.first().filter(|_| before_s > 0.0) else {
        return it.clone();
    };
    let trajectory = std::iter::once(traffic::TimedPose { t_s: 0.0, ..*first })
        .chain(it.trajectory.iter().map(|p| traffic::TimedPose {
            t_s: p.t_s + before_s,
            ..*p
        }))
        .collect();
    Itinerary {
        start_unix_ms: t0,
        trajectory,
        ..it.clone()
    }
}

/// The length of a drive, metres.
fn path_m(steps: &[Pose2]) -> f64 {
    steps
        .windows(2)
        .map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y))
        .sum()
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// A joint run: every plan of `planned` among all the others `committed`, as the schedule
/// holds them (`held_from: None`), or with each robot standing at its start from `held_from`
/// until its plan starts (`Some(t0)`).
fn joint_run(
    planned: &[PlanOutcome],
    committed: &[Itinerary],
    held_from: Option<i64>,
) -> Vec<Result<rehearsal::AmongReport, String>> {
    planned
        .par_iter()
        .map(|o| {
            let others: Vec<Itinerary> = committed
                .iter()
                .filter(|i| i.robot != o.robot)
                .map(|i| held_from.map_or_else(|| i.clone(), |t0| standing_from(i, t0)))
                .collect();
            o.rehearse_among(&others).map_err(|e| e.to_string())
        })
        .collect()
}

/// The times of the robots of a joint run that arrived, seconds.
fn arrival_times(joint: &[Result<rehearsal::AmongReport, String>]) -> Vec<f64> {
    joint
        .iter()
        .filter_map(|j| j.as_ref().ok())
        .filter(|r| r.outcome == AttemptOutcome::Reached)
        .map(|r| r.time_s)
        .collect()
}

fn run_floor(
    opts: &FleetBenchOptions,
    name: &str,
    yaml: &Path,
    grid: OccupancyGrid,
    layout: Option<&floors::Layout>,
) -> Result<FleetRow, BenchError> {
    let floor = prepare(opts, name, yaml, grid, layout)?;
    let schedule = Arc::new(MemorySchedule::default());
    // One planner per process, sharing the schedule.
    let planners: Vec<Arc<Planner>> = (0..opts.processes)
        .map(|_| floor.planner(Some(&schedule)))
        .collect();
    // The robots set off a minute from now, after the improver's time: until then every plan
    // may still be revised.
    let t0 = now_ms() + 60_000 + (opts.improve_s * 1000.0).round() as i64;
    let queries = floor.queries(opts, t0, opts.order_seed.is_some());
    floor.stand_all(opts, &planners[0], &queries, t0, yaml)?;
    let asked = queries.clone();
    let answers = match opts.order_seed {
        None => floor
            .runtime
            .block_on(plan_at_once_again(&planners, queries)),
        Some(seed) => floor
            .runtime
            .block_on(plan_in_turn(&planners, queries, seed)),
    };
    // The same missions planned alone (no schedule: nobody else on the floor), after the
    // clock: the baseline of the makespan and the sum of times. A plan among the fleet may
    // take a detour around robots standing in its way; alone it does not. Both on the same
    // roadmap: among robots standing the planner samples a denser one.
    let asked: Vec<PlanQuery> = asked
        .into_iter()
        .map(|mut q| {
            q.request.options.samples = Some(floor.dense_samples);
            q
        })
        .collect();
    let alone_plans: HashMap<String, (f64, f64)> = floor
        .runtime
        .block_on(plan_at_once(&[floor.planner(None)], asked))
        .into_iter()
        .filter_map(|(_, a)| a.ok())
        .map(|o| {
            let path = path_m(&o.report.steps);
            (o.robot, (o.report.simulated_time_s, path))
        })
        .collect();
    let mut latencies: Vec<f64> = answers
        .iter()
        .map(|a| a.0)
        .filter(|l| l.is_finite())
        .collect();
    latencies.sort_by(f64::total_cmp);
    let mut refusals = Vec::new();
    let mut planned = Vec::new();
    let mut latency_of = HashMap::new();
    for (ms, a) in answers {
        match a {
            Ok(o) => {
                latency_of.insert(o.robot.clone(), ms);
                planned.push(o);
            }
            Err(e) => refusals.push(e),
        }
    }
    let (improvement, makespan_first_come_s) = if opts.improve_s > 0.0 {
        let first_come = arrival_times(&joint_run(&planned, &schedule.all(), None));
        // Each process improves the plans it answered, in turn, sharing the time.
        let mut improvement = planner::Improvement::default();
        for planner in &planners {
            let by_this = floor
                .runtime
                .block_on(planner.improve(
                    &floor.floor_iri,
                    std::time::Duration::from_secs_f64(opts.improve_s / planners.len() as f64),
                ))
                .map_err(BenchError::Improve)?;
            absorb(&mut improvement, by_this);
        }
        // The plans as the improvers left them.
        for o in &mut planned {
            if let Some(now) = o.fleet.as_ref().and_then(|f| {
                planners
                    .iter()
                    .find_map(|p| p.committed_outcome(&f.itinerary.plan_id))
            }) {
                *o = now;
            }
        }
        let makespan = first_come.iter().copied().fold(0.0f64, f64::max);
        (improvement, Some(makespan))
    } else {
        (planner::Improvement::default(), None)
    };
    let committed = schedule.all();
    let joint = joint_run(&planned, &committed, None);
    let arrived_with_starts_held = arrival_times(&joint_run(&planned, &committed, Some(t0))).len();
    let mut row = joint_row(opts, &floor, name, &planned, &joint, &alone_plans);
    row.refusals = refusals;
    row.improve_s = opts.improve_s;
    row.revisions = improvement.kept;
    row.neighbourhoods_tried = improvement.tried;
    row.makespan_first_come_s = makespan_first_come_s;
    row.joint_success_starts_held_rate =
        arrived_with_starts_held as f64 / floor.missions.len() as f64;
    for r in &mut row.per_robot {
        r.latency_ms = latency_of.get(&r.robot).copied().unwrap_or(f64::NAN);
    }
    row.latency_p50_ms = percentile(&latencies, 0.5);
    row.latency_p95_ms = percentile(&latencies, 0.95);
    // The reference beside it, after the run's clock: the same missions first-come in
    // `--orders` orders.
    let first_come = reference::first_come(opts, &floor, yaml)?;
    first_come.fill(&mut row);
    Ok(row)
}

/// The row of a joint run of `planned` (`joint`, in the same order) against the robots'
/// plans alone on the map `name`: all but the refusals, latencies, the run with starts held
/// and the reference, which the caller fills in.
fn joint_row(
    opts: &FleetBenchOptions,
    floor: &Prepared,
    name: &str,
    planned: &[PlanOutcome],
    joint: &[Result<rehearsal::AmongReport, String>],
    alone_plans: &HashMap<String, (f64, f64)>,
) -> FleetRow {
    let (mut collisions, mut stalls, mut deadlocks) = (0usize, 0usize, 0usize);
    let (mut makespan_alone, mut sum_alone) = (0.0f64, 0.0f64);
    let mut joint_failures = Vec::new();
    for (o, j) in planned.iter().zip(joint) {
        let alone = alone_plans
            .get(&o.robot)
            .map(|a| a.0)
            .unwrap_or(o.report.simulated_time_s);
        makespan_alone = makespan_alone.max(alone);
        sum_alone += alone;
        match j {
            Ok(r) if r.outcome == AttemptOutcome::Reached => continue,
            Ok(r) if r.met_robot().is_some() => collisions += 1,
            Ok(r) if r.outcome == AttemptOutcome::Stalled => {
                stalls += 1;
                if r.min_robot_clearance_m
                    .is_some_and(|c| c < 2.0 * floor.radius)
                {
                    deadlocks += 1;
                }
            }
            Ok(_) => {}
            Err(e) => {
                joint_failures.push(format!("{}: {e}", o.robot));
                continue;
            }
        }
        if let Ok(r) = j {
            joint_failures.push(format!("{}: {}", o.robot, r.reason));
        }
    }
    let arrivals = arrival_times(joint);
    let makespan = arrivals.iter().copied().fold(0.0f64, f64::max);
    let per_robot = planned
        .iter()
        .zip(joint)
        .map(|(o, j)| {
            let reached = j
                .as_ref()
                .ok()
                .filter(|r| r.outcome == AttemptOutcome::Reached);
            FleetRobotRow {
                latency_ms: f64::NAN,
                robot: o.robot.clone(),
                alone_s: alone_plans.get(&o.robot).map(|a| a.0),
                joint_s: reached.map(|r| r.time_s),
                alone_path_m: alone_plans.get(&o.robot).map(|a| a.1),
                joint_path_m: j.as_ref().map_or(0.0, |r| path_m(&r.steps)),
                waits: o.fleet.as_ref().map_or_else(Vec::new, |f| {
                    f.waits
                        .iter()
                        .map(|w| (w.waypoint, w.wait_s, w.for_robots.clone()))
                        .collect()
                }),
                drives: o.fleet.as_ref().map_or(0, |f| f.drives),
            }
        })
        .collect();
    let robots = floor.missions.len();
    FleetRow {
        replay: crate::fleet_replay::joint_replay(
            name,
            opts.scenario.as_str(),
            &floor.floor_iri,
            planned,
            joint,
        ),
        map: name.to_owned(),
        scenario: opts.scenario.as_str().to_owned(),
        robots,
        people: opts.people,
        planned: planned.len(),
        refusals: Vec::new(),
        joint_failures,
        joint_success_rate: arrivals.len() as f64 / robots as f64,
        joint_success_starts_held_rate: f64::NAN,
        robot_collisions: collisions,
        stalls,
        deadlocks,
        makespan_s: makespan,
        makespan_alone_s: makespan_alone,
        makespan_ratio: if makespan_alone > 0.0 {
            makespan / makespan_alone
        } else {
            f64::NAN
        },
        sum_of_times_s: arrivals.iter().sum(),
        sum_alone_s: sum_alone,
        waits_s: planned
            .iter()
            .filter_map(|o| o.fleet.as_ref())
            .flat_map(|f| f.waits.iter().map(|w| w.wait_s))
            .sum(),
        makespan_lower_bound_s: makespan_alone,
        first_come_orders: 0,
        first_come_makespans_s: Vec::new(),
        first_come_arrived: Vec::new(),
        best_first_come_makespan_s: None,
        makespan_vs_best_first_come: None,
        improve_s: 0.0,
        revisions: 0,
        neighbourhoods_tried: 0,
        makespan_first_come_s: None,
        drives_among_fleet: planned
            .iter()
            .filter_map(|o| o.fleet.as_ref())
            .map(|f| f.drives)
            .sum(),
        latency_p50_ms: f64::NAN,
        latency_p95_ms: f64::NAN,
        per_robot,
    }
}

/// The rows as a Markdown table, then each row's first-come orders (`--orders`).
pub fn markdown(rows: &[FleetRow]) -> String {
    let mut md = String::from(
        "| map | scenario | robots | people/100 m² | planned | joint success | with starts held | robot collisions | stalls | deadlocks | makespan (s) | alone (s) | ratio | best first-come (s) | vs best | waits (s) | latency p50 / p95 (ms) |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let or_dash = |v: Option<f64>, places: usize| {
        v.map_or_else(|| "–".to_owned(), |v| format!("{v:.places$}"))
    };
    for r in rows {
        md.push_str(&format!(
            "| {} | {} | {} | {} | {} | {:.0}% | {:.0}% | {} | {} | {} | {:.1} | {:.1} | {:.2} | {} | {} | {:.1} | {:.0} / {:.0} |\n",
            r.map,
            r.scenario,
            r.robots,
            r.people,
            r.planned,
            r.joint_success_rate * 100.0,
            r.joint_success_starts_held_rate * 100.0,
            r.robot_collisions,
            r.stalls,
            r.deadlocks,
            r.makespan_s,
            r.makespan_alone_s,
            r.makespan_ratio,
            or_dash(r.best_first_come_makespan_s, 1),
            or_dash(r.makespan_vs_best_first_come, 2),
            r.waits_s,
            r.latency_p50_ms,
            r.latency_p95_ms
        ));
    }
    for r in rows {
        if let Some(first_come) = r.makespan_first_come_s {
            md.push_str(&format!(
                "\n{} ({}): the improver, {:.0} s: {} revisions ({} neighbourhood orders re-planned); joint makespan {:.1} s, first-come before it {:.1} s\n",
                r.map,
                r.scenario,
                r.improve_s,
                r.revisions,
                r.neighbourhoods_tried,
                r.makespan_s,
                first_come
            ));
        }
    }
    md.push_str(&reference::markdown_lines(rows));
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    fn later(start_unix_ms: i64) -> Itinerary {
        let pose = |t_s: f64, x: f64| traffic::TimedPose {
            t_s,
            x,
            y: 0.0,
            yaw: 0.0,
        };
        Itinerary {
            plan_id: "p".into(),
            robot: "r".into(),
            floor: "f".into(),
            start_unix_ms,
            trajectory: vec![pose(0.0, 1.0), pose(2.0, 3.0)],
            radius_m: 0.2,
            tolerance_s: 1.0,
            expires_unix_ms: start_unix_ms + 5_000,
            delay_s: 0.0,
            revision: 1,
        }
    }

    #[test]
    fn a_robot_told_to_start_later_stands_at_its_start_from_the_common_start() {
        let held = standing_from(&later(10_000), 4_000);
        held.check().expect("a valid itinerary");
        assert_eq!(held.start_unix_ms, 4_000);
        assert_eq!(held.pose_at(4_000), Some((1.0, 0.0)));
        assert_eq!(held.pose_at(9_000), Some((1.0, 0.0)));
        assert_eq!(held.pose_at(12_000), Some((3.0, 0.0)));
        assert_eq!(held.expires_unix_ms, 15_000);
        // One that starts with the others is as committed.
        assert_eq!(standing_from(&later(4_000), 4_000), later(4_000));
    }
}
