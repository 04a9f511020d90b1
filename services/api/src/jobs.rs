//! The jobs and policies REST API: create, list, read and cancel jobs, stream a job's events
//! (server-sent events, resumable with `Last-Event-ID`), list and download exported policies.
//!
//! Engineers create and cancel jobs; any valid token (robot or engineer) reads. A new job is a
//! [`jobs::JobRequest`] (its kind and typed payload) with how it is queued ([`NewJobRequest`]);
//! a job is shown as a [`JobView`], converted from the queue's types.

use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use edge::{
    ApiError, BearerAuth, Caller, EngineerCaller, ErrorBody, ErrorCode, ErrorDetail, Role,
    TokenSource, Tokens,
};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use tokio_util::sync::CancellationToken;
use utoipa::{OpenApi, ToSchema};
use uuid::Uuid;

use crate::policies::PolicyView;
use crate::streams::{StreamLimits, StreamPermit};
use jobs::{EvaluatePayload, JobEnv, PayloadError, TrainPayload};
use queue::{Job, JobEvent, JobState, LazyQueue, NewJob, QueueError};

/// The OpenAPI document of the fleet's routes (plans, roadmaps, traffic, jobs, policies),
/// generated from their handlers.
#[derive(OpenApi)]
#[openapi(
    info(title = "Mentalsim fleet service", description = "Plans validated in the mental simulation (POST /v1/plan); jobs (train, evaluate, validate, roadmap) in a durable queue, their progress as server-sent events, and the policies training exports."),
    paths(create_job, list_jobs, get_job, cancel_job, job_events, job_curves_csv, job_curves_png, crate::policies::list_policies, crate::policies::get_policy, crate::policies::policy_weights, crate::policies::policy_metadata, crate::plan::plan, crate::plan::roadmap_view::get_roadmap, crate::plan::roadmap_view::route_graph, crate::traffic::floor_traffic, crate::traffic::floor_traffic_events, crate::traffic::plans::get_plan, crate::traffic::cancel_plan, crate::traffic::report_progress, crate::traffic::stand),
    components(
        schemas(NewJobRequest, jobs::JobRequest, JobView, TrainPayload, EvaluatePayload, jobs::RoadmapPayload, jobs::JobResult, jobs::TrainResult, jobs::EvaluateResult, jobs::RoadmapResult, PolicyView, ErrorBody, ErrorDetail, ErrorCode, wire::types::PlanApiRequestDoc, wire::PlanApiResponse, crate::plan::roadmap_view::RoadmapView, crate::plan::roadmap_view::EdgeView, crate::traffic::FloorTraffic, crate::traffic::Progress, crate::traffic::Standing, crate::traffic::plans::PlanStatus, wire::schedule::PassingView, crate::traffic::plans::ProgressAnswer, wire::itinerary::Itinerary, wire::itinerary::TimedPose),
        responses(edge::error::responses::Unauthorized, edge::error::responses::Forbidden, edge::error::responses::StorageFull, edge::error::responses::PayloadTooLarge, edge::error::responses::UnsupportedMediaType, edge::error::responses::ServiceUnavailable)
    ),
    modifiers(&BearerAuth),
    security(("bearer" = []))
)]
pub struct FleetApi;

/// The state of the job routes.
pub struct JobRoutes {
    /// The queue (opened lazily).
    pub queue: Arc<LazyQueue>,
    /// Who may do what.
    pub tokens: Tokens,
    /// The job kinds: what a new job is checked against.
    pub kinds: Arc<JobEnv>,
    /// Fires when the process shuts down: event streams end.
    pub shutdown: CancellationToken,
    /// How often an event stream polls for new events.
    pub event_poll: Duration,
    /// Event streams open at once.
    pub streams: Arc<StreamLimits>,
}

impl TokenSource for JobRoutes {
    fn tokens(&self) -> &Tokens {
        &self.tokens
    }
}

impl std::fmt::Debug for JobRoutes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("JobRoutes")
            .field("kinds", &self.kinds)
            .finish_non_exhaustive()
    }
}

/// The job routes.
pub fn router(state: Arc<JobRoutes>) -> Router {
    Router::new()
        .route("/v1/jobs", post(create_job).get(list_jobs))
        .route("/v1/jobs/{id}", get(get_job))
        .route("/v1/jobs/{id}/cancel", post(cancel_job))
        .route("/v1/jobs/{id}/events", get(job_events))
        .route("/v1/jobs/{id}/curves.csv", get(job_curves_csv))
        .route("/v1/jobs/{id}/curves.png", get(job_curves_png))
        .with_state(state)
}

