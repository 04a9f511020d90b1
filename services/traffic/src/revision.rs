//! Plan revisions: a committed plan is a commitment to reach the goal safely, not to a fixed
//! timetable. Until its robot sets off, the schedule may revise the plan's timing or route
//! ([`crate::Schedule::revise`]); the robot learns of it (the floor's traffic stream,
//! `GET /v1/plans/{id}`) before it moves and acknowledges it with its next progress report.
//!
//! When a robot has set off ([`Planned::set_off`]): a progress report matched it past the end of
//! its wait at the start, or the time it was told to leave is nearer than its tolerance (it may
//! be early by that much) plus [`REVISION_NOTICE_S`] (the time a revision takes to reach it). A
//! plan whose robot has set off is never revised.

use crate::itinerary::{Itinerary, add_seconds};

/// How long before the earliest time a robot may set off a revision must be made, seconds:
/// the time it takes to reach the robot (the traffic stream pushes it at once; a robot
/// long-polling its plan sees it within its poll).
pub const REVISION_NOTICE_S: f64 = 1.0;

/// A committed plan as the schedule holds it: its itinerary (with its revision), the revision
/// its robot last acknowledged, and where the last progress report matched it.
#[derive(Debug, Clone, PartialEq)]
pub struct Planned {
    /// The itinerary; `itinerary.revision` is the plan's revision.
    pub itinerary: Itinerary,
    /// The revision the robot last acknowledged (1 until it acknowledges one).
    pub acknowledged: u32,
    /// The trajectory time the last progress report matched, seconds (`None`: no report).
    pub progress_t_s: Option<f64>,
}

impl Planned {
    /// Whether the robot may have set off by `now_unix_ms` (see the module docs).
    pub fn set_off(&self, now_unix_ms: i64) -> bool {
        let it = &self.itinerary;
        let reported_moving = self
            .progress_t_s
            .is_some_and(|t| t > it.departure_s() + 1e-6);
        reported_moving || now_unix_ms >= self.latest_revision_unix_ms()
    }

    /// The last moment the plan may still be revised, Unix milliseconds: its departure less
    /// its tolerance and [`REVISION_NOTICE_S`].
    pub fn latest_revision_unix_ms(&self) -> i64 {
        let it = &self.itinerary;
        add_seconds(
            it.departs_unix_ms(),
            -(it.tolerance_s.max(0.0) + REVISION_NOTICE_S),
        )
    }
}
