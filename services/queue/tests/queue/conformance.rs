//! The queue conformance suite: every case runs against SQLite and against PostgreSQL (a
//! temporary cluster), through the same public API, and must behave the same.

#![allow(clippy::unwrap_used)] // reason: tests panic on failure

use std::collections::HashMap;
use std::future::Future;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::common::{Fixture, START_MS};
use queue::{
    Backoff, Checkpoint, FailOutcome, JobContext, JobError, JobState, NewJob, Queue, QueueError,
    StopReason, Worker, WorkerConfig, handler_fn,
};
use serde_json::{Value, json};
use tokio_util::sync::CancellationToken;
use uuid::Uuid;

const LEASE: Duration = Duration::from_secs(30);

/// Where each handler run stopped, and why.
type Seen = Arc<Mutex<Vec<(Option<StopReason>, i64)>>>;

fixtures::on_both_backends!(
    crate::common::sqlite,
    crate::common::postgres,
    [
        schema_is_migrated,
        enqueue_claim_complete,
        claim_order_and_delay,
        stale_lease_writes_are_rejected,
        expired_lease_is_reclaimed_as_an_attempt,
        retries_back_off_exponentially_up_to_the_cap,
        cancellation,
        release_gives_the_attempt_back_and_keeps_the_checkpoint,
        a_deferred_job_waits_the_first_backoff_without_using_an_attempt,
        retention_deletes_old_finished_jobs_and_their_events,
        events_are_ordered_and_resumable,
        concurrent_claims_take_each_job_once,
        workers_run_every_job_exactly_once,
        runner_records_outcomes,
        runner_cancel_request_stops_the_handler,
        runner_shutdown_releases_and_another_worker_resumes,
        runner_stops_a_handler_whose_lease_was_taken,
        a_handler_that_lost_its_lease_cannot_install_files,
    ]
);

fn is_lease_lost<T: std::fmt::Debug>(r: Result<T, QueueError>) -> bool {
    matches!(r, Err(QueueError::LeaseLost { .. }))
}

async fn schema_is_migrated(f: Fixture) {
    let status = f.db.status().await.unwrap();
    assert_eq!(status.applied_migrations, status.expected_migrations);
    assert!(f.queue.stats().await.unwrap().is_empty());
}

async fn enqueue_claim_complete(f: Fixture) {
    let q = &f.queue;
    let payload = json!({"episodes": 10, "map": "floor-1", "nested": {"x": [1.5, "y", null]}});
    let id = q
        .enqueue(NewJob::new("train", payload.clone()).max_attempts(5))
        .await
        .unwrap();
    assert_eq!(id.get_version_num(), 7);
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!(job.state, JobState::Queued);
    assert_eq!((job.attempt, job.max_attempts), (0, 5));
    assert_eq!(job.payload, payload);
    assert_eq!(job.created_ms, START_MS);

    assert!(q.claim("w1", &["evaluate"], LEASE).await.unwrap().is_none());
    assert!(q.claim("w1", &[], LEASE).await.unwrap().is_none());
    let claimed = q
        .claim("w1", &["evaluate", "train"], LEASE)
        .await
        .unwrap()
        .unwrap();
    assert_eq!(claimed.job.id, id);
    assert_eq!(claimed.job.state, JobState::Running);
    assert_eq!(claimed.lease.attempt, 1);
    assert_eq!(claimed.lease.owner, "w1");
    assert_eq!(claimed.job.lease_owner.as_deref(), Some("w1"));
    assert_eq!(
        claimed.job.lease_expires_ms,
        Some(START_MS + LEASE.as_millis() as i64)
    );
    assert_eq!(claimed.job.started_ms, Some(START_MS));
    assert!(q.claim("w2", &["train"], LEASE).await.unwrap().is_none());

    f.clock.advance(Duration::from_secs(2));
    q.complete(&claimed.lease, &json!({"success_rate": 0.9}))
        .await
        .unwrap();
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!(job.state, JobState::Succeeded);
    assert_eq!(job.result, Some(json!({"success_rate": 0.9})));
    assert_eq!(job.finished_ms, Some(START_MS + 2000));
    assert_eq!(job.lease_owner, None);
    assert_eq!(job.lease_expires_ms, None);
    assert!(q.claim("w2", &["train"], LEASE).await.unwrap().is_none());
    // Finished is final: the old lease cannot write any more.
    assert!(is_lease_lost(q.complete(&claimed.lease, &json!(1)).await));
    let stats = q.stats().await.unwrap();
    assert_eq!(stats.get(&JobState::Succeeded), Some(&1));

    assert!(matches!(
        q.enqueue(NewJob::new("train", json!({})).max_attempts(0))
            .await,
        Err(QueueError::Invalid(_))
    ));
    assert!(matches!(
        q.enqueue(NewJob::new("", json!({}))).await,
        Err(QueueError::Invalid(_))
    ));
    let listed = q.list(Some(JobState::Succeeded), 10).await.unwrap();
    assert_eq!(listed.len(), 1);
    assert_eq!(listed[0].id, id);
    assert!(q.get(Uuid::now_v7()).await.unwrap().is_none());
}

