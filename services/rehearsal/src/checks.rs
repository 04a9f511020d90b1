//! The executor's checks of a request before any work: values within bounds, a start and goals
//! in free configuration space and in one free region; planner errors as the request's own.

use prm::{ConfigSpace, Point2, QueryError};
use sim::{Pose2, World};

use crate::error::{BlockedReason, Endpoint, PlanError, invalid};
use crate::executor::{
    MAX_ATTEMPTS, MAX_GOALS, MAX_PEOPLE_DRAWS, MAX_WAYPOINT_TIMEOUT_S, START_ESCAPE_M,
};
use crate::types::{PlanOptions, PlanRequest};

/// Checks a request's values before any work: finite poses, 1 to [`MAX_GOALS`] goals, options
/// within their bounds. `Err` is [`PlanError::InvalidInput`] naming the field.
pub fn check_request(request: &PlanRequest) -> Result<(), PlanError> {
    let s = request.start;
    for (field, v) in [("start.x", s.x), ("start.y", s.y), ("start.yaw", s.yaw)] {
        if !v.is_finite() {
            return Err(invalid(field, format!("must be a finite number, got {v}")));
        }
    }
    if request.goals.is_empty() {
        return Err(invalid("goals", "must hold at least one goal"));
    }
    if request.goals.len() > MAX_GOALS {
        return Err(invalid(
            "goals",
            format!(
                "holds {} goals; at most {MAX_GOALS} are taken",
                request.goals.len()
            ),
        ));
    }
    for (i, g) in request.goals.iter().enumerate() {
        if !(g.x.is_finite() && g.y.is_finite()) {
            let field = if g.x.is_finite() { "y" } else { "x" };
            return Err(invalid(
                format!("goals[{i}].{field}"),
                format!("must be a finite number, got ({}, {})", g.x, g.y),
            ));
        }
    }
    check_options(&request.options)
}

fn check_options(o: &PlanOptions) -> Result<(), PlanError> {
    if let Some((field, message)) = o.people.problem() {
        return Err(invalid(format!("options.{field}"), message));
    }
    if o.people_draws > MAX_PEOPLE_DRAWS {
        return Err(invalid(
            "options.people_draws",
            format!(
                "must lie in [0, {MAX_PEOPLE_DRAWS}], got {}",
                o.people_draws
            ),
        ));
    }
    if o.max_attempts == 0 || o.max_attempts > MAX_ATTEMPTS {
        return Err(invalid(
            "options.max_attempts",
            format!("must lie in [1, {MAX_ATTEMPTS}], got {}", o.max_attempts),
        ));
    }
    if !(o.waypoint_timeout_s.is_finite()
        && o.waypoint_timeout_s > 0.0
        && o.waypoint_timeout_s <= MAX_WAYPOINT_TIMEOUT_S)
    {
        return Err(invalid(
            "options.waypoint_timeout_s",
            format!(
                "must lie in (0, {MAX_WAYPOINT_TIMEOUT_S}] simulated seconds, got {}",
                o.waypoint_timeout_s
            ),
        ));
    }
    if !(o.safety_margin_m.is_finite() && (0.0..=5.0).contains(&o.safety_margin_m)) {
        return Err(invalid(
            "options.safety_margin_m",
            format!("must lie in [0, 5] metres, got {}", o.safety_margin_m),
        ));
    }
    if let Some(n) = o.samples
        && !(1..=prm::MAX_SAMPLES).contains(&n)
    {
        return Err(invalid(
            "options.samples",
            format!("must lie in [1, {}], got {n}", prm::MAX_SAMPLES),
        ));
    }
    if o.max_replans > 1000 {
        return Err(invalid(
            "options.max_replans",
            format!("must be at most 1000, got {}", o.max_replans),
        ));
    }
    Ok(())
}

/// Where the roadmap path starts: `None` when the start is free configuration space, or the
/// nearest free point when the robot fits at the start but stands closer to an obstacle than the
/// safety margin and can drive there straight.
pub(crate) fn start_entry(
    world: &World,
    cs: &ConfigSpace,
    start: Pose2,
    collision_clearance: f64,
) -> Result<Option<Point2>, PlanError> {
    let p = Point2::new(start.x, start.y);
    match cs.validate_endpoint(prm::Endpoint::Start, p) {
        Ok(()) => Ok(None),
        Err(e @ QueryError::InObstacle { .. }) => {
            let escape = cs.nearest_free(p).filter(|&q| {
                q.distance(p) <= START_ESCAPE_M
                    && segment_clear(world, p, q, collision_clearance + 0.02)
            });
            match escape {
                Some(q) => Ok(Some(q)),
                None => Err(blocked_error(Endpoint::Start, e)),
            }
        }
        Err(e) => Err(blocked_error(Endpoint::Start, e)),
    }
}

/// Every goal must be free and in the same free region as the point before it.
pub(crate) fn check_goals(
    cs: &ConfigSpace,
    from: Point2,
    goals: &[Point2],
) -> Result<(), PlanError> {
    for (i, &g) in goals.iter().enumerate() {
        cs.validate_endpoint(prm::Endpoint::Goal, g)
            .map_err(|e| blocked_error(Endpoint::Goal(i), e))?;
    }
    let mut prev = (from, Endpoint::Start);
    for (i, &g) in goals.iter().enumerate() {
        if cs.region_of(prev.0) != cs.region_of(g) {
            return Err(PlanError::Unreachable {
                goal_index: i,
                goal: g,
                from: prev.1,
            });
        }
        prev = (g, Endpoint::Goal(i));
    }
    Ok(())
}

/// A planner endpoint error as the request's own error, naming the point.
pub(crate) fn blocked_error(which: Endpoint, e: QueryError) -> PlanError {
    match e {
        QueryError::NonFinite { x, y, .. } => invalid(
            which.to_string(),
            format!("must be a finite point, got ({x}, {y})"),
        ),
        QueryError::OutsideMap {
            point,
            nearest_free,
            ..
        } => PlanError::Blocked {
            endpoint: which,
            point,
            reason: BlockedReason::OutsideMap,
            clearance_m: None,
            required_m: 0.0,
            nearest_free,
        },
        QueryError::InObstacle {
            point,
            clearance_m,
            required_m,
            nearest_free,
            ..
        } => PlanError::Blocked {
            endpoint: which,
            point,
            reason: BlockedReason::InObstacle,
            clearance_m: Some(clearance_m),
            required_m,
            nearest_free,
        },
        other @ (QueryError::Unreachable { .. } | QueryError::NotConnected) => {
            PlanError::Map(format!("{which}: {other}"))
        }
    }
}

/// Whether the robot's footprint keeps `min_clearance` along the straight segment `a`–`b`.
pub(crate) fn segment_clear(world: &World, a: Point2, b: Point2, min_clearance: f64) -> bool {
    let step = (world.resolution() / 2.0).max(1e-3);
    let len = a.distance(b);
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a short segment: a small positive count"
    )]
    let n = ((len / step).ceil() as usize).max(1);
    (0..=n).all(|k| {
        let t = k as f64 / n as f64;
        world.clearance(a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)) >= min_clearance
    })
}
