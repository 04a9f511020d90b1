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
pub mod types;

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Instant;

use axum::extract::State;
use axum::http::HeaderMap;
use axum::routing::post;
use axum::{Json, Router};
use edge::{ApiError, ErrorCode, Role};
use rehearsal::{PlanError, RoadmapCache};
use serde::{Deserialize, Serialize};
use sim::World;
use utoipa::ToSchema;

use crate::api::JobsApi;
use crate::jobs::PlanValidator;
use crate::jobs::policies::PolicyStore;
use crate::jobs::source::SourceError;
use crate::runner::JobError;

pub use self::error::PlanErrorResponse;
pub use self::types::{
    AttemptOutcome, AttemptReport, ControllerKind, LegReport, PlanOptions, PlanReport, PlanRequest,
    Point, Pose, RoadmapChoice, RoadmapInfo, RoadmapKind,
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
    /// The validated waypoints and the report of the simulated runs.
    #[serde(flatten)]
    pub report: PlanReport,
}

/// State of the plan route: the jobs API's (tokens, knowledge source, policies) plus caches of
/// roadmaps by map version and of loaded policies. Worlds are cached with their databases by
/// the knowledge source.
pub struct PlanApi {
    jobs: Arc<JobsApi>,
    roadmaps: RoadmapCache,
    /// Policy-aware roadmaps (PRM-RL), built in the background on first use.
    policy_roadmaps: Arc<PolicyRoadmaps>,
    /// Loaded policies by id, with the modification time of the weights they were read from
    /// (an export under the same id replaces the directory).
    policies: Mutex<HashMap<String, (std::time::SystemTime, Arc<learning::Policy>)>>,
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
            roadmaps: RoadmapCache::default(),
            policy_roadmaps: Arc::default(),
            policies: Mutex::new(HashMap::new()),
        }
    }

    /// The policy `id`, loaded again only when its weights file changed.
    async fn policy(&self, id: &str) -> Result<Arc<learning::Policy>, ApiError> {
        let dir = self
            .jobs
            .env
            .policies
            .path(id)
            .ok_or_else(|| ApiError::new(ErrorCode::NotFound, format!("no policy `{id}`")))?;
        let modified = std::fs::metadata(dir.join(learning::policy::WEIGHTS_FILE))
            .and_then(|m| m.modified())
            .ok();
        let cached = self
            .policies
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get(id)
            .filter(|(at, _)| Some(*at) == modified)
            .map(|(_, p)| Arc::clone(p));
        if let Some(p) = cached {
            return Ok(p);
        }
        let loaded = tokio::task::spawn_blocking(move || learning::Policy::load(&dir))
            .await
            .map_err(|e| ApiError::internal(format!("policy loader failed: {e}")))?
            .map_err(|e| {
                ApiError::new(
                    ErrorCode::Unprocessable,
                    format!("policy `{id}` cannot be loaded: {e}"),
                )
            })?;
        let loaded = Arc::new(loaded);
        let mut policies = self.policies.lock().unwrap_or_else(PoisonError::into_inner);
        if policies.len() >= LOADED_POLICIES {
            policies.clear();
        }
        if let Some(at) = modified {
            policies.insert(id.to_owned(), (at, Arc::clone(&loaded)));
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

/// Which policy-aware roadmap: the floor state (map version, which changes with the floor and
/// its objects), the policy and the weights file's modification time (an export under the same
/// id is another policy), and the safety margin it was inflated by. A floor that changes is a
/// new key: a roadmap built for an old state is never served for a new one.
type PolicyRoadmapKey = (String, String, Option<std::time::SystemTime>, u64);

/// A policy-aware roadmap, being built or built.
#[derive(Clone)]
enum PolicyRoadmapSlot {
    Building,
    Ready(Arc<planning::Roadmap>),
    Failed(String),
}

/// Policy-aware roadmaps per key, built on a blocking thread the first time a plan asks for
/// one; at most [`POLICY_ROADMAPS`] kept (the oldest states go first when full).
#[derive(Default)]
struct PolicyRoadmaps {
    slots: Mutex<HashMap<PolicyRoadmapKey, PolicyRoadmapSlot>>,
}

/// Policy-aware roadmaps kept at most.
const POLICY_ROADMAPS: usize = 16;

impl PolicyRoadmaps {
    /// The roadmap of `key` when built; otherwise starts building it (unless a build is under
    /// way; a failed build is tried again) and answers why there is none yet.
    fn get_or_start(
        self: &Arc<Self>,
        key: &PolicyRoadmapKey,
        build: impl FnOnce() -> Result<Arc<planning::Roadmap>, String> + Send + 'static,
    ) -> Result<Arc<planning::Roadmap>, String> {
        let mut map = self.slots.lock().unwrap_or_else(PoisonError::into_inner);
        let why = match map.get(key) {
            Some(PolicyRoadmapSlot::Ready(r)) => return Ok(Arc::clone(r)),
            Some(PolicyRoadmapSlot::Building) => return Err("it is being built".into()),
            Some(PolicyRoadmapSlot::Failed(e)) => {
                format!("its last build failed ({e}); it is being built again")
            }
            None => "it is being built".into(),
        };
        if map.len() >= POLICY_ROADMAPS {
            map.retain(|_, v| matches!(v, PolicyRoadmapSlot::Building));
        }
        map.insert(key.clone(), PolicyRoadmapSlot::Building);
        drop(map);
        let key = key.clone();
        let slots = Arc::clone(self);
        tokio::task::spawn_blocking(move || {
            let slot = match build() {
                Ok(r) => PolicyRoadmapSlot::Ready(r),
                Err(e) => {
                    tracing::warn!(floor = %key.0, policy = %key.1, "policy-aware roadmap failed: {e}");
                    PolicyRoadmapSlot::Failed(e)
                }
            };
            slots
                .slots
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .insert(key, slot);
        });
        Err(why)
    }
}

/// Builds the policy-aware roadmap of `world` for `policy`: the geometric roadmap the plan
/// endpoint's first attempt uses (n* samples, seed 0), every edge driven by the policy
/// ([`rehearsal::edges`], default parameters: 10 rollouts per direction, kept at 90%).
fn build_policy_roadmap(
    world: &Arc<World>,
    roadmaps: &RoadmapCache,
    map_version: &str,
    policy: &Arc<learning::Policy>,
    safety_margin_m: f64,
) -> Result<Arc<planning::Roadmap>, String> {
    let space = rehearsal::config_space(world, roadmaps, map_version, safety_margin_m)
        .map_err(|e| e.to_string())?;
    let params = planning::PrmParams {
        samples: planning::optimal_samples(space.free_area_m2),
        seed: 0,
        ..planning::PrmParams::default()
    };
    let (geometric, _) = roadmaps
        .roadmap(map_version, &space, &params)
        .map_err(|e| e.to_string())?;
    let started = Instant::now();
    let (roadmap, report) = rehearsal::policy_roadmap(
        world,
        &geometric,
        policy,
        &rehearsal::EdgeRolloutParams::default(),
    )
    .map_err(|e| e.to_string())?;
    tracing::info!(
        floor = map_version,
        edges = report.edges.len(),
        kept = report.kept().count(),
        edge_success_rate = report.edge_success_rate(),
        seconds = started.elapsed().as_secs_f64(),
        "policy-aware roadmap built"
    );
    Ok(roadmap)
}

/// The route.
pub fn router(state: Arc<PlanApi>) -> Router {
    Router::new()
        .route("/v1/plan", post(plan))
        .with_state(state)
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
    fn check(&self, payload: &serde_json::Value) -> Result<(), String> {
        let (plan, _) = ValidatePlan::parse(payload)?;
        if let Some(id) = &plan.policy
            && self.policies.metadata(id).is_none()
        {
            return Err(format!("payload.policy: no policy `{id}`"));
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
    request_body = PlanApiRequest,
    responses(
        (status = 200, description = "Waypoints validated in the mental simulation", body = PlanApiResponse),
        (status = 400, description = "Malformed request (a coordinate that is not a number, no goals, an option out of range)"),
        (status = 404, description = "Unknown robot, place or policy"),
        (status = 409, description = "No attempt could validate the plan (the attempts are in the details)"),
        (status = 422, description = "Start or goal inside an obstacle, outside the map, or unreachable from the start"),
    ),
    security(("bearer" = []))
)]
async fn plan(
    State(api): State<Arc<PlanApi>>,
    headers: HeaderMap,
    Json(req): Json<PlanApiRequest>,
) -> Result<Json<PlanApiResponse>, ApiError> {
    let started = Instant::now();
    api.jobs.tokens.require(&headers, Role::Robot)?;
    let goals =
        goals_of(req.goal, &req.goals).map_err(|m| ApiError::new(ErrorCode::BadRequest, m))?;
    let db = api
        .jobs
        .env
        .knowledge
        .floor_database(&req.place, &req.robot)
        .await
        .map_err(|e| match e {
            SourceError::NotFound(m) => ApiError::new(ErrorCode::NotFound, m),
            SourceError::Unprocessable(m) => ApiError::new(ErrorCode::Unprocessable, m),
            SourceError::Unavailable(m) => ApiError::new(ErrorCode::NotReady, m),
        })?;

    // The policy: the one named, else the robot's newest.
    let policies = &api.jobs.env.policies;
    let policy_id = match &req.policy {
        Some(id) => {
            if policies.metadata(id).is_none() {
                return Err(ApiError::new(
                    ErrorCode::NotFound,
                    format!("no policy `{id}`"),
                ));
            }
            Some(id.clone())
        }
        None => newest_policy(policies, &db.robot),
    };
    let policy = match &policy_id {
        Some(id) => Some(api.policy(id).await?),
        None => None,
    };

    let api2 = Arc::clone(&api);
    let choice = req.options.roadmap;
    let request = PlanRequest {
        start: req.start,
        goals,
        options: req.options.clone(),
    };
    let (floor, robot) = (db.floor.clone(), db.robot.clone());
    let weights_modified = policy_id
        .as_deref()
        .and_then(|id| api.jobs.env.policies.path(id))
        .and_then(|dir| std::fs::metadata(dir.join(learning::policy::WEIGHTS_FILE)).ok())
        .and_then(|m| m.modified().ok());
    let runtime = tokio::runtime::Handle::current();
    let policy_key = policy_id.clone().unwrap_or_default();
    let report = tokio::task::spawn_blocking(move || -> Result<PlanReport, ApiError> {
        let _enter = runtime.enter();
        let world = db
            .world()
            .map_err(|m| ApiError::new(ErrorCode::Unprocessable, m))?;
        let request = rehearsal::PlanRequest::from(request);
        let Some(policy) = policy else {
            return rehearsal::validate(&world, &api2.roadmaps, &db.version, &request, None)
                .map(PlanReport::from)
                .map_err(|e| e.to_api_error());
        };
        let policy_roadmap = match choice {
            RoadmapChoice::Geometric => None,
            RoadmapChoice::Auto | RoadmapChoice::Policy => {
                let margin = request.options.safety_margin_m;
                let key = (
                    db.version.clone(),
                    policy_key,
                    weights_modified,
                    margin.to_bits(),
                );
                let (w, p, api3) = (Arc::clone(&world), Arc::clone(&policy), Arc::clone(&api2));
                let version = db.version.clone();
                let got = api2.policy_roadmaps.get_or_start(&key, move || {
                    build_policy_roadmap(&w, &api3.roadmaps, &version, &p, margin)
                });
                match got {
                    Ok(r) => Some(r),
                    Err(why) if choice == RoadmapChoice::Policy => {
                        return Err(ApiError::new(
                            ErrorCode::Conflict,
                            format!("no policy-aware roadmap of this floor and policy yet: {why} (every edge driven by the policy); retry shortly, or ask for `options.roadmap`: `auto`"),
                        ));
                    }
                    Err(_) => None,
                }
            }
        };
        let mut primary = rehearsal::PolicyController::new(policy);
        let mut follower = rehearsal::ClassicalFollower::default();
        rehearsal::validate_with_fallback(
            &world,
            &api2.roadmaps,
            &db.version,
            &request,
            &mut primary,
            Some(&mut follower),
            policy_roadmap.as_ref(),
        )
        .map(PlanReport::from)
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
    Ok(Json(PlanApiResponse {
        robot,
        floor,
        policy: policy_id,
        note,
        service_ms: started.elapsed().as_secs_f64() * 1000.0,
        report,
    }))
}