async fn claim_order_and_delay(f: Fixture) {
    let q = &f.queue;
    let low = q.enqueue(NewJob::new("k", json!(1))).await.unwrap();
    let later = q
        .enqueue(
            NewJob::new("k", json!(2))
                .priority(5)
                .delay(Duration::from_secs(60)),
        )
        .await
        .unwrap();
    let high = q
        .enqueue(NewJob::new("k", json!(3)).priority(5))
        .await
        .unwrap();
    let low2 = q.enqueue(NewJob::new("k", json!(4))).await.unwrap();
    let mut order = Vec::new();
    while let Some(c) = q.claim("w", &["k"], LEASE).await.unwrap() {
        order.push(c.job.id);
        q.complete(&c.lease, &json!(null)).await.unwrap();
    }
    // Priority first, then age; the delayed job is not claimable yet.
    assert_eq!(order, [high, low, low2]);
    f.clock.advance(Duration::from_millis(59_999));
    assert!(q.claim("w", &["k"], LEASE).await.unwrap().is_none());
    f.clock.advance(Duration::from_millis(1));
    let c = q.claim("w", &["k"], LEASE).await.unwrap().unwrap();
    assert_eq!(c.job.id, later);
}

async fn stale_lease_writes_are_rejected(f: Fixture) {
    let q = &f.queue;
    let id = q.enqueue(NewJob::new("train", json!({}))).await.unwrap();
    let old = q
        .claim("w1", &["train"], LEASE)
        .await
        .unwrap()
        .unwrap()
        .lease;
    q.report_progress(&old, &json!({"step": 1})).await.unwrap();
    f.clock.advance(LEASE + Duration::from_millis(1));
    let new = q.claim("w2", &["train"], LEASE).await.unwrap().unwrap();
    assert_eq!(new.job.id, id);
    assert_eq!(new.lease.attempt, 2);
    assert!(new.lease.token > old.token);
    // The new owner sees the old owner's last progress, and writes its own.
    assert_eq!(new.job.progress, Some(json!({"step": 1})));
    q.report_progress(&new.lease, &json!({"step": 7}))
        .await
        .unwrap();
    q.save_checkpoint(&new.lease, &Checkpoint::new(json!({"step": 5})))
        .await
        .unwrap();

    // Every write under the old lease is rejected with a typed error, and changes nothing.
    assert!(is_lease_lost(q.heartbeat(&old, LEASE).await));
    assert!(is_lease_lost(
        q.report_progress(&old, &json!({"step": 99})).await
    ));
    assert!(is_lease_lost(
        q.save_checkpoint(&old, &Checkpoint::new(json!({"step": 99})))
            .await
    ));
    assert!(is_lease_lost(q.complete(&old, &json!("stale")).await));
    assert!(is_lease_lost(q.fail(&old, "stale", true).await));
    assert!(is_lease_lost(q.fail(&old, "stale", false).await));
    assert!(is_lease_lost(q.release(&old).await));
    assert!(is_lease_lost(q.mark_cancelled(&old).await));
    let err = q.complete(&old, &json!(0)).await.unwrap_err();
    assert!(err.to_string().contains(&id.to_string()), "{err}");

    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!(job.state, JobState::Running);
    assert_eq!(job.lease_owner.as_deref(), Some("w2"));
    assert_eq!(job.progress, Some(json!({"step": 7})));
    assert_eq!(job.checkpoint.unwrap().data, json!({"step": 5}));
    assert_eq!(job.result, None);
    let events = q.events(id, 0, 100).await.unwrap();
    assert!(
        events.iter().all(|e| !e.data.to_string().contains("99")),
        "{events:?}"
    );
    q.complete(&new.lease, &json!("done")).await.unwrap();
}

async fn expired_lease_is_reclaimed_as_an_attempt(f: Fixture) {
    let q = &f.queue;
    let id = q
        .enqueue(NewJob::new("train", json!({})).max_attempts(2))
        .await
        .unwrap();
    let first = q.claim("w1", &["train"], LEASE).await.unwrap().unwrap();
    f.clock.advance(Duration::from_secs(20));
    assert!(q.claim("w2", &["train"], LEASE).await.unwrap().is_none());
    // A heartbeat pushes the expiry to now + lease.
    let ack = q.heartbeat(&first.lease, LEASE).await.unwrap();
    assert!(!ack.cancel_requested);
    f.clock.advance(Duration::from_secs(25));
    assert!(q.claim("w2", &["train"], LEASE).await.unwrap().is_none());
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!(job.heartbeat_ms, Some(START_MS + 20_000));
    f.clock.advance(Duration::from_millis(5_001));
    let second = q.claim("w2", &["train"], LEASE).await.unwrap().unwrap();
    assert_eq!(
        (second.lease.attempt, second.lease.owner.as_str()),
        (2, "w2")
    );

    // The last attempt's lease expires too: the job fails instead of running a third time.
    f.clock.advance(LEASE + Duration::from_millis(1));
    assert!(q.claim("w3", &["train"], LEASE).await.unwrap().is_none());
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!(job.state, JobState::Failed);
    assert_eq!(job.attempt, 2);
    assert!(job.last_error.unwrap().contains("lease expired"));
    assert!(job.finished_ms.is_some());
    assert!(is_lease_lost(q.complete(&second.lease, &json!(1)).await));

    // An operator can expire a lease at once.
    let id = q.enqueue(NewJob::new("train", json!({}))).await.unwrap();
    q.claim("w1", &["train"], LEASE).await.unwrap().unwrap();
    assert!(q.claim("w2", &["train"], LEASE).await.unwrap().is_none());
    assert!(q.expire_lease(id).await.unwrap());
    let taken = q.claim("w2", &["train"], LEASE).await.unwrap().unwrap();
    assert_eq!((taken.job.id, taken.lease.attempt), (id, 2));
    assert!(!q.expire_lease(Uuid::now_v7()).await.unwrap());
}

