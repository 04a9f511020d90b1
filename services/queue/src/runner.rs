//! The runner: a [`Worker`] claims jobs of the kinds it has handlers for, runs each with a
//! heartbeat task that keeps its lease, hands the handler a [`JobContext`], and records the
//! outcome.
//!
//! Cancellation is cooperative. The context's token fires when a cancel is requested (seen at a
//! heartbeat or a progress/checkpoint write), when the worker shuts down, or when the lease was
//! lost; [`JobContext::stop_reason`] tells which. A handler that sees it should save a
//! checkpoint and return [`JobError::Stopped`]. On shutdown the job is then released back to the
//! queue without counting the attempt, and another worker resumes it from the checkpoint.

use std::collections::{BTreeMap, HashMap};
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

use serde::de::DeserializeOwned;
use serde_json::Value;
use tokio::sync::Semaphore;
use tokio::task::{AbortHandle, JoinSet};
use tokio_util::sync::CancellationToken;
use uuid::Uuid;

use crate::jobs::{Checkpoint, Claimed, Job, JobState, Lease, Queue, QueueError};

/// Why a handler's cancellation token fired.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StopReason {
    /// Someone asked to cancel the job: stop; the job ends `cancelled`.
    CancelRequested,
    /// The worker is shutting down: checkpoint and stop; the job goes back to the queue.
    Shutdown,
    /// The lease is gone (another worker owns the job): stop; nothing more can be written.
    LeaseLost,
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::CancelRequested => "cancel requested",
            Self::Shutdown => "worker shutting down",
            Self::LeaseLost => "lease lost",
        })
    }
}

/// How a handler's run ended, when not with a result.
#[derive(Debug, thiserror::Error)]
pub enum JobError {
    /// A transient failure: retried after the backoff while attempts remain.
    #[error("{0}")]
    Retryable(String),
    /// A permanent failure (bad payload, impossible request): the job fails now.
    #[error("{0}")]
    Fatal(String),
    /// The handler stopped because its cancellation token fired.
    #[error("stopped: {0}")]
    Stopped(StopReason),
    /// The disk is (nearly) full: the job goes back to the queue without the attempt counting
    /// and runs again, from its last checkpoint, after the retry backoff.
    #[error("{0}")]
    OutOfSpace(String),
    /// A queue write failed (including [`QueueError::LeaseLost`]).
    #[error(transparent)]
    Queue(#[from] QueueError),
}

impl JobError {
    /// A retryable error from anything displayable.
    pub fn retryable(e: impl std::fmt::Display) -> Self {
        Self::Retryable(e.to_string())
    }

    /// A fatal error from anything displayable.
    pub fn fatal(e: impl std::fmt::Display) -> Self {
        Self::Fatal(e.to_string())
    }

    /// `OutOfSpace` when `out_of_space` (the caller's reading of an error writing the job's
    /// own files), else `otherwise(message)`. Only a handler's own file errors are classified
    /// so: a message quoting a user's input must never defer a job forever.
    pub fn unless_out_of_space(
        message: String,
        out_of_space: bool,
        otherwise: fn(String) -> Self,
    ) -> Self {
        if out_of_space {
            Self::OutOfSpace(message)
        } else {
            otherwise(message)
        }
    }
}

/// What a handler gets: the job, its lease, and fenced ways to write progress and checkpoints.
/// Cheap to clone (for sub-tasks).
#[derive(Debug, Clone)]
pub struct JobContext {
    inner: Arc<ContextInner>,
}

#[derive(Debug)]
struct ContextInner {
    queue: Queue,
    job: Job,
    lease: Lease,
    /// How long a renewal extends the lease.
    lease_len: Duration,
    token: CancellationToken,
    reason: OnceLock<StopReason>,
}

impl JobContext {
    fn new(queue: Queue, claimed: Claimed, lease_len: Duration) -> Self {
        Self {
            inner: Arc::new(ContextInner {
                queue,
                job: claimed.job,
                lease: claimed.lease,
                lease_len,
                token: CancellationToken::new(),
                reason: OnceLock::new(),
            }),
        }
    }

    /// The job as it was when claimed.
    pub fn job(&self) -> &Job {
        &self.inner.job
    }

    /// The job's id.
    pub fn id(&self) -> Uuid {
        self.inner.job.id
    }

