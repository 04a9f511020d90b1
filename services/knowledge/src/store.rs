//! The graph store: one interface, two implementations.
//!
//! - **Embedded**: Oxigraph in this process, on RocksDB under the data directory (or in memory
//!   for tests and tools). Reads go straight to it.
//! - **Remote**: any SPARQL 1.1 store reached over the SPARQL 1.1 Protocol (an Oxigraph server,
//!   Fuseki, GraphDB, Virtuoso, Neptune), see [`crate::remote`]. Queries and updates sent to
//!   `/sparql` are forwarded; writes the service makes itself become SPARQL updates; the graph
//!   walks of the REST API (places, robots, on-demand databases) read a local in-memory copy
//!   of the remote dataset that is reused while the remote's version marker is unchanged.
//!
//! Everything the rest of the crate does with the store goes through the methods below, which
//! are blocking (call them from `spawn_blocking`); the SPARQL endpoint's hot path talks to the
//! remote asynchronously through [`KnowledgeStore::remote`].

use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use oxigraph::io::{RdfFormat, RdfParser};
use oxigraph::model::{GraphName, GraphNameRef, NamedNode, NamedNodeRef, Quad};
use oxigraph::store::Store;

use tosm::Place;

use crate::remote::{RemoteConfig, RemoteStore};

/// Why the store could not be opened or used.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// Oxigraph refused to open or query its directory.
    #[error("graph store at {location}: {source}")]
    Storage {
        /// The store directory, or the remote's URL.
        location: String,
        /// Oxigraph's error.
        #[source]
        source: oxigraph::store::StorageError,
    },
    /// A query the service runs itself failed to evaluate or to parse.
    #[error("graph store at {location}: {message}")]
    Query {
        /// The store directory, or the remote's URL.
        location: String,
        /// What went wrong.
        message: String,
    },
    /// The remote store cannot be reached (connection refused, DNS, TLS).
    #[error("graph store at {url} is unreachable: {message}")]
    Unavailable {
        /// The endpoint that was called.
        url: String,
        /// What the HTTP client said.
        message: String,
    },
    /// The remote store did not answer within the deadline.
    #[error("graph store at {url} did not answer within {seconds} s")]
    TimedOut {
        /// The endpoint that was called.
        url: String,
        /// The deadline.
        seconds: f64,
    },
    /// The remote store answered with an error status.
    #[error("graph store at {url} answered {status}: {message}")]
    Remote {
        /// The endpoint that was called.
        url: String,
        /// Its HTTP status.
        status: u16,
        /// The start of its error body.
        message: String,
    },
}

impl From<StoreError> for edge::ApiError {
    /// A remote that cannot be reached is 503 `not_ready`, one that timed out 503 `timeout`,
    /// one that answered an error 502 `bad_gateway`, each naming the remote; a local storage
    /// fault is 500 `internal`.
    fn from(e: StoreError) -> Self {
        use edge::{ApiError, ErrorCode};
        match &e {
            StoreError::Unavailable { .. } => ApiError::new(ErrorCode::NotReady, e.to_string()),
            StoreError::TimedOut { .. } => ApiError::new(ErrorCode::Timeout, e.to_string()),
            StoreError::Remote { .. } => ApiError::new(ErrorCode::BadGateway, e.to_string()),
            StoreError::Storage { .. } | StoreError::Query { .. } => ApiError::internal(e),
        }
    }
}

#[derive(Clone)]
enum Backend {
    Embedded(Store),
    Remote(Arc<RemoteStore>),
}

/// The knowledge graph. Cloning is cheap (both backends are reference-counted).
#[derive(Clone)]
pub struct KnowledgeStore {
    backend: Backend,
    location: String,
    derived: Arc<Derived>,
}

/// What the service derives from the graph and keeps until the next write: the typed places
/// every on-demand database and place lookup starts from (reading them decodes every floor's
/// map, which on a large building costs far more than the rest of a request).
struct Derived {
    /// Numbers the stores of this process, for [`KnowledgeStore::state_tag`].
    id: u64,
    /// Bumped after every write through the service (see [`crate::inference::refresh`]).
    generation: AtomicU64,
    places: Mutex<Option<(CacheKey, Arc<Vec<Place>>)>>,
}