async fn retries_back_off_exponentially_up_to_the_cap(f: Fixture) {
    let q = f.queue.clone().with_backoff(Backoff {
        base: Duration::from_secs(10),
        cap: Duration::from_secs(25),
    });
    let id = q
        .enqueue(NewJob::new("k", json!({})).max_attempts(4))
        .await
        .unwrap();
    let mut now = START_MS;
    for (attempt, delay_s) in [(1, 10), (2, 20), (3, 25)] {
        let c = q.claim("w", &["k"], LEASE).await.unwrap().unwrap();
        assert_eq!(c.lease.attempt, attempt);
        let outcome = q
            .fail(&c.lease, &format!("boom {attempt}"), true)
            .await
            .unwrap();
        let due = now + delay_s * 1000;
        assert_eq!(outcome, FailOutcome::Retrying { run_after_ms: due });
        let job = q.get(id).await.unwrap().unwrap();
        assert_eq!(job.state, JobState::Queued);
        assert_eq!(job.run_after_ms, due);
        assert_eq!(
            job.last_error.as_deref(),
            Some(format!("boom {attempt}").as_str())
        );
        assert_eq!(job.finished_ms, None);
        f.clock.set(due - 1);
        assert!(q.claim("w", &["k"], LEASE).await.unwrap().is_none());
        f.clock.set(due);
        now = due;
    }
    let c = q.claim("w", &["k"], LEASE).await.unwrap().unwrap();
    assert_eq!(c.lease.attempt, 4);
    assert_eq!(
        q.fail(&c.lease, "boom 4", true).await.unwrap(),
        FailOutcome::Failed
    );
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!((job.state, job.attempt), (JobState::Failed, 4));
    assert_eq!(job.finished_ms, Some(now));

    // A fatal error fails at once, attempts left or not.
    let id = q
        .enqueue(NewJob::new("k", json!({})).max_attempts(9))
        .await
        .unwrap();
    let c = q.claim("w", &["k"], LEASE).await.unwrap().unwrap();
    assert_eq!(
        q.fail(&c.lease, "bad payload", false).await.unwrap(),
        FailOutcome::Failed
    );
    assert_eq!(q.get(id).await.unwrap().unwrap().state, JobState::Failed);
}

async fn cancellation(f: Fixture) {
    let q = &f.queue;
    // Queued: cancelled at once, never claimed.
    let queued = q.enqueue(NewJob::new("k", json!({}))).await.unwrap();
    assert_eq!(q.request_cancel(queued).await.unwrap(), JobState::Cancelled);
    assert!(q.claim("w", &["k"], LEASE).await.unwrap().is_none());
    let job = q.get(queued).await.unwrap().unwrap();
    assert!(job.cancel_requested && job.finished_ms.is_some());

    // Running: flagged; the worker learns it from its next write and acknowledges.
    let running = q.enqueue(NewJob::new("k", json!({}))).await.unwrap();
    let c = q.claim("w", &["k"], LEASE).await.unwrap().unwrap();
    assert!(!q.heartbeat(&c.lease, LEASE).await.unwrap().cancel_requested);
    assert_eq!(q.request_cancel(running).await.unwrap(), JobState::Running);
    assert!(q.heartbeat(&c.lease, LEASE).await.unwrap().cancel_requested);
    let (ack, _) = q
        .report_progress(&c.lease, &json!({"step": 3}))
        .await
        .unwrap();
    assert!(ack.cancel_requested);
    q.mark_cancelled(&c.lease).await.unwrap();
    assert_eq!(
        q.get(running).await.unwrap().unwrap().state,
        JobState::Cancelled
    );

    // Finished jobs stay as they are; unknown ids are an error.
    assert_eq!(q.request_cancel(queued).await.unwrap(), JobState::Cancelled);
    let done = q.enqueue(NewJob::new("k", json!({}))).await.unwrap();
    let c = q.claim("w", &["k"], LEASE).await.unwrap().unwrap();
    q.complete(&c.lease, &json!(1)).await.unwrap();
    assert_eq!(q.request_cancel(done).await.unwrap(), JobState::Succeeded);
    assert!(matches!(
        q.request_cancel(Uuid::now_v7()).await,
        Err(QueueError::NotFound(_))
    ));

    // A cancel requested while running wins over a retry, a release and an expired lease.
    for how in ["fail", "release", "expire"] {
        let id = q.enqueue(NewJob::new("k", json!({}))).await.unwrap();
        let c = q.claim("w", &["k"], LEASE).await.unwrap().unwrap();
        q.request_cancel(id).await.unwrap();
        match how {
            "fail" => assert_eq!(
                q.fail(&c.lease, "x", true).await.unwrap(),
                FailOutcome::Cancelled
            ),
            "release" => assert_eq!(q.release(&c.lease).await.unwrap(), JobState::Cancelled),
            _ => {
                f.clock.advance(LEASE + Duration::from_millis(1));
                assert!(q.claim("w2", &["k"], LEASE).await.unwrap().is_none());
            }
        }
        assert_eq!(
            q.get(id).await.unwrap().unwrap().state,
            JobState::Cancelled,
            "{how}"
        );
    }
}

