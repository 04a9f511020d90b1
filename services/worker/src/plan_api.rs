//! `POST /v1/plan` — what robots call (the paper's Figure 4): the floor's on-demand database
//! from the knowledge service, its mental simulation, the cached roadmap for that map version,
//! and the plan driven in the simulation with the robot's latest trained policy through the
//! hybrid executor (the `rehearsal` crate) before the waypoints are answered.
//!
//! - [`types`]: the wire types (serde, OpenAPI schemas) and their conversions to and from the
//!   executor's core types;
//! - [`error`]: [`PlanErrorResponse`], the executor's refusals as API errors (code, `reason`,
//!   `details`).

pub mod error;
#[allow(
    unused_qualifications,
    reason = "utoipa's path macro expands the query extractor's type with its span"
)]
pub mod roadmap_view;
pub mod rosbag;
pub mod types;

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use axum::extract::State;
use axum::http::HeaderMap;
use axum::response::IntoResponse;
use axum::routing::post;
use axum::{Json, Router};
use edge::{ApiError, ErrorCode, Role};
use rehearsal::{PlanError, RoadmapCache};
use serde::{Deserialize, Serialize};
use sim::World;
use utoipa::ToSchema;

use crate::api::JobsApi;
use crate::jobs::policies::PolicyStore;
use crate::jobs::source::SourceError;
use crate::jobs::{PayloadError, PlanValidator, RoadmapKey};
use crate::runner::JobError;

pub use self::error::PlanErrorResponse;
pub use self::types::{
    AttemptOutcome, AttemptReport, ControllerKind, LegReport, PeopleChoice, PeopleMode,
    PeopleReport, PlanOptions, PlanReport, PlanRequest, Point, Pose, RoadmapChoice, RoadmapInfo,
    RoadmapKind,
};

/// What a robot asks.
#[derive(Debug, Clone, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PlanApiRequest {
    /// The robot: identifier or IRI.
    pub robot: String,
    /// Where the robot is: its floor, or a place on that floor (identifier or IRI).
    pub place: String,
    /// The robot's pose on that floor (map frame).
    pub start: Pose,
    /// One goal (give this or `goals`).
    #[serde(default)]
    pub goal: Option<Point>,
    /// Goals visited in order (give this or `goal`).
    #[serde(default)]
    pub goals: Vec<Point>,
    /// Validation settings.
    #[serde(default)]
    pub options: PlanOptions,
    /// The policy to drive with [default: the robot's newest trained policy].
    #[serde(default)]
    pub policy: Option<String>,
}

/// The validated plan and how it was validated.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct PlanApiResponse {
    /// The robot's IRI.
    pub robot: String,
    /// The floor's IRI.
    pub floor: String,
    /// The policy that drove the simulated robot, if any.
    pub policy: Option<String>,
    /// Why the classical follower was used, when it was: no policy yet, or legs no attempt
    /// with the policy validated.
    pub note: Option<String>,
    /// Wall-clock time of the whole request in this service, milliseconds.
    pub service_ms: f64,
    /// The start and the waypoints as a ROS 2 `nav_msgs/Path` in the floor's map frame: what
    /// a Nav2 robot publishes or hands its controller without conversion.
    pub path: types::RosPath,
    /// The validated waypoints and the report of the simulated runs.
    #[serde(flatten)]
    pub report: PlanReport,
}

/// State of the plan route: the jobs API's (tokens, knowledge source, policies) plus caches of
/// roadmaps by map version and of loaded policies. Worlds are cached with their databases by
/// the knowledge source.
pub struct PlanApi {
    jobs: Arc<JobsApi>,
    /// Policy-aware roadmaps (PRM-RL) read from the store, applied to their geometric roadmaps.
    /// Keyed with whether the unkept directions are in (`auto`) or not (`policy`).
    policy_roadmaps: Mutex<HashMap<(RoadmapKey, bool), Arc<planning::Roadmap>>>,
    /// The roadmap job enqueued per key by this process, so a burst of plans enqueues one.
    roadmap_jobs: tokio::sync::Mutex<HashMap<RoadmapKey, uuid::Uuid>>,
    /// Loaded policies by id, with the modification time of the weights they were read from
    /// (an export under the same id replaces the directory) and the weights' fingerprint.
    policies: Mutex<HashMap<String, (std::time::SystemTime, LoadedPolicy)>>,
}

