//! The HTTP edge shared by the services: the JSON error type with stable codes, bearer tokens
//! and roles, the middleware stack and metrics.
//!
//! Both the knowledge service and the worker service answer errors through [`ApiError`],
//! authenticate through the same [`Tokens`], and are wrapped by the same [`middleware::stack`],
//! so a client sees one error format, one token scheme and one set of headers (request ids,
//! limits, timeouts) whichever service it talks to.

pub mod auth;
pub mod error;
pub mod metrics;
pub mod middleware;

pub use auth::{BearerAuth, Principal, Role, Tokens};
pub use error::{ApiError, ErrorBody, ErrorCode, ErrorDetail};
