//! Liveness, readiness, metrics and the shared error format.

use crate::helpers::{spawn_app, spawn_app_with};

#[tokio::test]
async fn healthz_answers_200() {
    let app = spawn_app().await;
    let response = app.get("/healthz").await;
    assert_eq!(response.status(), 200);
    let body: serde_json::Value = response.json().await.unwrap();
    assert_eq!(body["status"], "ok");
    app.stop().await;
}

#[tokio::test]
async fn readyz_is_200_with_the_store_and_database_on_disk() {
    let app = spawn_app().await;
    let response = app.get("/readyz").await;
    assert_eq!(response.status(), 200);
    let body: serde_json::Value = response.json().await.unwrap();
    assert_eq!(body["status"], "ready", "{body}");
    assert_eq!(body["checks"]["graph_store"]["ok"], true);
    assert!(
        body["checks"]["job_database"]["migrations"]
            .as_u64()
            .unwrap()
            >= 1
    );
    // Real files on disk behind the answer: RocksDB's directory and the SQLite database.
    assert!(app.data_dir.join("oxigraph").join("CURRENT").is_file());
    assert!(app.data_dir.join("jobs.sqlite").is_file());
    app.stop().await;
}

#[tokio::test]
async fn readyz_is_503_with_a_reason_when_the_data_dir_is_not_writable() {
    // Tests may run as root, for whom permission bits do not stop writes; a data directory
    // below a regular file cannot be written by anyone.
    let temp = tempfile::tempdir().unwrap();
    let blocker = temp.path().join("not-a-directory");
    std::fs::write(&blocker, b"x").unwrap();
    let data_dir = blocker.join("data");
    let app = spawn_app_with(|c| c.data_dir = data_dir, Some(temp)).await;

    assert_eq!(app.get("/healthz").await.status(), 200, "liveness stays up");
    let response = app.get("/readyz").await;
    assert_eq!(response.status(), 503);
    let body: serde_json::Value = response.json().await.unwrap();
    assert_eq!(body["status"], "not_ready");
    let reason = body["reason"].as_str().unwrap();
    assert!(reason.contains("data_dir"), "{reason}");
    assert!(reason.contains("not writable"), "{reason}");
    assert_eq!(body["checks"]["graph_store"]["ok"], false);
    app.stop().await;
}

#[tokio::test]
async fn readyz_recovers_once_the_data_dir_becomes_writable() {
    let temp = tempfile::tempdir().unwrap();
    let blocker = temp.path().join("later");
    std::fs::write(&blocker, b"x").unwrap();
    let data_dir = blocker.join("data");
    let app = spawn_app_with(|c| c.data_dir = data_dir, Some(temp)).await;
    assert_eq!(app.get("/readyz").await.status(), 503);
    std::fs::remove_file(&blocker).unwrap();
    let response = app.get("/readyz").await;
    assert_eq!(response.status(), 200, "{}", response.text().await.unwrap());
    app.stop().await;
}

#[tokio::test]
async fn metrics_count_requests_by_matched_route() {
    let app = spawn_app().await;
    for _ in 0..3 {
        app.get("/healthz").await;
    }
    app.get("/no/such/route/12345").await;
    let text = app.get("/metrics").await.text().await.unwrap();
    let line = text
        .lines()
        .find(|l| {
            l.starts_with("http_requests_total{")
                && l.contains("route=\"/healthz\"")
                && l.contains("status=\"200\"")
        })
        .unwrap_or_else(|| panic!("no healthz counter in:\n{text}"));
    let count: f64 = line.rsplit(' ').next().unwrap().parse().unwrap();
    assert!(count >= 3.0, "{line}");
    assert!(text.contains("http_request_duration_seconds_bucket"));
    // Unknown paths are folded into one label, not one series per path.
    assert!(!text.contains("/no/such/route/12345"));
    assert!(text.contains("route=\"unmatched\""));
    app.stop().await;
}

#[tokio::test]
async fn unknown_route_is_a_json_404_with_a_request_id() {
    let app = spawn_app().await;
    // Without a token, not even which routes exist is answered.
    assert_eq!(app.get("/v1/nothing-here").await.status(), 401);
    let response = app
        .request(reqwest::Method::GET, "/v1/nothing-here")
        .send()
        .await
        .unwrap();
    assert_eq!(response.status(), 404);
    assert!(response.headers().contains_key("x-request-id"));
    let body: serde_json::Value = response.json().await.unwrap();
    assert_eq!(body["error"]["code"], "not_found");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("/v1/nothing-here")
    );
    app.stop().await;
}