impl Default for Derived {
    fn default() -> Self {
        static STORES: AtomicU64 = AtomicU64::new(0);
        Self {
            id: STORES.fetch_add(1, Ordering::Relaxed),
            generation: AtomicU64::new(0),
            places: Mutex::new(None),
        }
    }
}

/// A random name of this process, for [`KnowledgeStore::state_tag`].
fn process_tag() -> &'static str {
    static TAG: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TAG.get_or_init(|| uuid::Uuid::new_v4().simple().to_string()[..12].to_owned())
}

/// Identifies one state of the graph: the write generation, and for a remote store the
/// snapshot it was read from.
pub(crate) type CacheKey = (u64, u64);

impl std::fmt::Debug for KnowledgeStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KnowledgeStore")
            .field("location", &self.location)
            .finish_non_exhaustive()
    }
}

impl KnowledgeStore {
    /// Opens (creating if needed) the store in `path`. Blocking: call from `spawn_blocking`.
    #[cfg(feature = "rocksdb")]
    pub fn open(path: &Path) -> Result<Self, StoreError> {
        let location = path.display().to_string();
        let store = Store::open(path).map_err(|source| StoreError::Storage {
            location: location.clone(),
            source,
        })?;
        Ok(Self {
            backend: Backend::Embedded(store),
            location,
            derived: Arc::default(),
        })
    }

    /// Opening on disk needs the `rocksdb` feature; without it this is an error.
    #[cfg(not(feature = "rocksdb"))]
    pub fn open(path: &Path) -> Result<Self, StoreError> {
        Err(StoreError::Query {
            location: path.display().to_string(),
            message: "this build has no on-disk store (feature `rocksdb`)".to_owned(),
        })
    }

    /// A store in memory, gone when dropped: for tests and throwaway tools.
    pub fn in_memory() -> Result<Self, StoreError> {
        let location = ":memory:".to_owned();
        let store = Store::new().map_err(|source| StoreError::Storage {
            location: location.clone(),
            source,
        })?;
        Ok(Self {
            backend: Backend::Embedded(store),
            location,
            derived: Arc::default(),
        })
    }

    /// A remote SPARQL 1.1 store. Makes no request: [`Self::check`] tells whether it answers.
    /// Must be called inside a tokio runtime (its HTTP client lives there).
    pub fn remote(config: RemoteConfig) -> Result<Self, StoreError> {
        let remote = RemoteStore::new(config)?;
        Ok(Self {
            location: remote.query_url().to_owned(),
            backend: Backend::Remote(Arc::new(remote)),
            derived: Arc::default(),
        })
    }

    /// Runs a trivial query through the whole stack (parser, evaluator, RocksDB iterator; or
    /// the remote's endpoint). Blocking.
    pub fn check(&self) -> Result<(), StoreError> {
        match &self.backend {
            Backend::Embedded(store) => {
                let query_error = |message: String| StoreError::Query {
                    location: self.location.clone(),
                    message: format!("health query failed: {message}"),
                };
                let results = oxigraph::sparql::SparqlEvaluator::new()
                    .parse_query("ASK { ?s ?p ?o }")
                    .map_err(|e| query_error(e.to_string()))?
                    .on_store(store)
                    .execute()
                    .map_err(|e| query_error(e.to_string()))?;
                match results {
                    oxigraph::sparql::QueryResults::Boolean(_) => Ok(()),
                    _ => Err(query_error("ASK did not answer a boolean".to_owned())),
                }
            }
            Backend::Remote(remote) => remote.ask("ASK { ?s ?p ?o }").map(drop),
        }
    }

    /// Where the store lives: its directory, `:memory:`, or the remote's query endpoint.
    pub fn location(&self) -> &str {
        &self.location
    }

    /// The embedded Oxigraph store, when the store is embedded.
    pub fn embedded(&self) -> Option<&Store> {
        match &self.backend {
            Backend::Embedded(store) => Some(store),
            Backend::Remote(_) => None,
        }
    }

    /// The remote store, when the store is remote.
    pub fn remote_store(&self) -> Option<&Arc<RemoteStore>> {
        match &self.backend {
            Backend::Embedded(_) => None,
            Backend::Remote(remote) => Some(remote),
        }
    }

