//! Assembling and running the process: backing stores, the router with its middleware, the
//! listener, and graceful shutdown. `main` is a shim over this so tests start the same app on
//! port 0.

use std::future::Future;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use axum::Router;
use jobs::{InProcessKnowledge, JobDirs, JobEnv};
use knowledge::{Knowledge, KnowledgeStore, StoreError};
use queue::{JobDatabase, LazyQueue};
use tokio::net::TcpListener;
use tokio_util::sync::CancellationToken;

use crate::assembly::Fleet;

use crate::config::Config;

/// The backing stores, opened at start and re-tried on use until they open.
///
/// The process stays up when a store cannot be opened (a full disk, a read-only mount): it
/// answers `/healthz`, reports the reason on `/readyz`, and recovers without a restart once
/// the cause is fixed.
pub struct Components {
    data_dir: PathBuf,
    knowledge: Arc<Knowledge>,
    queue: Arc<LazyQueue>,
    fleet: Fleet,
}

impl Components {
    fn new(config: &Config) -> Self {
        let store_dir = config.store_dir();
        let embedded = move || -> Result<KnowledgeStore, StoreError> {
            if let Some(parent) = store_dir.parent() {
                std::fs::create_dir_all(parent).map_err(|e| StoreError::Query {
                    location: store_dir.display().to_string(),
                    message: format!("cannot create data directory {}: {e}", parent.display()),
                })?;
            }
            let store = KnowledgeStore::open(&store_dir)?;
            if knowledge::bundled::load_if_empty(&store)? {
                tracing::info!(path = %store_dir.display(), "loaded the bundled ontology, robot and sample building");
            }
            // A process killed between a write and the rebuild of the entailments after it
            // left the inferred graph behind the asserted ones: rebuild it before serving.
            knowledge::inference::refresh(&store)?;
            Ok(store)
        };
        // A remote store is "open" once it answers; until then every use tries again.
        let remote = config.remote_store().map(|remote| {
            move || -> Result<KnowledgeStore, StoreError> {
                let store = KnowledgeStore::remote(remote.clone())?;
                store.check()?;
                if knowledge::bundled::load_if_empty(&store)? {
                    tracing::info!(url = %store.location(), "loaded the bundled ontology, robot and sample building into the remote store");
                }
                knowledge::inference::refresh(&store)?;
                Ok(store)
            }
        });
        let opener: Box<dyn Fn() -> Result<KnowledgeStore, StoreError> + Send + Sync> = match remote
        {
            Some(remote) => Box::new(remote),
            None => Box::new(embedded),
        };
        let knowledge = Arc::new(
            Knowledge::lazy(opener, crate::tokens::load(config), config.query_limits())
                .with_disk(config.disk_watch()),
        );
        let queue = Arc::new(LazyQueue::new(
            config.database_url(),
            config.job_backoff(),
            Some(config.data_dir.clone()),
        ));
        let fleet = crate::assembly::fleet(
            Arc::new(InProcessKnowledge::new(knowledge.clone())),
            job_dirs(config),
            &queue,
            Some(edge::disk::DiskWatch::new(
                config.checkpoints_dir(),
                config.min_free_bytes,
            )),
        );
        Self {
            data_dir: config.data_dir.clone(),
            knowledge,
            queue,
            fleet,
        }
    }

    /// The job queue (opened lazily).
    pub fn queue(&self) -> &Arc<LazyQueue> {
        &self.queue
    }

    /// What job handlers share: the in-process knowledge source, checkpoint and policy
    /// directories, the plan validator.
    pub fn job_env(&self) -> &Arc<JobEnv> {
        &self.fleet.kinds
    }

    /// The data directory.
    pub fn data_dir(&self) -> &Path {
        &self.data_dir
    }

    /// The knowledge service state.
    pub fn knowledge(&self) -> &Arc<Knowledge> {
        &self.knowledge
    }

    /// The graph store, opening it if it is not open yet.
    pub async fn store(&self) -> Result<KnowledgeStore, String> {
        let knowledge = self.knowledge.clone();
        tokio::task::spawn_blocking(move || knowledge.try_store().map_err(|e| e.to_string()))
            .await
            .map_err(|e| format!("store open task failed: {e}"))?
    }

    /// The job database, opening and migrating it if it is not open yet.
    pub async fn jobs(&self) -> Result<&JobDatabase, String> {
        self.queue.get().await.map(queue::Queue::database)
    }

    async fn close(&self) {
        if let Some(queue) = self.queue.opened() {
            queue.database().close().await;
        }
        if let Some(store) = self.knowledge.opened_store() {
            match tokio::task::spawn_blocking(move || store.flush()).await {
                Ok(Ok(())) => {}
                Ok(Err(e)) => tracing::error!(error = %e, "flushing the graph store failed"),
                Err(e) => tracing::error!(error = %e, "flush task failed"),
            }
        }
    }
}

/// A bound, assembled service, ready to run.
pub struct Application {
    listener: TcpListener,
    router: Router,
    components: Arc<Components>,
    config: Config,
    stopping: CancellationToken,
}

impl Application {
    /// Opens the backing stores (failures are logged and reported on `/readyz`, not fatal),
    /// builds the router and binds the listener. Bind to port 0 to get a free port.
    pub async fn build(config: Config) -> anyhow::Result<Self> {
        let components = Arc::new(Components::new(&config));
        if let Err(reason) = components.store().await {
            tracing::error!(%reason, "graph store unavailable; /readyz will report it");
        }
        if let Err(reason) = components.jobs().await {
            tracing::error!(%reason, "job database unavailable; /readyz will report it");
        }
        let stopping = CancellationToken::new();
        let router = router(&config, components.clone(), stopping.clone());
        let listener = TcpListener::bind(config.bind)
            .await
            .map_err(|e| anyhow::anyhow!("cannot bind {}: {e}", config.bind))?;
        Ok(Self {
            listener,
            router,
            components,
            config,
            stopping,
        })
    }

