//! [`Planner::plan`]: a plan from its query to its outcome. It picks the policy and the
//! roadmap, enters the floor's traffic schedule, and then searches for the plan's way: each
//! [`Pass`] rehearses the plan in the mental simulation and fits it among the fleet, and the
//! [`Search`] between passes says what the next one tries (keeping clear of robots standing
//! with no plan or going through them, making way first).

use std::sync::{Arc, PoisonError};

use prm::Point2;
use rehearsal::{PlanError, PlanRequest, RoadmapChoice};

use crate::fleet::joining::{Among, FleetEntry};
use crate::fleet::{FleetOptions, FleetOutcome};
use crate::floor::FloorDatabase;
use crate::loaded::LoadedPolicy;
use crate::query::{PlanOutcome, PlanPeople, PlanQuery, roadmap_salt};
use crate::rehearse::{Rehearsal, Rehearsed};
use crate::roadmaps::PolicyRoadmapKey;
use crate::{PlanFailure, Planner, RoadmapPending, note};

/// What passing a robot standing with no plan costs a plan's first route among the fleet,
/// metres (about half a minute of the sample robot's driving): a detour longer than that
/// passes it instead, and the plan waits for that robot's plan (it is usually asking for one
/// at the same time) for [`crate::fleet::REROUTE_AFTER_S`] before it is rehearsed around it.
const PASS_STANDING_M: f64 = 20.0;

/// Times a plan among the fleet is rehearsed again to keep clear of robots standing in its
/// route that its route did not know of; after that it waits for their plans.
const MAX_REROUTES: usize = 3;

/// Where a robot makes way before its plan ([`crate::fleet::yielding`]): its first goal, for
/// the robots it stood in the way of.
#[derive(Debug, Clone)]
struct MakingWay {
    at: Point2,
    for_robots: Vec<String>,
}

/// The first leg of a plan that makes way, in the floor's schedule.
#[derive(Debug, Clone, Copy, PartialEq)]
enum FirstLeg {
    /// Not in the schedule (the plan makes no way, or its first leg was not committed yet).
    NotCommitted,
    /// Committed for the robot of this radius: from then on, every way out but a fitted plan
    /// stands the robot at its start again (it has not moved).
    Committed { radius_m: f64 },
}

/// Where a plan's search for its way through the floor stands between passes.
#[derive(Debug, Clone)]
struct Search {
    /// The route keeps clear of the robots standing on the floor with no plan yet (no wait
    /// resolves a conflict with them); where no route does, it goes through and waits for
    /// their plans.
    avoiding: bool,
    /// Times rehearsed again because a robot stood in the route that it did not know of.
    reroutes: usize,
    /// Where the robot makes way first, when it does.
    making_way: Option<MakingWay>,
    /// A plan makes way once at most.
    may_make_way: bool,
    first_leg: FirstLeg,
}

impl Search {
    fn new(among_a_fleet: bool) -> Self {
        Self {
            avoiding: among_a_fleet,
            reroutes: 0,
            making_way: None,
            may_make_way: true,
            first_leg: FirstLeg::NotCommitted,
        }
    }
}

/// What one pass of the search came to.
enum Pass {
    /// The plan validated, and fitted among the fleet where there is one.
    Done(Box<Validated>),
    /// Rehearse again, from the search's new state.
    Again,
}

/// A validated plan and its place in the floor's schedule.
struct Validated {
    rehearsed: Rehearsed,
    fleet: Option<FleetOutcome>,
}

/// What every pass of one plan shares.
struct Mission<'a> {
    db: &'a Arc<FloorDatabase>,
    /// The request as asked (its start is where the robot stands).
    request: &'a PlanRequest,
    rehearsal: &'a Rehearsal,
    /// The plan's entry in the floor's schedule, when there is one.
    entry: Option<&'a FleetEntry>,
    /// The plan's place in line for the cores.
    ticket: u64,
}