impl JobRoutes {
    /// The job `id` names; 404 for anything else.
    async fn job(&self, id: &str) -> Result<Job, ApiError> {
        let id = job_id(id)?;
        self.queue()
            .await?
            .get(id)
            .await
            .map_err(queue_error)?
            .ok_or_else(|| ApiError::not_found(format!("no job has id {id}")))
    }

    async fn queue(&self) -> Result<&queue::Queue, ApiError> {
        self.queue.get().await.map_err(|reason| {
            ApiError::new(
                ErrorCode::NotReady,
                format!("the job database is unavailable: {reason}"),
            )
        })
    }
}

fn queue_error(e: QueueError) -> ApiError {
    match e {
        QueueError::NotFound(id) => ApiError::not_found(format!("no job has id {id}")),
        QueueError::Invalid(m) => ApiError::new(ErrorCode::Unprocessable, m),
        other => ApiError::internal(other),
    }
}

/// A job refused at creation, as the API answers it.
fn payload_error(e: PayloadError) -> ApiError {
    {
        match e {
            PayloadError::UnknownKind(m) => ApiError::bad_request(m),
            PayloadError::Invalid { field, message } => {
                ApiError::new(ErrorCode::Unprocessable, format!("{field}: {message}"))
                    .with_field(field)
            }
            PayloadError::Unprocessable(m) => ApiError::new(ErrorCode::Unprocessable, m),
            PayloadError::NotFound(m) => ApiError::not_found(m),
            PayloadError::Unavailable(m) => ApiError::new(
                ErrorCode::NotReady,
                format!("cannot check the job against the knowledge service: {m}"),
            ),
        }
    }
}

fn job_id(id: &str) -> Result<Uuid, ApiError> {
    Uuid::parse_str(id).map_err(|_| ApiError::not_found(format!("no job has id {id:?}")))
}

/// A job to create: its kind and that kind's payload (one form per kind), and how it is
/// queued. Read from [`RawJobRequest`], so that an unknown kind is 400 and a payload that does
/// not fit its kind 422, naming the field.
#[derive(Debug, Serialize, Deserialize, ToSchema)]
#[serde(try_from = "RawJobRequest")]
pub struct NewJobRequest {
    /// The kind and its payload.
    #[serde(flatten)]
    pub job: jobs::JobRequest,
    /// Higher runs first [default: 0].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = -2147483648, maximum = 2147483647)]
    pub priority: Option<i32>,
    /// Attempts before the job fails for good, 1-100 [default: 3].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(minimum = 1, maximum = 100)]
    pub max_attempts: Option<u32>,
}

impl NewJobRequest {
    /// The job to enqueue.
    pub fn to_job(&self) -> NewJob {
        let mut job = self.job.to_job();
        if let Some(p) = self.priority {
            job = job.priority(p);
        }
        if let Some(n) = self.max_attempts {
            job = job.max_attempts(n);
        }
        job
    }
}

/// [`NewJobRequest`] as JSON has it, before its payload is read as its kind's.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawJobRequest {
    /// `train`, `evaluate`, `validate` or `roadmap`.
    kind: String,
    /// The kind's parameters.
    payload: Value,
    #[serde(default)]
    priority: Option<i32>,
    #[serde(default)]
    max_attempts: Option<u32>,
}

impl TryFrom<RawJobRequest> for NewJobRequest {
    type Error = PayloadError;

    fn try_from(raw: RawJobRequest) -> Result<Self, PayloadError> {
        let job = jobs::JobRequest::parse(&raw.kind, &raw.payload)?;
        if let Some(n) = raw.max_attempts
            && !(1..=100).contains(&n)
        {
            return Err(PayloadError::invalid(
                "max_attempts",
                format!("must be in 1..=100, got {n}"),
            ));
        }
        Ok(Self {
            job,
            priority: raw.priority,
            max_attempts: raw.max_attempts,
        })
    }
}

