//! What the fleet knows about people, through the real app: an engineer writes it over SPARQL,
//! robots post the counts they make (`POST /v1/places/{id}/observations`), the running
//! estimate moves as documented (the mean of the first five counts, then each new one weighs
//! 0.2), survives a restart, and reaches a mission's on-demand database; bad counts are 4xx
//! naming what is wrong, and change nothing.

use mentalsim::config::Config;
use serde_json::{Value, json};

use crate::helpers::{TestApp, answer, spawn_app_with, url_encode, with_tokens};

const ENGINEER: &str = "engineer-token-for-people";
const ROBOT: &str = "robot-token-for-people-1";
const OTHER_ROBOT: &str = "robot-token-for-people-2";
const FLOOR0: &str = "https://mentalsim.dev/data/buildings/sample-building/floors/0";
const TOSM: &str = "https://mentalsim.dev/ontology/tosm#";

fn tokens(c: &mut Config) {
    with_tokens(
        c,
        &[
            (ENGINEER, "alice", edge::Role::Engineer),
            (ROBOT, "robot-1", edge::Role::Robot),
            (OTHER_ROBOT, "robot-2", edge::Role::Robot),
        ],
    );
}

/// The app on `data_dir` (kept by the caller, so that a second app can open it again).
async fn app_on(data_dir: &std::path::Path) -> TestApp {
    let dir = data_dir.to_owned();
    let mut app = spawn_app_with(
        |c| {
            c.data_dir = dir;
            tokens(c);
        },
        None,
    )
    .await;
    app.token = ENGINEER.to_owned();
    app
}

/// `POST /v1/places/{place}/observations` with `body` as `token`.
async fn observe(app: &TestApp, token: &str, place: &str, body: Value) -> reqwest::Response {
    app.client
        .post(format!("{}/v1/places/{place}/observations", app.address))
        .bearer_auth(token)
        .json(&body)
        .send()
        .await
        .unwrap()
}

async fn sparql_update(app: &TestApp, update: String) {
    let r = app.sparql_update(&update).await;
    assert_eq!(r.status(), 204, "{}", r.text().await.unwrap());
}

/// The single binding of `?v` in the answer to `query`, if any.
async fn sparql_value(app: &TestApp, query: String) -> Option<String> {
    let r = app.sparql_query(&query).await;
    assert_eq!(r.status(), 200);
    let json: Value = r.json().await.unwrap();
    json["results"]["bindings"][0]["v"]["value"]
        .as_str()
        .map(str::to_owned)
}

fn close(a: &Value, b: f64) -> bool {
    a.as_f64().is_some_and(|a| (a - b).abs() < 1e-9)
}

