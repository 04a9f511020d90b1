//! `train`: TD3 in the mental simulation of a floor, checkpointed so any worker can resume it,
//! exported as a policy at the end.
//!
//! The trainer runs on a blocking thread; its progress callback (a few times a second) sends
//! notes to the job's task, which writes progress (at most every [`PROGRESS_EVERY`]) and, after
//! every trainer checkpoint, a checkpoint reference to the queue. The callback returns false
//! once the job's context is stopping (cancel, shutdown, lost lease): the trainer then
//! checkpoints and returns, and the handler answers `Err(ctx.stopped())`.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use learning::run::{Learner, LearnerSpec, Resume, RunError};
use learning::trainer::{Budget, Progress, TrainError, TrainOptions, Trainer};
use learning::{PolicyError, Scaling, TrainConfig};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use sim::{EnvConfig, World};

use super::results::{TrainResult, measured, stored};
use super::{JobEnv, PayloadError, to_json};
use planner::{HeldOutEval, PolicySummary};
use queue::Checkpoint;
use queue::{JobContext, JobError, JobHandler, StopReason};

/// Longest training a job may ask for, minutes (a week).
pub const MAX_MINUTES: f64 = 10_080.0;

/// Progress is written at most this often.
pub const PROGRESS_EVERY: Duration = Duration::from_secs(2);
/// How often a training looks at its disk's free space.
const DISK_CHECK_EVERY: Duration = Duration::from_secs(1);

/// What a `train` job is asked.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TrainPayload {
    /// The robot: IRI or `tosm:identifier`.
    pub robot: String,
    /// A floor, or a place on one (IRI or identifier): training runs on the whole floor.
    pub place: String,
    /// Wall-clock budget in minutes (a resumed run counts its earlier sessions).
    pub minutes: f64,
    /// Training configuration: any subset of `learning::TrainConfig`'s keys (unknown keys are
    /// refused by name); defaults for the rest.
    #[serde(default)]
    #[schema(value_type = Option<Object>)]
    pub config: Option<Value>,
    /// Seed of the run (overrides `config.seed`).
    #[serde(default)]
    pub seed: Option<u64>,
}

impl TrainPayload {
    /// Values in range, the configuration valid.
    pub fn check(&self) -> Result<(), PayloadError> {
        if !(self.minutes.is_finite() && self.minutes > 0.0 && self.minutes <= MAX_MINUTES) {
            return Err(PayloadError::invalid(
                "payload.minutes",
                format!(
                    "must be a positive number of minutes, at most {MAX_MINUTES} (a week), got {}",
                    self.minutes
                ),
            ));
        }
        if self.robot.trim().is_empty() {
            return Err(PayloadError::invalid(
                "payload.robot",
                "must not be empty".into(),
            ));
        }
        if self.place.trim().is_empty() {
            return Err(PayloadError::invalid(
                "payload.place",
                "must not be empty".into(),
            ));
        }
        self.train_config().map(|_| ())
    }

    /// The training configuration: `mentalsim train`'s default preset
    /// ([`TrainConfig::fast`]), the payload's keys over it, the seed.
    pub fn train_config(&self) -> Result<TrainConfig, PayloadError> {
        let mut config = match &self.config {
            Some(v) => TrainConfig::fast()
                .with_json(v.clone())
                .map_err(|e| PayloadError::invalid("payload.config", e.to_string()))?,
            None => TrainConfig::fast(),
        };
        if let Some(seed) = self.seed {
            config.seed = seed;
        }
        config
            .validate()
            .map_err(|e| PayloadError::invalid("payload.config", e.to_string()))?;
        Ok(config)
    }
}

/// Runs `train` jobs.
#[derive(Debug, Clone)]
pub struct TrainHandler {
    env: Arc<JobEnv>,
}

impl TrainHandler {
    /// A handler using `env`.
    pub fn new(env: Arc<JobEnv>) -> Self {
        Self { env }
    }
}

enum Note {
    Progress(Value),
    Checkpoint(Value),
}

