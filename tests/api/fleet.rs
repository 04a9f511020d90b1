//! The fleet's traffic schedule through the real service: plans committed to the job
//! database (SQLite), a second robot's plan fitted around the first one's with waits, the
//! 409 that names who is in the way, cancel and progress with their permissions, and two
//! service processes sharing one job database never committing conflicting plans.

use reqwest::Method;
use serde_json::{Value, json};

use crate::helpers::{EventReader, TestApp, spawn_app_with, with_tokens};
use crate::plan::{centroid, free_near, plan};

const FIRST: &str = "https://mentalsim.dev/data/robots/differential-robot";
const SECOND: &str = "https://mentalsim.dev/data/robots/second-robot";
const ENGINEER: &str = "fleet-engineer-token-0001";
pub(crate) const FIRST_ROBOT: &str = "fleet-first-robot-token-01";
pub(crate) const SECOND_ROBOT: &str = "fleet-second-robot-token-1";

/// An app whose tokens name the two robots, on `database_url` when given.
pub(crate) async fn fleet_app(database_url: Option<String>) -> TestApp {
    let temp = tempfile::tempdir().expect("temporary directory");
    let data_dir = temp.path().join("data");
    let mut app = spawn_app_with(
        |c| {
            c.data_dir = data_dir.clone();
            c.database_url = database_url;
            with_tokens(
                c,
                &[
                    (ENGINEER, "engineer", edge::Role::Engineer),
                    (FIRST_ROBOT, FIRST, edge::Role::Robot),
                    (SECOND_ROBOT, "second-robot", edge::Role::Robot),
                ],
            );
        },
        Some(temp),
    )
    .await;
    app.token = ENGINEER.to_owned();
    add_second_robot(&app).await;
    app
}

/// The bundled robot again under another IRI and identifier (`R-002`).
async fn add_second_robot(app: &TestApp) {
    let ttl = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("ontologies/robots/differential-robot.ttl"),
    )
    .unwrap()
    .replace("differential-robot", "second-robot")
    .replace("R-001", "R-002");
    let r = app
        .request(Method::POST, &format!("/store?graph={SECOND}"))
        .header("content-type", "text/turtle")
        .body(ttl)
        .send()
        .await
        .unwrap();
    assert!(r.status().is_success(), "{}", r.text().await.unwrap());
}

/// The same route for `robot`, setting off at `start_ms`.
pub(crate) fn route(
    robot: &str,
    from: (f64, f64),
    to: (f64, f64),
    start_ms: i64,
    options: Value,
) -> Value {
    let mut o =
        json!({"seed": 4, "trajectory_stride": 0, "people": "none", "start_time_ms": start_ms});
    for (k, v) in options.as_object().unwrap() {
        o[k] = v.clone();
    }
    json!({
        "robot": robot, "place": "F0",
        "start": {"x": from.0, "y": from.1, "yaw": 0.0},
        "goal": {"x": to.0, "y": to.1},
        "options": o
    })
}

pub(crate) fn now_ms() -> i64 {
    i64::try_from(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_millis(),
    )
    .unwrap()
}

/// The floor's committed plans.
pub(crate) async fn traffic(app: &TestApp, robot_token: &str) -> Value {
    let (status, body) = app
        .json_as(
            robot_token,
            Method::GET,
            "/v1/places/F0/traffic?robot=R-001",
            None,
        )
        .await;
    assert_eq!(status, 200, "{body}");
    body
}

/// Checks every pair of committed plans with the schedule's own geometry.
fn assert_apart(plans: &[Value]) {
    let itineraries: Vec<traffic::Itinerary> = plans
        .iter()
        .map(|p| serde_json::from_value(p.clone()).unwrap())
        .collect();
    for (i, a) in itineraries.iter().enumerate() {
        for b in &itineraries[i + 1..] {
            let conflict = traffic::first_conflict(a, b, 0.1);
            assert!(conflict.is_none(), "{conflict:?}");
        }
    }
}

