//! The embedded backend: Oxigraph in this process, on RocksDB under the data directory (feature
//! `rocksdb`) or in memory for tests and tools. Every whole-graph write is one transaction.
//!
//! All methods are blocking (RocksDB reads and writes files): call them from `spawn_blocking`.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use oxigraph::model::{GraphName, GraphNameRef, NamedNode, NamedNodeRef, Quad};
use oxigraph::store::{StorageError, Store};

use crate::store::error::StoreError;

/// An Oxigraph store and where it lives, for messages. Cloning is cheap.
#[derive(Clone)]
pub(crate) struct EmbeddedStore {
    store: Store,
    location: String,
    /// Set when a write found the disk full: RocksDB refuses writes from then on, until the
    /// store is opened again.
    failed: Arc<AtomicBool>,
}

impl EmbeddedStore {
    /// Opens (creating if needed) the store in `path`.
    #[cfg(feature = "rocksdb")]
    pub(crate) fn open(path: &Path) -> Result<Self, StoreError> {
        let location = path.display().to_string();
        let store = Store::open(path).map_err(|source| StoreError::Storage {
            location: location.clone(),
            source,
        })?;
        Ok(Self {
            store,
            location,
            failed: Arc::default(),
        })
    }

    /// Opening on disk needs the `rocksdb` feature; without it this is an error.
    #[cfg(not(feature = "rocksdb"))]
    pub(crate) fn open(path: &Path) -> Result<Self, StoreError> {
        Err(StoreError::Query {
            location: path.display().to_string(),
            message: "this build has no on-disk store (feature `rocksdb`)".to_owned(),
        })
    }

    /// A store in memory, gone when dropped.
    pub(crate) fn in_memory() -> Result<Self, StoreError> {
        let location = ":memory:".to_owned();
        let store = Store::new().map_err(|source| StoreError::Storage {
            location: location.clone(),
            source,
        })?;
        Ok(Self {
            store,
            location,
            failed: Arc::default(),
        })
    }

    /// The Oxigraph store itself.
    pub(crate) fn store(&self) -> &Store {
        &self.store
    }

    /// Its directory, or `:memory:`.
    pub(crate) fn location(&self) -> &str {
        &self.location
    }

    /// Oxigraph's error, naming this store (and remembering a full disk).
    pub(crate) fn storage(&self, source: StorageError) -> StoreError {
        self.note_failure(&source.to_string());
        StoreError::Storage {
            location: self.location.clone(),
            source,
        }
    }

    /// Remembers that a write failed for want of space, when `message` says so.
    pub(crate) fn note_failure(&self, message: &str) {
        if edge::disk::is_out_of_space(message) {
            self.failed.store(true, Ordering::Relaxed);
        }
    }

    /// Whether a write found the disk full since the store was opened.
    pub(crate) fn write_failed(&self) -> bool {
        self.failed.load(Ordering::Relaxed)
    }

    /// Runs a trivial query through the whole stack (parser, evaluator, RocksDB iterator).
    pub(crate) fn check(&self) -> Result<(), StoreError> {
        self.ask("ASK { ?s ?p ?o }").map(drop)
    }

    /// Evaluates an ASK query. Blocking.
    pub(crate) fn ask(&self, query: &str) -> Result<bool, StoreError> {
        let query_error = |message: String| StoreError::Query {
            location: self.location.clone(),
            message: format!("query failed: {message}"),
        };
        let results = oxigraph::sparql::SparqlEvaluator::new()
            .parse_query(query)
            .map_err(|e| query_error(e.to_string()))?
            .on_store(&self.store)
            .execute()
            .map_err(|e| query_error(e.to_string()))?;
        match results {
            oxigraph::sparql::QueryResults::Boolean(b) => Ok(b),
            _ => Err(query_error("ASK did not answer a boolean".to_owned())),
        }
    }

