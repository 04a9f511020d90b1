//! The graph store: one interface, [`KnowledgeStore`], over two backends.
//!
//! - **Embedded** (`embedded.rs`): Oxigraph in this process, on RocksDB under the data
//!   directory (or in memory for tests and tools). Reads go straight to it.
//! - **Remote** ([`remote`]): any SPARQL 1.1 store reached over the SPARQL 1.1 Protocol (an
//!   Oxigraph server, Fuseki, GraphDB, Virtuoso, Neptune). Queries and updates sent to
//!   `/sparql` are forwarded; writes the service makes itself become SPARQL updates; the graph
//!   walks of the REST API (places, robots, on-demand databases) read a local in-memory copy
//!   of the remote dataset that is reused while the remote's version marker is unchanged.
//!
//! Everything the rest of the crate does with the store goes through the methods below, which
//! are blocking (call them from `spawn_blocking`); the SPARQL endpoint's hot path talks to the
//! remote asynchronously through [`KnowledgeStore::remote_store`].
//!
//! The backends know nothing of this module or of each other: each imports only `error.rs`
//! (and the remote the graph names of [`crate::graphs`]), and this module dispatches to them.

mod embedded;
mod error;
pub mod remote;

use std::collections::HashMap;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use oxigraph::io::{RdfFormat, RdfParser};
use oxigraph::model::{GraphName, NamedNode, NamedNodeRef, Quad, Triple};
use oxigraph::store::Store;
use tosm::Place;

use self::embedded::EmbeddedStore;
pub use self::error::StoreError;
pub use self::remote::{RemoteConfig, RemoteStore};

#[derive(Clone)]
enum Backend {
    Embedded(EmbeddedStore),
    Remote(Arc<RemoteStore>),
}

/// The knowledge graph. Cloning is cheap (both backends are reference-counted).
#[derive(Clone)]
pub struct KnowledgeStore {
    backend: Backend,
    derived: Arc<Derived>,
}

/// What the service derives from the graph and keeps until the next write: the typed places
/// every on-demand database and place lookup starts from (reading them decodes every floor's
/// map, which on a large building costs far more than the rest of a request).
struct Derived {
    /// Numbers the stores of this process, for [`KnowledgeStore::state_tag`].
    id: u64,
    /// Bumped after every write through the service (the rebuild of the entailments calls
    /// [`KnowledgeStore::bump_generation`]).
    generation: AtomicU64,
    places: Mutex<Option<(CacheKey, Arc<Vec<Place>>)>>,
    closures: Mutex<Option<Closures>>,
}

/// A subject's closure as the on-demand databases read it: its asserted triples and those of
/// the individuals it owns, and every node visited.
pub(crate) type Closure = Arc<(Vec<Triple>, Vec<NamedNode>)>;

/// The most triples the closures of one state keep: past it they are dropped and read again
/// (about 300 bytes each: a few dozen MB at most).
const MAX_CACHED_TRIPLES: usize = 200_000;

/// The closures read for one state of the graph, by subject IRI and whether robot parts are
/// followed.
struct Closures {
    key: CacheKey,
    triples: usize,
    map: HashMap<(String, bool), Closure>,
}

impl Default for Derived {
    fn default() -> Self {
        static STORES: AtomicU64 = AtomicU64::new(0);
        Self {
            id: STORES.fetch_add(1, Ordering::Relaxed),
            generation: AtomicU64::new(0),
            places: Mutex::new(None),
            closures: Mutex::new(None),
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
            .field("location", &self.location())
            .finish_non_exhaustive()
    }
}

impl KnowledgeStore {
    fn with_backend(backend: Backend) -> Self {
        Self {
            backend,
            derived: Arc::default(),
        }
    }

    /// Opens (creating if needed) the store in `path`. Blocking: call from `spawn_blocking`.
    /// Without the `rocksdb` feature there is no on-disk store and this is an error.
    pub fn open(path: &Path) -> Result<Self, StoreError> {
        EmbeddedStore::open(path).map(|store| Self::with_backend(Backend::Embedded(store)))
    }

    /// A store in memory, gone when dropped: for tests and throwaway tools.
    pub fn in_memory() -> Result<Self, StoreError> {
        EmbeddedStore::in_memory().map(|store| Self::with_backend(Backend::Embedded(store)))
    }

    /// A remote SPARQL 1.1 store. Makes no request: [`Self::check`] tells whether it answers.
    /// Must be called inside a tokio runtime (its HTTP client lives there).
    pub fn remote(config: RemoteConfig) -> Result<Self, StoreError> {
        let remote = RemoteStore::new(config)?;
        Ok(Self::with_backend(Backend::Remote(Arc::new(remote))))
    }

    /// Runs a trivial query through the whole stack (parser, evaluator, RocksDB iterator; or
    /// the remote's endpoint). Blocking.
    pub fn check(&self) -> Result<(), StoreError> {
        match &self.backend {
            Backend::Embedded(store) => store.check(),
            Backend::Remote(remote) => remote.check(),
        }
    }

