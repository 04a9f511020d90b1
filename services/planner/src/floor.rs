//! Where plans and jobs get their worlds: the on-demand database of a floor (the knowledge
//! service's answer for one robot on one floor) and the mental simulation built from it.
//! Sources — the knowledge service in the same process, or over its REST API — implement
//! [`KnowledgeSource`]; everything a plan simulates comes through it, no side channel.

use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, OnceLock};

use oxrdf::Graph;
use sim::World;

/// Why no floor database could be had.
#[derive(Debug, Clone, thiserror::Error)]
pub enum SourceError {
    /// The robot or the place does not exist (the caller's to fix).
    #[error("{0}")]
    NotFound(String),
    /// They exist but make no world (a place on no floor, ...).
    #[error("{0}")]
    Unprocessable(String),
    /// The knowledge service cannot answer now (down, store unavailable, refused our token).
    #[error("{0}")]
    Unavailable(String),
}

/// The on-demand database of one floor for one robot, and the world made from it (built once,
/// on first use). Sources hand out shared copies while the knowledge is unchanged.
#[derive(Debug)]
pub struct FloorDatabase {
    /// The triples.
    pub graph: Graph,
    /// The robot's IRI.
    pub robot: String,
    /// The floor's IRI.
    pub floor: String,
    /// Names this content: equal versions mean equal triples (floor, robot and the state of
    /// the knowledge they were read at). Roadmaps and worlds are cached under it.
    pub version: String,
    world: OnceLock<Result<Arc<World>, String>>,
}

impl FloorDatabase {
    /// A database read at knowledge state `state`.
    pub fn new(graph: Graph, robot: String, floor: String, state: &str) -> Self {
        Self {
            version: format!("{floor}|{robot}|{state}"),
            graph,
            robot,
            floor,
            world: OnceLock::new(),
        }
    }

    /// The mental simulation of the floor with the robot: the simulation parser, then the
    /// world build. Blocking (milliseconds to a second for large maps) the first time, shared
    /// afterwards. The error names what in the knowledge does not make a world.
    pub fn world(&self) -> Result<Arc<World>, String> {
        self.world
            .get_or_init(|| {
                let spec =
                    sim::parse_floor(&self.graph, &self.robot, &self.floor).map_err(|p| {
                        format!("the knowledge of {} does not make a world: {p}", self.floor)
                    })?;
                World::build(spec).map_err(|e| format!("building the world of {}: {e}", self.floor))
            })
            .clone()
    }
}

/// A boxed future, for the object-safe trait below.
pub type SourceFuture<'a> =
    Pin<Box<dyn Future<Output = Result<Arc<FloorDatabase>, SourceError>> + Send + 'a>>;

/// Gives the on-demand database of the floor a place is on.
pub trait KnowledgeSource: Send + Sync + 'static {
    /// The database of the floor `place` (a floor, or a place on one; IRI or identifier) is
    /// on, with `robot` (IRI or identifier).
    fn floor_database<'a>(&'a self, place: &'a str, robot: &'a str) -> SourceFuture<'a>;
}