    /// Flushes memtables to disk.
    #[cfg(feature = "rocksdb")]
    pub(crate) fn flush(&self) -> Result<(), StoreError> {
        self.store.flush().map_err(|e| self.storage(e))
    }

    /// Nothing to flush in memory.
    #[cfg(not(feature = "rocksdb"))]
    pub(crate) fn flush(&self) -> Result<(), StoreError> {
        Ok(())
    }

    /// Whether the store holds no triple in any graph.
    pub(crate) fn is_empty(&self) -> Result<bool, StoreError> {
        self.store.is_empty().map_err(|e| self.storage(e))
    }

    /// Whether the named graph `graph` exists.
    pub(crate) fn contains_named_graph(&self, graph: NamedNodeRef<'_>) -> Result<bool, StoreError> {
        self.store
            .contains_named_graph(graph)
            .map_err(|e| self.storage(e))
    }

    /// Adds `quads` in one transaction.
    pub(crate) fn insert(&self, quads: &[Quad]) -> Result<(), StoreError> {
        let mut transaction = self
            .store
            .start_transaction()
            .map_err(|e| self.storage(e))?;
        transaction.extend(quads);
        transaction.commit().map_err(|e| self.storage(e))
    }

    /// The content of `graph` becomes `quads`, in one transaction; returns whether a named
    /// graph was created.
    pub(crate) fn replace_graph(
        &self,
        graph: &GraphName,
        quads: &[Quad],
    ) -> Result<bool, StoreError> {
        self.write_graph(graph, quads, true)
    }

    /// Adds `quads` to `graph`, creating it if needed, in one transaction; returns whether it
    /// was created.
    pub(crate) fn merge_into_graph(
        &self,
        graph: &GraphName,
        quads: &[Quad],
    ) -> Result<bool, StoreError> {
        self.write_graph(graph, quads, false)
    }

    /// Writes `quads` into `graph` in one transaction, emptying it first when `replace`, and
    /// creating a named graph that does not exist; returns whether one was created.
    fn write_graph(
        &self,
        graph: &GraphName,
        quads: &[Quad],
        replace: bool,
    ) -> Result<bool, StoreError> {
        let storage = |e| self.storage(e);
        let mut transaction = self.store.start_transaction().map_err(storage)?;
        let created = match graph {
            GraphName::NamedNode(g) => {
                let existed = transaction.contains_named_graph(g).map_err(storage)?;
                if !existed {
                    transaction.insert_named_graph(g);
                }
                !existed
            }
            GraphName::DefaultGraph | GraphName::BlankNode(_) => false,
        };
        if replace {
            transaction.clear_graph(graph.as_ref()).map_err(storage)?;
        }
        transaction.extend(quads);
        transaction.commit().map_err(storage)?;
        Ok(created)
    }

    /// Drops a named graph (returns whether it existed) or empties the default graph
    /// (returns true).
    pub(crate) fn drop_graph(&self, graph: &GraphName) -> Result<bool, StoreError> {
        match graph {
            GraphName::NamedNode(g) => {
                // The check and the drop are not one transaction; a concurrent drop of the
                // same graph makes one of them a harmless no-op.
                if !self.contains_named_graph(g.as_ref())? {
                    return Ok(false);
                }
                self.store
                    .remove_named_graph(g)
                    .map_err(|e| self.storage(e))?;
                Ok(true)
            }
            _ => {
                self.store
                    .clear_graph(GraphNameRef::DefaultGraph)
                    .map_err(|e| self.storage(e))?;
                Ok(true)
            }
        }
    }

    /// In `graph`, removes every triple whose subject is one of `subjects`, then adds `quads`,
    /// in one transaction. Returns whether anything was removed.
    pub(crate) fn replace_subjects(
        &self,
        graph: NamedNodeRef<'_>,
        subjects: &[NamedNode],
        quads: &[Quad],
    ) -> Result<bool, StoreError> {
        let storage = |e| self.storage(e);
        let mut transaction = self.store.start_transaction().map_err(storage)?;
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
}
