//! A plan in the wire types: what a robot asks (`POST /v1/plan`, and the payload of a
//! `validate` job, which is the same request) and what it is answered. Both callers translate
//! with [`PlanApiRequest::into_query`] and [`PlanApiResponse::of`] and leave every decision to
//! [`planner::Planner::plan`].
//!
//! - [`types`]: options and reports (serde, OpenAPI schemas), converted field by field to and
//!   from the executor's core types;
//! - [`ros`]: the path as a ROS 2 `nav_msgs/Path`;
//! - [`schedule`]: the plan in the floor's traffic schedule;
//! - [`itinerary`]: a committed plan as the traffic routes show it.

pub mod itinerary;
pub mod ros;
pub mod schedule;
pub mod types;

use planner::{InvalidField, PeopleSummary, PlanOutcome, PlanPeople, PlanQuery};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

pub use self::types::{
    AttemptOutcome, AttemptReport, ControllerChoiceReport, ControllerKind, ControllerOption,
    LegReport, PeopleChoice, PeopleDraws, PeopleMode, PeopleReport, PlanAmongFleet, PlanOptions,
    PlanReport, PlanSchedule, PlanWait, Point, Pose, RoadmapChoice, RoadmapInfo, RoadmapKind,
    RosPath, RosTime,
};

/// What a robot asks.
#[derive(Debug, Clone, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PlanApiRequest {
    /// The robot: identifier or IRI.
    pub robot: String,
    /// Where the robot is: its floor, or a place on that floor (identifier or IRI).
    pub place: String,
    /// The robot's pose on that floor (map frame).
    pub start: Pose,
    /// One goal (give this or `goals`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal: Option<Point>,
    /// Goals visited in order (give this or `goal`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub goals: Vec<Point>,
    /// Validation settings.
    #[serde(default)]
    pub options: PlanOptions,
    /// The policy to drive with [default: the robot's newest trained policy].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub policy: Option<String>,
}

impl PlanApiRequest {
    /// The goals: `goal` or `goals` (exactly one of them, non-empty).
    pub fn goals(&self) -> Result<Vec<Point>, InvalidField> {
        match (self.goal, self.goals.is_empty()) {
            (Some(_), false) => Err(InvalidField::new(
                "goals",
                "give `goal` or `goals`, not both",
            )),
            (Some(g), true) => Ok(vec![g]),
            (None, false) => Ok(self.goals.clone()),
            (None, true) => Err(InvalidField::new(
                "goal",
                "a plan needs a goal: give `goal` or a non-empty `goals`",
            )),
        }
    }

    /// The planner's query: the goals (an error naming the fields when neither or both are
    /// given), the options in the executor's types, and who walks about (`people: auto` is the
    /// knowledge's people at `people_hour`).
    pub fn into_query(self) -> Result<PlanQuery, InvalidField> {
        let goals = self.goals()?;
        let controller = self.options.controller.choice();
        let fleet = self.options.fleet();
        let people = match self.options.people {
            PeopleChoice::Named(PeopleMode::Auto) => PlanPeople::Expected {
                hour: self.options.people_hour,
            },
            PeopleChoice::Named(PeopleMode::None) | PeopleChoice::Density(_) => PlanPeople::AsGiven,
        };
        let request = rehearsal::PlanRequest {
            start: self.start.into(),
            goals: goals.into_iter().map(Into::into).collect(),
            options: self.options.into(),
            stop: rehearsal::Stop::default(),
        };
        Ok(PlanQuery {
            robot: self.robot,
            place: self.place,
            request,
            people,
            policy: self.policy,
            controller,
            fleet,
        })
    }
}

