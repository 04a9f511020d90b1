//! Evaluation of parsed SPARQL queries and updates on the store, into fully serialized
//! answers, under a cancellation token and the CONSTRUCT cap. Knows nothing of HTTP.

use oxigraph::io::{RdfFormat, RdfParser, RdfSerializer};
use oxigraph::model::{GraphName, NamedNode, NamedOrBlankNode, TripleRef};
use oxigraph::sparql::results::{
    QueryResultsFormat, QueryResultsParser, QueryResultsSerializer, SliceQueryResultsParserOutput,
};
use oxigraph::sparql::{
    CancellationToken, QueryDataset, QueryEvaluationError, QueryResults, SparqlEvaluator,
    UpdateEvaluationError,
};
use oxigraph::store::Store;

use super::negotiation::Format;
use crate::store::RemoteStore;

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
    /// The serialized answer grew past the byte cap of the caller's role.
    #[error("the answer is larger than {limit} bytes")]
    TooManyBytes {
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
    /// The remote store failed or refused.
    #[error(transparent)]
    Remote(#[from] crate::StoreError),
}

/// The dataset a request names with `default-graph-uri`/`named-graph-uri` (queries) or
/// `using-graph-uri`/`using-named-graph-uri` (updates). It replaces the operation's own
/// FROM/USING clauses.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ProtocolDataset {
    default: Vec<GraphName>,
    /// `None`: every named graph of the store stays available.
    named: Option<Vec<NamedOrBlankNode>>,
    /// The IRIs as the request gave them, forwarded as they are to a remote store.
    given: (Vec<NamedNode>, Vec<NamedNode>),
}

impl ProtocolDataset {
    /// The dataset from the two lists of IRIs, `None` when both are empty.
    pub(crate) fn from_iris(default: &[NamedNode], named: &[NamedNode]) -> Option<Self> {
        let named_given = named;
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
            given: (default.to_vec(), named_given.to_vec()),
        })
    }

    /// The protocol parameters that name this dataset to a remote store, under `default_name`
    /// and `named_name`.
    pub(crate) fn params<'a>(
        &'a self,
        default_name: &'a str,
        named_name: &'a str,
    ) -> Vec<(&'a str, &'a str)> {
        let default = self.given.0.iter().map(|g| (default_name, g.as_str()));
        let named = self.given.1.iter().map(|g| (named_name, g.as_str()));
        default.chain(named).collect()
    }

    fn apply(&self, spec: &mut QueryDataset) {
        *spec = QueryDataset::new();
        spec.set_default_graph(self.default.clone());
        if let Some(named) = &self.named {
            spec.set_available_named_graphs(named.clone());
        }
    }
}

/// A buffer that refuses to grow past `cap` bytes: serializers write into it, and the first
/// write past the cap fails with [`CapExceeded`], so an answer is never held whole beyond it.
pub(crate) struct CappedBuffer {
    pub(crate) bytes: Vec<u8>,
    cap: usize,
}

impl CappedBuffer {
    pub(crate) fn new(cap: usize) -> Self {
        Self {
            // Most answers are small: start with a few pages rather than growing from nothing.
            bytes: Vec::with_capacity(cap.min(16 * 1024)),
            cap,
        }
    }
}

impl std::io::Write for CappedBuffer {
    #[inline]
    fn write(&mut self, data: &[u8]) -> std::io::Result<usize> {
        self.write_all(data).map(|()| data.len())
    }

