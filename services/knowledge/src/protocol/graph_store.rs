//! `/store`: the SPARQL 1.1 Graph Store HTTP Protocol. A graph is named indirectly
//! (`/store?graph=IRI`, `/store?default`) or directly (the request URL under `/store/` is the
//! graph's IRI). GET and HEAD read; PUT replaces, POST merges (also multipart/form-data, and
//! POST to `/store` itself creates a graph and answers its IRI in `Location`); DELETE drops.

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::State;
use axum::http::header::{ACCEPT, CONTENT_TYPE, LOCATION, VARY};
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, Uri};
use axum::response::{IntoResponse, Response};
use edge::{ApiError, Caller, ErrorCode, Principal, Role};
use oxigraph::io::{RdfFormat, RdfParser, RdfSerializer};
use oxigraph::model::{GraphName, NamedNode, Quad, TripleRef};
use oxigraph::sparql::CancellationToken;

use super::negotiation::{self, DATASET_FORMATS, Format, GRAPH_FORMATS};
use super::{
    Deadline, Params, blocking, body_media_type, graph_store_method_not_allowed, request_origin,
};
use crate::graphs::INFERRED_GRAPH;
use crate::service::Knowledge;
use crate::store::KnowledgeStore;

/// What a request addresses.
#[derive(Debug, Clone)]
enum Target {
    /// The store's default graph (`?default`).
    Default,
    /// A named graph.
    Named(NamedNode),
    /// The endpoint itself, with no graph named: POST creates a graph, GET reads the dataset.
    Store,
}

impl Target {
    fn graph_name(&self) -> Option<GraphName> {
        match self {
            Target::Default => Some(GraphName::DefaultGraph),
            Target::Named(g) => Some(g.clone().into()),
            Target::Store => None,
        }
    }
}

/// `/store` with `?graph=IRI`, `?default`, or neither.
pub(super) async fn indirect(
    State(knowledge): State<Arc<Knowledge>>,
    method: Method,
    uri: Uri,
    Caller(caller): Caller,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, ApiError> {
    let role = authorize(&method, caller)?;
    let params = Params::of_uri(&uri)?;
    let target = match (params.at_most_one("graph")?, params.contains("default")) {
        (Some(_), true) => {
            return Err(ApiError::bad_request(
                "name either `graph=IRI` or `default`, not both",
            ));
        }
        (Some(iri), false) => Target::Named(NamedNode::new(iri).map_err(|e| {
            ApiError::bad_request(format!("`graph` value `{iri}` is not an absolute IRI: {e}"))
        })?),
        (None, true) => Target::Default,
        (None, false) => Target::Store,
    };
    handle(
        knowledge, method, target, &uri, &headers, &params, body, role,
    )
    .await
}

/// `/store/…`: the request URL is the graph's IRI.
pub(super) async fn direct(
    State(knowledge): State<Arc<Knowledge>>,
    method: Method,
    uri: Uri,
    Caller(caller): Caller,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, ApiError> {
    let role = authorize(&method, caller)?;
    let params = Params::of_uri(&uri)?;
    if params.contains("graph") || params.contains("default") {
        return Err(ApiError::bad_request(
            "a graph addressed by its own URL takes no `graph` or `default` parameter",
        ));
    }
    let iri = format!("{}{}", request_origin(&uri, &headers), uri.path());
    let graph = NamedNode::new(&iri).map_err(|e| {
        ApiError::bad_request(format!("the request URL `{iri}` is not an IRI: {e}"))
    })?;
    handle(
        knowledge,
        method,
        Target::Named(graph),
        &uri,
        &headers,
        &params,
        body,
        role,
    )
    .await
}

/// The caller's role, when it may use `method`: reads take any token, writes an engineer's.
fn authorize(method: &Method, caller: Principal) -> Result<Role, ApiError> {
    if method == Method::GET || method == Method::HEAD {
        Ok(caller.role)
    } else {
        caller.require(Role::Engineer).map(|p| p.role)
    }
}

#[allow(
    clippy::too_many_arguments,
    reason = "the request's parts, each read once; a struct would only rename them"
)]
async fn handle(
    knowledge: Arc<Knowledge>,
    method: Method,
    target: Target,
    uri: &Uri,
    headers: &HeaderMap,
    params: &Params,
    body: Bytes,
    role: Role,
) -> Result<Response, ApiError> {
    let is_write = matches!(method, Method::PUT | Method::POST | Method::DELETE);
    if is_write
        && let Target::Named(graph) = &target
        && graph.as_ref() == INFERRED_GRAPH
    {
        return Err(ApiError::new(
            ErrorCode::Conflict,
            format!(
                "<{INFERRED_GRAPH}> is rebuilt by the service after every write; write the \
                 asserted graphs instead"
            ),
        ));
    }
    match method {
        Method::GET | Method::HEAD => {
            read(
                knowledge,
                method == Method::HEAD,
                target,
                params,
                headers,
                role,
            )
            .await
        }
        Method::PUT => replace(knowledge, target, uri, headers, body).await,
        Method::POST => merge(knowledge, target, uri, headers, body).await,
        Method::DELETE => delete(knowledge, target).await,
        _ => Ok(graph_store_method_not_allowed()),
    }
}

