//! Evaluation of parsed SPARQL queries and updates on the store, into fully serialized
//! answers, under a cancellation token and the CONSTRUCT cap. Knows nothing of HTTP.

use oxigraph::io::RdfSerializer;
use oxigraph::model::{GraphName, NamedNode, NamedOrBlankNode};
use oxigraph::sparql::results::QueryResultsSerializer;
use oxigraph::sparql::{
    CancellationToken, QueryDataset, QueryEvaluationError, QueryResults, SparqlEvaluator,
    UpdateEvaluationError,
};
use oxigraph::store::Store;

use super::negotiation::Format;

/// rdflib's name for "the default graph" of a `Dataset`. rdflib sends it as
/// `default-graph-uri`, and writes either into the real default graph (`Dataset.add`) or into a
/// graph of that name (`Dataset.update`), so reads given it see the union of both.
pub(crate) const RDFLIB_DEFAULT_GRAPH: &str = "urn:x-rdflib:default";

/// Why an operation failed.
#[derive(Debug, thiserror::Error)]
pub(crate) enum EvaluationError {
    /// The cancellation token fired: the deadline passed or the client went away.
    #[error("evaluation cancelled")]
    Cancelled,
    /// A CONSTRUCT or DESCRIBE produced more triples than allowed.
    #[error("the result has more than {limit} triples")]
    TooLarge {
        /// The cap.
        limit: usize,
    },
    /// The operation cannot be evaluated as written (e.g. an unsupported SERVICE or LOAD).
    #[error("{0}")]
    Invalid(String),
    /// CREATE of a graph that exists.
    #[error("{0}")]
    Conflict(String),
    /// DROP of a graph that does not exist.
    #[error("{0}")]
    NotFound(String),
    /// The result cannot be written in the negotiated format (e.g. RDF/XML and a predicate
    /// IRI it cannot abbreviate).
    #[error("the result cannot be serialized as {format}: {message}")]
    Unserializable {
        /// The format's name.
        format: &'static str,
        /// The serializer's complaint.
        message: String,
    },
    /// The store failed.
    #[error("storage: {0}")]
    Storage(String),
}

/// The dataset a request names with `default-graph-uri`/`named-graph-uri` (queries) or
/// `using-graph-uri`/`using-named-graph-uri` (updates). It replaces the operation's own
/// FROM/USING clauses.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ProtocolDataset {
    default: Vec<GraphName>,
    /// `None`: every named graph of the store stays available.
    named: Option<Vec<NamedOrBlankNode>>,
}

impl ProtocolDataset {
    /// The dataset from the two lists of IRIs, `None` when both are empty.
    pub(crate) fn from_iris(default: &[NamedNode], named: &[NamedNode]) -> Option<Self> {
        if default.is_empty() && named.is_empty() {
            return None;
        }
        let rdflib_default = default.iter().any(|g| g.as_str() == RDFLIB_DEFAULT_GRAPH);
        let default_graphs = default
            .iter()
            .flat_map(|g| {
                if g.as_str() == RDFLIB_DEFAULT_GRAPH {
                    vec![GraphName::DefaultGraph, g.clone().into()]
                } else {
                    vec![g.clone().into()]
                }
            })
            .collect();
        // rdflib sends its default-graph name on every `Dataset.query`, also for queries that
        // use GRAPH; restricting the named graphs to none would make those see nothing.
        let named = if rdflib_default && named.is_empty() {
            None
        } else {
            Some(named.iter().cloned().map(Into::into).collect())
        };
        Some(Self {
            default: default_graphs,
            named,
        })
    }

    fn apply(&self, spec: &mut QueryDataset) {
        *spec = QueryDataset::new();
        spec.set_default_graph(self.default.clone());
        if let Some(named) = &self.named {
            spec.set_available_named_graphs(named.clone());
        }
    }
}