/// The job's progress, as stored and streamed.
pub fn progress_json(p: &Progress, budget_s: f64) -> Value {
    let c = &p.counters;
    let eta_s = match p.fraction_done {
        Some(f) if f >= 1.0 => Some(0.0),
        Some(f) if f > 0.0 => Some((budget_s - c.wall_s).max(0.0)),
        _ => None,
    };
    json!({
        "env_steps": c.env_steps,
        "episodes": c.episodes,
        "grad_steps": c.grad_steps,
        "wall_s": c.wall_s,
        "sessions": c.sessions,
        "success_rate_100": p.success_rate_100,
        "mean_reward_100": p.mean_reward_100,
        "last_eval": p.last_eval.as_ref().map(|e| json!({
            "env_steps": e.env_steps,
            "wall_s": e.wall_s,
            "success_rate": e.report.success_rate,
            "collision_rate": e.report.collision_rate,
            "timeout_rate": e.report.timeout_rate,
            "episodes": e.report.episodes,
        })),
        "fraction_done": p.fraction_done,
        "budget_s": budget_s,
        "eta_s": eta_s,
    })
}

enum Finished {
    Stopped,
    Done(Box<TrainResult>),
}

struct Run {
    world: Arc<World>,
    options: TrainOptions,
    budget: Budget,
    policy_id: String,
    summary: PolicySummary,
    env: Arc<JobEnv>,
}

impl JobHandler for TrainHandler {
    async fn run(&self, ctx: JobContext) -> Result<Value, JobError> {
        let payload: TrainPayload = ctx.payload_as()?;
        payload.check()?;
        let config = payload.train_config()?;
        let db = self
            .env
            .knowledge
            .floor_database(&payload.place, &payload.robot)
            .await
            .map_err(super::source_error)?;
        let floor_iri = db.floor.clone();
        let robot_iri = db.robot.clone();
        let world = tokio::task::spawn_blocking(move || db.world())
            .await
            .map_err(JobError::retryable)?
            .map_err(JobError::fatal)?;
        if ctx.is_stopping() {
            return Err(ctx.stopped());
        }
        let out_dir = checkpoint_dir(ctx.checkpoint(), ctx.id(), &self.env.checkpoints_dir);
        std::fs::create_dir_all(&out_dir).map_err(|e| {
            JobError::Retryable(format!("cannot create {}: {e}", out_dir.display()))
        })?;
        let budget_s = payload.minutes * 60.0;
        let policy_id = ctx.id().to_string();
        let run = Run {
            world,
            options: TrainOptions {
                config,
                env: EnvConfig::default(),
                scaling: Scaling::default(),
                out_dir: out_dir.clone(),
            },
            budget: Budget {
                wall_s: Some(budget_s),
                env_steps: None,
            },
            summary: PolicySummary {
                policy_id: Some(policy_id.clone()),
                robot: Some(robot_iri),
                place: Some(payload.place.clone()),
                floor: Some(floor_iri),
                job_id: Some(ctx.id().to_string()),
                created_ms: 0,
                eval: None,
            },
            policy_id,
            env: self.env.clone(),
        };

        let (tx, mut rx) = tokio::sync::mpsc::unbounded_channel::<Note>();
        let blocking_ctx = ctx.clone();
        let task = tokio::task::spawn_blocking(move || train_blocking(run, &blocking_ctx, &tx));
        while let Some(note) = rx.recv().await {
            let written = match &note {
                Note::Progress(p) => ctx.report_progress(p).await.map(|_| ()),
                Note::Checkpoint(c) => ctx.save_checkpoint(&Checkpoint::new(c.clone())).await,
            };
            // A lost lease stops the context (and so the trainer); other write failures are
            // logged: the trainer's files are the truth, the queue only points at them.
            if let Err(e) = written {
                tracing::warn!(job = %ctx.id(), error = %e, "recording training progress failed");
            }
        }
        let finished = task
            .await
            .map_err(|e| JobError::Retryable(format!("the training thread failed: {e}")))?;
        match finished {
            Ok(Finished::Done(mut result)) => {
                // The job will not resume: its checkpoint is no longer needed.
                let _ = std::fs::remove_dir_all(&out_dir);
                // The new policy's roadmap of the floor it was trained on, in the background,
                // so that the first plan with it finds it built.
                let follow_up = super::roadmap::request(
                    &ctx.id().to_string(),
                    &payload.place,
                    &payload.robot,
                    rehearsal::PlanOptions::default().safety_margin_m,
                )
                .to_job();
                match ctx.enqueue(follow_up).await {
                    Ok(id) => result.roadmap_job = Some(id.to_string()),
                    Err(e) => {
                        tracing::warn!(job = %ctx.id(), error = %e, "enqueueing the policy's roadmap job failed");
                    }
                }
                Ok(stored(&*result))
            }
            Ok(Finished::Stopped) => {
                if ctx.stop_reason() == Some(StopReason::CancelRequested) {
                    let _ = std::fs::remove_dir_all(&out_dir);
                }
                Err(ctx.stopped())
            }
            Err(e) => Err(e),
        }
    }
}

