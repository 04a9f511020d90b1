//! A plan in the floor's traffic schedule, as the answer carries it.

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// The plan in the floor's traffic schedule.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PlanSchedule {
    /// The plan's id: `DELETE /v1/plans/{id}` cancels it, `POST /v1/plans/{id}/progress`
    /// reports the robot's progress on it.
    pub plan_id: String,
    /// Whether it was committed (`options.commit`).
    pub committed: bool,
    /// The floor schedule's version after the commit.
    pub version: Option<i64>,
    /// When the robot sets off (after any wait at the start), ms since the Unix epoch.
    pub start_time_ms: i64,
    /// When the robot reaches each waypoint, ms since the Unix epoch (index as `waypoints`).
    pub waypoint_times_ms: Vec<i64>,
    /// Where and how long the robot waits for other robots to pass, in order.
    pub waits: Vec<PlanWait>,
    /// Other robots' committed plans on the floor it was checked against.
    pub others_checked: usize,
    /// The plan driven again in the simulation with its waits while the other robots drive
    /// their committed plans; absent when there were none.
    pub among_fleet: Option<PlanAmongFleet>,
    /// How early or late the robot may be, seconds.
    pub tolerance_s: f64,
    /// When the schedule lets the robot's place go (its last goal held until then), ms since
    /// the Unix epoch.
    pub expires_ms: i64,
    /// Where the plan meets another plan that passes there first (the schedule's order, which
    /// delays do not change), along the plan. Progress answers and `GET /v1/plans/{id}` say
    /// when each has passed.
    pub passes_after: Vec<PassingView>,
    /// How far the robot may go now, seconds of its trajectory's time (before any delay): up
    /// to the first meeting whose other robot has not passed it yet; absent: to its goal.
    pub may_go_until_t_s: Option<f64>,
}

/// A plan driven again with its waits among the other robots' committed plans (their
/// footprints seen by the laser, moving along their schedules).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PlanAmongFleet {
    /// Other robots in the simulation.
    pub robots: usize,
    /// Whether the robot arrived (a plan that touched another robot is never answered: 409).
    pub arrived: bool,
    /// How the drive ended, in words.
    pub reason: String,
    /// Simulated time from the start to the last goal, waits included, seconds.
    pub time_s: f64,
    /// Closest approach of the footprint to another robot, metres (absent when none was on the
    /// floor during the drive).
    pub min_robot_clearance_m: Option<f64>,
}

/// A wait in a plan, so that other robots can pass.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PlanWait {
    /// The waypoint waited at (index into `waypoints`); absent: at the start (a later start).
    pub waypoint: Option<usize>,
    /// Seconds waited.
    pub wait_s: f64,
    /// When the robot may go on, ms since the Unix epoch.
    pub not_before_ms: i64,
    /// The robots it lets pass (IRIs).
    pub for_robots: Vec<String>,
}

impl From<planner::FleetOutcome> for PlanSchedule {
    fn from(f: planner::FleetOutcome) -> Self {
        let start_wait = f
            .waits
            .iter()
            .filter(|w| w.waypoint.is_none())
            .map(|w| w.not_before_unix_ms)
            .max();
        Self {
            plan_id: f.itinerary.plan_id.clone(),
            committed: f.version.is_some(),
            version: f.version,
            start_time_ms: start_wait.unwrap_or(f.itinerary.start_unix_ms),
            waypoint_times_ms: f.waypoint_times_unix_ms,
            waits: f
                .waits
                .into_iter()
                .map(|w| PlanWait {
                    waypoint: w.waypoint,
                    wait_s: w.wait_s,
                    not_before_ms: w.not_before_unix_ms,
                    for_robots: w.for_robots,
                })
                .collect(),
            others_checked: f.others,
            among_fleet: f.among.map(|a| PlanAmongFleet {
                robots: a.robots,
                arrived: a.outcome == rehearsal::AttemptOutcome::Reached,
                reason: a.reason,
                time_s: a.time_s,
                min_robot_clearance_m: a.min_robot_clearance_m.filter(|c| c.is_finite()),
            }),
            tolerance_s: f.itinerary.tolerance_s,
            expires_ms: f.itinerary.expires_unix_ms,
            may_go_until_t_s: traffic::may_go_until_s(&f.passes_after),
            passes_after: f.passes_after.into_iter().map(Into::into).collect(),
        }
    }
}

impl PlanSchedule {
    /// The time each pose of the plan's path is stamped with: the start, then each waypoint's
    /// arrival, or the end of its wait where the robot waits there.
    pub fn path_times(&self) -> Vec<i64> {
        std::iter::once(self.start_time_ms)
            .chain(self.waypoint_times_ms.iter().enumerate().map(|(i, &t)| {
                self.waits
                    .iter()
                    .find(|w| w.waypoint == Some(i))
                    .map_or(t, |w| w.not_before_ms)
            }))
            .collect()
    }
}

/// A place where a plan passes after another.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PassingView {
    /// The plan passing first.
    pub plan_id: String,
    /// Its robot.
    pub robot: String,
    /// Where the paths first overlap, metres.
    pub x: f64,
    /// Where the paths first overlap, metres.
    pub y: f64,
    /// This plan's trajectory time there, seconds.
    pub t_s: f64,
    /// Whether the other robot has passed (its progress reports matched it beyond the place).
    pub passed: bool,
}

impl From<traffic::Passing> for PassingView {
    fn from(p: traffic::Passing) -> Self {
        Self {
            plan_id: p.plan_id,
            robot: p.robot,
            x: p.x,
            y: p.y,
            t_s: p.t_s,
            passed: p.passed,
        }
    }
}
