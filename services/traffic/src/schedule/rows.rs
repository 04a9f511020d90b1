//! Itineraries as rows of `traffic_itineraries`, and back.

use crate::error::TrafficError;
use crate::itinerary::{Itinerary, TimedPose};
use crate::revision::Planned;

/// The columns [`ItineraryRow`] reads, in a `SELECT` or `RETURNING` list.
pub(super) const COLUMNS: &str = "plan_id, floor, robot, start_ms, expires_ms, delay_s, \
                                  tolerance_s, radius_m, progress_t_s, trajectory, \
                                  revision, acknowledged";

/// A row of `traffic_itineraries`.
#[derive(Debug, sqlx::FromRow)]
pub(super) struct ItineraryRow {
    pub plan_id: String,
    pub floor: String,
    pub robot: String,
    pub start_ms: i64,
    pub expires_ms: i64,
    pub delay_s: f64,
    pub tolerance_s: f64,
    pub radius_m: f64,
    /// The trajectory time the last progress report matched.
    pub progress_t_s: Option<f64>,
    /// JSON: `[[t_s, x, y, yaw], ...]`.
    pub trajectory: String,
    /// The plan's revision.
    pub revision: i64,
    /// The revision its robot last acknowledged.
    pub acknowledged: i64,
}

impl ItineraryRow {
    /// The itinerary the row holds.
    pub fn into_itinerary(self) -> Result<Itinerary, TrafficError> {
        let poses: Vec<[f64; 4]> =
            serde_json::from_str(&self.trajectory).map_err(|e| TrafficError::Corrupt {
                plan_id: self.plan_id.clone(),
                message: format!("trajectory: {e}"),
            })?;
        let revision = self.revision_number(self.revision, "revision")?;
        Ok(Itinerary {
            plan_id: self.plan_id,
            robot: self.robot,
            floor: self.floor,
            start_unix_ms: self.start_ms,
            trajectory: poses
                .into_iter()
                .map(|[t_s, x, y, yaw]| TimedPose { t_s, x, y, yaw })
                .collect(),
            radius_m: self.radius_m,
            tolerance_s: self.tolerance_s,
            expires_unix_ms: self.expires_ms,
            delay_s: self.delay_s,
            revision,
        })
    }

    /// The row as a [`Planned`]: the itinerary and what its robot acknowledged.
    pub fn into_planned(self) -> Result<Planned, TrafficError> {
        let acknowledged = self.revision_number(self.acknowledged, "acknowledged")?;
        let progress_t_s = self.progress_t_s;
        Ok(Planned {
            acknowledged,
            progress_t_s,
            itinerary: self.into_itinerary()?,
        })
    }

    fn revision_number(&self, n: i64, column: &str) -> Result<u32, TrafficError> {
        u32::try_from(n).map_err(|_| TrafficError::Corrupt {
            plan_id: self.plan_id.clone(),
            message: format!("{column} is {n}, not a revision number"),
        })
    }
}

/// A trajectory as the JSON text the row stores.
pub(super) fn trajectory_text(poses: &[TimedPose]) -> Result<String, TrafficError> {
    let arrays: Vec<[f64; 4]> = poses.iter().map(|p| [p.t_s, p.x, p.y, p.yaw]).collect();
    serde_json::to_string(&arrays)
        .map_err(|e| TrafficError::Invalid(format!("trajectory cannot be stored: {e}")))
}
