//! Itineraries as rows of `traffic_itineraries`, and back.

use crate::error::TrafficError;
use crate::itinerary::{Itinerary, TimedPose};

/// The columns [`ItineraryRow`] reads, in a `SELECT` or `RETURNING` list.
pub(super) const COLUMNS: &str = "plan_id, floor, robot, start_ms, expires_ms, delay_s, \
                                  tolerance_s, radius_m, progress_t_s, trajectory";

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
}

impl ItineraryRow {
    /// The itinerary the row holds.
    pub fn into_itinerary(self) -> Result<Itinerary, TrafficError> {
        let poses: Vec<[f64; 4]> =
            serde_json::from_str(&self.trajectory).map_err(|e| TrafficError::Corrupt {
                plan_id: self.plan_id.clone(),
                message: format!("trajectory: {e}"),
            })?;
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
        })
    }
}

/// A trajectory as the JSON text the row stores.
pub(super) fn trajectory_text(poses: &[TimedPose]) -> Result<String, TrafficError> {
    let arrays: Vec<[f64; 4]> = poses.iter().map(|p| [p.t_s, p.x, p.y, p.yaw]).collect();
    serde_json::to_string(&arrays)
        .map_err(|e| TrafficError::Invalid(format!("trajectory cannot be stored: {e}")))
}
