//! The plan use case, with no HTTP in it: [`Planner::plan`] decides everything a plan decides —
//! the floor's mental simulation (through a [`KnowledgeSource`]), which policy drives (the one
//! named, else the robot's newest), which roadmap (the policy-aware one of this floor state and
//! policy when it is stored, else the geometric one, with a background build asked for), which
//! people walk about (the knowledge's expected people at an hour, or a density), the follower
//! as fallback per leg, and the note that says why — and calls the `rehearsal` executor.
//!
//! `POST /v1/plan`, the `validate` job kind and the CLI call it alike: they translate their
//! input into a [`PlanQuery`] and the [`PlanOutcome`] back, and decide nothing.
//!
//! - [`controllers`]: which controller validates a plan (`auto`: the one measured best on the
//!   floor state, never one measurably worse than another available);
//! - [`fleet`]: the plan among the other robots' committed plans (waits, the commit), and
//!   `among`: the plan's way through it (fit, drive among the others, commit, retry);
//! - [`floor`]: the on-demand database of a floor and the world made from it;
//! - [`policies`]: exported policies on disk and their summaries;
//! - [`roadmaps`]: stored policy-aware roadmaps.

mod among;
pub mod controllers;
pub mod fleet;
pub mod floor;
mod gate;
pub mod policies;
mod replay;
pub mod roadmaps;
mod yielding;

use std::collections::HashMap;
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::SystemTime;

use rehearsal::{ControllerChoice, PlanError, PlanRequest, RoadmapCache, RoadmapChoice};
use sim::World;

use replay::Replay;

pub use controllers::{ControllerPick, ControllerTrial};
pub use fleet::{FleetOptions, FleetOutcome, FleetSchedule, NoFit};
pub use floor::{FloorDatabase, KnowledgeSource, SourceError, SourceFuture};
pub use policies::{HeldOutEval, PolicyEntry, PolicyStore, PolicySummary};
pub use roadmaps::{AppliedRoadmap, PolicyRoadmapKey, RoadmapStore, StoredRoadmap};

/// Who walks about in a plan's rehearsal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PlanPeople {
    /// As many as the floor's knowledge expects (none where it says nothing), at the hour of
    /// day `hour` (0-23) where it has figures by hour, else its all-day figures.
    Expected {
        /// Hour of day, 0-23.
        hour: Option<u8>,
    },
    /// As the request's `options.people` says (nobody, or a density).
    AsGiven,
}

/// What to plan.
#[derive(Debug, Clone)]
pub struct PlanQuery {
    /// The robot (IRI or identifier).
    pub robot: String,
    /// Its floor, or a place on it (IRI or identifier).
    pub place: String,
    /// The start, the goals and the validation options (its `stop` is replaced by the one
    /// [`Planner::plan`] is given).
    pub request: PlanRequest,
    /// Who walks about.
    pub people: PlanPeople,
    /// The policy to drive with; `None`: the robot's newest.
    pub policy: Option<String>,
    /// The controller to validate with; `None`: `auto`, the one measured best on the floor
    /// state ([`controllers`]).
    pub controller: Option<ControllerChoice>,
    /// How the plan takes part in the floor's traffic schedule.
    pub fleet: FleetOptions,
}

/// Where a plan's people came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PeopleSource {
    /// The floor's knowledge (its expected people).
    Knowledge,
    /// A density the request gave.
    Density,
}

impl PeopleSource {
    /// `knowledge` or `density`.
    pub fn as_str(self) -> &'static str {
        match self {
            PeopleSource::Knowledge => "knowledge",
            PeopleSource::Density => "density",
        }
    }
}

/// How a plan fared among people: over every attempt (each its own draw), and its validating
/// runs' closest approach.
#[derive(Debug, Clone, PartialEq)]
pub struct PeopleSummary {
    /// Where the people came from.
    pub source: PeopleSource,
    /// People drawn in each attempt.
    pub people: usize,
    /// Closest approach to a person in the attempts that reached, metres.
    pub min_person_clearance_m: Option<f64>,
    /// Attempts run.
    pub attempts: usize,
    /// Attempts that reached their leg's goal.
    pub attempts_reached: usize,
    /// Attempts that ended touching a person.
    pub attempts_hit_person: usize,
    /// Attempts closer than [`rehearsal::NEAR_MISS_M`] to a person without touching one.
    pub attempts_near_miss: usize,
    /// The validated plan driven again among fresh draws (`options.people_draws`).
    pub draws: Option<rehearsal::DrawsReport>,
}

