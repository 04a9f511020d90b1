//! Crash tests with real processes. This test binary re-executes itself (`crash_child`, run
//! only when `WORKER_CRASH_CHILD_URL` is set) as a worker process running a synthetic
//! checkpointing job: it sums 1..=target one step at a time, checkpointing `(i, sum)` every
//! five steps. The tests SIGKILL (or SIGTERM) that process mid-job, start another one, and check
//! that the job finishes with the right sum, resumed from the last checkpoint rather than from
//! zero. On SQLite and on PostgreSQL.

#![allow(clippy::unwrap_used)] // reason: tests panic on failure

use std::process::{Child, Command, Stdio};
use std::time::Duration;

use fixtures::job_database::FreshDatabase;
use queue::{
    Checkpoint, JobContext, JobDatabase, JobState, NewJob, Queue, Worker, WorkerConfig, handler_fn,
};
use serde_json::json;
use tokio_util::sync::CancellationToken;
use uuid::Uuid;

const TARGET: i64 = 80;

fixtures::on_both_backends!(
    crate::crash::fresh_sqlite,
    fixtures::job_database::postgres,
    [
        sigkill_mid_job_resumes_from_the_last_checkpoint,
        sigterm_releases_the_job_to_the_next_process,
    ]
);

/// A fresh SQLite job database, as the backends' setups are: async, and `None` never.
async fn fresh_sqlite() -> Option<FreshDatabase> {
    Some(fixtures::job_database::sqlite())
}

/// The worker process: runs until the job is finished or SIGTERM arrives.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "the worker process of the crash tests; runs only when they start it"]
async fn crash_child() {
    let Ok(url) = std::env::var("WORKER_CRASH_CHILD_URL") else {
        return;
    };
    let job: Uuid = std::env::var("WORKER_CRASH_CHILD_JOB")
        .unwrap()
        .parse()
        .unwrap();
    let queue = Queue::new(JobDatabase::connect(&url).await.unwrap());
    let shutdown = CancellationToken::new();
    let on_term = shutdown.clone();
    let mut term =
        tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()).unwrap();
    tokio::spawn(async move {
        term.recv().await;
        on_term.cancel();
    });
    let when_done = shutdown.clone();
    let watch = queue.clone();
    tokio::spawn(async move {
        loop {
            let state = watch.get(job).await.unwrap().unwrap().state;
            if state.is_finished() {
                when_done.cancel();
                return;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    });
    let config = WorkerConfig {
        id: format!("child-{}", std::process::id()),
        concurrency: 1,
        // Long: the parent expires the lease of a killed child explicitly.
        lease: Duration::from_secs(120),
        heartbeat: Duration::from_millis(200),
        poll_interval: Duration::from_millis(20),
        shutdown_grace: Duration::from_secs(20),
    };
    let worker = Worker::new(queue, config).register(
        "sum",
        handler_fn(|ctx: JobContext| async move {
            let target = ctx.payload()["target"].as_i64().unwrap();
            let step = Duration::from_millis(ctx.payload()["step_ms"].as_u64().unwrap());
            let (mut i, mut sum) = ctx.checkpoint().map_or((0, 0), |c| {
                (
                    c.data["i"].as_i64().unwrap(),
                    c.data["sum"].as_i64().unwrap(),
                )
            });
            let resumed_from = i;
            while i < target {
                if ctx.is_stopping() {
                    ctx.save_checkpoint(&Checkpoint::new(json!({"i": i, "sum": sum})))
                        .await?;
                    return Err(ctx.stopped());
                }
                tokio::time::sleep(step).await;
                i += 1;
                sum += i;
                ctx.report_progress(&json!({"i": i})).await?;
                if i % 5 == 0 {
                    ctx.save_checkpoint(&Checkpoint::new(json!({"i": i, "sum": sum})))
                        .await?;
                }
            }
            Ok(json!({"i": i, "sum": sum, "resumed_from": resumed_from, "pid": std::process::id()}))
        }),
    );
    let report = worker.run(shutdown).await;
    println!("child report: {report:?}");
}

fn spawn_child(url: &str, job: Uuid) -> Child {
    Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "crash::crash_child",
            "--ignored",
            "--nocapture",
            "--test-threads=1",
        ])
        .env("WORKER_CRASH_CHILD_URL", url)
        .env("WORKER_CRASH_CHILD_JOB", job.to_string())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .spawn()
        .unwrap()
}