    /// This attempt (1-based).
    pub fn attempt(&self) -> u32 {
        self.inner.lease.attempt
    }

    /// The lease this run writes under.
    pub fn lease(&self) -> &Lease {
        &self.inner.lease
    }

    /// The payload.
    pub fn payload(&self) -> &Value {
        &self.inner.job.payload
    }

    /// The payload as `T`; a mismatch is a [`JobError::Fatal`] (retrying cannot fix it).
    pub fn payload_as<T: DeserializeOwned>(&self) -> Result<T, JobError> {
        serde_json::from_value(self.inner.job.payload.clone())
            .map_err(|e| JobError::Fatal(format!("invalid {} payload: {e}", self.job().kind)))
    }

    /// The last checkpoint saved before this attempt started (by any earlier attempt).
    pub fn checkpoint(&self) -> Option<&Checkpoint> {
        self.inner.job.checkpoint.as_ref()
    }

    /// Fires on cancel request, shutdown or lost lease; see [`JobContext::stop_reason`].
    pub fn cancellation(&self) -> &CancellationToken {
        &self.inner.token
    }

    /// Why the token fired, if it did.
    pub fn stop_reason(&self) -> Option<StopReason> {
        self.inner.reason.get().copied()
    }

    /// Whether the handler should stop.
    pub fn is_stopping(&self) -> bool {
        self.inner.token.is_cancelled()
    }

    /// The error a handler returns when it stops on the token.
    pub fn stopped(&self) -> JobError {
        JobError::Stopped(self.stop_reason().unwrap_or(StopReason::Shutdown))
    }

    fn stop(&self, reason: StopReason) {
        // The first reason wins: a shutdown after a cancel request is still a cancel.
        let _ = self.inner.reason.set(reason);
        self.inner.token.cancel();
    }

    fn written<T>(&self, result: Result<T, QueueError>) -> Result<T, JobError> {
        if let Err(QueueError::LeaseLost { .. }) = &result {
            self.stop(StopReason::LeaseLost);
        }
        Ok(result?)
    }

    /// Records progress (opaque JSON: steps, episodes, success rate, reward stats, ETA) and
    /// appends it to the job's event stream. Returns the event id.
    pub async fn report_progress(&self, progress: &Value) -> Result<i64, JobError> {
        let (ack, id) = self.written(
            self.inner
                .queue
                .report_progress(&self.inner.lease, progress)
                .await,
        )?;
        if ack.cancel_requested {
            self.stop(StopReason::CancelRequested);
        }
        Ok(id)
    }

    /// Renews the lease under its fencing token, from a blocking thread of the runtime: `Ok`
    /// means this attempt owns the job for at least one more lease period, so a file installed
    /// right after (a checkpoint, an exported policy) cannot race another worker's. A lost
    /// lease stops the job.
    pub fn fence_blocking(&self) -> Result<(), JobError> {
        let handle = tokio::runtime::Handle::try_current()
            .map_err(|e| JobError::Retryable(format!("no runtime to renew the lease on: {e}")))?;
        let renewed = handle.block_on(
            self.inner
                .queue
                .heartbeat(&self.inner.lease, self.inner.lease_len),
        );
        let ack = self.written(renewed)?;
        if ack.cancel_requested {
            self.stop(StopReason::CancelRequested);
        }
        Ok(())
    }

    /// Enqueues a follow-up job (a policy's roadmap after its export, say).
    pub async fn enqueue(&self, job: crate::jobs::NewJob) -> Result<Uuid, JobError> {
        self.inner
            .queue
            .enqueue(job)
            .await
            .map_err(|e| JobError::Retryable(format!("enqueueing a follow-up job: {e}")))
    }

    /// Stores a checkpoint durably; a later attempt (on any worker) starts from it.
    pub async fn save_checkpoint(&self, checkpoint: &Checkpoint) -> Result<(), JobError> {
        let ack = self.written(
            self.inner
                .queue
                .save_checkpoint(&self.inner.lease, checkpoint)
                .await,
        )?;
        if ack.cancel_requested {
            self.stop(StopReason::CancelRequested);
        }
        Ok(())
    }
}

/// Runs jobs of one kind.
///
/// ```ignore
/// struct Train;
/// impl JobHandler for Train {
///     async fn run(&self, ctx: JobContext) -> Result<serde_json::Value, JobError> { ... }
/// }
/// ```
pub trait JobHandler: Send + Sync + 'static {
    /// Runs one attempt of the job. Returns the result, or how it ended otherwise.
    fn run(&self, ctx: JobContext) -> impl Future<Output = Result<Value, JobError>> + Send;
}

