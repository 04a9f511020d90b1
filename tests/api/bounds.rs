//! What one misbehaving client can cost the service: bodies refused before they are read,
//! limits per route and role, slow or idle connections closed, requests beyond the in-flight
//! limit shed with `Retry-After`, answers capped per role, metric labels from a closed set,
//! readiness that reveals nothing and does not flap under concurrent probes.

use std::time::{Duration, Instant};

use mentalsim::config::{Config, TokenConfig};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

use crate::helpers::{TestApp, spawn_app_with};

const ENGINEER: &str = "engineer-token-for-bounds";
const ROBOT: &str = "robot-token-for-bounds-0";
const OTHER_ROBOT: &str = "robot-token-for-bounds-2";

async fn app_with(edit: impl FnOnce(&mut Config)) -> TestApp {
    let temp = tempfile::tempdir().unwrap();
    let data_dir = temp.path().join("data");
    spawn_app_with(
        |c| {
            c.data_dir = data_dir;
            c.tokens = vec![
                TokenConfig {
                    token: ENGINEER.to_owned(),
                    name: "alice".to_owned(),
                    role: edge::Role::Engineer,
                },
                TokenConfig {
                    token: ROBOT.to_owned(),
                    name: "robot-1".to_owned(),
                    role: edge::Role::Robot,
                },
                TokenConfig {
                    token: OTHER_ROBOT.to_owned(),
                    name: "robot-2".to_owned(),
                    role: edge::Role::Robot,
                },
            ];
            edit(c);
        },
        Some(temp),
    )
    .await
}

/// A raw connection to the app, for what a well-behaved client would never send.
async fn connect(app: &TestApp) -> TcpStream {
    TcpStream::connect(app.address.trim_start_matches("http://"))
        .await
        .unwrap()
}

/// What the server sends until it closes the connection or `within` passes.
async fn read_until_closed(stream: &mut TcpStream, within: Duration) -> (String, bool) {
    let mut got = Vec::new();
    let mut buf = [0_u8; 4096];
    let deadline = tokio::time::Instant::now() + within;
    loop {
        match tokio::time::timeout_at(deadline, stream.read(&mut buf)).await {
            Ok(Ok(0) | Err(_)) => return (String::from_utf8_lossy(&got).into_owned(), true),
            Ok(Ok(n)) => got.extend_from_slice(&buf[..n]),
            Err(_) => return (String::from_utf8_lossy(&got).into_owned(), false),
        }
    }
}

/// The first bytes of the answer, up to `within`.
async fn read_head(stream: &mut TcpStream, within: Duration) -> String {
    let mut buf = [0_u8; 4096];
    match tokio::time::timeout(within, stream.read(&mut buf)).await {
        Ok(Ok(n)) => String::from_utf8_lossy(&buf[..n]).into_owned(),
        _ => String::new(),
    }
}

#[tokio::test]
async fn an_anonymous_upload_is_refused_before_its_body_is_read() {
    let app = app_with(|_| {}).await;
    // 60 MB announced, none sent: a server that read the body first would wait forever.
    let mut stream = connect(&app).await;
    stream
        .write_all(
            b"POST /v1/maps HTTP/1.1\r\nHost: test\r\nContent-Type: multipart/form-data; \
              boundary=x\r\nContent-Length: 62914560\r\n\r\n--x\r\n",
        )
        .await
        .unwrap();
    let head = read_head(&mut stream, Duration::from_secs(5)).await;
    assert!(head.starts_with("HTTP/1.1 401"), "{head:?}");
    // A wrong token too.
    let mut stream = connect(&app).await;
    stream
        .write_all(
            b"PUT /store?default HTTP/1.1\r\nHost: test\r\nAuthorization: Bearer nope\r\n\
              Content-Type: text/turtle\r\nContent-Length: 62914560\r\n\r\n",
        )
        .await
        .unwrap();
    let head = read_head(&mut stream, Duration::from_secs(5)).await;
    assert!(head.starts_with("HTTP/1.1 401"), "{head:?}");
    app.stop().await;
}

