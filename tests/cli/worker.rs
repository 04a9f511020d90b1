//! `mentalsim worker` as a real process: against the job database file of a separately started
//! `mentalsim serve` (which runs no workers of its own), with that service's knowledge over
//! HTTP, it becomes ready, claims a training created through the service's API, completes it,
//! and stops cleanly on SIGTERM.

use std::time::{Duration, Instant};

use serde_json::{Value, json};

use super::served::{Serve, Worker};

#[test]
fn a_worker_process_completes_a_training_created_through_the_service() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let mut service = Serve::new()
        .data_dir(&data)
        .env("MENTALSIM_WORKER_CONCURRENCY", "0")
        .start();

    let mut worker = Worker::new(&service.url, dir.path().join("worker"))
        .database_url(format!("sqlite://{}", data.join("jobs.sqlite").display()))
        .env("MENTALSIM_KNOWLEDGE_TOKEN_FILE", data.join("admin.token"))
        .env("MENTALSIM_POLICIES_DIR", data.join("policies"))
        .env("MENTALSIM_CHECKPOINTS_DIR", data.join("checkpoints"))
        .start();
    worker.wait_ready(Duration::from_secs(60));
    let (url, health, token) = (&service.url, &worker.url, &service.token);

    let client = reqwest::blocking::Client::new();
    let healthz: Value = client
        .get(format!("{health}/healthz"))
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(healthz["role"], "worker");

    let created = client
        .post(format!("{url}/v1/jobs"))
        .bearer_auth(token)
        .json(&json!({
            "kind": "train",
            "payload": {
                "robot": "R-001", "place": "F0-office", "minutes": 0.04, "seed": 5,
                "config": {"td3": {"hidden": [16, 16], "batch_size": 32}, "envs": 2,
                           "buffer_capacity": 20000, "random_steps": 100,
                           "eval_every": 1000000, "eval_episodes": 3}
            }
        }))
        .send()
        .unwrap();
    assert_eq!(created.status(), 201);
    let id = created.json::<Value>().unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let deadline = Instant::now() + Duration::from_secs(240);
    let job = loop {
        let job: Value = client
            .get(format!("{url}/v1/jobs/{id}"))
            .bearer_auth(token)
            .send()
            .unwrap()
            .json()
            .unwrap();
        if job["state"] != "queued" && job["state"] != "running" {
            break job;
        }
        assert!(Instant::now() < deadline, "not done in time: {job:#}");
        std::thread::sleep(Duration::from_millis(300));
    };
    assert_eq!(job["state"], "succeeded", "{job:#}");
    // The worker took the floor of the office from the service: the whole floor F0.
    assert!(
        job["result"]["floor"]
            .as_str()
            .unwrap()
            .ends_with("/floors/0"),
        "{job:#}"
    );
    let policy_id = job["result"]["policy_id"].as_str().unwrap();
    let policies: Vec<Value> = client
        .get(format!("{url}/v1/policies"))
        .bearer_auth(token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert!(
        policies.iter().any(|p| p["id"] == policy_id),
        "{policies:?}"
    );

    worker.stop(Duration::from_secs(40));
    service.stop(Duration::from_secs(40));
}
