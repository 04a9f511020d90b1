//! The middleware stack every service router is wrapped in: request ids, tracing, metrics,
//! uniform JSON errors, timeouts, body limits and panic recovery.

use std::any::Any;
use std::time::Duration;

use axum::Router;
use axum::body::Body;
use axum::extract::{DefaultBodyLimit, MatchedPath, Request};
use axum::middleware::{Next, from_fn};
use axum::response::{IntoResponse, Response};
use http::header::{AUTHORIZATION, CONTENT_TYPE};
use http::{HeaderValue, StatusCode};
use tower_http::catch_panic::CatchPanicLayer;
use tower_http::limit::RequestBodyLimitLayer;
use tower_http::request_id::{MakeRequestUuid, PropagateRequestIdLayer, SetRequestIdLayer};
use tower_http::sensitive_headers::SetSensitiveRequestHeadersLayer;
use tower_http::timeout::TimeoutLayer;
use tower_http::trace::TraceLayer;

use crate::error::{ApiError, ErrorCode};

/// Limits applied to every request.
#[derive(Debug, Clone, Copy)]
pub struct Limits {
    /// Time from request to response head; longer work belongs in a job.
    pub request_timeout: Duration,
    /// Largest request body accepted, in bytes.
    pub body_limit: usize,
}

/// Wraps a router in the shared stack. Layers are listed innermost first.
pub fn stack(router: Router, limits: Limits) -> Router {
    stack_guarded(router, limits, None)
}

/// [`stack`] with the [`Guard`](crate::guard::Guard): requests in flight, authentication and
/// per-route body limits decided from the request head, before any body is read.
pub fn stack_guarded(
    router: Router,
    limits: Limits,
    guard: Option<std::sync::Arc<crate::guard::Guard>>,
) -> Router {
    // Install the recorder before the first request is counted, not at the first scrape.
    crate::metrics::handle();
    let router = router.layer(CatchPanicLayer::custom(panic_response));
    // The guard sets each request's body limit itself (by route and role).
    let router = match guard {
        Some(guard) => router
            .layer(RequestBodyLimitLayer::new(limits.body_limit))
            .layer(axum::middleware::from_fn_with_state(
                guard,
                crate::guard::guard,
            )),
        None => router
            .layer(DefaultBodyLimit::max(limits.body_limit))
            .layer(RequestBodyLimitLayer::new(limits.body_limit)),
    };
    router
        .layer(TimeoutLayer::with_status_code(
            StatusCode::SERVICE_UNAVAILABLE,
            limits.request_timeout,
        ))
        .layer(from_fn(uniform_errors))
        .layer(from_fn(crate::metrics::track))
        .layer(
            TraceLayer::new_for_http().make_span_with(|request: &Request<Body>| {
                let route = request
                    .extensions()
                    .get::<MatchedPath>()
                    .map(MatchedPath::as_str)
                    .unwrap_or("unmatched");
                let request_id = request
                    .headers()
                    .get("x-request-id")
                    .and_then(|v| v.to_str().ok())
                    .unwrap_or("-");
                tracing::info_span!(
                    "request",
                    method = %request.method(),
                    uri = %request.uri(),
                    route,
                    request_id,
                )
            }),
        )
        .layer(SetSensitiveRequestHeadersLayer::new([AUTHORIZATION]))
        .layer(PropagateRequestIdLayer::x_request_id())
        .layer(SetRequestIdLayer::x_request_id(MakeRequestUuid))
}

/// The answer for a route that does not exist, for use as a router fallback.
pub async fn not_found(request: Request) -> ApiError {
    ApiError::not_found(format!(
        "no route for {} {}",
        request.method(),
        request.uri().path()
    ))
}

fn panic_response(panic: Box<dyn Any + Send + 'static>) -> Response {
    let detail = panic
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "non-string panic payload".to_owned());
    ApiError::internal(format!("handler panicked: {detail}")).into_response()
}

