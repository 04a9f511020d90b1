//! The service with its knowledge graph in a remote SPARQL 1.1 store: a real `oxigraph serve`
//! (PyPI `oxigraph`, installed into the project venv by scripts/setup) on a free port with a
//! temporary directory. Every feature goes through our endpoints; what landed in the remote
//! is checked by asking the remote directly.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use reqwest::Method;
use serde_json::{Value, json};

use crate::helpers::{spawn_app_with, url_encode};

const TOSM: &str = "https://mentalsim.dev/ontology/tosm#";
const INFERRED: &str = "https://mentalsim.dev/graph/inferred";

/// The `oxigraph` server binary: `OXIGRAPH_BIN`, the project venv, or the PATH.
fn oxigraph_binary() -> Option<PathBuf> {
    if let Some(bin) = std::env::var_os("OXIGRAPH_BIN") {
        return Some(PathBuf::from(bin));
    }
    let mut candidates = Vec::new();
    if let Some(venv) = std::env::var_os("VIRTUAL_ENV") {
        candidates.push(PathBuf::from(venv).join("bin/oxigraph"));
    }
    candidates.push(
        PathBuf::from(
            std::env::var("CARGO_MANIFEST_DIR")
                .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_owned()),
        )
        .join(".venv/bin/oxigraph"),
    );
    if let Some(path) = std::env::var_os("PATH") {
        candidates.extend(std::env::split_paths(&path).map(|d| d.join("oxigraph")));
    }
    candidates.into_iter().find(|p| p.is_file())
}

/// A running `oxigraph serve`, killed when dropped.
struct OxigraphServer {
    child: Child,
    url: String,
    _dir: tempfile::TempDir,
}

impl OxigraphServer {
    async fn start(binary: &PathBuf) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let child = Command::new(binary)
            .args(["serve", "--location"])
            .arg(dir.path())
            .args(["--bind", &format!("127.0.0.1:{port}")])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let server = Self {
            child,
            url: format!("http://127.0.0.1:{port}"),
            _dir: dir,
        };
        let client = reqwest::Client::new();
        let started = Instant::now();
        loop {
            let probe = client
                .get(format!("{}/query", server.url))
                .query(&[("query", "ASK {}")])
                .send()
                .await;
            if probe.is_ok_and(|r| r.status().is_success()) {
                return server;
            }
            assert!(
                started.elapsed() < Duration::from_secs(30),
                "oxigraph serve did not start on {}",
                server.url
            );
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    }

