//! One committed plan as its robot follows it: `GET /v1/plans/{id}` with its revision as the
//! entity tag, so a robot asks "has my plan been revised since the one I drive?" with
//! `If-None-Match`, and may wait for the answer (`wait_s`, a long poll).
//!
//! The tag is weak: it names the plan's revision (what the robot must drive), not the bytes of
//! the answer (its delay moves with every progress report): `W/"<revision>-<plan>"`, where
//! `<plan>` is 16 hex digits of a hash of the plan id, so a tag of another plan is told apart.

use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::Json;
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use edge::{ApiError, ErrorCode, RobotCaller};
use serde::{Deserialize, Serialize};
use tokio::sync::broadcast;
use traffic::{Change, Planned};
use utoipa::{IntoParams, ToSchema};
use wire::schedule::PassingView;

use super::{TrafficRoutes, schedule, traffic_error};

/// The longest a `GET /v1/plans/{id}` waits for a revision, seconds.
pub const MAX_WAIT_S: f64 = 30.0;
/// Paths closer than both robots' radii and this gap meet, metres: the margin the fleet's
/// plans keep while both move.
const PASSING_GAP_M: f64 = planner::fleet::ROBOT_MARGIN_M;
/// How often a waiting request looks at the schedule for revisions made by other processes.
const POLL: Duration = Duration::from_millis(200);

/// How long to wait for a revision.
#[derive(Debug, Deserialize, IntoParams)]
pub struct PlanQuery {
    /// With `If-None-Match` naming the plan's current revision: wait up to this many seconds,
    /// in [0, 30], for another revision (or the plan's end) before answering 304 [default: 0].
    #[param(nullable = false)]
    pub wait_s: Option<f64>,
}

/// A committed plan as its robot follows it.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct PlanStatus {
    /// The plan as committed now (`revision`: the one to drive).
    pub plan: wire::itinerary::Itinerary,
    /// The revision its robot last acknowledged (`revision` of a progress report).
    pub acknowledged_revision: u32,
    /// Whether the robot may have set off: from then on the plan is never revised.
    pub set_off: bool,
    /// When the robot is to leave its start, ms since the Unix epoch (its delay included).
    pub departs_unix_ms: i64,
    /// Until when the service may still revise the plan, ms since the Unix epoch: its
    /// departure less its tolerance and the time a revision takes to reach the robot.
    pub revisable_until_unix_ms: i64,
    /// Where the plan meets another plan that passes there first (in the committed
    /// schedule's order, which delays do not change), along the plan.
    pub passes_after: Vec<PassingView>,
    /// How far the robot may go now, seconds of its trajectory's time (before its delay): up
    /// to the first meeting whose other robot has not reported passing it; absent: to its goal.
    /// A robot that keeps to it never meets another, however late either is.
    pub may_go_until_t_s: Option<f64>,
}

/// What a progress report answers: the plan as now scheduled, and how far its robot may go
/// now (as `GET /v1/plans/{id}` says).
#[derive(Debug, Serialize, ToSchema)]
pub struct ProgressAnswer {
    /// The plan as now scheduled (`delay_s`: how late the robot is; `revision`: the one to
    /// drive, newer than the report's where the plan was revised).
    #[serde(flatten)]
    pub plan: wire::itinerary::Itinerary,
    /// Where the plan meets another plan that passes there first, along the plan.
    pub passes_after: Vec<PassingView>,
    /// How far the robot may go now, seconds of its trajectory's time (before its delay): up
    /// to the first meeting whose other robot has not reported passing it; absent: to its goal.
    pub may_go_until_t_s: Option<f64>,
}

impl ProgressAnswer {
    /// The answer for plan `p` after its progress report, among the plans on its floor.
    pub(crate) fn of(p: Planned, now_unix_ms: i64, on_floor: &[Planned]) -> Self {
        let status = PlanStatus::of(p, now_unix_ms, on_floor);
        Self {
            plan: status.plan,
            passes_after: status.passes_after,
            may_go_until_t_s: status.may_go_until_t_s,
        }
    }
}

