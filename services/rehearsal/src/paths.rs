//! The roadmap paths a validation drives: a leg's path on the roadmap (timed among the
//! fleet's plans), the roadmap without the edges passing robots standing on the floor, a replan
//! from where the robot stands (a re-route avoiding a blocked spot), and long segments
//! subdivided so that every waypoint is within reach of its timer.

use std::sync::Arc;

use prm::{Point2, QueryError, QueryOptions, Roadmap};
use sim::{Pose2, World};

use crate::checks::{blocked_error, segment_clear};
use crate::error::{Endpoint, PlanError};
use crate::executor::START_ESCAPE_M;
use crate::recovery::RecoveryParams;
use crate::types::PlanOptions;

/// `points` after `from`, with evenly spaced points inserted in every segment longer than
/// `max_m`.
pub(crate) fn subdivide(from: Point2, points: Vec<Point2>, max_m: f64) -> Vec<Point2> {
    let mut out = Vec::with_capacity(points.len());
    let mut prev = from;
    for p in points {
        let d = prev.distance(p);
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a map-sized distance over at least 0.5 m: a small positive count"
        )]
        let pieces = (d / max_m).ceil().max(1.0) as usize;
        for k in 1..pieces {
            let t = k as f64 / pieces as f64;
            out.push(Point2::new(
                prev.x + t * (p.x - prev.x),
                prev.y + t * (p.y - prev.y),
            ));
        }
        out.push(p);
        prev = p;
    }
    out
}

/// What one leg plans from and to.
pub(crate) struct LegQuery {
    /// Where the robot stands.
    pub(crate) robot: Pose2,
    /// The previous goal, for every leg but the first (the robot stands within the goal
    /// tolerance of it): the roadmap path starts there.
    pub(crate) from: Option<Point2>,
    /// For the first leg, the start's way out of the safety margin, if it needs one.
    pub(crate) entry: Option<Point2>,
    pub(crate) goal: Point2,
    pub(crate) goal_index: usize,
    /// How to search (a policy-aware roadmap is not densified: new edges would be undriven).
    pub(crate) query: QueryOptions,
}

/// The waypoints of one leg after the robot's position, the last one its goal.
pub(crate) struct LegPath {
    pub(crate) waypoints: Vec<Point2>,
    /// Length of the roadmap path, metres (with the start's way out of the margin).
    pub(crate) length_m: f64,
}

/// The roadmap path of one leg from where the robot stands to its goal, subdivided into
/// waypoints no farther apart than `max_segment_m`; timed among `reserved` when given (the
/// shortest route when no timed one gets through).
pub(crate) fn plan_leg(
    roadmap: &Roadmap,
    opts: &PlanOptions,
    reserved: Option<&dyn prm::Reservations>,
    q: LegQuery,
    max_segment_m: f64,
) -> Result<LegPath, PlanError> {
    let s = Point2::new(q.robot.x, q.robot.y);
    let origin = q.from.or(q.entry).unwrap_or(s);
    let which = match q.goal_index {
        0 => Endpoint::Start,
        i => Endpoint::Goal(i - 1),
    };
    // A route timed among the fleet's plans that finds no way through them (every way
    // waits too long somewhere) is the shortest one: the fit makes it wait.
    let mut plan = roadmap
        .query_among(origin, q.goal, q.query, reserved)
        .or_else(|e| match (e, reserved) {
            (QueryError::Unreachable { .. } | QueryError::NotConnected, Some(_)) => {
                roadmap.query(origin, q.goal, q.query)
            }
            (e, _) => Err(e),
        })
        .map_err(|e| match e {
            QueryError::Unreachable { .. } | QueryError::NotConnected => PlanError::Unreachable {
                goal_index: q.goal_index,
                goal: q.goal,
                from: which,
            },
            other => blocked_error(Endpoint::Goal(q.goal_index), other),
        })?;
    if opts.shortcut {
        plan = roadmap.shortcut(&plan);
    }
    let length_m = q.entry.map_or(0.0, |e| e.distance(s)) + plan.length_m;
    let mut leg: Vec<Point2> = plan.waypoints.into_iter().skip(1).collect();
    if let Some(e) = q.entry {
        leg.insert(0, e);
    }
    if leg.is_empty() {
        // Start and goal coincide: the goal is still a waypoint to reach.
        leg.push(q.goal);
    }
    Ok(LegPath {
        waypoints: subdivide(q.from.unwrap_or(s), leg, max_segment_m),
        length_m,
    })
}

