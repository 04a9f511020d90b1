//! Liveness (`/healthz`), readiness (`/readyz`) and metrics of a process and its backing
//! stores.
//!
//! Readiness is one [`Readiness`] list of named [`Check`]s, the same for `mentalsim serve`
//! (data directory, graph store, job database) and `mentalsim worker` (job database, knowledge
//! service, checkpoint directory): 200 `{"status": "ready", "checks": {...}}` when every check
//! passes, else 503 `{"status": "not_ready", "reason": "<name>: <why>; ...", "checks": {...}}`,
//! each check `{"ok": bool, <what was checked>, "reason"?: string}`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use axum::extract::State;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::{Json, Router, routing::get};
use queue::JobDatabase;
use serde::Serialize;
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

/// This process's metrics in Prometheus' text format.
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
async fn readyz(
    State(components): State<Arc<Components>>,
    headers: axum::http::HeaderMap,
) -> Response {
    let full = components
        .knowledge()
        .tokens
        .require(&headers, edge::Role::Engineer)
        .is_ok();
    let data_dir = writable(components.data_dir()).await;
    let store = match components.store().await {
        Ok(store) => {
            let location = Detail::Location(store.location().to_owned());
            match tokio::task::spawn_blocking(move || store.check()).await {
                Ok(Ok(())) => Check::pass().with(location),
                Ok(Err(e)) => Check::fail(e.to_string()).with(location),
                Err(e) => Check::fail(format!("check task failed: {e}")),
            }
        }
        Err(reason) => Check::fail(reason),
    };
    let jobs = job_database(components.jobs().await).await;
    Readiness::default()
        .with("data_dir", data_dir)
        .with("graph_store", store)
        .with("job_database", jobs)
        .respond(full)
}

/// What a check looked at, shown whether it passed or not.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Detail {
    /// A directory (`"path"`).
    Path(PathBuf),
    /// Where the graph store is (`"location"`).
    Location(String),
    /// A service's URL (`"url"`).
    Url(String),
    /// Migrations applied (`"migrations"`).
    Migrations(usize),
}

/// One readiness check: whether it passed, what it looked at, and why it failed.
///
/// What it looked at and the full reason (paths, URLs, errors) are shown to engineers only;
/// anyone else (a load balancer's probe) sees the check's name and a short `summary`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Check {
    /// It passed.
    pub ok: bool,
    /// What it looked at (flattened into the check's object).
    #[serde(flatten)]
    pub detail: Option<Detail>,
    /// Why it failed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Why it failed, in words that name no path, URL or credential.
    #[serde(skip)]
    pub summary: &'static str,
}

impl Check {
    /// A check that passed.
    pub fn pass() -> Self {
        Self {
            ok: true,
            detail: None,
            reason: None,
            summary: "",
        }
    }

    /// A check that failed, and why (summarised as "unavailable").
    pub fn fail(reason: impl Into<String>) -> Self {
        Self::fail_as("unavailable", reason)
    }

    /// A check that failed: `summary` for anyone, `reason` for engineers and the log.
    pub fn fail_as(summary: &'static str, reason: impl Into<String>) -> Self {
        Self {
            ok: false,
            detail: None,
            reason: Some(reason.into()),
            summary,
        }
    }

    /// The same check, saying what it looked at.
    pub fn with(mut self, detail: Detail) -> Self {
        self.detail = Some(detail);
        self
    }

    /// What anyone may see: whether it passed, its summary, and counts (never paths or URLs).
    fn public(&self) -> serde_json::Value {
        let mut value = json!({ "ok": self.ok });
        if let Some(Detail::Migrations(n)) = self.detail {
            value["migrations"] = json!(n);
        }
        if !self.ok {
            value["reason"] = json!(self.summary);
        }
        value
    }
}

/// A process's readiness: its checks by name (the keys of `/readyz`'s `checks`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Readiness {
    checks: BTreeMap<&'static str, Check>,
}

impl Readiness {
    /// The list with `check` under `name`.
    pub fn with(mut self, name: &'static str, check: Check) -> Self {
        self.checks.insert(name, check);
        self
    }

    /// Every check passed.
    pub fn is_ready(&self) -> bool {
        self.checks.values().all(|c| c.ok)
    }