async fn release_gives_the_attempt_back_and_keeps_the_checkpoint(f: Fixture) {
    let q = &f.queue;
    let id = q
        .enqueue(NewJob::new("train", json!({})).max_attempts(1))
        .await
        .unwrap();
    let c = q.claim("w1", &["train"], LEASE).await.unwrap().unwrap();
    let blob: Vec<u8> = (0..=255).collect();
    q.save_checkpoint(
        &c.lease,
        &Checkpoint {
            data: json!({"path": "ckpt/step-40.pt", "step": 40}),
            blob: Some(blob.clone()),
        },
    )
    .await
    .unwrap();
    assert_eq!(q.release(&c.lease).await.unwrap(), JobState::Queued);
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!((job.state, job.attempt), (JobState::Queued, 0));
    assert_eq!(job.lease_owner, None);
    // Claimable at once, by anyone; still within its single attempt.
    let again = q.claim("w2", &["train"], LEASE).await.unwrap().unwrap();
    assert_eq!(again.lease.attempt, 1);
    assert!(again.lease.token > c.lease.token);
    let checkpoint = again.job.checkpoint.unwrap();
    assert_eq!(checkpoint.data["step"], 40);
    assert_eq!(checkpoint.blob, Some(blob));
    assert_eq!(again.job.checkpoint_ms, Some(START_MS));
    // A checkpoint without bytes replaces the bytes too.
    q.save_checkpoint(&again.lease, &Checkpoint::new(json!({"step": 41})))
        .await
        .unwrap();
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!(job.checkpoint, Some(Checkpoint::new(json!({"step": 41}))));
}

async fn a_deferred_job_waits_the_first_backoff_without_using_an_attempt(f: Fixture) {
    let q = f.queue.clone().with_backoff(Backoff {
        base: Duration::from_secs(10),
        cap: Duration::from_secs(25),
    });
    let id = q
        .enqueue(NewJob::new("train", json!({})).max_attempts(1))
        .await
        .unwrap();
    // Deferred again and again (a disk that stays full): never failed, never past its one
    // attempt, each time due one base delay later.
    let mut now = START_MS;
    for _ in 0..3 {
        let c = q.claim("w", &["train"], LEASE).await.unwrap().unwrap();
        assert_eq!(c.lease.attempt, 1);
        assert_eq!(
            q.defer(&c.lease, "waiting for disk space").await.unwrap(),
            JobState::Queued
        );
        let job = q.get(id).await.unwrap().unwrap();
        assert_eq!((job.state, job.attempt), (JobState::Queued, 0));
        assert_eq!(job.last_error.as_deref(), Some("waiting for disk space"));
        assert_eq!(job.run_after_ms, now + 10_000);
        assert!(is_lease_lost(q.defer(&c.lease, "again").await));
        f.clock.set(now + 9_999);
        assert!(q.claim("w", &["train"], LEASE).await.unwrap().is_none());
        now += 10_000;
        f.clock.set(now);
    }
    // A deferred job with a cancel requested is cancelled instead.
    let c = q.claim("w", &["train"], LEASE).await.unwrap().unwrap();
    q.request_cancel(id).await.unwrap();
    assert_eq!(
        q.defer(&c.lease, "waiting for disk space").await.unwrap(),
        JobState::Cancelled
    );
}