    /// The address actually bound (with the real port when the configuration said 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.listener.local_addr().unwrap_or(self.config.bind)
    }

    /// Serves until `shutdown` resolves, then stops accepting, lets requests in flight finish
    /// within the grace period, and closes the stores cleanly.
    ///
    /// Meanwhile `worker_concurrency` in-process workers run jobs (none when it is 0) and
    /// finished jobs past `job_retention_days` are purged hourly. On shutdown the workers stop
    /// claiming, running trainings checkpoint and their jobs go back to the queue.
    pub async fn run_until(
        self,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> anyhow::Result<()> {
        let grace = self.config.shutdown_grace();
        let stopping = self.stopping.clone();
        let workers = (self.config.worker_concurrency > 0).then(|| {
            tokio::spawn(jobs::service::run_workers(
                self.components.queue().clone(),
                self.components.job_env().clone(),
                self.config.worker_config(),
                stopping.clone(),
            ))
        });
        let purge = tokio::spawn(jobs::service::purge_loop(
            self.components.queue().clone(),
            self.components.job_env().clone(),
            self.config.job_retention(),
            std::time::Duration::from_secs(3600),
            stopping.clone(),
        ));
        let improver = (self.config.fleet_improve_every_s > 0.0).then(|| {
            tokio::spawn(crate::assembly::improve_fleet(
                Arc::clone(&self.components.fleet.planner),
                std::time::Duration::from_secs_f64(self.config.fleet_improve_every_s),
                stopping.clone(),
            ))
        });
        let (stopping_tx, stopping_rx) = tokio::sync::oneshot::channel::<()>();
        let on_shutdown = stopping.clone();
        let serve = edge::serve::serve(
            self.listener,
            self.router,
            self.config.serve_limits(),
            async move {
                shutdown.await;
                tracing::info!("shutting down: no new connections; finishing requests in flight");
                // Workers stop claiming and checkpoint; event streams end.
                on_shutdown.cancel();
                let _ = stopping_tx.send(());
            },
        );
        let serve = async move {
            serve.await;
            anyhow::Ok(())
        };
        tokio::pin!(serve);
        let served = tokio::select! {
            result = &mut serve => result,
            () = async {
                let _ = stopping_rx.await;
                tokio::time::sleep(grace).await;
            } => {
                tracing::warn!(?grace, "grace period over; dropping remaining connections");
                Ok(())
            }
        };
        stopping.cancel();
        if let Some(workers) = workers {
            // The runner bounds its own wait by the grace period, then releases what is left.
            match tokio::time::timeout(grace + std::time::Duration::from_secs(10), workers).await {
                Ok(Ok(report)) => tracing::info!(?report, "workers stopped"),
                Ok(Err(e)) => tracing::error!(error = %e, "worker task failed"),
                Err(_) => tracing::warn!("workers did not stop in time"),
            }
        }
        if let Some(improver) = improver {
            improver.abort();
            let _ = improver.await;
        }
        purge.abort();
        // The purge task holds the knowledge state (and so the graph store): let it go before
        // the stores close, so a process started next on this data directory can open them.
        let _ = purge.await;
        self.components.close().await;
        tracing::info!("stopped");
        served
    }
}

/// Both services and the health routes on one router, wrapped in the shared middleware stack.
fn router(config: &Config, components: Arc<Components>, stopping: CancellationToken) -> Router {
    let knowledge = components.knowledge().clone();
    let guard = config.guard(knowledge.tokens.clone());
    let fleet = api::FleetServices {
        queue: components.queue().clone(),
        tokens: knowledge.tokens.clone(),
        planner: Arc::clone(&components.fleet.planner),
        kinds: Arc::clone(&components.fleet.kinds),
        fleet: Arc::clone(&components.fleet.schedule),
        shutdown: stopping,
        event_poll: std::time::Duration::from_millis(250),
        // Each stream polls the job database every 250 ms; the pool is the heartbeats' too.
        streams: Arc::new(api::StreamLimits::new(64, 8)),
    };
    let app = Router::new()
        .merge(crate::health::router(components))
        .merge(api::router(fleet))
        .merge(knowledge::api::router(knowledge.clone()))
        .merge(knowledge::protocol::router(knowledge))
        .merge(
            crate::console::router(config.console_pages())
                .layer(tower_http::compression::CompressionLayer::new()),
        )
        .fallback(edge::middleware::not_found);
    edge::middleware::stack_guarded(
        app,
        edge::middleware::Limits {
            request_timeout: config.request_timeout(),
            body_limit: config.body_limit_bytes,
        },
        Some(guard),
    )
}

/// Where the jobs keep their files, as configured.
pub fn job_dirs(config: &Config) -> JobDirs {
    JobDirs {
        checkpoints: config.checkpoints_dir(),
        policies: config.policies_dir(),
        roadmaps: config.roadmaps_dir(),
    }
}

/// Resolves on SIGINT (Ctrl-C) or SIGTERM.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        if let Err(e) = tokio::signal::ctrl_c().await {
            tracing::error!(error = %e, "cannot listen for Ctrl-C");
            std::future::pending::<()>().await;
        }
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(e) => {
                tracing::error!(error = %e, "cannot listen for SIGTERM");
                std::future::pending::<()>().await;
            }
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => tracing::info!("received SIGINT"),
        () = terminate => tracing::info!("received SIGTERM"),
    }
}
