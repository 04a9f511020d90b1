//! `roadmap`: the policy-aware roadmap of a floor (PRM-RL): every edge of the floor's geometric
//! roadmap driven by a policy in the mental simulation, K times per direction, and the per-edge
//! report persisted under (floor state, policy weights, roadmap parameters), so that
//! `POST /v1/plan` uses it from then on, in this process or any other sharing the data
//! directory.
//!
//! The geometric roadmap itself is not stored: it is rebuilt deterministically (same floor
//! state, margin, sample count and seed give the same nodes and edges) and checked against a
//! fingerprint of its nodes before the stored report is applied to it.
//!
//! A `roadmap` job is enqueued when a training job exports a policy, and when a plan asks for a
//! floor state (a floor that changed is a new state) and policy that have none. A floor that
//! changes while its roadmap is built makes that build stale: it is not stored, and the job is
//! retried against the new state.

use std::sync::Arc;

use planner::roadmaps::{
    PolicyRoadmapKey, StoredEdge, StoredRoadmap, geometric_roadmap, nodes_fingerprint,
};
use rehearsal::EdgeRolloutParams;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use super::results::{RoadmapResult, stored};
use super::{JobEnv, JobRequest, PayloadError};
use queue::{JobContext, JobError, JobHandler};

/// Most rollouts per edge direction a job may ask for.
pub const MAX_ROLLOUTS: u32 = 100;
/// Largest safety margin a job may ask for, metres.
pub const MAX_MARGIN_M: f64 = 1.0;

/// What a `roadmap` job is asked.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct RoadmapPayload {
    /// The policy's id (see `GET /v1/policies`).
    pub policy: String,
    /// A floor, or a place on one (IRI or identifier).
    pub place: String,
    /// The robot [default: the one the policy was trained for].
    #[serde(default)]
    pub robot: Option<String>,
    /// Clearance kept from obstacles by the roadmap, metres [default: the plan endpoint's].
    #[serde(default)]
    pub safety_margin_m: Option<f64>,
    /// Rollouts per edge direction [default: 10].
    #[serde(default)]
    pub rollouts: Option<u32>,
    /// Success rate an edge direction needs to be kept [default: 0.9].
    #[serde(default)]
    pub keep_threshold: Option<f64>,
    /// Missions of the controller trial driven after the edges (every candidate of
    /// `options.controller: auto` over the same missions; 0: none, then `auto` validates with
    /// Regulated Pure Pursuit) [default: 16, at most 200].
    #[serde(default)]
    pub trial_missions: Option<u32>,
}

impl RoadmapPayload {
    /// Values in range.
    pub fn check(&self) -> Result<(), PayloadError> {
        if !planner::policies::valid_id(&self.policy) {
            return Err(PayloadError::NotFound(format!(
                "payload.policy: no policy has id {:?}",
                self.policy
            )));
        }
        if let Some(m) = self.safety_margin_m
            && !(m.is_finite() && (0.0..=MAX_MARGIN_M).contains(&m))
        {
            return Err(PayloadError::invalid(
                "payload.safety_margin_m",
                format!("must be in [0, {MAX_MARGIN_M}] metres, got {m}"),
            ));
        }
        if let Some(k) = self.rollouts
            && !(1..=MAX_ROLLOUTS).contains(&k)
        {
            return Err(PayloadError::invalid(
                "payload.rollouts",
                format!("must be in 1..={MAX_ROLLOUTS}, got {k}"),
            ));
        }
        if let Some(m) = self.trial_missions
            && m > planner::controllers::MAX_TRIAL_MISSIONS
        {
            return Err(PayloadError::invalid(
                "payload.trial_missions",
                format!(
                    "must be in 0..={}, got {m}",
                    planner::controllers::MAX_TRIAL_MISSIONS
                ),
            ));
        }
        if let Some(t) = self.keep_threshold
            && !(t.is_finite() && t > 0.0 && t <= 1.0)
        {
            return Err(PayloadError::invalid(
                "payload.keep_threshold",
                format!("must be in (0, 1], got {t}"),
            ));
        }
        Ok(())
    }

    /// The rollout parameters asked for.
    pub fn rollout_params(&self) -> EdgeRolloutParams {
        let d = EdgeRolloutParams::default();
        EdgeRolloutParams {
            rollouts: self.rollouts.unwrap_or(d.rollouts),
            keep_threshold: self.keep_threshold.unwrap_or(d.keep_threshold),
            ..d
        }
    }

    /// The safety margin asked for.
    pub fn margin(&self) -> f64 {
        self.safety_margin_m
            .unwrap_or(rehearsal::PlanOptions::default().safety_margin_m)
    }
}

/// The roadmap job for `policy` on `place` (the plan endpoint's and an export's): the rollouts,
/// keep threshold and trial at their defaults.
pub fn request(policy: &str, place: &str, robot: &str, margin: f64) -> JobRequest {
    JobRequest::Roadmap(RoadmapPayload {
        policy: policy.to_owned(),
        place: place.to_owned(),
        robot: Some(robot.to_owned()),
        safety_margin_m: Some(margin),
        rollouts: None,
        keep_threshold: None,
        trial_missions: None,
    })
}

/// Runs `roadmap` jobs.
#[derive(Debug, Clone)]
pub struct RoadmapHandler {
    env: Arc<JobEnv>,
}

impl RoadmapHandler {
    /// A handler using `env`.
    pub fn new(env: Arc<JobEnv>) -> Self {
        Self { env }
    }
}

