//! `POST /v1/plan` through the real app: the bundled building's floor from the in-process
//! knowledge service, its mental simulation, the roadmap, the classical follower (no policy has
//! been trained in a fresh data directory), and each kind of refusal.

use reqwest::Method;
use serde_json::{Value, json};

use crate::helpers::{TestApp, spawn_app};

pub(crate) async fn plan(app: &TestApp, body: &Value) -> (u16, Value) {
    app.post_json("/v1/plan", body).await
}

/// The centroid of a place's boundary, from the browsing API.
pub(crate) async fn centroid(app: &TestApp, place: &str) -> (f64, f64) {
    let r = app
        .request(Method::GET, &format!("/v1/places/{place}"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let v: Value = r.json().await.unwrap();
    let pts = v["boundary"].as_array().unwrap();
    let n = pts.len() as f64;
    let sx: f64 = pts.iter().map(|p| p[0].as_f64().unwrap()).sum();
    let sy: f64 = pts.iter().map(|p| p[1].as_f64().unwrap()).sum();
    (sx / n, sy / n)
}

/// A point the robot may stand on near `(x, y)`: the service's own nearest-free hint.
pub(crate) async fn free_near(app: &TestApp, (x, y): (f64, f64)) -> (f64, f64) {
    let (status, body) = plan(
        app,
        &json!({"robot": "R-001", "place": "F0", "start": {"x": x, "y": y}, "goal": {"x": x, "y": y}}),
    )
    .await;
    if status == 422 && body["error"]["details"]["nearest_free"].is_object() {
        let p = &body["error"]["details"]["nearest_free"];
        (p["x"].as_f64().unwrap(), p["y"].as_f64().unwrap())
    } else {
        (x, y)
    }
}

#[tokio::test]
async fn a_plan_across_rooms_is_validated_in_the_simulation_and_reported() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let goal = free_near(&app, centroid(&app, "F0-hall").await).await;
    let (status, body) = plan(
        &app,
        &json!({
            "robot": "R-001",
            "place": "F0",
            "start": {"x": start.0, "y": start.1, "yaw": 0.0},
            "goal": {"x": goal.0, "y": goal.1},
            "options": {"seed": 4}
        }),
    )
    .await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["controller"], "classical", "{body}");
    assert!(body["note"].as_str().unwrap().contains("no trained policy"));
    assert!(body["policy"].is_null());
    let waypoints = body["waypoints"].as_array().unwrap();
    assert!(waypoints.len() >= 2);
    let last = waypoints.last().unwrap();
    assert!((last["x"].as_f64().unwrap() - goal.0).abs() < 1e-6);
    assert!(!body["attempts"].as_array().unwrap().is_empty());
    // One leg, validated by the controller the robot has.
    assert_eq!(body["legs"].as_array().map(Vec::len), Some(1), "{body}");
    assert_eq!(body["legs"][0]["controller"], "classical");
    assert_eq!(body["attempts"][0]["handover_share"], 0.0, "{body}");
    assert_eq!(body["attempts"][0]["leg"], 0);
    assert!(body["distance_m"].as_f64().unwrap() > 0.0);
    assert!(body["simulated_time_s"].as_f64().unwrap() > 0.0);
    assert!(body["min_clearance_m"].as_f64().unwrap() > 0.0);
    // The same waypoints as a ROS 2 nav_msgs/Path in the map frame, from the start.
    assert_eq!(body["path"]["header"]["frame_id"], "map");
    let poses = body["path"]["poses"].as_array().unwrap();
    assert_eq!(poses.len(), waypoints.len() + 1);
    assert!((poses[0]["pose"]["position"]["x"].as_f64().unwrap() - start.0).abs() < 1e-9);
    let last_pose = &poses.last().unwrap()["pose"];
    assert!((last_pose["position"]["x"].as_f64().unwrap() - goal.0).abs() < 1e-6);
    let q = &last_pose["orientation"];
    let norm = q["z"].as_f64().unwrap().hypot(q["w"].as_f64().unwrap());
    assert!((norm - 1.0).abs() < 1e-9, "{q}");
    let trajectory = body["trajectory"].as_array().unwrap();
    let end = trajectory.last().unwrap();
    let d = (end["x"].as_f64().unwrap() - goal.0).hypot(end["y"].as_f64().unwrap() - goal.1);
    assert!(d < 0.5, "the simulated robot ended {d} m from the goal");

    // The same request again hits the caches and gives the same plan.
    let (status, again) = plan(
        &app,
        &json!({
            "robot": "R-001", "place": "F0",
            "start": {"x": start.0, "y": start.1, "yaw": 0.0},
            "goals": [{"x": goal.0, "y": goal.1}],
            "options": {"seed": 4}
        }),
    )
    .await;
    assert_eq!(status, 200);
    assert_eq!(again["waypoints"], body["waypoints"]);
}

