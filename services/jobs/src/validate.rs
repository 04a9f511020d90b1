//! `validate`: a plan tried in the mental simulation before a robot moves, as a job. The
//! payload is the request of `POST /v1/plan` and the result its answer: both go through the
//! same [`planner::Planner::plan`], so a job and a plan answer the same thing for the same input
//! (but for the commit to the fleet's schedule, which a job never makes).

use std::time::Instant;

use planner::{PlanFailure, PlanQuery};
use serde_json::Value;

use super::{JobEnv, PayloadError};
use queue::{JobContext, JobError, JobHandler};
use std::sync::Arc;
use wire::{PlanApiRequest, PlanApiResponse};

/// What a `validate` job is asked: exactly the request of `POST /v1/plan`.
pub type ValidatePayload = PlanApiRequest;

/// The planner's query of a payload, its refusals naming the payload's fields. A job checks
/// the plan against the fleet's committed plans but never commits it: it is an engineer's
/// rehearsal, not a robot's order.
pub fn query_of(request: &ValidatePayload) -> Result<PlanQuery, PayloadError> {
    let mut query = request
        .clone()
        .into_query()
        .map_err(|e| PayloadError::invalid(&format!("payload.{}", e.field), e.message))?;
    query.fleet.commit = false;
    Ok(query)
}

/// Checks a payload when the job is created: its shape, the bounds of a plan request (named in
/// the payload), and that a policy it names exists.
pub fn check(env: &JobEnv, request: &ValidatePayload) -> Result<PlanQuery, PayloadError> {
    let query = query_of(request)?;
    env.planner.check(&query).map_err(|e| match e {
        PlanFailure::NotFound(m) => PayloadError::NotFound(format!("payload.policy: {m}")),
        PlanFailure::Plan(rehearsal::PlanError::InvalidInput { field, message }) => {
            PayloadError::invalid(&format!("payload.{field}"), message)
        }
        other => match other.field() {
            Some(field) => PayloadError::invalid(&format!("payload.{field}"), other.to_string()),
            None => PayloadError::invalid("payload", other.to_string()),
        },
    })?;
    Ok(query)
}

/// Runs `validate` jobs with the planner.
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
    /// A handler using `env`'s planner.
    pub fn new(env: Arc<JobEnv>) -> Self {
        Self { env }
    }
}

impl JobHandler for ValidateHandler {
    async fn run(&self, ctx: JobContext) -> Result<Value, JobError> {
        let started = Instant::now();
        let query = super::parse(ctx.payload())
            .and_then(|request| check(&self.env, &request))
            .map_err(|m| JobError::Fatal(format!("invalid validate payload: {m}")))?;
        let start = wire::Pose::from(query.request.start);
        let _ = ctx
            .report_progress(&serde_json::json!({"stage": "simulating"}))
            .await;
        // The job's cancellation, the worker's shutdown and a lost lease stop the rehearsal at
        // its next check.
        let stop = rehearsal::Stop::new();
        let watch = {
            let (token, stop) = (ctx.cancellation().clone(), stop.clone());
            tokio::spawn(async move {
                token.cancelled().await;
                stop.request();
            })
        };
        let outcome = self.env.planner.plan(query, stop).await;
        watch.abort();
        let outcome = match outcome {
            Ok(o) => o,
            Err(PlanFailure::Plan(rehearsal::PlanError::Stopped)) if ctx.is_stopping() => {
                return Err(ctx.stopped());
            }
            Err(e @ PlanFailure::Unavailable(_)) => return Err(JobError::retryable(e)),
            Err(e) => return Err(JobError::Fatal(e.to_string())),
        };
        let answer = PlanApiResponse::of(outcome, &start, started.elapsed().as_secs_f64() * 1e3);
        serde_json::to_value(&answer).map_err(|e| JobError::Fatal(format!("the answer: {e}")))
    }
}
