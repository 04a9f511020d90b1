//! `evaluate`: an exported policy, run by the pure-Rust runtime robots embed, on random
//! missions in the mental simulation of a floor.

use std::sync::Arc;

use learning::Policy;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};

use super::results::{EvaluateResult, measured, stored};
use super::{JobEnv, PayloadError, PolicyStore};
use queue::{JobContext, JobError, JobHandler};

/// Missions run when the payload does not say.
pub const DEFAULT_EPISODES: usize = 100;
/// Most missions one job may run.
pub const MAX_EPISODES: usize = 100_000;

/// What an `evaluate` job is asked.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EvaluatePayload {
    /// The policy's id (see `GET /v1/policies`).
    pub policy: String,
    /// A floor, or a place on one (IRI or identifier).
    pub place: String,
    /// The robot [default: the one the policy was trained for].
    #[serde(default)]
    pub robot: Option<String>,
    /// Missions to run [default: 100].
    #[serde(default)]
    pub episodes: Option<usize>,
    /// Seed of the mission set [default: 7].
    #[serde(default)]
    pub seed: Option<u64>,
    /// Only goals the robot can reach in a straight line, as between a plan's waypoints
    /// [default: true]; false also draws goals behind walls.
    #[serde(default)]
    pub goals_in_view: Option<bool>,
}

impl EvaluatePayload {
    /// Values in range.
    pub fn check(&self) -> Result<(), PayloadError> {
        match self.episodes {
            Some(n) if n == 0 || n > MAX_EPISODES => Err(PayloadError::invalid(
                "payload.episodes",
                format!("must be in 1..={MAX_EPISODES}, got {n}"),
            )),
            _ if !planner::policies::valid_id(&self.policy) => Err(PayloadError::NotFound(
                format!("payload.policy: no policy has id {:?}", self.policy),
            )),
            _ => Ok(()),
        }
    }
}

/// The robot to evaluate with: the payload's, else the one the policy was trained for.
pub fn policy_robot(policies: &PolicyStore, p: &EvaluatePayload) -> Result<String, PayloadError> {
    let summary = policies.summary(&p.policy).ok_or_else(|| {
        PayloadError::NotFound(format!("payload.policy: no policy has id {:?}", p.policy))
    })?;
    match (&p.robot, summary.robot) {
        (Some(r), _) => Ok(r.clone()),
        (None, Some(r)) => Ok(r),
        (None, None) => Err(PayloadError::invalid(
            "payload.robot",
            "the policy does not say which robot it was trained for; name one".to_owned(),
        )),
    }
}

/// Runs `evaluate` jobs.
#[derive(Debug, Clone)]
pub struct EvaluateHandler {
    env: Arc<JobEnv>,
}

impl EvaluateHandler {
    /// A handler using `env`.
    pub fn new(env: Arc<JobEnv>) -> Self {
        Self { env }
    }
}

impl JobHandler for EvaluateHandler {
    async fn run(&self, ctx: JobContext) -> Result<Value, JobError> {
        let payload: EvaluatePayload = ctx.payload_as()?;
        payload.check()?;
        let robot = policy_robot(&self.env.policies, &payload)?;
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
        let episodes = payload.episodes.unwrap_or(DEFAULT_EPISODES);
        let seed = payload.seed.unwrap_or(7);
        let in_view = payload.goals_in_view.unwrap_or(true);
        let floor = db.floor.clone();
        let report = tokio::task::spawn_blocking(move || -> Result<_, JobError> {
            let policy = Policy::load(&dir)
                .map_err(|e| JobError::Fatal(format!("the policy does not load: {e}")))?;
            let world = db.world().map_err(JobError::fatal)?;
            learning::evaluate_held_out(&policy, &world, episodes, seed, in_view)
                .map_err(|e| JobError::Fatal(format!("evaluation: {e}")))
        })
        .await
        .map_err(JobError::retryable)??;
        let _ = ctx
            .report_progress(&json!({"episodes": report.episodes, "fraction_done": 1.0}))
            .await;
        Ok(stored(&EvaluateResult {
            policy: payload.policy,
            robot,
            place: payload.place,
            floor,
            success_rate: report.success_rate,
            collision_rate: report.collision_rate,
            timeout_rate: report.timeout_rate,
            mean_time_to_goal_s: measured(report.mean_time_to_goal_s),
            mean_return: report.mean_return,
            episodes: report.episodes,
            env_steps: report.env_steps,
            wall_s: report.wall_s,
            seed,
            goals_in_view: in_view,
        }))
    }
}