#[tokio::test]
async fn impossible_plans_get_distinct_client_errors() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let ok_start = json!({"x": start.0, "y": start.1});
    let cases = [
        (
            json!({"robot": "no-such-robot", "place": "F0", "start": ok_start, "goal": ok_start}),
            404,
            "not_found",
        ),
        (
            json!({"robot": "R-001", "place": "no-such-place", "start": ok_start, "goal": ok_start}),
            404,
            "not_found",
        ),
        (
            json!({"robot": "R-001", "place": "F0", "start": ok_start}),
            400,
            "bad_request",
        ),
        (
            json!({"robot": "R-001", "place": "F0", "start": ok_start, "goal": {"x": 1.0e6, "y": 0.0}}),
            422,
            "goal_outside_map",
        ),
        (
            json!({"robot": "R-001", "place": "F0", "start": ok_start, "goal": ok_start, "policy": "nope"}),
            404,
            "not_found",
        ),
        (
            json!({"robot": "R-001", "place": "F0", "start": ok_start, "goal": ok_start, "options": {"max_attempts": 0}}),
            400,
            "invalid_input",
        ),
    ];
    for (body, want, code) in cases {
        let (status, answer) = plan(&app, &body).await;
        assert_eq!(status, want, "{body} -> {answer}");
        let text = answer.to_string();
        assert!(text.contains(code), "{body} -> {answer}");
        assert!(
            answer["error"]["message"]
                .as_str()
                .is_some_and(|m| !m.is_empty())
        );
    }
    // A goal inside a wall: 422 naming it, with the nearest free point.
    let (status, answer) = plan(
        &app,
        &json!({"robot": "R-001", "place": "F0", "start": ok_start, "goal": {"x": -2.275, "y": -8.075}}),
    )
    .await;
    assert_eq!(status, 422, "{answer}");
    assert_eq!(
        answer["error"]["details"]["reason"], "goal_in_obstacle",
        "{answer}"
    );
    assert!(answer["error"]["details"]["nearest_free"].is_object());
    // Malformed JSON and a wrong type are 4xx too.
    let r = app
        .request(Method::POST, "/v1/plan")
        .header("content-type", "application/json")
        .body("{\"robot\": ")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 400);
    let (status, _) = plan(
        &app,
        &json!({"robot": "R-001", "place": "F0", "start": {"x": "one", "y": 0}, "goal": ok_start}),
    )
    .await;
    assert!(status == 400 || status == 422, "{status}");
}

#[tokio::test]
async fn a_plan_asked_in_a_form_it_does_not_come_in_is_a_406_naming_the_forms() {
    let app = spawn_app().await;
    let body = json!({"robot": "R-001", "place": "F0", "start": {"x": 0.0, "y": 0.0}, "goal": {"x": 1.0, "y": 0.0}});
    for refused in [
        "text/html",
        "application/xml, image/*",
        "application/json;q=0",
    ] {
        let r = app
            .request(Method::POST, "/v1/plan")
            .header("accept", refused)
            .json(&body)
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 406, "{refused}");
        let e: Value = r.json().await.unwrap();
        let message = e["error"]["message"].as_str().unwrap();
        assert!(
            message.contains("application/json") && message.contains("application/x-mcap"),
            "{message}"
        );
    }
    // JSON, any application type, anything: not refused for the form.
    for accept in [
        "application/json",
        "application/*;q=0.5",
        "*/*",
        "text/html, */*;q=0.1",
    ] {
        let r = app
            .request(Method::POST, "/v1/plan")
            .header("accept", accept)
            .json(&body)
            .send()
            .await
            .unwrap();
        assert_ne!(r.status(), 406, "{accept}");
    }
    app.stop().await;
}

/// The `(x, y)` of a CDR-encoded `geometry_msgs/PoseStamped`: after the encapsulation header,
/// the stamp (8 bytes) and the frame (a length-prefixed string), aligned to 8.
fn pose_stamped_xy(data: &[u8]) -> (f64, f64) {
    let frame_len = u32::from_le_bytes(data[12..16].try_into().unwrap()) as usize;
    let mut at = 16 + frame_len;
    while !(at - 4).is_multiple_of(8) {
        at += 1;
    }
    let f = |i: usize| f64::from_le_bytes(data[i..i + 8].try_into().unwrap());
    (f(at), f(at + 8))
}