/// A loaded policy and the FNV-1a fingerprint of its weights file (part of a stored roadmap's
/// key).
#[derive(Clone)]
struct LoadedPolicy {
    policy: Arc<learning::Policy>,
    weights: u64,
}

impl std::fmt::Debug for PlanApi {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PlanApi").finish_non_exhaustive()
    }
}

/// Policies kept loaded at most.
const LOADED_POLICIES: usize = 16;

impl PlanApi {
    /// Over the jobs API's state.
    pub fn new(jobs: Arc<JobsApi>) -> Self {
        Self {
            jobs,
            policy_roadmaps: Mutex::new(HashMap::new()),
            roadmap_jobs: tokio::sync::Mutex::new(HashMap::new()),
            policies: Mutex::new(HashMap::new()),
        }
    }

    /// Geometric roadmaps by floor state (shared with roadmap jobs in this process).
    fn roadmaps(&self) -> &RoadmapCache {
        &self.jobs.env.roadmaps
    }

    /// The roadmap job building `key` (enqueued by this process and not finished), else a
    /// new one.
    async fn ensure_roadmap_job(
        &self,
        key: &RoadmapKey,
        floor: &str,
        robot: &str,
        margin: f64,
    ) -> Result<uuid::Uuid, ApiError> {
        let queue = self.jobs.queue.get().await.map_err(|reason| {
            ApiError::new(
                ErrorCode::NotReady,
                format!("the job database is not available: {reason}"),
            )
        })?;
        let mut jobs = self.roadmap_jobs.lock().await;
        if let Some(id) = jobs.get(key).copied() {
            let pending = queue
                .get(id)
                .await
                .ok()
                .flatten()
                .is_some_and(|j| !j.state.is_finished());
            if pending {
                return Ok(id);
            }
        }
        let job = crate::queue::NewJob::new(
            crate::jobs::JobKind::Roadmap,
            crate::jobs::roadmap::payload(&key.policy, floor, robot, margin),
        );
        let id = queue.enqueue(job).await.map_err(|e| {
            ApiError::new(
                ErrorCode::NotReady,
                format!("enqueueing the roadmap job: {e}"),
            )
        })?;
        if jobs.len() >= POLICY_ROADMAPS {
            jobs.clear();
        }
        jobs.insert(key.clone(), id);
        Ok(id)
    }

    /// The floor database of `place` for `robot`, the knowledge source's refusals as API errors.
    async fn floor_database(
        &self,
        place: &str,
        robot: &str,
    ) -> Result<Arc<crate::jobs::source::FloorDatabase>, ApiError> {
        self.jobs
            .env
            .knowledge
            .floor_database(place, robot)
            .await
            .map_err(|e| match e {
                SourceError::NotFound(m) => ApiError::new(ErrorCode::NotFound, m),
                SourceError::Unprocessable(m) => ApiError::new(ErrorCode::Unprocessable, m),
                SourceError::Unavailable(m) => ApiError::new(ErrorCode::NotReady, m),
            })
    }

    /// The policy `id`, loaded again only when its weights file changed; 404 for a policy that
    /// was never exported.
    async fn policy(&self, id: &str) -> Result<LoadedPolicy, ApiError> {
        let not_found = || ApiError::new(ErrorCode::NotFound, format!("no policy `{id}`"));
        if self.jobs.env.policies.metadata(id).is_none() {
            return Err(not_found());
        }
        let dir = self.jobs.env.policies.path(id).ok_or_else(not_found)?;
        let modified = std::fs::metadata(dir.join(learning::policy::WEIGHTS_FILE))
            .and_then(|m| m.modified())
            .ok();
        let cached = self
            .policies
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get(id)
            .filter(|(at, _)| Some(*at) == modified)
            .map(|(_, p)| p.clone());
        if let Some(p) = cached {
            return Ok(p);
        }
        let loaded = tokio::task::spawn_blocking(move || {
            let weights = std::fs::read(dir.join(learning::policy::WEIGHTS_FILE))
                .map(|b| grid::hash::fnv1a(&b))
                .map_err(|e| e.to_string())?;
            learning::Policy::load(&dir)
                .map(|p| LoadedPolicy {
                    policy: Arc::new(p),
                    weights,
                })
                .map_err(|e| e.to_string())
        })
        .await
        .map_err(|e| ApiError::internal(format!("policy loader failed: {e}")))?
        .map_err(|e| {
            ApiError::new(
                ErrorCode::Unprocessable,
                format!("policy `{id}` cannot be loaded: {e}"),
            )
        })?;
        let mut policies = self.policies.lock().unwrap_or_else(PoisonError::into_inner);
        if policies.len() >= LOADED_POLICIES {
            policies.clear();
        }
        if let Some(at) = modified {
            policies.insert(id.to_owned(), (at, loaded.clone()));
        }
        Ok(loaded)
    }
}

