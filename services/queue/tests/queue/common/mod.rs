//! Test fixtures: a fresh job database on each backend.
//!
//! PostgreSQL: one temporary cluster per test binary (started on first use, stopped by its
//! watchdog when the binary exits), one fresh database per test. When the PostgreSQL binaries
//! are missing, [`fixtures::missing`] decides: under CI (`CI=true`) or with
//! `MENTALSIM_REQUIRE_ALL=1` (which `scripts/test` sets) the PostgreSQL tests fail, as they do
//! with the older `MENTALSIM_REQUIRE_POSTGRES=1`; in a clone of one's own they print why and
//! return.
#![allow(dead_code, clippy::unwrap_used)] // reason: shared by several modules, each using part; tests panic on failure

use std::sync::Arc;

use queue::{JobDatabase, ManualClock, Queue};

pub const START_MS: i64 = 1_700_000_000_000;

pub struct Fixture {
    pub db: JobDatabase,
    pub url: String,
    pub clock: Arc<ManualClock>,
    /// A queue on the manual clock: time moves only by `clock.advance`.
    pub queue: Queue,
    _fresh: Option<fixtures::job_database::FreshDatabase>,
}

impl Fixture {
    async fn new(url: String, fresh: Option<fixtures::job_database::FreshDatabase>) -> Self {
        let db = JobDatabase::connect(&url).await.unwrap();
        let clock = Arc::new(ManualClock::new(START_MS));
        let queue = Queue::new(db.clone()).with_clock(clock.clone());
        Self {
            db,
            url,
            clock,
            queue,
            _fresh: fresh,
        }
    }

    /// A queue on the system clock, for tests that run real workers.
    pub fn system_queue(&self) -> Queue {
        Queue::new(self.db.clone())
    }
}

pub async fn sqlite() -> Option<Fixture> {
    let fresh = fixtures::job_database::sqlite();
    Some(Fixture::new(fresh.url.clone(), Some(fresh)).await)
}

/// A fresh database in the shared temporary cluster, or `None` (the test returns) when
/// PostgreSQL is missing and [`fixtures::missing`] lets the test skip.
pub async fn postgres_url() -> Option<String> {
    let fresh = fixtures::job_database::postgres().await?;
    Some(fresh.url)
}

pub async fn postgres() -> Option<Fixture> {
    let fresh = fixtures::job_database::postgres().await?;
    Some(Fixture::new(fresh.url.clone(), Some(fresh)).await)
}
