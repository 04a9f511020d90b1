//! The fleet's traffic schedule over HTTP: what is committed on a floor, a plan cancelled, a
//! robot's progress on its plan. Plans are committed by `POST /v1/plan` (the planner); these
//! routes read and amend what it committed.

use std::sync::Arc;

use axum::extract::{Path, Query, State};
use axum::routing::{delete, get, post};
use axum::{Json, Router};
use edge::{ApiError, ErrorCode, Principal, RobotCaller, Role};
use serde::{Deserialize, Serialize};
use traffic::{Itinerary, TrafficError};
use utoipa::{IntoParams, ToSchema};

use crate::jobs::JobsApi;

/// The routes of the traffic schedule, over the jobs API's state (its job database).
pub fn router(state: Arc<JobsApi>) -> Router {
    Router::new()
        .route("/v1/places/{id}/traffic", get(floor_traffic))
        .route("/v1/plans/{id}", delete(cancel_plan))
        .route("/v1/plans/{id}/progress", post(report_progress))
        .with_state(state)
}

/// Which floor's traffic.
#[derive(Debug, Deserialize, IntoParams)]
pub struct TrafficQuery {
    /// A robot (identifier or IRI) whose floor map the place is found on; not needed when
    /// the path names the floor by its IRI.
    #[param(nullable = false)]
    pub robot: Option<String>,
}

/// What is committed on a floor now.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
pub struct FloorTraffic {
    /// The floor's IRI.
    pub floor: String,
    /// The floor schedule's version: it moves on with every commit, cancel and progress.
    pub version: i64,
    /// Every unexpired plan on the floor, by start.
    pub plans: Vec<Itinerary>,
}

/// Where a robot is on its plan, and when.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Progress {
    /// Position x in the floor's map frame, metres.
    pub x: f64,
    /// Position y, metres.
    pub y: f64,
    /// When the robot was there, ms since the Unix epoch [default: now].
    #[serde(default)]
    pub time_ms: Option<i64>,
}

fn traffic_error(e: TrafficError) -> ApiError {
    match e {
        TrafficError::Invalid(m) => ApiError::new(ErrorCode::Unprocessable, m),
        e @ TrafficError::NotFound { .. } => ApiError::new(ErrorCode::NotFound, e.to_string()),
        e @ TrafficError::NotYourPlan { .. } => ApiError::new(ErrorCode::Forbidden, e.to_string()),
        e @ (TrafficError::VersionChanged { .. } | TrafficError::PlanIdTaken { .. }) => {
            ApiError::new(ErrorCode::Conflict, e.to_string())
        }
        e => ApiError::new(ErrorCode::NotReady, e.to_string()),
    }
}

async fn schedule(api: &JobsApi) -> Result<&traffic::Schedule, ApiError> {
    api.env
        .fleet
        .schedule()
        .await
        .map_err(|m| ApiError::new(ErrorCode::NotReady, m))
}

/// Whether `caller` may act for `robot` (an IRI): engineers for every robot, a robot's token
/// only for the robot it is named after (its IRI, or the IRI's last segment).
fn acts_for(caller: &Principal, robot: &str) -> bool {
    caller.role == Role::Engineer
        || caller.name == robot
        || robot.rsplit('/').next() == Some(caller.name.as_str())
}

/// A plan of the schedule, 404 when there is none (or it expired), 403 when `caller` may not
/// act for its robot.
async fn own_plan(api: &JobsApi, caller: &Principal, id: &str) -> Result<Itinerary, ApiError> {
    let plan = schedule(api)
        .await?
        .get(id)
        .await
        .map_err(traffic_error)?
        .ok_or_else(|| ApiError::new(ErrorCode::NotFound, format!("no committed plan `{id}`")))?;
    if !acts_for(caller, &plan.robot) {
        return Err(ApiError::new(
            ErrorCode::Forbidden,
            format!(
                "plan `{id}` is {}'s: only its robot (a token named after it) or an engineer may change it",
                plan.robot
            ),
        ));
    }
    Ok(plan)
}

