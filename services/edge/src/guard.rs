//! What is decided from a request's head alone, before any handler reads its body: whether
//! the service has room for it (requests in flight), who sent it (a request without a valid
//! token is answered 401 before one byte of its body is read) and how large a body its route
//! and role may send.
//!
//! The principal it authenticated goes into the request's extensions, where the caller
//! extractors ([`crate::RobotCaller`], ...) find it: handlers check roles without
//! authenticating again. The guard makes sure that an anonymous client costs no more than its
//! headers, and that a robot's plan or an object report cannot bring the megabytes a map import
//! may.

use std::sync::Arc;

use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use http::header::{CONTENT_LENGTH, RETRY_AFTER};
use http::{HeaderValue, Method};
use tokio::sync::Semaphore;
use tower::{Layer, ServiceExt};

use crate::auth::{Role, Tokens};
use crate::error::{ApiError, ErrorCode};

/// The guard's settings.
#[derive(Debug, Clone)]
pub struct GuardConfig {
    /// The tokens requests are checked against (open: every request is an engineer's).
    pub tokens: Tokens,
    /// Route templates answered without a token (probes and metrics).
    pub public_routes: Vec<&'static str>,
    /// Routes (method, template) whose bodies may reach [`GuardConfig::large_body`] for an
    /// engineer's token: map imports, Graph Store writes, SPARQL updates.
    pub large_body_routes: Vec<(Method, &'static str)>,
    /// Largest body of those routes, bytes.
    pub large_body: usize,
    /// Largest body of every other request, bytes.
    pub small_body: usize,
    /// Requests handled at once (public probes excepted); beyond it, 503 with `Retry-After`.
    pub max_in_flight: usize,
    /// The `Retry-After` of that 503, seconds.
    pub retry_after_s: u32,
}

/// The state of the guard middleware.
#[derive(Debug)]
pub struct Guard {
    config: GuardConfig,
    in_flight: Arc<Semaphore>,
}

impl Guard {
    /// A guard with `config`.
    pub fn new(config: GuardConfig) -> Arc<Self> {
        let permits = config.max_in_flight.clamp(1, Semaphore::MAX_PERMITS);
        Arc::new(Self {
            in_flight: Arc::new(Semaphore::new(permits)),
            config,
        })
    }