/// Evaluates `query` and serializes its whole answer in `format`, which must fit the query
/// form: a results format for SELECT and ASK, an RDF format for CONSTRUCT and DESCRIBE.
/// Blocking.
pub(crate) fn run_query(
    store: &Store,
    query: spargebra::Query,
    dataset: Option<&ProtocolDataset>,
    format: Format,
    max_triples: usize,
    token: CancellationToken,
) -> Result<Vec<u8>, EvaluationError> {
    let mut prepared = SparqlEvaluator::new()
        .with_cancellation_token(token.clone())
        .for_query(query);
    if let Some(dataset) = dataset {
        dataset.apply(prepared.dataset_mut());
    }
    let results = prepared.on_store(store).execute().map_err(query_error)?;
    match (results, format) {
        (QueryResults::Boolean(value), Format::Results(format)) => {
            QueryResultsSerializer::from_format(format)
                .serialize_boolean_to_writer(Vec::new(), value)
                .map_err(|e| unserializable(format.name(), e))
        }
        (QueryResults::Solutions(solutions), Format::Results(format)) => {
            let unserializable = |e| unserializable(format.name(), e);
            let mut serializer = QueryResultsSerializer::from_format(format)
                .serialize_solutions_to_writer(Vec::new(), solutions.variables().to_vec())
                .map_err(unserializable)?;
            for solution in solutions {
                // Oxigraph checks its token when it reads the store, not while it combines
                // rows it already holds (a cross product); checking per row covers that.
                if token.is_cancelled() {
                    return Err(EvaluationError::Cancelled);
                }
                serializer
                    .serialize(&solution.map_err(query_error)?)
                    .map_err(unserializable)?;
            }
            serializer.finish().map_err(unserializable)
        }
        (QueryResults::Graph(triples), Format::Rdf(format)) => {
            let unserializable = |e| unserializable(format.name(), e);
            let mut serializer = RdfSerializer::from_format(format).for_writer(Vec::new());
            let mut count = 0_usize;
            for triple in triples {
                if token.is_cancelled() {
                    return Err(EvaluationError::Cancelled);
                }
                let triple = triple.map_err(query_error)?;
                count += 1;
                if count > max_triples {
                    return Err(EvaluationError::TooLarge { limit: max_triples });
                }
                serializer
                    .serialize_triple(&triple)
                    .map_err(unserializable)?;
            }
            serializer.finish().map_err(unserializable)
        }
        (_, _) => Err(EvaluationError::Invalid(
            "the negotiated format does not fit the query form".to_owned(),
        )),
    }
}

/// Applies `update` to the store in one transaction. Blocking.
pub(crate) fn run_update(
    store: &Store,
    update: spargebra::Update,
    dataset: Option<&ProtocolDataset>,
    token: CancellationToken,
) -> Result<(), EvaluationError> {
    let cancelled = token.clone();
    let mut prepared = SparqlEvaluator::new()
        .with_cancellation_token(token)
        .for_update(update);
    if let Some(dataset) = dataset {
        for spec in prepared.using_datasets_mut() {
            dataset.apply(spec);
        }
    }
    prepared.on_store(store).execute().map_err(|e| {
        // Oxigraph wraps a cancelled WHERE clause in an opaque error; the token says it all.
        if cancelled.is_cancelled() {
            return EvaluationError::Cancelled;
        }
        match e {
            UpdateEvaluationError::Storage(e) => EvaluationError::Storage(e.to_string()),
            UpdateEvaluationError::GraphAlreadyExists(_) => {
                EvaluationError::Conflict(e.to_string())
            }
            UpdateEvaluationError::GraphDoesNotExist(_) => EvaluationError::NotFound(e.to_string()),
            other => EvaluationError::Invalid(other.to_string()),
        }
    })
}

fn query_error(e: QueryEvaluationError) -> EvaluationError {
    match e {
        QueryEvaluationError::Cancelled => EvaluationError::Cancelled,
        QueryEvaluationError::Dataset(e) => EvaluationError::Storage(e.to_string()),
        other => EvaluationError::Invalid(other.to_string()),
    }
}

fn unserializable(format: &'static str, e: std::io::Error) -> EvaluationError {
    EvaluationError::Unserializable {
        format,
        message: e.to_string(),
    }
}
