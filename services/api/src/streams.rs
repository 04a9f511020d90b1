//! Caps on the server-sent event streams open at once (job events, traffic): each polls the
//! job database, whose pool the running jobs' heartbeats need.

use std::collections::HashMap;
use std::sync::Arc;

use edge::{ApiError, ErrorCode};

/// Caps on open event streams.
#[derive(Debug)]
pub struct StreamLimits {
    /// Streams open at once in all.
    pub total: usize,
    /// Streams open at once per token holder.
    pub per_principal: usize,
    open: std::sync::Mutex<HashMap<String, usize>>,
}

impl StreamLimits {
    /// At most `total` streams, `per_principal` of them by one token holder.
    pub fn new(total: usize, per_principal: usize) -> Self {
        Self {
            total,
            per_principal,
            open: std::sync::Mutex::default(),
        }
    }

    /// A place for one more stream of `who`, held until the stream ends.
    pub(crate) fn open(self: &Arc<Self>, who: &str) -> Result<StreamPermit, ApiError> {
        let mut open = self
            .open
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let all: usize = open.values().sum();
        let mine = open.get(who).copied().unwrap_or(0);
        if all >= self.total {
            return Err(ApiError::new(
                ErrorCode::Overloaded,
                format!("{all} event streams are open, the service's limit; retry later"),
            ));
        }
        if mine >= self.per_principal {
            return Err(ApiError::new(
                ErrorCode::TooManyRequests,
                format!(
                    "{who} has {mine} event streams open, the limit per token; close one first"
                ),
            ));
        }
        *open.entry(who.to_owned()).or_insert(0) += 1;
        Ok(StreamPermit {
            limits: Arc::clone(self),
            who: who.to_owned(),
        })
    }
}

/// One open stream's place; given back when the stream is dropped.
pub(crate) struct StreamPermit {
    limits: Arc<StreamLimits>,
    who: String,
}

impl Drop for StreamPermit {
    fn drop(&mut self) {
        let mut open = self
            .limits
            .open
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Some(n) = open.get_mut(&self.who) {
            *n = n.saturating_sub(1);
            if *n == 0 {
                open.remove(&self.who);
            }
        }
    }
}
