//! `mentalsim worker` as a real process: against the job database file of a separately started
//! `mentalsim serve` (which runs no workers of its own), with that service's knowledge over
//! HTTP, it becomes ready, claims a training created through the service's API, completes it,
//! and stops cleanly on SIGTERM.

use std::io::{BufRead, BufReader};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{Signal, kill};
use nix::unistd::Pid;
use serde_json::{Value, json};

use super::mentalsim;

/// Reads the child's stdout until a line with an `http://` URL, and returns that URL.
pub(super) fn printed_url(child: &mut Child) -> String {
    let stdout = child.stdout.take().unwrap();
    let mut reader = BufReader::new(stdout);
    let mut line = String::new();
    for _ in 0..10 {
        line.clear();
        reader.read_line(&mut line).unwrap();
        if let Some(url) = line.split_whitespace().find(|w| w.starts_with("http://")) {
            return url.to_owned();
        }
    }
    panic!("no URL printed; last line: {line}");
}

fn stop(child: &mut Child, what: &str) {
    kill(
        Pid::from_raw(i32::try_from(child.id()).unwrap()),
        Signal::SIGTERM,
    )
    .unwrap();
    let deadline = Instant::now() + Duration::from_secs(40);
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            assert!(status.success(), "{what} exit status: {status}");
            return;
        }
        assert!(Instant::now() < deadline, "{what} did not stop within 40 s");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Kills the children when dropped (a failed assertion must not leave servers behind).
pub(super) struct Killer(pub(super) Vec<Child>);

impl Drop for Killer {
    fn drop(&mut self) {
        for child in &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

#[test]
fn a_worker_process_completes_a_training_created_through_the_service() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let mut children = Killer(Vec::new());
    let serve = mentalsim()
        .args(["serve", "--bind", "127.0.0.1:0", "--data-dir"])
        .arg(&data)
        .env("MENTALSIM_WORKER_CONCURRENCY", "0")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    children.0.push(serve);
    let service = printed_url(&mut children.0[0]);
    let token = std::fs::read_to_string(data.join("admin.token"))
        .unwrap()
        .trim()
        .to_owned();

    let worker = mentalsim()
        .args(["worker", "--bind", "127.0.0.1:0", "--concurrency", "1"])
        .arg("--knowledge-url")
        .arg(&service)
        .arg("--database-url")
        .arg(format!("sqlite://{}", data.join("jobs.sqlite").display()))
        .arg("--data-dir")
        .arg(dir.path().join("worker"))
        .env("MENTALSIM_KNOWLEDGE_TOKEN_FILE", data.join("admin.token"))
        .env("MENTALSIM_POLICIES_DIR", data.join("policies"))
        .env("MENTALSIM_CHECKPOINTS_DIR", data.join("checkpoints"))
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    children.0.push(worker);
    let health = printed_url(&mut children.0[1]);

    let client = reqwest::blocking::Client::new();
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        let ready = client.get(format!("{health}/readyz")).send();
        if ready.as_ref().is_ok_and(|r| r.status() == 200) {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the worker never became ready: {:?}",
            ready.map(|r| r.text())
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    let healthz: Value = client
        .get(format!("{health}/healthz"))
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert_eq!(healthz["role"], "worker");

    let created = client
        .post(format!("{service}/v1/jobs"))
        .bearer_auth(&token)
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
            .get(format!("{service}/v1/jobs/{id}"))
            .bearer_auth(&token)
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
        .get(format!("{service}/v1/policies"))
        .bearer_auth(&token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    assert!(
        policies.iter().any(|p| p["id"] == policy_id),
        "{policies:?}"
    );

    stop(&mut children.0[1], "mentalsim worker");
    stop(&mut children.0[0], "mentalsim serve");
}
