//! A SPARQL 1.1 store reached over the SPARQL 1.1 Protocol: queries POSTed as
//! `application/sparql-query`, updates as `application/sparql-update`, dataset parameters in
//! the URL. Nothing store-specific: an Oxigraph server, Fuseki, GraphDB, Virtuoso or Neptune
//! all speak it.
//!
//! Besides the protocol calls, it implements the whole-graph writes of
//! [`KnowledgeStore`](crate::store::KnowledgeStore) as single SPARQL updates (the embedded
//! backend's transactions).
//!
//! The HTTP client is reqwest's async one. The SPARQL endpoint awaits it directly; the blocking
//! code of the crate (graph walks, inference, imports, running on `spawn_blocking` threads)
//! waits on it through the runtime's handle.
//!
//! Reads that walk the graph (places, robots, on-demand databases) use [`RemoteStore::snapshot`]:
//! an in-memory Oxigraph copy of the remote dataset, fetched with one SELECT and kept while the
//! version marker the service writes on every write stays the same, so a read costs one small
//! query to the remote, not one per triple pattern. Writes that bypass the service are seen
//! once the copy is older than [`SNAPSHOT_MAX_AGE`].

use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

use axum::body::Bytes;
use oxigraph::model::{
    GraphName, Literal, NamedNode, NamedNodeRef, NamedOrBlankNode, Quad, Term, Triple,
};
use oxigraph::sparql::results::{
    QueryResultsFormat, QueryResultsParser, SliceQueryResultsParserOutput,
};
use oxigraph::store::Store;

use crate::graphs::INFERRED_GRAPH;
use crate::store::error::StoreError;

/// How long a snapshot of the remote is used at most, even when the version marker did not
/// change: the bound on how stale a write that bypassed the service can look.
pub const SNAPSHOT_MAX_AGE: Duration = Duration::from_secs(30);

/// The predicate of the version marker, written in the inferred graph on every rebuild.
pub const VERSION: NamedNodeRef<'static> =
    NamedNodeRef::new_unchecked("https://mentalsim.dev/ontology/service#version");

/// Where the remote store is.
#[derive(Debug, Clone, PartialEq)]
pub struct RemoteConfig {
    /// The SPARQL query endpoint. A bare origin (`http://host:7878`) means an Oxigraph
    /// server's layout: `/query` and `/update` below it.
    pub url: String,
    /// The update endpoint [default: `…/update` beside a `…/query` URL, else the query URL].
    pub update_url: Option<String>,
    /// Deadline of each request to the remote.
    pub timeout: Duration,
}

impl RemoteConfig {
    /// The query and update endpoints this configuration names.
    pub fn endpoints(&self) -> (String, String) {
        let url = self.url.trim_end_matches('/').to_owned();
        let after_scheme = url.split_once("://").map_or(url.as_str(), |(_, rest)| rest);
        let (query, derived_update) = if !after_scheme.contains('/') {
            (format!("{url}/query"), format!("{url}/update"))
        } else if let Some(base) = url.strip_suffix("/query") {
            (url.clone(), format!("{base}/update"))
        } else {
            (url.clone(), url.clone())
        };
        (query, self.update_url.clone().unwrap_or(derived_update))
    }
}

struct Snapshot {
    store: Store,
    version: Option<String>,
    fetched: Instant,
}

/// A remote SPARQL 1.1 store.
pub struct RemoteStore {
    /// The endpoints as shown in logs and errors: user info replaced by `***`.
    query_display: String,
    update_display: String,
    query_url: String,
    update_url: String,
    timeout: Duration,
    client: reqwest::Client,
    runtime: tokio::runtime::Handle,
    snapshot: Mutex<Option<Snapshot>>,
    /// Counts snapshots installed: what was derived from an older one is stale.
    serial: std::sync::atomic::AtomicU64,
    /// Held while a snapshot downloads, so concurrent readers wait for one download.
    loading: Mutex<()>,
}

impl std::fmt::Debug for RemoteStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RemoteStore")
            .field("query_url", &redact(&self.query_url))
            .field("update_url", &redact(&self.update_url))
            .finish_non_exhaustive()
    }
}