/// A job as the API shows it.
#[derive(Debug, Serialize, ToSchema)]
pub struct JobView {
    /// The job's id (UUIDv7).
    id: String,
    /// `train`, `evaluate`, `validate` or `roadmap`.
    kind: String,
    /// `queued`, `running`, `succeeded`, `failed` or `cancelled`.
    state: String,
    /// The parameters it was created with.
    #[schema(value_type = Object)]
    payload: Value,
    /// Higher runs first.
    priority: i64,
    /// Attempts counted so far (the running one included).
    attempts: u32,
    /// Attempts allowed.
    max_attempts: u32,
    /// A cancel was requested.
    cancel_requested: bool,
    /// The worker running it.
    worker: Option<String>,
    /// The latest progress report.
    #[schema(value_type = Option<Object>)]
    progress: Option<Value>,
    /// The latest checkpoint's reference.
    #[schema(value_type = Option<Object>)]
    checkpoint: Option<Value>,
    /// The result, once succeeded: its form follows `kind` (`TrainResult`, `EvaluateResult`,
    /// the `POST /v1/plan` answer for `validate`, `RoadmapResult`).
    #[schema(value_type = Option<jobs::JobResult>)]
    result: Option<Value>,
    /// The latest error.
    error: Option<String>,
    /// Created (RFC 3339, UTC).
    created: String,
    /// Last changed.
    updated: String,
    /// First started.
    started: Option<String>,
    /// Finished.
    finished: Option<String>,
    /// Not claimable before (after a failed attempt).
    run_after: String,
    /// The job's event stream.
    events: String,
}

/// A checkpoint reference as a token of `role` sees it: the server's directory is for
/// engineers only (as `/readyz` shows paths to them alone).
fn checkpoint_for(mut data: Value, role: Role) -> Value {
    if role != Role::Engineer
        && let Some(o) = data.as_object_mut()
    {
        o.remove("dir");
    }
    data
}

impl JobView {
    /// The job as a token of `role` sees it.
    fn seen_by(j: &Job, role: Role) -> Self {
        let mut view = Self::from(j);
        view.checkpoint = view.checkpoint.map(|c| checkpoint_for(c, role));
        view
    }
}

impl From<&Job> for JobView {
    fn from(j: &Job) -> Self {
        let t = jobs::rfc3339;
        Self {
            id: j.id.to_string(),
            kind: j.kind.clone(),
            state: j.state.as_str().to_owned(),
            payload: j.payload.clone(),
            priority: j.priority,
            attempts: j.attempt,
            max_attempts: j.max_attempts,
            cancel_requested: j.cancel_requested,
            worker: j.lease_owner.clone(),
            progress: j.progress.clone(),
            checkpoint: j.checkpoint.as_ref().map(|c| c.data.clone()),
            result: j.result.clone(),
            error: j.last_error.clone(),
            created: t(j.created_ms),
            updated: t(j.updated_ms),
            started: j.started_ms.map(t),
            finished: j.finished_ms.map(t),
            run_after: t(j.run_after_ms),
            events: format!("/v1/jobs/{}/events", j.id),
        }
    }
}

/// Creates a job. The payload is checked now: an unknown kind is 400; a malformed payload or a
/// value out of range is 422 naming the field; an unknown robot, place or policy is 404.
#[utoipa::path(post, path = "/v1/jobs", request_body = NewJobRequest, responses(
    (status = 201, body = JobView, headers(("location" = String, description = "the job's URL"))),
    (status = 400, description = "The body is not JSON, or the kind is unknown.", body = ErrorBody),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 403, response = edge::error::responses::Forbidden),
    (status = 404, description = "The payload names a robot, place or policy that does not exist.", body = ErrorBody),
    (status = 413, response = edge::error::responses::PayloadTooLarge),
    (status = 415, response = edge::error::responses::UnsupportedMediaType),
    (status = 422, description = "The body does not fit the schema (a missing or unknown field, a wrong type), or a value is out of range (the message names the field).", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable),
    (status = 507, response = edge::error::responses::StorageFull)))]
async fn create_job(
    State(api): State<Arc<JobRoutes>>,
    EngineerCaller(principal): EngineerCaller,
    Json(raw): Json<RawJobRequest>,
) -> Result<Response, ApiError> {
    let request = NewJobRequest::try_from(raw).map_err(payload_error)?;
    api.kinds
        .check_new(&request.job)
        .await
        .map_err(payload_error)?;
    let job = request.to_job();
    let queue = api.queue().await?;
    let id = queue.enqueue(job).await.map_err(queue_error)?;
    tracing::info!(job = %id, kind = %request.job.kind(), by = %principal.name, "job created");
    let job = queue
        .get(id)
        .await
        .map_err(queue_error)?
        .ok_or_else(|| ApiError::internal(format!("job {id} vanished after enqueue")))?;
    let mut response = (StatusCode::CREATED, Json(JobView::from(&job))).into_response();
    if let Ok(v) = HeaderValue::from_str(&format!("/v1/jobs/{id}")) {
        response.headers_mut().insert(header::LOCATION, v);
    }
    Ok(response)
}