/// Two robots sent the same way at the same time: the first is committed as asked; the
/// second waits (at its start, then wherever the first is in its way) and says for whom, and
/// the committed pair never comes closer than the margin. Without time to wait, a 409 names
/// the robot in the way and the earliest start that fits; once the first plan is cancelled
/// (only by its robot or an engineer), the second goes without waiting. Progress reports shift
/// a late robot's schedule.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_robot_waits_for_the_first_and_the_schedule_keeps_them_apart() {
    let app = fleet_app(None).await;
    let from = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let to = free_near(&app, centroid(&app, "F0-hall").await).await;
    let start = now_ms() + 5_000;

    let (status, first) = plan(&app, &route("R-001", from, to, start, json!({}))).await;
    assert_eq!(status, 200, "{first}");
    let s1 = &first["schedule"];
    assert_eq!(s1["committed"], true, "{first}");
    assert_eq!(s1["others_checked"], 0, "{first}");
    assert!(s1["waits"].as_array().unwrap().is_empty(), "{first}");
    assert_eq!(s1["start_time_ms"], start);
    let times = s1["waypoint_times_ms"].as_array().unwrap();
    assert_eq!(times.len(), first["waypoints"].as_array().unwrap().len());
    assert!(times.windows(2).all(|w| w[0].as_i64() <= w[1].as_i64()));
    // The ROS path carries the times: the start, then each waypoint.
    let poses = first["path"]["poses"].as_array().unwrap();
    assert_eq!(poses[0]["header"]["stamp"]["sec"], start / 1000, "{first}");
    assert!(poses.iter().all(|p| p["header"]["stamp"].is_object()));

    // The second robot takes the same route 15 s later, from where the first has left by
    // then (both robots' tolerances past): the first is held at the goal when
    // it would arrive.
    let later = start + 15_000;
    let (status, second) = plan(&app, &route("R-002", from, to, later, json!({}))).await;
    assert_eq!(status, 200, "{second}");
    let s2 = &second["schedule"];
    assert_eq!(s2["committed"], true);
    assert_eq!(s2["others_checked"], 1, "{second}");
    // Driven again with its waits while the first robot drives its plan: it arrives, and the
    // two never touch.
    let among = &s2["among_fleet"];
    assert_eq!(among["robots"], 1, "{second}");
    assert_eq!(among["arrived"], true, "{second}");
    assert!(
        among["min_robot_clearance_m"].as_f64().unwrap() > 0.0,
        "{second}"
    );
    assert!(s1["among_fleet"].is_null(), "{first}");
    let waits = s2["waits"].as_array().unwrap();
    assert!(!waits.is_empty(), "the second robot must wait: {second}");
    assert!(
        waits.iter().all(|w| w["for_robots"] == json!([FIRST])),
        "{second}"
    );
    assert!(s2["start_time_ms"].as_i64().unwrap() >= later, "{second}");
    // Execution by precedence, in the answer itself: the first robot passes after no one and
    // may go to its goal; the second passes after the first on their shared route and may go
    // no further than the first meeting until the first robot reports it has passed.
    assert_eq!(s1["passes_after"], json!([]), "{first}");
    assert!(s1["may_go_until_t_s"].is_null(), "{first}");
    let passes = s2["passes_after"].as_array().unwrap();
    assert!(!passes.is_empty(), "{second}");
    assert!(
        passes
            .iter()
            .all(|p| p["plan_id"] == s1["plan_id"] && p["passed"] == false),
        "{second}"
    );
    assert_eq!(s2["may_go_until_t_s"], passes[0]["t_s"], "{second}");
    let committed = traffic(&app, SECOND_ROBOT).await;
    let plans = committed["plans"].as_array().unwrap();
    assert_eq!(plans.len(), 2, "{committed}");
    assert_apart(plans);

    // No time to wait: refused, naming the robot in the way and when it would fit. Nothing
    // is committed (the second robot's earlier plan stays).
    let (status, refused) = plan(
        &app,
        &route("R-002", from, to, later, json!({"max_wait_s": 0})),
    )
    .await;
    assert_eq!(status, 409, "{refused}");
    assert_eq!(
        refused["error"]["details"]["robots"],
        json!([FIRST]),
        "{refused}"
    );
    assert!(
        refused["error"]["details"]["earliest_start_ms"]
            .as_i64()
            .unwrap()
            > later,
        "{refused}"
    );
    let version = committed["version"].as_i64().unwrap();
    assert_eq!(traffic(&app, SECOND_ROBOT).await["version"], version);

    // A start where the first robot is held at its goal at that time cannot be waited out:
    // refused, naming it.
    let arrived = s1["waypoint_times_ms"]
        .as_array()
        .unwrap()
        .last()
        .unwrap()
        .as_i64()
        .unwrap();
    let (status, inside) = plan(&app, &route("R-002", to, from, arrived + 2_000, json!({}))).await;
    assert_eq!(status, 409, "{inside}");
    assert_eq!(
        inside["error"]["details"]["robots"],
        json!([FIRST]),
        "{inside}"
    );
    assert!(inside.to_string().contains("footprint"), "{inside}");

    // A start in the past, beyond the tolerance, cannot be scheduled.
    let (status, past) = plan(
        &app,
        &route("R-002", from, to, now_ms() - 60_000, json!({})),
    )
    .await;
    assert_eq!(status, 422, "{past}");
    assert!(past.to_string().contains("start_time_ms"), "{past}");

    // Only the plan's robot (or an engineer) may cancel it.
    let id1 = s1["plan_id"].as_str().unwrap();
    let r = app
        .client
        .delete(format!("{}/v1/plans/{id1}", app.address))
        .bearer_auth(SECOND_ROBOT)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 403);
    let r = app
        .client
        .delete(format!("{}/v1/plans/{id1}", app.address))
        .bearer_auth(FIRST_ROBOT)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.json::<Value>().await.unwrap()["plan_id"], id1);
    let r = app
        .request(Method::DELETE, &format!("/v1/plans/{id1}"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404, "cancelled already");
    let (status, alone) = plan(
        &app,
        &route("R-002", from, to, later, json!({"max_wait_s": 0})),
    )
    .await;
    assert_eq!(status, 200, "{alone}");
    assert!(alone["schedule"]["waits"].as_array().unwrap().is_empty());
    assert_eq!(
        traffic(&app, FIRST_ROBOT).await["plans"]
            .as_array()
            .unwrap()
            .len(),
        1
    );

    // The second robot reports itself still at its start 10 s after it should have set off:
    // the rest of its schedule shifts.
    let id2 = alone["schedule"]["plan_id"].as_str().unwrap();
    let progress = |token: &'static str, body: Value| {
        app.client
            .post(format!("{}/v1/plans/{id2}/progress", app.address))
            .bearer_auth(token)
            .json(&body)
            .send()
    };
    let r = progress(FIRST_ROBOT, json!({"x": from.0, "y": from.1}))
        .await
        .unwrap();
    assert_eq!(r.status(), 403, "another robot's plan");
    let r = progress(SECOND_ROBOT, json!({"x": "here", "y": 0}))
        .await
        .unwrap();
    assert!(r.status() == 400 || r.status() == 422, "{}", r.status());
    let r = progress(
        SECOND_ROBOT,
        json!({"x": from.0, "y": from.1, "time_ms": later + 10_000}),
    )
    .await
    .unwrap();
    assert_eq!(r.status(), 200);
    let shifted: Value = r.json().await.unwrap();
    // Late by 10 s less the time the schedule had it turning on the spot at its start.
    let delay = shifted["delay_s"].as_f64().unwrap();
    assert!((6.0..=10.0).contains(&delay), "{}", shifted["delay_s"]);
    let r = app
        .request(Method::POST, "/v1/plans/plan-nope/progress")
        .json(&json!({"x": 0.0, "y": 0.0}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404);
    app.stop().await;
}

