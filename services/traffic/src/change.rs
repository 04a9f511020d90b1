//! What changed in the schedule: [`Change`], as [`crate::Schedule::changes`] broadcasts it.

use serde::Serialize;

use crate::itinerary::Itinerary;

/// Why an itinerary left the schedule before its expiry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Removal {
    /// Its plan was cancelled.
    Cancelled,
    /// Its robot committed a new plan.
    Replaced,
}

/// A change to one floor's schedule and the floor's version after it. The changes one
/// operation makes (a replaced itinerary and the new one) carry the same version. Expiry is
/// not a change: an itinerary leaves the schedule at its `expires_unix_ms`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Change {
    /// An itinerary was committed.
    Committed {
        /// The floor's version after the commit.
        version: i64,
        /// The itinerary.
        itinerary: Itinerary,
    },
    /// An itinerary left the schedule.
    Removed {
        /// Its floor.
        floor: String,
        /// The floor's version after the removal.
        version: i64,
        /// Its plan id.
        plan_id: String,
        /// Its robot.
        robot: String,
        /// Why.
        reason: Removal,
    },
    /// A plan was revised before its robot set off: its new itinerary (`itinerary.revision`
    /// is the new revision). The plans one revision changes carry the same version.
    Revised {
        /// The floor's version after the revision.
        version: i64,
        /// The revised itinerary.
        itinerary: Itinerary,
    },
    /// A robot reported progress: its itinerary's delay (and expiry) changed.
    Progressed {
        /// The floor's version after the report.
        version: i64,
        /// The itinerary with its new delay.
        itinerary: Itinerary,
    },
}

impl Change {
    /// The floor changed.
    pub fn floor(&self) -> &str {
        match self {
            Self::Committed { itinerary, .. }
            | Self::Revised { itinerary, .. }
            | Self::Progressed { itinerary, .. } => &itinerary.floor,
            Self::Removed { floor, .. } => floor,
        }
    }

    /// The floor's version after the change.
    pub fn version(&self) -> i64 {
        match self {
            Self::Committed { version, .. }
            | Self::Revised { version, .. }
            | Self::Removed { version, .. }
            | Self::Progressed { version, .. } => *version,
        }
    }
}