/// The robot a roadmap job drives: the payload's, else the one the policy was trained for.
pub fn roadmap_robot(env: &JobEnv, p: &RoadmapPayload) -> Result<String, PayloadError> {
    super::evaluate::policy_robot(
        &env.policies,
        &super::EvaluatePayload {
            policy: p.policy.clone(),
            place: p.place.clone(),
            robot: p.robot.clone(),
            episodes: None,
            seed: None,
            goals_in_view: None,
        },
    )
}

impl JobHandler for RoadmapHandler {
    async fn run(&self, ctx: JobContext) -> Result<Value, JobError> {
        let payload: RoadmapPayload = ctx.payload_as()?;
        payload.check()?;
        let robot = roadmap_robot(&self.env, &payload)?;
        let dir =
            self.env.policies.path(&payload.policy).ok_or_else(|| {
                JobError::Fatal(format!("invalid policy id {:?}", payload.policy))
            })?;
        let db = self
            .env
            .knowledge
            .floor_database(&payload.place, &robot)
            .await
            .map_err(super::source_error)?;
        if ctx.is_stopping() {
            return Err(ctx.stopped());
        }
        let params = payload.rollout_params();
        let margin = payload.margin();
        let key = PolicyRoadmapKey::new(&db.version, &payload.policy, &dir, margin, &params)
            .ok_or_else(|| JobError::Fatal("the policy's weights cannot be read".into()))?;
        let roadmaps = Arc::clone(&self.env.roadmaps);
        let trial_missions = payload
            .trial_missions
            .unwrap_or(planner::controllers::DEFAULT_TRIAL_MISSIONS)
            as usize;
        let built = tokio::task::spawn_blocking(move || -> Result<StoredRoadmap, JobError> {
            let policy = Arc::new(
                learning::Policy::load(&dir)
                    .map_err(|e| JobError::Fatal(format!("the policy does not load: {e}")))?,
            );
            let world = db.world().map_err(JobError::fatal)?;
            // The geometric roadmap plans on this floor share (the cache's key names the
            // floor's geometry and the robot's size, not the robot).
            let version = world.geometry_key().to_owned();
            let geometric =
                geometric_roadmap(&world, &roadmaps, &version, margin).map_err(JobError::fatal)?;
            let started = std::time::Instant::now();
            let report = rehearsal::drive_edges(
                &world,
                &geometric,
                || rehearsal::PolicyController::new(Arc::clone(&policy)),
                &params,
            )
            .map_err(|e| JobError::Fatal(e.to_string()))?;
            // The controllers `auto` picks from, over the same missions, the hybrid on the
            // roadmap just measured (as a plan with `roadmap: auto` would be).
            let missions =
                planner::controllers::trial_missions(&geometric, trial_missions, params.seed);
            let trial = if missions.is_empty() {
                None
            } else {
                let policy_roadmap = rehearsal::reweight_with_unkept(&geometric, &report)
                    .map_err(|e| JobError::Fatal(e.to_string()))?;
                let floor = planner::controllers::TrialFloor {
                    world: &world,
                    roadmaps: &roadmaps,
                    version: &version,
                    policy: Some(&policy),
                    policy_roadmap: Some(&policy_roadmap),
                };
                let people = planner::knowledge_people(&world, None);
                Some(
                    planner::controllers::run_trial(&floor, &missions, &people, params.seed)
                        .map_err(|e| JobError::Fatal(format!("the controller trial: {e}")))?,
                )
            };
            Ok(StoredRoadmap {
                nodes: geometric.nodes().count(),
                nodes_fingerprint: nodes_fingerprint(&geometric),
                seed: params.seed,
                wall_s: started.elapsed().as_secs_f64(),
                edges: report.edges.iter().map(StoredEdge::from).collect(),
                key,
                trial,
            })
        })
        .await
        .map_err(JobError::retryable)??;
        // A floor that changed while the roadmap was built: the build is stale. Never stored
        // (it is keyed by the old state, which plans no longer ask for); built again.
        let now = self
            .env
            .knowledge
            .floor_database(&payload.place, &robot)
            .await
            .map_err(super::source_error)?;
        if now.version != built.key.floor_state {
            return Err(JobError::Retryable(
                "the floor changed while its policy-aware roadmap was built; building it again for the new state".into(),
            ));
        }
        let path = self
            .env
            .policy_roadmaps
            .put(&built)
            .map_err(|e| JobError::Retryable(format!("storing the roadmap: {e}")))?;
        let report = built.report();
        let _ = ctx
            .report_progress(&json!({"fraction_done": 1.0, "edges": built.edges.len()}))
            .await;
        Ok(stored(&RoadmapResult {
            policy: payload.policy,
            robot,
            place: payload.place,
            floor: now.floor.clone(),
            floor_state: built.key.floor_state.clone(),
            nodes: built.nodes,
            edge_directions: built.edges.len(),
            edge_directions_kept: report.kept().count(),
            edge_success_rate: report.edge_success_rate(),
            mean_edge_time_s: report.mean_edge_time_s(),
            near_miss_rate: report.near_miss_rate(),
            rollouts: built.key.rollouts,
            keep_threshold: f64::from_bits(built.key.keep_bits),
            safety_margin_m: margin,
            wall_s: built.wall_s,
            controller: built
                .trial
                .as_ref()
                .and_then(|t| t.pick(|_| true))
                .map(Into::into),
            file: path.file_name().map(|f| f.to_string_lossy().into_owned()),
        }))
    }
}
