//! The schedule's tables: its own migrations, applied once per database.
//!
//! The schedule shares the job database but not the queue's migrator. sqlx's `Migrator`
//! records its versions in `_sqlx_migrations`, and a migrator refuses a database that holds a
//! version it does not embed: the queue's would refuse a database migrated by the schedule's.
//! So the schedule numbers its migrations in a table of its own, `traffic_migrations`, and
//! applies them in one transaction under the database's write lock (SQLite: `BEGIN
//! IMMEDIATE`; PostgreSQL: a transaction-scoped advisory lock), so that processes opening the
//! schedule together migrate it once. A released migration is never edited: add the next one.

use super::{LOCK_CLASS, Schedule, on_pool};
use crate::error::TrafficError;

/// A step of the schema.
struct Migration {
    version: i64,
    description: &'static str,
    sql: &'static str,
}

const SQLITE: &[Migration] = &[
    Migration {
        version: 1,
        description: "schedule",
        sql: include_str!("../../migrations/sqlite/0001_schedule.sql"),
    },
    Migration {
        version: 2,
        description: "revisions",
        sql: include_str!("../../migrations/sqlite/0002_revisions.sql"),
    },
    Migration {
        version: 3,
        description: "waits",
        sql: include_str!("../../migrations/sqlite/0003_waits.sql"),
    },
];

const POSTGRES: &[Migration] = &[
    Migration {
        version: 1,
        description: "schedule",
        sql: include_str!("../../migrations/postgres/0001_schedule.sql"),
    },
    Migration {
        version: 2,
        description: "revisions",
        sql: include_str!("../../migrations/postgres/0002_revisions.sql"),
    },
    Migration {
        version: 3,
        description: "waits",
        sql: include_str!("../../migrations/postgres/0003_waits.sql"),
    },
];

const BOOKKEEPING: &str = "CREATE TABLE IF NOT EXISTS traffic_migrations (
    version     BIGINT PRIMARY KEY,
    description TEXT   NOT NULL,
    applied_ms  BIGINT NOT NULL
)";

/// The advisory lock's object id for migrations (the schedule's writes use 1).
const MIGRATION_LOCK: i32 = 0;

impl Schedule {
    /// Applies the migrations the database lacks; returns how many.
    pub(super) async fn migrate(&self) -> Result<usize, TrafficError> {
        let now = self.now_ms();
        let err = |e| self.db_err(e);
        let applied = on_pool!(self, |pool, pg| {
            let mut tx = if pg {
                pool.begin().await.map_err(err)?
            } else {
                pool.begin_with("BEGIN IMMEDIATE").await.map_err(err)?
            };
            if pg {
                sqlx::query("SELECT pg_advisory_xact_lock($1, $2)")
                    .bind(LOCK_CLASS)
                    .bind(MIGRATION_LOCK)
                    .execute(&mut *tx)
                    .await
                    .map_err(err)?;
            }
            let steps = if pg { POSTGRES } else { SQLITE };
            sqlx::query(BOOKKEEPING)
                .execute(&mut *tx)
                .await
                .map_err(err)?;
            let found: i64 =
                sqlx::query_scalar("SELECT COALESCE(MAX(version), 0) FROM traffic_migrations")
                    .fetch_one(&mut *tx)
                    .await
                    .map_err(err)?;
            let known = steps.last().map_or(0, |m| m.version);
            if found > known {
                return Err(TrafficError::SchemaTooNew {
                    url: self.url.to_string(),
                    found,
                    known,
                });
            }
            let mut applied = 0;
            for step in steps.iter().filter(|m| m.version > found) {
                sqlx::raw_sql(step.sql)
                    .execute(&mut *tx)
                    .await
                    .map_err(err)?;
                sqlx::query(
                    "INSERT INTO traffic_migrations (version, description, applied_ms) \
                     VALUES ($1, $2, $3)",
                )
                .bind(step.version)
                .bind(step.description)
                .bind(now)
                .execute(&mut *tx)
                .await
                .map_err(err)?;
                tracing::info!(
                    version = step.version,
                    description = step.description,
                    "traffic schedule migrated"
                );
                applied += 1;
            }
            tx.commit().await.map_err(err)?;
            applied
        });
        Ok(applied)
    }
}