/// A validated plan and how it was validated.
#[derive(Debug, Clone)]
pub struct PlanOutcome {
    /// The robot's IRI.
    pub robot: String,
    /// The floor's IRI.
    pub floor: String,
    /// The robot's policy (the one named, else its newest), if it has one; it drove the
    /// simulated robot when `controller` is a hybrid.
    pub policy: Option<String>,
    /// The controller that validated the plan (but for legs its fallback validated), and why.
    pub controller: ControllerPick,
    /// Why a classical controller validated the plan or some of its legs, when one did.
    pub note: Option<String>,
    /// The plan in the floor's traffic schedule (its times, waits and commit); `None` where
    /// the planner has no schedule.
    pub fleet: Option<FleetOutcome>,
    /// The executor's report.
    pub report: rehearsal::PlanReport,
    /// How the plan fared among people, when there were any.
    pub people: Option<PeopleSummary>,
    /// The mental simulation it was validated in.
    pub world: Arc<World>,
    /// How to drive it again.
    replay: Arc<Replay>,
}

impl PlanOutcome {
    /// The plan driven again with its waits while the robots of `others` drive their
    /// itineraries in the same simulation ([`rehearsal::drive_among`]), on the clock of the
    /// plan's start (now, without a schedule), each stopping where it would come too close to
    /// this robot, as its own shield would ([`sim::OtherRobots::shielded`]; the checks of a
    /// plan among the fleet keep them to their tracks). Blocks: seconds for long plans.
    pub fn rehearse_among(
        &self,
        others: &[traffic::Itinerary],
    ) -> Result<rehearsal::AmongReport, PlanFailure> {
        let (start, holds, draw) = match &self.fleet {
            Some(f) => (
                f.itinerary.start_unix_ms,
                fleet::holds(
                    &f.waits,
                    f.itinerary.start_unix_ms,
                    self.report.waypoints.len(),
                ),
                // Alone on the floor a plan is never driven among a fresh draw.
                f.among.as_ref().map_or(0, |a| a.people_draw),
            ),
            None => (now_ms(), Vec::new(), 0),
        };
        let robots = fleet::simulated_robots(others, start)
            .map_err(PlanFailure::Internal)?
            .shielded();
        self.replay
            .among(&self.world, &self.report, &robots, &holds, draw)
    }
}

/// The roadmap salt ([`rehearsal::PlanOptions::roadmap_salt`]) of `robot`'s plans: each robot
/// of a fleet on its own sampled roadmap. Measured on the plant (`bench fleet --same-seed`, 20
/// robots, 2 people per 100 m², three runs each): on one roadmap the fleet's sum of times was
/// 2.2–2.6 times the robots' alone and its makespan 508–634 s; each on its own, 1.41–1.43 and
/// 317–355 s.
pub fn roadmap_salt(robot: &str) -> u64 {
    grid::hash::fnv1a(robot.as_bytes())
}

/// Now, ms since the Unix epoch.
fn now_ms() -> i64 {
    SystemTime::now()
        .duration_since(SystemTime::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

/// Why no plan was answered. Callers map each to their own error (the HTTP edge to a status).
#[derive(Debug, thiserror::Error)]
pub enum PlanFailure {
    /// A malformed query (a value out of range); the message names the field.
    #[error("{0}")]
    BadRequest(String),
    /// The robot, place or policy does not exist.
    #[error("{0}")]
    NotFound(String),
    /// They exist but make no plan (a place on no floor, a map or policy that cannot be used).
    #[error("{0}")]
    Unprocessable(String),
    /// The knowledge service or the job database cannot answer now.
    #[error("{0}")]
    Unavailable(String),
    /// `roadmap: policy` and the policy-aware roadmap is not built yet, or cannot be read.
    #[error("{0}")]
    RoadmapNotReady(String),
    /// The plan conflicts with other robots' committed plans and no wait within the budget
    /// resolves it.
    #[error("{}", .0.message)]
    FleetConflict(NoFit),
    /// `roadmap: policy` and no edge the policy drives joins a leg.
    #[error(
        "on the policy-aware roadmap: {0} (no edge the policy drives joins them; `options.roadmap`: `auto` falls back to the geometric roadmap)"
    )]
    PolicyRoadmapUnreachable(PlanError),
    /// The executor refused the plan (blocked or unreachable goals, every attempt failed, ...).
    #[error("{0}")]
    Plan(PlanError),
    /// Something broke on our side.
    #[error("{0}")]
    Internal(String),
}

impl From<SourceError> for PlanFailure {
    fn from(e: SourceError) -> Self {
        match e {
            SourceError::NotFound(m) => PlanFailure::NotFound(m),
            SourceError::Unprocessable(m) => PlanFailure::Unprocessable(m),
            SourceError::Unavailable(m) => PlanFailure::Unavailable(m),
        }
    }
}

/// A boxed future for [`RoadmapBuilds`].
pub type BuildFuture<'a> = Pin<Box<dyn Future<Output = Result<String, String>> + Send + 'a>>;

