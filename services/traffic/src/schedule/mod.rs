//! The fleet's traffic schedule in the job database: [`Schedule`].
//!
//! One row per committed itinerary and one version per floor. Every write (commit, cancel,
//! progress) runs in one transaction under the schedule's write lock: on SQLite the database's
//! own (`BEGIN IMMEDIATE`: the transaction takes the write lock before it reads, so it never
//! fails upgrading a read lock, and the busy timeout queues writers), on PostgreSQL a
//! transaction-scoped advisory lock. Holding one lock for every floor keeps writes simple and
//! free of deadlocks (a commit may touch two floors: its own and the floor of the plan it
//! replaces); a plan request commits once, so the lock is never the bottleneck. Inside, a
//! commit bumps its floor's version with `UPDATE … WHERE version = expected`, which must
//! change one row: two processes sharing the database can never both commit against the same
//! version.
//!
//! A snapshot reads the version and the itineraries in one transaction (PostgreSQL:
//! `REPEATABLE READ`), so a caller that plans against a snapshot and commits with its version
//! commits only if nothing changed on the floor since.

mod migrate;
mod rows;
mod waits;
mod write;

use std::sync::Arc;

use queue::{Clock, JobDatabase, SystemClock};
use sqlx::postgres::PgPool;
use sqlx::sqlite::SqlitePool;
use tokio::sync::broadcast;

use crate::change::Change;
use crate::error::TrafficError;
use crate::itinerary::Itinerary;
use crate::revision::Planned;
use rows::{COLUMNS, ItineraryRow};

/// The advisory lock class of the schedule on PostgreSQL ("traf"); its object ids: 0 for
/// migrations, 1 for writes. Two-key advisory locks never collide with sqlx's one-key lock.
const LOCK_CLASS: i32 = 0x7472_6166;

/// How many changes a slow subscriber may fall behind before it misses some.
const CHANGES_CAPACITY: usize = 1024;

/// A connection pool of either backend.
#[derive(Debug, Clone)]
enum Pool {
    Sqlite(SqlitePool),
    Postgres(PgPool),
}

/// Runs `$body` with `$pool` bound to the backend's pool and `$pg` to whether it is
/// PostgreSQL. The body is compiled once per backend, so the same statements are type-checked
/// against both drivers (placeholders are `$1`, `$2`, ... on both).
macro_rules! on_pool {
    ($schedule:expr, |$pool:ident, $pg:ident| $body:expr) => {
        match &$schedule.pool {
            $crate::schedule::Pool::Sqlite($pool) => {
                #[allow(unused_variables)]
                let $pg = false;
                $body
            }
            $crate::schedule::Pool::Postgres($pool) => {
                #[allow(unused_variables)]
                let $pg = true;
                $body
            }
        }
    };
}
use on_pool;

/// The fleet's traffic schedule: per floor, every robot's committed itinerary and a version.
/// Cheap to clone; share one per process.
///
/// [`Schedule::changes`] broadcasts this process's changes. Other processes sharing the
/// database change it too, unseen by that stream: their changes show as a floor's version
/// moving on ([`Schedule::snapshot`], and `VersionChanged` from [`Schedule::commit`]).
#[derive(Clone)]
pub struct Schedule {
    pool: Pool,
    url: Arc<str>,
    clock: Arc<dyn Clock>,
    changes: broadcast::Sender<Change>,
}

impl std::fmt::Debug for Schedule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Schedule")
            .field("url", &self.url)
            .field("clock", &self.clock)
            .finish_non_exhaustive()
    }
}

impl Schedule {
    /// Opens the schedule in the job database, creating its tables if they are missing.
    pub async fn open(db: &JobDatabase) -> Result<Self, TrafficError> {
        let pool = match (db.sqlite_pool(), db.postgres_pool()) {
            (Some(pool), _) => Pool::Sqlite(pool.clone()),
            (None, Some(pool)) => Pool::Postgres(pool.clone()),
            (None, None) => {
                return Err(TrafficError::Invalid(format!(
                    "the job database {} has neither an SQLite nor a PostgreSQL pool",
                    db.url()
                )));
            }
        };
        let (changes, _) = broadcast::channel(CHANGES_CAPACITY);
        let schedule = Self {
            pool,
            url: Arc::from(db.url()),
            clock: Arc::new(SystemClock),
            changes,
        };
        schedule.migrate().await?;
        Ok(schedule)
    }

    /// Sets the clock that decides what has expired (tests use [`queue::ManualClock`]).
    pub fn with_clock(mut self, clock: Arc<dyn Clock>) -> Self {
        self.clock = clock;
        self
    }

    /// Now, by the schedule's clock (Unix ms).
    pub fn now_ms(&self) -> i64 {
        self.clock.now_ms()
    }

