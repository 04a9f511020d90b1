//! Policies loaded for plans, kept while their weights file is unchanged, with the FNV-1a
//! fingerprint of those weights (part of a stored roadmap's key).

use std::sync::{Arc, PoisonError};

use crate::policies;
use crate::{BoxError, Missing, PlanFailure, Planner, Unusable};

/// Policies kept loaded at most.
pub(crate) const LOADED_POLICIES: usize = 16;

/// A loaded policy and the FNV-1a fingerprint of its weights file.
#[derive(Clone)]
pub(crate) struct LoadedPolicy {
    pub(crate) policy: Arc<learning::Policy>,
    pub(crate) weights: u64,
}

impl Planner {
    /// The policy `id`, loaded again only when its weights file changed.
    pub(crate) async fn policy(&self, id: &str) -> Result<LoadedPolicy, PlanFailure> {
        let not_found = || PlanFailure::NotFound(Missing::Policy(id.to_owned()));
        if !self.policies.exists(id) {
            return Err(not_found());
        }
        let dir = self.policies.path(id).ok_or_else(not_found)?;
        let modified = std::fs::metadata(dir.join(policies::WEIGHTS))
            .and_then(|m| m.modified())
            .ok();
        let cached = self
            .loaded
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .get(id)
            .filter(|(at, _)| Some(*at) == modified)
            .map(|(_, p)| p.clone());
        if let Some(p) = cached {
            return Ok(p);
        }
        let loaded = tokio::task::spawn_blocking(move || {
            let weights = std::fs::read(dir.join(policies::WEIGHTS))
                .map(|b| grid::hash::fnv1a(&b))
                .map_err(|e| Arc::from(BoxError::from(e)))?;
            learning::Policy::load(&dir)
                .map(|p| LoadedPolicy {
                    policy: Arc::new(p),
                    weights,
                })
                .map_err(|e| Arc::from(BoxError::from(e)))
        })
        .await
        .map_err(|e| PlanFailure::Internal {
            what: "the policy loader failed".into(),
            source: Some(e.into()),
        })?
        .map_err(|source| {
            PlanFailure::Unprocessable(Unusable::Policy {
                id: id.to_owned(),
                source,
            })
        })?;
        let mut policies = self.loaded.lock().unwrap_or_else(PoisonError::into_inner);
        if policies.len() >= LOADED_POLICIES {
            policies.clear();
        }
        if let Some(at) = modified {
            policies.insert(id.to_owned(), (at, loaded.clone()));
        }
        Ok(loaded)
    }
}
