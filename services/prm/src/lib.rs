//! Probabilistic roadmap, graph search, hybrid PRM-RL executor and plan validation; no IO.
//!
//! The flow: a [`PlanningGrid`] (converted by the caller from its own map type) and the robot's
//! [`Inflation`] give a [`ConfigSpace`] (inflated free space, distance field, free regions),
//! computed once per map version and robot. A [`Roadmap`] is built on it once per
//! [`PrmParams`] (the cache key is a [`RoadmapKey`]) and answers many [`Roadmap::query`] calls.

mod cspace;
mod error;
mod map;
mod roadmap;
mod search;

pub use cspace::{ConfigSpace, Inflation, RegionId};
pub use error::{BuildError, ConfigSpaceError, Endpoint, GridError, QueryError};
pub use map::{PlanningGrid, Point2};
pub use roadmap::{
    BuildPhase, BuildStats, MAX_SAMPLES, Plan, PrmParams, QueryOptions, Reservations, Roadmap,
    RoadmapKey, optimal_samples,
};
pub use search::SearchAlgorithm;
