//! The fleet's traffic schedule over HTTP: what is committed on a floor, a plan cancelled, a
//! robot's progress on its plan. Plans are committed by `POST /v1/plan` (the planner); these
//! routes read and amend what it committed.

use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::{Path, Query, State};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{delete, get, post};
use axum::{Json, Router};
use edge::{ApiError, ErrorCode, Principal, RobotCaller, Role, TokenSource, Tokens};
use serde::{Deserialize, Serialize};
use tokio::sync::broadcast;
use tokio_util::sync::CancellationToken;
use traffic::{Change, Itinerary, Schedule, TrafficError};
use utoipa::{IntoParams, ToSchema};

use crate::streams::{StreamLimits, StreamPermit};

pub(crate) mod plans;

/// The state of the traffic routes.
pub struct TrafficRoutes {
    /// Who may do what.
    pub tokens: Tokens,
    /// The fleet's traffic schedule in the job database.
    pub fleet: Arc<jobs::QueueFleet>,
    /// The plan use case: which floor a place is on, where a robot stands.
    pub planner: Arc<planner::Planner>,
    /// Fires when the process shuts down: event streams end.
    pub shutdown: CancellationToken,
    /// Event streams open at once.
    pub streams: Arc<StreamLimits>,
}

impl TokenSource for TrafficRoutes {
    fn tokens(&self) -> &Tokens {
        &self.tokens
    }
}

/// The routes of the traffic schedule.
pub fn router(state: Arc<TrafficRoutes>) -> Router {
    Router::new()
        .route("/v1/places/{id}/traffic", get(floor_traffic))
        .route("/v1/places/{id}/traffic/events", get(floor_traffic_events))
        .route("/v1/places/{id}/traffic/standing", post(stand))
        .route("/v1/plans/{id}", delete(cancel_plan).get(plans::get_plan))
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
    pub plans: Vec<wire::itinerary::Itinerary>,
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
    /// The revision of the plan the robot drives: it acknowledges that revision (it learnt of
    /// it). A revision the plan never had is refused (409) [default: none acknowledged].
    #[serde(default)]
    pub revision: Option<u32>,
}

/// Where a robot stands with no plan (an idle robot, as a fleet adapter reports it).
#[derive(Debug, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Standing {
    /// The robot (identifier or IRI).
    pub robot: String,
    /// Position x in the floor's map frame, metres.
    pub x: f64,
    /// Position y, metres.
    pub y: f64,
    /// Heading, radians [default: 0].
    #[serde(default)]
    pub yaw: f64,
    /// From when, ms since the Unix epoch [default: now].
    #[serde(default)]
    pub time_ms: Option<i64>,
    /// For how long, seconds, in (0, 3600] [default: 300]; its next plan replaces it sooner.
    #[serde(default = "default_stand_s")]
    pub for_s: f64,
}

fn default_stand_s() -> f64 {
    300.0
}

fn traffic_error(e: TrafficError) -> ApiError {
    match e {
        TrafficError::Invalid(m) => ApiError::new(ErrorCode::Unprocessable, m),
        e @ TrafficError::UnknownRevision { .. } => {
            ApiError::new(ErrorCode::Conflict, e.to_string()).with_field("revision".to_owned())
        }
        e @ TrafficError::SetOff { .. } => ApiError::new(ErrorCode::Conflict, e.to_string()),
        e @ TrafficError::NotFound { .. } => ApiError::new(ErrorCode::NotFound, e.to_string()),
        e @ TrafficError::NotYourPlan { .. } => ApiError::new(ErrorCode::Forbidden, e.to_string()),
        e @ (TrafficError::VersionChanged { .. } | TrafficError::PlanIdTaken { .. }) => {
            ApiError::new(ErrorCode::Conflict, e.to_string())
        }
        e => ApiError::new(ErrorCode::NotReady, e.to_string()),
    }
}

