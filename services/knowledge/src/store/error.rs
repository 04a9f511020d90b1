//! Why the graph store could not be opened or used, for both backends, and what each cause
//! means to an HTTP client.

/// Why the store could not be opened or used.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// Oxigraph refused to open or query its directory.
    #[error("graph store at {location}: {source}")]
    Storage {
        /// The store directory, or the remote's URL.
        location: String,
        /// Oxigraph's error.
        #[source]
        source: oxigraph::store::StorageError,
    },
    /// A query the service runs itself failed to evaluate or to parse.
    #[error("graph store at {location}: {message}")]
    Query {
        /// The store directory, or the remote's URL.
        location: String,
        /// What went wrong.
        message: String,
    },
    /// The remote store cannot be reached (connection refused, DNS, TLS).
    #[error("graph store at {url} is unreachable: {message}")]
    Unavailable {
        /// The endpoint that was called.
        url: String,
        /// What the HTTP client said.
        message: String,
    },
    /// The remote store did not answer within the deadline.
    #[error("graph store at {url} did not answer within {seconds} s")]
    TimedOut {
        /// The endpoint that was called.
        url: String,
        /// The deadline.
        seconds: f64,
    },
    /// The remote store answered with an error status.
    #[error("graph store at {url} answered {status}: {message}")]
    Remote {
        /// The endpoint that was called.
        url: String,
        /// Its HTTP status.
        status: u16,
        /// The start of its error body.
        message: String,
    },
}

impl From<StoreError> for edge::ApiError {
    /// A remote that cannot be reached is 503 `not_ready`, one that timed out 503 `timeout`,
    /// one that answered an error 502 `bad_gateway`, each naming the remote; a local storage
    /// fault is 500 `internal`.
    fn from(e: StoreError) -> Self {
        use edge::{ApiError, ErrorCode};
        match &e {
            StoreError::Unavailable { .. } => ApiError::new(ErrorCode::NotReady, e.to_string()),
            StoreError::TimedOut { .. } => ApiError::new(ErrorCode::Timeout, e.to_string()),
            StoreError::Remote { .. } => ApiError::new(ErrorCode::BadGateway, e.to_string()),
            StoreError::Storage { .. } | StoreError::Query { .. } => ApiError::internal(e),
        }
    }
}
