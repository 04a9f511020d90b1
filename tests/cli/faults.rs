//! Faults on the real binary: `mentalsim serve` killed (SIGKILL) in the middle of concurrent
//! Graph Store writes and object reports. After a restart on the same data directory every
//! write that was acknowledged with 2xx is there, and the inferred graph is what the asserted
//! graphs entail (the same as after a fresh rebuild).

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::mentalsim;

const INFERRED: &str = "https://mentalsim.dev/graph/inferred";

struct Killed(Option<Child>);

impl Drop for Killed {
    fn drop(&mut self) {
        if let Some(child) = &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

fn start(data: &Path) -> (Killed, String, String) {
    let mut child = mentalsim()
        .args(["serve", "--bind", "127.0.0.1:0", "--data-dir"])
        .arg(data)
        .env("MENTALSIM_WORKER_CONCURRENCY", "0")
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut reader = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    let url = loop {
        line.clear();
        assert!(reader.read_line(&mut line).unwrap() > 0, "no URL printed");
        if let Some(url) = line.split_whitespace().find(|w| w.starts_with("http://")) {
            break url.to_owned();
        }
    };
    // Keep draining stdout so the child never blocks on a full pipe.
    std::thread::spawn(move || for _ in reader.lines() {});
    let token = std::fs::read_to_string(data.join("admin.token"))
        .unwrap()
        .trim()
        .to_owned();
    (Killed(Some(child)), url, token)
}

/// The sorted N-Triples lines of `graph`.
fn graph_lines(
    client: &::reqwest::blocking::Client,
    url: &str,
    token: &str,
    graph: &str,
) -> BTreeSet<String> {
    let r = client
        .get(format!("{url}/store"))
        .query(&[("graph", graph)])
        .bearer_auth(token)
        .header("accept", "application/n-triples")
        .send()
        .unwrap();
    assert_eq!(r.status(), 200, "GET {graph}");
    r.text()
        .unwrap()
        .lines()
        .map(str::to_owned)
        .filter(|l| !l.trim().is_empty())
        .collect()
}

#[test]
fn acknowledged_writes_survive_sigkill_and_inference_matches_the_asserted_graphs() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("data");
    let (mut server, url, token) = start(&data);
    let client = ::reqwest::blocking::Client::builder()
        .timeout(Duration::from_secs(30))
        .build()
        .unwrap();
    let acknowledged: Arc<Mutex<Vec<String>>> = Arc::default();
    let mut writers = Vec::new();
    for w in 0..8 {
        let (url, token, client, acknowledged) = (
            url.clone(),
            token.clone(),
            client.clone(),
            acknowledged.clone(),
        );
        writers.push(std::thread::spawn(move || {
            for i in 0..25 {
                let n = w * 25 + i;
                let ok = if n % 4 == 0 {
                    // An object report (it lands in the perceived graph and is inferred over).
                    client
                        .post(format!("{url}/v1/places/F0-office/objects"))
                        .bearer_auth(&token)
                        .json(&serde_json::json!({
                            "id": format!("box-{n}"), "class": "Table",
                            "pose": {"x": 1.0, "y": 1.0, "yaw": 0.0},
                            "shape": {"type": "box", "length": 0.3, "width": 0.3, "height": 0.3}
                        }))
                        .send()
                        .is_ok_and(|r| r.status().is_success())
                        .then(|| format!("object:box-{n}"))
                } else {
                    let graph = format!("urn:x:fault:{n}");
                    let body = format!(
                        "<urn:x:s{n}> a <https://mentalsim.dev/ontology/tosm#Room> ; \
                         <https://mentalsim.dev/ontology/tosm#identifier> \"fault-{n}\" ."
                    );
                    client
                        .put(format!("{url}/store"))
                        .query(&[("graph", &graph)])
                        .bearer_auth(&token)
                        .header("content-type", "text/turtle")
                        .body(body)
                        .send()
                        .is_ok_and(|r| r.status().is_success())
                        .then(|| format!("graph:{graph}"))
                };
                match ok {
                    Some(what) => acknowledged.lock().unwrap().push(what),
                    None => return, // the server is gone
                }
            }
        }));
    }
    // Kill it in the middle: once a third of the 200 writes are acknowledged.
    let deadline = Instant::now() + Duration::from_secs(120);
    while acknowledged.lock().unwrap().len() < 66 {
        assert!(Instant::now() < deadline, "the writes never got going");
        std::thread::sleep(Duration::from_millis(2));
    }
    let mut child = server.0.take().unwrap();
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    for w in writers {
        w.join().unwrap();
    }
    let acknowledged = acknowledged.lock().unwrap().clone();
    assert!(acknowledged.len() < 200, "the kill came after every write");

    let (_server, url, token) = start(&data);
    for what in &acknowledged {
        if let Some(graph) = what.strip_prefix("graph:") {
            let lines = graph_lines(&client, &url, &token, graph);
            assert_eq!(lines.len(), 2, "acknowledged write {graph} lost: {lines:?}");
        } else if let Some(id) = what.strip_prefix("object:") {
            let ask = format!(
                "ASK {{ GRAPH ?g {{ ?o <https://mentalsim.dev/ontology/tosm#identifier> \"{id}\" }} }}"
            );
            let answer: serde_json::Value = client
                .post(format!("{url}/sparql"))
                .bearer_auth(&token)
                .header("content-type", "application/sparql-query")
                .header("accept", "application/sparql-results+json")
                .body(ask)
                .send()
                .unwrap()
                .json()
                .unwrap();
            assert_eq!(answer["boolean"], true, "acknowledged report {id} lost");
        }
    }
    // The inferred graph after the restart equals a fresh rebuild's (a write triggers one).
    let inferred = graph_lines(&client, &url, &token, INFERRED);
    let scratch = client
        .put(format!("{url}/store"))
        .query(&[("graph", "urn:x:scratch")])
        .bearer_auth(&token)
        .header("content-type", "text/turtle")
        .body("<urn:x:a> <urn:x:b> <urn:x:c> .")
        .send()
        .unwrap();
    assert!(scratch.status().is_success());
    let deleted = client
        .delete(format!("{url}/store"))
        .query(&[("graph", "urn:x:scratch")])
        .bearer_auth(&token)
        .send()
        .unwrap();
    assert!(deleted.status().is_success());
    let rebuilt = graph_lines(&client, &url, &token, INFERRED);
    assert_eq!(
        inferred.symmetric_difference(&rebuilt).count(),
        0,
        "the inferred graph after the crash differs from what the asserted graphs entail"
    );
    eprintln!(
        "{} of 200 writes acknowledged before SIGKILL; all present after restart",
        acknowledged.len()
    );
}