async fn retention_deletes_old_finished_jobs_and_their_events(f: Fixture) {
    let q = &f.queue;
    let old_done = q.enqueue(NewJob::new("k", json!(1))).await.unwrap();
    let c = q.claim("w", &["k"], LEASE).await.unwrap().unwrap();
    q.complete(&c.lease, &json!(1)).await.unwrap();
    let old_failed = q
        .enqueue(NewJob::new("k", json!(2)).max_attempts(1))
        .await
        .unwrap();
    let c = q.claim("w", &["k"], LEASE).await.unwrap().unwrap();
    q.fail(&c.lease, "x", true).await.unwrap();
    let old_queued = q.enqueue(NewJob::new("other", json!(3))).await.unwrap();
    f.clock.advance(Duration::from_secs(7200));
    let recent = q.enqueue(NewJob::new("k", json!(4))).await.unwrap();
    let c = q.claim("w", &["k"], LEASE).await.unwrap().unwrap();
    q.complete(&c.lease, &json!(4)).await.unwrap();
    let running = q.enqueue(NewJob::new("k", json!(5))).await.unwrap();
    q.claim("w", &["k"], LEASE).await.unwrap().unwrap();

    assert_eq!(
        q.purge_finished(Duration::from_secs(3600)).await.unwrap(),
        2
    );
    assert!(q.get(old_done).await.unwrap().is_none());
    assert!(q.get(old_failed).await.unwrap().is_none());
    assert!(q.events(old_done, 0, 10).await.unwrap().is_empty());
    for kept in [old_queued, recent, running] {
        assert!(q.get(kept).await.unwrap().is_some());
        assert!(!q.events(kept, 0, 10).await.unwrap().is_empty());
    }
    assert_eq!(
        q.purge_finished(Duration::from_secs(3600)).await.unwrap(),
        0
    );
    assert_eq!(q.purge_finished(Duration::ZERO).await.unwrap(), 0);
    f.clock.advance(Duration::from_millis(1));
    assert_eq!(q.purge_finished(Duration::ZERO).await.unwrap(), 1);
}

async fn events_are_ordered_and_resumable(f: Fixture) {
    let q = &f.queue;
    let id = q.enqueue(NewJob::new("train", json!({}))).await.unwrap();
    let other = q.enqueue(NewJob::new("train", json!({}))).await.unwrap();
    let c = q.claim("w", &["train"], LEASE).await.unwrap().unwrap();
    assert_eq!(c.job.id, id);
    let mut progress_ids = Vec::new();
    for step in 1..=5 {
        f.clock.advance(Duration::from_millis(10));
        let (_, event_id) = q
            .report_progress(&c.lease, &json!({"step": step, "eta_s": 50 - step * 10}))
            .await
            .unwrap();
        progress_ids.push(event_id);
    }
    q.save_checkpoint(&c.lease, &Checkpoint::new(json!({"step": 5})))
        .await
        .unwrap();
    q.complete(&c.lease, &json!("ok")).await.unwrap();

    let events = q.events(id, 0, 100).await.unwrap();
    let kinds: Vec<&str> = events.iter().map(|e| e.kind.as_str()).collect();
    assert_eq!(
        kinds,
        [
            "state",
            "state",
            "progress",
            "progress",
            "progress",
            "progress",
            "progress",
            "checkpoint",
            "state"
        ]
    );
    assert_eq!(events[0].data["state"], "queued");
    assert_eq!(events[1].data["state"], "running");
    assert_eq!(events[8].data["state"], "succeeded");
    assert!(events.windows(2).all(|w| w[0].id < w[1].id));
    assert!(
        events
            .windows(2)
            .all(|w| w[0].created_ms <= w[1].created_ms)
    );
    assert!(events.iter().all(|e| e.job_id == id));
    let steps: Vec<i64> = events[2..7]
        .iter()
        .map(|e| e.data["step"].as_i64().unwrap())
        .collect();
    assert_eq!(steps, [1, 2, 3, 4, 5]);
    assert_eq!(
        progress_ids,
        events[2..7].iter().map(|e| e.id).collect::<Vec<_>>()
    );
    assert_eq!(
        q.get(id).await.unwrap().unwrap().progress.unwrap()["step"],
        5
    );

    // Resume after the third progress event (Last-Event-ID), in pages.
    let resumed = q.events(id, progress_ids[2], 2).await.unwrap();
    assert_eq!(resumed.len(), 2);
    assert_eq!(resumed[0].data["step"], 4);
    let rest = q.events(id, resumed[1].id, 100).await.unwrap();
    assert_eq!(rest.len(), 2);
    assert_eq!(rest[1].data["state"], "succeeded");
    // Another job's stream holds only its own events.
    let theirs = q.events(other, 0, 100).await.unwrap();
    assert_eq!(theirs.len(), 1);
}

async fn concurrent_claims_take_each_job_once(f: Fixture) {
    const JOBS: usize = 120;
    const CLAIMERS: usize = 6;
    let q = f.system_queue();
    for i in 0..JOBS {
        q.enqueue(NewJob::new("k", json!(i))).await.unwrap();
    }
    let mut tasks = tokio::task::JoinSet::new();
    for w in 0..CLAIMERS {
        let q = q.clone();
        tasks.spawn(async move {
            let mut mine = Vec::new();
            while let Some(c) = q.claim(&format!("w{w}"), &["k"], LEASE).await.unwrap() {
                q.complete(&c.lease, &json!(w)).await.unwrap();
                mine.push(c.job.id);
            }
            mine
        });
    }
    let mut all = Vec::new();
    while let Some(mine) = tasks.join_next().await {
        all.extend(mine.unwrap());
    }
    let total = all.len();
    all.sort();
    all.dedup();
    assert_eq!((total, all.len()), (JOBS, JOBS));
    assert_eq!(
        q.stats().await.unwrap().get(&JobState::Succeeded),
        Some(&(JOBS as u64))
    );
}