    /// The changes this process makes from now on (commits, cancels, progress), in order.
    ///
    /// Only this process's: another process sharing the database is seen through the floors'
    /// versions. A receiver that falls more than 1,024 changes behind gets
    /// `RecvError::Lagged` and should read a [`Schedule::snapshot`] again.
    pub fn changes(&self) -> broadcast::Receiver<Change> {
        self.changes.subscribe()
    }

    /// The floor's version and every itinerary on it not expired at `now_unix_ms` (ordered by
    /// start, then plan id). A floor nothing was ever committed to has version 0.
    pub async fn snapshot(
        &self,
        floor: &str,
        now_unix_ms: i64,
    ) -> Result<(i64, Vec<Itinerary>), TrafficError> {
        let err = |e| self.db_err(e);
        let select = format!(
            "SELECT {COLUMNS} FROM traffic_itineraries WHERE floor = $1 AND expires_ms >= $2 \
             ORDER BY start_ms, plan_id"
        );
        let (version, rows) = on_pool!(self, |pool, pg| {
            let mut tx = if pg {
                pool.begin_with("BEGIN ISOLATION LEVEL REPEATABLE READ, READ ONLY")
                    .await
                    .map_err(err)?
            } else {
                pool.begin().await.map_err(err)?
            };
            let version: Option<i64> =
                sqlx::query_scalar("SELECT version FROM traffic_floors WHERE floor = $1")
                    .bind(floor)
                    .fetch_optional(&mut *tx)
                    .await
                    .map_err(err)?;
            let rows: Vec<ItineraryRow> = sqlx::query_as(&select)
                .bind(floor)
                .bind(now_unix_ms)
                .fetch_all(&mut *tx)
                .await
                .map_err(err)?;
            tx.commit().await.map_err(err)?;
            (version.unwrap_or(0), rows)
        });
        let itineraries = rows
            .into_iter()
            .map(ItineraryRow::into_itinerary)
            .collect::<Result<_, _>>()?;
        Ok((version, itineraries))
    }

    /// The floor's version (0 when nothing was ever committed to it).
    pub async fn version(&self, floor: &str) -> Result<i64, TrafficError> {
        let version: Option<i64> = on_pool!(self, |pool, pg| {
            sqlx::query_scalar("SELECT version FROM traffic_floors WHERE floor = $1")
                .bind(floor)
                .fetch_optional(pool)
                .await
                .map_err(|e| self.db_err(e))?
        });
        Ok(version.unwrap_or(0))
    }

    /// The itinerary of plan `plan_id`, unless it is unknown, cancelled, replaced or expired.
    pub async fn get(&self, plan_id: &str) -> Result<Option<Itinerary>, TrafficError> {
        Ok(self.plan(plan_id).await?.map(|p| p.itinerary))
    }

    /// Plan `plan_id` as committed (its itinerary and revision, what its robot acknowledged),
    /// unless it is unknown, cancelled, replaced or expired.
    pub async fn plan(&self, plan_id: &str) -> Result<Option<Planned>, TrafficError> {
        let now = self.now_ms();
        let select = format!(
            "SELECT {COLUMNS} FROM traffic_itineraries WHERE plan_id = $1 AND expires_ms >= $2"
        );
        let row: Option<ItineraryRow> = on_pool!(self, |pool, pg| {
            sqlx::query_as(&select)
                .bind(plan_id)
                .bind(now)
                .fetch_optional(pool)
                .await
                .map_err(|e| self.db_err(e))?
        });
        row.map(ItineraryRow::into_planned).transpose()
    }

    /// Every plan on `floor` not expired now, with what its robot acknowledged and where its
    /// last progress report matched it (by start, then plan id).
    pub async fn plans_on(&self, floor: &str) -> Result<Vec<Planned>, TrafficError> {
        let now = self.now_ms();
        let select = format!(
            "SELECT {COLUMNS} FROM traffic_itineraries WHERE floor = $1 AND expires_ms >= $2 \
             ORDER BY start_ms, plan_id"
        );
        let rows: Vec<ItineraryRow> = on_pool!(self, |pool, pg| {
            sqlx::query_as(&select)
                .bind(floor)
                .bind(now)
                .fetch_all(pool)
                .await
                .map_err(|e| self.db_err(e))?
        });
        rows.into_iter().map(ItineraryRow::into_planned).collect()
    }

    fn db_err(&self, source: sqlx::Error) -> TrafficError {
        TrafficError::Database {
            url: self.url.to_string(),
            source,
        }
    }

    /// Sends changes to this process's subscribers.
    fn publish(&self, changes: Vec<Change>) {
        for change in changes {
            // An error only means nobody listens now, which is fine.
            if self.changes.send(change).is_err() {
                break;
            }
        }
    }
}
