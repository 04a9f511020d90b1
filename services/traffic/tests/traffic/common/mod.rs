//! Test fixtures: a fresh job database on each backend ([`fixtures::job_database`]) with the
//! schedule on its manual clock, and itineraries.
//!
//! PostgreSQL: one temporary cluster per test binary (started on first use, stopped by its
//! watchdog when the binary exits), one fresh database per test. When the PostgreSQL binaries
//! are missing, [`fixtures::missing`] decides: under CI (`CI=true`) or with
//! `MENTALSIM_REQUIRE_ALL=1` the PostgreSQL tests fail, as they do with
//! `MENTALSIM_REQUIRE_POSTGRES=1`; in a clone of one's own they print why and return.
#![allow(dead_code, clippy::unwrap_used)] // reason: shared by several modules, each using part; tests panic on failure

use fixtures::job_database::OpenedDatabase;
pub use fixtures::job_database::START_MS;
use queue::JobDatabase;
use traffic::{Itinerary, Schedule, TimedPose};

/// A fresh job database (`db`, `url`, `clock`, through `Deref`) and the schedule in it.
pub struct Fixture {
    opened: OpenedDatabase,
    /// The schedule on the manual clock: time moves only by `clock.advance` or `clock.set`.
    pub schedule: Schedule,
}

impl std::ops::Deref for Fixture {
    type Target = OpenedDatabase;
    fn deref(&self) -> &OpenedDatabase {
        &self.opened
    }
}

impl Fixture {
    async fn new(opened: OpenedDatabase) -> Self {
        let schedule = Schedule::open(&opened.db)
            .await
            .unwrap()
            .with_clock(opened.clock.clone());
        Self { opened, schedule }
    }

    /// Another handle on the same database through a pool of its own, as another process
    /// would open it.
    pub async fn another_process(&self) -> Schedule {
        let db = JobDatabase::connect(&self.url).await.unwrap();
        Schedule::open(&db)
            .await
            .unwrap()
            .with_clock(self.clock.clone())
    }
}

pub async fn sqlite() -> Option<Fixture> {
    Some(Fixture::new(fixtures::job_database::opened_sqlite().await?).await)
}

pub async fn postgres() -> Option<Fixture> {
    Some(Fixture::new(fixtures::job_database::opened_postgres().await?).await)
}

/// Milliseconds `seconds` after `START_MS`.
pub fn at(seconds: f64) -> i64 {
    #[allow(clippy::cast_possible_truncation)] // reason: test times, far inside i64
    let ms = (seconds * 1000.0).round() as i64;
    START_MS + ms
}

/// `robot` driving plan `plan_id` on `floor` straight from `from` to `to` at 1 m/s, a pose
/// every 0.5 s, starting at `START_MS`; radius 0.3 m, tolerance 1 s, expiring 60 s after its
/// end.
pub fn straight(
    plan_id: &str,
    robot: &str,
    floor: &str,
    from: [f64; 2],
    to: [f64; 2],
) -> Itinerary {
    let length = (to[0] - from[0]).hypot(to[1] - from[1]);
    let steps = (length / 0.5).ceil().max(1.0);
    #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)] // reason: small counts
    let n = steps as usize;
    let trajectory: Vec<TimedPose> = (0..=n)
        .map(|i| {
            #[allow(clippy::cast_precision_loss)] // reason: small counts
            let u = i as f64 / steps;
            TimedPose {
                t_s: u * length,
                x: from[0] + u * (to[0] - from[0]),
                y: from[1] + u * (to[1] - from[1]),
                yaw: (to[1] - from[1]).atan2(to[0] - from[0]),
            }
        })
        .collect();
    Itinerary {
        plan_id: plan_id.to_owned(),
        robot: robot.to_owned(),
        floor: floor.to_owned(),
        start_unix_ms: START_MS,
        trajectory,
        radius_m: 0.3,
        tolerance_s: 1.0,
        expires_unix_ms: at(length + 60.0),
        delay_s: 0.0,
        revision: 1,
    }
}