fn fast_config(id: &str) -> WorkerConfig {
    WorkerConfig {
        id: id.to_owned(),
        concurrency: 2,
        lease: Duration::from_secs(10),
        heartbeat: Duration::from_millis(50),
        poll_interval: Duration::from_millis(20),
        shutdown_grace: Duration::from_secs(10),
    }
}

/// Waits (a minute at most) until `check` holds, failing with `what`.
async fn wait_until<F, Fut>(what: &str, check: F)
where
    F: FnMut() -> Fut,
    Fut: Future<Output = bool>,
{
    fixtures::wait::eventually(what, Duration::from_secs(60))
        .until_async(check)
        .await;
}

async fn finished(q: &Queue, n: u64) -> bool {
    let stats = q.stats().await.unwrap();
    stats
        .iter()
        .filter(|(s, _)| s.is_finished())
        .map(|(_, n)| n)
        .sum::<u64>()
        >= n
}

async fn workers_run_every_job_exactly_once(f: Fixture) {
    const JOBS: usize = 60;
    const WORKERS: usize = 5;
    let q = f.system_queue();
    let mut ids = Vec::new();
    for i in 0..JOBS {
        ids.push(
            q.enqueue(NewJob::new("count", json!({"i": i})))
                .await
                .unwrap(),
        );
    }
    let runs: Arc<Mutex<HashMap<Uuid, u32>>> = Arc::default();
    let shutdown = CancellationToken::new();
    let mut workers = tokio::task::JoinSet::new();
    for w in 0..WORKERS {
        let runs = runs.clone();
        let worker = Worker::new(q.clone(), fast_config(&format!("w{w}"))).register(
            "count",
            handler_fn(move |ctx: JobContext| {
                let runs = runs.clone();
                async move {
                    *runs.lock().unwrap().entry(ctx.id()).or_default() += 1;
                    tokio::time::sleep(Duration::from_millis(3)).await;
                    ctx.report_progress(&json!({"done": true})).await?;
                    Ok(json!({"i": ctx.payload()["i"]}))
                }
            }),
        );
        workers.spawn(worker.run(shutdown.clone()));
    }
    wait_until("all jobs finished", || finished(&q, JOBS as u64)).await;
    shutdown.cancel();
    let mut succeeded = 0;
    let mut claimed = 0;
    while let Some(report) = workers.join_next().await {
        let report = report.unwrap();
        succeeded += report.succeeded;
        claimed += report.claimed;
    }
    assert_eq!((succeeded, claimed), (JOBS as u64, JOBS as u64));
    let runs = runs.lock().unwrap().clone();
    assert_eq!(runs.len(), JOBS);
    assert!(runs.values().all(|&n| n == 1), "{runs:?}");
    for (i, id) in ids.iter().enumerate() {
        let job = q.get(*id).await.unwrap().unwrap();
        assert_eq!((job.state, job.attempt), (JobState::Succeeded, 1));
        assert_eq!(job.result, Some(json!({"i": i})));
    }
}

async fn runner_records_outcomes(f: Fixture) {
    let q = f.system_queue().with_backoff(Backoff {
        base: Duration::from_millis(10),
        cap: Duration::from_millis(10),
    });
    let ok = q.enqueue(NewJob::new("ok", json!({"x": 2}))).await.unwrap();
    let flaky = q.enqueue(NewJob::new("flaky", json!({}))).await.unwrap();
    let fatal = q.enqueue(NewJob::new("fatal", json!({}))).await.unwrap();
    let panics = q
        .enqueue(NewJob::new("panics", json!({})).max_attempts(2))
        .await
        .unwrap();
    let bad_payload = q.enqueue(NewJob::new("ok", json!("nope"))).await.unwrap();
    #[derive(serde::Deserialize)]
    struct X {
        x: i64,
    }
    let worker = Worker::new(q.clone(), fast_config("w"))
        .register(
            "ok",
            handler_fn(|ctx: JobContext| async move {
                let p: X = ctx.payload_as()?;
                Ok(json!(p.x * 2))
            }),
        )
        .register(
            "flaky",
            handler_fn(|ctx: JobContext| async move {
                if ctx.attempt() < 3 {
                    Err(JobError::retryable("connection reset"))
                } else {
                    Ok(json!("third time"))
                }
            }),
        )
        .register(
            "fatal",
            handler_fn(|_ctx: JobContext| async move { Err(JobError::fatal("no such map")) }),
        )
        .register(
            "panics",
            handler_fn(|ctx: JobContext| async move {
                if ctx.attempt() > 0 {
                    panic!("handler bug");
                }
                Ok(Value::Null)
            }),
        );
    assert_eq!(worker.kinds(), ["fatal", "flaky", "ok", "panics"]);
    let shutdown = CancellationToken::new();
    let run = tokio::spawn(worker.run(shutdown.clone()));
    wait_until("all finished", || finished(&q, 5)).await;
    shutdown.cancel();
    let report = run.await.unwrap();
    assert_eq!((report.succeeded, report.failed, report.retried), (2, 3, 3));

    let job = |id| {
        let q = q.clone();
        async move { q.get(id).await.unwrap().unwrap() }
    };
    let j = job(ok).await;
    assert_eq!((j.state, j.result), (JobState::Succeeded, Some(json!(4))));
    let j = job(flaky).await;
    assert_eq!((j.state, j.attempt), (JobState::Succeeded, 3));
    assert_eq!(j.last_error.as_deref(), Some("connection reset"));
    let j = job(fatal).await;
    assert_eq!((j.state, j.attempt), (JobState::Failed, 1));
    assert_eq!(j.last_error.as_deref(), Some("no such map"));
    let j = job(panics).await;
    assert_eq!((j.state, j.attempt), (JobState::Failed, 2));
    assert!(j.last_error.unwrap().contains("panicked"));
    let j = job(bad_payload).await;
    assert_eq!((j.state, j.attempt), (JobState::Failed, 1));
    assert!(j.last_error.unwrap().contains("invalid ok payload"));
}