    /// The serializers write a JSON or XML answer a few bytes at a time: one check and one
    /// copy each, without `write_all`'s default loop.
    #[inline]
    fn write_all(&mut self, data: &[u8]) -> std::io::Result<()> {
        if self.bytes.len().saturating_add(data.len()) > self.cap {
            return Err(std::io::Error::other(CapExceeded(self.cap)));
        }
        self.bytes.extend_from_slice(data);
        Ok(())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The error a [`CappedBuffer`] fails with past its cap.
#[derive(Debug, thiserror::Error)]
#[error("the answer is larger than {0} bytes")]
pub(crate) struct CapExceeded(pub(crate) usize);

/// The cap, when `e` is a [`CappedBuffer`]'s refusal.
pub(crate) fn cap_exceeded(e: &std::io::Error) -> Option<usize> {
    e.get_ref()
        .and_then(|inner| inner.downcast_ref::<CapExceeded>())
        .map(|c| c.0)
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
    max_bytes: usize,
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
                .serialize_boolean_to_writer(CappedBuffer::new(max_bytes), value)
                .map(|b| b.bytes)
                .map_err(|e| unserializable(format.name(), e))
        }
        (QueryResults::Solutions(solutions), Format::Results(format)) => {
            let unserializable = |e| unserializable(format.name(), e);
            let mut serializer = QueryResultsSerializer::from_format(format)
                .serialize_solutions_to_writer(
                    CappedBuffer::new(max_bytes),
                    solutions.variables().to_vec(),
                )
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
            serializer.finish().map(|b| b.bytes).map_err(unserializable)
        }
        (QueryResults::Graph(triples), Format::Rdf(format)) => {
            let unserializable = |e| unserializable(format.name(), e);
            let mut serializer =
                RdfSerializer::from_format(format).for_writer(CappedBuffer::new(max_bytes));
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
            serializer.finish().map(|b| b.bytes).map_err(unserializable)
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

/// Sends `query` to the remote store and answers its result in `format`: a results body in the
/// negotiated format is passed through untouched; anything else (another results format, or
/// any graph, which must be counted against the cap) is parsed and written again.
pub(crate) async fn run_query_remote(
    remote: &RemoteStore,
    query: &spargebra::Query,
    dataset: Option<&ProtocolDataset>,
    format: Format,
    max_triples: usize,
    max_bytes: usize,
) -> Result<Vec<u8>, EvaluationError> {
    let params = dataset
        .map(|d| d.params("default-graph-uri", "named-graph-uri"))
        .unwrap_or_default();
    let text = query.to_string();
    match format {
        Format::Results(wanted) => {
            let accept = format!(
                "{}, application/sparql-results+json;q=0.5, application/sparql-results+xml;q=0.4",
                wanted.media_type()
            );
            let (content_type, body) = remote.query(&text, &params, &accept).await?;
            let got = content_type
                .as_deref()
                .and_then(QueryResultsFormat::from_media_type);
            if got == Some(wanted) {
                if body.len() > max_bytes {
                    return Err(EvaluationError::TooManyBytes { limit: max_bytes });
                }
                return Ok(body.to_vec());
            }
            let got = got.ok_or_else(|| unexpected(remote, content_type.as_deref()))?;
            transcode_results(&body, got, wanted, max_bytes)
        }
        Format::Rdf(wanted) => {
            let accept = "application/n-triples, text/turtle;q=0.9, application/rdf+xml;q=0.5, \
                          application/ld+json;q=0.4";
            let (content_type, body) = remote.query(&text, &params, accept).await?;
            let got = content_type
                .as_deref()
                .and_then(RdfFormat::from_media_type)
                .ok_or_else(|| unexpected(remote, content_type.as_deref()))?;
            let mut serializer =
                RdfSerializer::from_format(wanted).for_writer(CappedBuffer::new(max_bytes));
            for (count, triple) in RdfParser::from_format(got).for_slice(&body).enumerate() {
                if count >= max_triples {
                    return Err(EvaluationError::TooLarge { limit: max_triples });
                }
                let quad = triple.map_err(|e| {
                    EvaluationError::Storage(format!(
                        "the remote store's {} answer does not parse: {e}",
                        got.name()
                    ))
                })?;
                serializer
                    .serialize_triple(TripleRef::from(quad.as_ref()))
                    .map_err(|e| unserializable(wanted.name(), e))?;
            }
            serializer
                .finish()
                .map(|b| b.bytes)
                .map_err(|e| unserializable(wanted.name(), e))
        }
    }
}

fn unexpected(remote: &RemoteStore, content_type: Option<&str>) -> EvaluationError {
    EvaluationError::Storage(format!(
        "the remote store at {} answered the media type {content_type:?}, which the service \
         cannot read",
        remote.shown_query_url()
    ))
}

fn transcode_results(
    body: &[u8],
    from: QueryResultsFormat,
    to: QueryResultsFormat,
    max_bytes: usize,
) -> Result<Vec<u8>, EvaluationError> {
    let unreadable = |e: &dyn std::fmt::Display| {
        EvaluationError::Storage(format!("the remote store's results do not parse: {e}"))
    };
    let unserializable = |e| unserializable(to.name(), e);
    match QueryResultsParser::from_format(from)
        .for_slice(body)
        .map_err(|e| unreadable(&e))?
    {
        SliceQueryResultsParserOutput::Boolean(value) => QueryResultsSerializer::from_format(to)
            .serialize_boolean_to_writer(CappedBuffer::new(max_bytes), value)
            .map(|b| b.bytes)
            .map_err(unserializable),
        SliceQueryResultsParserOutput::Solutions(solutions) => {
            let mut serializer = QueryResultsSerializer::from_format(to)
                .serialize_solutions_to_writer(
                    CappedBuffer::new(max_bytes),
                    solutions.variables().to_vec(),
                )
                .map_err(unserializable)?;
            for solution in solutions {
                serializer
                    .serialize(&solution.map_err(|e| unreadable(&e))?)
                    .map_err(unserializable)?;
            }
            serializer.finish().map(|b| b.bytes).map_err(unserializable)
        }
    }
}

/// Sends `update` to the remote store.
pub(crate) async fn run_update_remote(
    remote: &RemoteStore,
    update: &spargebra::Update,
    dataset: Option<&ProtocolDataset>,
) -> Result<(), EvaluationError> {
    let params = dataset
        .map(|d| d.params("using-graph-uri", "using-named-graph-uri"))
        .unwrap_or_default();
    remote
        .update_async(&update.to_string(), &params)
        .await
        .map_err(EvaluationError::from)
}

fn query_error(e: QueryEvaluationError) -> EvaluationError {
    match e {
        QueryEvaluationError::Cancelled => EvaluationError::Cancelled,
        QueryEvaluationError::Dataset(e) => EvaluationError::Storage(e.to_string()),
        other => EvaluationError::Invalid(other.to_string()),
    }
}

fn unserializable(format: &'static str, e: std::io::Error) -> EvaluationError {
    if let Some(limit) = cap_exceeded(&e) {
        return EvaluationError::TooManyBytes { limit };
    }
    EvaluationError::Unserializable {
        format,
        message: e.to_string(),
    }
}
