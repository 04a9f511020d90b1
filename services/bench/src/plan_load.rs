//! `mentalsim bench plan-load`: POST /v1/plan latency of a running service under concurrent
//! robot clients (a closed-loop load generator: each client sends its next request when the
//! previous one is answered).

use std::time::{Duration, Instant};

use serde::Serialize;

use crate::error::BenchError;

/// What to send and for how long.
#[derive(Debug, Clone)]
pub struct PlanLoadOptions {
    /// The service's base URL.
    pub url: String,
    /// A robot's or engineer's bearer token.
    pub token: String,
    /// Concurrent clients.
    pub clients: usize,
    /// Seconds of load.
    pub seconds: f64,
    /// The plan request every client sends.
    pub body: serde_json::Value,
    /// The service's process on this machine, whose CPU time is then measured.
    pub server_pid: Option<u32>,
}

/// The figures.
#[derive(Debug, Clone, Serialize)]
pub struct PlanLoadReport {
    /// Median latency of answered requests (200), milliseconds, as the client saw it.
    pub p50_ms: f64,
    /// 99th percentile, milliseconds.
    pub p99_ms: f64,
    /// Mean, milliseconds.
    pub mean_ms: f64,
    /// Median of the service's own time (`service_ms` in the answers), milliseconds.
    pub service_p50_ms: f64,
    /// Requests answered with 200.
    pub requests: u64,
    /// Requests that failed (transport error or any other status).
    pub errors: u64,
    /// The first error seen, if any.
    pub first_error: Option<String>,
    /// Answered requests per second.
    pub requests_per_s: f64,
    /// Clients.
    pub clients: usize,
    /// Seconds of load.
    pub seconds: f64,
    /// The service's CPU time (user + system, every thread) per answered plan, milliseconds
    /// (with `--server-pid`).
    pub server_cpu_ms_per_plan: Option<f64>,
    /// The load generator's own CPU time per answered plan, milliseconds: on the service's
    /// machine it takes that much from the cores the service plans on.
    pub client_cpu_ms_per_plan: Option<f64>,
}

/// CPU time (user + system) of process `pid` (`None`: this one) so far, milliseconds, from
/// `/proc/PID/stat` (fields 14 and 15, in the kernel's fixed 100 Hz user ticks); `None` where
/// it cannot be read.
fn cpu_ms(pid: Option<u32>) -> Option<f64> {
    let path = match pid {
        Some(p) => format!("/proc/{p}/stat"),
        None => "/proc/self/stat".to_owned(),
    };
    let stat = std::fs::read_to_string(path).ok()?;
    // The command name (field 2) is in parentheses and may hold spaces: count after it.
    let rest = &stat[stat.rfind(')')? + 1..];
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // `rest` starts at field 3, so fields 14 and 15 are its 12th and 13th.
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) * 10.0)
}

/// The one field of an answer the load generator reads (the rest is skipped, not built).
#[derive(serde::Deserialize)]
struct Answered {
    service_ms: Option<f64>,
}

/// A plan across the bundled sample building's ground floor: from the living room to the hall
/// (about 15 m of roadmap path), for the bundled robot.
pub fn default_request() -> serde_json::Value {
    serde_json::json!({
        "robot": "R-001",
        "place": "F0",
        "start": {"x": 1.275, "y": -3.925, "yaw": 0.0},
        "goal": {"x": -11.875, "y": -3.375},
        "options": {"trajectory_stride": 0}
    })
}

/// One client's latencies, service times, error count and first error.
type ClientResult = (Vec<f64>, Vec<f64>, u64, Option<String>);

