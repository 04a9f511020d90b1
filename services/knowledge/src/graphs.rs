//! The named graphs the service names itself: where the entailments, robots' reports,
//! imported maps and the bundled knowledge live.
//!
//! One module that imports nothing from the crate, so the store, inference, the protocols, the
//! REST API and the bundled data agree on these IRIs without importing one another.

use oxigraph::model::NamedNodeRef;

/// The named graph holding the entailments (materialised by `inference`). Never edit it: it is
/// replaced on every write. For a remote store it also holds the version marker.
pub const INFERRED_GRAPH: NamedNodeRef<'static> =
    NamedNodeRef::new_unchecked("https://mentalsim.dev/graph/inferred");

/// The named graph robots' reports live in.
pub const PERCEIVED_GRAPH: &str = "https://mentalsim.dev/graph/perceived";

/// Prefix of the named graph each imported map lives in (the map's name follows).
pub const MAPS_GRAPH_NS: &str = "https://mentalsim.dev/graph/maps/";

/// The bundled TOSM ontology.
pub const ONTOLOGY_GRAPH: &str = "https://mentalsim.dev/graph/ontology/tosm";

/// The bundled robot: the paper's differential robot.
pub const ROBOT_GRAPH: &str = "https://mentalsim.dev/graph/robots/differential-robot";

/// The second bundled robot: a TIAGo-like base, so everything kept per robot model has two.
pub const TIAGO_ROBOT_GRAPH: &str = "https://mentalsim.dev/graph/robots/tiago-base";

/// The bundled sample building made from real maps.
pub const SAMPLE_BUILDING_GRAPH: &str = "https://mentalsim.dev/graph/environments/sample-building";
