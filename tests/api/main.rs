//! HTTP API tests against the real app started in-process on port 0.

mod health;
mod helpers;