#[tokio::test]
async fn a_plan_accepting_mcap_gets_the_whole_rehearsal_as_a_ros_2_recording() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let goal = free_near(&app, centroid(&app, "F0-hall").await).await;
    let request = json!({
        "robot": "R-001", "place": "F0",
        "start": {"x": start.0, "y": start.1, "yaw": 0.0}, "goal": {"x": goal.0, "y": goal.1},
        "options": {"seed": 4, "trace": true}
    });
    let (status, answer) = plan(&app, &request).await;
    assert_eq!(status, 200, "{answer}");
    let r = app
        .request(Method::POST, "/v1/plan")
        .header("accept", "application/x-mcap")
        .json(&request)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], "application/x-mcap");
    let bytes = r.bytes().await.unwrap();

    let mut topics: std::collections::BTreeMap<String, Vec<Vec<u8>>> = Default::default();
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let message = message.unwrap();
        assert_eq!(message.channel.message_encoding, "cdr");
        let schema = message.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "ros2msg");
        topics
            .entry(message.channel.topic.clone())
            .or_default()
            .push(message.data.into_owned());
    }
    for topic in ["/map", "/plan", "/tf_static"] {
        assert_eq!(topics[topic].len(), 1, "{topic}");
    }
    // Every recorded step of every attempt, in the simulation's order.
    let poses: Vec<&Value> = answer["attempts"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|a| a["trace"]["poses"].as_array().unwrap())
        .collect();
    assert!(!poses.is_empty());
    for topic in ["/rehearsal/pose", "/tf", "/rehearsal/scan"] {
        assert_eq!(topics[topic].len(), poses.len(), "{topic}");
    }
    let attempts = answer["attempts"].as_array().unwrap().len();
    assert_eq!(topics["/rehearsal/attempt"].len(), attempts);
    assert_eq!(topics["/rehearsal/attempt_path"].len(), attempts);
    for (data, pose) in topics["/rehearsal/pose"].iter().zip(&poses) {
        let (x, y) = pose_stamped_xy(data);
        assert_eq!(x, pose["x"].as_f64().unwrap());
        assert_eq!(y, pose["y"].as_f64().unwrap());
    }
    app.stop().await;
}

