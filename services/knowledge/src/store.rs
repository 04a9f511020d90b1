//! The graph store: embedded Oxigraph on RocksDB under the data directory.

use std::path::{Path, PathBuf};

use oxigraph::store::Store;

/// Why the store could not be opened or used.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// Oxigraph refused to open or query its directory.
    #[error("graph store at {path}: {source}")]
    Storage {
        /// The store directory.
        path: PathBuf,
        /// Oxigraph's error.
        #[source]
        source: oxigraph::store::StorageError,
    },
    /// A health query failed to evaluate.
    #[error("graph store at {path}: health query failed: {message}")]
    Query {
        /// The store directory.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

/// The knowledge graph, durable on disk. Cloning is cheap (the store is reference-counted).
#[derive(Clone)]
pub struct KnowledgeStore {
    store: Store,
    path: PathBuf,
}

impl std::fmt::Debug for KnowledgeStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("KnowledgeStore")
            .field("path", &self.path)
            .finish_non_exhaustive()
    }
}

impl KnowledgeStore {
    /// Opens (creating if needed) the store in `path`. Blocking: call from `spawn_blocking`.
    #[cfg(feature = "rocksdb")]
    pub fn open(path: &Path) -> Result<Self, StoreError> {
        let store = Store::open(path).map_err(|source| StoreError::Storage {
            path: path.to_owned(),
            source,
        })?;
        Ok(Self {
            store,
            path: path.to_owned(),
        })
    }

    /// A store in memory, gone when dropped: for tests and throwaway tools.
    pub fn in_memory() -> Result<Self, StoreError> {
        let path = PathBuf::from(":memory:");
        let store = Store::new().map_err(|source| StoreError::Storage {
            path: path.clone(),
            source,
        })?;
        Ok(Self { store, path })
    }

    /// Runs a trivial query through the whole stack (parser, evaluator, RocksDB iterator).
    /// Blocking.
    pub fn check(&self) -> Result<(), StoreError> {
        let query_error = |message: String| StoreError::Query {
            path: self.path.clone(),
            message,
        };
        let results = oxigraph::sparql::SparqlEvaluator::new()
            .parse_query("ASK { ?s ?p ?o }")
            .map_err(|e| query_error(e.to_string()))?
            .on_store(&self.store)
            .execute()
            .map_err(|e| query_error(e.to_string()))?;
        match results {
            oxigraph::sparql::QueryResults::Boolean(_) => Ok(()),
            _ => Err(query_error("ASK did not answer a boolean".to_owned())),
        }
    }

    /// The directory the store lives in.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The underlying Oxigraph store.
    pub fn inner(&self) -> &Store {
        &self.store
    }

    /// Flushes memtables to disk, for a clean shutdown. Blocking.
    pub fn flush(&self) -> Result<(), StoreError> {
        #[cfg(not(feature = "rocksdb"))]
        return Ok(());
        #[cfg(feature = "rocksdb")]
        self.store.flush().map_err(|source| StoreError::Storage {
            path: self.path.clone(),
            source,
        })
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
}
