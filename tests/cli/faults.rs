//! Faults on the real binary: `mentalsim serve` killed (SIGKILL) in the middle of concurrent
//! Graph Store writes and object reports. After a restart on the same data directory every
//! write that was acknowledged with 2xx is there, and the inferred graph is what the asserted
//! graphs entail (the same as after a fresh rebuild). And the data directory's disk filled up
//! (a small tmpfs mounted for the test) during writes and during a training: clear 507s, a
//! store that reopens intact, a training that goes back to the queue and resumes.

use std::collections::BTreeSet;
use std::process::Stdio;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use ::reqwest::blocking::Client;
use fixtures::wait::consistently;
use serde_json::{Value, json};

use super::served::Serve;

const INFERRED: &str = "https://mentalsim.dev/graph/inferred";

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
    let mut server = Serve::new()
        .data_dir(&data)
        .env("MENTALSIM_WORKER_CONCURRENCY", "0")
        .start();
    let (url, token) = (&server.url, &server.token);
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
    server.kill_now(); // SIGKILL
    for w in writers {
        w.join().unwrap();
    }
    let acknowledged = acknowledged.lock().unwrap().clone();
    assert!(acknowledged.len() < 200, "the kill came after every write");

    let server = Serve::new()
        .data_dir(&data)
        .env("MENTALSIM_WORKER_CONCURRENCY", "0")
        .start();
    let (url, token) = (&server.url, &server.token);
    for what in &acknowledged {
        if let Some(graph) = what.strip_prefix("graph:") {
            let lines = graph_lines(&client, url, token, graph);
            assert_eq!(lines.len(), 2, "acknowledged write {graph} lost: {lines:?}");
        } else if let Some(id) = what.strip_prefix("object:") {
            let ask = format!(
                "ASK {{ GRAPH ?g {{ ?o <https://mentalsim.dev/ontology/tosm#identifier> \"{id}\" }} }}"
            );
            let answer: Value = client
                .post(format!("{url}/sparql"))
                .bearer_auth(token)
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
    let inferred = graph_lines(&client, url, token, INFERRED);
    let scratch = client
        .put(format!("{url}/store"))
        .query(&[("graph", "urn:x:scratch")])
        .bearer_auth(token)
        .header("content-type", "text/turtle")
        .body("<urn:x:a> <urn:x:b> <urn:x:c> .")
        .send()
        .unwrap();
    assert!(scratch.status().is_success());
    let deleted = client
        .delete(format!("{url}/store"))
        .query(&[("graph", "urn:x:scratch")])
        .bearer_auth(token)
        .send()
        .unwrap();
    assert!(deleted.status().is_success());
    let rebuilt = graph_lines(&client, url, token, INFERRED);
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

/// A small tmpfs mounted for one test; unmounted when dropped.
struct Tmpfs(std::path::PathBuf);

impl Tmpfs {
    /// Mounts a tmpfs of `mib` MiB in a fresh directory, or says why it cannot.
    fn mount(mib: u32) -> Result<(tempfile::TempDir, Self), String> {
        let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
        let status = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={mib}m"), "tmpfs"])
            .arg(dir.path())
            .stderr(Stdio::null())
            .status()
            .map_err(|e| format!("`mount` cannot run: {e}"))?;
        if !status.success() {
            return Err("`mount -t tmpfs` failed (it needs root or CAP_SYS_ADMIN)".to_owned());
        }
        let path = dir.path().to_path_buf();
        Ok((dir, Self(path)))
    }

    /// Fills the filesystem until `leave` bytes are free (a real file of zeros, not a sparse
    /// one), or empties it again with `None`.
    fn fill(&self, leave: Option<u64>) {
        let filler = self.0.join("filler");
        let _ = std::fs::remove_file(&filler);
        let Some(leave) = leave else { return };
        let available = edge::disk::available_bytes(&self.0).unwrap();
        let mut left = available.saturating_sub(leave);
        let mut file = std::fs::File::create(&filler).unwrap();
        let chunk = vec![0u8; 1 << 20];
        while left > 0 {
            let n = usize::try_from(left.min(chunk.len() as u64)).unwrap();
            std::io::Write::write_all(&mut file, &chunk[..n]).unwrap();
            left -= n as u64;
        }
        file.sync_all().unwrap();
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount")
            .arg("-l")
            .arg(&self.0)
            .status();
    }
}

fn sparql_update(client: &Client, url: &str, token: &str, update: &str) -> (u16, Value) {
    let r = client
        .post(format!("{url}/sparql"))
        .bearer_auth(token)
        .header("content-type", "application/sparql-update")
        .body(update.to_owned())
        .send()
        .unwrap();
    let status = r.status().as_u16();
    (status, r.json().unwrap_or(Value::Null))
}

fn count(client: &Client, url: &str, token: &str, graph: &str) -> u64 {
    let answer: Value = client
        .post(format!("{url}/sparql"))
        .bearer_auth(token)
        .header("content-type", "application/sparql-query")
        .header("accept", "application/sparql-results+json")
        .body(format!(
            "SELECT (COUNT(*) AS ?n) WHERE {{ GRAPH <{graph}> {{ ?s ?p ?o }} }}"
        ))
        .send()
        .unwrap()
        .json()
        .unwrap();
    answer["results"]["bindings"][0]["n"]["value"]
        .as_str()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no count of {graph}: {answer}"))
}

fn import_map(client: &Client, url: &str, token: &str, name: &str) -> (u16, Value) {
    // A 200 × 200 floor: an empty room inside a wall.
    let mut pgm = b"P5\n200 200\n255\n".to_vec();
    pgm.extend((0..200 * 200).map(|i| {
        let (x, y) = (i % 200, i / 200);
        if x < 2 || y < 2 || x > 197 || y > 197 {
            0
        } else {
            254
        }
    }));
    let form = ::reqwest::blocking::multipart::Form::new()
        .text("name", name.to_owned())
        .text(
            "yaml",
            "image: room.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n\
             occupied_thresh: 0.65\nfree_thresh: 0.196\n",
        )
        .part(
            "image",
            ::reqwest::blocking::multipart::Part::bytes(pgm).file_name("room.pgm"),
        );
    let r = client
        .post(format!("{url}/v1/maps"))
        .bearer_auth(token)
        .multipart(form)
        .send()
        .unwrap();
    let status = r.status().as_u16();
    (status, r.json().unwrap_or(Value::Null))
}

fn job(client: &Client, url: &str, token: &str, id: &str) -> Value {
    client
        .get(format!("{url}/v1/jobs/{id}"))
        .bearer_auth(token)
        .send()
        .unwrap()
        .json()
        .unwrap()
}

fn wait_job(
    client: &Client,
    url: &str,
    token: &str,
    id: &str,
    within: Duration,
    done: impl Fn(&Value) -> bool,
) -> Value {
    let deadline = Instant::now() + within;
    loop {
        let j = job(client, url, token, id);
        if done(&j) {
            return j;
        }
        assert!(Instant::now() < deadline, "job never got there: {j:#}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn a_full_disk_gets_clear_errors_keeps_the_store_intact_and_training_resumes_when_space_returns() {
    let (_dir, disk) = match Tmpfs::mount(160) {
        Ok(mounted) => mounted,
        Err(why) => {
            fixtures::missing(format!("a small tmpfs for the disk-full test: {why}"));
            return;
        }
    };
    let data = disk.0.join("data");
    let client = Client::builder()
        .timeout(Duration::from_secs(30))
        .build()
        .unwrap();
    let mut rows = String::new();
    let triples = |n: usize| {
        let body: String = (0..n)
            .map(|i| format!("<urn:x:s{i}> <urn:x:p> \"{}\" .\n", "x".repeat(40)))
            .collect();
        format!("INSERT DATA {{ GRAPH <urn:x:full> {{ {body} }} }}")
    };

    // 1. No reserve: writes run into the full disk itself (RocksDB's log append fails).
    {
        let server = Serve::new()
            .data_dir(&data)
            .env("MENTALSIM_WORKER_CONCURRENCY", "0")
            .env("MENTALSIM_MIN_FREE_BYTES", "0")
            .start();
        let (url, token) = (&server.url, &server.token);
        assert_eq!(import_map(&client, url, token, "before").0, 201);
        disk.fill(Some(96 * 1024));
        let update = triples(900); // 57 kB: passes the free-space check, not RocksDB's log
        let (status, body) = sparql_update(&client, url, token, &update);
        assert_eq!(
            (status, &body["error"]["code"]),
            (507, &json!("storage_full")),
            "{body}"
        );
        let (status, body) = import_map(&client, url, token, "during");
        assert_eq!(
            (status, &body["error"]["code"]),
            (507, &json!("storage_full")),
            "{body}"
        );
        rows.push_str(&format!(
            "update and map import on a full disk: {status} storage_full\n"
        ));
        // Reads go on.
        assert_eq!(count(&client, url, token, "urn:x:full"), 0);
        disk.fill(None);
        // Space is back: the store reopens and takes writes again.
        let (status, body) = sparql_update(&client, url, token, &update);
        assert_eq!(status, 204, "{body}");
        assert_eq!(import_map(&client, url, token, "after").0, 201);
        assert_eq!(count(&client, url, token, "urn:x:full"), 900);
    }

    // 2. A restart finds the store intact; with a reserve, a training on a filling disk goes
    // back to the queue (its attempt not counted) and resumes from its checkpoint.
    let server = Serve::new()
        .data_dir(&data)
        .env("MENTALSIM_WORKER_CONCURRENCY", "1")
        .env("MENTALSIM_MIN_FREE_BYTES", (24u64 << 20).to_string())
        .env("MENTALSIM_JOB_RETRY_BASE_S", "1")
        .start();
    let (url, token) = (&server.url, &server.token);
    assert_eq!(count(&client, url, token, "urn:x:full"), 900);
    for floor in ["before", "after"] {
        let r = client
            .get(format!("{url}/v1/places/{floor}"))
            .bearer_auth(token)
            .send()
            .unwrap();
        assert_eq!(r.status(), 200, "floor {floor} lost");
    }
    let submitted: Value = client
        .post(format!("{url}/v1/jobs"))
        .bearer_auth(token)
        .json(&json!({
            "kind": "train",
            "payload": {
                "robot": "R-001", "place": "after", "minutes": 0.3, "seed": 3,
                "config": {
                    "td3": {"hidden": [16, 16], "batch_size": 32}, "envs": 2,
                    "buffer_capacity": 20000, "random_steps": 100, "demo_steps": 500,
                    "bc_steps": 100, "critic_warmup_steps": 100, "eval_every": 1000000,
                    "eval_episodes": 3, "checkpoint_every_s": 1.0
                }
            }
        }))
        .send()
        .unwrap()
        .json()
        .unwrap();
    let id = submitted["id"].as_str().expect("a job id").to_owned();
    let checkpoint = data.join("checkpoints").join(&id).join("checkpoint");
    let deadline = Instant::now() + Duration::from_secs(120);
    while !checkpoint.exists() {
        assert!(
            Instant::now() < deadline,
            "no checkpoint: {:#}",
            job(&client, url, token, &id)
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    disk.fill(Some(8 << 20)); // under the reserve, still room for the job database
    let deferred = wait_job(&client, url, token, &id, Duration::from_secs(30), |j| {
        j["state"] == "queued"
            && j["error"]
                .as_str()
                .is_some_and(|e| e.contains("disk space"))
    });
    let (status, body) = import_map(&client, url, token, "later");
    assert_eq!(
        (status, &body["error"]["code"]),
        (507, &json!("storage_full")),
        "{body}"
    );
    rows.push_str(&format!(
        "training on a full disk: back to the queue ({}); map import {status}\n",
        deferred["error"]
    ));
    // Stays queued while the disk is full (it is claimed, sees no room, goes back).
    consistently(
        "the training not finishing while the disk is full",
        Duration::from_secs(3),
    )
    .every(Duration::from_millis(100))
    .holds(|| {
        let j = job(&client, url, token, &id);
        if j["state"] == "succeeded" {
            Err(j)
        } else {
            Ok(())
        }
    });
    disk.fill(None);
    let finished = wait_job(&client, url, token, &id, Duration::from_secs(240), |j| {
        j["state"] != "queued" && j["state"] != "running"
    });
    assert_eq!(finished["state"], "succeeded", "{finished:#}");
    assert_eq!(
        finished["attempts"], 1,
        "a full disk used up an attempt: {finished:#}"
    );
    assert!(
        finished["result"]["sessions"].as_u64().unwrap_or(0) >= 2,
        "the training did not resume from its checkpoint: {finished:#}"
    );
    assert_eq!(import_map(&client, url, token, "later").0, 201);
    eprint!("{rows}");
}