#[tokio::test]
async fn plans_need_a_token() {
    let app = spawn_app().await;
    let r = app
        .client
        .post(format!("{}/v1/plan", app.address))
        .json(&json!({"robot": "R-001", "place": "F0", "start": {"x": 0, "y": 0}, "goal": {"x": 1, "y": 1}}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 401);
}

#[tokio::test]
async fn a_validate_job_runs_the_plan_executor_and_stores_its_report() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let goal = free_near(&app, centroid(&app, "F0-hall").await).await;
    let r = app
        .request(Method::POST, "/v1/jobs")
        .json(&json!({"kind": "validate", "payload": {
            "robot": "R-001", "place": "F0",
            "start": {"x": start.0, "y": start.1},
            "goal": {"x": goal.0, "y": goal.1},
            "options": {"seed": 4, "trajectory_stride": 0}
        }}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let job: Value = r.json().await.unwrap();
    let id = job["id"].as_str().unwrap().to_owned();
    let done = app.finished_job(&id).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    assert_eq!(done["result"]["controller"], "classical");
    assert!(done["result"]["waypoints"].as_array().unwrap().len() >= 2);

    // A validate job whose goal is in a wall fails, naming why, and is not retried.
    let r = app
        .request(Method::POST, "/v1/jobs")
        .json(&json!({"kind": "validate", "payload": {
            "robot": "R-001", "place": "F0",
            "start": {"x": start.0, "y": start.1}, "goal": {"x": -2.275, "y": -8.075}
        }}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let id = r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let failed = app.finished_job(&id).await;
    assert_eq!(failed["state"], "failed", "{failed}");
    assert!(failed.to_string().contains("obstacle"), "{failed}");
    // Refused at submission with the plan endpoint's bounds, naming the field; an unknown
    // policy is 404 as for every job kind.
    let too_many: Vec<Value> = (0..1001)
        .map(|_| json!({"x": goal.0, "y": goal.1}))
        .collect();
    for (payload, status, field) in [
        (json!({"goals": too_many}), 422, "payload.goals"),
        (
            json!({"goal": {"x": goal.0, "y": goal.1}, "options": {"max_attempts": 0}}),
            422,
            "payload.options.max_attempts",
        ),
        (
            json!({"goal": {"x": goal.0, "y": goal.1}, "options": {"samples": 100_000_000}}),
            422,
            "payload.options.samples",
        ),
        (
            json!({"goal": {"x": goal.0, "y": goal.1}, "policy": "no-such-policy"}),
            404,
            "payload.policy",
        ),
    ] {
        let mut payload = payload;
        payload["robot"] = json!("R-001");
        payload["place"] = json!("F0");
        payload["start"] = json!({"x": start.0, "y": start.1});
        let r = app
            .request(Method::POST, "/v1/jobs")
            .json(&json!({"kind": "validate", "payload": payload}))
            .send()
            .await
            .unwrap();
        let code = r.status().as_u16();
        let body: Value = r.json().await.unwrap();
        assert_eq!(code, status, "{field}: {body}");
        assert!(
            body["error"]["message"].as_str().unwrap().contains(field),
            "{body}"
        );
    }
}

/// The floor's database, world and roadmap are cached between plans, and a write to the
/// knowledge makes the next plan see it: an object reported at the goal blocks it.
#[tokio::test]
async fn a_plan_after_a_write_sees_the_new_knowledge() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let goal = free_near(&app, centroid(&app, "F0-hall").await).await;
    let request = json!({
        "robot": "R-001", "place": "F0",
        "start": {"x": start.0, "y": start.1, "yaw": 0.0},
        "goal": {"x": goal.0, "y": goal.1},
        "options": {"seed": 2}
    });
    for _ in 0..2 {
        let (status, body) = plan(&app, &request).await;
        assert_eq!(status, 200, "{body}");
    }
    app.report_box("F0-hall", "crate-at-the-goal", goal, 0.8)
        .await;
    let (status, body) = plan(&app, &request).await;
    assert_eq!(status, 422, "the goal is now inside the crate: {body}");
    assert!(
        body["error"]["message"].as_str().unwrap().contains("goal"),
        "{body}"
    );
    app.stop().await;
}

/// Loaded policies are kept between plans, and a policy exported again under the same id is
/// the one the next plan drives with.
#[tokio::test]
async fn a_policy_exported_again_replaces_the_loaded_one() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let goal = free_near(&app, centroid(&app, "F0-hall").await).await;
    let dir = app.data_dir.join("policies").join("steer");
    std::fs::create_dir_all(&dir).unwrap();
    let request = json!({
        "robot": "R-001", "place": "F0", "policy": "steer",
        "start": {"x": start.0, "y": start.1, "yaw": 0.0},
        "goal": {"x": goal.0, "y": goal.1},
        "options": {"seed": 3, "trajectory_stride": 0, "controller": "hybrid"}
    });
    for steps in [111, 222] {
        learning::policy::write_goal_seeking_policy(
            &dir,
            23,
            json!({"counters": {"env_steps": steps}}),
        )
        .unwrap();
        for _ in 0..2 {
            let (status, body) = plan(&app, &request).await;
            assert_eq!(status, 200, "{body}");
            assert_eq!(body["controller"], "policy", "{body}");
            let description = body["controller_description"].as_str().unwrap();
            assert!(
                description.contains(&format!("{steps} training steps"))
                    && description.contains("classical follower taking over"),
                "{description}"
            );
            // Each attempt says how much of its drive was the follower's handover.
            for a in body["attempts"].as_array().unwrap() {
                let share = a["handover_share"].as_f64().unwrap();
                assert!((0.0..=1.0).contains(&share), "{a}");
            }
        }
        // Another modification time for the next export, whatever the file system's clock.
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    // The policy on the smoothed path, asked for by name.
    let mut on_path = request.clone();
    on_path["options"]["controller"] = json!("hybrid_path");
    let (status, body) = plan(&app, &on_path).await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["controller"], "policy", "{body}");
    assert_eq!(
        body["controller_choice"]["controller"], "hybrid_path",
        "{body}"
    );
    let description = body["controller_description"].as_str().unwrap();
    assert!(
        description.contains("m ahead on the smoothed roadmap path")
            && description.contains("Regulated Pure Pursuit"),
        "{description}"
    );
    app.stop().await;
}

/// Installs `seeker`, a goal-seeking policy for the sample robot's 23 beams.
fn install_seeker(app: &TestApp) {
    let dir = app.data_dir.join("policies").join("seeker");
    std::fs::create_dir_all(&dir).unwrap();
    learning::policy::write_goal_seeking_policy(&dir, 23, json!({})).unwrap();
}

/// Asks `request` (with `options.roadmap: policy`) until its policy-aware roadmap is built
/// (409 meanwhile; three minutes at most) and returns the first plan answered on it.
async fn wait_for_policy_roadmap(app: &TestApp, request: &Value) -> Value {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(180);
    loop {
        let (status, body) = plan(app, request).await;
        if status == 200 {
            return body;
        }
        assert_eq!(status, 409, "{body}");
        assert!(std::time::Instant::now() < deadline, "never built: {body}");
        tokio::time::sleep(std::time::Duration::from_millis(300)).await;
    }
}

/// A policy-aware roadmap (PRM-RL) is built by a durable `roadmap` job, enqueued the first time
/// a plan with a policy asks for a floor state that has none: `policy` answers 409 naming the
/// job until it is stored, `auto` plans on the geometric roadmap meanwhile, and both plan on it
/// once built; the report says which roadmap. A floor that changes is a new state: its old
/// roadmap is never served for it, and a new one is built. Jobs for unknown policies or floors
/// are refused at submission.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_policy_aware_roadmap_is_built_by_a_job_and_then_used() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let goal = free_near(&app, centroid(&app, "F0-hall").await).await;
    install_seeker(&app);
    let request = |roadmap: &str| {
        json!({
            "robot": "R-001", "place": "F0", "policy": "seeker",
            "start": {"x": start.0, "y": start.1, "yaw": 0.0},
            "goal": {"x": goal.0, "y": goal.1},
            "options": {"seed": 3, "trajectory_stride": 0, "roadmap": roadmap, "controller": "hybrid"}
        })
    };
    let roadmap_jobs = || async {
        app.request(Method::GET, "/v1/jobs?kind=roadmap&limit=50")
            .send()
            .await
            .unwrap()
            .json::<Vec<Value>>()
            .await
            .unwrap()
    };
    // Geometric only: no job is started by it.
    let (status, body) = plan(&app, &request("geometric")).await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["roadmap"]["kind"], "geometric", "{body}");
    assert_eq!(body["legs"][0]["roadmap"], "geometric", "{body}");
    assert!(roadmap_jobs().await.is_empty());

    // The first `policy` request enqueues the job and is refused until it has run.
    let (status, body) = plan(&app, &request("policy")).await;
    assert_eq!(status, 409, "{body}");
    let message = body["error"]["message"].as_str().unwrap().to_owned();
    assert!(message.contains("`roadmap` job"), "{body}");
    // `auto` meanwhile plans on the geometric roadmap (or on the policy-aware one if done),
    // and does not enqueue a second job.
    let (status, body) = plan(&app, &request("auto")).await;
    assert_eq!(status, 200, "{body}");
    let body = wait_for_policy_roadmap(&app, &request("policy")).await;
    assert_eq!(body["roadmap"]["kind"], "policy", "{body}");
    assert_eq!(body["legs"][0]["roadmap"], "policy", "{body}");
    assert_eq!(body["legs"][0]["controller"], "policy", "{body}");
    let (status, body) = plan(&app, &request("auto")).await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["roadmap"]["kind"], "policy", "{body}");
    let jobs = roadmap_jobs().await;
    assert_eq!(jobs.len(), 1, "one job for one floor state: {jobs:#?}");
    assert_eq!(jobs[0]["state"], "succeeded", "{:#}", jobs[0]);
    let result = &jobs[0]["result"];
    assert!(
        result["edge_success_rate"].as_f64().unwrap() > 0.0,
        "{result}"
    );
    assert!(result["edge_directions"].as_u64().unwrap() >= 2, "{result}");
    // The job drove the controller trial too: `auto` now validates with what it measured
    // best on this floor state, and says so with the trial's figures.
    let picked = &result["controller"];
    assert!(
        picked["why"]
            .as_str()
            .unwrap()
            .starts_with("auto: measured on this floor state"),
        "{result}"
    );
    let mut auto = request("auto");
    auto["options"]["controller"] = json!("auto");
    let (status, body) = plan(&app, &auto).await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["controller_choice"], *picked, "{body}");
    let kind = if picked["controller"].as_str().unwrap().starts_with("hybrid") {
        "policy"
    } else {
        "classical"
    };
    assert_eq!(body["controller"], kind, "{body}");
    // Asked for by name, a classical controller drives whatever was measured.
    let mut mppi = request("auto");
    mppi["options"]["controller"] = json!("mppi");
    let (status, body) = plan(&app, &mppi).await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["controller_choice"]["controller"], "mppi", "{body}");
    assert_eq!(body["controller"], "classical", "{body}");
    // A controller that does not exist is a client error naming it.
    let mut bad = request("auto");
    bad["options"]["controller"] = json!("teleport");
    let (status, body) = plan(&app, &bad).await;
    assert!(status == 400 || status == 422, "{status} {body}");
    assert!(body.to_string().contains("teleport"), "{body}");
    // Persisted: a file in the store beside the policies.
    let stored = app.data_dir.join("policy-roadmaps");
    assert_eq!(std::fs::read_dir(&stored).unwrap().count(), 1);

    // The floor changes (an object is reported): the stored roadmap is for the old state and
    // is not served; a second job builds the new state's.
    app.report_box(
        "F0",
        "crate-1",
        free_near(&app, centroid(&app, "F0-storage").await).await,
        0.4,
    )
    .await;
    let (status, body) = plan(&app, &request("policy")).await;
    assert_eq!(status, 409, "the old state's roadmap was served: {body}");
    let body = wait_for_policy_roadmap(&app, &request("policy")).await;
    assert_eq!(body["roadmap"]["kind"], "policy", "{body}");
    assert_eq!(roadmap_jobs().await.len(), 2);
    assert_eq!(std::fs::read_dir(&stored).unwrap().count(), 2);

    // Submitted by hand: unknown policies and floors are refused at once.
    for (payload, status, word) in [
        (
            json!({"policy": "nope", "place": "F0", "robot": "R-001"}),
            404,
            "nope",
        ),
        (
            json!({"policy": "seeker", "place": "F9", "robot": "R-001"}),
            404,
            "F9",
        ),
    ] {
        let r = app
            .request(Method::POST, "/v1/jobs")
            .json(&json!({"kind": "roadmap", "payload": payload}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status().as_u16(), status);
        let body: Value = r.json().await.unwrap();
        assert!(body.to_string().contains(word), "{body}");
    }

    // A choice that does not exist is named.
    let (status, body) = plan(&app, &request("fastest")).await;
    assert!(status == 400 || status == 422, "{status} {body}");
    assert!(
        body.to_string().contains("roadmap") || body.to_string().contains("fastest"),
        "{body}"
    );
    app.stop().await;
}

