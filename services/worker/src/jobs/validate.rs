//! `validate`: a plan tried in the mental simulation before a robot moves. The handler does
//! what every kind does — payload, world from the knowledge service, blocking thread,
//! cancellation — and hands the world to a [`PlanValidator`], the plan executor's hook (the
//! `rehearsal` crate's hybrid PRM–RL executor implements it through
//! [`ExecutorValidator`](crate::plan_api::ExecutorValidator); see `JobEnv::validator`). Without
//! one, creating a `validate` job is refused (422) and a stray one fails as fatal.

use std::sync::Arc;

use serde::{Deserialize, Serialize};
use serde_json::Value;
use sim::World;

use super::JobEnv;
use crate::runner::{JobContext, JobError, JobHandler};

/// What every `validate` payload carries; the rest is the validator's (it checks it).
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
pub struct ValidatePayload {
    /// The robot: IRI or identifier.
    pub robot: String,
    /// A floor, or a place on one (IRI or identifier).
    pub place: String,
    /// The plan and the validator's options (waypoints, policy, runs, seed, ...).
    #[serde(flatten)]
    #[schema(value_type = Object)]
    pub rest: serde_json::Map<String, Value>,
}

/// The plan executor's hook.
pub trait PlanValidator: Send + Sync + 'static {
    /// Checks a payload when the job is created: a value out of range is
    /// [`PayloadError::Invalid`] naming the field (`payload.goals: ...`, 422), a policy that
    /// does not exist [`PayloadError::NotFound`] (404).
    fn check(&self, payload: &Value) -> Result<(), super::PayloadError>;

    /// Validates the plan of `payload` in `world` and returns the job's result. Runs on a
    /// blocking thread: poll `stopping` between runs and return [`JobError::Stopped`] (any
    /// reason; the runner knows the real one) when it is true. `progress` records a progress
    /// report (it is rate-limited by the caller's patience, not here: call it at most every
    /// second or so).
    fn validate(
        &self,
        world: Arc<World>,
        payload: &Value,
        stopping: &dyn Fn() -> bool,
        progress: &dyn Fn(Value),
    ) -> Result<Value, JobError>;
}

/// Runs `validate` jobs with the configured [`PlanValidator`].
#[derive(Clone)]
pub struct ValidateHandler {
    env: Arc<JobEnv>,
}

impl std::fmt::Debug for ValidateHandler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ValidateHandler").finish_non_exhaustive()
    }
}

impl ValidateHandler {
    /// A handler using `env` (and its validator, if any).
    pub fn new(env: Arc<JobEnv>) -> Self {
        Self { env }
    }
}

impl JobHandler for ValidateHandler {
    async fn run(&self, ctx: JobContext) -> Result<Value, JobError> {
        let Some(validator) = self.env.validator.clone() else {
            return Err(JobError::Fatal(
                "validate jobs are not available yet: this worker has no plan validator".to_owned(),
            ));
        };
        let payload: ValidatePayload = ctx.payload_as()?;
        validator
            .check(ctx.payload())
            .map_err(|m| JobError::Fatal(format!("invalid validate payload: {m}")))?;
        let db = self
            .env
            .knowledge
            .floor_database(&payload.place, &payload.robot)
            .await?;
        let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<Value>();
        let blocking_ctx = ctx.clone();
        let raw = ctx.payload().clone();
        let task = tokio::task::spawn_blocking(move || {
            let world = db.world().map_err(JobError::Fatal)?;
            let stopping = || blocking_ctx.is_stopping();
            let progress = |v: Value| {
                let _ = tx.send(v);
            };
            validator.validate(world, &raw, &stopping, &progress)
        });
        while let Some(p) = rx.recv().await {
            if let Err(e) = ctx.report_progress(&p).await {
                tracing::warn!(job = %ctx.id(), error = %e, "recording validation progress failed");
            }
        }
        let result = task.await.map_err(JobError::retryable)?;
        match result {
            Err(JobError::Stopped(_)) => Err(ctx.stopped()),
            other => other,
        }
    }
}
