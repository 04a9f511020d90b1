//! The HTTP edge shared by the services: the JSON error type with stable codes, bearer tokens
//! and roles, the middleware stack and metrics.
//!
//! Both the knowledge service and the worker service answer errors through [`ApiError`],
//! authenticate through the same [`Tokens`], and are wrapped by the same [`middleware::stack`],
//! so a client sees one error format, one token scheme and one set of headers (request ids,
//! limits, timeouts) whichever service it talks to.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
// (`planning` and `bench` do not yet; `cast_precision_loss` stays off everywhere: counts far
// below 2^52 convert to f64 exactly.)
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod accept;
pub mod auth;
pub mod disk;
pub mod error;
pub mod guard;
pub mod metrics;
pub mod middleware;
pub mod serve;

pub use auth::{
    BearerAuth, Caller, EngineerCaller, Principal, RobotCaller, Role, TokenSource, Tokens,
};
pub use error::{ApiError, ErrorBody, ErrorCode, ErrorDetail};
