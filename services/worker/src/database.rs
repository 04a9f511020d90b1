//! The job database: connection, durability settings and migrations.

use std::str::FromStr;
use std::time::Duration;

use sqlx::migrate::Migrator;
use sqlx::sqlite::{
    SqliteConnectOptions, SqliteJournalMode, SqlitePool, SqlitePoolOptions, SqliteSynchronous,
};

static SQLITE_MIGRATIONS: Migrator = sqlx::migrate!("../../migrations/sqlite");

/// Why the job database could not be opened or used.
#[derive(Debug, thiserror::Error)]
pub enum DatabaseError {
    /// The URL names a database this build cannot use.
    #[error("unsupported job database URL {url:?}: expected sqlite://PATH")]
    UnsupportedUrl {
        /// The URL as given.
        url: String,
    },
    /// Connecting or querying failed.
    #[error("job database {url}: {source}")]
    Sqlx {
        /// The URL with any password removed.
        url: String,
        /// The driver's error.
        #[source]
        source: sqlx::Error,
    },
    /// Applying the schema migrations failed.
    #[error("job database {url}: migrations failed: {source}")]
    Migrate {
        /// The URL with any password removed.
        url: String,
        /// The migrator's error.
        #[source]
        source: sqlx::migrate::MigrateError,
    },
}

/// The job queue's database, migrated to the schema this build expects.
#[derive(Debug, Clone)]
pub struct JobDatabase {
    pool: SqlitePool,
    url: String,
}

/// What a health check of the database found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DatabaseStatus {
    /// Migrations recorded as applied in the database.
    pub applied_migrations: usize,
    /// Migrations this build embeds.
    pub expected_migrations: usize,
}

impl JobDatabase {
    /// Opens (creating if needed) the database at `url` and applies pending migrations.
    ///
    /// SQLite runs in WAL mode with `synchronous = FULL`: a job acknowledged to a client has
    /// reached the disk, even if the machine loses power right after.
    pub async fn connect(url: &str) -> Result<Self, DatabaseError> {
        if !url.starts_with("sqlite:") {
            return Err(DatabaseError::UnsupportedUrl {
                url: url.to_owned(),
            });
        }
        let err = |source| DatabaseError::Sqlx {
            url: url.to_owned(),
            source,
        };
        let options = SqliteConnectOptions::from_str(url)
            .map_err(err)?
            .create_if_missing(true)
            .journal_mode(SqliteJournalMode::Wal)
            .synchronous(SqliteSynchronous::Full)
            .busy_timeout(Duration::from_secs(10))
            .foreign_keys(true);
        let pool = SqlitePoolOptions::new()
            .max_connections(8)
            .acquire_timeout(Duration::from_secs(10))
            .connect_with(options)
            .await
            .map_err(err)?;
        SQLITE_MIGRATIONS
            .run(&pool)
            .await
            .map_err(|source| DatabaseError::Migrate {
                url: url.to_owned(),
                source,
            })?;
        Ok(Self {
            pool,
            url: url.to_owned(),
        })
    }

    /// Checks that the database answers and that every embedded migration is applied.
    pub async fn status(&self) -> Result<DatabaseStatus, DatabaseError> {
        let applied: i64 =
            sqlx::query_scalar("SELECT COUNT(*) FROM _sqlx_migrations WHERE success = 1")
                .fetch_one(&self.pool)
                .await
                .map_err(|source| DatabaseError::Sqlx {
                    url: self.url.clone(),
                    source,
                })?;
        Ok(DatabaseStatus {
            applied_migrations: usize::try_from(applied).unwrap_or(0),
            expected_migrations: SQLITE_MIGRATIONS.iter().count(),
        })
    }

    /// The connection pool, for the queue.
    pub fn pool(&self) -> &SqlitePool {
        &self.pool
    }

    /// Closes the pool, waiting for connections in use to be returned.
    pub async fn close(&self) {
        self.pool.close().await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn connect_creates_and_migrates_the_database() {
        let dir = tempfile::tempdir().unwrap();
        let url = format!("sqlite://{}", dir.path().join("jobs.sqlite").display());
        let db = JobDatabase::connect(&url).await.unwrap();
        let status = db.status().await.unwrap();
        assert_eq!(status.applied_migrations, status.expected_migrations);
        assert!(status.expected_migrations >= 1);
        let mode: String = sqlx::query_scalar("PRAGMA journal_mode")
            .fetch_one(db.pool())
            .await
            .unwrap();
        assert_eq!(mode, "wal");
        db.close().await;
        // Reopening an existing database applies nothing twice.
        let again = JobDatabase::connect(&url).await.unwrap();
        assert_eq!(again.status().await.unwrap(), status);
    }

    #[tokio::test]
    async fn non_sqlite_url_is_refused_by_name() {
        let err = JobDatabase::connect("mysql://x").await.unwrap_err();
        assert!(err.to_string().contains("mysql://x"), "{err}");
    }

    #[tokio::test]
    async fn unwritable_location_is_an_error_not_a_panic() {
        let file = tempfile::NamedTempFile::new().unwrap();
        // A path below a regular file cannot be created, even by root.
        let url = format!("sqlite://{}/jobs.sqlite", file.path().display());
        assert!(JobDatabase::connect(&url).await.is_err());
    }
}