/// Media types asked for when the service reads solutions itself: TSV is the most compact, the
/// others are there for stores that do not write it.
const SOLUTIONS_ACCEPT: &str = "text/tab-separated-values, application/sparql-results+json;q=0.9, \
                                application/sparql-results+xml;q=0.8";

impl RemoteStore {
    /// A client for the remote. Must be called inside a tokio runtime.
    pub fn new(config: RemoteConfig) -> Result<Self, StoreError> {
        let (query_url, update_url) = config.endpoints();
        let (query_display, update_display) = (redact(&query_url), redact(&update_url));
        let fail = |message: String| StoreError::Query {
            location: query_display.clone(),
            message,
        };
        let runtime = tokio::runtime::Handle::try_current()
            .map_err(|e| fail(format!("a remote store needs a tokio runtime: {e}")))?;
        let client = reqwest::Client::builder()
            .timeout(config.timeout)
            .connect_timeout(config.timeout.min(Duration::from_secs(10)))
            .pool_max_idle_per_host(64)
            .build()
            .map_err(|e| fail(format!("cannot build the HTTP client: {e}")))?;
        Ok(Self {
            query_url,
            update_url,
            query_display,
            update_display,
            timeout: config.timeout,
            client,
            runtime,
            snapshot: Mutex::new(None),
            serial: std::sync::atomic::AtomicU64::new(0),
            loading: Mutex::new(()),
        })
    }

    /// How many snapshots were installed so far.
    pub fn snapshot_serial(&self) -> u64 {
        self.serial.load(std::sync::atomic::Ordering::SeqCst)
    }

    /// The query endpoint, as shown in logs and errors (credentials replaced by `***`).
    pub fn shown_query_url(&self) -> &str {
        &self.query_display
    }

    /// The update endpoint, as shown (credentials replaced by `***`).
    pub fn shown_update_url(&self) -> &str {
        &self.update_display
    }

    fn transport_error(&self, url: &str, e: reqwest::Error) -> StoreError {
        let url = &redact(url);
        // reqwest's message would repeat the URL, credentials and all.
        let e = &e.without_url();
        if e.is_timeout() {
            StoreError::TimedOut {
                url: url.to_owned(),
                seconds: self.timeout.as_secs_f64(),
            }
        } else {
            // The source chain says what really failed (refused, reset, DNS).
            let mut message = e.to_string();
            let mut source = std::error::Error::source(e);
            while let Some(cause) = source {
                message.push_str(": ");
                message.push_str(&cause.to_string());
                source = cause.source();
            }
            StoreError::Unavailable {
                url: url.to_owned(),
                message,
            }
        }
    }

    async fn send(
        &self,
        url: &str,
        request: reqwest::RequestBuilder,
    ) -> Result<(Option<String>, Bytes), StoreError> {
        let response = request
            .send()
            .await
            .map_err(|e| self.transport_error(url, e))?;
        let status = response.status();
        let content_type = response
            .headers()
            .get(reqwest::header::CONTENT_TYPE)
            .and_then(|v| v.to_str().ok())
            .map(str::to_owned);
        let body = response
            .bytes()
            .await
            .map_err(|e| self.transport_error(url, e))?;
        if !status.is_success() {
            let text = String::from_utf8_lossy(&body);
            let message: String = text.trim().chars().take(500).collect();
            return Err(StoreError::Remote {
                url: redact(url),
                status: status.as_u16(),
                message,
            });
        }
        Ok((content_type, body))
    }

    /// Sends `query` with the dataset `params` (`default-graph-uri`, `named-graph-uri`),
    /// asking for `accept`. Answers the body and its media type.
    pub async fn query(
        &self,
        query: &str,
        params: &[(&str, &str)],
        accept: &str,
    ) -> Result<(Option<String>, Bytes), StoreError> {
        let request = self
            .client
            .post(&self.query_url)
            .query(params)
            .header(reqwest::header::ACCEPT, accept)
            .header(reqwest::header::CONTENT_TYPE, "application/sparql-query")
            .body(query.to_owned());
        self.send(&self.query_url, request).await
    }