/// A handler from an async closure: `handler_fn(|ctx| async move { ... })`.
pub fn handler_fn<F, Fut>(f: F) -> FnHandler<F>
where
    F: Fn(JobContext) -> Fut + Send + Sync + 'static,
    Fut: Future<Output = Result<Value, JobError>> + Send + 'static,
{
    FnHandler(f)
}

/// See [`handler_fn`].
#[derive(Debug, Clone)]
pub struct FnHandler<F>(F);

impl<F, Fut> JobHandler for FnHandler<F>
where
    F: Fn(JobContext) -> Fut + Send + Sync + 'static,
    Fut: Future<Output = Result<Value, JobError>> + Send + 'static,
{
    fn run(&self, ctx: JobContext) -> impl Future<Output = Result<Value, JobError>> + Send {
        (self.0)(ctx)
    }
}

type BoxedRun<'a> = Pin<Box<dyn Future<Output = Result<Value, JobError>> + Send + 'a>>;

trait ErasedHandler: Send + Sync {
    fn run_boxed(&self, ctx: JobContext) -> BoxedRun<'_>;
}

impl<H: JobHandler> ErasedHandler for H {
    fn run_boxed(&self, ctx: JobContext) -> BoxedRun<'_> {
        Box::pin(self.run(ctx))
    }
}

/// How a [`Worker`] runs.
#[derive(Debug, Clone)]
pub struct WorkerConfig {
    /// The lease owner name (unique per worker: host, pid and a random suffix by default).
    pub id: String,
    /// Jobs run at once.
    pub concurrency: usize,
    /// Lease length; renewed every `heartbeat`. A worker that dies loses its jobs after this.
    pub lease: Duration,
    /// Heartbeat period (well below `lease`).
    pub heartbeat: Duration,
    /// Wait between claims when the queue is empty (or the database is down).
    pub poll_interval: Duration,
    /// After shutdown is signalled, how long handlers get to checkpoint and stop before they
    /// are aborted; their jobs are released either way.
    pub shutdown_grace: Duration,
}

impl Default for WorkerConfig {
    fn default() -> Self {
        Self {
            id: default_worker_id(),
            concurrency: 1,
            lease: Duration::from_secs(30),
            heartbeat: Duration::from_secs(10),
            poll_interval: Duration::from_secs(1),
            shutdown_grace: Duration::from_secs(30),
        }
    }
}

/// `host-pid-xxxxxxxx`.
pub fn default_worker_id() -> String {
    let host = std::env::var("HOSTNAME")
        .ok()
        .filter(|h| !h.is_empty())
        .or_else(|| {
            std::fs::read_to_string("/etc/hostname")
                .ok()
                .map(|h| h.trim().to_owned())
        })
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "worker".to_owned());
    let suffix = Uuid::new_v4().simple().to_string();
    format!(
        "{host}-{}-{}",
        std::process::id(),
        suffix.get(..8).unwrap_or(&suffix)
    )
}

/// What a worker did, counted by outcome (returned when it stops).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct WorkerReport {
    /// Jobs claimed.
    pub claimed: u64,
    /// Recorded as succeeded.
    pub succeeded: u64,
    /// Failed for good.
    pub failed: u64,
    /// Failed and queued for a retry.
    pub retried: u64,
    /// Recorded as cancelled.
    pub cancelled: u64,
    /// Released to the queue on shutdown.
    pub released: u64,
    /// Lease lost: another worker owns the job; nothing recorded.
    pub lost: u64,
}

#[derive(Debug, Clone, Copy)]
enum Outcome {
    Succeeded,
    Failed,
    Retried,
    Cancelled,
    Released,
    Lost,
}

/// Claims and runs jobs until shut down.
pub struct Worker {
    queue: Queue,
    config: WorkerConfig,
    handlers: BTreeMap<String, Arc<dyn ErasedHandler>>,
}

impl std::fmt::Debug for Worker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Worker")
            .field("config", &self.config)
            .field("kinds", &self.handlers.keys().collect::<Vec<_>>())
            .finish_non_exhaustive()
    }
}