    /// The body limit of a request to `route` with `method` by a token of `role`.
    pub fn body_limit(&self, method: &Method, route: Option<&str>, role: Role) -> usize {
        let large = role == Role::Engineer
            && route.is_some_and(|r| {
                self.config
                    .large_body_routes
                    .iter()
                    .any(|(m, t)| m == method && *t == r)
            });
        if large {
            self.config.large_body
        } else {
            self.config.small_body
        }
    }
}

/// The middleware (install with `axum::middleware::from_fn_with_state`).
pub async fn guard(State(guard): State<Arc<Guard>>, request: Request, next: Next) -> Response {
    let route = request
        .extensions()
        .get::<MatchedPath>()
        .map(|p| p.as_str().to_owned());
    let public = route
        .as_deref()
        .is_some_and(|r| guard.config.public_routes.contains(&r));
    if public {
        return run_limited(request, next, guard.config.small_body).await;
    }
    let Ok(_permit) = Arc::clone(&guard.in_flight).try_acquire_owned() else {
        return overloaded(&guard.config);
    };
    let mut request = request;
    let role = match guard.config.tokens.authenticate(request.headers()) {
        Ok(principal) => {
            let role = principal.role;
            // Handlers take it from here (the caller extractors): authenticated once.
            request.extensions_mut().insert(principal);
            role
        }
        Err(e) => return e.into_response(),
    };
    let limit = guard.body_limit(request.method(), route.as_deref(), role);
    run_limited(request, next, limit).await
}

/// The body length a request declares (`Content-Length`), when it declares one.
pub fn declared_length(headers: &http::HeaderMap) -> Option<u64> {
    headers
        .get(CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.trim().parse::<u64>().ok())
}

/// 413 at once when the declared length exceeds `limit`; else `next` with `limit` as the
/// request's body limit (axum's [`DefaultBodyLimit`], which every body extractor applies: a
/// chunked body that grows past it fails the handler's read with 413).
async fn run_limited(request: Request, next: Next, limit: usize) -> Response {
    let declared = declared_length(request.headers());
    if let Some(length) = declared
        && length > limit as u64
    {
        return ApiError::new(
            ErrorCode::PayloadTooLarge,
            format!(
                "the request body declares {length} bytes; {} {} takes at most {limit}",
                request.method(),
                request.uri().path()
            ),
        )
        .into_response();
    }
    let service = tower::service_fn(move |request: Request| {
        let next = next.clone();
        async move { Ok::<_, std::convert::Infallible>(next.run(request).await) }
    });
    match DefaultBodyLimit::max(limit)
        .layer(service)
        .oneshot(request)
        .await
    {
        Ok(response) => response,
        Err(never) => match never {},
    }
}

fn overloaded(config: &GuardConfig) -> Response {
    let mut response = ApiError::new(
        ErrorCode::Overloaded,
        format!(
            "the service is handling {} requests, its limit; retry in {} s",
            config.max_in_flight, config.retry_after_s
        ),
    )
    .into_response();
    response
        .headers_mut()
        .insert(RETRY_AFTER, HeaderValue::from(config.retry_after_s));
    response
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::Router;
    use axum::body::Body;
    use axum::routing::{get, post};
    use http::StatusCode;
    use tower::ServiceExt;

    fn config() -> GuardConfig {
        GuardConfig {
            tokens: Tokens::default().with("e", "alice", Role::Engineer).with(
                "r",
                "robot-1",
                Role::Robot,
            ),
            public_routes: vec!["/healthz"],
            large_body_routes: vec![(Method::POST, "/big")],
            large_body: 1000,
            small_body: 10,
            max_in_flight: 1,
            retry_after_s: 2,
        }
    }

    fn app(guard: Arc<Guard>) -> Router {
        let echo = |body: String| async move { body };
        Router::new()
            .route("/healthz", get(|| async { "ok" }))
            .route("/small", post(echo))
            .route("/big", post(echo))
            .route(
                "/slow",
                get(|| async {
                    tokio::time::sleep(std::time::Duration::from_millis(300)).await;
                    "done"
                }),
            )
            .layer(axum::middleware::from_fn_with_state(guard, super::guard))
    }

    fn post_req(uri: &str, token: Option<&str>, body: &str) -> Request {
        let mut b = Request::post(uri);
        if let Some(t) = token {
            b = b.header("authorization", format!("Bearer {t}"));
        }
        b.body(Body::from(body.to_owned())).unwrap()
    }

    #[tokio::test]
    async fn anonymous_requests_are_refused_before_the_body_is_read() {
        let guard = Guard::new(config());
        // A body that fails when read: the 401 proves it was never polled.
        let stream = futures_like_failing_body();
        let request = Request::post("/big").body(stream).unwrap();
        let response = app(guard).oneshot(request).await.unwrap();
        assert_eq!(response.status(), StatusCode::UNAUTHORIZED);
    }

    /// A body whose first poll is an error.
    fn futures_like_failing_body() -> Body {
        struct Failing;
        impl http_body::Body for Failing {
            type Data = bytes::Bytes;
            type Error = std::io::Error;
            fn poll_frame(
                self: std::pin::Pin<&mut Self>,
                _: &mut std::task::Context<'_>,
            ) -> std::task::Poll<Option<Result<http_body::Frame<Self::Data>, Self::Error>>>
            {
                panic!("the guard read the body of an anonymous request");
            }
        }
        Body::new(Failing)
    }

    #[tokio::test]
    async fn body_limits_follow_route_and_role() {
        let guard = Guard::new(config());
        let body = "x".repeat(100);
        let cases = [
            ("/small", "e", StatusCode::PAYLOAD_TOO_LARGE),
            ("/big", "e", StatusCode::OK),
            ("/big", "r", StatusCode::PAYLOAD_TOO_LARGE),
        ];
        for (uri, token, want) in cases {
            let response = app(guard.clone())
                .oneshot(post_req(uri, Some(token), &body))
                .await
                .unwrap();
            assert_eq!(response.status(), want, "{uri} as {token}");
        }
        let ok = app(guard)
            .oneshot(post_req("/small", Some("r"), "tiny"))
            .await
            .unwrap();
        assert_eq!(ok.status(), StatusCode::OK);
    }

    #[tokio::test]
    async fn a_full_house_is_answered_503_with_retry_after_and_probes_still_pass() {
        let guard = Guard::new(config());
        let slow = {
            let app = app(guard.clone());
            tokio::spawn(async move {
                let request = Request::get("/slow")
                    .header("authorization", "Bearer e")
                    .body(Body::empty())
                    .unwrap();
                app.oneshot(request).await.unwrap().status()
            })
        };
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
        let request = Request::get("/slow")
            .header("authorization", "Bearer e")
            .body(Body::empty())
            .unwrap();
        let refused = app(guard.clone()).oneshot(request).await.unwrap();
        assert_eq!(refused.status(), StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(refused.headers()[RETRY_AFTER], "2");
        let probe = Request::get("/healthz").body(Body::empty()).unwrap();
        assert_eq!(
            app(guard.clone()).oneshot(probe).await.unwrap().status(),
            StatusCode::OK
        );
        assert_eq!(slow.await.unwrap(), StatusCode::OK);
        // The permit came back.
        let request = Request::get("/slow")
            .header("authorization", "Bearer e")
            .body(Body::empty())
            .unwrap();
        assert_eq!(
            app(guard).oneshot(request).await.unwrap().status(),
            StatusCode::OK
        );
    }
}
