//! The fleet's jobs: the job kinds the job engine (`queue`) runs for a robot fleet, and what
//! they share.
//!
//! - [`jobs`]: the kinds (`train`, `evaluate`, `validate`, `roadmap`), their payloads and
//!   handlers, the knowledge sources worlds come from (in process or over HTTP), and
//!   [`jobs::JobEnv`], which also holds the [`planner::Planner`] plans and `validate` jobs
//!   share;
//! - [`plan`]: a plan's request and answer in the wire types, translated to and from the
//!   planner;
//! - [`service`]: runners for every kind, and the retention purge.
//!
//! No HTTP routes live here: they are at the binary's edge (`api`), so `mentalsim worker`
//! runs jobs without serving plans.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod jobs;
pub mod plan;
pub mod service;
