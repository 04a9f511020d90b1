//! What the console reads, through the real app: the pages and `/openapi.json` without a
//! token, `/v1/me`, a floor's objects and roadmap, a plan's trace, and training curves.
//! (The pages themselves are driven in a real browser by `tests/browser/run.py`.)

use reqwest::Method;
use serde_json::{Value, json};

use crate::helpers::{spawn_app, spawn_app_with};

#[tokio::test]
async fn the_pages_and_the_merged_document_need_no_token() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("index.html"),
        "<!doctype html><title>console</title>",
    )
    .unwrap();
    let pages = dir.path().to_owned();
    let app = spawn_app_with(
        |c| {
            c.data_dir = pages.join("data");
            c.console_dir = Some(pages.clone());
        },
        None,
    )
    .await;
    let client = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .unwrap();
    let root = client
        .get(format!("{}/", app.address))
        .send()
        .await
        .unwrap();
    assert_eq!(root.status(), 303);
    assert_eq!(root.headers()["location"], "/console/");
    let page = client
        .get(format!("{}/console/jobs", app.address))
        .send()
        .await
        .unwrap();
    assert_eq!(page.status(), 200);
    assert!(page.text().await.unwrap().contains("console"));

    let doc: Value = client
        .get(format!("{}/openapi.json", app.address))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    for path in [
        "/v1/places",
        "/v1/plan",
        "/v1/jobs/{id}/curves.csv",
        "/v1/roadmaps",
        "/v1/me",
    ] {
        assert!(
            doc["paths"][path].is_object(),
            "{path} is missing from /openapi.json"
        );
    }
    // Everything else still needs the token.
    let r = client
        .get(format!("{}/v1/me", app.address))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 401);
    app.stop().await;
}

#[tokio::test]
async fn me_names_the_token_holder_and_role() {
    let app = spawn_app().await;
    let (status, me) = app.get_json("/v1/me").await;
    assert_eq!(status, 200, "{me}");
    assert_eq!(me["role"], "engineer");
    assert!(me["name"].as_str().is_some_and(|n| !n.is_empty()));
    app.stop().await;
}

#[tokio::test]
async fn a_floor_lists_its_objects_as_the_simulation_sees_them() {
    let app = spawn_app().await;
    let (status, before) = app.get_json("/v1/places/F0/objects").await;
    assert_eq!(status, 200, "{before}");
    let n = before.as_array().unwrap().len();
    app.report_box("F0-hall", "crate-7", (1.0, 1.0), 0.5).await;
    let (_, after) = app.get_json("/v1/places/F0-hall/objects").await;
    let objects = after.as_array().unwrap();
    assert_eq!(objects.len(), n + 1, "{after}");
    let reported = objects
        .iter()
        .find(|o| o["iri"].as_str().unwrap().contains("crate-7"))
        .expect("the reported box is listed");
    assert_eq!(reported["shape"], "box");
    assert!(reported["colour"].as_str().unwrap().starts_with('#'));
    assert!(reported["size"][0].as_f64().unwrap() > 0.0);
    let (status, missing) = app.get_json("/v1/places/no-such-place/objects").await;
    assert_eq!(status, 404, "{missing}");
    app.stop().await;
}

#[tokio::test]
async fn a_floor_roadmap_has_nodes_and_edges_and_names_bad_queries() {
    let app = spawn_app().await;
    let (status, roadmap) = app.get_json("/v1/roadmaps?place=F0&robot=R-001").await;
    assert_eq!(status, 200, "{roadmap}");
    assert_eq!(roadmap["kind"], "geometric");
    let nodes = roadmap["nodes"].as_array().unwrap();
    let edges = roadmap["edges"].as_array().unwrap();
    assert!(nodes.len() >= 10 && !edges.is_empty(), "{roadmap}");
    for e in edges {
        let (a, b) = (e["a"].as_u64().unwrap(), e["b"].as_u64().unwrap());
        assert!(a < nodes.len() as u64 && b < nodes.len() as u64);
        assert!(e["length_m"].as_f64().unwrap() > 0.0);
        assert!(e["success"].is_null());
    }
    assert!(roadmap["inflation_m"].as_f64().unwrap() > 0.1);
    let (status, body) = app
        .get_json("/v1/roadmaps?place=F0&robot=R-001&policy=nope")
        .await;
    assert_eq!(status, 404, "{body}");
    let (status, body) = app.get_json("/v1/roadmaps?place=F0").await;
    assert_eq!(status, 400, "{body}");
    let (status, body) = app
        .get_json("/v1/roadmaps?place=F0&robot=R-001&safety_margin_m=9")
        .await;
    assert_eq!(status, 422, "{body}");
    app.stop().await;
}

