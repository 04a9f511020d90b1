//! The jobs and policies API through the real app (real Oxigraph, real SQLite, the in-process
//! worker): a training on the bundled sample building to an exported policy that downloads and
//! loads, its event stream, cancellation of a running training, and bad input.

use std::time::{Duration, Instant};

use fixtures::wait::consistently;
use reqwest::Method;
use serde_json::{Value, json};

use crate::helpers::{SseEvent, TestApp, read_events, spawn_app, spawn_app_with};

/// A training that finishes in seconds.
fn tiny_train(minutes: f64) -> Value {
    json!({
        "kind": "train",
        "payload": {
            "robot": "R-001",
            "place": "F0",
            "minutes": minutes,
            "seed": 3,
            "config": {
                "td3": {"hidden": [16, 16], "batch_size": 32},
                "envs": 2,
                "buffer_capacity": 20000,
                "random_steps": 100,
                "demo_steps": 500,
                "bc_steps": 100,
                "critic_warmup_steps": 100,
                "eval_every": 1000000,
                "eval_episodes": 3,
                "checkpoint_every_s": 1.0
            }
        }
    })
}

async fn post_job(app: &TestApp, body: &Value) -> reqwest::Response {
    app.request(Method::POST, "/v1/jobs")
        .json(body)
        .send()
        .await
        .unwrap()
}

