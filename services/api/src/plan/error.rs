//! How the plan endpoint (and a `validate` job's failure) answers a [`PlanError`] of the
//! executor: the API error code (and so the HTTP status), a stable machine-readable `reason`,
//! and the `details` JSON. Each is one exhaustive match, so a new refusal in `rehearsal` does not
//! compile here until it has its answer.

use edge::{ApiError, ErrorCode};
use rehearsal::{BlockedReason, Endpoint, PlanError};
use serde_json::{Value, json};

use super::types::{AttemptReport, Point};

/// The HTTP side of a [`PlanError`].
pub trait PlanErrorResponse {
    /// A stable machine-readable reason, finer than the HTTP code: `invalid_input`,
    /// `start_in_obstacle`, `goal_in_obstacle`, `start_outside_map`, `goal_outside_map`,
    /// `unreachable`, `not_validated`, `map_unusable`.
    fn reason(&self) -> &'static str;

    /// The API error code: `bad_request` (400) for malformed input, `unprocessable` (422) for a
    /// well-formed request that describes something impossible (a blocked or unreachable goal,
    /// a map without room for the robot), `conflict` (409) when the simulation refused every
    /// attempt (the plan conflicts with the world as known; the attempts say why).
    fn api_code(&self) -> ErrorCode;

    /// Machine-readable details for the error body: the reason and the variant's fields, in
    /// the wire types.
    fn details(&self) -> Value;

    /// The error as the HTTP edge answers it: code, the error's message, details.
    fn to_api_error(&self) -> ApiError;
}

impl PlanErrorResponse for PlanError {
    fn reason(&self) -> &'static str {
        match self {
            PlanError::InvalidInput { .. } => "invalid_input",
            PlanError::Blocked {
                endpoint, reason, ..
            } => match (endpoint, reason) {
                (Endpoint::Start, BlockedReason::InObstacle) => "start_in_obstacle",
                (Endpoint::Start, BlockedReason::OutsideMap) => "start_outside_map",
                // A waypoint is a point the robot drives to, as a goal is.
                (Endpoint::Goal(_) | Endpoint::Waypoint, BlockedReason::InObstacle) => {
                    "goal_in_obstacle"
                }
                (Endpoint::Goal(_) | Endpoint::Waypoint, BlockedReason::OutsideMap) => {
                    "goal_outside_map"
                }
            },
            PlanError::Unreachable { .. } => "unreachable",
            PlanError::NotValidated { .. } => "not_validated",
            PlanError::Map(_) => "map_unusable",
            PlanError::Stopped => "stopped",
        }
    }

    fn api_code(&self) -> ErrorCode {
        match self {
            PlanError::InvalidInput { .. } => ErrorCode::BadRequest,
            PlanError::Blocked { .. } | PlanError::Unreachable { .. } | PlanError::Map(_) => {
                ErrorCode::Unprocessable
            }
            PlanError::NotValidated { .. } => ErrorCode::Conflict,
            PlanError::Stopped => ErrorCode::Timeout,
        }
    }

    fn details(&self) -> Value {
        let mut d = match self {
            PlanError::InvalidInput { field, message } => {
                json!({ "field": field, "message": message })
            }
            PlanError::Blocked {
                endpoint,
                point,
                reason,
                clearance_m,
                required_m,
                nearest_free,
            } => json!({
                "which": endpoint.to_string(),
                "point": Point::from(*point),
                "blocked": blocked_name(*reason),
                "clearance_m": clearance_m,
                "required_m": required_m,
                "nearest_free": nearest_free.map(Point::from),
            }),
            PlanError::Unreachable {
                goal_index,
                goal,
                from,
            } => json!({
                "goal_index": goal_index,
                "goal": Point::from(*goal),
                "from": from.in_words(),
            }),
            PlanError::NotValidated { attempts } => {
                let attempts: Vec<AttemptReport> =
                    attempts.iter().cloned().map(AttemptReport::from).collect();
                json!({ "attempts": attempts })
            }
            PlanError::Map(message) => json!({ "message": message }),
            PlanError::Stopped => json!({}),
        };
        if let Some(o) = d.as_object_mut() {
            o.insert("reason".into(), self.reason().into());
        }
        d
    }

    fn to_api_error(&self) -> ApiError {
        let e = ApiError::new(self.api_code(), self.to_string()).with_details(self.details());
        match self {
            PlanError::InvalidInput { field, .. } => e.with_field(field.clone()),
            PlanError::Blocked { endpoint, .. } => match endpoint {
                Endpoint::Start => e.with_field("start"),
                Endpoint::Goal(_) => e.with_field("goal"),
                Endpoint::Waypoint => e,
            },
            _ => e,
        }
    }
}

/// The name of a [`BlockedReason`] in `details.blocked`.
fn blocked_name(reason: BlockedReason) -> &'static str {
    match reason {
        BlockedReason::InObstacle => "in_obstacle",
        BlockedReason::OutsideMap => "outside_map",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_endpoint_and_cause_has_its_reason_and_details() {
        let blocked = |endpoint, reason| PlanError::Blocked {
            endpoint,
            point: prm::Point2::new(1.0, 2.0),
            reason,
            clearance_m: Some(0.05),
            required_m: 0.3,
            nearest_free: None,
        };
        let cases = [
            (
                Endpoint::Start,
                BlockedReason::InObstacle,
                "start_in_obstacle",
            ),
            (
                Endpoint::Start,
                BlockedReason::OutsideMap,
                "start_outside_map",
            ),
            (
                Endpoint::Goal(3),
                BlockedReason::InObstacle,
                "goal_in_obstacle",
            ),
            (
                Endpoint::Goal(0),
                BlockedReason::OutsideMap,
                "goal_outside_map",
            ),
            (
                Endpoint::Waypoint,
                BlockedReason::InObstacle,
                "goal_in_obstacle",
            ),
        ];
        for (endpoint, reason, want) in cases {
            let e = blocked(endpoint, reason);
            assert_eq!(e.reason(), want);
            assert_eq!(e.api_code(), ErrorCode::Unprocessable);
        }
        let d = blocked(Endpoint::Goal(3), BlockedReason::InObstacle).details();
        assert_eq!(
            d,
            json!({
                "which": "goals[3]",
                "point": {"x": 1.0, "y": 2.0},
                "blocked": "in_obstacle",
                "clearance_m": 0.05,
                "required_m": 0.3,
                "nearest_free": null,
                "reason": "goal_in_obstacle",
            })
        );
        let d = PlanError::Unreachable {
            goal_index: 1,
            goal: prm::Point2::new(4.0, 5.0),
            from: Endpoint::Start,
        }
        .details();
        assert_eq!(
            d,
            json!({
                "goal_index": 1,
                "goal": {"x": 4.0, "y": 5.0},
                "from": "the start",
                "reason": "unreachable",
            })
        );
        let e = PlanError::Map("no room".into());
        assert_eq!(
            (e.reason(), e.api_code()),
            ("map_unusable", ErrorCode::Unprocessable)
        );
        assert_eq!(e.details()["message"], "no room");
    }
}