    /// A store to read with Oxigraph's API: the store itself when embedded; for a remote, an
    /// in-memory copy of its dataset, fetched again when the remote's version marker changed
    /// (every write through this service changes it) or the copy is older than
    /// [`crate::remote::SNAPSHOT_MAX_AGE`]. Blocking.
    pub fn snapshot(&self) -> Result<Store, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => Ok(store.clone()),
            Backend::Remote(remote) => remote.snapshot(),
        }
    }

    /// Flushes memtables to disk, for a clean shutdown. Blocking. Nothing to do for a remote.
    pub fn flush(&self) -> Result<(), StoreError> {
        match &self.backend {
            #[cfg(feature = "rocksdb")]
            Backend::Embedded(store) => store.flush().map_err(|e| self.storage(e)),
            #[cfg(not(feature = "rocksdb"))]
            Backend::Embedded(_) => Ok(()),
            Backend::Remote(_) => Ok(()),
        }
    }

    /// Called after every write through the service: what was derived is stale.
    pub(crate) fn bump_generation(&self) {
        self.derived.generation.fetch_add(1, Ordering::SeqCst);
        *self
            .derived
            .places
            .lock()
            .unwrap_or_else(PoisonError::into_inner) = None;
    }

    /// Names the graph's current state: equal tags mean equal content. It changes with every
    /// write through the service and every new snapshot of a remote store, and differs between
    /// processes and between stores of one process, so a tag outlives no restart. Blocking: for
    /// a remote store it asks the store whether its content changed (one small query).
    pub fn state_tag(&self) -> Result<String, StoreError> {
        if let Backend::Remote(remote) = &self.backend {
            remote.snapshot()?;
        }
        let (generation, snapshot) = self.cache_key();
        Ok(format!(
            "{}-{}-{generation}-{snapshot}",
            process_tag(),
            self.derived.id
        ))
    }

    /// The current state's key; take it after [`Self::snapshot`].
    pub(crate) fn cache_key(&self) -> CacheKey {
        let remote = match &self.backend {
            Backend::Embedded(_) => 0,
            Backend::Remote(remote) => remote.snapshot_serial(),
        };
        (self.derived.generation.load(Ordering::SeqCst), remote)
    }

    /// The places read for state `key`, if they are cached.
    pub(crate) fn cached_places(&self, key: CacheKey) -> Option<Arc<Vec<Place>>> {
        let slot = self
            .derived
            .places
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        slot.as_ref()
            .filter(|(k, _)| *k == key)
            .map(|(_, places)| places.clone())
    }

    /// Keeps the places read for state `key`, unless a write happened meanwhile.
    pub(crate) fn cache_places(&self, key: CacheKey, places: Arc<Vec<Place>>) {
        if self.cache_key() == key {
            *self
                .derived
                .places
                .lock()
                .unwrap_or_else(PoisonError::into_inner) = Some((key, places));
        }
    }

    pub(crate) fn storage(&self, source: oxigraph::store::StorageError) -> StoreError {
        StoreError::Storage {
            location: self.location.clone(),
            source,
        }
    }

    /// Whether the store holds no triple in any graph. Blocking.
    pub fn is_empty(&self) -> Result<bool, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => store.is_empty().map_err(|e| self.storage(e)),
            Backend::Remote(remote) => remote
                .ask("ASK { { ?s ?p ?o } UNION { GRAPH ?g { ?s ?p ?o } } }")
                .map(|any| !any),
        }
    }

    /// Whether the named graph `graph` exists. Blocking.
    pub fn contains_named_graph(&self, graph: NamedNodeRef<'_>) -> Result<bool, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => store
                .contains_named_graph(graph)
                .map_err(|e| self.storage(e)),
            Backend::Remote(remote) => remote.ask(&format!("ASK {{ GRAPH {graph} {{ }} }}")),
        }
    }

    /// Adds `quads` (in whatever graphs they name) in one transaction. Blocking.
    pub fn insert(&self, quads: &[Quad]) -> Result<(), StoreError> {
        match &self.backend {
            Backend::Embedded(store) => {
                let mut transaction = store.start_transaction().map_err(|e| self.storage(e))?;
                transaction.extend(quads);
                transaction.commit().map_err(|e| self.storage(e))
            }
            Backend::Remote(remote) => remote.update(&insert_data(quads)),
        }
    }

    /// Turtle parsed into `graph`, blank nodes renamed apart. Pure.
    pub fn parse_turtle(turtle: &str, graph: NamedNodeRef<'_>) -> Result<Vec<Quad>, String> {
        RdfParser::from_format(RdfFormat::Turtle)
            .rename_blank_nodes()
            .with_default_graph(graph)
            .for_slice(turtle.as_bytes())
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| e.to_string())
    }

    /// The content of `graph` becomes `quads` (which must all be in `graph`); a named graph
    /// that did not exist is created. Returns whether it was created. One transaction
    /// (embedded) or one update request (remote). Blocking.
    pub fn replace_graph(&self, graph: &GraphName, quads: &[Quad]) -> Result<bool, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => {
                let storage = |e| self.storage(e);
                let mut transaction = store.start_transaction().map_err(storage)?;
                let created = match graph {
                    GraphName::NamedNode(g) => {
                        let existed = transaction.contains_named_graph(g).map_err(storage)?;
                        if existed {
                            transaction.clear_graph(g).map_err(storage)?;
                        } else {
                            transaction.insert_named_graph(g);
                        }
                        !existed
                    }
                    GraphName::DefaultGraph | GraphName::BlankNode(_) => {
                        transaction.clear_graph(graph.as_ref()).map_err(storage)?;
                        false
                    }
                };
                transaction.extend(quads);
                transaction.commit().map_err(storage)?;
                Ok(created)
            }
            Backend::Remote(remote) => {
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
                remote.update(&update)?;
                Ok(created)
            }
        }
    }

    /// Adds `quads` (which must all be in `graph`) to `graph`, creating it if needed. Returns
    /// whether it was created. Blocking.
    pub fn merge_into_graph(&self, graph: &GraphName, quads: &[Quad]) -> Result<bool, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => {
                let storage = |e| self.storage(e);
                let mut transaction = store.start_transaction().map_err(storage)?;
                let created = match graph {
                    GraphName::NamedNode(g) => {
                        let existed = transaction.contains_named_graph(g).map_err(storage)?;
                        transaction.insert_named_graph(g);
                        !existed
                    }
                    GraphName::DefaultGraph | GraphName::BlankNode(_) => false,
                };
                transaction.extend(quads);
                transaction.commit().map_err(storage)?;
                Ok(created)
            }
            Backend::Remote(remote) => {
                let (created, mut update) = match graph {
                    GraphName::NamedNode(g) => (
                        !self.contains_named_graph(g.as_ref())?,
                        format!("CREATE SILENT GRAPH {g} ;\n"),
                    ),
                    GraphName::DefaultGraph | GraphName::BlankNode(_) => (false, String::new()),
                };
                update.push_str(&insert_data(quads));
                remote.update(&update)?;
                Ok(created)
            }
        }
    }

    /// Drops a named graph (returns whether it existed) or empties the default graph
    /// (returns true). Blocking.
    pub fn drop_graph(&self, graph: &GraphName) -> Result<bool, StoreError> {
        match (&self.backend, graph) {
            (Backend::Embedded(store), GraphName::NamedNode(g)) => {
                // The check and the drop are not one transaction; a concurrent drop of the
                // same graph makes one of them a harmless no-op.
                if !store.contains_named_graph(g).map_err(|e| self.storage(e))? {
                    return Ok(false);
                }
                store.remove_named_graph(g).map_err(|e| self.storage(e))?;
                Ok(true)
            }
            (Backend::Embedded(store), _) => {
                store
                    .clear_graph(GraphNameRef::DefaultGraph)
                    .map_err(|e| self.storage(e))?;
                Ok(true)
            }
            (Backend::Remote(remote), GraphName::NamedNode(g)) => {
                if !self.contains_named_graph(g.as_ref())? {
                    return Ok(false);
                }
                remote.update(&format!("DROP SILENT GRAPH {g}"))?;
                Ok(true)
            }
            (Backend::Remote(remote), _) => {
                remote.update("CLEAR SILENT DEFAULT")?;
                Ok(true)
            }
        }
    }

    /// In `graph`, removes every triple whose subject is one of `subjects`, then adds `quads`
    /// (which must be in `graph`), atomically. Returns whether anything was removed. Blocking.
    pub fn replace_subjects(
        &self,
        graph: NamedNodeRef<'_>,
        subjects: &[NamedNode],
        quads: &[Quad],
    ) -> Result<bool, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => {
                let storage = |e| self.storage(e);
                let mut transaction = store.start_transaction().map_err(storage)?;
                let mut stale = Vec::new();
                for subject in subjects {
                    for quad in transaction.quads_for_pattern(
                        Some(subject.as_ref().into()),
                        None,
                        None,
                        Some(graph.into()),
                    ) {
                        stale.push(quad.map_err(storage)?);
                    }
                }
                for quad in &stale {
                    transaction.remove(quad);
                }
                transaction.extend(quads);
                transaction.commit().map_err(storage)?;
                Ok(!stale.is_empty())
            }
            Backend::Remote(remote) => {
                let values: String = subjects.iter().map(|s| format!("{s} ")).collect();
                let pattern = format!("GRAPH {graph} {{ VALUES ?s {{ {values}}} ?s ?p ?o }}");
                let existed = remote.ask(&format!("ASK {{ {pattern} }}"))?;
                let mut update =
                    format!("DELETE {{ GRAPH {graph} {{ ?s ?p ?o }} }} WHERE {{ {pattern} }} ;\n");
                update.push_str(&insert_data(quads));
                remote.update(&update)?;
                Ok(existed)
            }
        }
    }
}