/// The title of a training job's curves.
pub fn curves_title(job: impl std::fmt::Display) -> String {
    format!("TD3 in the mental simulation: training job {job}")
}

/// Where this job checkpoints: the directory the queue's checkpoint names when it holds a
/// checkpoint here, else `<checkpoints_dir>/<job id>`.
/// (Also where `GET /v1/jobs/{id}/curves.csv` reads a running training's episodes.)
pub fn checkpoint_dir(
    checkpoint: Option<&Checkpoint>,
    job: uuid::Uuid,
    checkpoints_dir: &Path,
) -> PathBuf {
    let recorded = checkpoint
        .and_then(|c| c.data["dir"].as_str())
        .map(PathBuf::from)
        .filter(|d| Trainer::has_checkpoint(d));
    recorded.unwrap_or_else(|| checkpoints_dir.join(job.to_string()))
}

/// A training pipeline's error as the job's: out of memory is this machine's state, not the
/// job's (another attempt may find room); a file that found the disk full waits for space;
/// other files are retried; the rest (settings, evaluation) fails the job.
fn run_error(what: &str, e: RunError) -> JobError {
    let message = format!("{what}: {e}");
    match e {
        RunError::Train(TrainError::OutOfMemory(_)) => JobError::Retryable(message),
        RunError::Train(TrainError::Checkpoint { .. }) => unless_full(message, JobError::Fatal),
        RunError::Io { .. } | RunError::Plot(_) | RunError::Policy(PolicyError::Io { .. }) => {
            unless_full(message, JobError::Retryable)
        }
        _ => JobError::Fatal(message),
    }
}

/// `OutOfSpace` when the message of an error writing this job's own files says the disk is
/// full (the edge's reading of such messages), else `otherwise(message)`.
fn unless_full(message: String, otherwise: fn(String) -> JobError) -> JobError {
    let full = edge::disk::is_out_of_space(&message);
    JobError::unless_out_of_space(message, full, otherwise)
}