/// Starts the background build of a policy-aware roadmap (the job engine's `roadmap` job).
pub trait RoadmapBuilds: Send + Sync {
    /// Makes sure a build of `key` (for `robot` on `floor`, with `margin`) is under way, once
    /// per key however many plans ask; answers what is building it (a job id).
    fn ensure<'a>(
        &'a self,
        key: &'a PolicyRoadmapKey,
        floor: &'a str,
        robot: &'a str,
        margin: f64,
    ) -> BuildFuture<'a>;
}

/// What passing a robot standing with no plan costs a plan's first route among the fleet,
/// metres (about half a minute of the sample robot's driving): a detour longer than that
/// passes it instead, and the plan waits for that robot's plan (it is usually asking for one
/// at the same time) for [`fleet::REROUTE_AFTER_S`] before it is rehearsed around it.
const PASS_STANDING_M: f64 = 20.0;

/// Whether the route of `report` (its start, then its waypoints) passes within `reach` of `at`.
fn route_passes(report: &rehearsal::PlanReport, at: planning::Point2, reach: f64) -> bool {
    let start = report
        .steps
        .first()
        .map(|p| planning::Point2::new(p.x, p.y));
    let route: Vec<planning::Point2> = start
        .into_iter()
        .chain(report.waypoints.iter().copied())
        .collect();
    route
        .windows(2)
        .any(|w| at.distance_to_segment(w[0], w[1]) < reach)
}

/// Times a plan among the fleet is rehearsed again to keep clear of robots standing in its
/// route that its route did not know of; after that it waits for their plans.
const MAX_REROUTES: usize = 3;

/// Policies kept loaded at most.
const LOADED_POLICIES: usize = 16;
/// Policy-aware roadmaps kept applied in memory at most.
const POLICY_ROADMAPS: usize = 16;

/// A loaded policy and the FNV-1a fingerprint of its weights file (part of a stored roadmap's
/// key).
#[derive(Clone)]
struct LoadedPolicy {
    policy: Arc<learning::Policy>,
    weights: u64,
}

/// Applied policy-aware roadmaps, keyed with whether the unkept directions are in.
type Applied = Mutex<HashMap<(PolicyRoadmapKey, bool), AppliedRoadmap>>;

/// The plan use case over its stores and caches. Cheap to share (`Arc`).
pub struct Planner {
    knowledge: Arc<dyn KnowledgeSource>,
    policies: PolicyStore,
    roadmaps: Arc<RoadmapCache>,
    policy_roadmaps: RoadmapStore,
    builds: Arc<dyn RoadmapBuilds>,
    /// The fleet's traffic schedule, when plans take part in one.
    fleet: Option<Arc<dyn FleetSchedule>>,
    /// Loaded policies by id, with the modification time of the weights they were read from.
    loaded: Mutex<HashMap<String, (SystemTime, LoadedPolicy)>>,
    applied: Arc<Applied>,
    /// One lock per robot and one per floor (keyed `robot <IRI>`, `floor <IRI>`), held from a
    /// fleet snapshot to its commit, the robot's first. Plans validate in parallel, but in this
    /// process they are fitted and committed on a floor one at a time: each then sees the
    /// previous one's commit, and none loses its commit to another (which would fit it and
    /// drive it among the fleet again, as many times as plans committed meanwhile: twenty
    /// plans at once spent most of their seconds so). Other processes still race through the
    /// floor's version.
    fleet_locks: Mutex<HashMap<String, Arc<tokio::sync::Mutex<()>>>>,
    /// The cores the plans' simulation work shares, oldest plan first.
    cpu: Arc<gate::CpuGate>,
    /// The plans waiting for robots standing in their way ([`yielding`]).
    waits: Arc<yielding::Waits>,
}

impl std::fmt::Debug for Planner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Planner")
            .field("policies", &self.policies)
            .finish_non_exhaustive()
    }
}

impl Planner {
    /// A planner taking worlds from `knowledge`, policies from `policies`, geometric roadmaps
    /// from `roadmaps` (shared with roadmap builds in this process), stored policy-aware
    /// roadmaps from `policy_roadmaps`, and asking `builds` for the missing ones.
    pub fn new(
        knowledge: Arc<dyn KnowledgeSource>,
        policies: PolicyStore,
        roadmaps: Arc<RoadmapCache>,
        policy_roadmaps: RoadmapStore,
        builds: Arc<dyn RoadmapBuilds>,
    ) -> Self {
        Self {
            knowledge,
            policies,
            roadmaps,
            policy_roadmaps,
            builds,
            fleet: None,
            loaded: Mutex::new(HashMap::new()),
            applied: Arc::default(),
            fleet_locks: Mutex::new(HashMap::new()),
            waits: Arc::default(),
            cpu: gate::CpuGate::of_this_machine(),
        }
    }

    /// The planner with plans checked against, and committed to, `fleet`.
    #[must_use]
    pub fn with_fleet(mut self, fleet: Arc<dyn FleetSchedule>) -> Self {
        self.fleet = Some(fleet);
        self
    }

