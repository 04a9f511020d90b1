//! The knowledge service's shared state: the store, the tokens, the query limits, how its
//! SPARQL reads run, and what must happen after every write.
//!
//! Everything a service remembers lives here, per instance: two services in one process (the
//! in-process tests start many) share nothing.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use edge::{ApiError, ErrorCode, Tokens};

use crate::protocol::inline::ReadState;
use crate::store::{KnowledgeStore, StoreError};

/// Limits on SPARQL evaluation.
#[derive(Debug, Clone, Copy)]
pub struct QueryLimits {
    /// Wall-clock budget of one query or update; past it the evaluation is cancelled.
    pub deadline: Duration,
    /// Largest number of triples a CONSTRUCT/DESCRIBE may return; beyond it the answer is an
    /// error, never a truncated graph.
    pub max_construct_triples: usize,
    /// Largest serialized SPARQL or Graph Store answer to an engineer, bytes; past it the
    /// answer is refused (507) as soon as it crosses the cap, never cut or held whole.
    pub max_result_bytes: usize,
    /// The same cap for robots.
    pub robot_max_result_bytes: usize,
    /// Longest SPARQL query text, bytes (updates are bounded by the request body limit).
    pub max_query_bytes: usize,
}

impl QueryLimits {
    /// The answer cap of a caller with `role`.
    pub fn result_bytes(&self, role: edge::Role) -> usize {
        match role {
            edge::Role::Engineer => self.max_result_bytes,
            edge::Role::Robot => self.robot_max_result_bytes,
        }
    }
}

impl Default for QueryLimits {
    fn default() -> Self {
        Self {
            deadline: Duration::from_secs(30),
            max_construct_triples: 5_000_000,
            max_result_bytes: 256 * 1024 * 1024,
            robot_max_result_bytes: 16 * 1024 * 1024,
            max_query_bytes: 1024 * 1024,
        }
    }
}

type Opener = Box<dyn Fn() -> Result<KnowledgeStore, StoreError> + Send + Sync>;

/// Free space (beyond the reserve) a store that found its disk full waits for before it is
/// reopened: opening writes a new log and manifest, and flushes what the old log held.
const REOPEN_ROOM_BYTES: u64 = 16 << 20;

/// Object reports one robot may make per second, on average.
pub const REPORTS_PER_SECOND: f64 = 20.0;
/// Object reports one robot may make at once.
pub const REPORT_BURST: f64 = 100.0;

/// People counts one robot may report per second, on average (a batch of n counts costs n).
pub const OBSERVATIONS_PER_SECOND: f64 = 20.0;
/// People counts one robot may report at once; also the most one request may carry.
pub const OBSERVATION_BURST: f64 = 100.0;

/// A robot's allowance of one kind of report: tokens left and when they were last counted.
type Buckets = Mutex<HashMap<String, (f64, std::time::Instant)>>;

/// Takes `n` tokens from `robot`'s bucket (refilled at `rate` per second up to `burst`); `Err`
/// with the seconds until `n` are there.
fn take(buckets: &Buckets, robot: &str, n: f64, rate: f64, burst: f64) -> Result<(), f64> {
    let now = std::time::Instant::now();
    let mut buckets = buckets.lock().unwrap_or_else(PoisonError::into_inner);
    let (tokens, at) = buckets.entry(robot.to_owned()).or_insert((burst, now));
    *tokens = (*tokens + now.duration_since(*at).as_secs_f64() * rate).min(burst);
    *at = now;
    if *tokens >= n {
        *tokens -= n;
        Ok(())
    } else {
        Err((n - *tokens) / rate)
    }
}

/// Everything a knowledge handler needs. Shared behind an `Arc`.
///
/// The store may open late: when the data directory is unusable at start, handlers answer
/// 503 `not_ready` with the reason, and the next request after the cause is fixed opens it.
pub struct Knowledge {
    opener: Opener,
    store: Mutex<Option<KnowledgeStore>>,
    /// Who may do what.
    pub tokens: Tokens,
    /// SPARQL limits.
    pub limits: QueryLimits,
    refresh_lock: Mutex<()>,
    /// What this service's SPARQL reads cost last time, which run in place, and its watchdog.
    reads: Arc<ReadState>,
    /// Object reports per robot: a token bucket by principal name (bounded by the tokens).
    reports: Buckets,
    /// People counts per robot, the same way.
    observations: Buckets,
    /// Held while a people estimate is read, moved and written back, so that two requests
    /// about one place cannot both start from the same estimate and lose a count.
    estimates: Mutex<()>,
    /// The free-space reserve of the store's disk, when it is on one.
    disk: Option<edge::disk::DiskWatch>,
    /// Whether `opener` can open the store again (false for a store handed over open).
    reopenable: bool,
}

impl edge::TokenSource for Knowledge {
    fn tokens(&self) -> &Tokens {
        &self.tokens
    }
}

impl std::fmt::Debug for Knowledge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Knowledge")
            .field("tokens", &self.tokens)
            .field("limits", &self.limits)
            .finish_non_exhaustive()
    }
}

impl Knowledge {
    /// A service over an open store.
    pub fn new(store: KnowledgeStore, tokens: Tokens, limits: QueryLimits) -> Self {
        let mut service = Self::lazy(
            || {
                Err(StoreError::Query {
                    location: "(none)".into(),
                    message: "no opener".to_owned(),
                })
            },
            tokens,
            limits,
        );
        service.store = Mutex::new(Some(store));
        service.reopenable = false;
        service
    }

