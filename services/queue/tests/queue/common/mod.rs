//! Test fixtures: a fresh job database on each backend ([`fixtures::job_database`]), with a
//! queue on its manual clock.
//!
//! PostgreSQL: one temporary cluster per test binary (started on first use, stopped by its
//! watchdog when the binary exits), one fresh database per test. When the PostgreSQL binaries
//! are missing, [`fixtures::missing`] decides: under CI (`CI=true`) or with
//! `MENTALSIM_REQUIRE_ALL=1` (which `scripts/test` sets) the PostgreSQL tests fail, as they do
//! with the older `MENTALSIM_REQUIRE_POSTGRES=1`; in a clone of one's own they print why and
//! return.
#![allow(dead_code)] // reason: shared by several modules, each using part

use fixtures::job_database::OpenedDatabase;
pub use fixtures::job_database::START_MS;
use queue::Queue;

/// A fresh job database (`db`, `url`, `clock`, through `Deref`) and a queue on it.
pub struct Fixture {
    opened: OpenedDatabase,
    /// A queue on the manual clock: time moves only by `clock.advance`.
    pub queue: Queue,
}

impl std::ops::Deref for Fixture {
    type Target = OpenedDatabase;
    fn deref(&self) -> &OpenedDatabase {
        &self.opened
    }
}

impl Fixture {
    fn new(opened: OpenedDatabase) -> Self {
        let queue = Queue::new(opened.db.clone()).with_clock(opened.clock.clone());
        Self { opened, queue }
    }

    /// A queue on the system clock, for tests that run real workers.
    pub fn system_queue(&self) -> Queue {
        Queue::new(self.db.clone())
    }
}

pub async fn sqlite() -> Option<Fixture> {
    Some(Fixture::new(fixtures::job_database::opened_sqlite().await?))
}

pub async fn postgres() -> Option<Fixture> {
    Some(Fixture::new(
        fixtures::job_database::opened_postgres().await?,
    ))
}