    /// ASK straight at the remote, bypassing the service.
    async fn ask(&self, query: &str) -> bool {
        let response = reqwest::Client::new()
            .post(format!("{}/query", self.url))
            .header("content-type", "application/sparql-query")
            .header("accept", "application/sparql-results+json")
            .body(query.to_owned())
            .send()
            .await
            .unwrap();
        assert!(response.status().is_success(), "{query}");
        let body: Value = response.json().await.unwrap();
        body["boolean"].as_bool().unwrap()
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for OxigraphServer {
    fn drop(&mut self) {
        self.kill();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_feature_works_with_the_graph_in_an_oxigraph_server() {
    let Some(binary) = oxigraph_binary() else {
        fixtures::missing(
            "the `oxigraph` binary (pip install oxigraph into .venv, or set OXIGRAPH_BIN)",
        );
        return;
    };
    let mut remote = OxigraphServer::start(&binary).await;
    let temp = tempfile::tempdir().unwrap();
    let data_dir = temp.path().join("data");
    let url = remote.url.clone();
    let app = spawn_app_with(
        |c| {
            c.data_dir = data_dir.clone();
            c.store_url = Some(url.clone());
            c.query_deadline_s = 10.0;
        },
        Some(temp),
    )
    .await;

    // Bundled data went into the remote on first start, with its entailments.
    assert!(
        remote
            .ask("ASK { GRAPH <https://mentalsim.dev/graph/environments/sample-building> { ?s ?p ?o } }")
            .await
    );
    assert!(
        remote
            .ask(&format!(
                "ASK {{ GRAPH <{INFERRED}> {{ ?x a <{TOSM}Place> }} }}"
            ))
            .await
    );
    assert!(
        !app.data_dir.join("oxigraph").exists(),
        "no embedded store is opened"
    );
    // Where the store is shows to an engineer only.
    let ready: Value = app.get("/readyz").await.json().await.unwrap();
    assert_eq!(ready["status"], "ready", "{ready}");
    assert!(ready["checks"]["graph_store"].get("location").is_none());
    let ready: Value = app
        .request(Method::GET, "/readyz")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(
        ready["checks"]["graph_store"]["location"],
        format!("{}/query", remote.url)
    );

    // A query through our /sparql.
    let response = app
        .sparql_query(&format!(
            "SELECT (COUNT(DISTINCT ?p) AS ?n) WHERE {{ GRAPH ?g {{ ?p a <{TOSM}Room> }} }}"
        ))
        .await;
    assert_eq!(response.status(), 200);
    let body: Value = response.json().await.unwrap();
    let rooms: usize = body["results"]["bindings"][0]["n"]["value"]
        .as_str()
        .unwrap()
        .parse()
        .unwrap();
    assert!(rooms > 0, "{body}");
    // Negotiated formats other than the remote's first choice, and CONSTRUCT.
    let csv = app
        .request(Method::GET, "/sparql?query=SELECT%20%3Fs%20WHERE%20%7B%20GRAPH%20%3Fg%20%7B%20%3Fs%20%3Fp%20%3Fo%20%7D%20%7D%20LIMIT%202")
        .header("accept", "text/csv")
        .send()
        .await
        .unwrap();
    assert_eq!(csv.status(), 200);
    assert!(csv.text().await.unwrap().starts_with("s\r\n"));
    let turtle = app
        .request(Method::POST, "/sparql")
        .header("content-type", "application/sparql-query")
        .header("accept", "text/turtle")
        .body(format!(
            "CONSTRUCT {{ ?r a <{TOSM}Robot> }} WHERE {{ GRAPH ?g {{ ?r a <{TOSM}Robot> }} }}"
        ))
        .send()
        .await
        .unwrap();
    assert_eq!(turtle.status(), 200);
    assert!(turtle.text().await.unwrap().contains("differential-robot"));

    // An update through our /sparql is in the remote, and its entailments are too.
    let update = app.sparql_update(&format!(
            "INSERT DATA {{ GRAPH <urn:test:g> {{ <urn:test:lab> a <{TOSM}Room> ; <{TOSM}name> \"lab\" }} }}"
        ),
    )
    .await;
    assert_eq!(update.status(), 204, "{}", update.text().await.unwrap());
    assert!(
        remote
            .ask("ASK { GRAPH <urn:test:g> { <urn:test:lab> ?p \"lab\" } }")
            .await
    );
    assert!(
        remote
            .ask(&format!(
                "ASK {{ GRAPH <{INFERRED}> {{ <urn:test:lab> a <{TOSM}Place> }} }}"
            ))
            .await,
        "the inferred graph was rebuilt after the update"
    );

    // Graph Store Protocol: PUT, GET, DELETE.
    let put = app
        .request(Method::PUT, "/store?graph=urn:test:gsp")
        .header("content-type", "text/turtle")
        .body("<urn:test:a> <urn:test:p> \"v\" .")
        .send()
        .await
        .unwrap();
    assert_eq!(put.status(), 201);
    assert!(
        remote
            .ask("ASK { GRAPH <urn:test:gsp> { <urn:test:a> <urn:test:p> \"v\" } }")
            .await
    );
    let got = app
        .request(Method::GET, "/store?graph=urn:test:gsp")
        .header("accept", "application/n-triples")
        .send()
        .await
        .unwrap();
    assert_eq!(got.status(), 200);
    assert_eq!(
        got.text().await.unwrap().trim(),
        "<urn:test:a> <urn:test:p> \"v\" ."
    );
    let deleted = app
        .request(Method::DELETE, "/store?graph=urn:test:gsp")
        .send()
        .await
        .unwrap();
    assert_eq!(deleted.status(), 204);
    let missing = app
        .request(Method::GET, "/store?graph=urn:test:gsp")
        .send()
        .await
        .unwrap();
    assert_eq!(missing.status(), 404);

    // Places and robots browse from the remote.
    let places: Vec<Value> = app
        .request(Method::GET, "/v1/places")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(places.iter().any(|p| p["kind"] == "floor"));
    let robots: Vec<Value> = app
        .request(Method::GET, "/v1/robots")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    // The paper's robot and the TIAGo-like base.
    assert_eq!(robots.len(), 2);

    // An object report lands in the remote with its entailments, and in the next on-demand
    // database.
    let room = places
        .iter()
        .find(|p| p["kind"] == "room" && !p["connected"].as_array().unwrap().is_empty())
        .unwrap();
    let room_iri = room["iri"].as_str().unwrap();
    let neighbour = room["connected"][0].as_str().unwrap();
    let boundary = room["boundary"].as_array().unwrap();
    let n = boundary.len() as f64;
    let cx = boundary.iter().map(|p| p[0].as_f64().unwrap()).sum::<f64>() / n;
    let cy = boundary.iter().map(|p| p[1].as_f64().unwrap()).sum::<f64>() / n;
    let report = json!({
        "id": "vending-7",
        "class": "VendingMachine",
        "pose": {"x": cx, "y": cy},
        "shape": {"type": "box", "length": 0.8, "width": 0.7, "height": 1.8}
    });
    let created = app
        .request(
            Method::POST,
            &format!("/v1/places/{}/objects", url_encode(room_iri)),
        )
        .json(&report)
        .send()
        .await
        .unwrap();
    assert_eq!(created.status(), 201, "{}", created.text().await.unwrap());
    let again = app
        .request(
            Method::POST,
            &format!("/v1/places/{}/objects", url_encode(room_iri)),
        )
        .json(&report)
        .send()
        .await
        .unwrap();
    assert_eq!(again.status(), 200, "the same id updates");
    let object = format!("{room_iri}/objects/vending-7");
    assert!(
        remote
            .ask(&format!(
                "ASK {{ GRAPH <https://mentalsim.dev/graph/perceived> {{ <{object}> a <{TOSM}VendingMachine> }} }}"
            ))
            .await
    );
    assert!(
        remote
            .ask(&format!(
                "ASK {{ GRAPH <{INFERRED}> {{ <{object}> a <{TOSM}Object> }} }}"
            ))
            .await,
        "the report's entailments are materialised"
    );
    let mission =
        json!({"robot": "R-001", "start": {"place": room_iri}, "goals": [{"place": neighbour}]});
    let on_demand = app
        .request(Method::POST, "/v1/on-demand")
        .header("accept", "application/n-triples")
        .json(&mission)
        .send()
        .await
        .unwrap();
    assert_eq!(on_demand.status(), 200);
    let body = on_demand.text().await.unwrap();
    assert!(
        body.contains("objects/vending-7>"),
        "the report is included"
    );
    assert!(body.contains("differential-robot"));
    assert_eq!(
        body.matches("objects/vending-7> <https://mentalsim.dev/ontology/tosm#hasShape>")
            .count(),
        1,
        "updated, not duplicated"
    );

    // A map import goes to the remote.
    let yaml = "image: m.pgm\nresolution: 0.5\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
    let mut pgm = b"P5\n8 6\n255\n".to_vec();
    pgm.extend((0..48).map(|i| if i % 5 == 0 { 0u8 } else { 254 }));
    let form = reqwest::multipart::Form::new()
        .text("name", "remote-lab")
        .text("yaml", yaml)
        .part(
            "image",
            reqwest::multipart::Part::bytes(pgm).file_name("m.pgm"),
        );
    let imported = app
        .request(Method::POST, "/v1/maps")
        .multipart(form)
        .send()
        .await
        .unwrap();
    assert_eq!(imported.status(), 201, "{}", imported.text().await.unwrap());
    assert!(
        remote
            .ask(&format!(
                "ASK {{ GRAPH <https://mentalsim.dev/graph/maps/remote-lab> {{ <https://mentalsim.dev/data/maps/remote-lab> a <{TOSM}Floor> }} }}"
            ))
            .await
    );
    let floor = app
        .request(
            Method::GET,
            &format!(
                "/v1/places/{}",
                url_encode("https://mentalsim.dev/data/maps/remote-lab")
            ),
        )
        .send()
        .await
        .unwrap();
    assert_eq!(floor.status(), 200);

    // The remote goes away: readiness and queries say so, naming it; nothing panics.
    remote.kill();
    let not_ready = app.get("/readyz").await;
    assert_eq!(not_ready.status(), 503);
    let body: Value = not_ready.json().await.unwrap();
    let reason = body["reason"].as_str().unwrap();
    // A probe learns which component, not where it is; an engineer learns both.
    assert!(reason.contains("graph_store"), "{reason}");
    assert!(!reason.contains(&remote.url), "{reason}");
    let body: Value = app
        .request(Method::GET, "/readyz")
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let reason = body["reason"].as_str().unwrap();
    assert!(reason.contains(&remote.url), "{reason}");
    let down = app
        .sparql_query("SELECT * WHERE { ?s ?p ?o } LIMIT 1")
        .await;
    assert!(
        down.status() == 502 || down.status() == 503,
        "{}",
        down.status()
    );
    let body: Value = down.json().await.unwrap();
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains(&remote.url),
        "{body}"
    );
    let places = app.request(Method::GET, "/v1/places").send().await.unwrap();
    assert_eq!(places.status(), 503);
    app.stop().await;
}

/// People counts with the graph in a remote store: each request reads the estimate the last one
/// wrote (not a stale copy of the remote) and the estimate lands in the remote's perceived graph.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn people_counts_accumulate_in_an_oxigraph_server() {
    let Some(binary) = oxigraph_binary() else {
        fixtures::missing(
            "the `oxigraph` binary (pip install oxigraph into .venv, or set OXIGRAPH_BIN)",
        );
        return;
    };
    let remote = OxigraphServer::start(&binary).await;
    let temp = tempfile::tempdir().unwrap();
    let data_dir = temp.path().join("data");
    let url = remote.url.clone();
    let app = spawn_app_with(
        |c| {
            c.data_dir = data_dir.clone();
            c.store_url = Some(url.clone());
        },
        Some(temp),
    )
    .await;
    let mut estimate = Vec::new();
    for count in [2.0, 4.0, 9.0] {
        let r = app
            .request(Method::POST, "/v1/places/F0-hall/observations")
            .json(&json!({"observations": [{"count": count, "observed_at": "2025-05-06T12:30:00+02:00"}]}))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200);
        let body: Value = r.json().await.unwrap();
        estimate.push((
            body["estimate"]["people"].as_f64().unwrap(),
            body["by_hour"][0]["observations"].as_u64().unwrap(),
        ));
    }
    // The mean of 2, 4 and 9 at each step: 2, 3, 5.
    for ((people, n), (want, want_n)) in estimate.iter().zip([(2.0, 1), (3.0, 2), (5.0, 3)]) {
        assert!((people - want).abs() < 1e-9 && *n == want_n, "{estimate:?}");
    }
    let hall = "https://mentalsim.dev/data/buildings/sample-building/floors/0/hall";
    assert!(
        remote
            .ask(&format!(
                "ASK {{ GRAPH <https://mentalsim.dev/graph/perceived> {{ <{hall}/people/estimate/hour/12> <{TOSM}observationCount> 3 }} }}"
            ))
            .await
    );
    app.stop().await;
}