#[tokio::test]
async fn bodies_are_limited_per_route_and_role() {
    let app = app_with(|c| c.small_body_limit_bytes = 64 * 1024).await;
    let big = "x".repeat(200 * 1024);
    // A plan does not need 200 kB: 413 before the handler, naming the limit.
    let plan = app
        .client
        .post(format!("{}/v1/plan", app.address))
        .bearer_auth(ROBOT)
        .header("content-type", "application/json")
        .body(big.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(plan.status(), 413);
    let body: serde_json::Value = plan.json().await.unwrap();
    assert_eq!(body["error"]["code"], "payload_too_large");
    assert!(
        body["error"]["message"].as_str().unwrap().contains("65536"),
        "{body}"
    );
    // A chunked body (no length declared) is cut at the limit too.
    let mut stream = connect(&app).await;
    let head = format!(
        "POST /v1/places/F0/objects HTTP/1.1\r\nHost: test\r\nAuthorization: Bearer {ROBOT}\r\n\
         Content-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n"
    );
    stream.write_all(head.as_bytes()).await.unwrap();
    let chunk = format!("{:x}\r\n{}\r\n", 50 * 1024, " ".repeat(50 * 1024));
    for _ in 0..4 {
        // The server may answer and close before the last chunk.
        if stream.write_all(chunk.as_bytes()).await.is_err() {
            break;
        }
    }
    let _ = stream.write_all(b"0\r\n\r\n").await;
    let answer = read_head(&mut stream, Duration::from_secs(5)).await;
    assert!(answer.starts_with("HTTP/1.1 413"), "chunked: {answer:?}");
    // An engineer's Graph Store write may be large: the same bytes are parsed (and refused
    // as Turtle), not cut.
    let write = app
        .client
        .post(format!("{}/store?graph=urn:x:big", app.address))
        .bearer_auth(ENGINEER)
        .header("content-type", "text/turtle")
        .body(big.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(write.status(), 400, "{}", write.text().await.unwrap());
    // A robot's is not (it may not write at all).
    let write = app
        .client
        .post(format!("{}/store?graph=urn:x:big", app.address))
        .bearer_auth(ROBOT)
        .header("content-type", "text/turtle")
        .body(big)
        .send()
        .await
        .unwrap();
    assert_eq!(write.status(), 413);
    app.stop().await;
}

#[tokio::test]
async fn slow_headers_and_idle_connections_are_closed() {
    let app = app_with(|c| c.header_read_timeout_s = 0.5).await;
    let started = Instant::now();
    // Slowloris: half a request head, then nothing.
    let mut slow = connect(&app).await;
    slow.write_all(b"GET /healthz HTTP/1.1\r\nHost: te")
        .await
        .unwrap();
    // Meanwhile others are served.
    assert_eq!(app.get("/healthz").await.status(), 200);
    let (_, closed) = read_until_closed(&mut slow, Duration::from_secs(5)).await;
    assert!(closed, "a trickling client kept its connection");
    assert!(started.elapsed() < Duration::from_secs(3));
    // An idle kept-alive connection is closed after one request too.
    let mut idle = connect(&app).await;
    idle.write_all(b"GET /healthz HTTP/1.1\r\nHost: test\r\n\r\n")
        .await
        .unwrap();
    let (answer, closed) = read_until_closed(&mut idle, Duration::from_secs(5)).await;
    assert!(answer.starts_with("HTTP/1.1 200"), "{answer:?}");
    assert!(closed, "an idle connection stayed open");
    app.stop().await;
}

#[tokio::test]
async fn requests_beyond_the_in_flight_limit_are_shed_with_retry_after() {
    let app = app_with(|c| c.max_in_flight = 2).await;
    // Two requests whose bodies never come hold both places.
    let mut held = Vec::new();
    for _ in 0..2 {
        let mut stream = connect(&app).await;
        let head = format!(
            "POST /v1/plan HTTP/1.1\r\nHost: test\r\nAuthorization: Bearer {ROBOT}\r\n\
             Content-Type: application/json\r\nContent-Length: 1000\r\n\r\n{{"
        );
        stream.write_all(head.as_bytes()).await.unwrap();
        held.push(stream);
    }
    tokio::time::sleep(Duration::from_millis(200)).await;
    let shed = app
        .client
        .get(format!("{}/v1/robots", app.address))
        .bearer_auth(ROBOT)
        .send()
        .await
        .unwrap();
    assert_eq!(shed.status(), 503);
    assert_eq!(shed.headers()["retry-after"], "1");
    let body: serde_json::Value = shed.json().await.unwrap();
    assert_eq!(body["error"]["code"], "overloaded");
    // Probes are never shed.
    assert_eq!(app.get("/healthz").await.status(), 200);
    assert_eq!(app.get("/readyz").await.status(), 200);
    drop(held);
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let again = app
            .client
            .get(format!("{}/v1/robots", app.address))
            .bearer_auth(ROBOT)
            .send()
            .await
            .unwrap();
        if again.status() == 200 {
            break;
        }
        assert!(Instant::now() < deadline, "the held places never came back");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    app.stop().await;
}

#[tokio::test]
async fn invented_methods_do_not_grow_the_metrics() {
    let app = app_with(|_| {}).await;
    for i in 0..50 {
        let method = reqwest::Method::from_bytes(format!("BREW{i}").as_bytes()).unwrap();
        app.client
            .request(method, format!("{}/v1/robots", app.address))
            .send()
            .await
            .unwrap();
    }
    let text = app.get("/metrics").await.text().await.unwrap();
    assert!(!text.contains("BREW"), "invented methods became labels");
    assert!(text.contains("method=\"other\""), "{text}");
    app.stop().await;
}

#[tokio::test]
async fn answers_are_capped_per_role_with_507() {
    let app = app_with(|c| c.robot_max_result_bytes = 4096).await;
    let query = "SELECT * WHERE { GRAPH ?g { ?a ?b ?c } GRAPH ?h { ?d ?e ?f } } LIMIT 2000";
    let ask = |token: &'static str| {
        app.client
            .post(format!("{}/sparql", app.address))
            .bearer_auth(token)
            .header("content-type", "application/sparql-query")
            .header("accept", "application/sparql-results+json")
            .body(query)
            .send()
    };
    let robot = ask(ROBOT).await.unwrap();
    let status = robot.status();
    if status != 507 {
        let text = robot.text().await.unwrap();
        panic!(
            "{status}: {} bytes: {}",
            text.len(),
            &text[..text.len().min(300)]
        );
    }
    let body: serde_json::Value = robot.json().await.unwrap();
    assert_eq!(body["error"]["code"], "result_too_large");
    assert!(
        body["error"]["message"].as_str().unwrap().contains("4096"),
        "{body}"
    );
    let engineer = ask(ENGINEER).await.unwrap();
    assert_eq!(engineer.status(), 200);
    assert!(engineer.bytes().await.unwrap().len() > 4096);
    // The Graph Store too.
    let dump = app
        .client
        .get(format!("{}/store", app.address))
        .bearer_auth(ROBOT)
        .header("accept", "application/n-quads")
        .send()
        .await
        .unwrap();
    assert_eq!(dump.status(), 507);
    app.stop().await;
}

#[tokio::test]
async fn readiness_holds_under_concurrent_probes_and_reveals_no_paths() {
    let app = app_with(|_| {}).await;
    let mut probes = tokio::task::JoinSet::new();
    for _ in 0..30 {
        let (client, url) = (app.client.clone(), format!("{}/readyz", app.address));
        probes.spawn(async move { client.get(url).send().await.unwrap() });
    }
    while let Some(response) = probes.join_next().await {
        let response = response.unwrap();
        assert_eq!(response.status(), 200);
        let text = response.text().await.unwrap();
        let data_dir = app.data_dir.display().to_string();
        assert!(!text.contains(&data_dir), "a probe sees a path: {text}");
        assert!(!text.contains("path"), "{text}");
        assert!(!text.contains("location"), "{text}");
    }
    // An engineer sees where things are.
    let full: serde_json::Value = app
        .client
        .get(format!("{}/readyz", app.address))
        .bearer_auth(ENGINEER)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(full["checks"]["data_dir"]["path"].is_string(), "{full}");
    app.stop().await;
}

#[tokio::test]
async fn a_failed_check_names_the_component_without_its_path() {
    let temp = tempfile::tempdir().unwrap();
    let blocker = temp.path().join("not-a-directory");
    std::fs::write(&blocker, b"x").unwrap();
    let data_dir = blocker.join("data");
    let app = spawn_app_with(|c| c.data_dir = data_dir, Some(temp)).await;
    let response = app.get("/readyz").await;
    assert_eq!(response.status(), 503);
    let text = response.text().await.unwrap();
    assert!(text.contains("data_dir: not writable"), "{text}");
    assert!(!text.contains("not-a-directory"), "{text}");
    app.stop().await;
}

#[tokio::test]
async fn a_loop_of_places_is_a_422_naming_it_on_every_walk() {
    let app = app_with(|_| {}).await;
    // An engineer's mistake: two rooms each inside the other.
    let update = r#"PREFIX tosm: <https://mentalsim.dev/ontology/tosm#>
        DELETE { GRAPH ?g { ?a tosm:isDirectlyInsideOf ?f . ?b tosm:isDirectlyInsideOf ?f } }
        INSERT { GRAPH ?g { ?a tosm:isDirectlyInsideOf ?b . ?b tosm:isDirectlyInsideOf ?a } }
        WHERE { GRAPH ?g { ?a tosm:identifier "F0-office" ; tosm:isDirectlyInsideOf ?f .
                           ?b tosm:identifier "F0-storage" ; tosm:isDirectlyInsideOf ?f } }"#;
    let updated = app
        .client
        .post(format!("{}/sparql", app.address))
        .bearer_auth(ENGINEER)
        .header("content-type", "application/sparql-update")
        .body(update)
        .send()
        .await
        .unwrap();
    assert_eq!(updated.status(), 204, "{}", updated.text().await.unwrap());
    let check = |response: reqwest::Response| async move {
        let status = response.status();
        let body: serde_json::Value = response.json().await.unwrap();
        assert_eq!(status, 422, "{body}");
        let message = body["error"]["message"].as_str().unwrap().to_owned();
        assert!(message.contains("loops"), "{message}");
        assert!(
            message.contains("F0-office") || message.contains("office"),
            "{message}"
        );
    };
    let started = Instant::now();
    check(
        app.client
            .get(format!("{}/v1/places/F0-office/world.sdf", app.address))
            .bearer_auth(ROBOT)
            .send()
            .await
            .unwrap(),
    )
    .await;
    check(
        app.client
            .post(format!("{}/v1/plan", app.address))
            .bearer_auth(ROBOT)
            .json(&serde_json::json!({
                "robot": "R-001", "place": "F0-storage",
                "start": {"x": 1.0, "y": 1.0, "yaw": 0.0}, "goal": {"x": 2.0, "y": 1.0}
            }))
            .send()
            .await
            .unwrap(),
    )
    .await;
    check(
        app.client
            .get(format!(
                "{}/v1/places/F0-office/on-demand?robot=R-001",
                app.address
            ))
            .bearer_auth(ROBOT)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert!(started.elapsed() < Duration::from_secs(10));
    app.stop().await;
}

#[tokio::test]
async fn robots_may_not_federate_queries_with_service() {
    let app = app_with(|_| {}).await;
    let query = "SELECT * WHERE { SERVICE <http://169.254.169.254/latest/> { ?s ?p ?o } }";
    let refused = app
        .client
        .post(format!("{}/sparql", app.address))
        .bearer_auth(ROBOT)
        .header("content-type", "application/sparql-query")
        .body(query)
        .send()
        .await
        .unwrap();
    assert_eq!(refused.status(), 403);
    // The word in a literal is no SERVICE clause.
    let fine = app
        .client
        .post(format!("{}/sparql", app.address))
        .bearer_auth(ROBOT)
        .header("content-type", "application/sparql-query")
        .header("accept", "application/sparql-results+json")
        .body("ASK { ?s ?p \"SERVICE\" }")
        .send()
        .await
        .unwrap();
    assert_eq!(fine.status(), 200);
    app.stop().await;
}

#[tokio::test]
async fn deep_nesting_is_refused_and_the_service_lives_on() {
    let app = app_with(|_| {}).await;
    let deep = format!("SELECT * WHERE {}{}", "{".repeat(5000), "}".repeat(5000));
    let refused = app
        .client
        .post(format!("{}/sparql", app.address))
        .bearer_auth(ROBOT)
        .header("content-type", "application/sparql-query")
        .body(deep)
        .send()
        .await
        .unwrap();
    assert_eq!(refused.status(), 400);
    let body: serde_json::Value = refused.json().await.unwrap();
    assert!(
        body["error"]["message"].as_str().unwrap().contains("deep"),
        "{body}"
    );
    let jsonld = format!("{}{}", "[".repeat(5000), "]".repeat(5000));
    let refused = app
        .client
        .put(format!("{}/store?graph=urn:x:deep", app.address))
        .bearer_auth(ENGINEER)
        .header("content-type", "application/ld+json")
        .body(jsonld)
        .send()
        .await
        .unwrap();
    assert_eq!(refused.status(), 400);
    assert_eq!(app.get("/healthz").await.status(), 200);
    app.stop().await;
}

#[tokio::test]
async fn robots_change_only_their_own_objects_with_known_classes_at_a_bounded_rate() {
    let app = app_with(|_| {}).await;
    let report = |token: &'static str, id: &str, class: &str, place: &str| {
        app.client
            .post(format!("{}/v1/places/{place}/objects", app.address))
            .bearer_auth(token)
            .json(&serde_json::json!({
                "id": id, "class": class,
                "pose": {"x": 1.0, "y": 1.0, "yaw": 0.0},
                "shape": {"type": "box", "length": 0.5, "width": 0.5, "height": 0.5}
            }))
            .send()
    };
    let first = report(ROBOT, "crate-1", "Table", "F0-office")
        .await
        .unwrap();
    assert_eq!(first.status(), 201, "{}", first.text().await.unwrap());
    let other = report(OTHER_ROBOT, "crate-1", "Table", "F0-office")
        .await
        .unwrap();
    assert_eq!(other.status(), 403, "{}", other.text().await.unwrap());
    let again = report(ROBOT, "crate-1", "Chair", "F0-office")
        .await
        .unwrap();
    assert_eq!(again.status(), 200, "{}", again.text().await.unwrap());
    // An engineer may correct any object.
    let fixed = report(ENGINEER, "crate-1", "Table", "F0-office")
        .await
        .unwrap();
    assert_eq!(fixed.status(), 200, "{}", fixed.text().await.unwrap());
    // Classes come from the ontology.
    let invented = report(ROBOT, "thing-1", "http://example.org/Anything", "F0-office")
        .await
        .unwrap();
    assert_eq!(invented.status(), 422, "{}", invented.text().await.unwrap());
    // Found by the fuzzer: an invented term in the TOSM namespace is no class either.
    let invented = report(
        ROBOT,
        "thing-2",
        "https://mentalsim.dev/ontology/tosm#Sofa*",
        "F0-office",
    )
    .await
    .unwrap();
    assert_eq!(invented.status(), 422, "{}", invented.text().await.unwrap());
    // A burst beyond the allowance is refused with Retry-After (reports to an unknown place
    // cost the allowance too, and nothing else).
    let mut limited = None;
    for _ in 0..150 {
        let r = report(OTHER_ROBOT, "x", "Table", "no-such-place")
            .await
            .unwrap();
        if r.status() == 429 {
            limited = Some(r);
            break;
        }
        assert_eq!(r.status(), 404);
    }
    let limited = limited.expect("no 429 within 150 reports");
    assert!(limited.headers().contains_key("retry-after"));
    // The other robot is not affected.
    let mine = report(ROBOT, "crate-2", "Table", "F0-office")
        .await
        .unwrap();
    assert_eq!(mine.status(), 201, "{}", mine.text().await.unwrap());
    app.stop().await;
}

#[tokio::test]
async fn updates_to_the_inferred_graph_are_refused_as_the_graph_store_refuses_them() {
    let app = app_with(|_| {}).await;
    let update = |text: &'static str| {
        app.client
            .post(format!("{}/sparql", app.address))
            .bearer_auth(ENGINEER)
            .header("content-type", "application/sparql-update")
            .body(text)
            .send()
    };
    let refused = update(
        "INSERT DATA { GRAPH <https://mentalsim.dev/graph/inferred> { <urn:x:a> <urn:x:b> <urn:x:c> } }",
    )
    .await
    .unwrap();
    assert_eq!(refused.status(), 409, "{}", refused.text().await.unwrap());
    // Reading it in WHERE while writing elsewhere is fine.
    let fine = update(
        "INSERT { GRAPH <urn:x:copy> { ?s a ?c } } WHERE { GRAPH <https://mentalsim.dev/graph/inferred> { ?s a ?c } FILTER(false) }",
    )
    .await
    .unwrap();
    assert_eq!(fine.status(), 204, "{}", fine.text().await.unwrap());
    app.stop().await;
}