async fn wait_for<F>(queue: &Queue, id: Uuid, what: &str, child: &mut Child, mut check: F)
where
    F: FnMut(&queue::Job) -> bool,
{
    let deadline = tokio::time::Instant::now() + Duration::from_secs(90);
    loop {
        let job = queue.get(id).await.unwrap().unwrap();
        if check(&job) {
            return;
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("worker process exited ({status}) before {what}: {job:?}");
        }
        assert!(tokio::time::Instant::now() < deadline, "timed out: {what}");
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

fn checkpoint_i(job: &queue::Job) -> i64 {
    job.checkpoint
        .as_ref()
        .map_or(0, |c| c.data["i"].as_i64().unwrap())
}

async fn enqueue(url: &str) -> (Queue, Uuid) {
    let queue = Queue::new(JobDatabase::connect(url).await.unwrap());
    let id = queue
        .enqueue(NewJob::new("sum", json!({"target": TARGET, "step_ms": 25})))
        .await
        .unwrap();
    (queue, id)
}

async fn finish_in_a_new_process(queue: &Queue, url: &str, id: Uuid) -> queue::Job {
    let mut second = spawn_child(url, id);
    wait_for(queue, id, "the job finished", &mut second, |j| {
        j.state.is_finished()
    })
    .await;
    assert!(second.wait().unwrap().success());
    queue.get(id).await.unwrap().unwrap()
}

async fn sigkill_mid_job_resumes_from_the_last_checkpoint(fresh: FreshDatabase) {
    let url = fresh.url.as_str();
    let (queue, id) = enqueue(url).await;
    let mut first = spawn_child(url, id);
    wait_for(&queue, id, "a checkpoint at step 20", &mut first, |j| {
        checkpoint_i(j) >= 20
    })
    .await;
    first.kill().unwrap(); // SIGKILL: no cleanup of any kind
    first.wait().unwrap();

    let job = queue.get(id).await.unwrap().unwrap();
    assert_eq!(
        job.state,
        JobState::Running,
        "the dead worker still holds the lease"
    );
    let checkpoint = checkpoint_i(&job);
    assert!((20..TARGET).contains(&checkpoint), "{job:?}");
    let progress = job.progress.as_ref().unwrap()["i"].as_i64().unwrap();
    assert!(progress >= checkpoint);
    // Its lease is still valid: nobody can take the job yet...
    assert!(
        queue
            .claim("probe", &["sum"], Duration::from_secs(1))
            .await
            .unwrap()
            .is_none()
    );
    // ...until it expires (here at once, as an operator would).
    assert!(queue.expire_lease(id).await.unwrap());

    let job = finish_in_a_new_process(&queue, url, id).await;
    assert_eq!(job.state, JobState::Succeeded, "{job:?}");
    assert_eq!(job.attempt, 2, "the killed run counts as an attempt");
    let result = job.result.unwrap();
    assert_eq!(result["sum"], TARGET * (TARGET + 1) / 2);
    assert_eq!(result["i"], TARGET);
    assert_eq!(
        result["resumed_from"], checkpoint,
        "resumed from the last checkpoint"
    );
    assert_ne!(result["pid"], first.id());
}

async fn sigterm_releases_the_job_to_the_next_process(fresh: FreshDatabase) {
    let url = fresh.url.as_str();
    let (queue, id) = enqueue(url).await;
    let mut first = spawn_child(url, id);
    wait_for(&queue, id, "progress past step 12", &mut first, |j| {
        j.progress
            .as_ref()
            .is_some_and(|p| p["i"].as_i64() >= Some(12))
    })
    .await;
    let status = Command::new("kill")
        .args(["-TERM", &first.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    assert!(first.wait().unwrap().success(), "graceful exit");

    let job = queue.get(id).await.unwrap().unwrap();
    assert_eq!(job.state, JobState::Queued, "released, not failed: {job:?}");
    assert_eq!(job.attempt, 0, "a graceful release gives the attempt back");
    let checkpoint = checkpoint_i(&job);
    // The handler checkpointed where it stopped, not only at the last multiple of 5.
    assert_eq!(
        checkpoint,
        job.progress.as_ref().unwrap()["i"].as_i64().unwrap()
    );
    assert!(checkpoint >= 12);

    let job = finish_in_a_new_process(&queue, url, id).await;
    assert_eq!((job.state, job.attempt), (JobState::Succeeded, 1));
    let result = job.result.unwrap();
    assert_eq!(result["sum"], TARGET * (TARGET + 1) / 2);
    assert_eq!(result["resumed_from"], checkpoint);
}