/// Filters of the job list.
#[derive(Debug, Deserialize, utoipa::IntoParams)]
pub struct ListQuery {
    /// Only jobs in this state: `queued`, `running`, `succeeded`, `failed` or `cancelled`
    /// (empty: any).
    #[param(
        nullable = false,
        pattern = "^(queued|running|succeeded|failed|cancelled)?$"
    )]
    state: Option<String>,
    /// Only jobs of this kind (`train`, `evaluate`, `validate`, `roadmap`; empty: any).
    #[param(nullable = false)]
    kind: Option<String>,
    /// At most this many, 1-1000 [default: 50].
    #[param(nullable = false, minimum = 1, maximum = 1000)]
    limit: Option<u32>,
}

/// Jobs, newest first.
#[utoipa::path(get, path = "/v1/jobs", params(ListQuery), responses(
    (status = 200, body = [JobView]),
    (status = 400, description = "An unknown state, or a limit that is not an integer in 1-1000.", body = ErrorBody),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
async fn list_jobs(
    State(api): State<Arc<JobRoutes>>,
    Caller(caller): Caller,
    Query(query): Query<ListQuery>,
) -> Result<Json<Vec<JobView>>, ApiError> {
    let role = caller.role;
    let state = match query.state.as_deref() {
        None | Some("") => None,
        Some(s) => Some(s.parse::<JobState>().map_err(|_| {
            ApiError::bad_request(format!(
                "state: unknown job state {s:?}: expected queued, running, succeeded, failed or cancelled"
            ))
        })?),
    };
    let limit = query.limit.unwrap_or(50);
    if limit == 0 || limit > 1000 {
        return Err(ApiError::bad_request(format!(
            "limit: must be in 1..=1000, got {limit}"
        )));
    }
    let kind = query.kind.as_deref().filter(|k| !k.is_empty());
    let jobs = api
        .queue()
        .await?
        .list_by(state, kind, limit)
        .await
        .map_err(queue_error)?;
    Ok(Json(
        jobs.iter().map(|j| JobView::seen_by(j, role)).collect(),
    ))
}

/// One job: state, kind, payload, attempts, progress, result, error, timestamps.
#[utoipa::path(get, path = "/v1/jobs/{id}", params(("id" = String, Path, format = "uuid", description = "The job's id (a UUID; anything else is 404).")), responses(
    (status = 200, body = JobView),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No job has this id.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
async fn get_job(
    State(api): State<Arc<JobRoutes>>,
    Caller(caller): Caller,
    Path(id): Path<String>,
) -> Result<Json<JobView>, ApiError> {
    let role = caller.role;
    Ok(Json(JobView::seen_by(&api.job(&id).await?, role)))
}

