//! `/sparql`: the SPARQL 1.1 Protocol's query operation (GET, POST form, POST direct), its
//! update operation (POST form, POST direct), and the service description on a GET without a
//! query.

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::State;
use axum::http::header::{ACCEPT, CONTENT_TYPE, VARY};
use axum::http::{HeaderMap, HeaderValue, StatusCode, Uri};
use axum::response::{IntoResponse, Response};
use edge::{ApiError, Caller, ErrorCode, Principal, Role};
use oxigraph::model::NamedNode;
use spargebra::{GraphUpdateOperation, Query, SparqlParser};

use super::evaluation::{self, EvaluationError, ProtocolDataset};
use super::negotiation::{self, Format, GRAPH_FORMATS};
use super::{Deadline, Params, body_media_type, inline, method_not_allowed, request_origin};
use crate::service::Knowledge;

const FORM: &str = "application/x-www-form-urlencoded";
const SPARQL_QUERY: &str = "application/sparql-query";
const SPARQL_UPDATE: &str = "application/sparql-update";

/// GET: a query in `?query=`, or the service description when there is none.
pub(super) async fn get(
    State(knowledge): State<Arc<Knowledge>>,
    uri: Uri,
    Caller(caller): Caller,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let role = caller.role;
    let params = Params::of_uri(&uri)?;
    if params.contains("update") {
        return Ok(method_not_allowed(
            "POST",
            "a SPARQL update must be sent by POST (form or application/sparql-update), never GET",
        ));
    }
    let endpoint = format!("{}{}", request_origin(&uri, &headers), uri.path());
    match params.at_most_one("query")? {
        Some(query) => answer_query(knowledge, &endpoint, query, &params, &headers, role).await,
        None => super::service_description::answer(&endpoint, &params, &headers),
    }
}

