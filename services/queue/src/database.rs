//! The job database: connection, durability settings and migrations, on SQLite or PostgreSQL.
//!
//! The URL picks the backend: `sqlite://PATH` (the default: one file, WAL, `synchronous=FULL`)
//! or `postgres://…` / `postgresql://…` (the scale-out deployment). Both get the same schema
//! (`migrations/sqlite`, `migrations/postgres`) and the same queue code ([`crate::Queue`]).

use std::str::FromStr;
use std::time::Duration;

use sqlx::migrate::Migrator;
use sqlx::postgres::{PgConnectOptions, PgPool, PgPoolOptions};
use sqlx::sqlite::{
    SqliteConnectOptions, SqliteJournalMode, SqlitePool, SqlitePoolOptions, SqliteSynchronous,
};

static SQLITE_MIGRATIONS: Migrator = sqlx::migrate!("../../migrations/sqlite");
static POSTGRES_MIGRATIONS: Migrator = sqlx::migrate!("../../migrations/postgres");

/// Why the job database could not be opened or used.
#[derive(Debug, thiserror::Error)]
pub enum DatabaseError {
    /// The URL names a database this build cannot use.
    #[error(
        "unsupported job database URL {url:?}: expected sqlite://PATH, postgres://… or postgresql://…"
    )]
    UnsupportedUrl {
        /// The URL as given (password removed).
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

/// Which database holds the queue.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// One SQLite file in WAL mode.
    Sqlite,
    /// A PostgreSQL server.
    Postgres,
}

impl Backend {
    /// The backend a URL names, if any.
    pub fn of_url(url: &str) -> Option<Self> {
        if url.starts_with("sqlite:") {
            Some(Self::Sqlite)
        } else if url.starts_with("postgres://") || url.starts_with("postgresql://") {
            Some(Self::Postgres)
        } else {
            None
        }
    }
}

/// A connection pool of either backend.
#[derive(Debug, Clone)]
pub(crate) enum Pool {
    Sqlite(SqlitePool),
    Postgres(PgPool),
}

/// How many connections a pool keeps at most.
#[derive(Debug, Clone, Copy)]
pub struct PoolSize(pub u32);

impl Default for PoolSize {
    fn default() -> Self {
        Self(8)
    }
}

/// The job queue's database, migrated to the schema this build expects.
#[derive(Debug, Clone)]
pub struct JobDatabase {
    pub(crate) pool: Pool,
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

/// `url` with the password (if any) replaced by `***`, for messages and logs.
pub fn redact_url(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_owned();
    };
    let authority_end = rest.find(['/', '?']).unwrap_or(rest.len());
    let (authority, tail) = rest.split_at(authority_end);
    match authority.rsplit_once('@') {
        Some((userinfo, host)) => match userinfo.split_once(':') {
            Some((user, _password)) => format!("{scheme}://{user}:***@{host}{tail}"),
            None => url.to_owned(),
        },
        None => url.to_owned(),
    }
}

impl JobDatabase {
    /// Opens the database at `url` (creating an SQLite file if needed) and applies pending
    /// migrations, with the default pool size.
    ///
    /// SQLite runs in WAL mode with `synchronous = FULL` and a 10 s busy timeout: a job
    /// acknowledged to a client has reached the disk, even if the machine loses power right
    /// after. PostgreSQL commits are durable with its default `synchronous_commit = on`.
    pub async fn connect(url: &str) -> Result<Self, DatabaseError> {
        Self::connect_with(url, PoolSize::default()).await
    }

    /// [`JobDatabase::connect`] with a chosen pool size.
    pub async fn connect_with(url: &str, size: PoolSize) -> Result<Self, DatabaseError> {
        let shown = redact_url(url);
        let err = |source| DatabaseError::Sqlx {
            url: shown.clone(),
            source,
        };
        let migrate_err = |source| DatabaseError::Migrate {
            url: shown.clone(),
            source,
        };
        let pool = match Backend::of_url(url) {
            Some(Backend::Sqlite) => {
                let options = SqliteConnectOptions::from_str(url)
                    .map_err(err)?
                    .create_if_missing(true)
                    .journal_mode(SqliteJournalMode::Wal)
                    .synchronous(SqliteSynchronous::Full)
                    .busy_timeout(Duration::from_secs(10))
                    .foreign_keys(true);
                let pool = SqlitePoolOptions::new()
                    .max_connections(size.0.max(1))
                    .acquire_timeout(Duration::from_secs(10))
                    .connect_with(options)
                    .await
                    .map_err(err)?;
                SQLITE_MIGRATIONS.run(&pool).await.map_err(migrate_err)?;
                Pool::Sqlite(pool)
            }
            Some(Backend::Postgres) => {
                let options = PgConnectOptions::from_str(url).map_err(err)?;
                let pool = PgPoolOptions::new()
                    .max_connections(size.0.max(1))
                    .acquire_timeout(Duration::from_secs(10))
                    .connect_with(options)
                    .await
                    .map_err(err)?;
                // The migrator holds an advisory lock: workers starting together migrate once.
                POSTGRES_MIGRATIONS.run(&pool).await.map_err(migrate_err)?;
                Pool::Postgres(pool)
            }
            None => return Err(DatabaseError::UnsupportedUrl { url: shown }),
        };
        Ok(Self { pool, url: shown })
    }

