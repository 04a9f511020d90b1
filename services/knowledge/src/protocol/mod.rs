//! The SPARQL 1.1 Protocol (`/sparql`) and the Graph Store Protocol (`/store`) over the
//! knowledge graph: content negotiation, per-query deadlines, result caps and engineer-only
//! writes.
//!
//! Handlers are thin adapters: they read a request into a typed operation, check the bearer
//! token, and run the operation on a blocking thread (Oxigraph is blocking) under a
//! `Deadline`. Evaluation itself (`evaluation.rs`) knows nothing of HTTP. Answers are
//! serialized completely before the response starts, so a query that is cut short, by its
//! deadline or by the CONSTRUCT cap, is always an error status, never a truncated 200 body.

mod complexity;
mod evaluation;
mod graph_store;
pub(crate) mod inline;
pub mod negotiation;
mod service_description;
mod sparql;

use std::sync::Arc;
use std::time::{Duration, Instant};

use axum::Router;
use axum::http::header::{ALLOW, HOST};
use axum::http::{HeaderMap, HeaderValue, Uri};
use axum::response::{IntoResponse, Response};
use axum::routing::{MethodFilter, get, on};
use edge::{ApiError, ErrorCode};
use oxigraph::sparql::CancellationToken;

use self::inline::ReadState;
use crate::service::Knowledge;

/// The routes `/sparql`, `/store` and `/store/{graph…}` over `knowledge`.
///
/// The caller wraps the router in the shared middleware stack (request ids, body limits, the
/// request timeout); the query deadline from [`crate::QueryLimits`] is enforced here.
pub fn router(knowledge: Arc<Knowledge>) -> Router {
    let graph_store_methods = MethodFilter::GET
        .or(MethodFilter::HEAD)
        .or(MethodFilter::PUT)
        .or(MethodFilter::POST)
        .or(MethodFilter::DELETE);
    Router::new()
        .route(
            "/sparql",
            get(sparql::get).post(sparql::post).fallback(|| async {
                method_not_allowed("GET, HEAD, POST", "/sparql answers GET, HEAD and POST")
            }),
        )
        .route(
            "/store",
            on(graph_store_methods, graph_store::indirect)
                .fallback(|| async { graph_store_method_not_allowed() }),
        )
        .route(
            "/store/{*graph}",
            on(graph_store_methods, graph_store::direct)
                .fallback(|| async { graph_store_method_not_allowed() }),
        )
        .with_state(knowledge)
}

/// A 405 with its `Allow` header (an [`ApiError`] alone cannot carry headers).
fn method_not_allowed(allow: &'static str, message: &str) -> Response {
    let mut response = ApiError::new(ErrorCode::MethodNotAllowed, message).into_response();
    response
        .headers_mut()
        .insert(ALLOW, HeaderValue::from_static(allow));
    response
}

fn graph_store_method_not_allowed() -> Response {
    method_not_allowed(
        "GET, HEAD, PUT, POST, DELETE",
        "the graph store answers GET, HEAD, PUT, POST and DELETE",
    )
}

/// The decoded `name=value` pairs of a query string or a form body, in order.
#[derive(Debug, Default)]
struct Params(Vec<(String, String)>);

impl Params {
    /// Decodes `application/x-www-form-urlencoded` text (`+` is a space, `%XX` a byte), once.
    /// A value that is not UTF-8 after decoding is a 400: guessing its encoding would change
    /// the query.
    fn parse(encoded: &[u8]) -> Result<Self, ApiError> {
        let decode = |raw: &[u8]| -> Result<String, ApiError> {
            let spaced: Vec<u8> = raw
                .iter()
                .map(|&b| if b == b'+' { b' ' } else { b })
                .collect();
            let bytes: Vec<u8> = percent_encoding::percent_decode(&spaced).collect();
            String::from_utf8(bytes).map_err(|_| {
                ApiError::bad_request(format!(
                    "parameter `{}` is not UTF-8 once percent-decoded",
                    String::from_utf8_lossy(raw)
                ))
            })
        };
        let mut pairs = Vec::new();
        for piece in encoded.split(|&b| b == b'&').filter(|p| !p.is_empty()) {
            let (name, value) = match piece.iter().position(|&b| b == b'=') {
                Some(i) => (&piece[..i], &piece[i + 1..]),
                None => (piece, &b""[..]),
            };
            pairs.push((decode(name)?, decode(value)?));
        }
        Ok(Self(pairs))
    }

