//! The queue throughput benchmark (`bench::queue`), checked rather than timed:
//! the figures come from `mentalsim bench queue`, which runs the same `bench::queue::run`
//! with thousands of jobs. Here a few hundred jobs go through it on SQLite and PostgreSQL, and
//! the test asserts what the figures rest on: every job enqueued was claimed and completed
//! exactly once, by one attempt, and the reported rates are positive and finite.

#![allow(clippy::unwrap_used)] // reason: tests panic on failure

use bench::queue::{BenchOptions, ThroughputReport, queue_throughput, run};
use fixtures::job_database::FreshDatabase;
use queue::{JobDatabase, JobState, Queue};

const JOBS: usize = 240;
const CONCURRENCY: usize = 4;

fn assert_sound(report: &ThroughputReport) {
    assert_eq!(report.jobs, JOBS, "{report}");
    assert_eq!(report.concurrency, CONCURRENCY, "{report}");
    for rate in [report.enqueued_per_s, report.completed_per_s] {
        assert!(rate.is_finite() && rate > 0.0, "{report}");
    }
    assert!(report.enqueue_s > 0.0 && report.drain_s > 0.0, "{report}");
}

/// After a run on a fresh database: every job succeeded, on its first attempt, with one
/// `succeeded` event; nothing else is in the queue.
async fn assert_each_job_ran_once(queue: &Queue) {
    let stats = queue.stats().await.unwrap();
    assert_eq!(
        stats.into_iter().collect::<Vec<_>>(),
        [(JobState::Succeeded, JOBS as u64)]
    );
    let jobs = queue.list(None, 10_000).await.unwrap();
    assert_eq!(jobs.len(), JOBS);
    for job in &jobs {
        assert_eq!(job.attempt, 1, "{job:?}");
        assert_eq!(job.result, Some(serde_json::json!({"ok": true})), "{job:?}");
        let events = queue.events(job.id, 0, 100).await.unwrap();
        let states: Vec<&str> = events
            .iter()
            .filter(|e| e.kind == "state")
            .filter_map(|e| e.data["state"].as_str())
            .collect();
        assert_eq!(states, ["queued", "running", "succeeded"], "{}", job.id);
    }
}

async fn each_job_is_claimed_and_completed_once(fresh: FreshDatabase) {
    let queue = Queue::new(JobDatabase::connect(&fresh.url).await.unwrap());
    let report = queue_throughput(&queue, JOBS, CONCURRENCY).await.unwrap();
    assert_sound(&report);
    assert_each_job_ran_once(&queue).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sqlite_each_job_is_claimed_and_completed_once() {
    each_job_is_claimed_and_completed_once(fixtures::job_database::sqlite()).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn postgres_each_job_is_claimed_and_completed_once() {
    let Some(fresh) = fixtures::job_database::postgres().await else {
        return;
    };
    each_job_is_claimed_and_completed_once(fresh).await;
}

/// What `mentalsim bench queue` runs: a fresh SQLite file and a temporary durable PostgreSQL
/// cluster, one report each.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_benchmark_reports_both_backends() {
    let options = BenchOptions {
        jobs: JOBS,
        concurrency: CONCURRENCY,
        postgres_url: None,
    };
    let reports = run(&options).await.unwrap();
    assert_eq!(reports[0].backend, "sqlite");
    for report in &reports {
        assert_sound(report);
    }
    if reports.len() < 2 {
        fixtures::missing("PostgreSQL for the queue benchmark (scripts/setup installs it)");
        return;
    }
    assert_eq!(reports.len(), 2);
    assert_eq!(reports[1].backend, "postgres");
}