#[tokio::test]
async fn counts_move_the_estimate_as_documented_survive_a_restart_and_reach_the_mission() {
    let temp = tempfile::tempdir().unwrap();
    let data_dir = temp.path().join("data");
    let app = app_on(&data_dir).await;
    let office = format!("{FLOOR0}/office");

    // An engineer adds a desk people linger at, with plain triples over SPARQL.
    sparql_update(
        &app,
        format!(
            "PREFIX tosm: <{TOSM}>
             INSERT DATA {{ GRAPH <urn:mentalsim:test:people> {{
               <{FLOOR0}/attractors/desk> a tosm:Attractor ; tosm:name \"Desk\" ;
                 tosm:isDirectlyInsideOf <{office}> ; tosm:dwellTimeS 300 ;
                 tosm:hasPose <{FLOOR0}/attractors/desk/pose> .
               <{FLOOR0}/attractors/desk/pose> a tosm:Pose ; tosm:xM -14.9 ; tosm:yM 6.1 .
             }} }}"
        ),
    )
    .await;

    // A robot counts people in the office: 3 at 09:15 local time.
    let (status, body) = answer(
        observe(
            &app,
            ROBOT,
            "F0-office",
            json!({"observations": [{"count": 3, "observed_at": "2025-05-06T09:15:00+02:00"}]}),
        )
        .await,
    )
    .await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["place"], office.as_str());
    assert_eq!(body["accepted"], 1);
    assert!(close(&body["estimate"]["people"], 3.0), "{body}");
    assert_eq!(body["estimate"]["observations"], 1);
    assert_eq!(body["by_hour"][0]["hour"], 9);
    assert!(close(&body["by_hour"][0]["people"], 3.0), "{body}");

    // Then 1 at 09:45, 2 without a time (all day only), 4 at 09:05 (out of order) and 10 at
    // 14:00 (UTC, 14 as written): the first five are averaged.
    let (status, body) = answer(
        observe(
            &app,
            ROBOT,
            &url_encode(&office),
            json!({"observations": [
                {"count": 1, "observed_at": "2025-05-06T09:45:00+02:00"},
                {"count": 2},
                {"count": 4, "observed_at": "2025-05-06T09:05:00+02:00"},
                {"count": 10, "observed_at": "2025-05-06T14:00:00Z"}
            ]}),
        )
        .await,
    )
    .await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["accepted"], 4);
    assert!(
        close(&body["estimate"]["people"], 4.0),
        "(3+1+2+4+10)/5: {body}"
    );
    assert_eq!(body["estimate"]["observations"], 5);
    let hours: Vec<(u64, f64, u64)> = body["by_hour"]
        .as_array()
        .unwrap()
        .iter()
        .map(|h| {
            (
                h["hour"].as_u64().unwrap(),
                h["people"].as_f64().unwrap(),
                h["observations"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(hours, vec![(9, 8.0 / 3.0, 3), (14, 10.0, 1)], "{body}");
    // The hour's latest count was at 09:45, though 09:05 arrived after it.
    assert_eq!(
        body["by_hour"][0]["last_observed_at"],
        "2025-05-06T09:45:00+02:00"
    );

    // The sixth count weighs 0.2: 4 + 0.2 * (14 - 4) = 6.
    let (status, body) = answer(
        observe(
            &app,
            ROBOT,
            "F0-office",
            json!({"observations": [{"count": 14}]}),
        )
        .await,
    )
    .await;
    assert_eq!(status, 200, "{body}");
    assert!(close(&body["estimate"]["people"], 6.0), "{body}");
    assert_eq!(body["estimate"]["observations"], 6);

    // The mission's database carries the estimate, the engineer's desk and the floor's routes,
    // although only the office and the hallway are on the route.
    let r = app
        .client
        .post(format!("{}/v1/on-demand", app.address))
        .bearer_auth(ROBOT)
        .header("accept", "application/n-triples")
        .json(&json!({"robot": "R-001", "start": {"place": "F0-office"}, "goals": [{"place": "F0-hallway"}]}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let db = r.text().await.unwrap();
    for needle in [
        format!("<{office}> <{TOSM}hasPeopleEstimate> <{office}/people/estimate>"),
        format!("<{office}/people/estimate> <{TOSM}estimatedPeople> \"6\""),
        format!("<{office}/people/estimate/hour/14> <{TOSM}observationCount> \"1\""),
        format!("<{FLOOR0}/attractors/desk> <{TOSM}dwellTimeS>"),
        format!("<{FLOOR0}/attractors/vending-machine> <{TOSM}dwellTimeS>"),
        format!("<{FLOOR0}/routes/hall-to-vending-machine> <{TOSM}hasRoutePoint>"),
        format!("<{FLOOR0}/hall> <{TOSM}expectedPeople>"),
    ] {
        assert!(
            db.contains(&needle),
            "{needle} missing from the mission's database"
        );
    }
    assert!(
        !db.contains("/floors/1/"),
        "nothing of the other floor's people"
    );
    app.stop().await;

    // Durable: a restarted service reads the same estimate and keeps counting from it.
    let app = app_on(&data_dir).await;
    let stored = sparql_value(
        &app,
        format!(
            "PREFIX tosm: <{TOSM}> SELECT ?v WHERE {{ GRAPH ?g {{ <{office}/people/estimate> tosm:observationCount ?v }} }}"
        ),
    )
    .await;
    assert_eq!(stored.as_deref(), Some("6"));
    let (status, body) = answer(
        observe(
            &app,
            ROBOT,
            "F0-office",
            json!({"observations": [{"count": 1}]}),
        )
        .await,
    )
    .await;
    assert_eq!(status, 200, "{body}");
    assert_eq!(body["estimate"]["observations"], 7);
    assert!(
        close(&body["estimate"]["people"], 6.0 + 0.2 * (1.0 - 6.0)),
        "{body}"
    );
    app.stop().await;
}

#[tokio::test]
async fn bad_counts_are_4xx_naming_what_is_wrong_and_change_nothing() {
    let temp = tempfile::tempdir().unwrap();
    let app = app_on(&temp.path().join("data")).await;
    let one = |count: Value| json!({"observations": [{"count": 1}, {"count": count}]});
    let robot_iri = url_encode("https://mentalsim.dev/data/robots/differential-robot");
    let table_iri =
        url_encode("https://mentalsim.dev/data/buildings/sample-building/objects/table-1");
    let cases: Vec<(&str, &str, Value, u16, &str)> = vec![
        (
            "negative",
            "F0-hall",
            one(json!(-1)),
            422,
            "observations[1].count",
        ),
        (
            "huge",
            "F0-hall",
            one(json!(1e6)),
            422,
            "observations[1].count",
        ),
        (
            "a string",
            "F0-hall",
            one(json!("3")),
            422,
            "observations[1].count",
        ),
        (
            "missing",
            "F0-hall",
            json!({"observations": [{}]}),
            422,
            "count",
        ),
        (
            "none",
            "F0-hall",
            json!({"observations": []}),
            422,
            "at least one",
        ),
        (
            "no list",
            "F0-hall",
            json!({"count": 3}),
            422,
            "unknown field",
        ),
        (
            "a bad time",
            "F0-hall",
            json!({"observations": [{"count": 1, "observed_at": "yesterday at noon"}]}),
            422,
            "observations[0].observed_at",
        ),
        (
            "an extra field",
            "F0-hall",
            json!({"observations": [{"count": 1, "place": "F0-office"}]}),
            422,
            "unknown field",
        ),
        (
            "an unknown place",
            "F9-nowhere",
            one(json!(1)),
            404,
            "F9-nowhere",
        ),
        (
            "the robot, no place",
            &robot_iri,
            one(json!(1)),
            404,
            "differential-robot",
        ),
        (
            "an object, no place",
            &table_iri,
            one(json!(1)),
            404,
            "table-1",
        ),
        ("a building", "B-001", one(json!(1)), 422, "building"),
    ];
    for (what, place, body, status, needle) in cases {
        let (got, answer) = answer(observe(&app, ROBOT, place, body).await).await;
        assert_eq!(got, status, "{what}: {answer}");
        let message = answer["error"]["message"].as_str().unwrap_or_default();
        assert!(message.contains(needle), "{what}: {answer}");
    }
    // Too many counts in one request (an engineer's: a robot's allowance would end first).
    let many: Vec<Value> = (0..101).map(|_| json!({"count": 1})).collect();
    let (status, body) =
        answer(observe(&app, ENGINEER, "F0-hall", json!({ "observations": many })).await).await;
    assert_eq!(status, 422, "{body}");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("at most 100")
    );
    // Not JSON, NaN (not JSON either), no media type, no token.
    let raw = |body: &'static str, content_type: Option<&str>, token: Option<&str>| {
        let mut r = app
            .client
            .post(format!("{}/v1/places/F0-hall/observations", app.address))
            .body(body);
        if let Some(t) = content_type {
            r = r.header("content-type", t);
        }
        if let Some(t) = token {
            r = r.bearer_auth(t);
        }
        r.send()
    };
    for (body, content_type, token, status) in [
        ("counts", Some("application/json"), Some(ROBOT), 400),
        (
            r#"{"observations": [{"count": NaN}]}"#,
            Some("application/json"),
            Some(ROBOT),
            400,
        ),
        (
            r#"{"observations": [{"count": 1}]}"#,
            None,
            Some(ROBOT),
            415,
        ),
        (
            r#"{"observations": [{"count": 1}]}"#,
            Some("application/json"),
            None,
            401,
        ),
    ] {
        let (got, answer) = answer(raw(body, content_type, token).await.unwrap()).await;
        assert_eq!(got, status, "{body}: {answer}");
        assert!(answer["error"]["message"].is_string(), "{answer}");
    }
    // A body beyond the small body limit is refused before it is read.
    let huge = format!(
        "{{\"observations\": [{}]}}",
        vec!["{\"count\": 1}"; 100_000].join(",")
    );
    let r = app
        .client
        .post(format!("{}/v1/places/F0-hall/observations", app.address))
        .bearer_auth(ROBOT)
        .header("content-type", "application/json")
        .body(huge)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 413);
    // Nothing was stored by any of them.
    let stored = sparql_value(
        &app,
        format!(
            "PREFIX tosm: <{TOSM}> SELECT ?v WHERE {{ GRAPH ?g {{ ?v a tosm:PeopleEstimate }} }}"
        ),
    )
    .await;
    assert_eq!(stored, None);

    // An estimate an engineer's edit broke is a 409 naming it, not a 500.
    sparql_update(
        &app,
        format!(
            "PREFIX tosm: <{TOSM}>
             INSERT DATA {{ GRAPH <https://mentalsim.dev/graph/perceived> {{
               <{FLOOR0}/hall> tosm:hasPeopleEstimate <{FLOOR0}/hall/people/estimate> .
               <{FLOOR0}/hall/people/estimate> a tosm:PeopleEstimate ;
                 tosm:estimatedPeople 2 ; tosm:observationCount 0 .
             }} }}"
        ),
    )
    .await;
    let (status, body) = answer(
        observe(
            &app,
            ROBOT,
            "F0-hall",
            json!({"observations": [{"count": 1}]}),
        )
        .await,
    )
    .await;
    assert_eq!(status, 409, "{body}");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("observationCount"),
        "{body}"
    );
    app.stop().await;
}