    /// The failing checks, `name: reason` joined by `; ` (empty when ready).
    pub fn reason(&self) -> String {
        self.checks
            .iter()
            .filter(|(_, c)| !c.ok)
            .map(|(name, c)| format!("{name}: {}", c.reason.as_deref().unwrap_or("failed")))
            .collect::<Vec<_>>()
            .join("; ")
    }
}

impl Readiness {
    /// 200 when every check passed, else 503 naming each failing check and why: in full
    /// (paths, URLs, errors) when `full`, for an engineer, else by summary only. A failure is
    /// logged in full either way.
    pub fn respond(self, full: bool) -> Response {
        let ready = self.is_ready();
        if !ready {
            tracing::warn!(reason = %self.reason(), "not ready");
        }
        let (status, label) = if ready {
            (StatusCode::OK, "ready")
        } else {
            (StatusCode::SERVICE_UNAVAILABLE, "not_ready")
        };
        let mut body = if full {
            json!({ "status": label, "checks": self.checks })
        } else {
            let checks: serde_json::Map<String, serde_json::Value> = self
                .checks
                .iter()
                .map(|(name, c)| ((*name).to_owned(), c.public()))
                .collect();
            json!({ "status": label, "checks": checks })
        };
        if !ready {
            body["reason"] = json!(if full { self.reason() } else { self.summary() });
        }
        (status, Json(body)).into_response()
    }

    /// The failing checks, `name: summary` joined by `; `.
    fn summary(&self) -> String {
        self.checks
            .iter()
            .filter(|(_, c)| !c.ok)
            .map(|(name, c)| format!("{name}: {}", c.summary))
            .collect::<Vec<_>>()
            .join("; ")
    }
}

/// The job database answers, with every migration this build embeds applied.
pub(crate) async fn job_database(db: Result<&JobDatabase, String>) -> Check {
    match db {
        Ok(db) => match db.status().await {
            Ok(s) if s.applied_migrations == s.expected_migrations => {
                Check::pass().with(Detail::Migrations(s.applied_migrations))
            }
            Ok(s) => Check::fail_as(
                "migrations pending",
                format!(
                    "{} of {} migrations applied",
                    s.applied_migrations, s.expected_migrations
                ),
            ),
            Err(e) => Check::fail(e.to_string()),
        },
        Err(reason) => Check::fail(reason),
    }
}

/// `dir` takes writes: a probe file (named after this process and probe, as several workers
/// and concurrent probes may share the directory) is created, synced and removed — the only
/// reliable way to know (permissions, read-only mounts, a full disk, a path that is not a
/// directory).
pub(crate) async fn writable(dir: &Path) -> Check {
    static PROBES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let probe_number = PROBES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let path = dir.to_owned();
    let result = tokio::task::spawn_blocking(move || -> std::io::Result<()> {
        use std::io::Write;
        std::fs::create_dir_all(&path)?;
        let probe = path.join(format!(
            ".readyz-probe-{}-{probe_number}",
            std::process::id()
        ));
        let mut file = std::fs::File::create(&probe)?;
        file.write_all(b"ok")?;
        file.sync_all()?;
        std::fs::remove_file(&probe)
    })
    .await;
    let check = match result {
        Ok(Ok(())) => Check::pass(),
        Ok(Err(e)) => Check::fail_as("not writable", format!("not writable: {e}")),
        Err(e) => Check::fail_as("not writable", format!("write probe failed: {e}")),
    };
    check.with(Detail::Path(dir.to_owned()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_serialize_as_readyz_shows_them() {
        let ready = Readiness::default()
            .with("job_database", Check::pass().with(Detail::Migrations(3)))
            .with(
                "data_dir",
                Check::fail("not writable: denied").with(Detail::Path("/d".into())),
            )
            .with("graph_store", Check::fail("closed"));
        assert_eq!(
            serde_json::to_value(&ready.checks).unwrap(),
            json!({
                "job_database": {"ok": true, "migrations": 3},
                "data_dir": {"ok": false, "path": "/d", "reason": "not writable: denied"},
                "graph_store": {"ok": false, "reason": "closed"},
            })
        );
        assert!(!ready.is_ready());
        assert_eq!(
            ready.reason(),
            "data_dir: not writable: denied; graph_store: closed"
        );
        assert!(Readiness::default().with("x", Check::pass()).is_ready());
    }
}
