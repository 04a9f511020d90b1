//! Prometheus metrics: one process-wide recorder, and request counts and latencies by matched route.

use std::sync::OnceLock;
use std::time::{Duration, Instant};

use axum::extract::{MatchedPath, Request};
use axum::middleware::Next;
use axum::response::Response;
use metrics_exporter_prometheus::{Matcher, PrometheusBuilder, PrometheusHandle};

/// Latency buckets in seconds: from sub-millisecond SPARQL lookups to minute-long CONSTRUCTs.
const LATENCY_BUCKETS: &[f64] = &[
    0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0,
    60.0,
];

static HANDLE: OnceLock<PrometheusHandle> = OnceLock::new();

/// The process-wide Prometheus handle, installing the recorder on first use.
///
/// A process has one global `metrics` recorder, so several apps started in one test process
/// share it; their counts add up, which is what a scrape of one process would show anyway.
pub fn handle() -> &'static PrometheusHandle {
    HANDLE.get_or_init(|| {
        let builder = PrometheusBuilder::new()
            .set_buckets_for_metric(
                Matcher::Full("http_request_duration_seconds".to_owned()),
                LATENCY_BUCKETS,
            )
            .unwrap_or_else(|_| PrometheusBuilder::new());
        let recorder = builder.build_recorder();
        let handle = recorder.handle();
        // Another recorder may already be installed (a host program embedding us); then we
        // still render our own handle, which simply stays empty.
        let _ = metrics::set_global_recorder(recorder);
        start_upkeep(handle.clone());
        handle
    })
}

/// How often pending histogram samples are folded into their buckets.
const UPKEEP_INTERVAL: Duration = Duration::from_secs(5);

/// A recorder built by `build_recorder` (not `install`) keeps every histogram sample in a
/// pending list until a scrape renders it: without a Prometheus scraping `/metrics`, memory
/// would grow with every request. One thread folds them in every [`UPKEEP_INTERVAL`].
fn start_upkeep(handle: PrometheusHandle) {
    let spawned = std::thread::Builder::new()
        .name(UPKEEP_THREAD.to_owned())
        .spawn(move || {
            loop {
                std::thread::sleep(UPKEEP_INTERVAL);
                handle.run_upkeep();
            }
        });
    if let Err(e) = spawned {
        tracing::error!(error = %e, "cannot start the metrics upkeep thread; histogram samples will pile up until /metrics is scraped");
    }
}

/// The upkeep thread's name.
const UPKEEP_THREAD: &str = "metrics-upkeep";

/// Middleware recording `http_requests_total` and `http_request_duration_seconds`, labelled by
/// method, matched route template (never the raw path, which would explode cardinality) and status.
pub async fn track(request: Request, next: Next) -> Response {
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map(|p| p.as_str().to_owned())
        .unwrap_or_else(|| "unmatched".to_owned());
    let method = method_label(request.method());
    let started = Instant::now();
    let response = next.run(request).await;
    let status = response.status().as_u16().to_string();
    let labels = [
        ("method", method.to_owned()),
        ("route", route),
        ("status", status),
    ];
    metrics::counter!("http_requests_total", &labels).increment(1);
    metrics::histogram!("http_request_duration_seconds", &labels)
        .record(started.elapsed().as_secs_f64());
    response
}

/// The method as a label from a closed set: an invented method (any token is a valid HTTP
/// method) folds into `other`, so clients cannot grow the label set, and memory, at will.
fn method_label(method: &http::Method) -> &'static str {
    use http::Method;
    match *method {
        Method::GET => "GET",
        Method::HEAD => "HEAD",
        Method::POST => "POST",
        Method::PUT => "PUT",
        Method::DELETE => "DELETE",
        Method::PATCH => "PATCH",
        Method::OPTIONS => "OPTIONS",
        _ => "other",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn invented_methods_share_one_label() {
        let invented = http::Method::from_bytes(b"BREW").unwrap();
        assert_eq!(method_label(&invented), "other");
        assert_eq!(method_label(&http::Method::POST), "POST");
    }

    /// Regression: without upkeep, every request's latency sample stayed in memory until a
    /// scrape.
    #[test]
    fn the_handle_comes_with_an_upkeep_thread() {
        handle();
        let running = || {
            let threads = std::fs::read_dir("/proc/self/task").expect("linux /proc");
            threads.filter_map(Result::ok).any(|task| {
                std::fs::read_to_string(task.path().join("comm"))
                    .is_ok_and(|comm| comm.trim() == UPKEEP_THREAD)
            })
        };
        // The thread names itself once it runs.
        let started = Instant::now();
        while !running() {
            assert!(
                started.elapsed() < Duration::from_secs(5),
                "no {UPKEEP_THREAD} thread"
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}