/// Asks a job to stop: a queued job is cancelled at once; a running one stops at its next
/// progress report or heartbeat (a training checkpoints first) and ends `cancelled`.
#[utoipa::path(post, path = "/v1/jobs/{id}/cancel", params(("id" = String, Path, format = "uuid", description = "The job's id (a UUID; anything else is 404).")), responses(
    (status = 202, body = JobView),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 403, response = edge::error::responses::Forbidden),
    (status = 404, description = "No job has this id.", body = ErrorBody),
    (status = 409, description = "The job has already finished.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
async fn cancel_job(
    State(api): State<Arc<JobRoutes>>,
    EngineerCaller(principal): EngineerCaller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let id = job_id(&id)?;
    let queue = api.queue().await?;
    let before = queue
        .get(id)
        .await
        .map_err(queue_error)?
        .ok_or_else(|| ApiError::not_found(format!("no job has id {id}")))?;
    if before.state.is_finished() {
        return Err(ApiError::new(
            ErrorCode::Conflict,
            format!(
                "job {id} already finished ({}): nothing to cancel",
                before.state
            ),
        ));
    }
    queue.request_cancel(id).await.map_err(queue_error)?;
    tracing::info!(job = %id, by = %principal.name, "job cancel requested");
    let job = queue
        .get(id)
        .await
        .map_err(queue_error)?
        .ok_or_else(|| ApiError::not_found(format!("no job has id {id}")))?;
    Ok((StatusCode::ACCEPTED, Json(JobView::from(&job))).into_response())
}

/// Where an event stream starts.
#[derive(Debug, Deserialize, utoipa::IntoParams)]
pub struct EventsQuery {
    /// Replay events with ids greater than this event id, an integer (the `Last-Event-ID`
    /// header wins) [default: 0, every event]. Anything but an integer is 400.
    #[param(nullable = false)]
    after: Option<i64>,
}

/// The job's events as server-sent events: stored events after `Last-Event-ID` (or `?after=`)
/// first, then new ones as they happen. Each event's `id` is its id in the job's event log,
/// its `event` the kind (`state`, `progress`, `checkpoint`, `cancel_requested`) and its `data`
/// JSON (`{"kind", "data", "created"}`). The stream ends once the job has finished and its
/// last event was sent.
#[utoipa::path(get, path = "/v1/jobs/{id}/events", params(
        ("id" = String, Path, format = "uuid", description = "The job's id (a UUID; anything else is 404)."),
        EventsQuery,
        ("Last-Event-ID" = Option<i64>, Header, nullable = false, description = "Resume after this event id (an integer; anything else is 400); wins over `after`.")),
    responses(
    (status = 200, content_type = "text/event-stream", body = String),
    (status = 400, description = "`after` or `Last-Event-ID` is not an integer.", body = ErrorBody),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No job has this id.", body = ErrorBody),
    (status = 429, description = "This token already has 8 event streams open (`too_many_requests`, with `Retry-After`); close one.", body = ErrorBody),
    (status = 503, description = "64 event streams are open in all (`overloaded`, with `Retry-After`), or the service cannot serve now (`not_ready`, `timeout`).", body = ErrorBody)))]
async fn job_events(
    State(api): State<Arc<JobRoutes>>,
    Caller(principal): Caller,
    headers: HeaderMap,
    Path(id): Path<String>,
    Query(query): Query<EventsQuery>,
) -> Result<Response, ApiError> {
    let id = job_id(&id)?;
    let last_event_id = match headers.get("last-event-id") {
        Some(v) => Some(
            v.to_str()
                .ok()
                .and_then(|s| s.trim().parse::<i64>().ok())
                .ok_or_else(|| {
                    ApiError::bad_request("Last-Event-ID: must be an event id (an integer)")
                })?,
        ),
        None => None,
    };
    let after = last_event_id.or(query.after).unwrap_or(0);
    // 404 now, not an empty stream, for a job that does not exist.
    api.queue()
        .await?
        .get(id)
        .await
        .map_err(queue_error)?
        .ok_or_else(|| ApiError::not_found(format!("no job has id {id}")))?;
    let permit = api.streams.open(&principal.name)?;
    let stream = event_stream(api, id, after, permit, principal.role);
    Ok(Sse::new(stream)
        .keep_alive(KeepAlive::new().interval(Duration::from_secs(15)))
        .into_response())
}

struct Cursor {
    /// Held while the stream lives.
    _permit: StreamPermit,
    api: Arc<JobRoutes>,
    job: Uuid,
    after: i64,
    pending: std::collections::VecDeque<JobEvent>,
    finished_seen: bool,
    done: bool,
    /// The reader's role (what it may see of checkpoints).
    role: Role,
}

fn sse_event(e: &JobEvent, role: Role) -> Event {
    let data = serde_json::json!({
        "kind": e.kind,
        "data": if e.kind == "checkpoint" { checkpoint_for(e.data.clone(), role) } else { e.data.clone() },
        "created": jobs::rfc3339(e.created_ms),
    });
    Event::default()
        .id(e.id.to_string())
        .event(e.kind.clone())
        .data(data.to_string())
}