/// Counts steps until `target`, checkpointing every 5 steps; stops on the token after saving
/// a checkpoint. Resumes from the last checkpoint.
fn counting_handler(step: Duration, seen: Seen) -> impl queue::JobHandler {
    handler_fn(move |ctx: JobContext| {
        let seen = seen.clone();
        async move {
            let target = ctx.payload()["target"].as_i64().unwrap_or(0);
            let start = ctx
                .checkpoint()
                .map_or(0, |c| c.data["i"].as_i64().unwrap_or(0));
            let mut i = start;
            let result: Result<(), JobError> = async {
                while i < target {
                    if ctx.is_stopping() {
                        ctx.save_checkpoint(&Checkpoint::new(json!({"i": i})))
                            .await?;
                        return Err(ctx.stopped());
                    }
                    tokio::select! {
                        () = tokio::time::sleep(step) => {}
                        () = ctx.cancellation().cancelled() => continue,
                    }
                    i += 1;
                    ctx.report_progress(&json!({"i": i})).await?;
                    if i % 5 == 0 {
                        ctx.save_checkpoint(&Checkpoint::new(json!({"i": i})))
                            .await?;
                    }
                }
                Ok(())
            }
            .await;
            if let Err(e) = result {
                seen.lock().unwrap().push((ctx.stop_reason(), i));
                return Err(e);
            }
            Ok(json!({"count": i, "resumed_from": start}))
        }
    })
}

async fn runner_cancel_request_stops_the_handler(f: Fixture) {
    let q = f.system_queue();
    let id = q
        .enqueue(NewJob::new("count", json!({"target": 100_000})))
        .await
        .unwrap();
    let seen = Arc::default();
    let worker = Worker::new(q.clone(), fast_config("w")).register(
        "count",
        counting_handler(Duration::from_millis(5), Arc::clone(&seen)),
    );
    let shutdown = CancellationToken::new();
    let run = tokio::spawn(worker.run(shutdown.clone()));
    wait_until("progress", || {
        let q = q.clone();
        async move {
            q.get(id)
                .await
                .unwrap()
                .unwrap()
                .progress
                .is_some_and(|p| p["i"].as_i64() > Some(3))
        }
    })
    .await;
    assert_eq!(q.request_cancel(id).await.unwrap(), JobState::Running);
    wait_until("cancelled", || finished(&q, 1)).await;
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!(job.state, JobState::Cancelled);
    assert!(job.checkpoint.is_some());
    let seen = seen.lock().unwrap().clone();
    assert_eq!(seen.len(), 1);
    assert_eq!(seen[0].0, Some(StopReason::CancelRequested));
    shutdown.cancel();
    let report = run.await.unwrap();
    assert_eq!((report.cancelled, report.released), (1, 0));
    let events = q.events(id, 0, 100_000).await.unwrap();
    assert!(events.iter().any(|e| e.kind == "cancel_requested"));
    assert_eq!(events.last().unwrap().data["state"], "cancelled");
}

async fn runner_shutdown_releases_and_another_worker_resumes(f: Fixture) {
    let q = f.system_queue();
    let id = q
        .enqueue(NewJob::new("count", json!({"target": 60})).max_attempts(1))
        .await
        .unwrap();
    let seen: Seen = Arc::default();
    let first = Worker::new(q.clone(), fast_config("first")).register(
        "count",
        counting_handler(Duration::from_millis(10), seen.clone()),
    );
    let shutdown = CancellationToken::new();
    let run = tokio::spawn(first.run(shutdown.clone()));
    wait_until("progress", || {
        let q = q.clone();
        async move {
            q.get(id)
                .await
                .unwrap()
                .unwrap()
                .progress
                .is_some_and(|p| p["i"].as_i64() >= Some(12))
        }
    })
    .await;
    shutdown.cancel();
    let report = run.await.unwrap();
    assert_eq!(
        (report.released, report.failed),
        (1, 0),
        "{report:?} {seen:?}"
    );
    let stopped_at = {
        let seen = seen.lock().unwrap();
        assert_eq!(seen.len(), 1);
        assert_eq!(seen[0].0, Some(StopReason::Shutdown));
        seen[0].1
    };
    let job = q.get(id).await.unwrap().unwrap();
    // Released, not failed: the attempt is given back (max_attempts is 1).
    assert_eq!((job.state, job.attempt), (JobState::Queued, 0));
    assert_eq!(job.checkpoint.unwrap().data["i"], stopped_at);

    let second = Worker::new(q.clone(), fast_config("second")).register(
        "count",
        counting_handler(Duration::from_millis(1), seen.clone()),
    );
    let shutdown = CancellationToken::new();
    let run = tokio::spawn(second.run(shutdown.clone()));
    wait_until("finished", || finished(&q, 1)).await;
    shutdown.cancel();
    assert_eq!(run.await.unwrap().succeeded, 1);
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!((job.state, job.attempt), (JobState::Succeeded, 1));
    assert_eq!(
        job.result,
        Some(json!({"count": 60, "resumed_from": stopped_at}))
    );
}