/// Runs the executor ([`rehearsal::validate`]) on a request in the wire types and answers the
/// report in them: with `policy` (hybrid PRM-RL) when given, else the classical follower.
/// `map_version` keys `roadmaps`: equal strings must mean equal maps (and objects). Blocks: call
/// it on a blocking thread.
pub fn rehearse(
    world: &Arc<World>,
    roadmaps: &RoadmapCache,
    map_version: &str,
    request: &PlanRequest,
    policy: Option<Arc<learning::Policy>>,
) -> Result<PlanReport, PlanError> {
    let request = rehearsal::PlanRequest::from(request.clone());
    rehearsal::validate(world, roadmaps, map_version, &request, policy).map(PlanReport::from)
}

/// Counts a rehearsal in the `plan_rehearsals_running` gauge while it lives: what `/metrics`
/// shows of plans still computing (a stopped request's rehearsal leaves within milliseconds).
struct Rehearsing;

impl Rehearsing {
    fn start() -> Self {
        metrics::gauge!("plan_rehearsals_running").increment(1.0);
        Self
    }
}

impl Drop for Rehearsing {
    fn drop(&mut self) {
        metrics::gauge!("plan_rehearsals_running").decrement(1.0);
    }
}

/// Policy-aware roadmaps kept applied in memory at most (and roadmap jobs remembered).
const POLICY_ROADMAPS: usize = 16;

