//! Plan revisions through the real service: `GET /v1/plans/{id}` tags a plan with its
//! revision (`ETag`, `If-None-Match`, 304, a long poll with `wait_s`), a revision made by
//! another process sharing the job database reaches a robot waiting on its plan, and progress
//! reports acknowledge the revisions they were sent and no others; and the service's own
//! idle-time improver revises a plan that waits for one cancelled meanwhile.

use std::time::{Duration, Instant};

use reqwest::Method;
use serde_json::{Value, json};

use crate::fleet::{FIRST_ROBOT, SECOND_ROBOT, fleet_app, now_ms, route, traffic};
use crate::helpers::TestApp;
use crate::plan::{centroid, free_near, plan};

/// `GET /v1/plans/{id}` as the first robot, with `If-None-Match` when given: status, `ETag`
/// and body (`Null` for a 304).
async fn get_plan(
    app: &TestApp,
    id: &str,
    if_none_match: Option<&str>,
    query: &str,
) -> (u16, String, Value) {
    get_plan_as(app, FIRST_ROBOT, id, if_none_match, query).await
}

/// [`get_plan`] as the robot of `token`.
async fn get_plan_as(
    app: &TestApp,
    token: &str,
    id: &str,
    if_none_match: Option<&str>,
    query: &str,
) -> (u16, String, Value) {
    let mut request = app
        .client
        .get(format!("{}/v1/plans/{id}{query}", app.address))
        .bearer_auth(token);
    if let Some(tag) = if_none_match {
        request = request.header("if-none-match", tag);
    }
    let r = request.send().await.unwrap();
    let status = r.status().as_u16();
    let etag = r
        .headers()
        .get("etag")
        .map(|v| v.to_str().unwrap().to_owned())
        .unwrap_or_default();
    let body = r.text().await.unwrap();
    let body = if body.is_empty() {
        Value::Null
    } else {
        serde_json::from_str(&body).unwrap()
    };
    (status, etag, body)
}

