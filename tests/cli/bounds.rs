//! Bounds proven on the real binary, where the process is the unit: a plan whose client hangs
//! up stops rehearsing (its own process's `plan_rehearsals_running` gauge), and a worker that
//! the knowledge service would refuse is not ready.

use std::io::Write;
use std::net::TcpStream;
use std::time::{Duration, Instant};

use fixtures::wait::consistently;
use serde_json::{Value, json};

use super::served::{Serve, Worker};

/// The value of the gauge `name` in the service's `/metrics` (0 when absent).
fn gauge(client: &::reqwest::blocking::Client, url: &str, name: &str) -> f64 {
    let text = client
        .get(format!("{url}/metrics"))
        .send()
        .unwrap()
        .text()
        .unwrap();
    text.lines()
        .find(|l| l.starts_with(name) && l[name.len()..].starts_with(' '))
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0)
}

/// A point the robot may stand on near the centroid of `place`.
fn free_point(client: &::reqwest::blocking::Client, url: &str, token: &str, place: &str) -> Value {
    let v: Value = client
        .get(format!("{url}/v1/places/{place}"))
        .bearer_auth(token)
        .send()
        .unwrap()
        .json()
        .unwrap();
    let pts = v["boundary"].as_array().unwrap();
    let n = pts.len() as f64;
    let x = pts.iter().map(|p| p[0].as_f64().unwrap()).sum::<f64>() / n;
    let y = pts.iter().map(|p| p[1].as_f64().unwrap()).sum::<f64>() / n;
    let probe = json!({"robot": "R-001", "place": "F0", "start": {"x": x, "y": y}, "goal": {"x": x, "y": y}});
    let answer: Value = client
        .post(format!("{url}/v1/plan"))
        .bearer_auth(token)
        .json(&probe)
        .send()
        .unwrap()
        .json()
        .unwrap();
    let hint = &answer["error"]["details"]["nearest_free"];
    if hint.is_object() {
        json!({"x": hint["x"], "y": hint["y"]})
    } else {
        json!({"x": x, "y": y})
    }
}

#[test]
fn a_plan_whose_client_hangs_up_stops_rehearsing() {
    let service = Serve::new()
        .env("MENTALSIM_WORKER_CONCURRENCY", "0")
        .start();
    let (url, token) = (&service.url, &service.token);
    let client = ::reqwest::blocking::Client::new();
    let a = free_point(&client, url, token, "F0-living-room");
    let b = free_point(&client, url, token, "F0-hall");
    // A plan that takes long: a thousand goals back and forth across the floor.
    let goals: Vec<Value> = (0..1000)
        .map(|i| if i % 2 == 0 { b.clone() } else { a.clone() })
        .collect();
    let body = json!({
        "robot": "R-001", "place": "F0",
        "start": {"x": a["x"], "y": a["y"], "yaw": 0.0},
        "goals": goals,
        "options": {"trajectory_stride": 0}
    })
    .to_string();
    let address = url.trim_start_matches("http://");
    let mut stream = TcpStream::connect(address).unwrap();
    write!(
        stream,
        "POST /v1/plan HTTP/1.1\r\nHost: {address}\r\nAuthorization: Bearer {token}\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let deadline = Instant::now() + Duration::from_secs(30);
    while gauge(&client, url, "plan_rehearsals_running") < 1.0 {
        assert!(Instant::now() < deadline, "the rehearsal never started");
        std::thread::sleep(Duration::from_millis(10));
    }
    // Let it run a little, then hang up.
    consistently(
        "the rehearsal running until the hang-up (if not, make the plan longer)",
        Duration::from_millis(300),
    )
    .holds(|| match gauge(&client, url, "plan_rehearsals_running") {
        1.0 => Ok(()),
        running => Err(format!("plan_rehearsals_running {running}")),
    });
    let hung_up = Instant::now();
    drop(stream);
    while gauge(&client, url, "plan_rehearsals_running") > 0.0 {
        assert!(
            hung_up.elapsed() < Duration::from_secs(2),
            "the rehearsal went on after its client hung up"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    eprintln!(
        "rehearsal stopped {:.0} ms after the client hung up (polling every 5 ms)",
        hung_up.elapsed().as_secs_f64() * 1000.0
    );
}

#[test]
fn a_worker_the_knowledge_service_would_refuse_is_not_ready() {
    let service = Serve::new()
        .env("MENTALSIM_WORKER_CONCURRENCY", "0")
        .start();
    let url = &service.url;
    let dir = tempfile::tempdir().unwrap();
    let client = ::reqwest::blocking::Client::new();
    for (case, token) in [
        ("no knowledge token configured", None),
        (
            "the knowledge service rejects the worker's token",
            Some("not-the-token-of-this-service"),
        ),
    ] {
        let mut worker = Worker::new(url, dir.path().join(format!("worker-{}", token.is_some())));
        if let Some(t) = token {
            worker = worker.env("MENTALSIM_KNOWLEDGE_TOKEN", t);
        }
        let worker = worker.start();
        let ready = client.get(format!("{}/readyz", worker.url)).send().unwrap();
        assert_eq!(ready.status(), 503, "{case}");
        let body: Value = ready.json().unwrap();
        let reason = body["reason"].as_str().unwrap();
        assert!(reason.contains(case), "{case}: {body}");
        // The probe names the component, not where it is.
        assert!(!reason.contains(url.as_str()), "{body}");
        assert!(!body.to_string().contains("/worker-"), "{body}");
    }
}
