//! The queue throughput benchmark: jobs enqueued per second, and jobs claimed and completed
//! per second, by `concurrency` tasks, on SQLite and PostgreSQL. Each enqueue and each outcome
//! is its own durable commit (SQLite `synchronous=FULL`; PostgreSQL `fsync=on`), as in service.

use std::fmt;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use serde::Serialize;
use serde_json::json;

use fixtures::{Durability, TempPostgres, TempPostgresError};
use queue::{Backend, JobDatabase, PoolSize};
use queue::{NewJob, Queue, QueueError};

/// One backend's figures.
#[derive(Debug, Clone, Serialize)]
pub struct ThroughputReport {
    /// `sqlite` or `postgres`.
    pub backend: String,
    /// Jobs enqueued and drained.
    pub jobs: usize,
    /// Concurrent enqueuers, then concurrent workers.
    pub concurrency: usize,
    /// Wall time of the enqueue phase.
    pub enqueue_s: f64,
    /// Wall time of the drain phase (claim + complete every job).
    pub drain_s: f64,
    /// Jobs enqueued per second.
    pub enqueued_per_s: f64,
    /// Jobs claimed and completed per second.
    pub completed_per_s: f64,
}

impl fmt::Display for ThroughputReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:<8} {:>6} jobs x{:<2} enqueue {:>8.0} jobs/s ({:.2} s)   claim+complete {:>8.0} jobs/s ({:.2} s)",
            self.backend,
            self.jobs,
            self.concurrency,
            self.enqueued_per_s,
            self.enqueue_s,
            self.completed_per_s,
            self.drain_s
        )
    }
}

/// What to run.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    /// Jobs per backend.
    pub jobs: usize,
    /// Concurrent tasks (enqueuers, then workers).
    pub concurrency: usize,
    /// A PostgreSQL database to use; `None` starts a temporary durable cluster if PostgreSQL
    /// is installed, and skips PostgreSQL otherwise.
    pub postgres_url: Option<String>,
}

impl Default for BenchOptions {
    fn default() -> Self {
        Self {
            jobs: 2000,
            concurrency: 4,
            postgres_url: None,
        }
    }
}

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A queue operation failed.
    #[error(transparent)]
    Queue(#[from] QueueError),
    /// Setting up a database failed.
    #[error("{0}")]
    Setup(String),
}

/// Enqueues `jobs` jobs with `concurrency` tasks, then drains them with `concurrency` tasks
/// that claim and complete, on `queue`. Uses a kind of its own, so other jobs are untouched.
pub async fn queue_throughput(
    queue: &Queue,
    jobs: usize,
    concurrency: usize,
) -> Result<ThroughputReport, BenchError> {
    let concurrency = concurrency.max(1);
    let kind = format!("bench-{}", uuid::Uuid::new_v4().simple());
    let started = Instant::now();
    let mut tasks = tokio::task::JoinSet::new();
    for t in 0..concurrency {
        let queue = queue.clone();
        let kind = kind.clone();
        let n = jobs / concurrency + usize::from(t < jobs % concurrency);
        tasks.spawn(async move {
            for i in 0..n {
                queue
                    .enqueue(NewJob::new(kind.as_str(), json!({"task": t, "i": i})))
                    .await?;
            }
            Ok::<usize, QueueError>(n)
        });
    }
    join_all(&mut tasks).await?;
    let enqueue_s = started.elapsed().as_secs_f64();

    let started = Instant::now();
    for t in 0..concurrency {
        let queue = queue.clone();
        let kind = kind.clone();
        tasks.spawn(async move {
            let owner = format!("bench-worker-{t}");
            let mut done = 0;
            while let Some(claimed) = queue
                .claim(&owner, &[kind.as_str()], Duration::from_secs(60))
                .await?
            {
                queue.complete(&claimed.lease, &json!({"ok": true})).await?;
                done += 1;
            }
            Ok(done)
        });
    }
    let drained = join_all(&mut tasks).await?;
    let drain_s = started.elapsed().as_secs_f64();
    if drained != jobs {
        return Err(BenchError::Setup(format!(
            "drained {drained} jobs, expected {jobs}"
        )));
    }
    let backend = match queue.database().backend() {
        Backend::Sqlite => "sqlite",
        Backend::Postgres => "postgres",
    };
    Ok(ThroughputReport {
        backend: backend.to_owned(),
        jobs,
        concurrency,
        enqueue_s,
        drain_s,
        enqueued_per_s: jobs as f64 / enqueue_s.max(1e-9),
        completed_per_s: jobs as f64 / drain_s.max(1e-9),
    })
}

async fn join_all(
    tasks: &mut tokio::task::JoinSet<Result<usize, QueueError>>,
) -> Result<usize, BenchError> {
    let mut total = 0;
    while let Some(done) = tasks.join_next().await {
        total += done.map_err(|e| BenchError::Setup(format!("benchmark task: {e}")))??;
    }
    Ok(total)
}

/// Runs the benchmark on a fresh SQLite file and on PostgreSQL (see [`BenchOptions`]); prints
/// nothing, returns one report per backend run.
pub async fn run(options: &BenchOptions) -> Result<Vec<ThroughputReport>, BenchError> {
    let mut reports = Vec::new();
    let pool = PoolSize(u32::try_from(options.concurrency + 2).unwrap_or(u32::MAX));

    let dir = std::env::temp_dir().join(format!(
        "mentalsim-queue-bench-{}",
        uuid::Uuid::new_v4().simple()
    ));
    std::fs::create_dir_all(&dir).map_err(|e| BenchError::Setup(e.to_string()))?;
    let sqlite = async {
        let url = format!("sqlite://{}", dir.join("jobs.sqlite").display());
        let db = JobDatabase::connect_with(&url, pool)
            .await
            .map_err(QueueError::from)?;
        let report =
            queue_throughput(&Queue::new(db.clone()), options.jobs, options.concurrency).await;
        db.close().await;
        report
    }
    .await;
    remove_dir(dir);
    reports.push(sqlite?);

    let mut cluster = None;
    let url = match &options.postgres_url {
        Some(url) => Some(url.clone()),
        None => {
            match tokio::task::spawn_blocking(|| TempPostgres::start(Durability::Durable))
                .await
                .map_err(|e| BenchError::Setup(e.to_string()))?
            {
                Ok(pg) => {
                    let url = pg
                        .create_database("bench")
                        .await
                        .map_err(|e| BenchError::Setup(e.to_string()))?;
                    cluster = Some(pg);
                    Some(url)
                }
                Err(TempPostgresError::NotInstalled) => None,
                Err(e) => return Err(BenchError::Setup(e.to_string())),
            }
        }
    };
    if let Some(url) = url {
        let db = JobDatabase::connect_with(&url, pool)
            .await
            .map_err(QueueError::from)?;
        let report =
            queue_throughput(&Queue::new(db.clone()), options.jobs, options.concurrency).await;
        db.close().await;
        reports.push(report?);
    }
    if let Some(pg) = cluster {
        let _ = tokio::task::spawn_blocking(move || pg.stop()).await;
    }
    Ok(reports)
}

fn remove_dir(dir: PathBuf) {
    let _ = std::fs::remove_dir_all(dir);
}