impl PlanStatus {
    /// Plan `p` at `now_unix_ms`, among the plans on its floor (`on_floor`, itself included).
    fn of(p: Planned, now_unix_ms: i64, on_floor: &[Planned]) -> Self {
        let passings = traffic::passings(&p.itinerary, on_floor, PASSING_GAP_M);
        Self {
            acknowledged_revision: p.acknowledged,
            set_off: p.set_off(now_unix_ms),
            departs_unix_ms: p.itinerary.departs_unix_ms(),
            revisable_until_unix_ms: p.latest_revision_unix_ms(),
            may_go_until_t_s: traffic::may_go_until_s(&passings),
            passes_after: passings.into_iter().map(Into::into).collect(),
            plan: p.itinerary.into(),
        }
    }
}

/// The entity tag of revision `revision` of plan `plan_id`.
pub fn etag(plan_id: &str, revision: u32) -> String {
    format!("W/\"{revision}-{:016x}\"", plan_hash(plan_id))
}

/// FNV-1a, 64 bits: stable across processes and releases (the tag outlives a process).
fn plan_hash(plan_id: &str) -> u64 {
    plan_id.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// What an `If-None-Match` header asks of plan `plan_id`.
#[derive(Debug, PartialEq, Eq)]
enum Known {
    /// No header: the plan, whatever its revision.
    Nothing,
    /// `*`: any revision.
    Any,
    /// The newest revision of this plan among the tags.
    Revision(u32),
}

/// Reads `If-None-Match` for plan `plan_id`: 422 for a tag this service does not give or one of
/// another plan.
fn known_revision(headers: &HeaderMap, plan_id: &str) -> Result<Known, ApiError> {
    let Some(value) = headers.get(header::IF_NONE_MATCH) else {
        return Ok(Known::Nothing);
    };
    let unreadable = |why: String| {
        ApiError::new(ErrorCode::Unprocessable, why).with_field("If-None-Match".to_owned())
    };
    let text = value
        .to_str()
        .map_err(|_| unreadable("If-None-Match is not ASCII text".to_owned()))?;
    if text.trim() == "*" {
        return Ok(Known::Any);
    }
    let ours = plan_hash(plan_id);
    let mut newest = None;
    for tag in text.split(',').map(str::trim).filter(|t| !t.is_empty()) {
        let parsed = tag
            .trim_start_matches("W/")
            .strip_prefix('"')
            .and_then(|t| t.strip_suffix('"'))
            .and_then(|t| t.split_once('-'))
            .and_then(|(r, h)| Some((r.parse::<u32>().ok()?, u64::from_str_radix(h, 16).ok()?)));
        let Some((revision, hash)) = parsed else {
            return Err(unreadable(format!(
                "If-None-Match: {tag} is not a plan's entity tag (W/\"<revision>-<plan>\", as the ETag of GET /v1/plans/{{id}})"
            )));
        };
        if hash != ours {
            return Err(unreadable(format!(
                "If-None-Match: {tag} is the tag of another plan, not of plan `{plan_id}`"
            )));
        }
        newest = newest.max(Some(revision));
    }
    Ok(newest.map_or(Known::Nothing, Known::Revision))
}

/// A committed plan, its revision and whether it may still be revised; with `If-None-Match`
/// (its `ETag`) and `wait_s`, a long poll for the next revision.
#[utoipa::path(
    get,
    path = "/v1/plans/{id}",
    params(("id" = String, Path, description = "The plan's id (`schedule.plan_id` of its answer)"), PlanQuery,
        ("If-None-Match" = Option<String>, Header, description = "The `ETag` of the revision the robot has: 304 while it is the plan's")),
    responses(
        (status = 200, description = "The plan as committed now; `ETag` names its revision", body = PlanStatus,
            headers(("etag" = String, description = "W/\"<revision>-<plan>\""))),
        (status = 304, description = "Still the revision `If-None-Match` names (after waiting up to `wait_s`)", headers(("etag" = String))),
        (status = 400, description = "A malformed query (`wait_s` not a number)", body = edge::ErrorBody),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 404, description = "No such committed plan (or it expired, was cancelled or replaced)", body = edge::ErrorBody),
        (status = 409, description = "`If-None-Match` names a revision the plan never had", body = edge::ErrorBody),
        (status = 422, description = "`If-None-Match` is not a plan's tag, or another plan's; `wait_s` out of range", body = edge::ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
    ),
    security(("bearer" = []))
)]
pub(super) async fn get_plan(
    State(api): State<Arc<TrafficRoutes>>,
    _caller: RobotCaller,
    Path(id): Path<String>,
    Query(query): Query<PlanQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let wait_s = query.wait_s.unwrap_or(0.0);
    if !(wait_s.is_finite() && (0.0..=MAX_WAIT_S).contains(&wait_s)) {
        return Err(ApiError::new(
            ErrorCode::Unprocessable,
            format!("wait_s must lie in [0, {MAX_WAIT_S}] seconds, got {wait_s}"),
        )
        .with_field("wait_s".to_owned()));
    }
    let known = known_revision(&headers, &id)?;
    let schedule = schedule(&api).await?;
    // Subscribed before the first read: no revision falls between the two.
    let mut changes = schedule.changes();
    let deadline = Instant::now() + Duration::from_secs_f64(wait_s);
    loop {
        let planned = schedule
            .plan(&id)
            .await
            .map_err(traffic_error)?
            .ok_or_else(|| {
                ApiError::new(ErrorCode::NotFound, format!("no committed plan `{id}`"))
            })?;
        let revision = planned.itinerary.revision;
        let unchanged = match known {
            Known::Nothing => false,
            Known::Any => true,
            Known::Revision(r) if r > revision => {
                return Err(ApiError::new(
                    ErrorCode::Conflict,
                    format!(
                        "plan `{id}` is at revision {revision}: revision {r} (If-None-Match) was never sent"
                    ),
                )
                .with_field("If-None-Match".to_owned()));
            }
            Known::Revision(r) => r == revision,
        };
        if !unchanged {
            let on_floor = schedule
                .plans_on(&planned.itinerary.floor)
                .await
                .map_err(traffic_error)?;
            let status = PlanStatus::of(planned, schedule.now_ms(), &on_floor);
            return Ok(tagged(Json(status).into_response(), &id, revision));
        }
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() || api.shutdown.is_cancelled() {
            return Ok(tagged(
                StatusCode::NOT_MODIFIED.into_response(),
                &id,
                revision,
            ));
        }
        wait_for_change(&api, &mut changes, &id, left.min(POLL)).await;
    }
}

