//! The plan use case, with no HTTP in it: [`Planner::plan`] decides everything a plan decides —
//! the floor's mental simulation (through a [`KnowledgeSource`]), which policy drives (the one
//! named, else the robot's newest), which roadmap (the policy-aware one of this floor state and
//! policy when it is stored, else the geometric one, with a background build asked for), which
//! people walk about (the knowledge's expected people at an hour, or a density), the follower
//! as fallback per leg, the plan's place among the fleet, and the note that says why — and
//! calls the `rehearsal` executor.
//!
//! `POST /v1/plan`, the `validate` job kind and the CLI call it alike: they translate their
//! input into a [`PlanQuery`] and the [`PlanOutcome`] back, and decide nothing.
//!
//! - [`query`]: what a plan is asked and answers; [`error`]: why none was answered;
//! - `plan`: [`Planner::plan`], a search over passes (rehearse, fit among the fleet);
//! - `rehearse`: the blocking part (world, people, roadmap, controller, executor);
//! - [`controllers`]: which controller validates a plan (`auto`: RPP unless the floor state's
//!   trial measured another doing measurably better than RPP);
//! - [`fleet`]: fleet coordination, the plan among the other robots' committed plans (fit,
//!   waits, commits, robots standing until planned, making way) and its port
//!   [`FleetSchedule`];
//! - [`floor`]: the port [`KnowledgeSource`] and the world made from a floor's on-demand
//!   database; [`builds`]: the port [`RoadmapBuilds`];
//! - [`policies`], `loaded`: exported policies on disk, and those loaded for plans;
//! - [`roadmaps`]: stored policy-aware roadmaps;
//! - `gate`: the cores plans share, oldest plan first.

pub mod builds;
pub mod controllers;
pub mod error;
pub mod fleet;
pub mod floor;
mod gate;
mod loaded;
mod note;
mod plan;
pub mod policies;
pub mod query;
mod rehearse;
mod replay;
pub mod roadmaps;

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::SystemTime;

use rehearsal::RoadmapCache;

pub use builds::{BuildFuture, RoadmapBuilds};
pub use controllers::{ControllerPick, ControllerTrial};
pub use error::PlanFailure;
pub use error::{
    BoxError, InvalidField, Missing, PortError, RoadmapPending, Unavailable, Unusable,
};
pub use fleet::improve::{Improvement, Totals};
pub use fleet::{FleetOptions, FleetOutcome, FleetSchedule, NoFit};
pub use floor::{FloorDatabase, KnowledgeSource, SourceError, SourceFuture, WorldError};
pub use policies::{HeldOutEval, PolicyEntry, PolicyStore, PolicySummary};
pub use query::{PeopleSource, PeopleSummary, PlanOutcome, PlanPeople, PlanQuery, roadmap_salt};
pub use rehearse::knowledge_people;
pub use roadmaps::{AppliedRoadmap, PolicyRoadmapKey, RoadmapStore, StoredRoadmap};

use loaded::LoadedPolicy;
use rehearse::Applied;

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
    /// The plans waiting for robots standing in their way ([`fleet::yielding`]).
    waits: Arc<fleet::yielding::Waits>,
    /// The committed plans this process planned, which the improver may revise
    /// ([`fleet::improve`]).
    revisables: fleet::improve::Revisables,
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
            revisables: fleet::improve::Revisables::default(),
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

    /// Runs the blocking `work` on the blocking pool.
    async fn blocking<T: Send + 'static>(
        &self,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, PlanFailure> {
        tokio::task::spawn_blocking(work)
            .await
            .map_err(|e| PlanFailure::Internal {
                what: "the plan task failed".into(),
                source: Some(e.into()),
            })
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
}
