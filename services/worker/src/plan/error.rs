//! Why a plan could not be validated: each cause its own variant, so the HTTP layer answers
//! each with its own status and code.

use edge::{ApiError, ErrorCode};
use serde::Serialize;

use super::types::{AttemptReport, Point};

/// Why a point cannot be planned from or to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BlockedReason {
    /// Inside an obstacle, unknown space, or closer to one than the robot's radius plus the
    /// safety margin.
    InObstacle,
    /// Outside the map.
    OutsideMap,
}

/// A plan request that could not be answered with a validated plan.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// A field is malformed: a coordinate that is not a finite number, no goals, an option out
    /// of range, a policy that does not fit the robot's laser.
    #[error("invalid plan request: `{field}` {message}")]
    InvalidInput {
        /// The field, as a path into the request (`goals[2].x`, `options.max_attempts`).
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The start or a goal is inside an obstacle or outside the map.
    #[error("{which} ({:.3}, {:.3}) is {}{}", point.x, point.y, match reason {
        BlockedReason::InObstacle => "inside an obstacle or too close to one for the robot",
        BlockedReason::OutsideMap => "outside the map",
    }, match nearest_free {
        Some(p) => format!("; nearest free point ({:.3}, {:.3})", p.x, p.y),
        None => "; the map has no free point".to_owned(),
    })]
    Blocked {
        /// `start` or `goals[i]`.
        which: String,
        /// The point given.
        point: Point,
        /// Obstacle or outside.
        reason: BlockedReason,
        /// Clearance at the point, metres (distance to the nearest blocked cell's edge), when
        /// on the map.
        clearance_m: Option<f64>,
        /// Clearance the robot needs: its radius plus the safety margin, metres.
        required_m: f64,
        /// The nearest point the robot may stand on, if any.
        nearest_free: Option<Point>,
    },
    /// The goal lies in a free region that the start's region does not connect to.
    #[error(
        "goals[{goal_index}] ({:.3}, {:.3}) is unreachable: it lies in a free region not connected to {from}",
        goal.x, goal.y
    )]
    Unreachable {
        /// Which goal.
        goal_index: usize,
        /// The goal.
        goal: Point,
        /// `the start` or `goals[i - 1]`.
        from: String,
    },
    /// Every simulated attempt collided or stalled.
    #[error("no attempt validated the plan ({} attempts: {})", attempts.len(), summary(attempts))]
    NotValidated {
        /// The attempts and why each failed.
        attempts: Vec<AttemptReport>,
    },
    /// The world cannot be planned on at all (no free space for this robot, a grid too large).
    #[error("the map cannot be planned on: {0}")]
    Map(String),
}

fn summary(attempts: &[AttemptReport]) -> String {
    attempts
        .iter()
        .map(|a| format!("#{} {}", a.attempt, a.reason))
        .collect::<Vec<_>>()
        .join("; ")
}

impl PlanError {
    /// A stable machine-readable reason, finer than the HTTP code: `invalid_input`,
    /// `start_in_obstacle`, `goal_in_obstacle`, `start_outside_map`, `goal_outside_map`,
    /// `unreachable`, `not_validated`, `map_unusable`.
    pub fn reason(&self) -> &'static str {
        match self {
            PlanError::InvalidInput { .. } => "invalid_input",
            PlanError::Blocked { which, reason, .. } => {
                match (which.starts_with("start"), reason) {
                    (true, BlockedReason::InObstacle) => "start_in_obstacle",
                    (false, BlockedReason::InObstacle) => "goal_in_obstacle",
                    (true, BlockedReason::OutsideMap) => "start_outside_map",
                    (false, BlockedReason::OutsideMap) => "goal_outside_map",
                }
            }
            PlanError::Unreachable { .. } => "unreachable",
            PlanError::NotValidated { .. } => "not_validated",
            PlanError::Map(_) => "map_unusable",
        }
    }

    /// The API error code: `bad_request` (400) for malformed input, `unprocessable` (422) for a
    /// well-formed request that describes something impossible (a blocked or unreachable goal,
    /// a map without room for the robot), `conflict` (409) when the simulation refused every
    /// attempt (the plan conflicts with the world as known; the attempts say why).
    pub fn api_code(&self) -> ErrorCode {
        match self {
            PlanError::InvalidInput { .. } => ErrorCode::BadRequest,
            PlanError::Blocked { .. } | PlanError::Unreachable { .. } | PlanError::Map(_) => {
                ErrorCode::Unprocessable
            }
            PlanError::NotValidated { .. } => ErrorCode::Conflict,
        }
    }

    /// Machine-readable details for the error body: the reason and the variant's fields.
    pub fn details(&self) -> serde_json::Value {
        let mut d = match self {
            PlanError::InvalidInput { field, message } => {
                serde_json::json!({ "field": field, "message": message })
            }
            PlanError::Blocked {
                which,
                point,
                reason,
                clearance_m,
                required_m,
                nearest_free,
            } => serde_json::json!({
                "which": which,
                "point": point,
                "blocked": reason,
                "clearance_m": clearance_m,
                "required_m": required_m,
                "nearest_free": nearest_free,
            }),
            PlanError::Unreachable {
                goal_index,
                goal,
                from,
            } => serde_json::json!({ "goal_index": goal_index, "goal": goal, "from": from }),
            PlanError::NotValidated { attempts } => serde_json::json!({ "attempts": attempts }),
            PlanError::Map(message) => serde_json::json!({ "message": message }),
        };
        if let Some(o) = d.as_object_mut() {
            o.insert("reason".into(), self.reason().into());
        }
        d
    }

    /// The error as the HTTP edge answers it.
    pub fn to_api_error(&self) -> ApiError {
        ApiError::new(self.api_code(), self.to_string()).with_details(self.details())
    }
}

impl From<PlanError> for ApiError {
    fn from(e: PlanError) -> Self {
        e.to_api_error()
    }
}

pub(crate) fn invalid(field: impl Into<String>, message: impl Into<String>) -> PlanError {
    PlanError::InvalidInput {
        field: field.into(),
        message: message.into(),
    }
}