/// Many plans for one robot at once (a robot re-asking while its last request still runs):
/// each is answered and committed in turn, the later replacing the earlier, and the schedule
/// ends with exactly one of them. None is refused because the others' commits changed the
/// floor's version under it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn concurrent_plans_for_one_robot_all_commit_and_the_last_one_stands() {
    let app = fleet_app(None).await;
    let from = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let to = free_near(&app, centroid(&app, "F0-hall").await).await;
    let start = now_ms() + 5_000;
    let body = route("R-001", from, to, start, json!({}));
    let mut requests = tokio::task::JoinSet::new();
    for _ in 0..24 {
        let request = app
            .client
            .post(format!("{}/v1/plan", app.address))
            .bearer_auth(&app.token)
            .json(&body);
        requests.spawn(async move {
            let r = request.send().await.unwrap();
            (r.status().as_u16(), r.json::<Value>().await.unwrap())
        });
    }
    let answers = requests.join_all().await;
    let mut ids = Vec::new();
    for (status, answer) in &answers {
        assert_eq!(*status, 200, "{answer}");
        assert_eq!(answer["schedule"]["committed"], true, "{answer}");
        ids.push(answer["schedule"]["plan_id"].clone());
    }
    let committed = traffic(&app, FIRST_ROBOT).await;
    let plans = committed["plans"].as_array().unwrap();
    assert_eq!(plans.len(), 1, "{committed}");
    assert!(ids.contains(&plans[0]["plan_id"]), "{committed}");
}