    /// The policies it drives with.
    pub fn policies(&self) -> &PolicyStore {
        &self.policies
    }

    /// Geometric roadmaps by floor state.
    pub fn roadmaps(&self) -> &Arc<RoadmapCache> {
        &self.roadmaps
    }

    /// Stored policy-aware roadmaps.
    pub fn policy_roadmaps(&self) -> &RoadmapStore {
        &self.policy_roadmaps
    }

    /// The on-demand database of the floor `place` is on, for `robot`.
    pub async fn floor(&self, place: &str, robot: &str) -> Result<Arc<FloorDatabase>, PlanFailure> {
        Ok(self.knowledge.floor_database(place, robot).await?)
    }

    /// The key plans look a policy-aware roadmap up by: `policy` (loaded to fingerprint its
    /// weights) on `floor` with `margin`.
    pub async fn roadmap_key(
        &self,
        floor: &FloorDatabase,
        policy: &str,
        margin: f64,
    ) -> Result<PolicyRoadmapKey, PlanFailure> {
        let loaded = self.policy(policy).await?;
        Ok(PolicyRoadmapKey::for_plans(
            &floor.version,
            policy,
            loaded.weights,
            margin,
        ))
    }

    /// Checks a query as far as it can be without the floor: the bounds of the request
    /// (goals, attempts, samples, timer, people), the hour, and that a named policy exists.
    pub fn check(&self, query: &PlanQuery) -> Result<(), PlanFailure> {
        check_bounds(query)?;
        if let Some(id) = &query.policy
            && !self.policies.exists(id)
        {
            return Err(PlanFailure::NotFound(format!("no policy `{id}`")));
        }
        Ok(())
    }

