//! `POST /v1/plan` — what robots call (the paper's Figure 4): the request translated into the
//! planner's query, [`planner::Planner::plan`] (which decides everything: policy, roadmap,
//! people, fallback), and its outcome answered as JSON or as a ROS 2 recording.
//!
//! - [`error`]: [`PlanErrorResponse`], the executor's refusals as API errors (code, `reason`,
//!   `details`);
//! - [`roadmap_view`]: `GET /v1/roadmaps` and the route graph as GeoJSON;
//! - [`rosbag`]: a rehearsal as a ROS 2 MCAP recording.

pub mod error;
#[allow(
    unused_qualifications,
    reason = "utoipa's path macro expands the query extractor's type with its span"
)]
pub mod roadmap_view;
pub mod rosbag;

use std::sync::Arc;
use std::time::Instant;

use axum::extract::State;
use axum::http::HeaderMap;
use axum::response::IntoResponse;
use axum::routing::{get, post};
use axum::{Json, Router};
use edge::{ApiError, ErrorCode, RobotCaller, TokenSource, Tokens};
use planner::PlanFailure;
use sim::World;
use wire::{PlanApiRequest, PlanApiResponse, types};

pub use self::error::PlanErrorResponse;
/// The state of the plan and roadmap routes.
pub struct PlanRoutes {
    /// Who may do what.
    pub tokens: Tokens,
    /// The plan use case.
    pub planner: Arc<planner::Planner>,
}

impl TokenSource for PlanRoutes {
    fn tokens(&self) -> &Tokens {
        &self.tokens
    }
}

/// The routes of plans and roadmaps.
pub fn router(state: Arc<PlanRoutes>) -> Router {
    Router::new()
        .route("/v1/plan", post(plan))
        .route("/v1/roadmaps", get(roadmap_view::get_roadmap))
        .route(
            "/v1/places/{id}/route-graph.geojson",
            get(roadmap_view::route_graph),
        )
        .with_state(state)
}

/// The media types `POST /v1/plan` answers in, JSON first (no `Accept`, or `*/*`, gets it).
const PLAN_MEDIA_TYPES: &[&str] = &["application/json", rosbag::MEDIA_TYPE];

/// Whether the request's `Accept` asks for the rehearsal as an MCAP recording (else JSON); 406
/// when it takes neither, naming both.
fn wants_recording(headers: &HeaderMap) -> Result<bool, ApiError> {
    let accept = headers
        .get(axum::http::header::ACCEPT)
        .map(|v| v.to_str().unwrap_or("\u{fffd}"));
    let chosen = edge::accept::choose(accept, PLAN_MEDIA_TYPES, "POST /v1/plan")?;
    Ok(chosen == rosbag::MEDIA_TYPE)
}

/// A planner's refusal as the API answers it: a status per cause, and the request field at
/// fault where the cause names one.
pub(crate) fn plan_failure(e: PlanFailure) -> ApiError {
    let field = e.field().map(str::to_owned);
    let error = match e {
        PlanFailure::BadRequest(m) => ApiError::new(ErrorCode::BadRequest, m.message),
        PlanFailure::NotFound(m) => ApiError::new(ErrorCode::NotFound, m.to_string()),
        PlanFailure::Unprocessable(m) => ApiError::new(ErrorCode::Unprocessable, m.to_string()),
        PlanFailure::Unavailable(m) => ApiError::new(ErrorCode::NotReady, m.to_string()),
        PlanFailure::RoadmapNotReady(m) => ApiError::new(ErrorCode::Conflict, m.to_string()),
        PlanFailure::PolicyRoadmapUnreachable(ref p) => {
            ApiError::new(ErrorCode::Conflict, e.to_string()).with_details(p.details())
        }
        PlanFailure::FleetConflict(f) => ApiError::new(ErrorCode::Conflict, f.message)
            .with_details(serde_json::json!({
                "robots": f.robots,
                "earliest_start_ms": f.earliest_start_unix_ms,
            })),
        PlanFailure::Plan(p) => return p.to_api_error(),
        PlanFailure::Internal { what, source } => match source {
            Some(source) => ApiError::internal(format!("{what}: {source}")),
            None => ApiError::internal(what),
        },
    };
    match field {
        Some(field) => error.with_field(field),
        None => error,
    }
}