async fn schedule(api: &TrafficRoutes) -> Result<&traffic::Schedule, ApiError> {
    api.fleet
        .schedule()
        .await
        .map_err(|e| ApiError::new(ErrorCode::NotReady, e.to_string()))
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
async fn own_plan(
    api: &TrafficRoutes,
    caller: &Principal,
    id: &str,
) -> Result<Itinerary, ApiError> {
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
    State(api): State<Arc<TrafficRoutes>>,
    _caller: RobotCaller,
    Path(id): Path<String>,
    Query(query): Query<TrafficQuery>,
) -> Result<Json<FloorTraffic>, ApiError> {
    let floor = traffic_floor(&api, id, query.robot).await?;
    let schedule = schedule(&api).await?;
    Ok(Json(floor_snapshot(schedule, floor).await?))
}

/// The floor a traffic route names: its IRI, or the floor of a place on `robot`'s map.
async fn traffic_floor(
    api: &TrafficRoutes,
    id: String,
    robot: Option<String>,
) -> Result<String, ApiError> {
    if id.contains("://") && robot.is_none() {
        return Ok(id);
    }
    let robot = robot.ok_or_else(|| {
        ApiError::new(
            ErrorCode::BadRequest,
            "give the floor's IRI, or a place with `robot` (identifier or IRI) to find its floor",
        )
    })?;
    Ok(api
        .planner
        .floor(&id, &robot)
        .await
        .map_err(crate::plan::plan_failure)?
        .floor
        .clone())
}

async fn floor_snapshot(schedule: &Schedule, floor: String) -> Result<FloorTraffic, ApiError> {
    let (version, plans) = schedule
        .snapshot(&floor, schedule.now_ms())
        .await
        .map_err(traffic_error)?;
    Ok(FloorTraffic {
        floor,
        version,
        plans: plans.into_iter().map(Into::into).collect(),
    })
}

/// The floor's traffic as server-sent events, for a live view: first a `snapshot` (what
/// `GET /v1/places/{id}/traffic` answers), then every change as it happens: `committed`,
/// `revised` (a plan's new revision, before its robot set off), `removed` (cancelled or
/// replaced) and `progressed` (`data`: the change as JSON, with its
/// `kind`). Each event's `id` is the floor's version after it. Changes made by another API
/// process sharing the job database show as a new `snapshot` within a second, as does a reader
/// that fell behind. An itinerary leaves at its `expires_unix_ms` without an event.
#[utoipa::path(
    get,
    path = "/v1/places/{id}/traffic/events",
    params(("id" = String, Path, description = "A floor's IRI, or a place on a floor (identifier or IRI) with `robot`"), TrafficQuery),
    responses(
        (status = 200, content_type = "text/event-stream", body = String),
        (status = 400, description = "A place without `robot`", body = edge::ErrorBody),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 404, description = "Unknown place", body = edge::ErrorBody),
        (status = 429, description = "This token already has 8 event streams open (`too_many_requests`, with `Retry-After`); close one.", body = edge::ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
    ),
    security(("bearer" = []))
)]
async fn floor_traffic_events(
    State(api): State<Arc<TrafficRoutes>>,
    RobotCaller(caller): RobotCaller,
    Path(id): Path<String>,
    Query(query): Query<TrafficQuery>,
) -> Result<Response, ApiError> {
    let floor = traffic_floor(&api, id, query.robot).await?;
    let schedule = schedule(&api).await?.clone();
    let permit = api.streams.open(&caller.name)?;
    // Subscribed before the first snapshot is read: no change falls between the two.
    let changes = schedule.changes();
    let stream = traffic_stream(TrafficCursor {
        _permit: permit,
        api,
        schedule,
        floor,
        changes,
        snapshot_due: true,
        snapshot_version: 0,
        version: 0,
        poll: {
            let mut poll = tokio::time::interval(VERSION_POLL);
            poll.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
            poll
        },
    });
    Ok(Sse::new(stream)
        .keep_alive(KeepAlive::new().interval(Duration::from_secs(15)))
        .into_response())
}

/// How often a traffic stream looks for changes made by other processes.
const VERSION_POLL: Duration = Duration::from_secs(1);