/// Metres a re-route recovery adds to the roadmap edges passing the blocked spot: the search
/// takes them only where no other route is within that detour.
pub const REROUTE_PENALTY_M: f64 = 50.0;

/// `roadmap` without the edges passing a robot standing still (`opts.standing`) closer than its
/// radius plus this robot's plus the safety margin, or with them costing
/// `opts.standing_pass_m` more.
pub(crate) fn clear_of_standing(
    roadmap: Arc<Roadmap>,
    opts: &PlanOptions,
    world: &World,
) -> Result<Arc<Roadmap>, PlanError> {
    if opts.standing.is_empty() {
        return Ok(roadmap);
    }
    let reach = world.spec().robot.footprint_radius + opts.safety_margin_m;
    let nodes: Vec<Point2> = roadmap.nodes().collect();
    let kept = roadmap
        .reweighted(|u, v, w| {
            let passes = opts
                .standing
                .iter()
                .any(|&(c, r)| c.distance_to_segment(nodes[u], nodes[v]) < r + reach);
            match (passes, opts.standing_pass_m) {
                (false, _) => Some(w),
                (true, pass) if pass.is_finite() => Some(w + pass),
                (true, _) => None,
            }
        })
        .map_err(|e| PlanError::Map(format!("keeping clear of standing robots: {e}")))?;
    Ok(Arc::new(kept))
}

/// A fresh roadmap path from where the robot stands to `goal`, or why there is none; with
/// `blocked`, on the roadmap whose edges passing within the re-route radius of that spot cost
/// [`REROUTE_PENALTY_M`] more.
pub(crate) fn replan(
    roadmap: &Roadmap,
    opts: &PlanOptions,
    world: &World,
    (from, goal): (Point2, Point2),
    blocked: Option<Point2>,
    max_segment_m: f64,
    query: QueryOptions,
) -> Result<Vec<Point2>, String> {
    let avoiding;
    let roadmap = match blocked {
        None => roadmap,
        Some(b) => {
            let nodes: Vec<Point2> = roadmap.nodes().collect();
            let radius = RecoveryParams::default().reroute_radius_m;
            avoiding = roadmap
                .reweighted(|u, v, w| {
                    let near = b.distance_to_segment(nodes[u], nodes[v]) < radius;
                    Some(if near { w + REROUTE_PENALTY_M } else { w })
                })
                .map_err(|e| format!("re-routing failed: {e}"))?;
            &avoiding
        }
    };
    let cs = roadmap.cspace();
    // A robot pushed closer to a wall than the margin first drives back into free space.
    let entry = if cs.is_free(from) {
        None
    } else {
        let q = cs
            .nearest_free(from)
            .filter(|&q| q.distance(from) <= START_ESCAPE_M && segment_clear(world, from, q, 0.0))
            .ok_or_else(|| {
                format!(
                    "no free space within {START_ESCAPE_M} m of ({:.2}, {:.2}) to replan from",
                    from.x, from.y
                )
            })?;
        Some(q)
    };
    let mut plan = roadmap
        .query(entry.unwrap_or(from), goal, query)
        .map_err(|e| format!("replanning failed: {e}"))?;
    if opts.shortcut {
        plan = roadmap.shortcut(&plan);
    }
    let mut out: Vec<Point2> = entry.into_iter().collect();
    out.extend(plan.waypoints.into_iter().skip(1));
    if out.is_empty() {
        out.push(goal);
    }
    Ok(subdivide(from, out, max_segment_m))
}