fn event_stream(
    api: Arc<JobRoutes>,
    job: Uuid,
    after: i64,
    permit: StreamPermit,
    role: Role,
) -> impl futures_util::Stream<Item = Result<Event, Infallible>> + Send {
    let cursor = Cursor {
        role,
        _permit: permit,
        api,
        job,
        after,
        pending: std::collections::VecDeque::new(),
        finished_seen: false,
        done: false,
    };
    futures_util::stream::unfold(cursor, |mut c| async move {
        loop {
            if let Some(e) = c.pending.pop_front() {
                c.after = e.id;
                let event = sse_event(&e, c.role);
                return Some((Ok(event), c));
            }
            if c.done || c.api.shutdown.is_cancelled() {
                return None;
            }
            let Ok(queue) = c.api.queue.get().await else {
                return None;
            };
            match queue.events(c.job, c.after, 500).await {
                Ok(events) if !events.is_empty() => {
                    c.pending.extend(events);
                    continue;
                }
                Ok(_) => {}
                Err(e) => {
                    tracing::warn!(job = %c.job, error = %e, "reading job events failed");
                }
            }
            if c.finished_seen {
                // The job had finished before the last read, which found nothing new: its
                // final event is sent.
                return None;
            }
            match queue.get(c.job).await {
                Ok(Some(j)) if j.state.is_finished() => {
                    c.finished_seen = true;
                    continue;
                }
                Ok(None) => return None,
                _ => {}
            }
            tokio::select! {
                () = tokio::time::sleep(c.api.event_poll) => {}
                () = c.api.shutdown.cancelled() => { c.done = true; }
            }
        }
    })
}

/// A curves use case's refusal as the API answers it.
fn curves_error(e: jobs::curves::CurvesError) -> ApiError {
    use jobs::curves::CurvesError;
    match e {
        e @ (CurvesError::NotTraining { .. } | CurvesError::NoPointYet(_)) => {
            ApiError::not_found(e.to_string())
        }
        e @ CurvesError::Unreadable { .. } => ApiError::internal(e),
    }
}

/// Runs the blocking curves use case `curves` on training job `id`.
async fn curves_of<T: Send + 'static>(
    api: &JobRoutes,
    id: &str,
    curves: fn(&JobEnv, &Job) -> Result<T, jobs::curves::CurvesError>,
) -> Result<T, ApiError> {
    let job = api.job(id).await?;
    let kinds = Arc::clone(&api.kinds);
    tokio::task::spawn_blocking(move || curves(&kinds, &job))
        .await
        .map_err(|e| ApiError::internal(format!("the curves task failed: {e}")))?
        .map_err(curves_error)
}

/// A training job's learning curves as CSV: one row per episode with its reward, outcome and
/// the moving mean, standard deviation and success rate over 100 episodes (the columns of
/// `mentalsim train`'s `curves.csv`). From the latest checkpoint while it runs.
#[utoipa::path(get, path = "/v1/jobs/{id}/curves.csv", params(("id" = String, Path, format = "uuid", description = "A training job's id.")), responses(
    (status = 200, content_type = "text/csv", body = String),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No job has this id, it is not a training job, or it has no curve point yet.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
async fn job_curves_csv(
    State(api): State<Arc<JobRoutes>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let csv = curves_of(&api, &id, jobs::curves::curves_csv).await?;
    Ok(([(header::CONTENT_TYPE, "text/csv; charset=utf-8")], csv).into_response())
}

/// A training job's learning curve as a PNG (reward per episode: moving mean ± one standard
/// deviation over 100 episodes, like the paper's Figure 10).
#[utoipa::path(get, path = "/v1/jobs/{id}/curves.png", params(("id" = String, Path, format = "uuid", description = "A training job's id.")), responses(
    (status = 200, content_type = "image/png", body = Vec<u8>),
    (status = 401, response = edge::error::responses::Unauthorized),
    (status = 404, description = "No job has this id, it is not a training job, or it has no curve point yet.", body = ErrorBody),
    (status = 503, response = edge::error::responses::ServiceUnavailable)))]
async fn job_curves_png(
    State(api): State<Arc<JobRoutes>>,
    _caller: Caller,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let png = curves_of(&api, &id, jobs::curves::curves_png).await?;
    Ok(([(header::CONTENT_TYPE, "image/png")], png).into_response())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_engineers_see_where_a_checkpoint_lies_on_the_server() {
        let data = serde_json::json!({"dir": "/srv/data/checkpoints/x", "env_steps": 10});
        let robot = checkpoint_for(data.clone(), Role::Robot);
        assert_eq!(robot, serde_json::json!({"env_steps": 10}));
        assert_eq!(checkpoint_for(data.clone(), Role::Engineer), data);
        let event = JobEvent {
            id: 3,
            job_id: Uuid::nil(),
            kind: "checkpoint".into(),
            data,
            created_ms: 0,
        };
        let shown = format!("{:?}", sse_event(&event, Role::Robot));
        assert!(!shown.contains("/srv/data"), "{shown}");
        assert!(format!("{:?}", sse_event(&event, Role::Engineer)).contains("/srv/data"));
    }
}