    /// Sends `update` with the dataset `params` (`using-graph-uri`, `using-named-graph-uri`).
    pub async fn update_async(
        &self,
        update: &str,
        params: &[(&str, &str)],
    ) -> Result<(), StoreError> {
        let request = self
            .client
            .post(&self.update_url)
            .query(params)
            .header(reqwest::header::CONTENT_TYPE, "application/sparql-update")
            .body(update.to_owned());
        self.send(&self.update_url, request).await.map(drop)
    }

    /// Waits for `future` on this blocking thread.
    fn block<F: Future>(&self, future: F) -> F::Output {
        self.runtime.block_on(future)
    }

    /// Applies `update`. Blocking.
    pub fn update(&self, update: &str) -> Result<(), StoreError> {
        self.block(self.update_async(update, &[]))
    }

    /// Evaluates an ASK query. Blocking.
    pub fn ask(&self, query: &str) -> Result<bool, StoreError> {
        let (content_type, body) = self.block(self.query(
            query,
            &[],
            "application/sparql-results+json, application/sparql-results+xml;q=0.9",
        ))?;
        match self.parse_results(content_type.as_deref(), &body)? {
            SliceQueryResultsParserOutput::Boolean(b) => Ok(b),
            SliceQueryResultsParserOutput::Solutions(_) => {
                Err(self.bad_answer("ASK answered solutions"))
            }
        }
    }

    /// Runs a trivial query on the remote's endpoint. Blocking.
    pub(crate) fn check(&self) -> Result<(), StoreError> {
        self.ask("ASK { ?s ?p ?o }").map(drop)
    }

    /// Whether the remote holds no triple in any graph. Blocking.
    pub(crate) fn is_empty(&self) -> Result<bool, StoreError> {
        self.ask("ASK { { ?s ?p ?o } UNION { GRAPH ?g { ?s ?p ?o } } }")
            .map(|any| !any)
    }

    /// Whether the named graph `graph` exists. Blocking.
    pub(crate) fn contains_named_graph(&self, graph: NamedNodeRef<'_>) -> Result<bool, StoreError> {
        self.ask(&format!("ASK {{ GRAPH {graph} {{ }} }}"))
    }

    /// Adds `quads` in one update. Blocking.
    pub(crate) fn insert(&self, quads: &[Quad]) -> Result<(), StoreError> {
        self.update(&insert_data(quads))
    }

    /// The content of `graph` becomes `quads`, in one update; returns whether a named graph
    /// was created. Blocking.
    pub(crate) fn replace_graph(
        &self,
        graph: &GraphName,
        quads: &[Quad],
    ) -> Result<bool, StoreError> {
        let (created, mut update) = match graph {
            GraphName::NamedNode(g) => (
                !self.contains_named_graph(g.as_ref())?,
                format!("DROP SILENT GRAPH {g} ;\nCREATE SILENT GRAPH {g} ;\n"),
            ),
            GraphName::DefaultGraph | GraphName::BlankNode(_) => {
                (false, "CLEAR SILENT DEFAULT ;\n".to_owned())
            }
        };
        update.push_str(&insert_data(quads));
        self.update(&update)?;
        Ok(created)
    }

    /// Adds `quads` to `graph`, creating it if needed, in one update; returns whether it was
    /// created. Blocking.
    pub(crate) fn merge_into_graph(
        &self,
        graph: &GraphName,
        quads: &[Quad],
    ) -> Result<bool, StoreError> {
        let (created, mut update) = match graph {
            GraphName::NamedNode(g) => (
                !self.contains_named_graph(g.as_ref())?,
                format!("CREATE SILENT GRAPH {g} ;\n"),
            ),
            GraphName::DefaultGraph | GraphName::BlankNode(_) => (false, String::new()),
        };
        update.push_str(&insert_data(quads));
        self.update(&update)?;
        Ok(created)
    }

    /// Drops a named graph (returns whether it existed) or empties the default graph
    /// (returns true). Blocking.
    pub(crate) fn drop_graph(&self, graph: &GraphName) -> Result<bool, StoreError> {
        match graph {
            GraphName::NamedNode(g) => {
                if !self.contains_named_graph(g.as_ref())? {
                    return Ok(false);
                }
                self.update(&format!("DROP SILENT GRAPH {g}"))?;
                Ok(true)
            }
            _ => {
                self.update("CLEAR SILENT DEFAULT")?;
                Ok(true)
            }
        }
    }