async fn get_job(app: &TestApp, id: &str) -> Value {
    let (status, job) = app.get_json(&format!("/v1/jobs/{id}")).await;
    assert_eq!(status, 200, "{job}");
    job
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_training_job_streams_its_events_and_exports_a_policy_that_downloads_and_loads() {
    let app = spawn_app().await;
    let response = post_job(&app, &tiny_train(0.05)).await;
    assert_eq!(response.status(), 201);
    let location = response.headers()[reqwest::header::LOCATION]
        .to_str()
        .unwrap()
        .to_owned();
    let job: Value = response.json().await.unwrap();
    let id = job["id"].as_str().unwrap().to_owned();
    assert_eq!(location, format!("/v1/jobs/{id}"));
    assert_eq!(job["kind"], "train");
    assert_eq!(job["state"], "queued");
    assert_eq!(job["payload"]["place"], "F0");

    // The live stream: everything from the start, until the job has finished.
    let stream = app
        .request(Method::GET, &format!("/v1/jobs/{id}/events"))
        .send()
        .await
        .unwrap();
    let events = read_events(stream, Duration::from_secs(240)).await;
    assert!(
        events.windows(2).all(|w| w[0].id < w[1].id),
        "ids increase: {events:?}"
    );
    assert_eq!(events[0].event, "state");
    assert_eq!(events[0].data["data"]["state"], "queued");
    let progress: Vec<&SseEvent> = events.iter().filter(|e| e.event == "progress").collect();
    assert!(!progress.is_empty(), "{events:?}");
    assert!(
        progress.last().unwrap().data["data"]["env_steps"]
            .as_u64()
            .unwrap()
            > 0
    );
    assert!(events.iter().any(|e| e.event == "checkpoint"), "{events:?}");
    let last = events.last().unwrap();
    assert_eq!(last.event, "state");
    assert_eq!(last.data["data"]["state"], "succeeded", "{events:?}");

    // Resuming after an event replays only what followed it.
    let second = events[1].id;
    let resumed = app
        .request(Method::GET, &format!("/v1/jobs/{id}/events"))
        .header("Last-Event-ID", second.to_string())
        .send()
        .await
        .unwrap();
    let rest = read_events(resumed, Duration::from_secs(30)).await;
    assert_eq!(
        rest.iter().map(|e| e.id).collect::<Vec<_>>(),
        events[2..].iter().map(|e| e.id).collect::<Vec<_>>()
    );
    let after = app
        .request(
            Method::GET,
            &format!("/v1/jobs/{id}/events?after={}", last.id),
        )
        .send()
        .await
        .unwrap();
    assert!(read_events(after, Duration::from_secs(30)).await.is_empty());

    let job = get_job(&app, &id).await;
    assert_eq!(job["state"], "succeeded", "{job:#}");
    assert_eq!(job["attempts"], 1);
    assert!(job["finished"].as_str().unwrap().ends_with('Z'));
    let result = &job["result"];
    let policy_id = result["policy_id"].as_str().unwrap().to_owned();
    assert!(result["success_rate"].as_f64().unwrap() >= 0.0);
    assert_eq!(result["eval_episodes"], 3);
    assert!(result["env_steps"].as_u64().unwrap() > 100);
    // Its checkpoint is gone with it.
    assert!(!app.data_dir.join("checkpoints").join(&id).exists());

    // Its learning curves stay, with the policy: one CSV row per episode, and the picture.
    let csv = app
        .request(Method::GET, &format!("/v1/jobs/{id}/curves.csv"))
        .send()
        .await
        .unwrap();
    assert_eq!(csv.status(), 200);
    let csv = csv.text().await.unwrap();
    assert!(
        csv.starts_with("episode,env_steps,wall_s,reward,outcome"),
        "{csv}"
    );
    let rows = csv.lines().count() - 1;
    assert!(
        rows as u64 >= result["episodes"].as_u64().unwrap().min(1),
        "{csv}"
    );
    let png = app
        .request(Method::GET, &format!("/v1/jobs/{id}/curves.png"))
        .send()
        .await
        .unwrap();
    assert_eq!(png.status(), 200);
    assert_eq!(png.headers()["content-type"], "image/png");
    assert!(png.bytes().await.unwrap().starts_with(b"\x89PNG"));

    // Listed, described and downloadable.
    let list: Vec<Value> = app
        .request(Method::GET, "/v1/policies")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let listed = list.iter().find(|p| p["id"] == policy_id).unwrap();
    assert_eq!(
        listed["robot"],
        "https://mentalsim.dev/data/robots/differential-robot"
    );
    assert_eq!(listed["place"], "F0");
    assert_eq!(listed["job_id"], id.as_str());
    assert_eq!(listed["eval"]["episodes"], 3);
    let one: Value = app
        .request(Method::GET, &format!("/v1/policies/{policy_id}"))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(one["metadata"]["format"], "mentalsim-td3-actor");
    let weights = app
        .request(
            Method::GET,
            &format!("/v1/policies/{policy_id}/policy.safetensors"),
        )
        .send()
        .await
        .unwrap();
    assert_eq!(weights.status(), 200);
    let weights = weights.bytes().await.unwrap();
    let meta = app
        .request(
            Method::GET,
            &format!("/v1/policies/{policy_id}/policy.json"),
        )
        .send()
        .await
        .unwrap()
        .bytes()
        .await
        .unwrap();
    let policy = learning::Policy::from_bytes(&meta, &weights).unwrap();
    assert_eq!(policy.metadata().hidden, vec![16, 16]);
    let missing = app
        .request(Method::GET, "/v1/policies/nope/policy.json")
        .send()
        .await
        .unwrap();
    assert_eq!(missing.status(), 404);

    // The policy evaluates on the floor through an `evaluate` job.
    let response = post_job(
        &app,
        &json!({"kind": "evaluate", "payload": {"policy": policy_id, "place": "F0", "episodes": 4}}),
    )
    .await;
    assert_eq!(response.status(), 201);
    let eval_id = response.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let eval = app
        .wait_for_job(&eval_id, Duration::from_secs(120), |j| {
            j["state"] != "queued" && j["state"] != "running"
        })
        .await;
    assert_eq!(eval["state"], "succeeded", "{eval:#}");
    assert_eq!(eval["result"]["episodes"], 4);
    for key in ["success_rate", "collision_rate", "env_steps", "wall_s"] {
        assert!(eval["result"][key].is_number(), "{key}: {eval:#}");
    }

    // Filters.
    let trains: Vec<Value> = app
        .request(Method::GET, "/v1/jobs?kind=train&state=succeeded&limit=10")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(trains.len(), 1);
    assert_eq!(trains[0]["id"], id.as_str());
    app.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cancelling_a_running_training_stops_its_trainer() {
    let app = spawn_app().await;
    let response = post_job(&app, &tiny_train(30.0)).await;
    assert_eq!(response.status(), 201);
    let id = response.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let running = app
        .wait_for_job(&id, Duration::from_secs(120), |j| {
            j["state"] == "running" && j["progress"]["env_steps"].as_u64().unwrap_or(0) > 0
        })
        .await;
    assert!(
        running["progress"]["eta_s"].as_f64().unwrap() > 0.0,
        "{running:#}"
    );
    let cancel = app
        .request(Method::POST, &format!("/v1/jobs/{id}/cancel"))
        .send()
        .await
        .unwrap();
    assert_eq!(cancel.status(), 202);
    let asked: Value = cancel.json().await.unwrap();
    assert_eq!(asked["cancel_requested"], true);
    let started = Instant::now();
    let job = app
        .wait_for_job(&id, Duration::from_secs(60), |j| {
            j["state"] != "running" && j["state"] != "queued"
        })
        .await;
    assert_eq!(job["state"], "cancelled", "{job:#}");
    assert!(
        started.elapsed() < Duration::from_secs(30),
        "stopped in {:?}",
        started.elapsed()
    );
    // The trainer stopped: its progress no longer moves, its checkpoint is removed.
    let steps = job["progress"]["env_steps"].clone();
    consistently(
        format!("the cancelled training's env_steps staying at {steps}"),
        Duration::from_secs(3),
    )
    .every(Duration::from_millis(100))
    .holds_async(|| async {
        let now = get_job(&app, &id).await["progress"]["env_steps"].clone();
        if now == steps { Ok(()) } else { Err(now) }
    })
    .await;
    assert!(!app.data_dir.join("checkpoints").join(&id).exists());
    // A finished job cannot be cancelled again; an unknown one does not exist.
    let again = app
        .request(Method::POST, &format!("/v1/jobs/{id}/cancel"))
        .send()
        .await
        .unwrap();
    assert_eq!(again.status(), 409);
    let unknown = app
        .request(
            Method::POST,
            "/v1/jobs/01900000-0000-7000-8000-000000000000/cancel",
        )
        .send()
        .await
        .unwrap();
    assert_eq!(unknown.status(), 404);
    app.stop().await;
}

async fn refused(app: &TestApp, body: Value) -> (u16, String) {
    let r = post_job(app, &body).await;
    let status = r.status().as_u16();
    let body: Value = r.json().await.unwrap();
    (
        status,
        body["error"]["message"].as_str().unwrap().to_owned(),
    )
}

#[tokio::test]
async fn bad_jobs_are_refused_with_distinct_errors_naming_what_is_wrong() {
    let app = spawn_app().await;
    let train = |payload: Value| json!({"kind": "train", "payload": payload});

    let (status, message) = refused(&app, json!({"kind": "dance", "payload": {}})).await;
    assert_eq!(status, 400, "{message}");
    assert!(
        message.contains("dance") && message.contains("train"),
        "{message}"
    );

    // (request, status, words the message must contain)
    let cases: Vec<(Value, u16, &[&str])> = vec![
        (
            train(json!({"robot": "R-001", "minutes": 1})),
            422,
            &["place"],
        ),
        (
            train(json!({"robot": "R-001", "place": "F0", "minutes": 0.0})),
            422,
            &["minutes"],
        ),
        (
            train(json!({"robot": "R-001", "place": "F0", "minutes": -1.0})),
            422,
            &["minutes"],
        ),
        (
            train(json!({"robot": "R-001", "place": "F0", "minutes": 1.0e9})),
            422,
            &["minutes", "at most"],
        ),
        (
            train(
                json!({"robot": "R-001", "place": "F0", "minutes": 1, "config": {"envs": 1_000_000_000u64}}),
            ),
            422,
            &["envs", "at most"],
        ),
        (
            train(
                json!({"robot": "R-001", "place": "F0", "minutes": 1, "config": {"buffer_capacity": 1u64 << 40}}),
            ),
            422,
            &["buffer_capacity", "at most"],
        ),
        (
            train(
                json!({"robot": "R-001", "place": "F0", "minutes": 1, "config": {"td3": {"tau": 0}}}),
            ),
            422,
            &["config", "tau"],
        ),
        (
            train(json!({"robot": "R-001", "place": "F0", "minutes": 1, "config": {"nope": 1}})),
            422,
            &["nope"],
        ),
        (
            train(json!({"robot": "R-404", "place": "F0", "minutes": 1})),
            404,
            &["R-404"],
        ),
        (
            train(json!({"robot": "R-001", "place": "F9", "minutes": 1})),
            404,
            &["F9"],
        ),
        (
            train(json!({"robot": "R-001", "place": "B-001", "minutes": 1})),
            422,
            &["no floor"],
        ),
        (
            json!({"kind": "evaluate", "payload": {"policy": "missing", "place": "F0"}}),
            404,
            &["policy"],
        ),
        (
            json!({"kind": "roadmap", "payload": {"policy": "missing", "place": "F0"}}),
            404,
            &["policy", "missing"],
        ),
        (
            json!({"kind": "roadmap", "payload": {"policy": "missing", "place": "F0", "rollouts": 0}}),
            422,
            &["rollouts"],
        ),
        (
            json!({"kind": "roadmap", "payload": {"policy": "missing", "place": "F0", "keep_threshold": 1.5}}),
            422,
            &["keep_threshold"],
        ),
        (
            json!({"kind": "validate", "payload": {"robot": "R-001", "place": "F0"}}),
            422,
            &["start"],
        ),
    ];
    for (body, want, words) in cases {
        let (status, message) = refused(&app, body.clone()).await;
        assert_eq!(status, want, "{body}: {message}");
        for w in words {
            assert!(message.contains(w), "{body}: {message} lacks {w}");
        }
    }

    // Nothing was queued.
    let jobs: Vec<Value> = app
        .request(Method::GET, "/v1/jobs")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(jobs.is_empty(), "{jobs:?}");

    let bad_state = app
        .request(Method::GET, "/v1/jobs?state=done")
        .send()
        .await
        .unwrap();
    assert_eq!(bad_state.status(), 400);
    let body: Value = bad_state.json().await.unwrap();
    assert!(body["error"]["message"].as_str().unwrap().contains("done"));
    let unknown = app
        .request(Method::GET, "/v1/jobs/not-a-job")
        .send()
        .await
        .unwrap();
    assert_eq!(unknown.status(), 404);
    let events = app
        .request(
            Method::GET,
            "/v1/jobs/01900000-0000-7000-8000-000000000000/events",
        )
        .send()
        .await
        .unwrap();
    assert_eq!(events.status(), 404);
    app.stop().await;
}

#[tokio::test]
async fn robots_read_jobs_but_only_engineers_create_and_cancel_them() {
    let temp = tempfile::tempdir().unwrap();
    let data_dir = temp.path().join("data");
    let engineer = "engineer-token-0123456789";
    let robot = "robot-token-0123456789abc";
    let app = spawn_app_with(
        |c| {
            c.data_dir = data_dir;
            c.worker_concurrency = 0;
            c.tokens = vec![
                mentalsim::config::TokenConfig {
                    token: engineer.to_owned(),
                    name: "alice".to_owned(),
                    role: edge::Role::Engineer,
                },
                mentalsim::config::TokenConfig {
                    token: robot.to_owned(),
                    name: "R-001".to_owned(),
                    role: edge::Role::Robot,
                },
            ];
        },
        Some(temp),
    )
    .await;
    let url = |p: &str| format!("{}{p}", app.address);
    let as_robot = app
        .client
        .post(url("/v1/jobs"))
        .bearer_auth(robot)
        .json(&tiny_train(1.0))
        .send()
        .await
        .unwrap();
    assert_eq!(as_robot.status(), 403);
    let anonymous = app
        .client
        .post(url("/v1/jobs"))
        .json(&tiny_train(1.0))
        .send()
        .await
        .unwrap();
    assert_eq!(anonymous.status(), 401);
    let created = app
        .client
        .post(url("/v1/jobs"))
        .bearer_auth(engineer)
        .json(&tiny_train(1.0))
        .send()
        .await
        .unwrap();
    assert_eq!(created.status(), 201);
    let id = created.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let read = app
        .client
        .get(url(&format!("/v1/jobs/{id}")))
        .bearer_auth(robot)
        .send()
        .await
        .unwrap();
    assert_eq!(read.status(), 200);
    let listed = app
        .client
        .get(url("/v1/policies"))
        .bearer_auth(robot)
        .send()
        .await
        .unwrap();
    assert_eq!(listed.status(), 200);
    let cancel = app
        .client
        .post(url(&format!("/v1/jobs/{id}/cancel")))
        .bearer_auth(robot)
        .send()
        .await
        .unwrap();
    assert_eq!(cancel.status(), 403);
    // No worker runs in this app: the queued job is cancelled at once.
    let cancel = app
        .client
        .post(url(&format!("/v1/jobs/{id}/cancel")))
        .bearer_auth(engineer)
        .send()
        .await
        .unwrap();
    assert_eq!(cancel.status(), 202);
    let job: Value = cancel.json().await.unwrap();
    assert_eq!(job["state"], "cancelled");
    app.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_training_stopped_by_shutdown_checkpoints_and_resumes_in_the_next_process() {
    let temp = tempfile::tempdir().unwrap();
    let data_dir = temp.path().join("data");
    let dir = data_dir.clone();
    let app = spawn_app_with(move |c| c.data_dir = dir, None).await;
    let response = post_job(&app, &tiny_train(0.25)).await;
    assert_eq!(response.status(), 201);
    let id = response.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    app.wait_for_job(&id, Duration::from_secs(120), |j| {
        j["state"] == "running" && j["progress"]["env_steps"].as_u64().unwrap_or(0) > 0
    })
    .await;
    // SIGTERM, in effect: the worker stops claiming, the trainer checkpoints, the job goes back.
    app.stop().await;
    let dir = data_dir.clone();
    let app = spawn_app_with(move |c| c.data_dir = dir, None).await;
    let job = app
        .wait_for_job(&id, Duration::from_secs(240), |j| {
            j["state"] != "queued" && j["state"] != "running"
        })
        .await;
    assert_eq!(job["state"], "succeeded", "{job:#}");
    // The same attempt, resumed from its checkpoint in a second session.
    assert_eq!(job["attempts"], 1, "{job:#}");
    assert_eq!(job["result"]["sessions"], 2, "{job:#}");
    let events: Vec<SseEvent> = read_events(
        app.request(Method::GET, &format!("/v1/jobs/{id}/events"))
            .send()
            .await
            .unwrap(),
        Duration::from_secs(30),
    )
    .await;
    assert!(
        events
            .iter()
            .any(|e| e.event == "state" && e.data["data"]["released"] == true),
        "{events:?}"
    );
    app.stop().await;
}
