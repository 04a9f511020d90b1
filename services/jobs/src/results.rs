//! What each job kind answers when it succeeds: typed, with schemas, so a client can type a
//! job's `result` by its `kind` ([`JobResult`]). Handlers build these and store them as JSON.

use serde::{Deserialize, Serialize};
use serde_json::Value;
use utoipa::ToSchema;

use wire::PlanApiResponse;

/// A finished `train` job: the exported policy and its held-out evaluation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TrainResult {
    /// The exported policy's id.
    pub policy_id: String,
    /// Where to read it (`/v1/policies/{id}`).
    pub policy: String,
    /// Held-out missions reached.
    pub success_rate: f64,
    /// Held-out missions ended by a collision.
    pub collision_rate: f64,
    /// Held-out missions out of time.
    pub timeout_rate: f64,
    /// Mean simulated time of the reached held-out missions, seconds.
    pub mean_time_to_goal_s: Option<f64>,
    /// Held-out missions run.
    pub eval_episodes: usize,
    /// Training episodes.
    pub episodes: u64,
    /// Environment steps.
    pub env_steps: u64,
    /// Gradient steps.
    pub grad_steps: u64,
    /// Training wall time, seconds (every session).
    pub wall_s: f64,
    /// Sessions the training ran in (resumed after a restart or a lost lease).
    pub sessions: u32,
    /// The robot's IRI.
    pub robot: String,
    /// The place the job named.
    pub place: String,
    /// The floor's IRI.
    pub floor: String,
    /// The last evaluation during training.
    #[schema(value_type = Option<Object>)]
    pub last_training_eval: Value,
    /// The `roadmap` job enqueued to build the policy's roadmap of the floor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub roadmap_job: Option<String>,
}

/// A finished `evaluate` job.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct EvaluateResult {
    /// The policy evaluated.
    pub policy: String,
    /// The robot it drove.
    pub robot: String,
    /// The place the job named.
    pub place: String,
    /// The floor's IRI.
    pub floor: String,
    /// Missions reached.
    pub success_rate: f64,
    /// Missions ended by a collision.
    pub collision_rate: f64,
    /// Missions out of time.
    pub timeout_rate: f64,
    /// Mean simulated time of the reached missions, seconds.
    pub mean_time_to_goal_s: Option<f64>,
    /// Mean return (Eq. 1) per mission.
    pub mean_return: f64,
    /// Missions run.
    pub episodes: usize,
    /// Environment steps.
    pub env_steps: u64,
    /// Wall time, seconds.
    pub wall_s: f64,
    /// Seed of the missions.
    pub seed: u64,
    /// Whether goals were drawn in view of the start.
    pub goals_in_view: bool,
}

/// A finished `roadmap` job: the policy-aware roadmap it stored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct RoadmapResult {
    /// The policy that drove the edges.
    pub policy: String,
    /// The robot.
    pub robot: String,
    /// The place the job named.
    pub place: String,
    /// The floor's IRI.
    pub floor: String,
    /// The floor state it was built for.
    pub floor_state: String,
    /// Nodes of the geometric roadmap.
    pub nodes: usize,
    /// Edge directions driven.
    pub edge_directions: usize,
    /// Edge directions kept (success at least the keep threshold).
    pub edge_directions_kept: usize,
    /// Rollouts that arrived, over all directions.
    pub edge_success_rate: f64,
    /// Mean simulated time of the arrivals, seconds.
    pub mean_edge_time_s: Option<f64>,
    /// Rollouts closer than 10 cm to an obstacle.
    pub near_miss_rate: f64,
    /// Rollouts per direction.
    pub rollouts: u32,
    /// Success a direction needs to be kept.
    pub keep_threshold: f64,
    /// Clearance kept from obstacles, metres.
    pub safety_margin_m: f64,
    /// Build time, seconds.
    pub wall_s: f64,
    /// What `options.controller: auto` validates with on this floor state from now on, from
    /// the controller trial the job drove (absent with `trial_missions: 0`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub controller: Option<wire::ControllerChoiceReport>,
    /// The stored file's name.
    pub file: Option<String>,
}

/// A job's result by its kind (documentation of `JobView.result`: the `kind` beside it says
/// which form it has).
#[derive(Debug, Clone, Serialize, ToSchema)]
#[serde(untagged)]
pub enum JobResult {
    /// `train`.
    Train(TrainResult),
    /// `evaluate`.
    Evaluate(EvaluateResult),
    /// `validate`: the answer `POST /v1/plan` gives for the same request.
    Validate(Box<PlanApiResponse>),
    /// `roadmap`.
    Roadmap(RoadmapResult),
}

/// A mean that is `NaN` when nothing was measured, as an option.
pub fn measured(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// A result as the JSON the queue stores (serialising our own types cannot fail).
pub fn stored<T: Serialize>(result: &T) -> Value {
    serde_json::to_value(result).unwrap_or(Value::Null)
}
