//! The SPARQL 1.1 Service Description served on `GET /sparql` without a query: what the
//! endpoint speaks, which formats it answers in, and what its dataset holds.

use axum::http::header::{ACCEPT, CONTENT_TYPE, VARY};
use axum::http::{HeaderMap, HeaderValue};
use axum::response::{IntoResponse, Response};
use edge::ApiError;
use oxigraph::io::{RdfFormat, RdfSerializer};
use oxigraph::model::vocab::{rdf, rdfs};
use oxigraph::model::{Literal, NamedNode, Term, Triple};

use super::Params;
use super::negotiation::{self, Format, GRAPH_FORMATS, RESULT_FORMATS};
use crate::graphs::INFERRED_GRAPH;

const SD: &str = "http://www.w3.org/ns/sparql-service-description#";

/// The description of the endpoint at `endpoint`, in the negotiated RDF format.
pub(super) fn answer(
    endpoint: &str,
    params: &Params,
    headers: &HeaderMap,
) -> Result<Response, ApiError> {
    let accept = headers.get(ACCEPT).and_then(|v| v.to_str().ok());
    let format = negotiation::rdf_format(
        accept,
        &params.format_hints(),
        GRAPH_FORMATS,
        "the service description",
    )?;
    let triples = describe(endpoint)?;
    let body = serialize(&triples, format).map_err(ApiError::internal)?;
    Ok((
        [
            (
                CONTENT_TYPE,
                HeaderValue::from_static(negotiation::content_type(Format::Rdf(format))),
            ),
            (VARY, HeaderValue::from_static("accept")),
        ],
        body,
    )
        .into_response())
}

fn sd(local: &str) -> NamedNode {
    NamedNode::new_unchecked(format!("{SD}{local}"))
}

/// The description as triples. Its resources are named under the endpoint's IRI rather than
/// left blank, so two fetches of it merge cleanly.
fn describe(endpoint: &str) -> Result<Vec<Triple>, ApiError> {
    let iri = |suffix: &str| {
        NamedNode::new(format!("{endpoint}{suffix}")).map_err(|e| {
            ApiError::bad_request(format!("the request URL `{endpoint}` is not an IRI: {e}"))
        })
    };
    let service = iri("#service")?;
    let dataset = iri("#dataset")?;
    let default_graph = iri("#default-graph")?;
    let inferred = iri("#inferred-graph")?;
    let mut triples = vec![
        Triple::new(service.clone(), rdf::TYPE, sd("Service")),
        Triple::new(service.clone(), sd("endpoint"), iri("")?),
        Triple::new(
            service.clone(),
            sd("supportedLanguage"),
            sd("SPARQL11Query"),
        ),
        Triple::new(
            service.clone(),
            sd("supportedLanguage"),
            sd("SPARQL11Update"),
        ),
        // Oxigraph keeps a named graph that CREATE GRAPH made, or that was emptied.
        Triple::new(service.clone(), sd("feature"), sd("EmptyGraphs")),
        Triple::new(
            service.clone(),
            sd("defaultEntailmentRegime"),
            NamedNode::new_unchecked("http://www.w3.org/ns/entailment/Simple"),
        ),
        Triple::new(service.clone(), sd("defaultDataset"), dataset.clone()),
        Triple::new(dataset.clone(), rdf::TYPE, sd("Dataset")),
        Triple::new(dataset.clone(), sd("defaultGraph"), default_graph.clone()),
        Triple::new(default_graph, rdf::TYPE, sd("Graph")),
        Triple::new(dataset, sd("namedGraph"), inferred.clone()),
        Triple::new(inferred.clone(), rdf::TYPE, sd("NamedGraph")),
        Triple::new(inferred.clone(), sd("name"), INFERRED_GRAPH.into_owned()),
        Triple::new(
            inferred,
            rdfs::COMMENT,
            Literal::new_simple_literal(
                "Entailments of the asserted graphs (class and property hierarchy, inverse, \
                 symmetric and transitive properties), rebuilt by the service after every \
                 write. Read it; never write it.",
            ),
        ),
    ];
    let result_formats = RESULT_FORMATS.iter().map(|f| f.iri());
    let graph_formats = GRAPH_FORMATS.iter().map(|f| f.iri());
    for format in result_formats.chain(graph_formats) {
        triples.push(Triple::new(
            service.clone(),
            sd("resultFormat"),
            Term::from(NamedNode::new_unchecked(format)),
        ));
    }
    Ok(triples)
}

fn serialize(triples: &[Triple], format: RdfFormat) -> std::io::Result<Vec<u8>> {
    let serializer = RdfSerializer::from_format(format)
        .with_prefix("sd", SD)
        .map_err(std::io::Error::other)?;
    let mut writer = serializer.for_writer(Vec::new());
    for triple in triples {
        writer.serialize_triple(triple)?;
    }
    writer.finish()
}