#[tokio::test]
async fn a_robot_counts_at_a_bounded_rate_and_others_are_not_affected() {
    let temp = tempfile::tempdir().unwrap();
    let app = app_on(&temp.path().join("data")).await;
    let batch: Vec<Value> = (0..100).map(|i| json!({"count": i % 4})).collect();
    let body = json!({ "observations": batch });
    let (status, answer_body) =
        answer(observe(&app, OTHER_ROBOT, "F0-hall", body.clone()).await).await;
    assert_eq!(status, 200, "{answer_body}");
    let limited = observe(&app, OTHER_ROBOT, "F0-hall", body.clone()).await;
    assert_eq!(limited.status(), 429);
    let retry: u64 = limited.headers()["retry-after"]
        .to_str()
        .unwrap()
        .parse()
        .unwrap();
    assert!((1..=6).contains(&retry), "{retry}");
    let (_, answer_body) = answer(limited).await;
    assert!(
        answer_body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("robot-2"),
        "{answer_body}"
    );
    // Another robot, and engineers, still count.
    let (status, _) = answer(observe(&app, ROBOT, "F0-hall", body.clone()).await).await;
    assert_eq!(status, 200);
    let (status, answer_body) = answer(observe(&app, ENGINEER, "F0-hall", body).await).await;
    assert_eq!(status, 200);
    assert_eq!(answer_body["estimate"]["observations"], 300);
    app.stop().await;
}