/// Error responses produced by infrastructure (axum's extractors and method router, tower-http's
/// timeout and body limit) come as empty or plain-text bodies. Rewrite them into our JSON error
/// format, keeping their message, so clients parse one format everywhere.
async fn uniform_errors(request: Request, next: Next) -> Response {
    let response = next.run(request).await;
    let status = response.status();
    if !(status.is_client_error() || status.is_server_error()) {
        return response;
    }
    let is_json = response
        .headers()
        .get(CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/json"));
    if is_json {
        return response;
    }
    let Some(code) = code_for_foreign_status(status) else {
        return response;
    };
    let allow = response.headers().get(http::header::ALLOW).cloned();
    let text = match axum::body::to_bytes(response.into_body(), 8 * 1024).await {
        Ok(bytes) => String::from_utf8_lossy(&bytes).trim().to_owned(),
        Err(_) => String::new(),
    };
    let message = if !text.is_empty() {
        text
    } else if code == ErrorCode::Timeout {
        "the request did not finish within the configured request timeout".to_owned()
    } else {
        status
            .canonical_reason()
            .unwrap_or("request failed")
            .to_lowercase()
    };
    let mut rewritten = ApiError::new(code, message).into_response();
    if let Some(allow) = allow {
        rewritten.headers_mut().insert(http::header::ALLOW, allow);
    }
    // Keep the original status: e.g. axum answers 422 for a JSON body of the wrong shape.
    *rewritten.status_mut() = status;
    rewritten
        .headers_mut()
        .insert(CONTENT_TYPE, HeaderValue::from_static("application/json"));
    rewritten
}

fn code_for_foreign_status(status: StatusCode) -> Option<ErrorCode> {
    Some(match status.as_u16() {
        400 => ErrorCode::BadRequest,
        401 => ErrorCode::Unauthorized,
        403 => ErrorCode::Forbidden,
        404 => ErrorCode::NotFound,
        405 => ErrorCode::MethodNotAllowed,
        406 => ErrorCode::NotAcceptable,
        409 => ErrorCode::Conflict,
        413 => ErrorCode::PayloadTooLarge,
        415 => ErrorCode::UnsupportedMediaType,
        422 => ErrorCode::Unprocessable,
        503 => ErrorCode::Timeout,
        500 => ErrorCode::Internal,
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::routing::{get, post};
    use tower::ServiceExt;

    fn app() -> Router {
        let router = Router::new()
            .route("/ok", get(|| async { "ok" }))
            .route("/echo", post(|body: String| async move { body }))
            .route(
                "/slow",
                get(|| async {
                    tokio::time::sleep(Duration::from_secs(5)).await;
                    "late"
                }),
            )
            .route(
                "/panic",
                get(|| async {
                    let v: Vec<u8> = Vec::new();
                    #[allow(clippy::indexing_slicing)]
                    let x = v[3];
                    x.to_string()
                }),
            )
            .fallback(not_found);
        stack(
            router,
            Limits {
                request_timeout: Duration::from_millis(200),
                body_limit: 16,
            },
        )
    }

    async fn json(response: Response) -> serde_json::Value {
        let bytes = axum::body::to_bytes(response.into_body(), 1 << 20)
            .await
            .unwrap();
        serde_json::from_slice(&bytes).unwrap()
    }

    fn get_req(uri: &str) -> Request {
        Request::builder().uri(uri).body(Body::empty()).unwrap()
    }

    #[tokio::test]
    async fn request_id_is_set_and_propagated() {
        let response = app().oneshot(get_req("/ok")).await.unwrap();
        assert_eq!(response.status(), StatusCode::OK);
        assert!(response.headers().contains_key("x-request-id"));
    }

    #[tokio::test]
    async fn unknown_route_is_json_404() {
        let response = app().oneshot(get_req("/nope")).await.unwrap();
        assert_eq!(response.status(), StatusCode::NOT_FOUND);
        assert_eq!(json(response).await["error"]["code"], "not_found");
    }

    #[tokio::test]
    async fn wrong_method_is_json_405_with_allow() {
        let request = Request::builder()
            .method("DELETE")
            .uri("/ok")
            .body(Body::empty())
            .unwrap();
        let response = app().oneshot(request).await.unwrap();
        assert_eq!(response.status(), StatusCode::METHOD_NOT_ALLOWED);
        assert!(response.headers().contains_key("allow"));
        assert_eq!(json(response).await["error"]["code"], "method_not_allowed");
    }

    #[tokio::test]
    async fn oversized_body_is_json_413() {
        let request = Request::builder()
            .method("POST")
            .uri("/echo")
            .body(Body::from("x".repeat(100)))
            .unwrap();
        let response = app().oneshot(request).await.unwrap();
        assert_eq!(response.status(), StatusCode::PAYLOAD_TOO_LARGE);
        assert_eq!(json(response).await["error"]["code"], "payload_too_large");
    }

    #[tokio::test]
    async fn slow_handler_times_out_with_json() {
        let response = app().oneshot(get_req("/slow")).await.unwrap();
        assert_eq!(response.status(), StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(json(response).await["error"]["code"], "timeout");
    }

    #[tokio::test]
    async fn panic_becomes_json_500_without_details() {
        let response = app().oneshot(get_req("/panic")).await.unwrap();
        assert_eq!(response.status(), StatusCode::INTERNAL_SERVER_ERROR);
        let body = json(response).await;
        assert_eq!(body["error"]["code"], "internal");
        assert!(!body.to_string().contains("index out of bounds"));
    }
}