    /// Which backend this is.
    pub fn backend(&self) -> Backend {
        match self.pool {
            Pool::Sqlite(_) => Backend::Sqlite,
            Pool::Postgres(_) => Backend::Postgres,
        }
    }

    /// The URL, password removed.
    pub fn url(&self) -> &str {
        &self.url
    }

    pub(crate) fn error(&self, source: sqlx::Error) -> DatabaseError {
        DatabaseError::Sqlx {
            url: self.url.clone(),
            source,
        }
    }

    /// Checks that the database answers and that every embedded migration is applied.
    pub async fn status(&self) -> Result<DatabaseStatus, DatabaseError> {
        const APPLIED: &str = "SELECT COUNT(*) FROM _sqlx_migrations WHERE success";
        let (applied, expected) = match &self.pool {
            Pool::Sqlite(pool) => (
                sqlx::query_scalar::<_, i64>(APPLIED).fetch_one(pool).await,
                SQLITE_MIGRATIONS.iter().count(),
            ),
            Pool::Postgres(pool) => (
                sqlx::query_scalar::<_, i64>(APPLIED).fetch_one(pool).await,
                POSTGRES_MIGRATIONS.iter().count(),
            ),
        };
        let applied = applied.map_err(|e| self.error(e))?;
        Ok(DatabaseStatus {
            applied_migrations: usize::try_from(applied).unwrap_or(0),
            expected_migrations: expected,
        })
    }

    /// The SQLite pool, when this is SQLite (for tests and diagnostics).
    pub fn sqlite_pool(&self) -> Option<&SqlitePool> {
        match &self.pool {
            Pool::Sqlite(pool) => Some(pool),
            Pool::Postgres(_) => None,
        }
    }

    /// The PostgreSQL pool, when this is PostgreSQL (for tests and diagnostics).
    pub fn postgres_pool(&self) -> Option<&PgPool> {
        match &self.pool {
            Pool::Postgres(pool) => Some(pool),
            Pool::Sqlite(_) => None,
        }
    }

    /// Closes the pool, waiting for connections in use to be returned.
    pub async fn close(&self) {
        match &self.pool {
            Pool::Sqlite(pool) => pool.close().await,
            Pool::Postgres(pool) => pool.close().await,
        }
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
        assert_eq!(db.backend(), Backend::Sqlite);
        let status = db.status().await.unwrap();
        assert_eq!(status.applied_migrations, status.expected_migrations);
        assert!(status.expected_migrations >= 2);
        let mode: String = sqlx::query_scalar("PRAGMA journal_mode")
            .fetch_one(db.sqlite_pool().unwrap())
            .await
            .unwrap();
        assert_eq!(mode, "wal");
        db.close().await;
        // Reopening an existing database applies nothing twice.
        let again = JobDatabase::connect(&url).await.unwrap();
        assert_eq!(again.status().await.unwrap(), status);
    }

    #[tokio::test]
    async fn a_database_from_the_first_schema_keeps_its_jobs() {
        let dir = tempfile::tempdir().unwrap();
        let url = format!("sqlite://{}", dir.path().join("jobs.sqlite").display());
        {
            let options = SqliteConnectOptions::from_str(&url)
                .unwrap()
                .create_if_missing(true);
            let pool = SqlitePool::connect_with(options).await.unwrap();
            let first = Migrator {
                migrations: SQLITE_MIGRATIONS.migrations[..1].to_vec().into(),
                ..Migrator::DEFAULT
            };
            first.run(&pool).await.unwrap();
            sqlx::query(
                "INSERT INTO jobs (id, kind, state, payload, attempt, run_after_ms, created_ms, updated_ms)
                 VALUES ('j1', 'train', 'queued', '{}', 1, 5, 5, 5)",
            )
            .execute(&pool)
            .await
            .unwrap();
            pool.close().await;
        }
        let db = JobDatabase::connect(&url).await.unwrap();
        let (kind, token): (String, i64) =
            sqlx::query_as("SELECT kind, lease_token FROM jobs WHERE id = 'j1'")
                .fetch_one(db.sqlite_pool().unwrap())
                .await
                .unwrap();
        assert_eq!((kind.as_str(), token), ("train", 1));
    }

    #[tokio::test]
    async fn unsupported_url_is_refused_by_name() {
        let err = JobDatabase::connect("mysql://x").await.unwrap_err();
        assert!(err.to_string().contains("mysql://x"), "{err}");
    }

    #[test]
    fn passwords_are_redacted() {
        assert_eq!(
            redact_url("postgres://ms:secret@db:5432/jobs?sslmode=disable"),
            "postgres://ms:***@db:5432/jobs?sslmode=disable"
        );
        assert_eq!(redact_url("postgres://ms@db/jobs"), "postgres://ms@db/jobs");
        assert_eq!(redact_url("sqlite://./a:b@c"), "sqlite://./a:b@c");
        assert_eq!(Backend::of_url("postgresql://x"), Some(Backend::Postgres));
    }

    #[tokio::test]
    async fn unwritable_location_is_an_error_not_a_panic() {
        let file = tempfile::NamedTempFile::new().unwrap();
        // A path below a regular file cannot be created, even by root.
        let url = format!("sqlite://{}/jobs.sqlite", file.path().display());
        assert!(JobDatabase::connect(&url).await.is_err());
    }
}