/// Sets the `tosm:frameId` of floor F0's map over SPARQL, as an engineer would.
async fn set_map_frame(app: &TestApp, frame: &str) {
    let update = format!(
        r#"PREFIX tosm: <https://mentalsim.dev/ontology/tosm#>
        DELETE {{ GRAPH ?g {{ ?m tosm:frameId ?old }} }}
        INSERT {{ GRAPH ?g {{ ?m tosm:frameId "{frame}" }} }}
        WHERE {{ GRAPH ?g {{ ?f tosm:identifier "F0" ; tosm:hasMetricMap ?m }}
                 OPTIONAL {{ GRAPH ?g {{ ?m tosm:frameId ?old }} }} }}"#
    );
    let updated = app
        .request(Method::POST, "/sparql")
        .header("content-type", "application/sparql-update")
        .body(update)
        .send()
        .await
        .unwrap();
    assert_eq!(updated.status(), 204, "{}", updated.text().await.unwrap());
}

#[tokio::test]
async fn the_map_frame_stated_in_the_graph_names_every_pose_of_the_floor() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let goal = free_near(&app, centroid(&app, "F0-hall").await).await;
    let request = json!({
        "robot": "R-001", "place": "F0",
        "start": {"x": start.0, "y": start.1}, "goal": {"x": goal.0, "y": goal.1}
    });
    set_map_frame(&app, "level_0/map").await;
    let (status, body) = plan(&app, &request).await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["path"]["header"]["frame_id"], "level_0/map");
    assert!(
        body["path"]["poses"]
            .as_array()
            .unwrap()
            .iter()
            .all(|p| p["header"]["frame_id"] == "level_0/map"),
        "{body}"
    );
    let graph: Value = app
        .request(Method::GET, "/v1/places/F0/route-graph.geojson?robot=R-001")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let nodes: Vec<&Value> = graph["features"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["geometry"]["type"] == "Point")
        .collect();
    assert!(!nodes.is_empty());
    assert!(
        nodes
            .iter()
            .all(|n| n["properties"]["frame"] == "level_0/map")
    );

    // A frame that is no ROS name is the engineer's mistake, named.
    set_map_frame(&app, "2nd floor").await;
    let (status, body) = plan(&app, &request).await;
    assert_eq!(status, 422, "{body}");
    let message = body["error"]["message"].as_str().unwrap();
    assert!(message.contains("frameId"), "{message}");
}

