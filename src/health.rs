//! Liveness (`/healthz`) and readiness (`/readyz`) of the process and its backing stores.

use std::path::Path;
use std::sync::Arc;

use axum::extract::State;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::{Json, Router, routing::get};
use serde_json::json;

use crate::startup::Components;

/// The health routes.
pub fn router(components: Arc<Components>) -> Router {
    Router::new()
        .route("/healthz", get(healthz))
        .route("/readyz", get(readyz))
        .route("/metrics", get(metrics))
        .with_state(components)
}

/// The process is up and serving HTTP. Says nothing about the stores, by design: a liveness
/// probe that failed on a full disk would get a healthy process restarted in a loop.
pub(crate) async fn healthz() -> Json<serde_json::Value> {
    Json(json!({ "status": "ok", "version": env!("CARGO_PKG_VERSION") }))
}

pub(crate) async fn metrics() -> impl IntoResponse {
    (
        [(
            axum::http::header::CONTENT_TYPE,
            "text/plain; version=0.0.4",
        )],
        edge::metrics::handle().render(),
    )
}

/// Ready when the data directory takes writes, the graph store answers a query, and the job
/// database answers with every migration applied. Each check reports separately; a failing one
/// says why, and the answer is 503.
async fn readyz(State(components): State<Arc<Components>>) -> Response {
    let data_dir = match probe_writable(components.data_dir()).await {
        Ok(()) => json!({ "ok": true, "path": components.data_dir() }),
        Err(reason) => json!({ "ok": false, "path": components.data_dir(), "reason": reason }),
    };
    let store = match components.store().await {
        Ok(store) => {
            let location = store.location().to_owned();
            match tokio::task::spawn_blocking(move || store.check()).await {
                Ok(Ok(())) => json!({ "ok": true, "location": location }),
                Ok(Err(e)) => json!({ "ok": false, "location": location, "reason": e.to_string() }),
                Err(e) => json!({ "ok": false, "reason": format!("check task failed: {e}") }),
            }
        }
        Err(reason) => json!({ "ok": false, "reason": reason }),
    };
    let jobs = match components.jobs().await {
        Ok(db) => match db.status().await {
            Ok(s) if s.applied_migrations == s.expected_migrations => json!({
                "ok": true,
                "migrations": s.applied_migrations,
            }),
            Ok(s) => json!({
                "ok": false,
                "reason": format!(
                    "{} of {} migrations applied", s.applied_migrations, s.expected_migrations
                ),
            }),
            Err(e) => json!({ "ok": false, "reason": e.to_string() }),
        },
        Err(reason) => json!({ "ok": false, "reason": reason }),
    };
    let checks = json!({ "data_dir": data_dir, "graph_store": store, "job_database": jobs });
    readiness(checks)
}

/// `/readyz`'s answer from named checks (`{"name": {"ok": bool, "reason"?: ...}}`): 200 when
/// every check is ok, else 503 naming each failing check and its reason.
pub(crate) fn readiness(checks: serde_json::Value) -> Response {
    let failing: Vec<String> = checks
        .as_object()
        .into_iter()
        .flatten()
        .filter(|(_, v)| v["ok"] != true)
        .map(|(k, v)| format!("{k}: {}", v["reason"].as_str().unwrap_or("failed")))
        .collect();
    if failing.is_empty() {
        (
            StatusCode::OK,
            Json(json!({ "status": "ready", "checks": checks })),
        )
            .into_response()
    } else {
        (
            StatusCode::SERVICE_UNAVAILABLE,
            Json(json!({
                "status": "not_ready",
                "reason": failing.join("; "),
                "checks": checks,
            })),
        )
            .into_response()
    }
}

/// Creates, syncs and removes a small file: the only reliable way to know writes succeed
/// (permissions, read-only mounts, a full disk, a path that is not a directory).
async fn probe_writable(dir: &Path) -> Result<(), String> {
    let dir = dir.to_owned();
    let result = tokio::task::spawn_blocking(move || -> std::io::Result<()> {
        use std::io::Write;
        std::fs::create_dir_all(&dir)?;
        let probe = dir.join(".readyz-probe");
        let mut file = std::fs::File::create(&probe)?;
        file.write_all(b"ok")?;
        file.sync_all()?;
        std::fs::remove_file(&probe)
    })
    .await;
    match result {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(format!("data directory is not writable: {e}")),
        Err(e) => Err(format!("write probe failed: {e}")),
    }
}
