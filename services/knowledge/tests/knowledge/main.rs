//! The `knowledge` crate's integration tests in one binary (one build and link, one copy of
//! what they share); each module's docs say what it covers.

#![allow(clippy::unwrap_used)] // reason: tests panic on failure

mod clients;
mod openapi;
mod people;
mod protocol;
mod support;
mod w3c_protocol;
