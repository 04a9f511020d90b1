//! Layered configuration: built-in defaults → optional TOML file → `MENTALSIM_*` environment →
//! command-line flags → one typed, validated [`Config`].
//!
//! Every error names the key and the layer it came from (e.g. "`bind` from environment variable
//! MENTALSIM_BIND"), so a bad value is found without reading code.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use figment::Figment;
use figment::providers::{Env, Format, Serialized, Toml};
use serde::{Deserialize, Serialize};

/// How logs are written to standard error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LogFormat {
    /// One JSON object per event, for log collectors.
    Json,
    /// Human-readable lines.
    Text,
}

/// A bearer token and what it may do.
#[derive(Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TokenConfig {
    /// The secret a client sends as `Authorization: Bearer <token>`.
    pub token: String,
    /// Who holds it, for logs and provenance.
    pub name: String,
    /// `engineer` (read and write) or `robot` (read, robot endpoints).
    pub role: edge::Role,
}

impl std::fmt::Debug for TokenConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TokenConfig")
            .field("name", &self.name)
            .field("role", &self.role)
            .finish_non_exhaustive()
    }
}

/// The service's configuration, after all layers are merged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Address the HTTP server binds (both services share it).
    pub bind: SocketAddr,
    /// Directory holding the graph store, the job database and the admin token.
    pub data_dir: PathBuf,
    /// Job database URL; defaults to SQLite in the data directory.
    pub database_url: Option<String>,
    /// Time from request to response head, in seconds.
    pub request_timeout_s: f64,
    /// Largest request body of a map import, a Graph Store write or a SPARQL update by an
    /// engineer, in bytes (map imports carry images: keep it generous).
    pub body_limit_bytes: usize,
    /// Largest body of every other request (a plan, a query, an object report), in bytes.
    pub small_body_limit_bytes: usize,
    /// Requests handled at once, probes excepted; beyond it requests are answered 503 with
    /// `Retry-After` instead of queueing.
    pub max_in_flight: usize,
    /// Open connections at most; further ones wait in the accept queue.
    pub max_connections: usize,
    /// Free space kept on the data directory's disk, bytes: writes that would eat into it
    /// (imports, Graph Store writes, updates, object reports, training checkpoints) are
    /// refused with 507 `storage_full` or deferred, so that state changes still fit. 0: none.
    pub min_free_bytes: u64,
    /// Time a client has to send a request's headers (and the idle timeout of a kept-alive
    /// connection), in seconds.
    pub header_read_timeout_s: f64,
    /// Time running work gets to finish after SIGINT/SIGTERM, in seconds.
    pub shutdown_grace_s: f64,
    /// Log format.
    pub log_format: LogFormat,
    /// Log filter in `tracing_subscriber::EnvFilter` syntax; `RUST_LOG` overrides it.
    pub log_filter: String,
    /// Wall-clock budget of one SPARQL query or update, in seconds; past it, it is cancelled.
    pub query_deadline_s: f64,
    /// Largest CONSTRUCT/DESCRIBE answer, in triples; larger answers are refused, not cut.
    pub max_construct_triples: usize,
    /// Largest serialized SPARQL or Graph Store answer to an engineer, in bytes; a larger one
    /// is refused with 507 as soon as it passes the cap, never cut or held whole.
    pub max_result_bytes: usize,
    /// The same cap for robot tokens.
    pub robot_max_result_bytes: usize,
    /// Bearer tokens. With none, `serve` creates an engineer token in `<data_dir>/admin.token`.
    pub tokens: Vec<TokenConfig>,
    /// A SPARQL 1.1 store to keep the knowledge graph in instead of the embedded one: its
    /// query endpoint (a bare `http://host:port` means an Oxigraph server's `/query` and
    /// `/update`).
    pub store_url: Option<String>,
    /// The remote store's update endpoint [default: `…/update` beside a `…/query` URL, else
    /// `store_url` itself].
    pub store_update_url: Option<String>,
    /// The knowledge service a `mentalsim worker` fetches worlds from (`http://host:port`).
    pub knowledge_url: Option<String>,
    /// The bearer token a `mentalsim worker` sends to the knowledge service; when unset, the
    /// contents of `knowledge_token_file`.
    pub knowledge_token: Option<String>,
    /// File holding that token [default: `<data_dir>/admin.token`].
    pub knowledge_token_file: Option<PathBuf>,
    /// Jobs run at once by one process (`serve`: 0 runs none in process).
    pub worker_concurrency: usize,
    /// A worker's lease on a job, in seconds; a worker that dies loses its jobs after it.
    pub job_lease_s: f64,
    /// Heartbeat period renewing the lease, in seconds (below `job_lease_s`).
    pub job_heartbeat_s: f64,
    /// Delay before the first retry of a failed attempt, in seconds (doubling per attempt).
    pub job_retry_base_s: f64,
    /// Longest delay between retries, in seconds.
    pub job_retry_cap_s: f64,
    /// Finished jobs are deleted this many days after they finished.
    pub job_retention_days: f64,
    /// Seconds between the idle-time improver's rounds over the floors this process planned
    /// on (`serve`; 0: never revise a committed plan).
    pub fleet_improve_every_s: f64,
    /// Where exported policies go [default: `<data_dir>/policies`].
    pub policies_dir: Option<PathBuf>,
    /// Where training checkpoints go [default: `<data_dir>/checkpoints`]; shared by all
    /// workers, so whichever takes a job over can resume it.
    pub checkpoints_dir: Option<PathBuf>,
    /// Serve the console's pages from this directory instead of the copy built into the
    /// binary (front-end development: `npm run build` without rebuilding the binary).
    pub console_dir: Option<PathBuf>,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            bind: SocketAddr::from(([127, 0, 0, 1], 8080)),
            data_dir: PathBuf::from("./data"),
            database_url: None,
            request_timeout_s: 120.0,
            body_limit_bytes: 64 * 1024 * 1024,
            small_body_limit_bytes: 1024 * 1024,
            max_in_flight: 512,
            max_connections: 1024,
            min_free_bytes: 64 * 1024 * 1024,
            header_read_timeout_s: 10.0,
            shutdown_grace_s: 30.0,
            log_format: LogFormat::Text,
            log_filter: "info".to_owned(),
            query_deadline_s: 30.0,
            max_construct_triples: 5_000_000,
            max_result_bytes: 256 * 1024 * 1024,
            robot_max_result_bytes: 16 * 1024 * 1024,
            tokens: Vec::new(),
            store_url: None,
            store_update_url: None,
            knowledge_url: None,
            knowledge_token: None,
            knowledge_token_file: None,
            worker_concurrency: 1,
            fleet_improve_every_s: 1.0,
            job_lease_s: 30.0,
            job_heartbeat_s: 10.0,
            job_retry_base_s: 5.0,
            job_retry_cap_s: 600.0,
            job_retention_days: 30.0,
            policies_dir: None,
            checkpoints_dir: None,
            console_dir: None,
        }
    }
}

