//! The HTTP edge shared by the services: the JSON error type with stable codes, and the middleware stack.
//!
//! Both the knowledge service and the worker service answer errors through [`ApiError`], and both
//! are wrapped by the same [`middleware::stack`], so a client sees one error format and one set of
//! headers (request ids, limits, timeouts) whichever service it talks to.

pub mod error;
pub mod metrics;
pub mod middleware;

pub use error::{ApiError, ErrorCode};
