//! Knowledge service: the TOSM graph store, SPARQL and Graph Store protocols, on-demand
//! databases and map import.
//!
//! Only this crate, `api` and `edge` serve HTTP; only this crate knows Oxigraph and the remote
//! SPARQL store it may keep its graph in. Tokens, roles and the error body come from `edge`,
//! which every service shares. It uses `sim` for the parser's exports it serves (`world.sdf`,
//! `robot.urdf`): one simulation parser, as the paper has it.

// Casts that can lose a sign, wrap or truncate hide bugs: each one here says why it cannot.
// (`planning` and `bench` do not yet; `cast_precision_loss` stays off everywhere: counts far
// below 2^52 convert to f64 exactly.)
#![warn(
    clippy::cast_possible_truncation,
    clippy::cast_sign_loss,
    clippy::cast_possible_wrap
)]

pub mod api;
pub mod bundled;
pub mod graphs;
pub mod inference;
pub mod maps;
pub mod on_demand;
pub mod protocol;
pub mod service;
pub mod store;

pub use service::{Knowledge, QueryLimits};
pub use store::{KnowledgeStore, RemoteConfig, StoreError};