fn train_blocking(
    run: Run,
    ctx: &JobContext,
    tx: &tokio::sync::mpsc::UnboundedSender<Note>,
) -> Result<Finished, JobError> {
    let Run {
        world,
        options,
        budget,
        policy_id,
        mut summary,
        env,
    } = run;
    let out_dir = options.out_dir.clone();
    let budget_s = budget.wall_s.unwrap_or(0.0);
    let mut learner = Learner::open(LearnerSpec {
        world: Arc::clone(&world),
        extra_worlds: Vec::new(),
        hold_out: false,
        options,
        resume: Resume::CheckpointOrFresh,
    })
    .map_err(|e| run_error("training", e))?;
    if let Some(why) = learner.discarded_checkpoint() {
        tracing::warn!(job = %ctx.id(), error = %why, "the checkpoint cannot be resumed; starting over");
    } else if learner.resumed() {
        tracing::info!(job = %ctx.id(), dir = %out_dir.display(), env_steps = learner.trainer().counters().env_steps, "resuming training from its checkpoint");
    }
    // A checkpoint replaces the previous one only under a freshly renewed lease: a worker that
    // lost the job cannot overwrite what its successor wrote.
    let fence = ctx.clone();
    learner.trainer_mut().set_install_guard(Box::new(move || {
        fence.fence_blocking().map_err(|e| e.to_string())
    }));
    let mut last_sent: Option<Instant> = None;
    let mut checkpoints = 0u64;
    let (mut disk_checked, mut out_of_space) = (Instant::now(), false);
    let mut on_progress = |p: &Progress| {
        // A full disk stops the training before its next checkpoint fails half-written.
        if let Some(disk) = &env.disk
            && disk_checked.elapsed() >= DISK_CHECK_EVERY
        {
            disk_checked = Instant::now();
            out_of_space = !disk.has_room(0);
        }
        if p.checkpoints_written != checkpoints {
            checkpoints = p.checkpoints_written;
            let _ = tx.send(Note::Checkpoint(json!({
                "dir": out_dir.display().to_string(),
                "env_steps": p.counters.env_steps,
                "episodes": p.counters.episodes,
                "wall_s": p.counters.wall_s,
            })));
        }
        if last_sent.is_none_or(|t| t.elapsed() >= PROGRESS_EVERY) {
            last_sent = Some(Instant::now());
            let _ = tx.send(Note::Progress(progress_json(p, budget_s)));
        }
        !ctx.is_stopping() && !out_of_space
    };
    learner
        .train(budget_s, &mut on_progress)
        .map_err(|e| run_error("training", e))?;
    let trainer = learner.trainer();
    if out_of_space && !ctx.is_stopping() {
        return Err(JobError::OutOfSpace(format!(
            "training stopped at {} environment steps: less than {} MiB free for checkpoints",
            trainer.counters().env_steps,
            env.disk
                .as_ref()
                .map_or(0, edge::disk::DiskWatch::min_free_bytes)
                >> 20
        )));
    }
    let progress = trainer.progress(&budget);
    let _ = tx.send(Note::Progress(progress_json(&progress, budget_s)));
    if ctx.is_stopping() {
        return Ok(Finished::Stopped);
    }

    // Export with the learning curves (`GET /v1/jobs/{id}/curves.csv`, `.png`), then evaluate
    // the exported policy with the pure-Rust runtime robots embed, as `mentalsim train` does.
    // Staged under this attempt's own name; installed only under a renewed lease.
    let staged = env.policies.staging(&policy_id, ctx.attempt());
    let io = |what: &str, e: std::io::Error| JobError::Retryable(format!("{what}: {e}"));
    if staged.exists() {
        std::fs::remove_dir_all(&staged).map_err(|e| io("clearing the staging directory", e))?;
    }
    let policy = learner
        .export(&staged, &curves_title(ctx.id()), to_json(&summary))
        .map_err(|e| {
            let _ = std::fs::remove_dir_all(&staged);
            run_error("exporting the policy", e)
        })?;
    let config = &trainer.options().config;
    let held_out = learning::run::evaluate(
        &policy,
        &world,
        config,
        config.eval_episodes,
        learning::Goals::InView,
    )
    .map_err(|e| run_error("evaluating the exported policy", e))?;
    let report = held_out.report;
    let created_ms = queue::Clock::now_ms(&queue::SystemClock);
    summary.created_ms = created_ms;
    summary.eval = Some(HeldOutEval {
        success_rate: report.success_rate,
        collision_rate: report.collision_rate,
        timeout_rate: report.timeout_rate,
        mean_time_to_goal_s: measured(report.mean_time_to_goal_s),
        episodes: report.episodes,
        seed: learning::run::held_out_seed(config),
        goals: "in-view".to_owned(),
    });
    learning::policy::set_summary(&staged, to_json(&summary))
        .map_err(|e| unless_full(format!("exporting the policy: {e}"), JobError::Retryable))?;
    ctx.fence_blocking()?;
    env.policies
        .install(&policy_id, &staged)
        .map_err(|e| io("installing the policy", e))?;
    let counters = trainer.counters();
    Ok(Finished::Done(Box::new(TrainResult {
        policy: format!("/v1/policies/{policy_id}"),
        policy_id,
        success_rate: report.success_rate,
        collision_rate: report.collision_rate,
        timeout_rate: report.timeout_rate,
        mean_time_to_goal_s: measured(report.mean_time_to_goal_s),
        eval_episodes: report.episodes,
        episodes: counters.episodes,
        env_steps: counters.env_steps,
        grad_steps: counters.grad_steps,
        wall_s: counters.wall_s,
        sessions: counters.sessions,
        robot: summary.robot.clone().unwrap_or_default(),
        place: summary.place.clone().unwrap_or_default(),
        floor: summary.floor.clone().unwrap_or_default(),
        last_training_eval: to_json(&trainer.evals().last()),
        roadmap_job: None,
    })))
}