/// Aborts a task when dropped (so aborting a job's task also stops its handler and heartbeat).
struct AbortOnDrop(AbortHandle);

impl Drop for AbortOnDrop {
    fn drop(&mut self) {
        self.0.abort();
    }
}

type Running = Arc<Mutex<HashMap<Uuid, Lease>>>;

impl Worker {
    /// A worker with no handlers yet.
    pub fn new(queue: Queue, config: WorkerConfig) -> Self {
        Self {
            queue,
            config,
            handlers: BTreeMap::new(),
        }
    }

    /// Runs jobs of `kind` with `handler` (replacing an earlier handler of that kind).
    pub fn register(mut self, kind: impl Into<String>, handler: impl JobHandler) -> Self {
        self.handlers.insert(kind.into(), Arc::new(handler));
        self
    }

    /// The kinds this worker claims.
    pub fn kinds(&self) -> Vec<&str> {
        self.handlers.keys().map(String::as_str).collect()
    }

    /// Its configuration.
    pub fn config(&self) -> &WorkerConfig {
        &self.config
    }

    /// Claims and runs jobs until `shutdown` fires, then stops claiming, tells running handlers
    /// to checkpoint and stop (reason [`StopReason::Shutdown`]), waits up to the grace period,
    /// aborts what is left, and releases every unfinished job back to the queue.
    ///
    /// Database errors while claiming are logged and retried every poll interval: a worker
    /// outlives a database restart.
    pub async fn run(self, shutdown: CancellationToken) -> WorkerReport {
        let kinds: Vec<String> = self.handlers.keys().cloned().collect();
        let kinds: Vec<&str> = kinds.iter().map(String::as_str).collect();
        let permits = Arc::new(Semaphore::new(self.config.concurrency.max(1)));
        let running: Running = Arc::default();
        let mut tasks: JoinSet<Outcome> = JoinSet::new();
        let mut report = WorkerReport::default();
        tracing::info!(worker = %self.config.id, kinds = ?kinds, concurrency = self.config.concurrency, "worker started");

        loop {
            while let Some(done) = tasks.try_join_next() {
                count(&mut report, done);
            }
            let permit = tokio::select! {
                biased;
                () = shutdown.cancelled() => break,
                permit = permits.clone().acquire_owned() => match permit {
                    Ok(permit) => permit,
                    Err(_) => break,
                },
            };
            match self
                .queue
                .claim(&self.config.id, &kinds, self.config.lease)
                .await
            {
                Ok(Some(claimed)) if shutdown.is_cancelled() => {
                    // Shutdown began while the claim was in flight (it may even have picked up
                    // a job another handler just released): give it back unrun.
                    if let Err(e) = self.queue.release(&claimed.lease).await {
                        tracing::warn!(job = %claimed.job.id, error = %e, "releasing a job claimed during shutdown failed; its lease will expire");
                    }
                    break;
                }
                Ok(Some(claimed)) => {
                    report.claimed += 1;
                    let Some(handler) = self.handlers.get(&claimed.job.kind).cloned() else {
                        // Cannot happen: we claim only kinds we have handlers for.
                        let _ = self.queue.release(&claimed.lease).await;
                        continue;
                    };
                    tracing::info!(job = %claimed.job.id, kind = %claimed.job.kind, attempt = claimed.lease.attempt, "job claimed");
                    if let Ok(mut map) = running.lock() {
                        map.insert(claimed.job.id, claimed.lease.clone());
                    }
                    let queue = self.queue.clone();
                    let config = self.config.clone();
                    let shutdown = shutdown.clone();
                    let running = running.clone();
                    tasks.spawn(async move {
                        let id = claimed.job.id;
                        let outcome = run_job(queue, handler, claimed, config, shutdown).await;
                        if let Ok(mut map) = running.lock() {
                            map.remove(&id);
                        }
                        drop(permit);
                        outcome
                    });
                }
                Ok(None) => {
                    drop(permit);
                    self.idle(&shutdown, &mut tasks, &mut report).await;
                }
                Err(e) => {
                    drop(permit);
                    tracing::warn!(worker = %self.config.id, error = %e, "claiming a job failed; retrying");
                    self.idle(&shutdown, &mut tasks, &mut report).await;
                }
            }
        }

        tracing::info!(worker = %self.config.id, running = tasks.len(), "worker shutting down");
        let grace = tokio::time::sleep(self.config.shutdown_grace);
        tokio::pin!(grace);
        loop {
            tokio::select! {
                done = tasks.join_next() => match done {
                    Some(done) => count(&mut report, done),
                    None => break,
                },
                () = &mut grace => {
                    tracing::warn!(worker = %self.config.id, running = tasks.len(), "shutdown grace over; aborting handlers");
                    tasks.abort_all();
                    while let Some(done) = tasks.join_next().await {
                        count(&mut report, done);
                    }
                    break;
                }
            }
        }
        let leftover: Vec<Lease> = match running.lock() {
            Ok(mut map) => map.drain().map(|(_, lease)| lease).collect(),
            Err(_) => Vec::new(),
        };
        for lease in leftover {
            match self.queue.release(&lease).await {
                Ok(_) => report.released += 1,
                Err(e) => {
                    tracing::warn!(job = %lease.job_id, error = %e, "releasing an aborted job failed; its lease will expire")
                }
            }
        }
        tracing::info!(worker = %self.config.id, ?report, "worker stopped");
        report
    }