/// POST: a query or an update, URL-encoded in a form or directly as the body.
pub(super) async fn post(
    State(knowledge): State<Arc<Knowledge>>,
    uri: Uri,
    Caller(caller): Caller,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, ApiError> {
    let role = caller.role;
    let mut params = Params::of_uri(&uri)?;
    let endpoint = format!("{}{}", request_origin(&uri, &headers), uri.path());
    let Some((media_type, utf8)) = body_media_type(&headers) else {
        return Err(unsupported_body("no Content-Type"));
    };
    if !utf8 && [FORM, SPARQL_QUERY, SPARQL_UPDATE].contains(&media_type.as_str()) {
        return Err(ApiError::bad_request(
            "the body's charset must be UTF-8, the only encoding SPARQL requests may use",
        ));
    }
    match media_type.as_str() {
        FORM => {
            // The protocol puts every parameter in the body; some clients leave the dataset or
            // format parameters in the URL, so both count (a `query` in each is a duplicate).
            let mut all = Params::parse(&body)?;
            all.extend(params);
            params = all;
            match (params.at_most_one("query")?, params.at_most_one("update")?) {
                (Some(query), None) => {
                    answer_query(knowledge, &endpoint, query, &params, &headers, role).await
                }
                (None, Some(update)) => {
                    apply_update(knowledge, &endpoint, update, &params, caller).await
                }
                (Some(_), Some(_)) => Err(ApiError::bad_request(
                    "the form has both `query` and `update`; send one operation per request",
                )),
                (None, None) => Err(ApiError::bad_request(
                    "the form has neither a `query` nor an `update` parameter",
                )),
            }
        }
        SPARQL_QUERY | SPARQL_UPDATE => {
            if params.contains("query") || params.contains("update") {
                return Err(ApiError::bad_request(
                    "the operation is in the body; the URL must not carry `query` or `update` too",
                ));
            }
            let text = std::str::from_utf8(&body)
                .map_err(|e| ApiError::bad_request(format!("the body is not UTF-8: {e}")))?;
            if media_type == SPARQL_QUERY {
                answer_query(knowledge, &endpoint, text, &params, &headers, role).await
            } else {
                apply_update(knowledge, &endpoint, text, &params, caller).await
            }
        }
        other => Err(unsupported_body(&format!("Content-Type `{other}`"))),
    }
}

fn unsupported_body(what: &str) -> ApiError {
    ApiError::new(
        ErrorCode::UnsupportedMediaType,
        format!(
            "{what}: POST a query or update as {FORM}, a query as {SPARQL_QUERY}, or an update as \
             {SPARQL_UPDATE}"
        ),
    )
}

async fn answer_query(
    knowledge: Arc<Knowledge>,
    endpoint: &str,
    text: &str,
    params: &Params,
    headers: &HeaderMap,
    role: Role,
) -> Result<Response, ApiError> {
    let max_query = knowledge.limits.max_query_bytes;
    if text.len() > max_query {
        return Err(ApiError::new(
            ErrorCode::PayloadTooLarge,
            format!(
                "the query is {} bytes; queries are limited to {max_query} (data belongs in an \
                 update or a Graph Store write)",
                text.len()
            ),
        ));
    }
    super::complexity::check_sparql(text).map_err(|m| ApiError::new(ErrorCode::InvalidQuery, m))?;
    // SERVICE makes the store call out to any URL (a remote store would): not for robots.
    if role == Role::Robot && super::complexity::has_keyword(text, "SERVICE") {
        return Err(ApiError::new(
            ErrorCode::Forbidden,
            "robot tokens may not use SERVICE (federated queries call other endpoints); ask \
             an engineer",
        ));
    }
    let query = parser(endpoint)?.parse_query(text).map_err(|e| {
        ApiError::new(
            ErrorCode::InvalidQuery,
            format!("the query does not parse: {e}"),
        )
    })?;
    let accept = headers.get(ACCEPT).and_then(|v| v.to_str().ok());
    let hints = params.format_hints();
    let format =
        match &query {
            Query::Select { .. } => Format::Results(negotiation::results_format(
                accept,
                &hints,
                "a SELECT result",
            )?),
            Query::Ask { .. } => Format::Results(negotiation::results_format(
                accept,
                &hints,
                "an ASK result",
            )?),
            Query::Construct { .. } | Query::Describe { .. } => Format::Rdf(
                negotiation::rdf_format(accept, &hints, GRAPH_FORMATS, "a graph result")?,
            ),
        };
    let content_type = negotiation::content_type(format);
    let dataset = protocol_dataset(params, "default-graph-uri", "named-graph-uri")?;
    let limits = knowledge.limits;
    let max_bytes = limits.result_bytes(role);
    let deadline = Deadline::start(knowledge.reads(), limits.deadline);
    let exceeded = deadline.exceeded();
    let store = knowledge.store_async().await?;
    let body = if let Some(remote) = store.remote_store().cloned() {
        // The deadline is the HTTP client's timeout too; this one also bounds re-serializing.
        let forwarded = evaluation::run_query_remote(
            &remote,
            &query,
            dataset.as_ref(),
            format,
            limits.max_construct_triples,
            max_bytes,
        );
        match tokio::time::timeout(limits.deadline, forwarded).await {
            Err(_elapsed) => return Err(exceeded),
            Ok(result) => result.map_err(|e| evaluation_error(e, &exceeded))?,
        }
    } else {
        // Same text, dataset and format: the same cost as last time, most likely.
        let key = inline::key(&[text, content_type, &format!("{dataset:?}{max_bytes}")]);
        deadline
            .read_remembered(key, move |token| {
                let Some(embedded) = store.embedded() else {
                    return Err(ApiError::internal("the store has no backend"));
                };
                evaluation::run_query(
                    embedded,
                    query.clone(),
                    dataset.as_ref(),
                    format,
                    limits.max_construct_triples,
                    max_bytes,
                    token,
                )
                .map_err(|e| evaluation_error(e, &exceeded))
            })
            .await?
    };
    Ok((
        [
            (CONTENT_TYPE, HeaderValue::from_static(content_type)),
            (VARY, HeaderValue::from_static("accept")),
        ],
        body,
    )
        .into_response())
}

async fn apply_update(
    knowledge: Arc<Knowledge>,
    endpoint: &str,
    text: &str,
    params: &Params,
    caller: Principal,
) -> Result<Response, ApiError> {
    caller.require(Role::Engineer)?;
    knowledge.check_space(text.len() as u64)?;
    super::complexity::check_sparql(text).map_err(|m| ApiError::new(ErrorCode::InvalidQuery, m))?;
    let update = parser(endpoint)?.parse_update(text).map_err(|e| {
        ApiError::new(
            ErrorCode::InvalidQuery,
            format!("the update does not parse: {e}"),
        )
    })?;
    if writes_inferred(&update) {
        return Err(ApiError::new(
            ErrorCode::Conflict,
            format!(
                "<{}> is rebuilt by the service after every write: an update to it would be \
                 lost at once; write the asserted graphs instead",
                crate::graphs::INFERRED_GRAPH
            ),
        ));
    }
    let dataset = protocol_dataset(params, "using-graph-uri", "using-named-graph-uri")?;
    let names_its_own_dataset = update.operations.iter().any(|operation| {
        matches!(
            operation,
            GraphUpdateOperation::DeleteInsert { using: Some(_), .. }
        )
    });
    if dataset.is_some() && names_its_own_dataset {
        return Err(ApiError::bad_request(
            "using-graph-uri/using-named-graph-uri cannot be combined with an update that has \
             its own USING or WITH clause",
        ));
    }
    let deadline = Deadline::start(knowledge.reads(), knowledge.limits.deadline);
    let (token, exceeded) = (deadline.token(), deadline.exceeded());
    let store = knowledge.store_async().await?;
    if let Some(remote) = store.remote_store().cloned() {
        // A task of its own: once sent, the update and the inference rebuild after it run to
        // the end even if the client goes away.
        let limit = knowledge.limits.deadline;
        let task = tokio::spawn(async move {
            let forwarded = evaluation::run_update_remote(&remote, &update, dataset.as_ref());
            let outcome = match tokio::time::timeout(limit, forwarded).await {
                Err(_elapsed) => Err(exceeded.clone()),
                Ok(result) => result.map_err(|e| evaluation_error(e, &exceeded)),
            };
            // Also after a failure: the remote may have applied part of it, or all of it
            // just as the deadline passed.
            let rebuilt =
                super::blocking(move || knowledge.after_write().map_err(ApiError::from)).await;
            outcome.and(rebuilt)
        });
        task.await
            .map_err(|e| ApiError::internal(format!("update task failed: {e}")))??;
        return Ok(StatusCode::NO_CONTENT.into_response());
    }
    deadline
        .write(move || {
            let Some(embedded) = store.embedded() else {
                return Err(ApiError::internal("the store has no backend"));
            };
            evaluation::run_update(embedded, update, dataset.as_ref(), token).map_err(|e| {
                if let EvaluationError::Storage(message) = &e {
                    store.note_failure(message);
                }
                evaluation_error(e, &exceeded)
            })?;
            knowledge.after_write().map_err(ApiError::from)
        })
        .await?;
    Ok(StatusCode::NO_CONTENT.into_response())
}

/// Whether `update` names the inferred graph as one it writes (reading it in WHERE is fine).
fn writes_inferred(update: &spargebra::Update) -> bool {
    use spargebra::algebra::GraphTarget;
    use spargebra::term::{GraphName, GraphNamePattern};
    let inferred = |n: &NamedNode| n.as_str() == crate::graphs::INFERRED_GRAPH;
    let name = |g: &GraphName| matches!(g, GraphName::NamedNode(n) if inferred(n));
    let pattern = |g: &GraphNamePattern| matches!(g, GraphNamePattern::NamedNode(n) if inferred(n));
    update.operations.iter().any(|operation| match operation {
        GraphUpdateOperation::InsertData { data } => data.iter().any(|q| name(&q.graph_name)),
        GraphUpdateOperation::DeleteData { data } => data.iter().any(|q| name(&q.graph_name)),
        GraphUpdateOperation::DeleteInsert { delete, insert, .. } => {
            delete.iter().any(|q| pattern(&q.graph_name))
                || insert.iter().any(|q| pattern(&q.graph_name))
        }
        GraphUpdateOperation::Load { destination, .. } => name(destination),
        GraphUpdateOperation::Clear { graph, .. } | GraphUpdateOperation::Drop { graph, .. } => {
            matches!(graph, GraphTarget::NamedNode(n) if inferred(n))
        }
        GraphUpdateOperation::Create { graph, .. } => inferred(graph),
    })
}

/// The parser for operations sent to `endpoint`, which is also their base IRI (the protocol
/// lets the service choose it, and the endpoint is the natural one).
fn parser(endpoint: &str) -> Result<SparqlParser, ApiError> {
    SparqlParser::new().with_base_iri(endpoint).map_err(|e| {
        ApiError::bad_request(format!(
            "the request URL `{endpoint}` is not a usable base IRI: {e}"
        ))
    })
}

/// The dataset named by two protocol parameters, each repeatable.
fn protocol_dataset(
    params: &Params,
    default_name: &str,
    named_name: &str,
) -> Result<Option<ProtocolDataset>, ApiError> {
    let iris = |name: &str| -> Result<Vec<NamedNode>, ApiError> {
        params
            .all(name)
            .map(|value| {
                NamedNode::new(value).map_err(|e| {
                    ApiError::bad_request(format!(
                        "`{name}` value `{value}` is not an absolute IRI: {e}"
                    ))
                })
            })
            .collect()
    };
    Ok(ProtocolDataset::from_iris(
        &iris(default_name)?,
        &iris(named_name)?,
    ))
}

/// The HTTP error for an evaluation failure; `exceeded` is the deadline's own message.
pub(super) fn evaluation_error(e: EvaluationError, exceeded: &ApiError) -> ApiError {
    match e {
        EvaluationError::Cancelled => exceeded.clone(),
        EvaluationError::TooLarge { limit } => ApiError::new(
            ErrorCode::ResultTooLarge,
            format!(
                "the result has more than {limit} triples, the configured cap; narrow the query \
                 or add a LIMIT"
            ),
        ),
        EvaluationError::TooManyBytes { limit } => ApiError::new(
            ErrorCode::ResultTooLarge,
            format!(
                "the answer is larger than {limit} bytes, the cap of this token's role; narrow \
                 the query or page it with LIMIT/OFFSET"
            ),
        ),
        EvaluationError::Invalid(message) => ApiError::new(ErrorCode::InvalidQuery, message),
        EvaluationError::Conflict(message) => ApiError::new(ErrorCode::Conflict, message),
        EvaluationError::NotFound(message) => ApiError::not_found(message),
        e @ EvaluationError::Unserializable { .. } => {
            ApiError::new(ErrorCode::NotAcceptable, e.to_string())
        }
        EvaluationError::Storage(message) => ApiError::internal(message),
        EvaluationError::Remote(crate::StoreError::TimedOut { .. }) => exceeded.clone(),
        EvaluationError::Remote(crate::StoreError::Remote {
            url,
            status,
            message,
        }) if (400..500).contains(&status) => ApiError::new(
            ErrorCode::InvalidQuery,
            format!("the graph store at {url} refused the operation ({status}): {message}"),
        ),
        EvaluationError::Remote(e) => ApiError::from(e),
    }
}