#[tokio::test]
async fn event_streams_are_limited_per_token() {
    let app = app_with(|c| c.worker_concurrency = 0).await;
    let created = app
        .client
        .post(format!("{}/v1/jobs", app.address))
        .bearer_auth(ENGINEER)
        .json(&serde_json::json!({
            "kind": "train",
            "payload": {"robot": "R-001", "place": "F0", "minutes": 1}
        }))
        .send()
        .await
        .unwrap();
    assert_eq!(created.status(), 201, "{}", created.text().await.unwrap());
    let job: serde_json::Value = created.json().await.unwrap();
    let url = format!(
        "{}/v1/jobs/{}/events",
        app.address,
        job["id"].as_str().unwrap()
    );
    let open = || app.client.get(&url).bearer_auth(ROBOT).send();
    let mut streams = Vec::new();
    for _ in 0..8 {
        let stream = open().await.unwrap();
        assert_eq!(stream.status(), 200);
        streams.push(stream);
    }
    let refused = open().await.unwrap();
    assert_eq!(refused.status(), 429, "{}", refused.text().await.unwrap());
    // Another token still gets one.
    let other = app
        .client
        .get(&url)
        .bearer_auth(OTHER_ROBOT)
        .send()
        .await
        .unwrap();
    assert_eq!(other.status(), 200);
    // A closed stream gives its place back.
    drop(streams.pop());
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let again = open().await.unwrap();
        if again.status() == 200 {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "the closed stream's place never came back"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    app.stop().await;
}