#[tokio::test]
async fn a_traced_plan_carries_every_attempts_drive_and_the_laser() {
    let app = spawn_app().await;
    // Two points in free space, from the roadmap itself.
    let (_, roadmap) = app.get_json("/v1/roadmaps?place=F0&robot=R-001").await;
    let nodes = roadmap["nodes"].as_array().unwrap();
    let (a, b) = (&nodes[0], &nodes[nodes.len() / 2]);
    let r = app
        .request(Method::POST, "/v1/plan")
        .json(&json!({
            "robot": "R-001", "place": "F0",
            "start": {"x": a[0], "y": a[1], "yaw": 0.0},
            "goal": {"x": b[0], "y": b[1]},
            "options": {"trace": true, "seed": 3}
        }))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let plan: Value = r.json().await.unwrap();
    let beams = plan["laser"]["angles_rad"].as_array().unwrap().len();
    assert_eq!(beams, 23, "{}", plan["laser"]);
    assert!(plan["laser"]["max_range_m"].as_f64().unwrap() > 1.0);
    for attempt in plan["attempts"].as_array().unwrap() {
        let trace = &attempt["trace"];
        let poses = trace["poses"].as_array().unwrap();
        assert!(poses.len() >= 2);
        assert_eq!(trace["ranges"].as_array().unwrap().len(), poses.len());
        assert_eq!(trace["times_s"].as_array().unwrap().len(), poses.len());
        assert!(trace["ranges"][0].as_array().unwrap().len() == beams);
        assert!(!trace["path"].as_array().unwrap().is_empty());
        let last = poses.last().unwrap();
        assert!(
            (last["x"].as_f64().unwrap() - attempt["end_pose"]["x"].as_f64().unwrap()).abs() < 1e-9
        );
    }
    // Without `trace`, neither is answered.
    let r = app
        .request(Method::POST, "/v1/plan")
        .json(&json!({
            "robot": "R-001", "place": "F0",
            "start": {"x": a[0], "y": a[1], "yaw": 0.0},
            "goal": {"x": b[0], "y": b[1]},
            "options": {"seed": 3}
        }))
        .send()
        .await
        .unwrap();
    let plain: Value = r.json().await.unwrap();
    assert!(plain.get("laser").is_none());
    assert!(plain["attempts"][0].get("trace").is_none());
    app.stop().await;
}

#[tokio::test]
async fn curves_belong_to_training_jobs() {
    // No job runner: the training stays queued.
    let temp = tempfile::tempdir().unwrap();
    let data_dir = temp.path().join("data");
    let app = spawn_app_with(
        |c| {
            c.data_dir = data_dir.clone();
            c.worker_concurrency = 0;
        },
        Some(temp),
    )
    .await;
    let (status, body) = app
        .get_json("/v1/jobs/01890000-0000-7000-8000-000000000000/curves.csv")
        .await;
    assert_eq!(status, 404, "{body}");
    // A queued training has no point yet; the 404 says so.
    let r = app
        .request(Method::POST, "/v1/jobs")
        .json(&json!({"kind": "train", "payload": {"robot": "R-001", "place": "F0", "minutes": 1}}))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 201);
    let job: Value = r.json().await.unwrap();
    let id = job["id"].as_str().unwrap();
    let (status, body) = app.get_json(&format!("/v1/jobs/{id}/curves.png")).await;
    assert_eq!(status, 404, "{body}");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("no learning curve yet")
    );
    app.stop().await;
}

#[tokio::test]
async fn a_floor_route_graph_is_nav2_route_server_geojson() {
    let app = spawn_app().await;
    let (_, roadmap) = app.get_json("/v1/roadmaps?place=F0&robot=R-001").await;
    let r = app
        .request(Method::GET, "/v1/places/F0/route-graph.geojson?robot=R-001")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], "application/geo+json");
    let graph: Value = r.json().await.unwrap();
    assert_eq!(graph["type"], "FeatureCollection");
    let features = graph["features"].as_array().unwrap();
    let nodes: Vec<&Value> = features
        .iter()
        .filter(|f| f["geometry"]["type"] == "Point")
        .collect();
    let edges: Vec<&Value> = features
        .iter()
        .filter(|f| f["geometry"]["type"] == "MultiLineString")
        .collect();
    // What nav2_route's GeoJSON parser reads: node id and frame, edge id, startid, endid, cost.
    assert_eq!(nodes.len(), roadmap["nodes"].as_array().unwrap().len());
    assert_eq!(edges.len(), 2 * roadmap["edges"].as_array().unwrap().len());
    let mut ids = std::collections::HashSet::new();
    for f in features {
        assert!(
            ids.insert(f["properties"]["id"].as_u64().unwrap()),
            "ids are unique"
        );
    }
    let node_ids: std::collections::HashSet<u64> = nodes
        .iter()
        .map(|n| {
            assert_eq!(n["properties"]["frame"], "map");
            n["properties"]["id"].as_u64().unwrap()
        })
        .collect();
    for e in &edges {
        let p = &e["properties"];
        assert!(node_ids.contains(&p["startid"].as_u64().unwrap()));
        assert!(node_ids.contains(&p["endid"].as_u64().unwrap()));
        assert!(p["cost"].as_f64().unwrap() > 0.0);
        let line = &e["geometry"]["coordinates"][0];
        assert_eq!(line.as_array().unwrap().len(), 2);
    }
    let r = app
        .request(Method::GET, "/v1/places/F0/route-graph.geojson")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 400, "the robot is required");
    app.stop().await;
}