    async fn idle(
        &self,
        shutdown: &CancellationToken,
        tasks: &mut JoinSet<Outcome>,
        report: &mut WorkerReport,
    ) {
        let sleep = tokio::time::sleep(self.config.poll_interval);
        tokio::pin!(sleep);
        loop {
            tokio::select! {
                biased;
                () = shutdown.cancelled() => return,
                () = &mut sleep => return,
                Some(done) = tasks.join_next(), if !tasks.is_empty() => count(report, done),
            }
        }
    }
}

fn count(report: &mut WorkerReport, done: Result<Outcome, tokio::task::JoinError>) {
    match done {
        Ok(Outcome::Succeeded) => report.succeeded += 1,
        Ok(Outcome::Failed) => report.failed += 1,
        Ok(Outcome::Retried) => report.retried += 1,
        Ok(Outcome::Cancelled) => report.cancelled += 1,
        Ok(Outcome::Released) => report.released += 1,
        Ok(Outcome::Lost) => report.lost += 1,
        // Aborted after the grace period: released afterwards from the running map.
        Err(_) => {}
    }
}

async fn heartbeat_loop(
    queue: Queue,
    ctx: JobContext,
    config: WorkerConfig,
    shutdown: CancellationToken,
    done: CancellationToken,
) {
    let period = config.heartbeat.max(Duration::from_millis(10));
    let mut ticks = tokio::time::interval_at(tokio::time::Instant::now() + period, period);
    ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut shutdown_seen = false;
    // Past one lease period without a renewal another worker may own the job: stop it then,
    // even when the queue cannot say so (the database is unreachable).
    let mut renewed = tokio::time::Instant::now();
    loop {
        tokio::select! {
            biased;
            () = done.cancelled() => return,
            () = shutdown.cancelled(), if !shutdown_seen => {
                shutdown_seen = true;
                // Keep heartbeating: the handler may take a while to checkpoint.
                ctx.stop(StopReason::Shutdown);
            }
            _ = ticks.tick() => match queue.heartbeat(ctx.lease(), config.lease).await {
                Ok(ack) => {
                    renewed = tokio::time::Instant::now();
                    if ack.cancel_requested {
                        ctx.stop(StopReason::CancelRequested);
                    }
                }
                Err(QueueError::LeaseLost { .. }) => {
                    tracing::warn!(job = %ctx.id(), "lease lost; stopping the handler");
                    ctx.stop(StopReason::LeaseLost);
                    return;
                }
                Err(e) if renewed.elapsed() + period >= config.lease => {
                    tracing::warn!(job = %ctx.id(), error = %e, "the lease cannot be renewed within its period; stopping the handler");
                    ctx.stop(StopReason::LeaseLost);
                    return;
                }
                Err(e) => tracing::warn!(job = %ctx.id(), error = %e, "heartbeat failed; retrying"),
            },
        }
    }
}

