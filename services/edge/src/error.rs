//! One JSON error type with a stable machine-readable code per error and an exhaustive code→status map.

use axum::Json;
use axum::response::{IntoResponse, Response};
use http::StatusCode;
use serde::Serialize;

/// A stable, machine-readable error code. Clients match on these strings; never rename one.
///
/// Every code maps to exactly one HTTP status in [`ErrorCode::status`], and that match has no
/// catch-all arm, so adding a code forces a decision about its status.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, utoipa::ToSchema)]
#[schema(
    description = "A stable, machine-readable error code: clients match on these strings, which never change."
)]
#[serde(rename_all = "snake_case")]
pub enum ErrorCode {
    /// The request is malformed: a parameter is missing, ill-typed or out of range.
    BadRequest,
    /// A SPARQL query or update does not parse or cannot be evaluated as written.
    InvalidQuery,
    /// The body's media type is not one the endpoint reads.
    UnsupportedMediaType,
    /// None of the media types the client accepts can be produced.
    NotAcceptable,
    /// The addressed resource does not exist.
    NotFound,
    /// The route exists but not with this method.
    MethodNotAllowed,
    /// No valid bearer token was presented.
    Unauthorized,
    /// The token is valid but its role may not do this.
    Forbidden,
    /// The request body is larger than the configured limit.
    PayloadTooLarge,
    /// The request did not finish within its deadline and was stopped.
    Timeout,
    /// A result would exceed a configured size cap and was refused rather than truncated.
    ResultTooLarge,
    /// The service's disk is (nearly) full: nothing of the request was stored; retry once
    /// space is freed.
    StorageFull,
    /// The request conflicts with the current state of the resource.
    Conflict,
    /// The request is well-formed but describes something impossible (e.g. a goal inside a wall).
    Unprocessable,
    /// The service is starting or a backing store is unavailable; retry later.
    NotReady,
    /// The service is at its limit of requests in flight; retry after the `Retry-After` seconds.
    Overloaded,
    /// This client sent more requests of a kind than its rate allows; retry later.
    TooManyRequests,
    /// A backing service (e.g. a remote SPARQL store) answered with an error of its own.
    BadGateway,
    /// A fault inside the service. Details are logged, never sent.
    Internal,
}

impl ErrorCode {
    /// The HTTP status for this code.
    pub fn status(self) -> StatusCode {
        match self {
            ErrorCode::BadRequest | ErrorCode::InvalidQuery => StatusCode::BAD_REQUEST,
            ErrorCode::UnsupportedMediaType => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            ErrorCode::NotAcceptable => StatusCode::NOT_ACCEPTABLE,
            ErrorCode::NotFound => StatusCode::NOT_FOUND,
            ErrorCode::MethodNotAllowed => StatusCode::METHOD_NOT_ALLOWED,
            ErrorCode::Unauthorized => StatusCode::UNAUTHORIZED,
            ErrorCode::Forbidden => StatusCode::FORBIDDEN,
            ErrorCode::PayloadTooLarge => StatusCode::PAYLOAD_TOO_LARGE,
            ErrorCode::Timeout => StatusCode::SERVICE_UNAVAILABLE,
            ErrorCode::ResultTooLarge => StatusCode::INSUFFICIENT_STORAGE,
            ErrorCode::StorageFull => StatusCode::INSUFFICIENT_STORAGE,
            ErrorCode::Conflict => StatusCode::CONFLICT,
            ErrorCode::Unprocessable => StatusCode::UNPROCESSABLE_ENTITY,
            ErrorCode::NotReady | ErrorCode::Overloaded => StatusCode::SERVICE_UNAVAILABLE,
            ErrorCode::TooManyRequests => StatusCode::TOO_MANY_REQUESTS,
            ErrorCode::BadGateway => StatusCode::BAD_GATEWAY,
            ErrorCode::Internal => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }

    /// The code as it appears on the wire.
    pub fn as_str(self) -> &'static str {
        match self {
            ErrorCode::BadRequest => "bad_request",
            ErrorCode::InvalidQuery => "invalid_query",
            ErrorCode::UnsupportedMediaType => "unsupported_media_type",
            ErrorCode::NotAcceptable => "not_acceptable",
            ErrorCode::NotFound => "not_found",
            ErrorCode::MethodNotAllowed => "method_not_allowed",
            ErrorCode::Unauthorized => "unauthorized",
            ErrorCode::Forbidden => "forbidden",
            ErrorCode::PayloadTooLarge => "payload_too_large",
            ErrorCode::Timeout => "timeout",
            ErrorCode::ResultTooLarge => "result_too_large",
            ErrorCode::StorageFull => "storage_full",
            ErrorCode::Conflict => "conflict",
            ErrorCode::Unprocessable => "unprocessable",
            ErrorCode::NotReady => "not_ready",
            ErrorCode::Overloaded => "overloaded",
            ErrorCode::TooManyRequests => "too_many_requests",
            ErrorCode::BadGateway => "bad_gateway",
            ErrorCode::Internal => "internal",
        }
    }
}