#[tokio::test]
async fn plans_rehearse_among_people_and_say_how_close_they_came() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let goal = free_near(&app, centroid(&app, "F0-hall").await).await;
    let ask = |people: Value| {
        json!({
            "robot": "R-001",
            "place": "F0",
            "start": {"x": start.0, "y": start.1, "yaw": 0.0},
            "goal": {"x": goal.0, "y": goal.1},
            "options": {"seed": 4, "people": people}
        })
    };
    // A density: people drawn afresh per attempt, the closest approach in every attempt.
    let (status, body) = plan(&app, &ask(json!(1.0))).await;
    assert!(status == 200 || status == 409, "{body}");
    let (report, attempts) = if status == 200 {
        (
            &body["people"],
            body["attempts"].as_array().unwrap().clone(),
        )
    } else {
        (
            &Value::Null,
            body["error"]["details"]["attempts"]
                .as_array()
                .unwrap()
                .clone(),
        )
    };
    for a in &attempts {
        assert!(a["min_person_clearance_m"].is_number(), "{a}");
    }
    if status == 200 {
        assert_eq!(report["source"], "density", "{body}");
        assert!(report["people"].as_u64().unwrap() >= 1, "{body}");
        assert_eq!(
            report["attempts"].as_u64(),
            Some(attempts.len() as u64),
            "{body}"
        );
        assert!(report["min_person_clearance_m"].as_f64().unwrap() > 0.0);
    }
    // `none`: the empty building, nothing about people in the answer.
    let (status, body) = plan(&app, &ask(json!("none"))).await;
    assert_eq!(status, 200, "{body}");
    assert!(body.get("people").is_none(), "{body}");
    assert!(body["attempts"][0].get("min_person_clearance_m").is_none());
    // `auto` (the default): the people the bundled building's knowledge expects.
    let (status, body) = plan(&app, &ask(json!("auto"))).await;
    let people = if status == 200 {
        body["people"].clone()
    } else {
        Value::Null
    };
    assert!(status == 200 || status == 409, "{body}");
    if status == 200 {
        assert_eq!(people["source"], "knowledge", "{body}");
        assert!(people["people"].as_u64().unwrap() >= 1, "{body}");
    }
    // At noon the bundled building's knowledge expects more people than over the whole day.
    let with = |options: Value| {
        let mut request = ask(json!("auto"));
        request["options"] = options;
        request
    };
    let all_day = people["people"].as_u64();
    let (status, body) = plan(&app, &with(json!({"seed": 4, "people_hour": 12}))).await;
    assert!(status == 200 || status == 409, "{body}");
    if status == 200 {
        let noon = body["people"]["people"].as_u64().unwrap();
        assert!(
            all_day.is_none_or(|n| noon > n),
            "{noon} at noon vs {all_day:?}"
        );
    }
    // The validated plan driven again among fresh draws: each reached or named as failed.
    let (status, body) = plan(
        &app,
        &with(json!({"seed": 4, "people": 1.0, "people_draws": 3})),
    )
    .await;
    assert!(status == 200 || status == 409, "{body}");
    if status == 200 {
        let draws = &body["people"]["draws"];
        assert_eq!(draws["draws"], 3, "{body}");
        let reached = draws["reached"].as_u64().unwrap();
        let failures = draws["failures"].as_array().unwrap();
        assert_eq!(reached + failures.len() as u64, 3, "{body}");
        assert!(
            draws["min_person_clearance_m"].as_f64().unwrap() > -0.05,
            "{body}"
        );
    }
    // Without people there is nothing to draw, and no `people` in the answer.
    let (status, body) = plan(
        &app,
        &with(json!({"seed": 4, "people": "none", "people_draws": 3})),
    )
    .await;
    assert_eq!(status, 200, "{body}");
    assert!(body.get("people").is_none(), "{body}");
    // Nonsense is refused, naming the option.
    for bad in [json!("lots"), json!(-1), json!(99), json!(true)] {
        let (status, body) = plan(&app, &ask(bad.clone())).await;
        assert!(status == 400 || status == 422, "{bad} -> {status} {body}");
        assert!(body.to_string().contains("people"), "{bad} -> {body}");
    }
    for (bad, field) in [
        (json!({"people_hour": 24}), "people_hour"),
        (json!({"people_hour": -1}), "people_hour"),
        (json!({"people_draws": 21}), "people_draws"),
        (json!({"people_draws": "many"}), "people_draws"),
    ] {
        let (status, body) = plan(&app, &with(bad.clone())).await;
        assert!(status == 400 || status == 422, "{bad} -> {status} {body}");
        assert!(body.to_string().contains(field), "{bad} -> {body}");
    }
}