/// Validate a plan in the mental simulation before the robot moves.
#[utoipa::path(
    post,
    path = "/v1/plan",
    request_body(content = types::PlanApiRequestDoc, description = "One goal (`goal`) or a non-empty sequence of goals (`goals`, at most 1000), never both; every option within its bounds."),
    responses(
        (status = 200, description = "Waypoints validated in the mental simulation: as JSON, or with `Accept: application/x-mcap` the whole rehearsal as a ROS 2 recording (MCAP, CDR): `/map`, `/plan`, `/tf_static`, and per attempt `/rehearsal/attempt`, `/rehearsal/attempt_path`, and per simulated step `/rehearsal/pose`, `/tf`, `/rehearsal/scan`", content((PlanApiResponse = "application/json"), (Vec<u8> = "application/x-mcap"))),
        (status = 400, description = "Malformed request: the body is not JSON, neither or both of `goal` and `goals`, too many goals, an option out of range", body = edge::ErrorBody),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 403, response = edge::error::responses::Forbidden),
        (status = 404, description = "Unknown robot, place or policy", body = edge::ErrorBody),
        (status = 409, description = "No attempt could validate the plan (the attempts are in the details); `options.roadmap` is `policy` and the policy-aware roadmap is not built yet or joins no leg; or the plan conflicts with other robots' committed plans and no wait within `options.max_wait_s` resolves it (details: `robots` in the way, `earliest_start_ms` that fits)", body = edge::ErrorBody),
        (status = 406, description = "The request's `Accept` takes neither JSON nor MCAP (the answer's forms).", body = edge::ErrorBody),
        (status = 413, response = edge::error::responses::PayloadTooLarge),
        (status = 415, response = edge::error::responses::UnsupportedMediaType),
        (status = 422, description = "The body does not fit the schema (a missing or unknown field, a wrong type); the start or a goal is inside an obstacle, outside the map, or unreachable from the start; the place is on no floor; the map or the policy cannot be used", body = edge::ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
    ),
    security(("bearer" = []))
)]
async fn plan(
    State(api): State<Arc<PlanRoutes>>,
    _caller: RobotCaller,
    headers: HeaderMap,
    Json(mut req): Json<PlanApiRequest>,
) -> Result<axum::response::Response, ApiError> {
    let started = Instant::now();
    let recording = wants_recording(&headers)?;
    // A recording replays every attempt step by step.
    req.options.trace |= recording;
    let start = req.start;
    let query = req.into_query().map_err(|e| plan_failure(e.into()))?;
    // When this future is dropped (the request timed out, the client hung up), the rehearsal
    // sees the stop at its next check and ends.
    let stop = rehearsal::Stop::new();
    let _stop_on_drop = rehearsal::StopOnDrop(stop.clone());
    let outcome = api.planner.plan(query, stop).await.map_err(plan_failure)?;
    let world = Arc::clone(&outcome.world);
    let service_ms = started.elapsed().as_secs_f64() * 1000.0;
    let answer = PlanApiResponse::of(outcome, &start, service_ms);
    if !recording {
        return Ok(Json(answer).into_response());
    }
    let bytes = tokio::task::spawn_blocking(move || recording_of(&answer, &world))
        .await
        .map_err(|e| ApiError::internal(format!("recording task failed: {e}")))??;
    Ok((
        [(axum::http::header::CONTENT_TYPE, rosbag::MEDIA_TYPE)],
        bytes,
    )
        .into_response())
}

/// The answer as an MCAP recording ([`rosbag`]).
fn recording_of(answer: &PlanApiResponse, world: &World) -> Result<Vec<u8>, ApiError> {
    let spec = world.spec();
    let frames = sim::export::RobotFrames::of(&spec.robot);
    let start_ns = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
    let mut metadata = std::collections::BTreeMap::from([
        ("robot".to_owned(), answer.robot.clone()),
        ("floor".to_owned(), answer.floor.clone()),
        (
            "controller".to_owned(),
            answer.report.controller_description.clone(),
        ),
    ]);
    if let Some(p) = &answer.policy {
        metadata.insert("policy".to_owned(), p.clone());
    }
    if let Some(n) = &answer.note {
        metadata.insert("note".to_owned(), n.clone());
    }
    rosbag::write(&rosbag::Recording {
        path: &answer.path,
        report: &answer.report,
        grid: spec.floor.as_ref().map(|f| &f.grid),
        map_frame: spec.map_frame(),
        frames: &frames,
        laser: &spec.robot.laser,
        start_ns,
        metadata,
    })
    .map_err(|e| ApiError::internal(format!("writing the recording: {e}")))
}