    /// The parameters of a request URI.
    fn of_uri(uri: &Uri) -> Result<Self, ApiError> {
        Self::parse(uri.query().unwrap_or_default().as_bytes())
    }

    fn extend(&mut self, other: Params) {
        self.0.extend(other.0);
    }

    fn all<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a str> + 'a {
        self.0
            .iter()
            .filter(move |(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    fn contains(&self, name: &str) -> bool {
        self.0.iter().any(|(n, _)| n == name)
    }

    /// The value of a parameter that may be given once at most.
    fn at_most_one<'a>(&'a self, name: &'a str) -> Result<Option<&'a str>, ApiError> {
        let mut values = self.all(name);
        let first = values.next();
        if values.next().is_some() {
            return Err(ApiError::bad_request(format!(
                "parameter `{name}` is given more than once; send exactly one"
            )));
        }
        Ok(first)
    }

    /// The values of SPARQLWrapper's output-format parameters, in order.
    fn format_hints(&self) -> Vec<&str> {
        self.0
            .iter()
            .filter(|(n, _)| matches!(n.as_str(), "format" | "output" | "results"))
            .map(|(_, v)| v.as_str())
            .collect()
    }
}

/// `scheme://authority` of the request as the client addressed it: the base of relative IRIs
/// in queries, of the service description's `sd:endpoint`, and of directly identified graphs.
/// Behind a TLS-terminating proxy, `X-Forwarded-Proto` gives the scheme.
fn request_origin(uri: &Uri, headers: &HeaderMap) -> String {
    let scheme = headers
        .get("x-forwarded-proto")
        .and_then(|v| v.to_str().ok())
        .map(|v| {
            v.split(',')
                .next()
                .unwrap_or_default()
                .trim()
                .to_ascii_lowercase()
        })
        .filter(|v| v == "http" || v == "https")
        .or_else(|| uri.scheme_str().map(str::to_owned))
        .unwrap_or_else(|| "http".to_owned());
    let authority = uri
        .authority()
        .map(|a| a.as_str().to_owned())
        .or_else(|| {
            headers
                .get(HOST)
                .and_then(|v| v.to_str().ok())
                .map(str::to_owned)
        })
        .filter(|a| !a.is_empty() && !a.contains(['/', ' ', '<', '>', '"']))
        .unwrap_or_else(|| "localhost".to_owned());
    format!("{scheme}://{authority}")
}

/// The media type of a request body (lower-cased, without parameters), and whether its
/// `charset` parameter, if any, is UTF-8.
fn body_media_type(headers: &HeaderMap) -> Option<(String, bool)> {
    let value = headers
        .get(axum::http::header::CONTENT_TYPE)?
        .to_str()
        .ok()?;
    let mut parts = value.split(';');
    let essence = parts.next()?.trim().to_ascii_lowercase();
    let mut utf8 = true;
    for parameter in parts {
        if let Some((name, value)) = parameter.split_once('=')
            && name.trim().eq_ignore_ascii_case("charset")
        {
            let charset = value.trim().trim_matches('"');
            utf8 = charset.eq_ignore_ascii_case("utf-8") || charset.eq_ignore_ascii_case("utf8");
        }
    }
    Some((essence, utf8))
}

/// Stops an evaluation when its deadline passes or when the request that started it goes
/// away.
///
/// Dropping a future does not stop a blocking Oxigraph evaluation, so the token is cancelled
/// from `Drop`: when axum drops the handler's future (the client disconnected, or the outer
/// request timeout fired) the evaluation sees the cancelled token at its next step and
/// returns. The deadline itself is a timer raced against the blocking task, so a request
/// costs no extra task.
///
/// Reads are counted, and remembered for running in place, in the service's [`ReadState`].
struct Deadline {
    token: CancellationToken,
    limit: Duration,
    reads: Arc<ReadState>,
}

impl Deadline {
    fn start(reads: &Arc<ReadState>, limit: Duration) -> Self {
        Self {
            token: CancellationToken::new(),
            limit,
            reads: Arc::clone(reads),
        }
    }

    fn token(&self) -> CancellationToken {
        self.token.clone()
    }

    fn exceeded(&self) -> ApiError {
        ApiError::new(
            ErrorCode::Timeout,
            format!(
                "the operation ran past its deadline of {} s and was stopped",
                self.limit.as_secs_f64()
            ),
        )
    }

    /// Runs a read on a blocking thread. At the deadline the answer is a 503 at once, even if
    /// the evaluation has not yet noticed its cancelled token: it has no side effects, so
    /// nothing is lost by not waiting for it. (Returning drops `self`, which cancels.)
    async fn read<T: Send + 'static>(
        &self,
        work: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
    ) -> Result<T, ApiError> {
        self.read_within(self.limit, work).await
    }

    /// [`Self::read`] with `limit` left of the deadline.
    async fn read_within<T: Send + 'static>(
        &self,
        limit: Duration,
        work: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
    ) -> Result<T, ApiError> {
        let reads = Arc::clone(&self.reads);
        let work = move || {
            let _running = reads.enter();
            work()
        };
        match tokio::time::timeout(limit, tokio::task::spawn_blocking(work)).await {
            Err(_elapsed) => {
                self.token.cancel();
                Err(self.exceeded())
            }
            Ok(Err(join)) => Err(ApiError::internal(format!(
                "evaluation task failed: {join}"
            ))),
            Ok(Ok(result)) => result,
        }
    }

