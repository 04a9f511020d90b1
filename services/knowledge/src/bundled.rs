//! The bundled knowledge loaded on first start: the TOSM ontology, the paper's differential
//! robot, a TIAGo-like base and a sample building made from real maps, each in its own named graph so an engineer
//! can replace one with a Graph Store PUT.

use oxigraph::model::NamedNodeRef;

use crate::graphs::{ONTOLOGY_GRAPH, ROBOT_GRAPH, SAMPLE_BUILDING_GRAPH, TIAGO_ROBOT_GRAPH};
use crate::store::{KnowledgeStore, StoreError};

/// One bundled file and the named graph it is loaded into.
#[derive(Debug, Clone, Copy)]
pub struct BundledGraph {
    /// The named graph.
    pub graph: &'static str,
    /// Path under `ontologies/`, for messages.
    pub file: &'static str,
    /// The Turtle text, compiled into the binary so a fresh data directory needs no files.
    pub turtle: &'static str,
}

/// Everything bundled, in load order.
pub const BUNDLED: &[BundledGraph] = &[
    BundledGraph {
        graph: ONTOLOGY_GRAPH,
        file: "tosm.ttl",
        turtle: include_str!("../../../ontologies/tosm.ttl"),
    },
    BundledGraph {
        graph: ROBOT_GRAPH,
        file: "robots/differential-robot.ttl",
        turtle: include_str!("../../../ontologies/robots/differential-robot.ttl"),
    },
    BundledGraph {
        graph: TIAGO_ROBOT_GRAPH,
        file: "robots/tiago-base.ttl",
        turtle: include_str!("../../../ontologies/robots/tiago-base.ttl"),
    },
    BundledGraph {
        graph: SAMPLE_BUILDING_GRAPH,
        file: "environments/sample-building.ttl",
        turtle: include_str!("../../../ontologies/environments/sample-building.ttl"),
    },
];

/// Loads the bundled graphs when the store is empty (a fresh data directory). A store that
/// already holds data is left alone: engineers' edits survive restarts. Blocking.
/// Returns whether anything was loaded.
pub fn load_if_empty(store: &KnowledgeStore) -> Result<bool, StoreError> {
    if !store.is_empty()? {
        return Ok(false);
    }
    let mut quads = Vec::new();
    for bundled in BUNDLED {
        let parsed = KnowledgeStore::parse_turtle(
            bundled.turtle,
            NamedNodeRef::new_unchecked(bundled.graph),
        )
        .map_err(|e| StoreError::Query {
            location: store.location().to_owned(),
            message: format!("bundled {} does not load: {e}", bundled.file),
        })?;
        quads.extend(parsed);
    }
    store.insert(&quads)?;
    crate::inference::refresh(store)?;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bundled_graphs_load_once_and_parse_as_tosm() {
        let store = KnowledgeStore::in_memory().unwrap();
        assert!(load_if_empty(&store).unwrap());
        assert!(
            !load_if_empty(&store).unwrap(),
            "second start loads nothing"
        );
        for bundled in BUNDLED {
            assert!(
                store
                    .contains_named_graph(NamedNodeRef::new_unchecked(bundled.graph))
                    .unwrap()
            );
        }
        // The entailments are there: the vending machine is a tosm:Object through its class.
        let q = "PREFIX tosm: <https://mentalsim.dev/ontology/tosm#>
                 ASK { GRAPH ?g { ?x a tosm:VendingMachine } GRAPH ?h { ?x a tosm:Object } }";
        let answer = oxigraph::sparql::SparqlEvaluator::new()
            .parse_query(q)
            .unwrap()
            .on_store(store.embedded().unwrap())
            .execute()
            .unwrap();
        assert!(matches!(
            answer,
            oxigraph::sparql::QueryResults::Boolean(true)
        ));
    }
}