/// A `validate` job and `POST /v1/plan` are one use case (the planner): for the same request
/// — the knowledge's people at an hour, a policy and its policy-aware roadmap — they answer
/// the same plan, attempt for attempt.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_validate_job_answers_what_the_plan_endpoint_answers() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let goal = free_near(&app, centroid(&app, "F0-hall").await).await;
    install_seeker(&app);
    let request = |roadmap: &str| {
        json!({
            "robot": "R-001", "place": "F0", "policy": "seeker",
            "start": {"x": start.0, "y": start.1, "yaw": 0.0},
            "goal": {"x": goal.0, "y": goal.1},
            "options": {"seed": 5, "trajectory_stride": 0, "roadmap": roadmap,
                        "people": "auto", "people_hour": 12, "controller": "hybrid"}
        })
    };
    // The policy-aware roadmap first: both must find it.
    wait_for_policy_roadmap(&app, &request("policy")).await;
    let (status, mut answered) = plan(&app, &request("auto")).await;
    assert_eq!(status, 200, "{answered}");
    assert_eq!(answered["roadmap"]["kind"], "policy", "{answered}");
    assert_eq!(answered["people"]["source"], "knowledge", "{answered}");
    assert!(
        answered["people"]["people"].as_u64().unwrap() > 0,
        "{answered}"
    );

    let r = app
        .request(Method::POST, "/v1/jobs")
        .json(&json!({"kind": "validate", "payload": request("auto")}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let id = r.json::<Value>().await.unwrap()["id"]
        .as_str()
        .unwrap()
        .to_owned();
    let done = app.finished_job(&id).await;
    assert_eq!(done["state"], "succeeded", "{done}");
    let mut validated = done["result"].clone();
    // A job checks the plan against the fleet but never commits it (a rehearsal, not an
    // order): the plan endpoint's answer is committed.
    assert_eq!(answered["schedule"]["committed"], true, "{answered}");
    assert_eq!(validated["schedule"]["committed"], false, "{validated}");
    // Only the wall-clock time, the roadmap cache's state and the schedule (its id and times:
    // the path's stamps) may differ.
    for v in [&mut answered, &mut validated] {
        v.as_object_mut().unwrap().remove("service_ms");
        v.as_object_mut().unwrap().remove("schedule");
        v["roadmap"].as_object_mut().unwrap().remove("cached");
        for pose in v["path"]["poses"].as_array_mut().unwrap() {
            pose["header"].as_object_mut().unwrap().remove("stamp");
        }
    }
    assert_eq!(validated, answered);
}

/// Both bundled robot models plan the same route over HTTP, each in its own mental simulation:
/// the TIAGo-like base (1.0 m/s, 0.5 m/s², round) drives it with its own limits, so its
/// rehearsal is not the paper's robot's.
#[tokio::test]
async fn each_bundled_robot_model_plans_with_its_own_limits() {
    let app = spawn_app().await;
    let start = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let goal = free_near(&app, centroid(&app, "F0-hall").await).await;
    let ask = |robot: &str| {
        json!({
            "robot": robot,
            "place": "F0",
            "start": {"x": start.0, "y": start.1, "yaw": 0.0},
            "goal": {"x": goal.0, "y": goal.1},
            "options": {"seed": 4, "people": "none", "controller": "rpp", "commit": false}
        })
    };
    let (status, paper) = plan(&app, &ask("R-001")).await;
    assert_eq!(status, 200, "{paper}");
    let (status, tiago) = plan(&app, &ask("TB-001")).await;
    assert_eq!(status, 200, "{tiago}");
    assert!(
        tiago["robot"].as_str().unwrap().ends_with("/tiago-base"),
        "{tiago}"
    );
    // RPP is scaled to each robot's top speed.
    let described = |b: &Value| b["controller_description"].as_str().unwrap().to_owned();
    assert!(
        described(&paper).contains("up to 0.8 m/s"),
        "{}",
        described(&paper)
    );
    assert!(
        described(&tiago).contains("up to 1 m/s"),
        "{}",
        described(&tiago)
    );
    let (a, b) = (
        paper["simulated_time_s"].as_f64().unwrap(),
        tiago["simulated_time_s"].as_f64().unwrap(),
    );
    assert!(a > 0.0 && b > 0.0 && (a - b).abs() > 1e-6, "{a} {b}");
    app.stop().await;
}