impl Planner {
    /// Checks a query as far as it can be without the floor: the bounds of the request
    /// (goals, attempts, samples, timer, people), the hour, and that a named policy exists.
    pub fn check(&self, query: &PlanQuery) -> Result<(), PlanFailure> {
        check_bounds(query)?;
        if let Some(id) = &query.policy
            && !self.policies.exists(id)
        {
            return Err(PlanFailure::NotFound(crate::Missing::Policy(id.clone())));
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
        let fleet_options = fleet;
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
        let policy = policy_id.as_deref().zip(loaded.as_ref());
        let key = self.stored_policy_roadmap(&db, policy, &request).await?;
        let entry = self.enter(&db, &request, &fleet, ticket).await?;
        let rehearsal = Rehearsal {
            db: Arc::clone(&db),
            roadmaps: Arc::clone(&self.roadmaps),
            policy_roadmaps: self.policy_roadmaps.clone(),
            applied: Arc::clone(&self.applied),
            policy: loaded.map(|l| l.policy),
            key,
            people,
            controller,
        };
        let mission = Mission {
            db: &db,
            request: &request,
            rehearsal: &rehearsal,
            entry: entry.as_ref(),
            ticket,
        };
        let mut search = Search::new(entry.is_some());
        let Validated { rehearsed, fleet } = loop {
            match self.pass(&mission, &mut search).await? {
                Pass::Done(validated) => break *validated,
                Pass::Again => {}
            }
        };
        let note = note::note(policy_id.is_some(), &rehearsed.pick, &rehearsed.report);
        let outcome = PlanOutcome {
            fleet,
            robot: db.robot.clone(),
            floor: db.floor.clone(),
            policy: policy_id,
            controller: rehearsed.pick,
            note: with_making_way(note, search.making_way.as_ref()),
            report: rehearsed.report,
            people: rehearsed.people,
            world: rehearsed.world,
            replay: rehearsed.replay,
        };
        self.revisables.register(&outcome, fleet_options);
        Ok(outcome)
    }

    /// The key of the policy-aware roadmap of this floor state and `policy` when it is stored
    /// (in memory or on disk) by a background build. When there is none yet, one is asked
    /// for (a floor that changed is a new state, so it gets its own), and the plan goes on
    /// the geometric roadmap (`auto`) or is refused (`policy`).
    async fn stored_policy_roadmap(
        &self,
        db: &FloorDatabase,
        policy: Option<(&str, &LoadedPolicy)>,
        request: &PlanRequest,
    ) -> Result<Option<PolicyRoadmapKey>, PlanFailure> {
        let choice = request.options.roadmap;
        let margin = request.options.safety_margin_m;
        // Looked up whatever the roadmap choice: its controller trial is what `auto` picks from.
        let Some(key) =
            policy.map(|(id, l)| PolicyRoadmapKey::for_plans(&db.version, id, l.weights, margin))
        else {
            return Ok(None);
        };
        let stored = {
            let applied = self.applied.lock().unwrap_or_else(PoisonError::into_inner);
            applied.keys().any(|(k, _)| *k == key) || self.policy_roadmaps.contains(&key)
        };
        // `geometric` asks for no build (its trial is read when one is stored).
        if !stored && choice != RoadmapChoice::Geometric {
            let build = self.builds.ensure(&key, &db.floor, &db.robot, margin).await;
            if choice == RoadmapChoice::Policy {
                return Err(PlanFailure::RoadmapNotReady(match build {
                    Ok(job) => RoadmapPending::Building { job },
                    Err(e) => RoadmapPending::NotEnqueued(e),
                }));
            }
            if let Err(e) = build {
                tracing::warn!(error = %e, "asking for a policy-aware roadmap build failed");
            }
        }
        Ok(stored.then_some(key))
    }

    /// On a floor with a schedule, the robot stands at its start in it from now on (for a
    /// request the rehearsal takes), so plans checked meanwhile keep clear of it.
    async fn enter(
        &self,
        db: &Arc<FloorDatabase>,
        request: &PlanRequest,
        fleet: &FleetOptions,
        ticket: u64,
    ) -> Result<Option<FleetEntry>, PlanFailure> {
        let Some(schedule) = &self.fleet else {
            return Ok(None);
        };
        let (db2, roadmaps, request2) =
            (Arc::clone(db), Arc::clone(&self.roadmaps), request.clone());
        let (radius, fits) = self
            .blocking(move || {
                let world = db2.world()?;
                let key = world.geometry_key();
                let fits = rehearsal::check_endpoints(&world, &roadmaps, key, &request2);
                Ok::<_, crate::WorldError>((world.spec().robot.footprint_radius, fits.is_ok()))
            })
            .await??;
        let mut entry = self
            .enter_the_fleet(schedule.as_ref(), db, radius, request.start, fleet, fits)
            .await?;
        entry.ticket = ticket;
        Ok(Some(entry))
    }

    /// One pass: the plan rehearsed as the search now stands, then fitted among the fleet.
    async fn pass(&self, m: &Mission<'_>, s: &mut Search) -> Result<Pass, PlanFailure> {
        let mut request = m.request.clone();
        if let Some(w) = &s.making_way {
            request.goals.insert(0, w.at);
        }
        let standing_robots = self.keep_clear(m, s, &mut request).await?;
        let with_standing = !request.options.standing.is_empty();
        let standing_at = request.options.standing.clone();
        let margin = request.options.safety_margin_m;
        let run = m.rehearsal.clone();
        let rehearsed = self
            .simulating(m.ticket, None, move || run.run(request))
            .await;
        if let (FirstLeg::Committed { radius_m }, false) =
            (s.first_leg, matches!(rehearsed, Ok(Ok(_))))
        {
            s.first_leg = FirstLeg::NotCommitted;
            self.stand_again_if_in_fleet(m, radius_m).await;
        }
        let rehearsed = match rehearsed? {
            Err(PlanFailure::Plan(PlanError::Unreachable { .. })) if with_standing => {
                s.avoiding = false;
                return Ok(Pass::Again);
            }
            // The place to make way at did not validate: the plan as asked, waiting.
            Err(_) if s.making_way.is_some() => {
                s.making_way = None;
                return Ok(Pass::Again);
            }
            r => r?,
        };
        let (Some(schedule), Some(entry)) = (&self.fleet, m.entry) else {
            return Ok(Pass::Done(Box::new(Validated {
                rehearsed,
                fleet: None,
            })));
        };
        // The standing robots the route keeps clear of (it may pass some).
        let radius = rehearsed.world.spec().robot.footprint_radius;
        let avoided: Vec<String> = standing_robots
            .into_iter()
            .zip(&standing_at)
            .filter(|(_, (at, r))| !route_passes(&rehearsed.report, *at, r + radius + margin))
            .map(|(name, _)| name)
            .collect();
        let avoided = (s.avoiding && s.reroutes < MAX_REROUTES).then_some(avoided.as_slice());
        // Committed once: a route rehearsed again after it keeps the same first goal, and the
        // fit below is checked against that leg.
        if s.making_way.is_some() && s.first_leg == FirstLeg::NotCommitted {
            let committed = self
                .commit_first_leg(schedule.as_ref(), m.db, radius, &rehearsed.report, entry)
                .await?;
            if !committed {
                s.making_way = None;
                return Ok(Pass::Again);
            }
            s.first_leg = FirstLeg::Committed { radius_m: radius };
        }
        let among = self
            .among_the_fleet(
                schedule.as_ref(),
                m.db,
                (&rehearsed.world, &rehearsed.report, &rehearsed.replay),
                entry,
                avoided,
                s.may_make_way.then_some(margin),
            )
            .await;
        // Refused after its first leg was committed: the robot has not moved.
        if among.is_err() && s.first_leg != FirstLeg::NotCommitted {
            self.stand_again_if_in_fleet(m, radius).await;
        }
        Ok(match among? {
            Among::Fitted(o) => Pass::Done(Box::new(Validated {
                rehearsed,
                fleet: Some(*o),
            })),
            Among::Reroute => {
                s.reroutes += 1;
                Pass::Again
            }
            Among::MakeWay(at, for_robots) => {
                s.making_way = Some(MakingWay { at, for_robots });
                s.may_make_way = false;
                Pass::Again
            }
        })
    }

    /// Among the fleet: the robots standing with no plan that `request`'s route keeps clear
    /// of (while the search avoids them), and the other robots' reserved tracks. Answers the
    /// standing robots' names, in the order of `request.options.standing`.
    async fn keep_clear(
        &self,
        m: &Mission<'_>,
        s: &Search,
        request: &mut PlanRequest,
    ) -> Result<Vec<String>, PlanFailure> {
        let mut standing_robots = Vec::new();
        let (Some(schedule), Some(entry)) = (&self.fleet, m.entry) else {
            return Ok(standing_robots);
        };
        let (standing, moving) = self.others_on_the_floor(schedule.as_ref(), m.db).await?;
        for o in standing.into_iter().filter(|_| s.avoiding) {
            if let Some(p) = o.trajectory.first() {
                let at = Point2::new(p.x, p.y);
                request.options.standing.push((at, o.radius_m));
                standing_robots.push(o.robot);
            }
        }
        // The first route passes a standing robot rather than go far around it (it is likely
        // asking for its plan now); once one was in its way, it keeps clear. Making way, it
        // keeps clear of them.
        if s.reroutes == 0 && s.making_way.is_none() {
            request.options.standing_pass_m = PASS_STANDING_M;
        }
        request.options.reserved = entry.reserved(&moving).map(Arc::new);
        Ok(standing_robots)
    }

    /// Stands the robot of a plan whose first leg was committed at its start again.
    async fn stand_again_if_in_fleet(&self, m: &Mission<'_>, radius_m: f64) {
        if let (Some(schedule), Some(entry)) = (&self.fleet, m.entry) {
            self.stand_again(schedule.as_ref(), m.db, radius_m, m.request.start, entry)
                .await;
        }
    }
}

/// The note with where the robot made way, when it did.
fn with_making_way(note: Option<String>, making_way: Option<&MakingWay>) -> Option<String> {
    let Some(w) = making_way else {
        return note;
    };
    Some(format!(
        "{}made way at ({:.2}, {:.2}), its first goal, for {}: they stood in each other's way with no plan",
        note.map(|n| format!("{n}; ")).unwrap_or_default(),
        w.at.x,
        w.at.y,
        w.for_robots.join(", ")
    ))
}

/// Whether the route of `report` (its start, then its waypoints) passes within `reach` of `at`.
fn route_passes(report: &rehearsal::PlanReport, at: Point2, reach: f64) -> bool {
    let start = report.steps.first().map(|p| Point2::new(p.x, p.y));
    let route: Vec<Point2> = start
        .into_iter()
        .chain(report.waypoints.iter().copied())
        .collect();
    route
        .windows(2)
        .any(|w| at.distance_to_segment(w[0], w[1]) < reach)
}

/// The bounds of a query that need no store: the hour, and the request's goals, attempts,
/// samples, timer and people.
fn check_bounds(query: &PlanQuery) -> Result<(), PlanFailure> {
    if let PlanPeople::Expected { hour: Some(h) } = query.people
        && h > 23
    {
        return Err(PlanFailure::BadRequest(crate::InvalidField::new(
            "options.people_hour",
            format!("`options.people_hour` is an hour of day in [0, 23], got {h}"),
        )));
    }
    query.fleet.check()?;
    rehearsal::check_request(&query.request).map_err(PlanFailure::Plan)
}