async fn read(
    knowledge: Arc<Knowledge>,
    head: bool,
    target: Target,
    params: &Params,
    headers: &HeaderMap,
    role: Role,
) -> Result<Response, ApiError> {
    let accept = headers.get(ACCEPT).and_then(|v| v.to_str().ok());
    let hints = params.format_hints();
    let format = match target {
        Target::Store => {
            negotiation::rdf_format(accept, &hints, DATASET_FORMATS, "the whole dataset")?
        }
        Target::Default | Target::Named(_) => {
            negotiation::rdf_format(accept, &hints, GRAPH_FORMATS, "a graph")?
        }
    };
    let limits = knowledge.limits;
    let max_bytes = limits.result_bytes(role);
    let deadline = Deadline::start(knowledge.reads(), limits.deadline);
    let (token, exceeded) = (deadline.token(), deadline.exceeded());
    let body = deadline
        .read(move || {
            let store = knowledge.store()?;
            if let Target::Named(graph) = &target
                && !store.contains_named_graph(graph.as_ref())?
            {
                return Err(ApiError::not_found(format!(
                    "graph <{graph}> does not exist"
                )));
            }
            if head {
                return Ok(Vec::new());
            }
            serialize(
                &store,
                &target,
                format,
                (limits.max_construct_triples, max_bytes),
                &token,
            )
            .map_err(|e| match e {
                Dump::Cancelled => exceeded,
                Dump::TooLarge(limit) => ApiError::new(
                    ErrorCode::ResultTooLarge,
                    format!(
                        "the graph has more than {limit} triples, the configured cap; read \
                             it in parts with SPARQL (LIMIT/OFFSET)"
                    ),
                ),
                Dump::TooManyBytes(limit) => ApiError::new(
                    ErrorCode::ResultTooLarge,
                    format!(
                        "the graph serializes to more than {limit} bytes, the cap of this \
                         token's role; read it in parts with SPARQL (LIMIT/OFFSET)"
                    ),
                ),
                Dump::Store(e) => ApiError::from(e),
                Dump::Failed(message) => ApiError::internal(message),
            })
        })
        .await?;
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

enum Dump {
    Cancelled,
    TooLarge(usize),
    TooManyBytes(usize),
    Store(crate::StoreError),
    Failed(String),
}

/// The target's triples (or the whole dataset's quads) in `format`. Blocking.
fn serialize(
    store: &KnowledgeStore,
    target: &Target,
    format: RdfFormat,
    (max_triples, max_bytes): (usize, usize),
    token: &CancellationToken,
) -> Result<Vec<u8>, Dump> {
    match (store.embedded(), store.remote_store()) {
        (Some(embedded), _) => {
            let quads = match target.graph_name() {
                Some(graph) => embedded.quads_for_pattern(None, None, None, Some(graph.as_ref())),
                None => embedded.iter(),
            };
            write_quads(quads, target, format, (max_triples, max_bytes), token)
        }
        (None, Some(remote)) => {
            // One more than the cap tells whether the cap is exceeded.
            let quads = remote
                .quads(
                    target.graph_name().as_ref(),
                    Some(max_triples.saturating_add(1)),
                )
                .map_err(Dump::Store)?;
            write_quads(
                quads.into_iter().map(Ok::<Quad, std::convert::Infallible>),
                target,
                format,
                (max_triples, max_bytes),
                token,
            )
        }
        (None, None) => Err(Dump::Failed("the store has no backend".to_owned())),
    }
}

fn write_quads<E: std::fmt::Display>(
    quads: impl Iterator<Item = Result<Quad, E>>,
    target: &Target,
    format: RdfFormat,
    (max_triples, max_bytes): (usize, usize),
    token: &CancellationToken,
) -> Result<Vec<u8>, Dump> {
    let failed = |e: &std::io::Error| match super::evaluation::cap_exceeded(e) {
        Some(limit) => Dump::TooManyBytes(limit),
        None => Dump::Failed(e.to_string()),
    };
    let mut serializer = RdfSerializer::from_format(format)
        .for_writer(super::evaluation::CappedBuffer::new(max_bytes));
    for (count, quad) in quads.enumerate() {
        // Checking an atomic per quad is cheap next to serializing it.
        if token.is_cancelled() {
            return Err(Dump::Cancelled);
        }
        if count >= max_triples {
            return Err(Dump::TooLarge(max_triples));
        }
        let quad = quad.map_err(|e| Dump::Failed(e.to_string()))?;
        match target {
            Target::Store => serializer.serialize_quad(&quad),
            Target::Default | Target::Named(_) => {
                serializer.serialize_triple(TripleRef::from(quad.as_ref()))
            }
        }
        .map_err(|e| failed(&e))?;
    }
    serializer.finish().map(|b| b.bytes).map_err(|e| failed(&e))
}

/// One RDF document of a request body.
struct Document {
    format: RdfFormat,
    bytes: Bytes,
}

const READABLE: &str = "text/turtle, application/n-triples, application/rdf+xml, \
                        application/ld+json, application/n-quads, application/trig, text/n3 \
                        (UTF-8), or multipart/form-data of those";

fn input_format(content_type: &str) -> Result<RdfFormat, ApiError> {
    RdfFormat::from_media_type(content_type).ok_or_else(|| {
        ApiError::new(
            ErrorCode::UnsupportedMediaType,
            format!("`{content_type}` is not an RDF syntax the store reads; send {READABLE}"),
        )
    })
}

/// The documents of a request body: the body itself, or each part of a multipart/form-data
/// body (typed by its own Content-Type, or else by its file name's extension).
async fn documents(headers: &HeaderMap, body: Bytes) -> Result<Vec<Document>, ApiError> {
    let Some((media_type, _)) = body_media_type(headers) else {
        return Err(ApiError::new(
            ErrorCode::UnsupportedMediaType,
            format!("the body has no Content-Type; send {READABLE}"),
        ));
    };
    let content_type = headers
        .get(CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or_default();
    if media_type != "multipart/form-data" {
        return Ok(vec![Document {
            format: input_format(content_type)?,
            bytes: body,
        }]);
    }
    let malformed =
        |e: multer::Error| ApiError::bad_request(format!("malformed multipart body: {e}"));
    let boundary = multer::parse_boundary(content_type).map_err(malformed)?;
    let stream = futures_util::stream::once(async move { Ok::<_, std::convert::Infallible>(body) });
    let mut multipart = multer::Multipart::new(stream, boundary);
    let mut documents = Vec::new();
    while let Some(field) = multipart.next_field().await.map_err(malformed)? {
        let format = match (field.content_type(), field.file_name()) {
            (Some(mime), _) => input_format(mime.as_ref())?,
            (None, Some(name)) => name
                .rsplit_once('.')
                .and_then(|(_, extension)| RdfFormat::from_extension(extension))
                .ok_or_else(|| {
                    ApiError::new(
                        ErrorCode::UnsupportedMediaType,
                        format!("part `{name}` has no Content-Type and no known RDF extension"),
                    )
                })?,
            (None, None) => {
                return Err(ApiError::new(
                    ErrorCode::UnsupportedMediaType,
                    "a multipart part has neither a Content-Type nor a file name",
                ));
            }
        };
        let bytes = field.bytes().await.map_err(malformed)?;
        documents.push(Document { format, bytes });
    }
    Ok(documents)
}

/// The documents' triples, placed in `graph`. Blank nodes are renamed apart, so data from two
/// requests never shares a blank node by accident of labels. Blocking.
fn parse(documents: &[Document], graph: &GraphName, base: &str) -> Result<Vec<Quad>, ApiError> {
    let mut quads = Vec::new();
    for document in documents {
        // The JSON-LD parser recurses per nesting level: refuse what would overflow its stack.
        if matches!(document.format, RdfFormat::JsonLd { .. }) {
            super::complexity::check_json(&document.bytes).map_err(ApiError::bad_request)?;
        }
        let parser = RdfParser::from_format(document.format)
            .rename_blank_nodes()
            .without_named_graphs()
            .with_default_graph(graph.clone())
            .with_base_iri(base)
            .map_err(|e| {
                ApiError::bad_request(format!("`{base}` is not a usable base IRI: {e}"))
            })?;
        for quad in parser.for_slice(&document.bytes) {
            quads.push(quad.map_err(|e| {
                ApiError::bad_request(format!(
                    "the body does not parse as {}: {e}",
                    document.format.name()
                ))
            })?);
        }
    }
    Ok(quads)
}

/// PUT: the graph's content becomes the body's. 201 when the graph is new, else 204.
async fn replace(
    knowledge: Arc<Knowledge>,
    target: Target,
    uri: &Uri,
    headers: &HeaderMap,
    body: Bytes,
) -> Result<Response, ApiError> {
    let Some(graph) = target.graph_name() else {
        return Err(ApiError::bad_request(
            "PUT needs a graph: `/store?graph=IRI`, `/store?default`, or a URL under /store/",
        ));
    };
    knowledge.check_space(body.len() as u64)?;
    let documents = documents(headers, body).await?;
    let base = base_for(&graph, uri, headers);
    let created = blocking(move || {
        let quads = parse(&documents, &graph, &base)?;
        let store = knowledge.store()?;
        let created = store.replace_graph(&graph, &quads)?;
        knowledge.after_write()?;
        Ok(created)
    })
    .await?;
    Ok(written(created, None))
}

/// POST: the body's triples are added to the graph (201 when that creates it, else 204); to
/// the endpoint itself, they become a new graph whose IRI is answered in `Location`.
async fn merge(
    knowledge: Arc<Knowledge>,
    target: Target,
    uri: &Uri,
    headers: &HeaderMap,
    body: Bytes,
) -> Result<Response, ApiError> {
    let (graph, location) = match target.graph_name() {
        Some(graph) => (graph, None),
        None => {
            let iri = format!(
                "{}{}/{}",
                request_origin(uri, headers),
                uri.path().trim_end_matches('/'),
                uuid::Uuid::new_v4()
            );
            let graph = NamedNode::new(&iri).map_err(|e| {
                ApiError::bad_request(format!("the request URL does not make a graph IRI: {e}"))
            })?;
            (graph.into(), Some(iri))
        }
    };
    knowledge.check_space(body.len() as u64)?;
    let documents = documents(headers, body).await?;
    let base = base_for(&graph, uri, headers);
    let created = blocking(move || {
        let quads = parse(&documents, &graph, &base)?;
        let store = knowledge.store()?;
        let created = store.merge_into_graph(&graph, &quads)?;
        knowledge.after_write()?;
        Ok(created)
    })
    .await?;
    Ok(written(created, location))
}

/// DELETE: a named graph is dropped (404 if there is none), the default graph emptied.
async fn delete(knowledge: Arc<Knowledge>, target: Target) -> Result<Response, ApiError> {
    let Some(graph) = target.graph_name() else {
        return Err(ApiError::bad_request(
            "DELETE needs a graph: `/store?graph=IRI`, `/store?default`, or a URL under /store/",
        ));
    };
    blocking(move || {
        let store = knowledge.store()?;
        if !store.drop_graph(&graph)? {
            return Err(ApiError::not_found(format!("graph {graph} does not exist")));
        }
        knowledge.after_write().map_err(ApiError::from)
    })
    .await?;
    Ok(StatusCode::NO_CONTENT.into_response())
}

/// The base IRI of a body: the graph's own IRI, or the request URL for the default graph.
fn base_for(graph: &GraphName, uri: &Uri, headers: &HeaderMap) -> String {
    match graph {
        GraphName::NamedNode(g) => g.as_str().to_owned(),
        GraphName::DefaultGraph | GraphName::BlankNode(_) => {
            format!("{}{}", request_origin(uri, headers), uri.path())
        }
    }
}

fn written(created: bool, location: Option<String>) -> Response {
    if !created {
        return StatusCode::NO_CONTENT.into_response();
    }
    let mut response = StatusCode::CREATED.into_response();
    if let Some(value) = location.and_then(|l| HeaderValue::from_str(&l).ok()) {
        response.headers_mut().insert(LOCATION, value);
    }
    response
}