/// An error answered to an HTTP client as `{"error": {"code", "message", "field"?,
/// "details"?}}`.
#[derive(Debug, Clone)]
pub struct ApiError {
    code: ErrorCode,
    message: String,
    field: Option<String>,
    details: Option<serde_json::Value>,
}

#[derive(Serialize)]
struct Body<'a> {
    error: Inner<'a>,
}

#[derive(Serialize)]
struct Inner<'a> {
    code: ErrorCode,
    message: &'a str,
    #[serde(skip_serializing_if = "Option::is_none")]
    field: Option<&'a str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    details: Option<&'a serde_json::Value>,
}

// The OpenAPI schema of what `ApiError` serialises to (its doc comment is the schema's
// description, so it stays as published).
/// The error body every endpoint answers with.
#[derive(Serialize, utoipa::ToSchema)]
pub struct ErrorBody {
    error: ErrorDetail,
}

/// An error's code and message.
#[derive(Serialize, utoipa::ToSchema)]
pub struct ErrorDetail {
    /// Stable machine-readable code, e.g. `bad_request`, `not_found`, `unprocessable`.
    #[schema(value_type = ErrorCode)]
    code: String,
    /// What is wrong, for people.
    message: String,
    /// The request field the error is about, as a dotted path into the request's JSON (e.g.
    /// `options.max_wait_s`, `goal`, `payload.episodes`), when one field is at fault. Clients
    /// point at it by this, never by parsing the message.
    #[serde(skip_serializing_if = "Option::is_none")]
    field: Option<String>,
    /// Structured details when the error has some (e.g. the problems found, the attempts of a
    /// plan that could not be validated).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    details: Option<serde_json::Value>,
}

/// The error answers every authenticated operation may give, as reusable OpenAPI responses
/// (`#/components/responses/...`): name them in an operation's `responses(...)` with
/// `(status = 401, response = edge::error::responses::Unauthorized)` and list them in the
/// document's `components(responses(...))`.
pub mod responses {
    use super::ErrorBody;

    /// No valid bearer token (`unauthorized`): the `Authorization` header is missing, is not
    /// `Bearer <token>`, or names no configured token. Answered before the request's body is
    /// read.
    #[derive(utoipa::ToResponse)]
    pub struct Unauthorized(pub ErrorBody);

    /// The token is valid but its role may not do this (`forbidden`): engineers may do
    /// everything; robots read, and use the robot operations (on-demand databases, object
    /// reports, plans).
    #[derive(utoipa::ToResponse)]
    pub struct Forbidden(pub ErrorBody);

    /// The request body is larger than the operation takes from this token's role
    /// (`payload_too_large`; refused at once when `Content-Length` says so): map imports take
    /// up to `body_limit_bytes` (64 MiB by default) from engineers, every other body up to
    /// `small_body_limit_bytes` (1 MiB by default).
    #[derive(utoipa::ToResponse)]
    pub struct PayloadTooLarge(pub ErrorBody);

    /// The body was not sent as JSON (`unsupported_media_type`): send
    /// `Content-Type: application/json`.
    #[derive(utoipa::ToResponse)]
    pub struct UnsupportedMediaType(pub ErrorBody);

    /// The service cannot take the request now; retry later. It is at its limit of requests in
    /// flight (`overloaded`, with `Retry-After`), starting or without a backing store
    /// (`not_ready`), or the request did not finish within the configured request timeout
    /// (`timeout`).
    #[derive(utoipa::ToResponse)]
    #[response(headers(
        ("Retry-After" = u32, description = "Seconds to wait before retrying (with `overloaded`).")
    ))]
    pub struct ServiceUnavailable(pub ErrorBody);

    /// The service's disk is full or nearly so (`storage_full`): the write was refused before
    /// it started (less than `min_free_bytes` would be left) or failed; nothing of it is
    /// stored. Retry once space is freed.
    #[derive(utoipa::ToResponse)]
    pub struct StorageFull(pub ErrorBody);
}