struct TrafficCursor {
    /// Held while the stream lives.
    _permit: StreamPermit,
    api: Arc<TrafficRoutes>,
    schedule: Schedule,
    floor: String,
    changes: broadcast::Receiver<Change>,
    /// Whether the next event is a snapshot (at the start, after a gap or a lag).
    snapshot_due: bool,
    /// The version of the last snapshot sent: changes up to it are in it.
    snapshot_version: i64,
    /// The newest version sent.
    version: i64,
    /// When to look at the floor's version again (not reset by other floors' changes).
    poll: tokio::time::Interval,
}

fn change_event(change: &Change) -> Event {
    let kind = match change {
        Change::Committed { .. } => "committed",
        Change::Revised { .. } => "revised",
        Change::Removed { .. } => "removed",
        Change::Progressed { .. } => "progressed",
    };
    Event::default()
        .id(change.version().to_string())
        .event(kind)
        .data(serde_json::to_string(change).unwrap_or_default())
}

fn traffic_stream(
    cursor: TrafficCursor,
) -> impl futures_util::Stream<Item = Result<Event, Infallible>> + Send {
    futures_util::stream::unfold(cursor, |mut c| async move {
        loop {
            if c.api.shutdown.is_cancelled() {
                return None;
            }
            if c.snapshot_due {
                let snapshot = match floor_snapshot(&c.schedule, c.floor.clone()).await {
                    Ok(s) => s,
                    Err(e) => {
                        tracing::warn!(floor = %c.floor, error = %e.message(), "reading the floor's traffic failed");
                        return None;
                    }
                };
                c.snapshot_due = false;
                c.snapshot_version = snapshot.version;
                c.version = snapshot.version;
                let event = Event::default()
                    .id(snapshot.version.to_string())
                    .event("snapshot")
                    .data(serde_json::to_string(&snapshot).unwrap_or_default());
                return Some((Ok(event), c));
            }
            tokio::select! {
                change = c.changes.recv() => match change {
                    Ok(change) if change.floor() == c.floor => {
                        let v = change.version();
                        if v <= c.snapshot_version {
                            continue;
                        }
                        if v > c.version + 1 {
                            // Another process changed the floor in between: start over.
                            c.snapshot_due = true;
                            continue;
                        }
                        c.version = v;
                        return Some((Ok(change_event(&change)), c));
                    }
                    Ok(_) => {}
                    Err(broadcast::error::RecvError::Lagged(_)) => c.snapshot_due = true,
                    Err(broadcast::error::RecvError::Closed) => return None,
                },
                _ = c.poll.tick() => {
                    match c.schedule.version(&c.floor).await {
                        Ok(v) if v > c.version => c.snapshot_due = true,
                        Ok(_) => {}
                        Err(e) => tracing::warn!(floor = %c.floor, error = %e, "reading the floor's version failed"),
                    }
                }
                () = c.api.shutdown.cancelled() => return None,
            }
        }
    })
}

/// Records where a robot stands with no plan (replacing its itinerary on the schedule), so the
/// plans of other robots keep clear of it: routed around it, or waiting for its next plan.
#[utoipa::path(
    post,
    path = "/v1/places/{id}/traffic/standing",
    params(("id" = String, Path, description = "The robot's floor, or a place on it (identifier or IRI)")),
    request_body = Standing,
    responses(
        (status = 200, description = "Recorded: the robot standing, as the schedule holds it (one pose, until `expires_unix_ms`)", body = wire::itinerary::Itinerary),
        (status = 400, description = "Malformed body", body = edge::ErrorBody),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 403, description = "Another robot (a robot's token acts only for itself)", body = edge::ErrorBody),
        (status = 404, description = "Unknown robot or place", body = edge::ErrorBody),
        (status = 409, description = "Inside the footprint another robot's schedule reserves there at that time (details: `robots`)", body = edge::ErrorBody),
        (status = 413, response = edge::error::responses::PayloadTooLarge),
        (status = 415, response = edge::error::responses::UnsupportedMediaType),
        (status = 422, description = "The robot does not fit there (a wall or an object), a value out of range, or the floor's schedule is full", body = edge::ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
    ),
    security(("bearer" = []))
)]
async fn stand(
    State(api): State<Arc<TrafficRoutes>>,
    RobotCaller(caller): RobotCaller,
    Path(id): Path<String>,
    Json(standing): Json<Standing>,
) -> Result<Json<wire::itinerary::Itinerary>, ApiError> {
    let planner = &api.planner;
    let floor = planner
        .floor(&id, &standing.robot)
        .await
        .map_err(crate::plan::plan_failure)?;
    if !acts_for(&caller, &floor.robot) {
        return Err(ApiError::new(
            ErrorCode::Forbidden,
            format!(
                "only {} (a token named after it) or an engineer may say where it stands",
                floor.robot
            ),
        ));
    }
    let at = sim::Pose2::new(standing.x, standing.y, standing.yaw);
    let recorded = planner
        .stand(&standing.robot, &id, at, standing.time_ms, standing.for_s)
        .await
        .map_err(crate::plan::plan_failure)?;
    tracing::info!(robot = %recorded.robot, plan = %recorded.plan_id, "robot standing recorded");
    Ok(Json(recorded.into()))
}