/// The validated plan and how it was validated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PlanApiResponse {
    /// The robot's IRI.
    pub robot: String,
    /// The floor's IRI.
    pub floor: String,
    /// The robot's policy (the one named, else its newest), if it has one: it drove the
    /// simulated robot when `controller_choice` is a hybrid.
    pub policy: Option<String>,
    /// The controller that validated the plan and why it was the one (`options.controller`).
    pub controller_choice: ControllerChoiceReport,
    /// Why a classical controller validated the plan or some of its legs, when one did: no
    /// policy yet, `auto` measured a classical one better, or legs no attempt with the picked
    /// controller validated.
    pub note: Option<String>,
    /// The plan in the floor's traffic schedule: its id, when the robot reaches each waypoint,
    /// where it waits for other robots; absent where the service keeps no schedule.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub schedule: Option<PlanSchedule>,
    /// Wall-clock time of the whole request in this service, milliseconds.
    pub service_ms: f64,
    /// The start and the waypoints as a ROS 2 `nav_msgs/Path` in the floor's map frame: what
    /// a Nav2 robot publishes or hands its controller without conversion.
    pub path: RosPath,
    /// The validated waypoints and the report of the simulated runs.
    #[serde(flatten)]
    pub report: PlanReport,
}

impl PlanApiResponse {
    /// The answer to a plan from `start` that the planner validated as `outcome`, after
    /// `service_ms` milliseconds.
    pub fn of(outcome: PlanOutcome, start: &Pose, service_ms: f64) -> Self {
        let PlanOutcome {
            robot,
            floor,
            policy,
            controller,
            note,
            report,
            people,
            world,
            fleet,
            ..
        } = outcome;
        let mut report = PlanReport::from(report);
        report.people = people.map(PeopleReport::from);
        let schedule = fleet.map(PlanSchedule::from);
        let mut path = RosPath::through(start, &report.waypoints, world.spec().map_frame());
        if let Some(s) = &schedule {
            path = path.stamped(&s.path_times());
        }
        Self {
            robot,
            floor,
            policy,
            controller_choice: controller.into(),
            note,
            schedule,
            service_ms,
            path,
            report,
        }
    }
}

impl From<PeopleSummary> for PeopleReport {
    fn from(s: PeopleSummary) -> Self {
        let PeopleSummary {
            source,
            people,
            min_person_clearance_m,
            attempts,
            attempts_reached,
            attempts_hit_person,
            attempts_near_miss,
            draws,
        } = s;
        Self {
            source: source.as_str().to_owned(),
            people,
            min_person_clearance_m,
            attempts,
            attempts_reached,
            attempts_hit_person,
            attempts_near_miss,
            draws: draws.map(Into::into),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request(goal: Option<Point>, goals: Vec<Point>) -> PlanApiRequest {
        PlanApiRequest {
            robot: "r".into(),
            place: "p".into(),
            start: Pose::new(0.0, 0.0, 0.0),
            goal,
            goals,
            options: PlanOptions::default(),
            policy: None,
        }
    }

    #[test]
    fn a_request_needs_exactly_one_of_goal_and_goals() {
        let p = Point::new(1.0, 2.0);
        assert_eq!(request(Some(p), vec![]).goals(), Ok(vec![p]));
        assert_eq!(request(None, vec![p, p]).goals(), Ok(vec![p, p]));
        assert!(
            request(Some(p), vec![p])
                .goals()
                .unwrap_err()
                .message
                .contains("not both")
        );
        assert!(
            request(None, vec![])
                .goals()
                .unwrap_err()
                .message
                .contains("needs a goal")
        );
    }

    #[test]
    fn people_auto_asks_the_knowledge_at_the_hour_and_a_density_is_given() {
        let mut r = request(Some(Point::new(1.0, 1.0)), vec![]);
        r.options.people_hour = Some(8);
        let q = r.clone().into_query().unwrap();
        assert_eq!(q.people, PlanPeople::Expected { hour: Some(8) });
        assert!(!q.request.options.people.any());
        r.options.people = PeopleChoice::Density(2.0);
        let q = r.into_query().unwrap();
        assert_eq!(q.people, PlanPeople::AsGiven);
        assert!((q.request.options.people.density - 2.0).abs() < 1e-12);
    }
}