async fn run_job(
    queue: Queue,
    handler: Arc<dyn ErasedHandler>,
    claimed: Claimed,
    config: WorkerConfig,
    shutdown: CancellationToken,
) -> Outcome {
    let ctx = JobContext::new(queue.clone(), claimed, config.lease);
    let lease = ctx.lease().clone();
    let done = CancellationToken::new();
    let heartbeat = tokio::spawn(heartbeat_loop(
        queue.clone(),
        ctx.clone(),
        config.clone(),
        shutdown,
        done.clone(),
    ));
    let _heartbeat_guard = AbortOnDrop(heartbeat.abort_handle());
    let handler_ctx = ctx.clone();
    let run = tokio::spawn(async move { handler.run_boxed(handler_ctx).await });
    let _run_guard = AbortOnDrop(run.abort_handle());
    let result = run.await;
    done.cancel();
    let _ = heartbeat.await;

    let reason = ctx.stop_reason();
    let job = lease.job_id;
    let outcome = match result {
        Ok(Ok(value)) => {
            record(&queue, &lease, |q, l| {
                let value = value.clone();
                async move { q.complete(&l, &value).await.map(|()| Outcome::Succeeded) }
            })
            .await
        }
        Ok(Err(JobError::Queue(QueueError::LeaseLost { .. }))) => Outcome::Lost,
        Ok(Err(_)) if reason == Some(StopReason::LeaseLost) => Outcome::Lost,
        Ok(Err(e @ JobError::OutOfSpace(_))) if reason.is_none() => {
            let message = format!("waiting for disk space: {e}");
            tracing::warn!(%job, error = %e, "the disk is full; the job goes back to the queue");
            record(&queue, &lease, |q, l| {
                let message = message.clone();
                async move {
                    q.defer(&l, &message).await.map(|state| match state {
                        JobState::Cancelled => Outcome::Cancelled,
                        _ => Outcome::Released,
                    })
                }
            })
            .await
        }
        Ok(Err(JobError::Fatal(message))) => fail(&queue, &lease, message, false).await,
        Ok(Err(_)) if reason == Some(StopReason::Shutdown) => {
            record(&queue, &lease, |q, l| async move {
                q.release(&l).await.map(|state| match state {
                    JobState::Cancelled => Outcome::Cancelled,
                    _ => Outcome::Released,
                })
            })
            .await
        }
        Ok(Err(_)) if reason == Some(StopReason::CancelRequested) => {
            record(&queue, &lease, |q, l| async move {
                q.mark_cancelled(&l).await.map(|()| Outcome::Cancelled)
            })
            .await
        }
        Ok(Err(JobError::Stopped(r))) => {
            let message = format!("handler stopped ({r}) without a stop request");
            fail(&queue, &lease, message, true).await
        }
        Ok(Err(e)) => fail(&queue, &lease, e.to_string(), true).await,
        Err(join) => {
            let message = if join.is_panic() {
                "the handler panicked".to_owned()
            } else {
                "the handler was aborted".to_owned()
            };
            fail(&queue, &lease, message, true).await
        }
    };
    tracing::info!(%job, attempt = lease.attempt, ?outcome, "job attempt ended");
    outcome
}

async fn fail(queue: &Queue, lease: &Lease, message: String, retryable: bool) -> Outcome {
    record(queue, lease, |q, l| {
        let message = message.clone();
        async move {
            q.fail(&l, &message, retryable)
                .await
                .map(|outcome| match outcome {
                    crate::jobs::FailOutcome::Retrying { .. } => Outcome::Retried,
                    crate::jobs::FailOutcome::Failed => Outcome::Failed,
                    crate::jobs::FailOutcome::Cancelled => Outcome::Cancelled,
                })
        }
    })
    .await
}

/// Writes an outcome, retrying database errors a few times; a lost lease is final.
async fn record<F, Fut>(queue: &Queue, lease: &Lease, write: F) -> Outcome
where
    F: Fn(Queue, Lease) -> Fut,
    Fut: Future<Output = Result<Outcome, QueueError>>,
{
    let mut delay = Duration::from_millis(100);
    for attempt in 1..=5 {
        match write(queue.clone(), lease.clone()).await {
            Ok(outcome) => return outcome,
            Err(QueueError::LeaseLost { .. }) => return Outcome::Lost,
            Err(e) => {
                tracing::warn!(job = %lease.job_id, attempt, error = %e, "recording the outcome failed");
                tokio::time::sleep(delay).await;
                delay *= 2;
            }
        }
    }
    // The lease will expire and another worker will take the job over.
    Outcome::Lost
}