/// The robot of `token` long-polling plan `id` past revision `tag` (up to 20 s), in a task of
/// its own: the status, when the answer came, and its body.
fn watch(
    app: &TestApp,
    token: &str,
    id: &str,
    tag: &str,
) -> tokio::task::JoinHandle<(u16, Instant, Option<Value>)> {
    let request = app
        .client
        .get(format!("{}/v1/plans/{id}?wait_s=20", app.address))
        .bearer_auth(token)
        .header("if-none-match", tag);
    tokio::spawn(async move {
        let r = request.send().await.unwrap();
        (
            r.status().as_u16(),
            Instant::now(),
            r.json::<Value>().await.ok(),
        )
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_revision_reaches_the_robot_waiting_on_its_plan_and_is_acknowledged() {
    let shared = tempfile::tempdir().unwrap();
    let url = format!("sqlite://{}", shared.path().join("jobs.db").display());
    let app = fleet_app(Some(url.clone())).await;
    let from = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let to = free_near(&app, centroid(&app, "F0-hall").await).await;
    // Told to set off in 30 s: revisable until then, less its tolerance and the notice.
    let (status, answer) = plan(
        &app,
        &route("R-001", from, to, now_ms() + 30_000, json!({})),
    )
    .await;
    assert_eq!(status, 200, "{answer}");
    let id = answer["schedule"]["plan_id"].as_str().unwrap().to_owned();

    let (status, tag, first) = get_plan(&app, &id, None, "").await;
    assert_eq!(status, 200, "{first}");
    assert_eq!(first["plan"]["revision"], 1, "{first}");
    assert_eq!(first["acknowledged_revision"], 1, "{first}");
    assert_eq!(first["set_off"], false, "{first}");
    assert!(tag.starts_with("W/\"1-"), "{tag}");
    assert!(
        first["revisable_until_unix_ms"].as_i64().unwrap()
            < first["departs_unix_ms"].as_i64().unwrap()
    );
    let (status, again, body) = get_plan(&app, &id, Some(&tag), "").await;
    assert_eq!(
        (status, again.as_str(), body),
        (304, tag.as_str(), Value::Null)
    );

    // Bad input, each named.
    let foreign = format!("W/\"1-{}\"", "0".repeat(16));
    for (tag, status, says) in [
        (foreign.as_str(), 422, "another plan"),
        ("\"yesterday\"", 422, "not a plan's entity tag"),
        (&tag.replacen("W/\"1-", "W/\"7-", 1), 409, "never sent"),
    ] {
        let (got, _, body) = get_plan(&app, &id, Some(tag), "").await;
        assert_eq!(got, status, "{tag}: {body}");
        assert!(
            body["error"]["message"].as_str().unwrap().contains(says),
            "{body}"
        );
        assert_eq!(body["error"]["field"], "If-None-Match", "{body}");
    }
    let (got, _, body) = get_plan(&app, &id, None, "?wait_s=99").await;
    assert_eq!(
        (got, &body["error"]["field"]),
        (422, &json!("wait_s")),
        "{body}"
    );
    let (got, _, _) = get_plan(&app, "plan-nope", None, "").await;
    assert_eq!(got, 404);

    // The robot waits on its plan; another process revises it (the same route 5 s later).
    let waiting = watch(&app, FIRST_ROBOT, &id, &tag);
    tokio::time::sleep(Duration::from_millis(300)).await;
    let db = queue::JobDatabase::connect(&url).await.unwrap();
    let elsewhere = traffic::Schedule::open(&db).await.unwrap();
    let planned = elsewhere.plan(&id).await.unwrap().unwrap();
    let mut later = planned.itinerary.clone();
    later.start_unix_ms += 5_000;
    later.expires_unix_ms += 5_000;
    let version = elsewhere.version(&later.floor).await.unwrap();
    let (_, revised) = elsewhere
        .revise(vec![later.clone()], version)
        .await
        .unwrap();
    let revised_at = Instant::now();
    let (status, answered_at, body) = waiting.await.unwrap();
    let body = body.unwrap();
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["plan"]["revision"], 2, "{body}");
    assert_eq!(body["plan"]["start_unix_ms"], later.start_unix_ms, "{body}");
    eprintln!(
        "the revision reached the waiting robot {:.0} ms after it was committed (another process)",
        answered_at.duration_since(revised_at).as_secs_f64() * 1000.0
    );
    assert_eq!(revised[0].revision, 2);
    let floor = traffic(&app, FIRST_ROBOT).await;
    let shown = floor["plans"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["plan_id"] == id.as_str())
        .unwrap()
        .clone();
    assert_eq!(shown["revision"], 2, "{floor}");

    // Progress acknowledges what it was sent, and nothing newer.
    let progress = |revision: u32| {
        app.request(Method::POST, &format!("/v1/plans/{id}/progress"))
            .bearer_auth(FIRST_ROBOT)
            .json(&json!({"x": from.0, "y": from.1, "revision": revision}))
            .send()
    };
    let r = progress(3).await.unwrap();
    assert_eq!(r.status(), 409);
    let body: Value = r.json().await.unwrap();
    assert_eq!(body["error"]["field"], "revision", "{body}");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("never sent"),
        "{body}"
    );
    let r = progress(2).await.unwrap();
    assert_eq!(r.status(), 200);
    // The answer: the plan as now scheduled, and how far the robot may go (all the way alone).
    let answer: Value = r.json().await.unwrap();
    assert_eq!(
        (&answer["plan_id"], &answer["revision"]),
        (&json!(id), &json!(2)),
        "{answer}"
    );
    assert_eq!(answer["passes_after"], json!([]), "{answer}");
    assert!(answer["may_go_until_t_s"].is_null(), "{answer}");
    let (_, tag2, status) = get_plan(&app, &id, None, "").await;
    assert_eq!(status["acknowledged_revision"], 2, "{status}");
    assert!(tag2.starts_with("W/\"2-"), "{tag2}");
    assert_eq!(
        status["passes_after"],
        json!([]),
        "alone on the floor: {status}"
    );
    assert!(status["may_go_until_t_s"].is_null(), "{status}");

    // Another robot's plan (committed by the other process) through where the first one
    // starts, after it left: it passes after the first robot there, and may go only up to
    // there until the first one reports it has passed.
    let mut crossing = later.clone();
    crossing.plan_id = "plan-crossing".to_owned();
    crossing.robot = "https://example.org/robots/visitor".to_owned();
    crossing.start_unix_ms = later.start_unix_ms + 20_000;
    crossing.expires_unix_ms = later.expires_unix_ms + 20_000;
    let version = elsewhere.version(&later.floor).await.unwrap();
    elsewhere.commit(crossing, version).await.unwrap();
    let id2 = "plan-crossing".to_owned();
    let (_, _, follows) = get_plan(&app, &id2, None, "").await;
    let passes = follows["passes_after"].as_array().unwrap();
    assert!(!passes.is_empty(), "{follows}");
    assert!(
        passes
            .iter()
            .all(|p| p["plan_id"] == id.as_str() && p["passed"] == false),
        "{follows}"
    );
    let until = follows["may_go_until_t_s"].as_f64().unwrap();
    assert!(
        (until - passes[0]["t_s"].as_f64().unwrap()).abs() < 1e-9,
        "{follows}"
    );
    // The first robot reports it is at its goal, on time: the second may go all the way.
    let end = shown["trajectory"].as_array().unwrap().last().unwrap()["t_s"]
        .as_f64()
        .unwrap();
    #[allow(clippy::cast_possible_truncation)] // reason: seconds of a test plan
    let arrived_ms = later.start_unix_ms + (end * 1000.0) as i64;
    let r = app
        .request(Method::POST, &format!("/v1/plans/{id}/progress"))
        .bearer_auth(FIRST_ROBOT)
        .json(&json!({"x": to.0, "y": to.1, "time_ms": arrived_ms, "revision": 2}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let (_, _, released) = get_plan(&app, &id2, None, "").await;
    let passes = released["passes_after"].as_array().unwrap();
    assert!(passes.iter().all(|p| p["passed"] == true), "{released}");
    assert!(released["may_go_until_t_s"].is_null(), "{released}");
    app.stop().await;
}

/// The service's idle-time improver (`fleet_improve_every_s`, 1 s by default): the second
/// robot's plan waits at its start for the first one, held at the goal they share; once the
/// first plan is cancelled, the improver fits the second again, drives it, and revises it
/// without the wait; the robot long-polling its plan sees revision 2 and acknowledges it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_improver_revises_a_plan_that_waits_for_one_cancelled() {
    let app = fleet_app(None).await;
    let from = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let to = free_near(&app, centroid(&app, "F0-hall").await).await;
    // The first robot sets off at once: it is never revised. It is held at the goal for 90 s
    // (the default is 30), so that the second, setting off 28 s later, waits for it there
    // however long the drives take (within the second's 120 s of waiting).
    let (status, first) = plan(
        &app,
        &route("R-001", from, to, now_ms() + 2_000, json!({"hold_s": 90})),
    )
    .await;
    assert_eq!(status, 200, "{first}");
    let first_id = first["schedule"]["plan_id"].as_str().unwrap().to_owned();
    let start = now_ms() + 30_000;
    let (status, second) = plan(&app, &route("R-002", from, to, start, json!({}))).await;
    assert_eq!(status, 200, "{second}");
    let waits = second["schedule"]["waits"].as_array().unwrap();
    assert!(
        !waits.is_empty(),
        "the second robot waits for the first at the goal: {second}"
    );
    let id = second["schedule"]["plan_id"].as_str().unwrap().to_owned();
    let (status, tag, before) = get_plan_as(&app, SECOND_ROBOT, &id, None, "").await;
    assert_eq!(status, 200, "{before}");
    // Nothing to gain while the first plan stands: still revision 1 a round later.
    tokio::time::sleep(Duration::from_millis(1_500)).await;
    let (status, _, body) = get_plan_as(&app, SECOND_ROBOT, &id, Some(&tag), "").await;
    assert_eq!(status, 304, "revised with nothing to gain: {body}");

    let watching = watch(&app, SECOND_ROBOT, &id, &tag);
    let r = app
        .client
        .delete(format!("{}/v1/plans/{first_id}", app.address))
        .bearer_auth(FIRST_ROBOT)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let cancelled_at = Instant::now();
    let (status, answered_at, after) = watching.await.unwrap();
    let after = after.unwrap();
    assert_eq!(status, 200, "{after}");
    assert_eq!(after["plan"]["revision"], 2, "{after}");
    eprintln!(
        "revised {:.0} ms after the first plan was cancelled",
        answered_at.duration_since(cancelled_at).as_secs_f64() * 1000.0
    );
    // The same start, no longer waiting: it leaves no later and arrives earlier.
    assert_eq!(after["plan"]["start_unix_ms"], start, "{after}");
    let (b, a) = (&before["departs_unix_ms"], &after["departs_unix_ms"]);
    assert!(a.as_i64() <= b.as_i64(), "departs {a} after {b}");
    let end = |s: &Value| {
        s["plan"]["trajectory"].as_array().unwrap().last().unwrap()["t_s"]
            .as_f64()
            .unwrap()
    };
    assert!(end(&after) + 0.5 < end(&before), "{after}");
    assert_eq!(after["set_off"], false, "{after}");
    // The robot acknowledges the revision with its next progress report.
    let r = app
        .request(Method::POST, &format!("/v1/plans/{id}/progress"))
        .bearer_auth(SECOND_ROBOT)
        .json(&json!({"x": from.0, "y": from.1, "revision": 2}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200, "{}", r.text().await.unwrap());
    let (_, _, acknowledged) = get_plan_as(&app, SECOND_ROBOT, &id, None, "").await;
    assert_eq!(acknowledged["acknowledged_revision"], 2, "{acknowledged}");
    app.stop().await;
}