    /// In `graph`, removes every triple whose subject is one of `subjects`, then adds `quads`,
    /// in one update. Returns whether anything was removed. Blocking.
    pub(crate) fn replace_subjects(
        &self,
        graph: NamedNodeRef<'_>,
        subjects: &[NamedNode],
        quads: &[Quad],
    ) -> Result<bool, StoreError> {
        let values: String = subjects.iter().map(|s| format!("{s} ")).collect();
        let pattern = format!("GRAPH {graph} {{ VALUES ?s {{ {values}}} ?s ?p ?o }}");
        let existed = self.ask(&format!("ASK {{ {pattern} }}"))?;
        let mut update =
            format!("DELETE {{ GRAPH {graph} {{ ?s ?p ?o }} }} WHERE {{ {pattern} }} ;\n");
        update.push_str(&insert_data(quads));
        self.update(&update)?;
        Ok(existed)
    }

    fn bad_answer(&self, message: impl Into<String>) -> StoreError {
        StoreError::Query {
            location: self.query_display.clone(),
            message: message.into(),
        }
    }

    fn parse_results<'a>(
        &self,
        content_type: Option<&str>,
        body: &'a [u8],
    ) -> Result<SliceQueryResultsParserOutput<'a>, StoreError> {
        let format = content_type
            .and_then(QueryResultsFormat::from_media_type)
            .ok_or_else(|| {
                self.bad_answer(format!(
                    "the answer's media type {content_type:?} is not a SPARQL results format"
                ))
            })?;
        QueryResultsParser::from_format(format)
            .for_slice(body)
            .map_err(|e| self.bad_answer(format!("unreadable SPARQL results: {e}")))
    }

    /// Every quad of the dataset (`graph` `None`), or the triples of one graph placed in that
    /// graph, at most `limit` of them (`None`: all). Blocking.
    pub fn quads(
        &self,
        graph: Option<&GraphName>,
        limit: Option<usize>,
    ) -> Result<Vec<Quad>, StoreError> {
        let limit = limit.map(|l| format!(" LIMIT {l}")).unwrap_or_default();
        let query = match graph {
            None => format!(
                "SELECT ?s ?p ?o ?g WHERE {{ {{ ?s ?p ?o }} UNION {{ GRAPH ?g {{ ?s ?p ?o }} }} }}{limit}"
            ),
            Some(GraphName::NamedNode(g)) => {
                format!("SELECT ?s ?p ?o WHERE {{ GRAPH {g} {{ ?s ?p ?o }} }}{limit}")
            }
            Some(_) => format!("SELECT ?s ?p ?o WHERE {{ ?s ?p ?o }}{limit}"),
        };
        let (content_type, body) = self.block(self.query(&query, &[], SOLUTIONS_ACCEPT))?;
        let SliceQueryResultsParserOutput::Solutions(solutions) =
            self.parse_results(content_type.as_deref(), &body)?
        else {
            return Err(self.bad_answer("SELECT answered a boolean"));
        };
        let mut out = Vec::new();
        for solution in solutions {
            let solution =
                solution.map_err(|e| self.bad_answer(format!("unreadable SPARQL results: {e}")))?;
            let subject = match solution.get("s") {
                Some(Term::NamedNode(n)) => NamedOrBlankNode::from(n.clone()),
                Some(Term::BlankNode(b)) => NamedOrBlankNode::from(b.clone()),
                _ => continue,
            };
            let Some(Term::NamedNode(predicate)) = solution.get("p") else {
                continue;
            };
            let Some(object) = solution.get("o") else {
                continue;
            };
            let graph_name = match (graph, solution.get("g")) {
                (Some(g), _) => g.clone(),
                (None, Some(Term::NamedNode(g))) => GraphName::NamedNode(g.clone()),
                (None, Some(Term::BlankNode(g))) => GraphName::BlankNode(g.clone()),
                (None, _) => GraphName::DefaultGraph,
            };
            out.push(Quad::new(
                subject,
                predicate.clone(),
                object.clone(),
                graph_name,
            ));
        }
        Ok(out)
    }

    /// The version marker in the inferred graph (`None` before the service wrote one).
    /// Blocking.
    pub fn version(&self) -> Result<Option<String>, StoreError> {
        let query = format!(
            "SELECT ?v WHERE {{ GRAPH {INFERRED_GRAPH} {{ {INFERRED_GRAPH} {VERSION} ?v }} }}"
        );
        let (content_type, body) = self.block(self.query(&query, &[], SOLUTIONS_ACCEPT))?;
        let SliceQueryResultsParserOutput::Solutions(mut solutions) =
            self.parse_results(content_type.as_deref(), &body)?
        else {
            return Err(self.bad_answer("SELECT answered a boolean"));
        };
        match solutions.next() {
            Some(Ok(solution)) => Ok(match solution.get("v") {
                Some(Term::Literal(l)) => Some(l.value().to_owned()),
                _ => None,
            }),
            Some(Err(e)) => Err(self.bad_answer(format!("unreadable SPARQL results: {e}"))),
            None => Ok(None),
        }
    }

    /// An in-memory copy of the remote dataset, reused while the version marker is unchanged
    /// and the copy younger than [`SNAPSHOT_MAX_AGE`]. Blocking.
    pub fn snapshot(&self) -> Result<Store, StoreError> {
        let version = self.version()?;
        if let Some(store) = self.fresh_snapshot(&version) {
            return Ok(store);
        }
        let _loading = self.loading.lock().unwrap_or_else(PoisonError::into_inner);
        // Another reader may have loaded it while this one waited.
        if let Some(store) = self.fresh_snapshot(&version) {
            return Ok(store);
        }
        let quads = self.quads(None, None)?;
        self.install_snapshot(&quads, version)
    }

    fn fresh_snapshot(&self, version: &Option<String>) -> Option<Store> {
        let slot = self.snapshot.lock().unwrap_or_else(PoisonError::into_inner);
        slot.as_ref()
            .filter(|s| &s.version == version && s.fetched.elapsed() < SNAPSHOT_MAX_AGE)
            .map(|s| s.store.clone())
    }

    /// Makes `quads` the snapshot for `version`.
    fn install_snapshot(
        &self,
        quads: &[Quad],
        version: Option<String>,
    ) -> Result<Store, StoreError> {
        let storage = |source| StoreError::Storage {
            location: self.query_display.clone(),
            source,
        };
        let store = Store::new().map_err(storage)?;
        let mut transaction = store.start_transaction().map_err(storage)?;
        transaction.extend(quads);
        transaction.commit().map_err(storage)?;
        *self.snapshot.lock().unwrap_or_else(PoisonError::into_inner) = Some(Snapshot {
            store: store.clone(),
            version,
            fetched: Instant::now(),
        });
        self.serial
            .fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        Ok(store)
    }

    /// Replaces the remote's inferred graph by `inferred` plus a new version marker, in one
    /// update, and makes `asserted` + that graph the snapshot. Triples with blank nodes are
    /// left out: a blank node of the remote cannot be named in a request. Blocking.
    pub(crate) fn write_inferred(
        &self,
        asserted: Vec<Quad>,
        inferred: &[Triple],
    ) -> Result<usize, StoreError> {
        let version = uuid::Uuid::new_v4().to_string();
        let mut quads: Vec<Quad> = inferred
            .iter()
            .filter(|t| !t.subject.is_blank_node() && !t.object.is_blank_node())
            .map(|t| t.clone().in_graph(INFERRED_GRAPH))
            .collect();
        let written = quads.len();
        quads.push(Quad::new(
            INFERRED_GRAPH.into_owned(),
            VERSION.into_owned(),
            Literal::new_simple_literal(&version),
            INFERRED_GRAPH.into_owned(),
        ));
        let mut update = format!("DROP SILENT GRAPH {INFERRED_GRAPH} ;\n");
        update.push_str(&insert_data(&quads));
        self.update(&update)?;
        let mut all = asserted;
        all.extend(quads);
        self.install_snapshot(&all, Some(version))?;
        Ok(written)
    }
}

