//! Knowledge service: the TOSM graph store, SPARQL and Graph Store protocols, on-demand
//! databases and map import.
//!
//! Only this crate and `worker` know axum; only this crate knows Oxigraph and the remote
//! SPARQL store it may keep its graph in.

pub mod api;
pub mod auth;
pub mod bundled;
pub mod inference;
pub mod maps;
pub mod on_demand;
pub mod protocol;
pub mod remote;
pub mod service;
pub mod store;

pub use auth::{Principal, Role, Tokens};
pub use remote::RemoteConfig;
pub use service::{Knowledge, QueryLimits};
pub use store::{KnowledgeStore, StoreError};