async fn runner_stops_a_handler_whose_lease_was_taken(f: Fixture) {
    let q = f.system_queue();
    let id = q
        .enqueue(NewJob::new("count", json!({"target": 100_000})))
        .await
        .unwrap();
    let seen: Seen = Arc::default();
    // One job at a time, so this worker cannot reclaim the expired lease itself.
    let config = WorkerConfig {
        concurrency: 1,
        ..fast_config("slow")
    };
    let worker = Worker::new(q.clone(), config).register(
        "count",
        counting_handler(Duration::from_millis(5), seen.clone()),
    );
    let shutdown = CancellationToken::new();
    let run = tokio::spawn(worker.run(shutdown.clone()));
    wait_until("running", || {
        let q = q.clone();
        async move { q.get(id).await.unwrap().unwrap().progress.is_some() }
    })
    .await;
    // Another worker takes the job over (as if the first one had stalled past its lease). The
    // first worker's heartbeat may renew the expired lease before the thief claims: retry.
    let thief = loop {
        assert!(q.expire_lease(id).await.unwrap());
        if let Some(thief) = q.claim("thief", &["count"], LEASE).await.unwrap() {
            break thief;
        }
    };
    wait_until("the first handler stopped", || {
        let seen = seen.clone();
        async move { !seen.lock().unwrap().is_empty() }
    })
    .await;
    assert_eq!(seen.lock().unwrap()[0].0, Some(StopReason::LeaseLost));
    shutdown.cancel();
    let report = run.await.unwrap();
    assert_eq!((report.lost, report.released, report.failed), (1, 0, 0));
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!(job.state, JobState::Running);
    assert_eq!(job.lease_owner.as_deref(), Some("thief"));
    assert_eq!(job.lease_token, thief.lease.token);
    q.complete(&thief.lease, &json!("thief's")).await.unwrap();
}

/// A handler installs its files (a checkpoint, an exported policy) only after
/// `fence_blocking` renewed its lease: once another worker took the job, the fence refuses, so
/// two workers can never both install one job's files.
async fn a_handler_that_lost_its_lease_cannot_install_files(f: Fixture) {
    let q = f.system_queue();
    let id = q.enqueue(NewJob::new("install", json!({}))).await.unwrap();
    let taken = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let fences: Arc<Mutex<Vec<bool>>> = Arc::default();
    let handler = {
        let (taken, fences) = (taken.clone(), fences.clone());
        handler_fn(move |ctx: JobContext| {
            let (taken, fences) = (taken.clone(), fences.clone());
            async move {
                tokio::task::spawn_blocking(move || {
                    // Owned: the fence holds.
                    fences.lock().unwrap().push(ctx.fence_blocking().is_ok());
                    while !taken.load(std::sync::atomic::Ordering::SeqCst) {
                        std::thread::sleep(Duration::from_millis(5));
                    }
                    // Taken over: the fence refuses, and the job stops.
                    let fenced = ctx.fence_blocking();
                    fences.lock().unwrap().push(fenced.is_ok());
                    assert!(ctx.is_stopping());
                    Err::<Value, _>(ctx.stopped())
                })
                .await
                .unwrap()
            }
        })
    };
    let config = WorkerConfig {
        concurrency: 1,
        ..fast_config("slow")
    };
    let worker = Worker::new(q.clone(), config).register("install", handler);
    let shutdown = CancellationToken::new();
    let run = tokio::spawn(worker.run(shutdown.clone()));
    wait_until("the first fence", || {
        let fences = fences.clone();
        async move { !fences.lock().unwrap().is_empty() }
    })
    .await;
    let thief = loop {
        assert!(q.expire_lease(id).await.unwrap());
        if let Some(thief) = q.claim("thief", &["install"], LEASE).await.unwrap() {
            break thief;
        }
    };
    taken.store(true, std::sync::atomic::Ordering::SeqCst);
    wait_until("the second fence", || {
        let fences = fences.clone();
        async move { fences.lock().unwrap().len() == 2 }
    })
    .await;
    assert_eq!(*fences.lock().unwrap(), vec![true, false]);
    shutdown.cancel();
    run.await.unwrap();
    let job = q.get(id).await.unwrap().unwrap();
    assert_eq!(job.lease_owner.as_deref(), Some("thief"));
    q.complete(&thief.lease, &json!("thief's")).await.unwrap();
}