    /// A service whose store is opened by `opener` on first use, and again on every use until
    /// it succeeds.
    pub fn lazy(
        opener: impl Fn() -> Result<KnowledgeStore, StoreError> + Send + Sync + 'static,
        tokens: Tokens,
        limits: QueryLimits,
    ) -> Self {
        Self {
            opener: Box::new(opener),
            store: Mutex::new(None),
            tokens,
            limits,
            refresh_lock: Mutex::new(()),
            reads: Arc::new(ReadState::new()),
            reports: Mutex::new(HashMap::new()),
            observations: Mutex::new(HashMap::new()),
            estimates: Mutex::new(()),
            disk: None,
            reopenable: true,
        }
    }

    /// Keeps `disk`'s reserve free: writes that would eat into it are refused (507).
    #[must_use]
    pub fn with_disk(mut self, disk: edge::disk::DiskWatch) -> Self {
        self.disk = Some(disk);
        self
    }

    /// `Ok` when a write of about `bytes` leaves the disk's reserve free; else 507
    /// `storage_full`, before anything is written.
    pub fn check_space(&self, bytes: u64) -> Result<(), ApiError> {
        self.disk.as_ref().map_or(Ok(()), |disk| disk.check(bytes))
    }

    /// Takes one object report from `robot`'s allowance ([`REPORTS_PER_SECOND`], bursts of
    /// [`REPORT_BURST`]); `Err` with the seconds until the next one is allowed.
    pub fn take_report(&self, robot: &str) -> Result<(), f64> {
        take(&self.reports, robot, 1.0, REPORTS_PER_SECOND, REPORT_BURST)
    }

    /// Takes `n` people counts from `robot`'s allowance ([`OBSERVATIONS_PER_SECOND`], bursts
    /// of [`OBSERVATION_BURST`]); `Err` with the seconds until they are allowed.
    pub fn take_observations(&self, robot: &str, n: usize) -> Result<(), f64> {
        take(
            &self.observations,
            robot,
            n as f64,
            OBSERVATIONS_PER_SECOND,
            OBSERVATION_BURST,
        )
    }

    /// Serialises the updates of people estimates (see `api/people.rs`): hold the guard from
    /// reading an estimate to writing it back.
    pub fn estimates_lock(&self) -> std::sync::MutexGuard<'_, ()> {
        self.estimates
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    }

    /// The store, opening it if needed. Blocking the first time (RocksDB opens its files).
    ///
    /// A store whose write found the disk full refuses every later write (RocksDB stops
    /// writing after a failed log append); once the reserve is free again it is closed and
    /// opened afresh, which replays its log: what was acknowledged stays, the failed write
    /// is gone. Until then it keeps answering reads.
    pub fn try_store(&self) -> Result<KnowledgeStore, StoreError> {
        let mut slot = self.store.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(store) = slot.as_ref() {
            if !self.due_for_reopen(store) {
                return Ok(store.clone());
            }
            tracing::info!(
                location = store.location(),
                "reopening the graph store after a full disk"
            );
            // Dropped before opening: RocksDB allows one open per directory. Requests still
            // holding the old store make the open fail; the next request tries again.
            *slot = None;
        }
        let store = (self.opener)()?;
        *slot = Some(store.clone());
        Ok(store)
    }

    /// The store for a handler: 503 `not_ready` naming the cause when it cannot be opened.
    pub fn store(&self) -> Result<KnowledgeStore, ApiError> {
        self.try_store().map_err(|e| {
            if edge::disk::is_out_of_space(&e.to_string()) {
                return edge::disk::storage_full(&e.to_string());
            }
            ApiError::new(
                ErrorCode::NotReady,
                format!("the graph store is unavailable: {e}"),
            )
        })
    }

    /// The store for an async handler: the open store at once, or opened on a blocking thread.
    pub async fn store_async(self: &Arc<Self>) -> Result<KnowledgeStore, ApiError> {
        if let Some(store) = self.opened_store() {
            return Ok(store);
        }
        let knowledge = self.clone();
        tokio::task::spawn_blocking(move || knowledge.store())
            .await
            .map_err(|e| ApiError::internal(format!("store open task failed: {e}")))?
    }

    /// The store if it is already open (and not due to be reopened), without trying to open
    /// it.
    pub fn opened_store(&self) -> Option<KnowledgeStore> {
        self.store
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
            .filter(|store| !self.due_for_reopen(store))
    }

    /// Whether `store` found its disk full and the disk has room again.
    fn due_for_reopen(&self, store: &KnowledgeStore) -> bool {
        self.reopenable
            && store.write_failed()
            && self
                .disk
                .as_ref()
                .is_none_or(|disk| disk.has_room(REOPEN_ROOM_BYTES))
    }

    /// How this service's SPARQL reads run (see `protocol/inline.rs`).
    pub(crate) fn reads(&self) -> &Arc<ReadState> {
        &self.reads
    }

    /// SPARQL reads (queries, graph dumps) of this service running right now, including those
    /// whose client has gone and which are still unwinding: a gauge for metrics, and how tests
    /// see that a cancelled evaluation really stopped.
    pub fn running_reads(&self) -> usize {
        self.reads.running()
    }

    /// Must be called after every successful write (SPARQL update, Graph Store PUT/POST/DELETE,
    /// imports): brings the materialised entailments up to date. Blocking.
    pub fn after_write(&self) -> Result<(), StoreError> {
        let store = self.try_store()?;
        // Serialised: two concurrent rebuilds would race on clearing the inferred graph.
        let _guard = self
            .refresh_lock
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        crate::inference::refresh(&store).map(|_| ())
    }
}