/// The floor's traffic as server-sent events (what the console's live view reads), opened
/// with a robot's token.
async fn traffic_events(app: &TestApp) -> EventReader {
    let r = app
        .client
        .get(format!(
            "{}/v1/places/F0/traffic/events?robot=R-001",
            app.address
        ))
        .bearer_auth(FIRST_ROBOT)
        .send()
        .await
        .unwrap();
    EventReader::new(r)
}

fn deadline(seconds: u64) -> tokio::time::Instant {
    tokio::time::Instant::now() + std::time::Duration::from_secs(seconds)
}

/// The floor's traffic streamed: a snapshot first, then each commit, replacement, progress
/// report and cancel as it happens, each event's id the floor's version after it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_floor_traffic_streams_every_change_with_its_version() {
    let app = fleet_app(None).await;
    let (status, body) = app
        .json_as(
            FIRST_ROBOT,
            Method::GET,
            "/v1/places/F0/traffic/events",
            None,
        )
        .await;
    assert_eq!(status, 400, "a place without its robot: {body}");
    let (status, body) = app
        .json_as(
            FIRST_ROBOT,
            Method::GET,
            "/v1/places/nowhere/traffic/events?robot=R-001",
            None,
        )
        .await;
    assert_eq!(status, 404, "{body}");

    let mut events = traffic_events(&app).await;
    let snapshot = events.next(deadline(30)).await.unwrap();
    assert_eq!(snapshot.event, "snapshot", "{snapshot:?}");
    assert_eq!((snapshot.id, &snapshot.data["plans"]), (0, &json!([])));
    let floor = snapshot.data["floor"].as_str().unwrap().to_owned();
    assert!(floor.contains("://"), "{floor}");

    let from = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let to = free_near(&app, centroid(&app, "F0-hall").await).await;
    let start = now_ms() + 5_000;
    let (status, first) = plan(&app, &route("R-001", from, to, start, json!({}))).await;
    assert_eq!(status, 200, "{first}");
    let id1 = first["schedule"]["plan_id"].as_str().unwrap().to_owned();
    // First the robot standing at its start while its plan was made, then the plan, under
    // one plan id (no removal between them).
    let standing = events.next(deadline(30)).await.unwrap();
    assert_eq!((standing.event.as_str(), standing.id), ("committed", 1));
    let trajectory = standing.data["itinerary"]["trajectory"].as_array().unwrap();
    assert_eq!(trajectory.len(), 1, "{standing:?}");
    assert_eq!(
        (trajectory[0]["x"].as_f64(), trajectory[0]["y"].as_f64()),
        (Some(from.0), Some(from.1))
    );
    let committed = events.next(deadline(30)).await.unwrap();
    assert_eq!((committed.event.as_str(), committed.id), ("committed", 2));
    assert_eq!(committed.data["kind"], "committed");
    for e in [&standing, &committed] {
        assert_eq!(e.data["itinerary"]["plan_id"], id1.as_str());
        assert_eq!(e.data["itinerary"]["robot"], FIRST);
        assert_eq!(e.data["itinerary"]["floor"], floor.as_str());
    }
    assert!(
        committed.data["itinerary"]["trajectory"]
            .as_array()
            .unwrap()
            .len()
            > 1
    );

    // A new plan for the same robot replaces its first (the schedule holds the robot already,
    // so nothing is recorded while it is made): both changes carry version 3.
    let (status, second) = plan(&app, &route("R-001", to, from, start, json!({}))).await;
    assert_eq!(status, 200, "{second}");
    let id2 = second["schedule"]["plan_id"].as_str().unwrap().to_owned();
    let mut seen = Vec::new();
    for _ in 0..2 {
        let e = events.next(deadline(30)).await.unwrap();
        assert_eq!(e.id, 3, "{e:?}");
        seen.push(e);
    }
    seen.sort_by_key(|e| e.event.clone());
    assert_eq!(seen[0].event, "committed");
    assert_eq!(seen[0].data["itinerary"]["plan_id"], id2.as_str());
    assert_eq!(seen[1].event, "removed");
    assert_eq!(seen[1].data["plan_id"], id1.as_str());
    assert_eq!(seen[1].data["reason"], "replaced");

    let r = app
        .client
        .post(format!("{}/v1/plans/{id2}/progress", app.address))
        .bearer_auth(FIRST_ROBOT)
        .json(&json!({"x": to.0, "y": to.1, "time_ms": start + 8_000}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let progressed = events.next(deadline(30)).await.unwrap();
    assert_eq!(
        (progressed.event.as_str(), progressed.id),
        ("progressed", 4)
    );
    assert!(progressed.data["itinerary"]["delay_s"].as_f64().unwrap() > 0.0);

    let r = app
        .client
        .delete(format!("{}/v1/plans/{id2}", app.address))
        .bearer_auth(FIRST_ROBOT)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let removed = events.next(deadline(30)).await.unwrap();
    assert_eq!((removed.event.as_str(), removed.id), ("removed", 5));
    assert_eq!(removed.data["reason"], "cancelled");
    assert!(
        traffic(&app, FIRST_ROBOT).await["plans"]
            .as_array()
            .unwrap()
            .is_empty()
    );
    app.stop().await;
}

/// Two service processes on one job database, each asked at the same moment to send a robot
/// the same way (the second 15 s later, from where the first has left by then): whatever order their commits land in, the committed
/// plans keep the robots apart — the floor's version makes the later commit check again, and
/// it then waits, or is refused (409) when no wait fits; never both committed in conflict.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_processes_sharing_the_job_database_never_commit_conflicting_plans() {
    let shared = tempfile::tempdir().unwrap();
    let url = format!("sqlite://{}", shared.path().join("jobs.db").display());
    let (a, b) = tokio::join!(fleet_app(Some(url.clone())), fleet_app(Some(url)));
    let from = free_near(&a, centroid(&a, "F0-living-room").await).await;
    let to = free_near(&a, centroid(&a, "F0-hall").await).await;
    let start = now_ms() + 5_000;
    // A live view of the floor on process `a`: it sees `b`'s commit too.
    let mut live = traffic_events(&a).await;
    assert_eq!(live.next(deadline(30)).await.unwrap().event, "snapshot");
    let (ask_first, ask_second) = (
        route("R-001", from, to, start, json!({})),
        route("R-002", from, to, start + 15_000, json!({})),
    );
    let (first, second) = tokio::join!(plan(&a, &ask_first), plan(&b, &ask_second));
    let answered: Vec<&Value> = [&first, &second]
        .into_iter()
        .filter(|(status, body)| {
            assert!(*status == 200 || *status == 409, "{status} {body}");
            *status == 200
        })
        .map(|(_, body)| body)
        .collect();
    assert!(!answered.is_empty(), "{first:?} {second:?}");
    assert!(
        answered.iter().all(|p| p["schedule"]["committed"] == true),
        "{answered:?}"
    );
    // Each robot answered is there with its plan; a robot refused stands at its start (its
    // plan never moved it).
    let mut want = std::collections::BTreeSet::new();
    for app in [&a, &b] {
        let committed = traffic(app, FIRST_ROBOT).await;
        let plans = committed["plans"].as_array().unwrap();
        assert_eq!(plans.len(), 2, "{committed}");
        let moving = |p: &&Value| p["trajectory"].as_array().unwrap().len() > 1;
        assert_eq!(
            plans.iter().filter(moving).count(),
            answered.len(),
            "{committed}"
        );
        assert_apart(plans);
        want = plans
            .iter()
            .map(|p| p["plan_id"].as_str().unwrap().to_owned())
            .collect();
    }
    assert!(
        answered
            .iter()
            .all(|p| want.contains(p["schedule"]["plan_id"].as_str().unwrap()))
    );
    // What the live view on `a` holds converges to what is committed, within the stream's
    // poll of the floor's version (another process's commit arrives as a new snapshot).
    let mut held = std::collections::BTreeSet::new();
    let until = deadline(30);
    while held != want {
        let e = live.next(until).await.unwrap();
        match e.event.as_str() {
            "snapshot" => {
                held = e.data["plans"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|p| p["plan_id"].as_str().unwrap().to_owned())
                    .collect();
            }
            "committed" => {
                held.insert(e.data["itinerary"]["plan_id"].as_str().unwrap().to_owned());
            }
            other => panic!("unexpected {other}: {e:?}"),
        }
    }
    if answered.len() == 2 {
        let waited = answered
            .iter()
            .filter(|p| !p["schedule"]["waits"].as_array().unwrap().is_empty())
            .count();
        assert_eq!(
            waited, 1,
            "the later commit fitted around the first: {answered:?}"
        );
    }
    a.stop().await;
    b.stop().await;
}

