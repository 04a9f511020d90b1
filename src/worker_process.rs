//! `mentalsim worker`: job runners alone, against a shared job database, taking worlds from a
//! knowledge service over HTTP. Serves `/healthz`, `/readyz` and `/metrics` for orchestrators.

use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::State;
use axum::response::Response;
use axum::routing::get;
use axum::{Json, Router};
use jobs::{HttpKnowledge, JobEnv};
use queue::{LazyQueue, Queue};
use serde_json::json;
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

use crate::config::Config;
use crate::health::{self, Check, Detail, Readiness};

struct Shared {
    queue: Arc<LazyQueue>,
    knowledge: HttpKnowledge,
    /// Every directory a job writes in, by the name of its readiness check.
    writes: Vec<(&'static str, PathBuf)>,
}

/// A bound worker process, ready to run.
pub struct WorkerProcess {
    listener: TcpListener,
    router: Router,
    shared: Arc<Shared>,
    env: Arc<JobEnv>,
    config: Config,
}

impl WorkerProcess {
    /// Checks the configuration (a knowledge URL is required), binds the health listener.
    pub async fn build(config: Config) -> anyhow::Result<Self> {
        let Some(url) = config.knowledge_url.clone() else {
            anyhow::bail!(
                "mentalsim worker needs the knowledge service's URL: set `knowledge_url` \
                 (--knowledge-url or MENTALSIM_KNOWLEDGE_URL)"
            );
        };
        if config.worker_concurrency == 0 {
            anyhow::bail!("`worker_concurrency` must be at least 1 for mentalsim worker");
        }
        let knowledge = HttpKnowledge::new(&url, config.knowledge_token())
            .map_err(|e| anyhow::anyhow!("the knowledge client: {e}"))?;
        let queue = Arc::new(LazyQueue::new(
            config.database_url(),
            config.job_backoff(),
            Some(config.data_dir.clone()),
        ));
        if let Err(reason) = queue.get().await {
            tracing::error!(%reason, "job database unavailable; /readyz will report it");
        }
        let env = crate::assembly::fleet(
            Arc::new(knowledge.clone()),
            crate::startup::job_dirs(&config),
            &queue,
            Some(edge::disk::DiskWatch::new(
                config.checkpoints_dir(),
                config.min_free_bytes,
            )),
        )
        .kinds;
        let shared = Arc::new(Shared {
            queue,
            knowledge,
            writes: vec![
                ("checkpoints_dir", config.checkpoints_dir()),
                ("policies_dir", config.policies_dir()),
                ("roadmaps_dir", config.roadmaps_dir()),
            ],
        });
        let router = Router::new()
            .route("/healthz", get(healthz))
            .route("/readyz", get(readyz))
            .route("/metrics", get(health::metrics))
            .with_state(shared.clone())
            .fallback(edge::middleware::not_found);
        let router = edge::middleware::stack(
            router,
            edge::middleware::Limits {
                request_timeout: config.request_timeout(),
                body_limit: config.body_limit_bytes,
            },
        );
        let listener = TcpListener::bind(config.bind)
            .await
            .map_err(|e| anyhow::anyhow!("cannot bind {}: {e}", config.bind))?;
        Ok(Self {
            listener,
            router,
            shared,
            env,
            config,
        })
    }

    /// The health listener's address.
    pub fn local_addr(&self) -> SocketAddr {
        self.listener.local_addr().unwrap_or(self.config.bind)
    }

    /// Runs jobs until `shutdown` resolves; then stops claiming, lets running jobs checkpoint
    /// within the grace period and hands them back to the queue.
    pub async fn run_until(
        self,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> anyhow::Result<()> {
        let stopping = CancellationToken::new();
        let config = self.config.worker_config();
        tracing::info!(worker = %config.id, knowledge = %self.shared.knowledge.base(), concurrency = config.concurrency, "mentalsim worker starting");
        let workers = tokio::spawn(jobs::service::run_workers(
            self.shared.queue.clone(),
            self.env.clone(),
            config,
            stopping.clone(),
        ));
        let on_shutdown = stopping.clone();
        let server = tokio::spawn(edge::serve::serve(
            self.listener,
            self.router,
            self.config.serve_limits(),
            async move { on_shutdown.cancelled().await },
        ));
        shutdown.await;
        tracing::info!(
            "shutting down: no new jobs; running jobs checkpoint and go back to the queue"
        );
        stopping.cancel();
        let grace = self.config.shutdown_grace();
        match tokio::time::timeout(grace + Duration::from_secs(10), workers).await {
            Ok(Ok(report)) => tracing::info!(?report, "workers stopped"),
            Ok(Err(e)) => tracing::error!(error = %e, "worker task failed"),
            Err(_) => tracing::warn!("workers did not stop in time"),
        }
        let _ = tokio::time::timeout(Duration::from_secs(5), server).await;
        if let Some(queue) = self.shared.queue.opened() {
            queue.database().close().await;
        }
        tracing::info!("stopped");
        Ok(())
    }
}

async fn healthz() -> Json<serde_json::Value> {
    Json(json!({ "status": "ok", "version": env!("CARGO_PKG_VERSION"), "role": "worker" }))
}

/// Ready when the job database answers with every migration applied, the knowledge service
/// is ready and accepts the worker's token, and every directory jobs write in (checkpoints,
/// policies, policy-aware roadmaps) takes writes. Probes see which check failed, never a path
/// or URL; the log has the full reason.
async fn readyz(State(shared): State<Arc<Shared>>) -> Response {
    let jobs = health::job_database(shared.queue.get().await.map(Queue::database)).await;
    let knowledge = match shared.knowledge.ready().await {
        Ok(()) => Check::pass(),
        Err(e) => Check::fail_as(e.summary, e.reason),
    }
    .with(Detail::Url(shared.knowledge.base().to_owned()));
    let mut readiness = Readiness::default()
        .with("job_database", jobs)
        .with("knowledge", knowledge);
    for (name, dir) in &shared.writes {
        readiness = readiness.with(name, health::writable(dir).await);
    }
    readiness.respond(false)
}