/// Waits up to `within` for a change of plan `id` in this process (another process's shows at
/// the next read).
async fn wait_for_change(
    api: &TrafficRoutes,
    changes: &mut broadcast::Receiver<Change>,
    id: &str,
    within: Duration,
) {
    let ours = |c: &Change| match c {
        Change::Committed { itinerary, .. }
        | Change::Revised { itinerary, .. }
        | Change::Progressed { itinerary, .. } => itinerary.plan_id == id,
        Change::Removed { plan_id, .. } => plan_id == id,
    };
    let sleep = tokio::time::sleep(within);
    tokio::pin!(sleep);
    loop {
        tokio::select! {
            change = changes.recv() => match change {
                Ok(c) if ours(&c) => return,
                Ok(_) => {}
                // Behind, or closed: read the schedule again.
                Err(_) => return,
            },
            () = &mut sleep => return,
            () = api.shutdown.cancelled() => return,
        }
    }
}

fn tagged(mut response: Response, plan_id: &str, revision: u32) -> Response {
    if let Ok(v) = HeaderValue::from_str(&etag(plan_id, revision)) {
        response.headers_mut().insert(header::ETAG, v);
    }
    response
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(v: &str) -> HeaderMap {
        let mut h = HeaderMap::new();
        h.insert(header::IF_NONE_MATCH, HeaderValue::from_str(v).unwrap());
        h
    }

    #[test]
    fn tags_name_the_revision_and_the_plan() {
        let tag = etag("p-1", 3);
        assert_eq!(
            known_revision(&header(&tag), "p-1").unwrap(),
            Known::Revision(3)
        );
        let both = format!("{}, {tag}", etag("p-1", 2));
        assert_eq!(
            known_revision(&header(&both), "p-1").unwrap(),
            Known::Revision(3)
        );
        assert_eq!(known_revision(&header("*"), "p-1").unwrap(), Known::Any);
        assert_eq!(
            known_revision(&HeaderMap::new(), "p-1").unwrap(),
            Known::Nothing
        );
        let other = known_revision(&header(&tag), "p-2").unwrap_err();
        assert!(
            other.message().contains("another plan"),
            "{}",
            other.message()
        );
        assert_eq!(other.field(), Some("If-None-Match"));
        for bad in ["\"abc\"", "W/\"3\"", "3-ff", "\"-1-00\""] {
            let e = known_revision(&header(bad), "p-1").unwrap_err();
            assert_eq!(e.code(), ErrorCode::Unprocessable, "{bad}");
        }
    }
}