    /// Validates the plan of `query` in the mental simulation of its floor and answers it.
    /// `stop` ends the rehearsal early (the caller hung up, the job was cancelled): then the
    /// failure is [`PlanError::Stopped`].
    pub async fn plan(
        &self,
        query: PlanQuery,
        stop: rehearsal::Stop,
    ) -> Result<PlanOutcome, PlanFailure> {
        // Whether a named policy exists is the loader's to say (404), below.
        check_bounds(&query)?;
        // The plan's place in line for the cores: asked earlier, served earlier.
        let ticket = self.cpu.ticket();
        let PlanQuery {
            robot,
            place,
            mut request,
            people,
            policy,
            controller,
            fleet,
        } = query;
        request.stop = stop;
        let db = self.knowledge.floor_database(&place, &robot).await?;
        // Each robot plans on its own sampled roadmap: robots of a fleet asking with the same
        // options (the default seed) would otherwise all take the same lanes and queue in them.
        request.options.roadmap_salt = roadmap_salt(&db.robot);

        // The policy: the one named, else the robot's newest.
        let policy_id = policy.or_else(|| self.policies.newest_for(&db.robot));
        let loaded = match &policy_id {
            Some(id) => Some(self.policy(id).await?),
            None => None,
        };

        // The policy-aware roadmap of this floor state and policy, stored by a background
        // build. When there is none yet, one is asked for (a floor that changed is a new state,
        // so it gets its own), and the plan goes on the geometric roadmap (`auto`) or is
        // refused (`policy`).
        let choice = request.options.roadmap;
        let margin = request.options.safety_margin_m;
        // Looked up whatever the roadmap choice: its controller trial is what `auto` picks from.
        let key = match (&policy_id, &loaded) {
            (Some(id), Some(l)) => Some(PolicyRoadmapKey::for_plans(
                &db.version,
                id,
                l.weights,
                margin,
            )),
            _ => None,
        };
        let stored = key.as_ref().is_some_and(|key| {
            let applied = self.applied.lock().unwrap_or_else(PoisonError::into_inner);
            applied.keys().any(|(k, _)| k == key) || self.policy_roadmaps.contains(key)
        });
        // `geometric` asks for no build (its trial is read when one is stored).
        if let Some(key) = key
            .as_ref()
            .filter(|_| !stored && choice != RoadmapChoice::Geometric)
        {
            let build = self.builds.ensure(key, &db.floor, &db.robot, margin).await;
            if choice == RoadmapChoice::Policy {
                let why = match build {
                    Ok(id) => format!("the `roadmap` job {id} is building it"),
                    Err(e) => format!("no job could be enqueued to build it ({e})"),
                };
                return Err(PlanFailure::RoadmapNotReady(format!(
                    "no policy-aware roadmap of this floor state and policy yet: {why} (every edge driven by the policy); retry when it has finished, or ask for `options.roadmap`: `auto`"
                )));
            }
            if let Err(e) = build {
                tracing::warn!(error = %e, "asking for a policy-aware roadmap build failed");
            }
        }

        // On a floor with a schedule, the robot stands at its start in it from now on (for
        // a request the rehearsal takes), so plans checked meanwhile keep clear of it.
        let entry = match &self.fleet {
            Some(schedule) => {
                let (db2, roadmaps, request2) =
                    (Arc::clone(&db), Arc::clone(&self.roadmaps), request.clone());
                let (radius, fits) = self
                    .blocking(move || {
                        let world = db2.world()?;
                        let key = world.geometry_key();
                        let fits = rehearsal::check_endpoints(&world, &roadmaps, key, &request2);
                        Ok::<_, String>((world.spec().robot.footprint_radius, fits.is_ok()))
                    })
                    .await?
                    .map_err(PlanFailure::Unprocessable)?;
                let mut entry = self
                    .enter_the_fleet(schedule.as_ref(), &db, radius, request.start, &fleet, fits)
                    .await?;
                entry.ticket = ticket;
                Some(entry)
            }
            None => None,
        };
        let rehearsal = Rehearsal {
            db: Arc::clone(&db),
            roadmaps: Arc::clone(&self.roadmaps),
            policy_roadmaps: self.policy_roadmaps.clone(),
            applied: Arc::clone(&self.applied),
            policy: loaded.map(|l| l.policy),
            key: key.filter(|_| stored),
            people,
            controller,
        };
        // Among the fleet, the route keeps clear of the robots standing on the floor with no
        // plan yet (no wait resolves a conflict with them), rehearsed again where one stands in
        // it that was not there before; where no route keeps clear of them, it goes through and
        // waits for their plans.
        let mut avoiding = entry.is_some();
        let mut reroutes = 0;
        // Where robots standing with no plan wait for each other's plans, this one may make way
        // once ([`yielding`]): its route goes first to the place given, and that first leg is
        // committed before the whole plan is fitted.
        let mut making_way: Option<(planning::Point2, Vec<String>)> = None;
        let mut may_make_way = true;
        // The robot's radius once the first leg is in the schedule: from then on, every way out
        // but a fitted plan stands the robot at its start again (it has not moved).
        let mut leg_committed: Option<f64> = None;
        let asked_start = request.start;
        let (report, world, people, pick, replay, fleet) = loop {
            let mut request = request.clone();
            if let Some((at, _)) = &making_way {
                request.goals.insert(0, *at);
            }
            let mut standing_robots: Vec<String> = Vec::new();
            if let (Some(schedule), Some(entry)) = (&self.fleet, &entry) {
                let (standing, moving) = self.others_on_the_floor(schedule.as_ref(), &db).await?;
                for o in standing.into_iter().filter(|_| avoiding) {
                    if let Some(p) = o.trajectory.first() {
                        let at = planning::Point2::new(p.x, p.y);
                        request.options.standing.push((at, o.radius_m));
                        standing_robots.push(o.robot);
                    }
                }
                // The first route passes a standing robot rather than go far around it (it is
                // likely asking for its plan now); once one was in its way, it keeps clear.
                // Making way, it keeps clear of them.
                if reroutes == 0 && making_way.is_none() {
                    request.options.standing_pass_m = PASS_STANDING_M;
                }
                request.options.reserved = entry.reserved(&moving).map(Arc::new);
            }
            let with_standing = !request.options.standing.is_empty();
            let standing_at = request.options.standing.clone();
            let margin = request.options.safety_margin_m;
            let run = rehearsal.clone();
            let rehearsed = self
                .simulating(ticket, None, move || run.run(request))
                .await;
            if let (Some(radius), false) = (leg_committed, matches!(rehearsed, Ok(Ok(_)))) {
                leg_committed = None;
                if let (Some(schedule), Some(entry)) = (&self.fleet, &entry) {
                    self.stand_again(schedule.as_ref(), &db, radius, asked_start, entry)
                        .await;
                }
            }
            let (report, world, people, pick, replay) = match rehearsed? {
                Err(PlanFailure::Plan(PlanError::Unreachable { .. })) if with_standing => {
                    avoiding = false;
                    continue;
                }
                // The place to make way at did not validate: the plan as asked, waiting.
                Err(_) if making_way.is_some() => {
                    making_way = None;
                    continue;
                }
                r => r?,
            };
            let (Some(schedule), Some(entry)) = (&self.fleet, &entry) else {
                break (report, world, people, pick, replay, None);
            };
            // The standing robots the route keeps clear of (it may pass some).
            let radius = world.spec().robot.footprint_radius;
            let avoided: Vec<String> = standing_robots
                .into_iter()
                .zip(&standing_at)
                .filter(|(_, (at, r))| !route_passes(&report, *at, r + radius + margin))
                .map(|(name, _)| name)
                .collect();
            let avoided = (avoiding && reroutes < MAX_REROUTES).then_some(avoided.as_slice());
            // Committed once: a route rehearsed again after it keeps the same first goal, and
            // the fit below is checked against that leg.
            if making_way.is_some() && leg_committed.is_none() {
                let committed = self
                    .commit_first_leg(schedule.as_ref(), &db, radius, &report, entry)
                    .await?;
                leg_committed = committed.then_some(radius);
                if !committed {
                    making_way = None;
                    continue;
                }
            }
            let among = self
                .among_the_fleet(
                    schedule.as_ref(),
                    &db,
                    (&world, &report, &replay),
                    entry,
                    avoided,
                    may_make_way.then_some(margin),
                )
                .await;
            // Refused after its first leg was committed: the robot has not moved.
            if among.is_err() && leg_committed.is_some() {
                self.stand_again(schedule.as_ref(), &db, radius, asked_start, entry)
                    .await;
            }
            match among? {
                among::Among::Fitted(o) => break (report, world, people, pick, replay, Some(*o)),
                among::Among::Reroute => reroutes += 1,
                among::Among::MakeWay(at, robots) => {
                    making_way = Some((at, robots));
                    may_make_way = false;
                }
            }
        };
        let note = note(policy_id.is_some(), &pick, &report);
        let note = match &making_way {
            Some((at, robots)) => Some(format!(
                "{}made way at ({:.2}, {:.2}), its first goal, for {}: they stood in each other's way with no plan",
                note.map(|n| format!("{n}; ")).unwrap_or_default(),
                at.x,
                at.y,
                robots.join(", ")
            )),
            None => note,
        };
        Ok(PlanOutcome {
            fleet,
            robot: db.robot.clone(),
            floor: db.floor.clone(),
            policy: policy_id,
            controller: pick,
            note,
            report,
            people,
            world,
            replay,
        })
    }