/// A robot says where it stands idle (`POST /v1/places/{id}/traffic/standing`): the schedule
/// holds it there, another robot's plan keeps clear of it (routed around it, or refused naming
/// it), and the route takes it in again once its standing is cancelled. Only the robot itself
/// (or an engineer) may say so; where it does not fit, or inside another robot's footprint,
/// it is refused.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_robot_standing_idle_is_kept_clear_of_and_only_it_says_where_it_stands() {
    let app = fleet_app(None).await;
    let from = free_near(&app, centroid(&app, "F0-living-room").await).await;
    let to = free_near(&app, centroid(&app, "F0-hall").await).await;
    let stand = |token: &'static str, body: Value| {
        let app = &app;
        async move {
            app.json_as(
                token,
                Method::POST,
                "/v1/places/F0/traffic/standing",
                Some(&body),
            )
            .await
        }
    };
    // Where the second robot's route alone passes, midway.
    let start = now_ms() + 5_000;
    let (status, alone) = plan(
        &app,
        &route("R-002", from, to, start, json!({"commit": false})),
    )
    .await;
    assert_eq!(status, 200, "{alone}");
    let waypoints = alone["waypoints"].as_array().unwrap();
    let mid = &waypoints[waypoints.len() / 2];
    let (mx, my) = (mid["x"].as_f64().unwrap(), mid["y"].as_f64().unwrap());

    let (status, body) = stand(SECOND_ROBOT, json!({"robot": "R-001", "x": mx, "y": my})).await;
    assert_eq!(status, 403, "another robot: {body}");
    let (status, body) = stand(
        FIRST_ROBOT,
        json!({"robot": "R-001", "x": -1000.0, "y": 0.0}),
    )
    .await;
    assert_eq!(status, 422, "off the map: {body}");
    let (status, body) = stand(
        FIRST_ROBOT,
        json!({"robot": "R-001", "x": mx, "y": my, "for_s": 0}),
    )
    .await;
    assert_eq!(status, 422, "{body}");
    assert!(
        body["error"]["message"].as_str().unwrap().contains("for_s"),
        "{body}"
    );
    let (status, body) = stand(FIRST_ROBOT, json!({"robot": "R-001", "x": mx})).await;
    assert!(status == 400 || status == 422, "{status} {body}");

    let (status, standing) = stand(
        FIRST_ROBOT,
        json!({"robot": "R-001", "x": mx, "y": my, "for_s": 120}),
    )
    .await;
    assert_eq!(status, 200, "{standing}");
    assert_eq!(standing["robot"], FIRST);
    assert_eq!(standing["trajectory"].as_array().unwrap().len(), 1);
    let plans = traffic(&app, FIRST_ROBOT).await["plans"].clone();
    assert_eq!(plans.as_array().unwrap().len(), 1, "{plans}");

    // The second robot may not stand where the first one does.
    let (status, body) = stand(SECOND_ROBOT, json!({"robot": "R-002", "x": mx, "y": my})).await;
    assert_eq!(status, 409, "{body}");
    assert_eq!(body["error"]["details"]["robots"], json!([FIRST]), "{body}");

    // Its plan now keeps clear of the first robot: routed around it, or refused naming it.
    let (status, around) = plan(&app, &route("R-002", from, to, start, json!({}))).await;
    if status == 200 {
        let committed = traffic(&app, SECOND_ROBOT).await;
        let plans = committed["plans"].as_array().unwrap();
        assert_eq!(plans.len(), 2, "{committed}");
        assert_apart(plans);
        assert_ne!(around["waypoints"], alone["waypoints"], "{around}");
    } else {
        assert_eq!(status, 409, "{around}");
        assert_eq!(
            around["error"]["details"]["robots"],
            json!([FIRST]),
            "{around}"
        );
    }

    // Cancelled, the first robot no longer stands there.
    let id = standing["plan_id"].as_str().unwrap();
    let r = app
        .client
        .delete(format!("{}/v1/plans/{id}", app.address))
        .bearer_auth(FIRST_ROBOT)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert!(
        traffic(&app, FIRST_ROBOT).await["plans"]
            .as_array()
            .unwrap()
            .iter()
            .all(|p| p["robot"] != FIRST)
    );
    app.stop().await;
}