    /// Evaluates an ASK query (over every graph: use `GRAPH`). Blocking.
    pub fn ask(&self, query: &str) -> Result<bool, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => store.ask(query),
            Backend::Remote(remote) => remote.ask(query),
        }
    }

    /// Where the store lives: its directory, `:memory:`, or the remote's query endpoint.
    pub fn location(&self) -> &str {
        match &self.backend {
            Backend::Embedded(store) => store.location(),
            Backend::Remote(remote) => remote.shown_query_url(),
        }
    }

    /// The embedded Oxigraph store, when the store is embedded.
    pub fn embedded(&self) -> Option<&Store> {
        match &self.backend {
            Backend::Embedded(store) => Some(store.store()),
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
    /// [`remote::SNAPSHOT_MAX_AGE`]. Blocking.
    pub fn snapshot(&self) -> Result<Store, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => Ok(store.store().clone()),
            Backend::Remote(remote) => remote.snapshot(),
        }
    }

    /// Flushes memtables to disk, for a clean shutdown. Blocking. Nothing to do for a remote.
    pub fn flush(&self) -> Result<(), StoreError> {
        match &self.backend {
            Backend::Embedded(store) => store.flush(),
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
        *self
            .derived
            .closures
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

    /// The closure of `subject` read for state `key` (with robot parts when `parts`), if it
    /// is cached.
    pub(crate) fn cached_closure(
        &self,
        key: CacheKey,
        subject: &str,
        parts: bool,
    ) -> Option<Closure> {
        let slot = self
            .derived
            .closures
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        slot.as_ref()
            .filter(|c| c.key == key)
            .and_then(|c| c.map.get(&(subject.to_owned(), parts)).cloned())
    }

    /// Keeps the closure of `subject` read for state `key`, unless a write happened meanwhile;
    /// past [`MAX_CACHED_TRIPLES`] the state's closures are dropped first.
    pub(crate) fn cache_closure(
        &self,
        key: CacheKey,
        subject: &str,
        parts: bool,
        closure: Closure,
    ) {
        if self.cache_key() != key {
            return;
        }
        let mut slot = self
            .derived
            .closures
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let n = closure.0.len();
        let fresh = slot
            .as_ref()
            .is_none_or(|c| c.key != key || c.triples + n > MAX_CACHED_TRIPLES);
        if fresh {
            *slot = Some(Closures {
                key,
                triples: 0,
                map: HashMap::new(),
            });
        }
        if let Some(c) = slot.as_mut()
            && c.map.insert((subject.to_owned(), parts), closure).is_none()
        {
            c.triples += n;
        }
    }

    /// Oxigraph's error, naming this store (and remembering a full disk).
    pub(crate) fn storage(&self, source: oxigraph::store::StorageError) -> StoreError {
        self.note_failure(&source.to_string());
        StoreError::Storage {
            location: self.location().to_owned(),
            source,
        }
    }

    /// Remembers a write that failed with `message` outside this type's own methods (a
    /// SPARQL update): when it says the disk is full, the store must be reopened.
    pub fn note_failure(&self, message: &str) {
        if let Backend::Embedded(store) = &self.backend {
            store.note_failure(message);
        }
    }

    /// Whether a write found the disk full since this store was opened (embedded only: a
    /// remote store recovers by itself).
    pub fn write_failed(&self) -> bool {
        match &self.backend {
            Backend::Embedded(store) => store.write_failed(),
            Backend::Remote(_) => false,
        }
    }

    /// Whether the store holds no triple in any graph. Blocking.
    pub fn is_empty(&self) -> Result<bool, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => store.is_empty(),
            Backend::Remote(remote) => remote.is_empty(),
        }
    }

    /// Whether the named graph `graph` exists. Blocking.
    pub fn contains_named_graph(&self, graph: NamedNodeRef<'_>) -> Result<bool, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => store.contains_named_graph(graph),
            Backend::Remote(remote) => remote.contains_named_graph(graph),
        }
    }

    /// Adds `quads` (in whatever graphs they name) in one transaction. Blocking.
    pub fn insert(&self, quads: &[Quad]) -> Result<(), StoreError> {
        match &self.backend {
            Backend::Embedded(store) => store.insert(quads),
            Backend::Remote(remote) => remote.insert(quads),
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
            Backend::Embedded(store) => store.replace_graph(graph, quads),
            Backend::Remote(remote) => remote.replace_graph(graph, quads),
        }
    }

    /// Adds `quads` (which must all be in `graph`) to `graph`, creating it if needed. Returns
    /// whether it was created. Blocking.
    pub fn merge_into_graph(&self, graph: &GraphName, quads: &[Quad]) -> Result<bool, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => store.merge_into_graph(graph, quads),
            Backend::Remote(remote) => remote.merge_into_graph(graph, quads),
        }
    }

    /// Drops a named graph (returns whether it existed) or empties the default graph
    /// (returns true). Blocking.
    pub fn drop_graph(&self, graph: &GraphName) -> Result<bool, StoreError> {
        match &self.backend {
            Backend::Embedded(store) => store.drop_graph(graph),
            Backend::Remote(remote) => remote.drop_graph(graph),
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
            Backend::Embedded(store) => store.replace_subjects(graph, subjects, quads),
            Backend::Remote(remote) => remote.replace_subjects(graph, subjects, quads),
        }
    }
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