    /// [`Self::read`] for a read that may come again (a query, by its text, dataset and
    /// format: `key`), given the token that stops it. One that was short last time runs in
    /// place on this async worker instead, on a leash ([`inline::LEASH`]): if it has not
    /// finished by then (the data grew), the watchdog stops it, it is remembered as long, and
    /// it runs again from the start on a blocking thread with what is left of the deadline.
    /// A read has no side effects, so the second run answers exactly what the first would
    /// have. Every run's cost is remembered for the next.
    async fn read_remembered<T: Send + 'static>(
        &self,
        key: u64,
        work: impl Fn(CancellationToken) -> Result<T, ApiError> + Send + 'static,
    ) -> Result<T, ApiError> {
        let reads = Arc::clone(&self.reads);
        let measured = move |token: CancellationToken| {
            let clock = inline::CostClock::start();
            let result = work(token);
            reads.record(key, clock.elapsed());
            result
        };
        let Some(in_place) = self.reads.permit(key) else {
            let token = self.token();
            return self.read(move || measured(token)).await;
        };
        let started = Instant::now();
        let leash = CancellationToken::new();
        let result = {
            let _running = self.reads.enter();
            let _watched = in_place.watch(leash.clone(), started + self.limit.min(inline::LEASH));
            measured(leash.clone())
        };
        drop(in_place);
        let left = self.limit.saturating_sub(started.elapsed());
        if result.is_ok() || !leash.is_cancelled() {
            return result;
        }
        if left.is_zero() {
            return Err(self.exceeded());
        }
        let token = self.token();
        self.read_within(left, move || measured(token)).await
    }

    /// Runs a write on a blocking thread, cancels it at the deadline, and waits for its real
    /// outcome: an update that committed just as the deadline passed did happen, and saying
    /// otherwise would mislead the client. A cancelled update leaves its transaction
    /// uncommitted.
    async fn write<T: Send + 'static>(
        &self,
        work: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
    ) -> Result<T, ApiError> {
        let mut task = tokio::task::spawn_blocking(work);
        let joined = tokio::select! {
            joined = &mut task => joined,
            () = tokio::time::sleep(self.limit) => {
                self.token.cancel();
                task.await
            }
        };
        joined.unwrap_or_else(|join| Err(ApiError::internal(format!("write task failed: {join}"))))
    }
}

impl Drop for Deadline {
    fn drop(&mut self) {
        self.token.cancel();
    }
}

/// Runs `work` on a blocking thread and waits for it, however long it takes.
async fn blocking<T: Send + 'static>(
    work: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    match tokio::task::spawn_blocking(work).await {
        Err(join) => Err(ApiError::internal(format!("blocking task failed: {join}"))),
        Ok(result) => result,
    }
}

#[cfg(test)]
mod tests;