/// `INSERT DATA { … }` for `quads`, grouped by graph, terms in their N-Triples form (which
/// SPARQL reads as is). Blank nodes keep their labels, so within one request they stay one
/// node each.
pub(crate) fn insert_data(quads: &[Quad]) -> String {
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

    #[test]
    #[cfg(feature = "rocksdb")]
    fn opens_on_disk_and_answers_a_query() {
        let dir = tempfile::tempdir().unwrap();
        let store = KnowledgeStore::open(&dir.path().join("oxigraph")).unwrap();
        store.check().unwrap();
        store.flush().unwrap();
        assert!(dir.path().join("oxigraph").is_dir());
    }

    #[test]
    fn in_memory_store_answers_a_query() {
        KnowledgeStore::in_memory().unwrap().check().unwrap();
    }

    #[test]
    #[cfg(feature = "rocksdb")]
    fn a_path_below_a_file_is_an_error() {
        let file = tempfile::NamedTempFile::new().unwrap();
        let err = KnowledgeStore::open(&file.path().join("oxigraph")).unwrap_err();
        assert!(err.to_string().contains("graph store at"), "{err}");
    }

    #[test]
    fn insert_data_round_trips_through_an_update() {
        let g = NamedNode::new("http://example.org/g").unwrap();
        let quads = KnowledgeStore::parse_turtle(
            "@prefix : <http://example.org/> . :a :p \"x\\\"y\\n\"@en , [ :q 1 ] . :b :r :c .",
            g.as_ref(),
        )
        .unwrap();
        let mut all = quads.clone();
        all.push(Quad::new(
            NamedNode::new("http://example.org/d").unwrap(),
            NamedNode::new("http://example.org/p").unwrap(),
            oxigraph::model::Literal::from(2.5),
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

    #[test]
    fn graph_writes_report_created_and_existing() {
        let store = KnowledgeStore::in_memory().unwrap();
        let g = NamedNode::new("http://example.org/g").unwrap();
        let quads =
            KnowledgeStore::parse_turtle("<http://e/a> <http://e/p> 1 .", g.as_ref()).unwrap();
        let graph = GraphName::from(g.clone());
        assert!(store.replace_graph(&graph, &quads).unwrap());
        assert!(!store.replace_graph(&graph, &quads).unwrap());
        assert!(!store.merge_into_graph(&graph, &quads).unwrap());
        assert!(
            store
                .replace_subjects(g.as_ref(), &[NamedNode::new("http://e/a").unwrap()], &[])
                .unwrap()
        );
        assert!(store.contains_named_graph(g.as_ref()).unwrap());
        assert!(store.drop_graph(&graph).unwrap());
        assert!(!store.drop_graph(&graph).unwrap());
    }
}