/// What the fleet's plans commit on a floor now.
#[utoipa::path(
    get,
    path = "/v1/places/{id}/traffic",
    params(("id" = String, Path, description = "A floor's IRI, or a place on a floor (identifier or IRI) with `robot`"), TrafficQuery),
    responses(
        (status = 200, description = "The floor's version and every unexpired committed plan", body = FloorTraffic),
        (status = 400, description = "A place without `robot`", body = edge::ErrorBody),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 404, description = "Unknown place", body = edge::ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
    ),
    security(("bearer" = []))
)]
async fn floor_traffic(
    State(api): State<Arc<JobsApi>>,
    _caller: RobotCaller,
    Path(id): Path<String>,
    Query(query): Query<TrafficQuery>,
) -> Result<Json<FloorTraffic>, ApiError> {
    let floor = if id.contains("://") && query.robot.is_none() {
        id
    } else {
        let robot = query.robot.ok_or_else(|| {
            ApiError::new(
                ErrorCode::BadRequest,
                "give the floor's IRI, or a place with `robot` (identifier or IRI) to find its floor",
            )
        })?;
        api.env
            .planner
            .floor(&id, &robot)
            .await
            .map_err(crate::plan::plan_failure)?
            .floor
            .clone()
    };
    let schedule = schedule(&api).await?;
    let (version, plans) = schedule
        .snapshot(&floor, schedule.now_ms())
        .await
        .map_err(traffic_error)?;
    Ok(Json(FloorTraffic {
        floor,
        version,
        plans,
    }))
}

/// Cancels a committed plan: its robot's place in the schedule is freed at once.
#[utoipa::path(
    delete,
    path = "/v1/plans/{id}",
    params(("id" = String, Path, description = "The plan's id (`schedule.plan_id` of its answer)")),
    responses(
        (status = 200, description = "Cancelled: the plan as it was committed", body = Itinerary),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 403, description = "Another robot's plan", body = edge::ErrorBody),
        (status = 404, description = "No such committed plan (or it expired)", body = edge::ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
    ),
    security(("bearer" = []))
)]
async fn cancel_plan(
    State(api): State<Arc<JobsApi>>,
    RobotCaller(caller): RobotCaller,
    Path(id): Path<String>,
) -> Result<Json<Itinerary>, ApiError> {
    own_plan(&api, &caller, &id).await?;
    let cancelled = schedule(&api)
        .await?
        .cancel(&id)
        .await
        .map_err(traffic_error)?
        .ok_or_else(|| ApiError::new(ErrorCode::NotFound, format!("no committed plan `{id}`")))?;
    tracing::info!(plan = %id, by = %caller.name, "plan cancelled");
    Ok(Json(cancelled))
}

/// Reports where the plan's robot is: the rest of its schedule shifts by its observed delay.
#[utoipa::path(
    post,
    path = "/v1/plans/{id}/progress",
    params(("id" = String, Path, description = "The plan's id")),
    request_body = Progress,
    responses(
        (status = 200, description = "The plan as now scheduled (`delay_s`: how late the robot is)", body = Itinerary),
        (status = 400, description = "Malformed body", body = edge::ErrorBody),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 403, description = "Another robot's plan", body = edge::ErrorBody),
        (status = 404, description = "No such committed plan (or it expired)", body = edge::ErrorBody),
        (status = 413, response = edge::error::responses::PayloadTooLarge),
        (status = 415, response = edge::error::responses::UnsupportedMediaType),
        (status = 422, description = "A position or time that is not a number", body = edge::ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
    ),
    security(("bearer" = []))
)]
async fn report_progress(
    State(api): State<Arc<JobsApi>>,
    RobotCaller(caller): RobotCaller,
    Path(id): Path<String>,
    Json(progress): Json<Progress>,
) -> Result<Json<Itinerary>, ApiError> {
    if !(progress.x.is_finite() && progress.y.is_finite()) {
        return Err(ApiError::new(
            ErrorCode::Unprocessable,
            "`x` and `y` must be finite numbers",
        ));
    }
    let plan = own_plan(&api, &caller, &id).await?;
    let schedule = schedule(&api).await?;
    let at = progress.time_ms.unwrap_or_else(|| schedule.now_ms());
    let updated = schedule
        .progress(&id, &plan.robot, at, progress.x, progress.y)
        .await
        .map_err(traffic_error)?;
    Ok(Json(updated))
}
