//! The blocking part of a plan: the world, the people, the roadmap and the controller, and
//! the executor's validation with the follower as fallback per leg ([`Rehearsal::run`]).

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};

use rehearsal::{ControllerChoice, PlanError, PlanRequest, RoadmapCache, RoadmapChoice};
use sim::World;

use crate::controllers::{self, ControllerPick, ControllerTrial};
use crate::floor::FloorDatabase;
use crate::query::{PeopleSource, PeopleSummary, PlanPeople};
use crate::replay::Replay;
use crate::roadmaps::{self, AppliedRoadmap, PolicyRoadmapKey, RoadmapStore};
use crate::{PlanFailure, RoadmapPending, Unusable};

/// Policy-aware roadmaps kept applied in memory at most.
const POLICY_ROADMAPS: usize = 16;

/// Applied policy-aware roadmaps, keyed with whether the unkept directions are in.
pub(crate) type Applied = Mutex<HashMap<(PolicyRoadmapKey, bool), AppliedRoadmap>>;

/// What the blocking part of a plan needs.
#[derive(Clone)]
pub(crate) struct Rehearsal {
    pub(crate) db: Arc<FloorDatabase>,
    pub(crate) roadmaps: Arc<RoadmapCache>,
    pub(crate) policy_roadmaps: RoadmapStore,
    pub(crate) applied: Arc<Applied>,
    pub(crate) policy: Option<Arc<learning::Policy>>,
    /// The stored policy-aware roadmap to plan on, when there is one.
    pub(crate) key: Option<PolicyRoadmapKey>,
    pub(crate) people: PlanPeople,
    /// The controller asked for; `None`: `auto`.
    pub(crate) controller: Option<ControllerChoice>,
}

/// A plan validated in the mental simulation, before it meets the fleet.
pub(crate) struct Rehearsed {
    /// The executor's report.
    pub(crate) report: rehearsal::PlanReport,
    /// The world it was validated in.
    pub(crate) world: Arc<World>,
    /// How it fared among people, when there were any.
    pub(crate) people: Option<PeopleSummary>,
    /// The controller that validated it, and why.
    pub(crate) pick: ControllerPick,
    /// How to drive it again.
    pub(crate) replay: Arc<Replay>,
}

impl Rehearsal {
    /// The world, the people, the roadmap, and the executor. Blocks.
    pub(crate) fn run(self, mut request: PlanRequest) -> Result<Rehearsed, PlanFailure> {
        let _running = Rehearsing::start();
        let world = self.db.world()?;
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
            .ok_or_else(|| PlanFailure::internal("the picked controller needs a policy"))?;
        // The policy-aware roadmap is the policy's: the classical controllers plan on the
        // geometric one.
        let policy_roadmap = applied
            .filter(|_| pick.choice.needs_policy() && choice != RoadmapChoice::Geometric)
            .map(|a| a.roadmap);
        if choice == RoadmapChoice::Policy && pick.choice.needs_policy() && policy_roadmap.is_none()
        {
            return Err(PlanFailure::RoadmapNotReady(RoadmapPending::Unreadable));
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
        Ok(Rehearsed {
            report,
            world,
            people,
            pick,
            replay,
        })
    }

    /// The controller: the one asked for, else `auto`'s pick from the floor state's trial.
    fn pick(&self, trial: Option<&ControllerTrial>) -> Result<ControllerPick, PlanFailure> {
        let has_policy = self.policy.is_some();
        if let Some(choice) = self.controller {
            if choice.needs_policy() && !has_policy {
                return Err(PlanFailure::Unprocessable(Unusable::NoPolicyFor {
                    controller: choice.as_str(),
                }));
            }
            return Ok(ControllerPick {
                choice,
                compared_with: None,
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
        .map_err(|e| PlanFailure::Internal {
            what: e.to_string(),
            source: Some(e.into()),
        })?;
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