/// Values given on the command line; `None` leaves the lower layers' value in place.
#[derive(Debug, Default, Clone, Serialize)]
pub struct Overrides {
    /// `--bind`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bind: Option<String>,
    /// `--data-dir`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub data_dir: Option<PathBuf>,
    /// `--store-url`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub store_url: Option<String>,
    /// `--database-url`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub database_url: Option<String>,
    /// `--knowledge-url`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub knowledge_url: Option<String>,
    /// `--concurrency`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub worker_concurrency: Option<usize>,
}

/// A configuration that could not be loaded or is invalid.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// A value has the wrong type or syntax; the message names key and source.
    #[error("invalid configuration: {0}")]
    Parse(String),
    /// A value parsed but is out of range.
    #[error("invalid configuration: `{key}` {problem} (set by {source_name})")]
    Invalid {
        /// The key.
        key: &'static str,
        /// What is wrong.
        problem: String,
        /// Where the value came from.
        source_name: String,
    },
    /// The named configuration file does not exist.
    #[error("configuration file {0} does not exist")]
    MissingFile(PathBuf),
}

/// "`key` from SOURCE: problem", where SOURCE is the exact environment variable or file.
fn describe(error: &figment::Error) -> String {
    let key = error.path.join(".").to_lowercase();
    let source = match &error.metadata {
        Some(m) if m.name.contains("environment") && !key.is_empty() => {
            format!(
                "environment variable MENTALSIM_{}",
                key.to_uppercase().replace('.', "__")
            )
        }
        Some(m) => match &m.source {
            Some(source) => format!("{} ({source})", m.name),
            None => m.name.to_string(),
        },
        None => "configuration".to_owned(),
    };
    if key.is_empty() {
        format!("{} in {source}", error.kind)
    } else {
        format!("`{key}` from {source}: {}", error.kind)
    }
}

/// Environment variables with our prefix that are not configuration keys: the configuration
/// file, the CLI clients' service and token, and what the scripts and tests read (the venv, the
/// missing-fixture rule, the PostgreSQL binaries, the shared fixtures, the Python clients'
/// endpoint). A shell that sets them must still be able to run `serve`.
const NOT_KEYS: &[&str] = &[
    "config",
    "bin",
    "fault_stuck_task",
    "url",
    "token",
    "venv",
    "require_all",
    "require_postgres",
    "pg_bin",
    "shared",
    "sparql_url",
];

