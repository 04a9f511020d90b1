//! The queue of a service process, opened on first use and re-tried on every use until it
//! opens: a database that is down at start delays jobs, it does not stop the process.

use std::path::PathBuf;

use tokio::sync::OnceCell;

use crate::database::JobDatabase;
use crate::jobs::{Backoff, Queue};

/// A [`Queue`] opened lazily.
#[derive(Debug)]
pub struct LazyQueue {
    url: String,
    backoff: Backoff,
    create_dir: Option<PathBuf>,
    cell: OnceCell<Queue>,
}

impl LazyQueue {
    /// The queue at `url` with `backoff`; `create_dir` (the data directory of an SQLite
    /// database) is created before opening.
    pub fn new(url: impl Into<String>, backoff: Backoff, create_dir: Option<PathBuf>) -> Self {
        Self {
            url: url.into(),
            backoff,
            create_dir,
            cell: OnceCell::new(),
        }
    }

    /// The queue, opening (and migrating) the database if it is not open yet.
    pub async fn get(&self) -> Result<&Queue, String> {
        self.cell
            .get_or_try_init(|| async {
                if let Some(dir) = &self.create_dir
                    && let Err(e) = tokio::fs::create_dir_all(dir).await
                {
                    return Err(format!(
                        "cannot create data directory {}: {e}",
                        dir.display()
                    ));
                }
                let db = JobDatabase::connect(&self.url)
                    .await
                    .map_err(|e| e.to_string())?;
                Ok(Queue::new(db).with_backoff(self.backoff))
            })
            .await
    }

    /// The queue if it is open.
    pub fn opened(&self) -> Option<&Queue> {
        self.cell.get()
    }
}