/// `INSERT DATA { … }` for `quads`, grouped by graph, terms in their N-Triples form (which
/// SPARQL reads as is). Blank nodes keep their labels, so within one request they stay one
/// node each.
fn insert_data(quads: &[Quad]) -> String {
    use std::fmt::Write;
    let mut out = String::with_capacity(quads.len() * 120 + 32);
    out.push_str("INSERT DATA {\n");
    let mut current: Option<&GraphName> = None;
    for quad in quads {
        if current != Some(&quad.graph_name) {
            if matches!(current, Some(GraphName::NamedNode(_))) {
                out.push_str("}\n");
            }
            if let GraphName::NamedNode(g) = &quad.graph_name {
                let _ = writeln!(out, "GRAPH {g} {{");
            }
            current = Some(&quad.graph_name);
        }
        let _ = writeln!(out, "{} {} {} .", quad.subject, quad.predicate, quad.object);
    }
    if matches!(current, Some(GraphName::NamedNode(_))) {
        out.push_str("}\n");
    }
    out.push('}');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn endpoints(url: &str) -> (String, String) {
        RemoteConfig {
            url: url.to_owned(),
            update_url: None,
            timeout: Duration::from_secs(1),
        }
        .endpoints()
    }

    #[test]
    fn endpoints_follow_the_common_layouts() {
        assert_eq!(
            endpoints("http://h:7878"),
            ("http://h:7878/query".into(), "http://h:7878/update".into())
        );
        assert_eq!(
            endpoints("http://h:7878/"),
            ("http://h:7878/query".into(), "http://h:7878/update".into())
        );
        assert_eq!(
            endpoints("http://h/ds/query"),
            ("http://h/ds/query".into(), "http://h/ds/update".into())
        );
        assert_eq!(
            endpoints("https://h/sparql"),
            ("https://h/sparql".into(), "https://h/sparql".into())
        );
        let explicit = RemoteConfig {
            url: "http://h/repositories/x".into(),
            update_url: Some("http://h/repositories/x/statements".into()),
            timeout: Duration::from_secs(1),
        };
        assert_eq!(explicit.endpoints().1, "http://h/repositories/x/statements");
    }

    #[test]
    fn insert_data_round_trips_through_an_update() {
        let g = NamedNode::new("http://example.org/g").unwrap();
        let turtle =
            "@prefix : <http://example.org/> . :a :p \"x\\\"y\\n\"@en , [ :q 1 ] . :b :r :c .";
        let quads = oxigraph::io::RdfParser::from_format(oxigraph::io::RdfFormat::Turtle)
            .rename_blank_nodes()
            .with_default_graph(g.as_ref())
            .for_slice(turtle.as_bytes())
            .collect::<Result<Vec<_>, _>>()
            .unwrap();
        let mut all = quads.clone();
        all.push(Quad::new(
            NamedNode::new("http://example.org/d").unwrap(),
            NamedNode::new("http://example.org/p").unwrap(),
            Literal::from(2.5),
            GraphName::DefaultGraph,
        ));
        let store = Store::new().unwrap();
        store.update(insert_data(&all).as_str()).unwrap();
        assert_eq!(store.len().unwrap(), all.len());
        let blank_links = store
            .quads_for_pattern(None, None, None, Some(g.as_ref().into()))
            .filter(|q| q.as_ref().unwrap().object.is_blank_node())
            .count();
        assert_eq!(blank_links, 1);
    }
}

/// `url` with any user name and password replaced by `***`, for logs and error messages.
pub fn redact(url: &str) -> String {
    match reqwest::Url::parse(url) {
        Ok(mut u) if !u.username().is_empty() || u.password().is_some() => {
            let _ = u.set_username("***");
            let _ = u.set_password(None);
            u.to_string()
        }
        Ok(_) => url.to_owned(),
        Err(_) => "(an unparsable URL)".to_owned(),
    }
}

#[cfg(test)]
mod redaction_tests {
    #[test]
    fn credentials_never_reach_the_shown_url() {
        let shown = super::redact("http://alice:s3cret@store.example:7878/query");
        assert_eq!(shown, "http://***@store.example:7878/query");
        assert_eq!(
            super::redact("http://store:7878/query"),
            "http://store:7878/query"
        );
    }
}