/// Where each key's value came from, to name it in errors: the merged layers' metadata.
struct Sources<'a>(&'a Figment);

impl Sources<'_> {
    /// The layer that set `key`: the exact environment variable, the file, or the defaults.
    fn of(&self, key: &str) -> String {
        self.0
            .find_metadata(key)
            .map(|m| match &m.source {
                _ if m.name.contains("environment") => {
                    format!("environment variable MENTALSIM_{}", key.to_uppercase())
                }
                Some(s) => format!("{} ({s})", m.name),
                None => m.name.to_string(),
            })
            .unwrap_or_else(|| "defaults".to_owned())
    }

    /// The error for `key`'s value, with `problem` and where the value came from.
    fn invalid(&self, key: &'static str, problem: String) -> ConfigError {
        ConfigError::Invalid {
            key,
            problem,
            source_name: self.of(key),
        }
    }

    /// Checks that `key`'s `value` is a positive, finite number of seconds.
    fn positive_seconds(&self, key: &'static str, value: f64) -> Result<(), ConfigError> {
        if value.is_finite() && value > 0.0 {
            Ok(())
        } else {
            Err(self.invalid(
                key,
                format!("must be a positive number of seconds, got {value}"),
            ))
        }
    }
}

/// What is wrong with `url` as the address of an HTTP service (an http:// or https:// URL with
/// a host), if anything.
fn http_url_problem(url: &str) -> Option<String> {
    let parsed = reqwest::Url::parse(url).map_err(|e| e.to_string());
    match parsed {
        Ok(u) if matches!(u.scheme(), "http" | "https") && u.has_host() => None,
        Ok(u) => Some(format!(
            "must be an http:// or https:// URL with a host, got {url:?} (scheme {})",
            u.scheme()
        )),
        Err(e) => Some(format!(
            "must be an http:// or https:// URL, got {url:?}: {e}"
        )),
    }
}

impl Config {
    /// Merges the layers. `file` is the optional TOML file (`--config` or `MENTALSIM_CONFIG`).
    pub fn load(file: Option<&Path>, overrides: &Overrides) -> Result<Self, ConfigError> {
        let figment = Self::figment(file, overrides)?;
        let config: Config = figment.extract().map_err(|e| {
            // One line per error, each naming the key and the exact source it came from.
            ConfigError::Parse(
                e.into_iter()
                    .map(|e| describe(&e))
                    .collect::<Vec<_>>()
                    .join("; "),
            )
        })?;
        config.validate(&figment)?;
        Ok(config)
    }

    fn figment(file: Option<&Path>, overrides: &Overrides) -> Result<Figment, ConfigError> {
        let mut figment = Figment::from(Serialized::defaults(Config::default()));
        if let Some(file) = file {
            if !file.is_file() {
                return Err(ConfigError::MissingFile(file.to_owned()));
            }
            figment = figment.merge(Toml::file_exact(file));
        }
        figment = figment
            .merge(Env::prefixed("MENTALSIM_").filter(|key| {
                !NOT_KEYS
                    .iter()
                    .any(|k| key.as_str().eq_ignore_ascii_case(k))
            }))
            .merge(Serialized::defaults(overrides).profile(figment::Profile::Default));
        Ok(figment)
    }

    /// Checks the merged values; the first problem found is the error, naming its key and the
    /// layer that set it.
    fn validate(&self, figment: &Figment) -> Result<(), ConfigError> {
        let sources = Sources(figment);
        self.validate_timeouts(&sources)?;
        self.validate_tokens(&sources)?;
        self.validate_limits(&sources)?;
        self.validate_stores(&sources)?;
        self.validate_jobs(&sources)
    }

    /// The HTTP timeouts: positive, and the generic request timeout no shorter than the query
    /// deadline.
    fn validate_timeouts(&self, sources: &Sources<'_>) -> Result<(), ConfigError> {
        sources.positive_seconds("request_timeout_s", self.request_timeout_s)?;
        sources.positive_seconds("shutdown_grace_s", self.shutdown_grace_s)?;
        sources.positive_seconds("query_deadline_s", self.query_deadline_s)?;
        sources.positive_seconds("header_read_timeout_s", self.header_read_timeout_s)?;
        if self.request_timeout_s < self.query_deadline_s {
            return Err(sources.invalid(
                "request_timeout_s",
                format!(
                    "({}) must be at least query_deadline_s ({}), or queries are cut by the \
                     generic timeout before their own deadline reports them",
                    self.request_timeout_s, self.query_deadline_s
                ),
            ));
        }
        Ok(())
    }