/// Runs the load and measures.
pub fn run(opts: &PlanLoadOptions) -> Result<PlanLoadReport, BenchError> {
    if opts.clients == 0 || !(opts.seconds > 0.0 && opts.seconds.is_finite()) {
        return Err(BenchError::BadOption(
            "clients must be at least 1 and seconds positive".into(),
        ));
    }
    let endpoint = format!("{}/v1/plan", opts.url.trim_end_matches('/'));
    let client = reqwest::blocking::Client::builder()
        .timeout(Duration::from_secs(120))
        .pool_max_idle_per_host(opts.clients)
        .build()
        .map_err(|e| BenchError::BadOption(format!("HTTP client: {e}")))?;
    // One request first: a service that refuses the plan is reported, not measured.
    let probe = client
        .post(&endpoint)
        .bearer_auth(&opts.token)
        .json(&opts.body)
        .send()
        .map_err(|e| BenchError::BadOption(format!("cannot reach {endpoint}: {e}")))?;
    if !probe.status().is_success() {
        let status = probe.status();
        let text = probe.text().unwrap_or_default();
        return Err(BenchError::BadOption(format!(
            "the service refused the plan request ({status}): {text}"
        )));
    }
    if let Some(pid) = opts.server_pid
        && cpu_ms(Some(pid)).is_none()
    {
        return Err(BenchError::BadOption(format!(
            "--server-pid {pid}: no such process on this machine (/proc/{pid}/stat unreadable)"
        )));
    }
    let cpu_before = (opts.server_pid.and_then(|p| cpu_ms(Some(p))), cpu_ms(None));
    let deadline = Instant::now() + Duration::from_secs_f64(opts.seconds);
    let started = Instant::now();
    let results: Vec<ClientResult> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..opts.clients)
            .map(|_| {
                let client = client.clone();
                let endpoint = endpoint.clone();
                s.spawn(move || {
                    let (mut lat, mut service, mut errors, mut first) =
                        (Vec::new(), Vec::new(), 0u64, None);
                    while Instant::now() < deadline {
                        let t = Instant::now();
                        let r = client
                            .post(&endpoint)
                            .bearer_auth(&opts.token)
                            .json(&opts.body)
                            .send();
                        match r {
                            Ok(r) if r.status().is_success() => {
                                let answered = r.json::<Answered>().ok();
                                lat.push(t.elapsed().as_secs_f64() * 1000.0);
                                if let Some(ms) = answered.and_then(|a| a.service_ms) {
                                    service.push(ms);
                                }
                            }
                            Ok(r) => {
                                errors += 1;
                                first.get_or_insert_with(|| format!("status {}", r.status()));
                            }
                            Err(e) => {
                                errors += 1;
                                first.get_or_insert_with(|| e.to_string());
                            }
                        }
                    }
                    (lat, service, errors, first)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_default())
            .collect()
    });
    let wall = started.elapsed().as_secs_f64();
    let cpu_after = (opts.server_pid.and_then(|p| cpu_ms(Some(p))), cpu_ms(None));
    let mut lat: Vec<f64> = results.iter().flat_map(|r| r.0.iter().copied()).collect();
    let mut service: Vec<f64> = results.iter().flat_map(|r| r.1.iter().copied()).collect();
    let errors = results.iter().map(|r| r.2).sum();
    let first_error = results.iter().find_map(|r| r.3.clone());
    lat.sort_by(f64::total_cmp);
    service.sort_by(f64::total_cmp);
    let pct = |v: &[f64], p: f64| -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        #[allow(
            clippy::cast_possible_truncation,
            clippy::cast_sign_loss,
            reason = "a rank"
        )]
        let rank = ((p / 100.0) * v.len() as f64).ceil() as usize;
        v[rank.clamp(1, v.len()) - 1]
    };
    let n = lat.len() as f64;
    Ok(PlanLoadReport {
        p50_ms: pct(&lat, 50.0),
        p99_ms: pct(&lat, 99.0),
        mean_ms: lat.iter().sum::<f64>() / n.max(1.0),
        service_p50_ms: pct(&service, 50.0),
        requests: lat.len() as u64,
        errors,
        first_error,
        requests_per_s: n / wall,
        clients: opts.clients,
        seconds: opts.seconds,
        server_cpu_ms_per_plan: cpu_before
            .0
            .zip(cpu_after.0)
            .map(|(b, a)| (a - b) / n.max(1.0)),
        client_cpu_ms_per_plan: cpu_before
            .1
            .zip(cpu_after.1)
            .map(|(b, a)| (a - b) / n.max(1.0)),
    })
}
