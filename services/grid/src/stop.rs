//! [`Stop`]: a request to stop long work early, shared between the thread doing the work (which
//! polls it at its own checkpoints) and whoever may cancel it (a request that timed out, a
//! client that hung up, a job that lost its lease).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// A stop flag. [`Stop::never`] (the default) is never requested and costs one branch to poll.
/// Clones share the flag.
#[derive(Clone, Debug, Default)]
pub struct Stop(Option<Arc<AtomicBool>>);

impl Stop {
    /// A flag that can be requested.
    pub fn new() -> Self {
        Self(Some(Arc::new(AtomicBool::new(false))))
    }

    /// A flag that is never requested.
    pub fn never() -> Self {
        Self(None)
    }

    /// Asks the work to stop.
    pub fn request(&self) {
        if let Some(flag) = &self.0 {
            flag.store(true, Ordering::Relaxed);
        }
    }

    /// Whether a stop was requested.
    pub fn requested(&self) -> bool {
        self.0.as_ref().is_some_and(|f| f.load(Ordering::Relaxed))
    }
}

/// A stop handle is not part of the work it may stop: all handles compare equal, so the values
/// that carry one still compare by what they describe.
impl PartialEq for Stop {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// Requests its [`Stop`] when dropped: held by an async request handler, it stops the blocking
/// work the handler started when the handler's future is dropped (a timeout, a client that
/// went away) — and harmlessly after the work finished otherwise.
#[derive(Debug)]
pub struct StopOnDrop(pub Stop);

impl Drop for StopOnDrop {
    fn drop(&mut self) {
        self.0.request();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clones_share_the_flag_and_never_is_never() {
        let stop = Stop::new();
        let seen = stop.clone();
        assert!(!seen.requested());
        drop(StopOnDrop(stop));
        assert!(seen.requested());
        let never = Stop::never();
        never.request();
        assert!(!never.requested());
    }
}