    /// Runs the blocking `work` on the blocking pool.
    async fn blocking<T: Send + 'static>(
        &self,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, PlanFailure> {
        tokio::task::spawn_blocking(work)
            .await
            .map_err(|e| PlanFailure::Internal(format!("plan task failed: {e}")))
    }

    /// Runs the blocking simulation `work` of the plan holding `ticket` on the blocking pool
    /// once it has a core ([`gate::CpuGate`]), or with `held`, the core its caller took.
    async fn simulating<T: Send + 'static>(
        &self,
        ticket: u64,
        held: Option<gate::Permit>,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, PlanFailure> {
        let core = match held {
            Some(p) => p,
            None => self.cpu.acquire(ticket).await,
        };
        self.blocking(move || {
            let _core = core;
            work()
        })
        .await
    }

    /// The lock serialising the fleet commits of `key` (a robot or a floor) in this process.
    fn fleet_lock(&self, key: String) -> Arc<tokio::sync::Mutex<()>> {
        let mut locks = self
            .fleet_locks
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        // Locks nobody holds or waits for go, so the map stays as large as the robots planning.
        locks.retain(|_, l| Arc::strong_count(l) > 1);
        Arc::clone(locks.entry(key).or_default())
    }

    /// The policy `id`, loaded again only when its weights file changed.
    async fn policy(&self, id: &str) -> Result<LoadedPolicy, PlanFailure> {
        let not_found = || PlanFailure::NotFound(format!("no policy `{id}`"));
        if !self.policies.exists(id) {
            return Err(not_found());
        }
        let dir = self.policies.path(id).ok_or_else(not_found)?;
        let modified = std::fs::metadata(dir.join(policies::WEIGHTS))
            .and_then(|m| m.modified())
            .ok();
        let cached = self
            .loaded
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get(id)
            .filter(|(at, _)| Some(*at) == modified)
            .map(|(_, p)| p.clone());
        if let Some(p) = cached {
            return Ok(p);
        }
        let loaded = tokio::task::spawn_blocking(move || {
            let weights = std::fs::read(dir.join(policies::WEIGHTS))
                .map(|b| grid::hash::fnv1a(&b))
                .map_err(|e| e.to_string())?;
            learning::Policy::load(&dir)
                .map(|p| LoadedPolicy {
                    policy: Arc::new(p),
                    weights,
                })
                .map_err(|e| e.to_string())
        })
        .await
        .map_err(|e| PlanFailure::Internal(format!("policy loader failed: {e}")))?
        .map_err(|e| PlanFailure::Unprocessable(format!("policy `{id}` cannot be loaded: {e}")))?;
        let mut policies = self.loaded.lock().unwrap_or_else(PoisonError::into_inner);
        if policies.len() >= LOADED_POLICIES {
            policies.clear();
        }
        if let Some(at) = modified {
            policies.insert(id.to_owned(), (at, loaded.clone()));
        }
        Ok(loaded)
    }
}

/// The bounds of a query that need no store: the hour, and the request's goals, attempts,
/// samples, timer and people.
fn check_bounds(query: &PlanQuery) -> Result<(), PlanFailure> {
    if let PlanPeople::Expected { hour: Some(h) } = query.people
        && h > 23
    {
        return Err(PlanFailure::BadRequest(format!(
            "`options.people_hour` is an hour of day in [0, 23], got {h}"
        )));
    }
    query.fleet.check().map_err(PlanFailure::BadRequest)?;
    rehearsal::check_request(&query.request).map_err(PlanFailure::Plan)
}

