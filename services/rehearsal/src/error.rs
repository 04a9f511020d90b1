//! Why a plan could not be validated: each cause its own variant, and the point a refusal is
//! about named by an [`Endpoint`], so a caller (the HTTP edge) answers each in its own way.

use std::fmt;

use prm::Point2;

use crate::types::AttemptReport;

/// Which point of a request a refusal is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Endpoint {
    /// The robot's start pose.
    Start,
    /// The goal at this index of the request's goals.
    Goal(usize),
    /// A waypoint the simulated drive was sent to. Waypoints come from free configuration
    /// space, so the executor's checks make this unreachable in practice.
    Waypoint,
}

impl Endpoint {
    /// The point in a sentence: `the start`, `goals[i]` or `a waypoint`.
    pub fn in_words(self) -> String {
        match self {
            Endpoint::Start => "the start".to_owned(),
            Endpoint::Goal(_) => self.to_string(),
            Endpoint::Waypoint => "a waypoint".to_owned(),
        }
    }
}

impl fmt::Display for Endpoint {
    /// The point as a field of the request: `start`, `goals[i]` or `waypoint`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Endpoint::Start => f.write_str("start"),
            Endpoint::Goal(i) => write!(f, "goals[{i}]"),
            Endpoint::Waypoint => f.write_str("waypoint"),
        }
    }
}

/// Why a point cannot be planned from or to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
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
    #[error("{endpoint} ({:.3}, {:.3}) is {}{}", point.x, point.y, match reason {
        BlockedReason::InObstacle => "inside an obstacle or too close to one for the robot",
        BlockedReason::OutsideMap => "outside the map",
    }, match nearest_free {
        Some(p) => format!("; nearest free point ({:.3}, {:.3})", p.x, p.y),
        None => "; the map has no free point".to_owned(),
    })]
    Blocked {
        /// Which point.
        endpoint: Endpoint,
        /// The point given.
        point: Point2,
        /// Obstacle or outside.
        reason: BlockedReason,
        /// Clearance at the point, metres (distance to the nearest blocked cell's edge), when
        /// on the map.
        clearance_m: Option<f64>,
        /// Clearance the robot needs: its radius plus the safety margin, metres.
        required_m: f64,
        /// The nearest point the robot may stand on, if any.
        nearest_free: Option<Point2>,
    },
    /// The goal lies in a free region that the start's region does not connect to.
    #[error(
        "goals[{goal_index}] ({:.3}, {:.3}) is unreachable: it lies in a free region not connected to {}",
        goal.x, goal.y, from.in_words()
    )]
    Unreachable {
        /// Which goal.
        goal_index: usize,
        /// The goal.
        goal: Point2,
        /// The point the goal is driven to from: the start or the goal before it.
        from: Endpoint,
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
    /// The caller asked the work to stop (its request timed out or its client went away).
    #[error("the plan's validation was stopped before it finished")]
    Stopped,
}

fn summary(attempts: &[AttemptReport]) -> String {
    attempts
        .iter()
        .map(|a| format!("#{} {}", a.attempt, a.reason))
        .collect::<Vec<_>>()
        .join("; ")
}

/// An [`PlanError::InvalidInput`] naming `field`.
pub(crate) fn invalid(field: impl Into<String>, message: impl Into<String>) -> PlanError {
    PlanError::InvalidInput {
        field: field.into(),
        message: message.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_read_as_request_fields_and_in_sentences() {
        assert_eq!(Endpoint::Start.to_string(), "start");
        assert_eq!(Endpoint::Goal(2).to_string(), "goals[2]");
        assert_eq!(Endpoint::Waypoint.to_string(), "waypoint");
        assert_eq!(Endpoint::Start.in_words(), "the start");
        assert_eq!(Endpoint::Goal(0).in_words(), "goals[0]");
        let e = PlanError::Blocked {
            endpoint: Endpoint::Goal(1),
            point: Point2::new(1.0, 2.0),
            reason: BlockedReason::OutsideMap,
            clearance_m: None,
            required_m: 0.0,
            nearest_free: Some(Point2::new(0.5, 0.25)),
        };
        assert_eq!(
            e.to_string(),
            "goals[1] (1.000, 2.000) is outside the map; nearest free point (0.500, 0.250)"
        );
        let e = PlanError::Unreachable {
            goal_index: 0,
            goal: Point2::new(3.0, 4.0),
            from: Endpoint::Start,
        };
        assert_eq!(
            e.to_string(),
            "goals[0] (3.000, 4.000) is unreachable: it lies in a free region not connected to the start"
        );
    }
}
