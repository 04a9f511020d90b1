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
    world: OnceLock<Result<Arc<World>, WorldError>>,
}

impl FloorDatabase {
    /// A database read at knowledge state `state`. Its version names its triples, not the
    /// state: a write elsewhere in the knowledge, or a restart of the service, keeps the
    /// floor's cached world and its stored roadmaps. A graph with blank nodes (whose labels
    /// differ from one read to the next) is named by `state` instead.
    pub fn new(graph: Graph, robot: String, floor: String, state: &str) -> Self {
        let content = content_version(&graph)
            .map_or_else(|| state.to_owned(), |(a, b)| format!("{a:016x}{b:016x}"));
        Self {
            version: format!("{floor}|{robot}|{content}"),
            graph,
            robot,
            floor,
            world: OnceLock::new(),
        }
    }

    /// The mental simulation of the floor with the robot: the simulation parser, then the
    /// world build. Blocking (milliseconds to a second for large maps) the first time, shared
    /// afterwards. The error names what in the knowledge does not make a world.
    pub fn world(&self) -> Result<Arc<World>, WorldError> {
        self.world
            .get_or_init(|| {
                let floor = || self.floor.clone();
                let spec =
                    sim::parse_floor(&self.graph, &self.robot, &self.floor).map_err(|source| {
                        WorldError::Parse {
                            floor: floor(),
                            source,
                        }
                    })?;
                World::build(spec).map_err(|source| WorldError::Build {
                    floor: floor(),
                    source,
                })
            })
            .clone()
    }
}

/// Why a floor's on-demand database makes no mental simulation.
#[derive(Debug, Clone, thiserror::Error)]
pub enum WorldError {
    /// The simulation parser found errors in the knowledge.
    #[error("the knowledge of {floor} does not make a world: {source}")]
    Parse {
        /// The floor's IRI.
        floor: String,
        /// What the parser found.
        #[source]
        source: sim::SpecProblems,
    },
    /// The world could not be built from the parsed specification.
    #[error("building the world of {floor}: {source}")]
    Build {
        /// The floor's IRI.
        floor: String,
        /// What the build found.
        #[source]
        source: sim::SpecProblems,
    },
}

/// A fingerprint of `graph`'s triples that does not depend on their order (the sum and the
/// xor of each triple's FNV-1a hash, with the count folded in: 128 bits), or `None` when it
/// holds a blank node.
fn content_version(graph: &Graph) -> Option<(u64, u64)> {
    let (mut sum, mut xor) = (graph.len() as u64, 0u64);
    for t in graph {
        if t.subject.is_blank_node() || t.object.is_blank_node() {
            return None;
        }
        let h = grid::hash::fnv1a(t.to_string().as_bytes());
        sum = sum.wrapping_add(h);
        xor ^= h.rotate_left(17);
    }
    Some((sum, xor))
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

#[cfg(test)]
mod tests {
    use oxrdf::{BlankNode, Graph, Literal, NamedNode, Triple};

    use super::FloorDatabase;

    fn triple(s: &str, o: &str) -> Triple {
        Triple::new(
            NamedNode::new_unchecked(format!("https://ex.org/{s}")),
            NamedNode::new_unchecked("https://ex.org/p"),
            Literal::new_simple_literal(o),
        )
    }

    fn version(triples: &[Triple], state: &str) -> String {
        let mut g = Graph::new();
        for t in triples {
            g.insert(t);
        }
        FloorDatabase::new(g, "r".into(), "f".into(), state).version
    }

    #[test]
    fn the_version_names_the_triples_not_the_state_they_were_read_at() {
        let (a, b, c) = (triple("a", "1"), triple("b", "2"), triple("b", "3"));
        let ab = version(&[a.clone(), b.clone()], "state-1");
        assert_eq!(ab, version(&[b.clone(), a.clone()], "state-2"));
        assert_ne!(ab, version(&[a.clone(), c.clone()], "state-1"));
        assert_ne!(ab, version(std::slice::from_ref(&a), "state-1"));
        // Blank node labels change between reads: such a graph is named by its state.
        let blank = Triple::new(
            BlankNode::default(),
            NamedNode::new_unchecked("https://ex.org/p"),
            Literal::new_simple_literal("x"),
        );
        assert!(version(&[a, blank], "state-9").ends_with("|state-9"));
    }
}