    /// Every bearer token is at least 16 characters long.
    fn validate_tokens(&self, sources: &Sources<'_>) -> Result<(), ConfigError> {
        for (i, t) in self.tokens.iter().enumerate() {
            if t.token.len() < 16 {
                return Err(sources.invalid(
                    "tokens",
                    format!(
                        "entry {i} ({}) has a token shorter than 16 characters",
                        t.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The body, result and connection limits have their least useful values.
    fn validate_limits(&self, sources: &Sources<'_>) -> Result<(), ConfigError> {
        for (key, value, least) in [
            ("body_limit_bytes", self.body_limit_bytes, 1024),
            ("small_body_limit_bytes", self.small_body_limit_bytes, 1024),
            ("max_in_flight", self.max_in_flight, 1),
            ("max_connections", self.max_connections, 1),
            ("max_result_bytes", self.max_result_bytes, 1024),
            ("robot_max_result_bytes", self.robot_max_result_bytes, 1024),
        ] {
            if value < least {
                return Err(sources.invalid(key, format!("must be at least {least}, got {value}")));
            }
        }
        Ok(())
    }

    /// Where things are kept: a data directory, a remote graph store's URLs (an update URL
    /// only beside a store URL), the job database's and the knowledge service's URLs.
    fn validate_stores(&self, sources: &Sources<'_>) -> Result<(), ConfigError> {
        if self.data_dir.as_os_str().is_empty() {
            return Err(sources.invalid("data_dir", "must not be empty".to_owned()));
        }
        for (key, url) in [
            ("store_url", &self.store_url),
            ("store_update_url", &self.store_update_url),
        ] {
            if let Some(url) = url
                && let Some(problem) = http_url_problem(url)
            {
                return Err(sources.invalid(key, problem));
            }
        }
        if self.store_update_url.is_some() && self.store_url.is_none() {
            return Err(sources.invalid(
                "store_update_url",
                "is set but store_url is not; set both or neither".to_owned(),
            ));
        }
        if let Some(url) = &self.database_url
            && queue::Backend::of_url(url).is_none()
        {
            return Err(sources.invalid(
                "database_url",
                format!(
                    "must be a sqlite:, postgres:// or postgresql:// URL, got {:?}",
                    queue::database::redact_url(url)
                ),
            ));
        }
        if let Some(url) = &self.knowledge_url
            && !(url.starts_with("http://") || url.starts_with("https://"))
        {
            return Err(sources.invalid(
                "knowledge_url",
                format!("must be an http:// or https:// URL, got {url:?}"),
            ));
        }
        Ok(())
    }

    /// The job queue's timing (positive; heartbeats inside a lease; a retry cap no smaller
    /// than its base), the retention and the worker concurrency.
    fn validate_jobs(&self, sources: &Sources<'_>) -> Result<(), ConfigError> {
        sources.positive_seconds("job_lease_s", self.job_lease_s)?;
        sources.positive_seconds("job_heartbeat_s", self.job_heartbeat_s)?;
        sources.positive_seconds("job_retry_base_s", self.job_retry_base_s)?;
        sources.positive_seconds("job_retry_cap_s", self.job_retry_cap_s)?;
        if self.job_heartbeat_s >= self.job_lease_s {
            return Err(sources.invalid(
                "job_heartbeat_s",
                format!(
                    "({}) must be below job_lease_s ({}), or leases run out between heartbeats",
                    self.job_heartbeat_s, self.job_lease_s
                ),
            ));
        }
        if self.job_retry_cap_s < self.job_retry_base_s {
            return Err(sources.invalid(
                "job_retry_cap_s",
                format!(
                    "({}) must be at least job_retry_base_s ({})",
                    self.job_retry_cap_s, self.job_retry_base_s
                ),
            ));
        }
        if !(self.job_retention_days.is_finite() && self.job_retention_days > 0.0) {
            return Err(sources.invalid(
                "job_retention_days",
                format!(
                    "must be a positive number of days, got {}",
                    self.job_retention_days
                ),
            ));
        }
        if !(self.fleet_improve_every_s.is_finite()
            && (0.0..=3600.0).contains(&self.fleet_improve_every_s))
        {
            return Err(sources.invalid(
                "fleet_improve_every_s",
                format!(
                    "must lie in [0, 3600] seconds (0: off), got {}",
                    self.fleet_improve_every_s
                ),
            ));
        }
        if self.worker_concurrency > 256 {
            return Err(sources.invalid(
                "worker_concurrency",
                format!("must be at most 256, got {}", self.worker_concurrency),
            ));
        }
        Ok(())
    }

    /// The job database URL, defaulting to `sqlite://<data_dir>/jobs.sqlite`.
    pub fn database_url(&self) -> String {
        self.database_url
            .clone()
            .unwrap_or_else(|| format!("sqlite://{}", self.data_dir.join("jobs.sqlite").display()))
    }

    /// The remote graph store, when `store_url` is set; requests to it get the query deadline
    /// as their timeout.
    pub fn remote_store(&self) -> Option<knowledge::RemoteConfig> {
        self.store_url.as_ref().map(|url| knowledge::RemoteConfig {
            url: url.clone(),
            update_url: self.store_update_url.clone(),
            timeout: Duration::from_secs_f64(self.query_deadline_s),
        })
    }

    /// Where exported policies go.
    pub fn policies_dir(&self) -> PathBuf {
        self.policies_dir
            .clone()
            .unwrap_or_else(|| self.data_dir.join("policies"))
    }

    /// Where policy-aware roadmaps are stored: beside the policies, so that every process that
    /// sees the policies sees them.
    pub fn roadmaps_dir(&self) -> PathBuf {
        let policies = self.policies_dir();
        policies.parent().map_or_else(
            || self.data_dir.join("policy-roadmaps"),
            |p| p.join("policy-roadmaps"),
        )
    }

    /// Where running trainings keep their checkpoints.
    pub fn checkpoints_dir(&self) -> PathBuf {
        self.checkpoints_dir
            .clone()
            .unwrap_or_else(|| self.data_dir.join("checkpoints"))
    }

    /// The token a worker sends to the knowledge service: `knowledge_token`, else the contents
    /// of `knowledge_token_file` (default `<data_dir>/admin.token`) when readable.
    pub fn knowledge_token(&self) -> Option<String> {
        if let Some(t) = &self.knowledge_token {
            return Some(t.clone());
        }
        let file = self
            .knowledge_token_file
            .clone()
            .unwrap_or_else(|| self.admin_token_path());
        std::fs::read_to_string(file)
            .ok()
            .map(|t| t.trim().to_owned())
            .filter(|t| !t.is_empty())
    }

    /// The runners' settings (lease, heartbeat, concurrency, shutdown grace).
    pub fn worker_config(&self) -> queue::WorkerConfig {
        queue::WorkerConfig {
            concurrency: self.worker_concurrency.max(1),
            lease: Duration::from_secs_f64(self.job_lease_s),
            heartbeat: Duration::from_secs_f64(self.job_heartbeat_s),
            shutdown_grace: self.shutdown_grace(),
            ..queue::WorkerConfig::default()
        }
    }

    /// The retry backoff.
    pub fn job_backoff(&self) -> queue::Backoff {
        queue::Backoff {
            base: Duration::from_secs_f64(self.job_retry_base_s),
            cap: Duration::from_secs_f64(self.job_retry_cap_s),
        }
    }

    /// How long finished jobs are kept.
    pub fn job_retention(&self) -> Duration {
        Duration::from_secs_f64(self.job_retention_days * 86_400.0)
    }

    /// Where the embedded graph store lives.
    pub fn store_dir(&self) -> PathBuf {
        self.data_dir.join("oxigraph")
    }

    /// The request timeout as a duration.
    pub fn request_timeout(&self) -> Duration {
        Duration::from_secs_f64(self.request_timeout_s)
    }

    /// The free-space reserve of the data directory's disk.
    pub fn disk_watch(&self) -> edge::disk::DiskWatch {
        edge::disk::DiskWatch::new(&self.data_dir, self.min_free_bytes)
    }

    /// Where the console's pages come from.
    pub fn console_pages(&self) -> crate::console::Pages {
        match &self.console_dir {
            Some(dir) => crate::console::Pages::Directory(dir.clone()),
            None => crate::console::Pages::Embedded,
        }
    }

    /// The connection limits of the HTTP server.
    pub fn serve_limits(&self) -> edge::serve::ServeLimits {
        edge::serve::ServeLimits {
            header_read_timeout: Duration::from_secs_f64(self.header_read_timeout_s),
            max_connections: self.max_connections,
        }
    }

    /// What is decided from a request's head (see `edge::guard`): `tokens`, the probes that
    /// need none, the routes that may carry large bodies, requests in flight.
    pub fn guard(&self, tokens: edge::Tokens) -> std::sync::Arc<edge::guard::Guard> {
        use axum::http::Method;
        edge::guard::Guard::new(edge::guard::GuardConfig {
            tokens,
            public_routes: ["/healthz", "/readyz", "/metrics"]
                .into_iter()
                .chain(crate::console::PUBLIC_ROUTES)
                .collect(),
            large_body_routes: vec![
                (Method::POST, "/v1/maps"),
                (Method::POST, "/sparql"),
                (Method::PUT, "/store"),
                (Method::POST, "/store"),
                (Method::PUT, "/store/{*graph}"),
                (Method::POST, "/store/{*graph}"),
            ],
            large_body: self.body_limit_bytes,
            small_body: self.small_body_limit_bytes.min(self.body_limit_bytes),
            max_in_flight: self.max_in_flight,
            retry_after_s: 1,
        })
    }

    /// The SPARQL limits.
    pub fn query_limits(&self) -> knowledge::QueryLimits {
        knowledge::QueryLimits {
            deadline: Duration::from_secs_f64(self.query_deadline_s),
            max_construct_triples: self.max_construct_triples,
            max_result_bytes: self.max_result_bytes,
            robot_max_result_bytes: self.robot_max_result_bytes,
            max_query_bytes: self.small_body_limit_bytes,
        }
    }

    /// Where the generated admin token is kept when no tokens are configured.
    pub fn admin_token_path(&self) -> PathBuf {
        self.data_dir.join("admin.token")
    }

    /// The shutdown grace period as a duration.
    pub fn shutdown_grace(&self) -> Duration {
        Duration::from_secs_f64(self.shutdown_grace_s)
    }
}

#[cfg(test)]
#[allow(
    clippy::result_large_err,
    reason = "figment's Jail closures return its own large error type"
)]
mod tests {
    use super::*;
    use figment::Jail;

    fn load(jail_file: Option<&str>, overrides: Overrides) -> Result<Config, String> {
        Config::load(jail_file.map(Path::new), &overrides).map_err(|e| e.to_string())
    }

    #[test]
    fn defaults_apply_without_any_layer() {
        Jail::expect_with(|jail| {
            jail.clear_env();
            let config = load(None, Overrides::default()).unwrap();
            assert_eq!(config, Config::default());
            assert_eq!(config.bind.port(), 8080);
            Ok(())
        });
    }

    #[test]
    fn layers_override_in_order_file_env_flags() {
        Jail::expect_with(|jail| {
            jail.clear_env();
            jail.create_file(
                "m.toml",
                "bind = '0.0.0.0:9000'\ndata_dir = '/srv/a'\nrequest_timeout_s = 50",
            )?;
            jail.set_env("MENTALSIM_DATA_DIR", "/srv/b");
            // What the scripts and the CLI clients read is not configuration, and no error.
            for key in ["VENV", "REQUIRE_ALL", "TOKEN", "URL", "PG_BIN"] {
                jail.set_env(format!("MENTALSIM_{key}"), "x");
            }
            let config = load(Some("m.toml"), Overrides::default()).unwrap();
            assert_eq!(config.bind.port(), 9000);
            assert_eq!(config.data_dir, PathBuf::from("/srv/b"));
            assert_eq!(config.request_timeout_s, 50.0);
            let flags = Overrides {
                bind: Some("127.0.0.1:9100".to_owned()),
                data_dir: Some(PathBuf::from("/srv/c")),
                store_url: None,
                ..Overrides::default()
            };
            let config = load(Some("m.toml"), flags).unwrap();
            assert_eq!(config.bind.port(), 9100);
            assert_eq!(config.data_dir, PathBuf::from("/srv/c"));
            Ok(())
        });
    }

    #[test]
    fn non_numeric_port_in_env_names_key_and_variable() {
        Jail::expect_with(|jail| {
            jail.clear_env();
            jail.set_env("MENTALSIM_BIND", "127.0.0.1:http");
            let err = load(None, Overrides::default()).unwrap_err();
            assert!(err.contains("bind"), "{err}");
            assert!(err.contains("MENTALSIM_BIND"), "{err}");
            Ok(())
        });
    }

    #[test]
    fn ill_typed_number_in_file_names_key_and_file() {
        Jail::expect_with(|jail| {
            jail.clear_env();
            jail.create_file("bad.toml", "request_timeout_s = 'soon'")?;
            let err = load(Some("bad.toml"), Overrides::default()).unwrap_err();
            assert!(err.contains("request_timeout_s"), "{err}");
            assert!(err.contains("bad.toml"), "{err}");
            Ok(())
        });
    }

    #[test]
    fn out_of_range_value_names_key_and_source() {
        Jail::expect_with(|jail| {
            jail.clear_env();
            jail.set_env("MENTALSIM_REQUEST_TIMEOUT_S", "-3");
            let err = load(None, Overrides::default()).unwrap_err();
            assert!(err.contains("request_timeout_s"), "{err}");
            assert!(err.contains("MENTALSIM_REQUEST_TIMEOUT_S"), "{err}");
            Ok(())
        });
    }

    #[test]
    fn unknown_key_in_file_is_refused() {
        Jail::expect_with(|jail| {
            jail.clear_env();
            jail.create_file("typo.toml", "bnid = '127.0.0.1:1'")?;
            let err = load(Some("typo.toml"), Overrides::default()).unwrap_err();
            assert!(err.contains("bnid"), "{err}");
            Ok(())
        });
    }

    #[test]
    fn store_url_comes_from_every_layer_and_bad_ones_name_key_and_source() {
        Jail::expect_with(|jail| {
            jail.clear_env();
            jail.create_file("r.toml", "store_url = 'http://db:7878'")?;
            let config = load(Some("r.toml"), Overrides::default()).unwrap();
            let remote = config.remote_store().unwrap();
            assert_eq!(remote.endpoints().0, "http://db:7878/query");
            jail.set_env("MENTALSIM_STORE_URL", "http://other:7878/query");
            let config = load(Some("r.toml"), Overrides::default()).unwrap();
            assert_eq!(config.store_url.as_deref(), Some("http://other:7878/query"));
            let flags = Overrides {
                store_url: Some("https://flag/sparql".to_owned()),
                ..Overrides::default()
            };
            let config = load(Some("r.toml"), flags).unwrap();
            assert_eq!(config.store_url.as_deref(), Some("https://flag/sparql"));
            jail.set_env("MENTALSIM_STORE_URL", "ftp://db/q");
            let err = load(None, Overrides::default()).unwrap_err();
            assert!(err.contains("store_url"), "{err}");
            assert!(err.contains("MENTALSIM_STORE_URL"), "{err}");
            jail.set_env("MENTALSIM_STORE_URL", "not a url");
            let err = load(None, Overrides::default()).unwrap_err();
            assert!(err.contains("MENTALSIM_STORE_URL"), "{err}");
            jail.clear_env();
            jail.create_file("bad.toml", "store_url = 'db:7878'")?;
            let err = load(Some("bad.toml"), Overrides::default()).unwrap_err();
            assert!(
                err.contains("store_url") && err.contains("bad.toml"),
                "{err}"
            );
            Ok(())
        });
    }

    #[test]
    fn missing_file_is_named() {
        Jail::expect_with(|jail| {
            jail.clear_env();
            let err = load(Some("nowhere.toml"), Overrides::default()).unwrap_err();
            assert!(err.contains("nowhere.toml"), "{err}");
            Ok(())
        });
    }

    #[test]
    fn job_database_urls_of_both_backends_are_accepted_and_others_named() {
        Jail::expect_with(|jail| {
            jail.clear_env();
            jail.set_env("MENTALSIM_DATABASE_URL", "postgres://ms:pw@db:5432/jobs");
            let config = load(None, Overrides::default()).unwrap();
            assert_eq!(config.database_url(), "postgres://ms:pw@db:5432/jobs");
            jail.set_env("MENTALSIM_DATABASE_URL", "postgresql://db/jobs");
            assert!(load(None, Overrides::default()).is_ok());
            jail.set_env("MENTALSIM_DATABASE_URL", "mysql://ms:secret@db/jobs");
            let err = load(None, Overrides::default()).unwrap_err();
            assert!(err.contains("database_url"), "{err}");
            assert!(err.contains("MENTALSIM_DATABASE_URL"), "{err}");
            assert!(!err.contains("secret"), "{err}");
            Ok(())
        });
    }

    #[test]
    fn job_keys_have_defaults_and_are_checked_by_name() {
        Jail::expect_with(|jail| {
            jail.clear_env();
            let config = load(None, Overrides::default()).unwrap();
            assert_eq!(config.worker_concurrency, 1);
            assert_eq!(config.policies_dir(), PathBuf::from("./data/policies"));
            assert_eq!(
                config.checkpoints_dir(),
                PathBuf::from("./data/checkpoints")
            );
            assert_eq!(config.worker_config().lease, Duration::from_secs(30));
            jail.set_env("MENTALSIM_WORKER_CONCURRENCY", "3");
            jail.set_env("MENTALSIM_POLICIES_DIR", "/srv/p");
            jail.set_env("MENTALSIM_KNOWLEDGE_URL", "http://knowledge:8080");
            let config = load(None, Overrides::default()).unwrap();
            assert_eq!(config.worker_concurrency, 3);
            assert_eq!(config.policies_dir(), PathBuf::from("/srv/p"));
            assert_eq!(
                config.knowledge_url.as_deref(),
                Some("http://knowledge:8080")
            );
            let flags = Overrides {
                worker_concurrency: Some(5),
                knowledge_url: Some("https://k.example".to_owned()),
                ..Overrides::default()
            };
            let config = load(None, flags).unwrap();
            assert_eq!(config.worker_concurrency, 5);
            assert_eq!(config.knowledge_url.as_deref(), Some("https://k.example"));

            jail.set_env("MENTALSIM_KNOWLEDGE_URL", "knowledge:8080");
            let err = load(None, Overrides::default()).unwrap_err();
            assert!(err.contains("knowledge_url"), "{err}");
            assert!(err.contains("MENTALSIM_KNOWLEDGE_URL"), "{err}");
            jail.set_env("MENTALSIM_KNOWLEDGE_URL", "http://k");
            jail.set_env("MENTALSIM_JOB_HEARTBEAT_S", "60");
            let err = load(None, Overrides::default()).unwrap_err();
            assert!(err.contains("job_heartbeat_s"), "{err}");
            jail.set_env("MENTALSIM_JOB_HEARTBEAT_S", "5");
            jail.create_file("j.toml", "job_retention_days = 0")?;
            let err = load(Some("j.toml"), Overrides::default()).unwrap_err();
            assert!(err.contains("job_retention_days"), "{err}");
            assert!(err.contains("j.toml"), "{err}");
            jail.set_env("MENTALSIM_WORKER_CONCURRENCY", "many");
            let err = load(None, Overrides::default()).unwrap_err();
            assert!(err.contains("worker_concurrency"), "{err}");
            Ok(())
        });
    }

    /// Every check names its key, the problem and the layer that set the value; the first
    /// problem found is the one reported. Pinned message by message.
    #[test]
    fn every_check_names_key_problem_and_layer() {
        let cases: &[(&str, &str, &str)] = &[
            (
                "shutdown_grace_s = 0",
                "shutdown_grace_s",
                "must be a positive number of seconds, got 0",
            ),
            (
                "request_timeout_s = 10.0\nquery_deadline_s = 20.0",
                "request_timeout_s",
                "(10) must be at least query_deadline_s (20), or queries are cut by the generic \
                 timeout before their own deadline reports them",
            ),
            (
                "[[tokens]]\ntoken = \"short\"\nname = \"bot\"\nrole = \"robot\"",
                "tokens",
                "entry 0 (bot) has a token shorter than 16 characters",
            ),
            (
                "max_in_flight = 0",
                "max_in_flight",
                "must be at least 1, got 0",
            ),
            (
                "robot_max_result_bytes = 10",
                "robot_max_result_bytes",
                "must be at least 1024, got 10",
            ),
            ("data_dir = \"\"", "data_dir", "must not be empty"),
            (
                "store_url = \"ftp://x\"",
                "store_url",
                "must be an http:// or https:// URL with a host, got \"ftp://x\" (scheme ftp)",
            ),
            (
                "store_update_url = \"not a url\"",
                "store_update_url",
                "must be an http:// or https:// URL, got \"not a url\": relative URL without a \
                 base",
            ),
            (
                "store_update_url = \"http://x/update\"",
                "store_update_url",
                "is set but store_url is not; set both or neither",
            ),
            (
                "database_url = \"mysql://u:secret@h/db\"",
                "database_url",
                "must be a sqlite:, postgres:// or postgresql:// URL, got \"mysql://u:***@h/db\"",
            ),
            (
                "knowledge_url = \"knowledge:8080\"",
                "knowledge_url",
                "must be an http:// or https:// URL, got \"knowledge:8080\"",
            ),
            (
                "job_lease_s = -1.0",
                "job_lease_s",
                "must be a positive number of seconds, got -1",
            ),
            (
                "job_retry_base_s = 10.0\njob_retry_cap_s = 5.0",
                "job_retry_cap_s",
                "(5) must be at least job_retry_base_s (10)",
            ),
            (
                "job_retention_days = -2.0",
                "job_retention_days",
                "must be a positive number of days, got -2",
            ),
            (
                "worker_concurrency = 300",
                "worker_concurrency",
                "must be at most 256, got 300",
            ),
            (
                "max_in_flight = 0\njob_lease_s = -1.0",
                "max_in_flight",
                "must be at least 1, got 0",
            ),
        ];
        Jail::expect_with(|jail| {
            jail.clear_env();
            for (toml, key, problem) in cases {
                jail.create_file("c.toml", toml)?;
                assert_eq!(
                    load(Some("c.toml"), Overrides::default()).unwrap_err(),
                    format!("invalid configuration: `{key}` {problem} (set by TOML file (c.toml))")
                );
            }
            jail.set_env("MENTALSIM_WORKER_CONCURRENCY", "257");
            assert_eq!(
                load(None, Overrides::default()).unwrap_err(),
                "invalid configuration: `worker_concurrency` must be at most 256, got 257 (set by \
                 environment variable MENTALSIM_WORKER_CONCURRENCY)"
            );
            Ok(())
        });
    }
}