/// The route.
pub fn router(state: Arc<PlanApi>) -> Router {
    Router::new()
        .route("/v1/plan", post(plan))
        .route(
            "/v1/roadmaps",
            axum::routing::get(roadmap_view::get_roadmap),
        )
        .route(
            "/v1/places/{id}/route-graph.geojson",
            axum::routing::get(roadmap_view::route_graph),
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

/// The goals of a request that gives `goal` or `goals` (exactly one of them, non-empty).
fn goals_of(goal: Option<Point>, goals: &[Point]) -> Result<Vec<Point>, String> {
    match (goal, goals.is_empty()) {
        (Some(_), false) => Err("give `goal` or `goals`, not both".into()),
        (Some(g), true) => Ok(vec![g]),
        (None, false) => Ok(goals.to_vec()),
        (None, true) => Err("a plan needs a goal: give `goal` or a non-empty `goals`".into()),
    }
}

/// The newest policy trained for the robot `robot_iri` (its summary names the robot by IRI or
/// by identifier).
fn newest_policy(policies: &PolicyStore, robot_iri: &str) -> Option<String> {
    policies
        .list()
        .into_iter()
        .find(|p| {
            p.robot
                .as_deref()
                .is_some_and(|r| r == robot_iri || robot_iri.ends_with(&format!("/{r}")))
        })
        .map(|p| p.id)
}

/// The plan executor behind `validate` jobs: the payload's `start`, `goal` or `goals`,
/// `options` and optional `policy` are those of `POST /v1/plan`; the job's result is the plan
/// report.
#[derive(Debug, Clone)]
pub struct ExecutorValidator {
    policies: PolicyStore,
}

impl ExecutorValidator {
    /// With the policies in `policies`.
    pub fn new(policies: PolicyStore) -> Self {
        Self { policies }
    }
}

/// The plan part of a `validate` payload.
#[derive(Debug, Deserialize)]
struct ValidatePlan {
    start: Pose,
    #[serde(default)]
    goal: Option<Point>,
    #[serde(default)]
    goals: Vec<Point>,
    #[serde(default)]
    options: PlanOptions,
    #[serde(default)]
    policy: Option<String>,
}

impl ValidatePlan {
    fn parse(payload: &serde_json::Value) -> Result<(ValidatePlan, PlanRequest), String> {
        let mut rest = payload.clone();
        if let Some(o) = rest.as_object_mut() {
            o.remove("robot");
            o.remove("place");
        }
        let plan: ValidatePlan =
            serde_json::from_value(rest).map_err(|e| format!("payload: {e}"))?;
        let goals = goals_of(plan.goal, &plan.goals).map_err(|m| format!("payload: {m}"))?;
        let request = PlanRequest {
            start: plan.start,
            goals,
            options: plan.options.clone(),
        };
        Ok((plan, request))
    }
}

impl PlanValidator for ExecutorValidator {
    fn check(&self, payload: &serde_json::Value) -> Result<(), PayloadError> {
        let (plan, request) = ValidatePlan::parse(payload).map_err(PayloadError::Invalid)?;
        // The bounds a plan request has (goals, attempts, samples, timer), named in the payload.
        if let Err(e) = rehearsal::check_request(&rehearsal::PlanRequest::from(request)) {
            return Err(PayloadError::Invalid(match e {
                PlanError::InvalidInput { field, message } => {
                    format!("payload.{field}: {message}")
                }
                other => format!("payload: {other}"),
            }));
        }
        if let Some(id) = &plan.policy
            && self.policies.metadata(id).is_none()
        {
            return Err(PayloadError::NotFound(format!(
                "payload.policy: no policy `{id}`"
            )));
        }
        Ok(())
    }

    fn validate(
        &self,
        world: Arc<World>,
        payload: &serde_json::Value,
        stopping: &dyn Fn() -> bool,
        progress: &dyn Fn(serde_json::Value),
    ) -> Result<serde_json::Value, JobError> {
        let (plan, request) = ValidatePlan::parse(payload).map_err(JobError::Fatal)?;
        if stopping() {
            return Err(JobError::Stopped(crate::runner::StopReason::Shutdown));
        }
        let policy_id = plan
            .policy
            .clone()
            .or_else(|| newest_policy(&self.policies, &world.spec().robot.id));
        let policy = match &policy_id {
            Some(id) => {
                let dir = self
                    .policies
                    .path(id)
                    .ok_or_else(|| JobError::Fatal(format!("no policy `{id}`")))?;
                Some(Arc::new(learning::Policy::load(&dir).map_err(|e| {
                    JobError::Fatal(format!("policy `{id}` cannot be loaded: {e}"))
                })?))
            }
            None => None,
        };
        progress(serde_json::json!({"stage": "simulating", "policy": policy_id}));
        let roadmaps = RoadmapCache::new(8, 1);
        let report = rehearse(&world, &roadmaps, "validate-job", &request, policy)
            .map_err(|e| JobError::Fatal(e.to_string()))?;
        let mut value =
            serde_json::to_value(&report).map_err(|e| JobError::Fatal(format!("report: {e}")))?;
        if let Some(o) = value.as_object_mut() {
            o.insert("policy".into(), policy_id.into());
        }
        Ok(value)
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
        (status = 409, description = "No attempt could validate the plan (the attempts are in the details), or `options.roadmap` is `policy` and the policy-aware roadmap is not built yet or joins no leg", body = edge::ErrorBody),
        (status = 406, description = "The request's `Accept` takes neither JSON nor MCAP (the answer's forms).", body = edge::ErrorBody),
        (status = 413, response = edge::error::responses::PayloadTooLarge),
        (status = 415, response = edge::error::responses::UnsupportedMediaType),
        (status = 422, description = "The body does not fit the schema (a missing or unknown field, a wrong type); the start or a goal is inside an obstacle, outside the map, or unreachable from the start; the place is on no floor; the map or the policy cannot be used", body = edge::ErrorBody),
        (status = 503, response = edge::error::responses::ServiceUnavailable),
    ),
    security(("bearer" = []))
)]
async fn plan(
    State(api): State<Arc<PlanApi>>,
    headers: HeaderMap,
    Json(mut req): Json<PlanApiRequest>,
) -> Result<axum::response::Response, ApiError> {
    let started = Instant::now();
    api.jobs.tokens.require(&headers, Role::Robot)?;
    let recording = wants_recording(&headers)?;
    // A recording replays every attempt step by step.
    req.options.trace |= recording;
    let goals =
        goals_of(req.goal, &req.goals).map_err(|m| ApiError::new(ErrorCode::BadRequest, m))?;
    let db = api.floor_database(&req.place, &req.robot).await?;

    // The policy: the one named, else the robot's newest.
    let policies = &api.jobs.env.policies;
    let policy_id = match &req.policy {
        // An unknown one is a 404 from `PlanApi::policy` below.
        Some(id) => Some(id.clone()),
        None => newest_policy(policies, &db.robot),
    };
    let policy = match &policy_id {
        Some(id) => Some(api.policy(id).await?),
        None => None,
    };

    let choice = req.options.roadmap;
    // The policy-aware roadmap of this floor state and policy: stored by a `roadmap` job. When
    // there is none yet, one is enqueued (a floor that changed is a new state, so it gets
    // its own), and the plan goes on the geometric roadmap (`auto`) or is refused (`policy`).
    let margin = req.options.safety_margin_m;
    let roadmap_key = match (&policy_id, &policy, choice) {
        (Some(id), Some(loaded), RoadmapChoice::Auto | RoadmapChoice::Policy) => Some(
            RoadmapKey::for_plans(&db.version, id, loaded.weights, margin),
        ),
        _ => None,
    };
    let stored = match &roadmap_key {
        Some(key) => {
            let in_memory = api
                .policy_roadmaps
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .keys()
                .any(|(k, _)| k == key);
            in_memory || api.jobs.env.policy_roadmaps.contains(key)
        }
        None => false,
    };
    if let Some(key) = roadmap_key.as_ref().filter(|_| !stored) {
        let job = api
            .ensure_roadmap_job(key, &db.floor, &db.robot, margin)
            .await;
        if choice == RoadmapChoice::Policy {
            let why = match job {
                Ok(id) => format!("the `roadmap` job {id} is building it"),
                Err(e) => format!("no job could be enqueued to build it ({})", e.message()),
            };
            return Err(ApiError::new(
                ErrorCode::Conflict,
                format!(
                    "no policy-aware roadmap of this floor state and policy yet: {why} (every edge driven by the policy); retry when it has finished, or ask for `options.roadmap`: `auto`"
                ),
            ));
        }
        if let Err(e) = job {
            tracing::warn!(error = %e.message(), "enqueueing a roadmap job failed");
        }
    }

    let api2 = Arc::clone(&api);
    let people_choice = req.options.people;
    let people_hour = req.options.people_hour;
    if people_hour.is_some_and(|h| h > 23) {
        return Err(ApiError::new(
            ErrorCode::BadRequest,
            format!(
                "`options.people_hour` is an hour of day in [0, 23], got {}",
                people_hour.unwrap_or_default()
            ),
        ));
    }
    let request = PlanRequest {
        start: req.start,
        goals,
        options: req.options.clone(),
    };
    let (floor, robot) = (db.floor.clone(), db.robot.clone());
    // When this handler's future is dropped (the request timed out, the client hung up), the
    // rehearsal on the blocking thread sees the stop at its next check and ends.
    let stop = rehearsal::Stop::new();
    let _stop_on_drop = rehearsal::StopOnDrop(stop.clone());
    type Rehearsed = (
        PlanReport,
        Arc<World>,
        sim::PeopleConfig,
        Option<rehearsal::DrawsReport>,
    );
    let (mut report, world, people, draws) = tokio::task::spawn_blocking(move || -> Result<Rehearsed, ApiError> {
        let _running = Rehearsing::start();
        let world = db
            .world()
            .map_err(|m| ApiError::new(ErrorCode::Unprocessable, m))?;
        let mut request = rehearsal::PlanRequest::from(request);
        request.stop = stop;
        if people_choice == PeopleChoice::Named(PeopleMode::Auto) {
            request.options.people = knowledge_people(&world, people_hour);
        }
        let people = request.options.people.clone();
        let Some(LoadedPolicy { policy, .. }) = policy else {
            return rehearsal::validate(&world, api2.roadmaps(), &db.version, &request, None)
                .map(|r| {
                    let draws = r.people_draws.clone();
                    (PlanReport::from(r), world, people, draws)
                })
                .map_err(|e| e.to_api_error());
        };
        // `auto` plans on every measured direction (the unkept ones only where the kept ones
        // join no route); `policy` on the kept ones alone.
        let with_unkept = choice == RoadmapChoice::Auto;
        let policy_roadmap = match roadmap_key.filter(|_| stored) {
            None => None,
            Some(key) => {
                let key = (key, with_unkept);
                let cached = api2
                    .policy_roadmaps
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .get(&key)
                    .cloned();
                match cached {
                    Some(r) => Some(r),
                    None => {
                        let loaded = crate::jobs::roadmap::load_policy_roadmap(
                            &api2.jobs.env.policy_roadmaps,
                            &key.0,
                            &world,
                            api2.roadmaps(),
                            with_unkept,
                        )
                        .map_err(|m| ApiError::internal(format!("the stored policy-aware roadmap: {m}")))?;
                        if let Some(r) = &loaded {
                            let mut map = api2
                                .policy_roadmaps
                                .lock()
                                .unwrap_or_else(PoisonError::into_inner);
                            if map.len() >= POLICY_ROADMAPS {
                                map.clear();
                            }
                            map.insert(key, Arc::clone(r));
                        }
                        loaded
                    }
                }
            }
        };
        if choice == RoadmapChoice::Policy && policy_roadmap.is_none() {
            return Err(ApiError::new(
                ErrorCode::Conflict,
                "the stored policy-aware roadmap of this floor state and policy cannot be read; ask for `options.roadmap`: `auto`",
            ));
        }
        let mut primary = rehearsal::PolicyController::new(policy);
        let mut follower = rehearsal::follower_for(&request.options);
        rehearsal::validate_with_fallback(
            &world,
            api2.roadmaps(),
            &db.version,
            &request,
            &mut primary,
            Some(&mut *follower),
            policy_roadmap.as_ref(),
        )
        .map(|r| {
            let draws = r.people_draws.clone();
            (PlanReport::from(r), Arc::clone(&world), people, draws)
        })
        .map_err(|e| match e {
            // Only the policy-aware roadmap was asked for, and no kept edge joins the leg.
            PlanError::Unreachable { .. } if choice == RoadmapChoice::Policy => ApiError::new(
                ErrorCode::Conflict,
                format!("on the policy-aware roadmap: {e} (no edge the policy drives joins them; `options.roadmap`: `auto` falls back to the geometric roadmap)"),
            )
            .with_details(e.details()),
            other => other.to_api_error(),
        })
    })
    .await
    .map_err(|e| ApiError::internal(format!("plan task failed: {e}")))??;
    if people.any() {
        let source = if people_choice == PeopleChoice::Named(PeopleMode::Auto) {
            "knowledge"
        } else {
            "density"
        };
        let mut summary = people_report(
            source,
            people.count_for(world.free_region_area_m2()),
            &report.attempts,
        );
        summary.draws = draws.map(Into::into);
        report.people = Some(summary);
    }
    let fallback_legs = report
        .legs
        .iter()
        .filter(|l| l.controller != report.controller)
        .count();
    let note = if policy_id.is_none() {
        Some("no trained policy for this robot yet: validated with the classical path follower (rotate towards the next waypoint, then drive with proportional heading correction)".to_owned())
    } else if fallback_legs > 0 {
        Some(format!(
            "{} of {} legs validated with the classical path follower: no attempt with the policy validated them (see `legs`)",
            fallback_legs,
            report.legs.len()
        ))
    } else {
        None
    };
    let path = types::RosPath::through(&req.start, &report.waypoints, world.spec().map_frame());
    let answer = PlanApiResponse {
        robot,
        floor,
        policy: policy_id,
        note,
        service_ms: started.elapsed().as_secs_f64() * 1000.0,
        path,
        report,
    };
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

/// The people the floor's knowledge expects (its places' expected numbers, summed, at `hour`
/// where a place has one for it; none where it says nothing), walking its routes and
/// attractors.
fn knowledge_people(world: &World, hour: Option<u8>) -> sim::PeopleConfig {
    let expected = world.spec().people.expected_at(hour);
    if !(expected.is_finite() && expected >= 0.5) {
        return sim::PeopleConfig::default();
    }
    #[allow(
        clippy::cast_possible_truncation,
        clippy::cast_sign_loss,
        reason = "a rounded positive count, capped"
    )]
    let count = (expected.round() as usize).min(sim::crowd::MAX_PEOPLE);
    sim::PeopleConfig {
        count: Some(count),
        ..sim::PeopleConfig::default()
    }
}

/// How a plan fared among people: over every attempt (each its own draw), and its validating
/// runs' closest approach.
fn people_report(source: &str, people: usize, attempts: &[AttemptReport]) -> PeopleReport {
    let reached = |a: &&AttemptReport| a.outcome == AttemptOutcome::Reached;
    let hit = |a: &&AttemptReport| rehearsal::hit_person(&a.reason);
    PeopleReport {
        source: source.to_owned(),
        people,
        min_person_clearance_m: attempts
            .iter()
            .filter(reached)
            .filter_map(|a| a.min_person_clearance_m)
            .reduce(f64::min),
        attempts: attempts.len(),
        attempts_reached: attempts.iter().filter(reached).count(),
        attempts_hit_person: attempts.iter().filter(hit).count(),
        attempts_near_miss: attempts
            .iter()
            .filter(|a| !hit(a))
            .filter(|a| {
                a.min_person_clearance_m
                    .is_some_and(|c| c < rehearsal::NEAR_MISS_M)
            })
            .count(),
        draws: None,
    }
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
