//! Waits: a plan waiting for robots that stand in its way with no plan yet says so in the
//! schedule ([`Wait`]), so that the processes sharing the database see each other's waits and
//! a cycle of waits (A's plan waits for B, B's for A) is found whichever processes the plans
//! are asked of. A wait lasts until its plan stops waiting, or until its `until_unix_ms`
//! (a process that died leaves no wait behind for longer than that).

use crate::TrafficError;
use crate::itinerary::{MAX_NAME_BYTES, MAX_POSES};

/// A plan waiting for robots standing in its way with no plan yet.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Wait {
    /// The waiting plan's robot's IRI.
    pub robot: String,
    /// The floor's IRI.
    pub floor: String,
    /// The standing robots it waits for.
    pub by: Vec<String>,
    /// Points along its route, metres.
    pub route: Vec<(f64, f64)>,
    /// Its robot's footprint radius, metres.
    pub radius_m: f64,
    /// It looked for a place to make way at and found none (another robot of a cycle of
    /// waits takes its turn).
    pub cannot_make_way: bool,
    /// When the wait ends at the latest, Unix milliseconds.
    pub until_unix_ms: i64,
}

impl Wait {
    /// The wait, or what is out of range in it.
    pub fn check(&self) -> Result<(), TrafficError> {
        let name = |what: &str, s: &str| {
            if s.is_empty() || s.len() > MAX_NAME_BYTES {
                Err(TrafficError::Invalid(format!(
                    "a wait's {what} must have 1 to {MAX_NAME_BYTES} bytes, got {}",
                    s.len()
                )))
            } else {
                Ok(())
            }
        };
        name("robot", &self.robot)?;
        name("floor", &self.floor)?;
        for b in &self.by {
            name("standing robot", b)?;
        }
        if self.by.len() > MAX_POSES || self.route.len() > MAX_POSES {
            return Err(TrafficError::Invalid(format!(
                "a wait holds at most {MAX_POSES} standing robots and route points"
            )));
        }
        let finite = self
            .route
            .iter()
            .all(|(x, y)| x.is_finite() && y.is_finite());
        if !(finite && self.radius_m.is_finite() && self.radius_m > 0.0) {
            return Err(TrafficError::Invalid(
                "a wait's route points and radius must be finite, the radius positive".into(),
            ));
        }
        Ok(())
    }
}
