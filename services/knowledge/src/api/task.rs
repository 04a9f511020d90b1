//! Handlers' blocking work: graph walks, Oxigraph and RocksDB calls run on tokio's blocking
//! threads, never on an async worker.

use edge::ApiError;

/// Runs `f` on a blocking thread; a panic in it is an internal error.
pub(super) async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(ApiError::internal)?
}