/// Cancels a committed plan: its robot's place in the schedule is freed at once.
#[utoipa::path(
    delete,
    path = "/v1/plans/{id}",
    params(("id" = String, Path, description = "The plan's id (`schedule.plan_id` of its answer)")),
    responses(
        (status = 200, description = "Cancelled: the plan as it was committed", body = wire::itinerary::Itinerary),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 403, description = "Another robot's plan", body = edge::ErrorBody),
        (status = 404, description = "No such committed plan (or it expired)", body = edge::ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
    ),
    security(("bearer" = []))
)]
async fn cancel_plan(
    State(api): State<Arc<TrafficRoutes>>,
    RobotCaller(caller): RobotCaller,
    Path(id): Path<String>,
) -> Result<Json<wire::itinerary::Itinerary>, ApiError> {
    own_plan(&api, &caller, &id).await?;
    let cancelled = schedule(&api)
        .await?
        .cancel(&id)
        .await
        .map_err(traffic_error)?
        .ok_or_else(|| ApiError::new(ErrorCode::NotFound, format!("no committed plan `{id}`")))?;
    tracing::info!(plan = %id, by = %caller.name, "plan cancelled");
    Ok(Json(cancelled.into()))
}

/// Reports where the plan's robot is: the rest of its schedule shifts by its observed delay.
#[utoipa::path(
    post,
    path = "/v1/plans/{id}/progress",
    params(("id" = String, Path, description = "The plan's id")),
    request_body = Progress,
    responses(
        (status = 200, description = "The plan as now scheduled (`delay_s`: how late the robot is; `revision`: the one to drive, newer than the report's where the plan was revised), and how far the robot may go now (`may_go_until_t_s`, the plans it passes after)", body = plans::ProgressAnswer),
        (status = 400, description = "Malformed body", body = edge::ErrorBody),
        (status = 401, response = edge::error::responses::Unauthorized),
        (status = 403, description = "Another robot's plan", body = edge::ErrorBody),
        (status = 404, description = "No such committed plan (or it expired)", body = edge::ErrorBody),
        (status = 409, description = "`revision` acknowledges a revision the plan never had (`field`: `revision`)", body = edge::ErrorBody),
        (status = 413, response = edge::error::responses::PayloadTooLarge),
        (status = 415, response = edge::error::responses::UnsupportedMediaType),
        (status = 422, description = "A position or time that is not a number", body = edge::ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
    ),
    security(("bearer" = []))
)]
async fn report_progress(
    State(api): State<Arc<TrafficRoutes>>,
    RobotCaller(caller): RobotCaller,
    Path(id): Path<String>,
    Json(progress): Json<Progress>,
) -> Result<Json<plans::ProgressAnswer>, ApiError> {
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
        .progress(
            &id,
            &plan.robot,
            at,
            (progress.x, progress.y),
            progress.revision,
        )
        .await
        .map_err(traffic_error)?;
    let on_floor = schedule
        .plans_on(&updated.itinerary.floor)
        .await
        .map_err(traffic_error)?;
    Ok(Json(plans::ProgressAnswer::of(
        updated,
        schedule.now_ms(),
        &on_floor,
    )))
}