impl ApiError {
    /// An error with a code and a message that names what is wrong.
    pub fn new(code: ErrorCode, message: impl Into<String>) -> Self {
        Self {
            code,
            message: message.into(),
            field: None,
            details: None,
        }
    }

    /// Names the request field at fault (a dotted path into the request's JSON).
    pub fn with_field(mut self, field: impl Into<String>) -> Self {
        self.field = Some(field.into());
        self
    }

    /// The request field at fault, when one is.
    pub fn field(&self) -> Option<&str> {
        self.field.as_deref()
    }

    /// Attaches structured details (e.g. the nearest free point, a list of problems).
    pub fn with_details(mut self, details: serde_json::Value) -> Self {
        self.details = Some(details);
        self
    }

    /// Shorthand for [`ErrorCode::BadRequest`].
    pub fn bad_request(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::BadRequest, message)
    }

    /// Shorthand for [`ErrorCode::NotFound`].
    pub fn not_found(message: impl Into<String>) -> Self {
        Self::new(ErrorCode::NotFound, message)
    }

    /// A fault inside the service: the cause is logged with the request's span, the client only
    /// learns that something failed on our side.
    ///
    /// A cause that is a full disk (see [`crate::disk::is_out_of_space`]) is not a fault of the
    /// service's logic and says so: 507 `storage_full`.
    pub fn internal(cause: impl std::fmt::Display) -> Self {
        let cause = cause.to_string();
        if crate::disk::is_out_of_space(&cause) {
            return crate::disk::storage_full(&cause);
        }
        tracing::error!(error = %cause, "internal error");
        Self::new(ErrorCode::Internal, "internal error; see the service log")
    }

    /// The stable code.
    pub fn code(&self) -> ErrorCode {
        self.code
    }

    /// The human-readable message.
    pub fn message(&self) -> &str {
        &self.message
    }
}

impl std::fmt::Display for ApiError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: {}", self.code.as_str(), self.message)
    }
}

impl std::error::Error for ApiError {}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let body = Body {
            error: Inner {
                code: self.code,
                message: &self.message,
                field: self.field.as_deref(),
                details: self.details.as_ref(),
            },
        };
        (self.code.status(), Json(body)).into_response()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_serialize_as_their_wire_names() {
        for code in [
            ErrorCode::BadRequest,
            ErrorCode::InvalidQuery,
            ErrorCode::UnsupportedMediaType,
            ErrorCode::NotAcceptable,
            ErrorCode::NotFound,
            ErrorCode::MethodNotAllowed,
            ErrorCode::Unauthorized,
            ErrorCode::Forbidden,
            ErrorCode::PayloadTooLarge,
            ErrorCode::Timeout,
            ErrorCode::ResultTooLarge,
            ErrorCode::StorageFull,
            ErrorCode::Conflict,
            ErrorCode::Unprocessable,
            ErrorCode::NotReady,
            ErrorCode::Overloaded,
            ErrorCode::TooManyRequests,
            ErrorCode::BadGateway,
            ErrorCode::Internal,
        ] {
            let json = serde_json::to_value(code).unwrap();
            assert_eq!(json, serde_json::Value::String(code.as_str().to_owned()));
            assert!(code.status().is_client_error() || code.status().is_server_error());
        }
    }

    #[tokio::test]
    async fn response_body_has_code_and_message() {
        let response = ApiError::bad_request("port must be a number").into_response();
        assert_eq!(response.status(), StatusCode::BAD_REQUEST);
        let bytes = axum::body::to_bytes(response.into_body(), 1 << 16)
            .await
            .unwrap();
        let json: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
        assert_eq!(json["error"]["code"], "bad_request");
        assert_eq!(json["error"]["message"], "port must be a number");
        assert!(json["error"].get("field").is_none());
    }

    #[tokio::test]
    async fn a_field_at_fault_is_named_beside_the_message() {
        let response = ApiError::bad_request("must be positive")
            .with_field("options.max_wait_s")
            .into_response();
        let bytes = axum::body::to_bytes(response.into_body(), 1 << 16)
            .await
            .unwrap();
        let json: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
        assert_eq!(json["error"]["field"], "options.max_wait_s");
        assert_eq!(json["error"]["message"], "must be positive");
    }
}
