//! What a plan is asked ([`PlanQuery`]) and what it answers ([`PlanOutcome`]): the planner's
//! own types, which the wire types at the HTTP edge convert to and from on purpose.

use std::sync::Arc;
use std::time::SystemTime;

use rehearsal::{ControllerChoice, PlanRequest};
use sim::World;

use crate::PlanFailure;
use crate::controllers::ControllerPick;
use crate::fleet::{self, FleetOptions, FleetOutcome};
use crate::replay::Replay;

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
    pub(crate) replay: Arc<Replay>,
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
        let robots = fleet::simulated_robots(others, start)?.shielded();
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
