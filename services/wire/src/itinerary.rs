//! A committed plan as the traffic routes show it: the wire form of the schedule's
//! [`traffic::Itinerary`], converted field by field (the schedule's own type carries no OpenAPI
//! schema).

use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// A pose of a trajectory, at a time counted from the itinerary's start.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TimedPose {
    /// Seconds after the itinerary's start (`start_unix_ms`), before any delay.
    pub t_s: f64,
    /// Position on the floor, metres.
    pub x: f64,
    /// Position on the floor, metres.
    pub y: f64,
    /// Heading, radians.
    pub yaw: f64,
}

/// A robot's plan as the fleet's traffic schedule holds it: where the robot will be and when.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct Itinerary {
    /// The plan this itinerary comes from; unique in the schedule.
    pub plan_id: String,
    /// The robot driving it. A robot has at most one itinerary: a new one replaces the old.
    pub robot: String,
    /// The floor it drives on.
    pub floor: String,
    /// When the trajectory's time 0 is, Unix milliseconds.
    pub start_unix_ms: i64,
    /// The poses, with strictly increasing times.
    pub trajectory: Vec<TimedPose>,
    /// The radius of a disc covering the robot's footprint, metres.
    pub radius_m: f64,
    /// How late or early the robot may be, seconds: at any time it may be anywhere its
    /// schedule puts it within this many seconds of that time.
    pub tolerance_s: f64,
    /// When the schedule forgets this itinerary, Unix milliseconds. Until then, after the
    /// trajectory's end, the robot is parked at its last pose. A progress report moves it by
    /// the change in delay, so the robot keeps the parking time it was committed with.
    pub expires_unix_ms: i64,
    /// The delay observed from the robot's progress, seconds: every time of the trajectory is
    /// this much later (negative: earlier).
    pub delay_s: f64,
    /// The plan's revision: 1 when committed, one more each time the service revised its
    /// timing or route before the robot set off. Drive the newest.
    pub revision: u32,
}

impl From<traffic::TimedPose> for TimedPose {
    fn from(p: traffic::TimedPose) -> Self {
        Self {
            t_s: p.t_s,
            x: p.x,
            y: p.y,
            yaw: p.yaw,
        }
    }
}

impl From<traffic::Itinerary> for Itinerary {
    fn from(i: traffic::Itinerary) -> Self {
        Self {
            plan_id: i.plan_id,
            robot: i.robot,
            floor: i.floor,
            start_unix_ms: i.start_unix_ms,
            trajectory: i.trajectory.into_iter().map(TimedPose::from).collect(),
            radius_m: i.radius_m,
            tolerance_s: i.tolerance_s,
            expires_unix_ms: i.expires_unix_ms,
            delay_s: i.delay_s,
            revision: i.revision,
        }
    }
}