/// What the blocking part of a plan needs.
#[derive(Clone)]
struct Rehearsal {
    db: Arc<FloorDatabase>,
    roadmaps: Arc<RoadmapCache>,
    policy_roadmaps: RoadmapStore,
    applied: Arc<Applied>,
    policy: Option<Arc<learning::Policy>>,
    /// The stored policy-aware roadmap to plan on, when there is one.
    key: Option<PolicyRoadmapKey>,
    people: PlanPeople,
    /// The controller asked for; `None`: `auto`.
    controller: Option<ControllerChoice>,
}

type Rehearsed = (
    rehearsal::PlanReport,
    Arc<World>,
    Option<PeopleSummary>,
    ControllerPick,
    Arc<Replay>,
);

impl Rehearsal {
    /// The world, the people, the roadmap, and the executor. Blocks.
    fn run(self, mut request: PlanRequest) -> Result<Rehearsed, PlanFailure> {
        let _running = Rehearsing::start();
        let world = self.db.world().map_err(PlanFailure::Unprocessable)?;
        let source = match self.people {
            PlanPeople::Expected { hour } => {
                request.options.people = knowledge_people(&world, hour);
                PeopleSource::Knowledge
            }
            PlanPeople::AsGiven => PeopleSource::Density,
        };
        let crowd = request.options.people.clone();
        // The roadmap cache's key: the floor's geometry and the robot's size, so robots of
        // one model share configuration spaces and roadmaps.
        let version = world.geometry_key();
        let choice = request.options.roadmap;
        let applied = self.policy_roadmap(&world, choice)?;
        let pick = self.pick(applied.as_ref().and_then(|a| a.trial.as_deref()))?;
        let mut primary = pick
            .choice
            .build(self.policy.as_ref(), request.options.seed)
            .ok_or_else(|| PlanFailure::Internal("the picked controller needs a policy".into()))?;
        // The policy-aware roadmap is the policy's: the classical controllers plan on the
        // geometric one.
        let policy_roadmap = applied
            .filter(|_| pick.choice.needs_policy() && choice != RoadmapChoice::Geometric)
            .map(|a| a.roadmap);
        if choice == RoadmapChoice::Policy && pick.choice.needs_policy() && policy_roadmap.is_none()
        {
            return Err(PlanFailure::RoadmapNotReady(
                "the stored policy-aware roadmap of this floor state and policy cannot be read; ask for `options.roadmap`: `auto`".to_owned(),
            ));
        }
        // Robots carry the classical follower too: a leg no attempt validates with the picked
        // controller is tried with it (behind the shield among people).
        let mut follower = (!matches!(
            pick.choice,
            ControllerChoice::Follower | ControllerChoice::ShieldedFollower
        ))
        .then(|| rehearsal::follower_for(&request.options));
        let report = rehearsal::validate_with_fallback(
            &world,
            &self.roadmaps,
            version,
            &request,
            &mut *primary,
            follower
                .as_deref_mut()
                .map(|f| f as &mut dyn rehearsal::Controller),
            policy_roadmap.as_ref(),
        )
        .map_err(|e| match e {
            PlanError::Unreachable { .. }
                if choice == RoadmapChoice::Policy && pick.choice.needs_policy() =>
            {
                PlanFailure::PolicyRoadmapUnreachable(e)
            }
            other => PlanFailure::Plan(other),
        })?;
        let people = crowd.any().then(|| {
            people_summary(
                source,
                crowd.count_for(world.free_region_area_m2()),
                &report,
            )
        });
        let replay = Arc::new(Replay {
            request,
            policy: self.policy.clone(),
            choice: pick.choice,
        });
        Ok((report, world, people, pick, replay))
    }

    /// The controller: the one asked for, else `auto`'s pick from the floor state's trial.
    fn pick(&self, trial: Option<&ControllerTrial>) -> Result<ControllerPick, PlanFailure> {
        let has_policy = self.policy.is_some();
        if let Some(choice) = self.controller {
            if choice.needs_policy() && !has_policy {
                return Err(PlanFailure::Unprocessable(format!(
                    "`options.controller`: `{}` drives a trained policy, and this robot has none yet; ask for `auto`, `rpp`, `mppi` or `follower`",
                    choice.as_str()
                )));
            }
            return Ok(ControllerPick {
                choice,
                why: "asked for in `options.controller`".to_owned(),
            });
        }
        if !has_policy {
            return Ok(controllers::unmeasured(
                "no trained policy for this robot yet",
            ));
        }
        Ok(match trial {
            Some(t) => t.pick(|_| true).unwrap_or_else(|| {
                controllers::unmeasured("the floor state's trial drove no controller")
            }),
            None if self.key.is_some() => controllers::unmeasured(
                "the policy-aware roadmap of this floor state was stored without a trial of the controllers",
            ),
            None => controllers::unmeasured(
                "the policy has not been measured against the classical controllers on this floor state yet (the `roadmap` job builds its roadmap and drives the trial)",
            ),
        })
    }

    /// The stored policy-aware roadmap applied to the floor's geometric roadmap: `auto` plans
    /// on every measured direction (the unkept ones only where the kept ones join no route),
    /// `policy` on the kept ones alone.
    fn policy_roadmap(
        &self,
        world: &Arc<World>,
        choice: RoadmapChoice,
    ) -> Result<Option<AppliedRoadmap>, PlanFailure> {
        let Some(key) = &self.key else {
            return Ok(None);
        };
        let key = (key.clone(), choice != RoadmapChoice::Policy);
        let cached = self
            .applied
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get(&key)
            .cloned();
        if cached.is_some() {
            return Ok(cached);
        }
        let loaded = roadmaps::load_policy_roadmap(
            &self.policy_roadmaps,
            &key.0,
            world,
            &self.roadmaps,
            key.1,
        )
        .map_err(|m| PlanFailure::Internal(format!("the stored policy-aware roadmap: {m}")))?;
        if let Some(r) = &loaded {
            let mut applied = self.applied.lock().unwrap_or_else(PoisonError::into_inner);
            if applied.len() >= POLICY_ROADMAPS {
                applied.clear();
            }
            applied.insert(key, r.clone());
        }
        Ok(loaded)
    }
}

/// Why a classical controller validated a plan or some of its legs, when one did.
fn note(had_policy: bool, pick: &ControllerPick, report: &rehearsal::PlanReport) -> Option<String> {
    let fallback_legs = report
        .legs
        .iter()
        .filter(|l| l.controller != report.controller)
        .count();
    let name = pick.choice.as_str();
    if !had_policy {
        Some(format!(
            "no trained policy for this robot yet: validated with the classical path follower `{name}`"
        ))
    } else if fallback_legs > 0 {
        Some(format!(
            "{} of {} legs validated with the classical path follower: no attempt with `{name}` validated them (see `legs`)",
            fallback_legs,
            report.legs.len()
        ))
    } else if !pick.choice.needs_policy() {
        Some(format!(
            "validated with the classical controller `{name}` rather than the policy: {}",
            pick.why
        ))
    } else {
        None
    }
}

/// The people the floor's knowledge expects (its places' expected numbers, summed, at `hour`
/// where a place has one for it; none where it says nothing), walking its routes and
/// attractors.
pub fn knowledge_people(world: &World, hour: Option<u8>) -> sim::PeopleConfig {
    let expected = world.spec().people.expected_at(hour);
    if !(expected.is_finite() && expected >= 0.5) {
        return sim::PeopleConfig::default();
    }
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a rounded positive count, capped"
    )]
    let count = (expected.round() as usize).min(sim::crowd::MAX_PEOPLE);
    sim::PeopleConfig {
        count: Some(count),
        ..sim::PeopleConfig::default()
    }
}

/// How a plan fared among `people` people, over its attempts.
fn people_summary(
    source: PeopleSource,
    people: usize,
    report: &rehearsal::PlanReport,
) -> PeopleSummary {
    let attempts = &report.attempts;
    let reached = |a: &&rehearsal::AttemptReport| a.outcome == rehearsal::AttemptOutcome::Reached;
    let hit = |a: &&rehearsal::AttemptReport| rehearsal::hit_person(&a.reason);
    PeopleSummary {
        source,
        people,
        min_person_clearance_m: attempts
            .iter()
            .filter(reached)
            .filter_map(|a| a.min_person_clearance_m)
            .reduce(f64::min),
        attempts: attempts.len(),
        attempts_reached: attempts.iter().filter(reached).count(),
        attempts_hit_person: attempts.iter().filter(hit).count(),
        attempts_near_miss: attempts
            .iter()
            .filter(|a| !hit(a))
            .filter(|a| {
                a.min_person_clearance_m
                    .is_some_and(|c| c < rehearsal::NEAR_MISS_M)
            })
            .count(),
        draws: report.people_draws.clone(),
    }
}

/// Counts a rehearsal in the `plan_rehearsals_running` gauge while it lives: what `/metrics`
/// shows of plans still computing (a stopped request's rehearsal leaves within milliseconds).
struct Rehearsing;

impl Rehearsing {
    fn start() -> Self {
        metrics::gauge!("plan_rehearsals_running").increment(1.0);
        Self
    }
}

impl Drop for Rehearsing {
    fn drop(&mut self) {
        metrics::gauge!("plan_rehearsals_running").decrement(1.0);
    }
}
