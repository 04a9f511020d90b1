//! The store as the on-demand database reads it: asserted triples only, from a snapshot.

use std::collections::{BTreeSet, HashSet};
use std::sync::Arc;

use oxigraph::model::vocab::rdf;
use oxigraph::model::{GraphNameRef, NamedNode, NamedNodeRef, Term, TermRef, Triple};
use tosm::vocab;

use crate::graphs::INFERRED_GRAPH;
use crate::store::{KnowledgeStore, StoreError};

/// Reads asserted triples out of the store (every graph but the inferred one): the embedded
/// store itself, or the in-memory snapshot of a remote one.
pub(super) struct Reader {
    pub(super) store: oxigraph::store::Store,
    location: String,
    pub(super) owner: KnowledgeStore,
    pub(super) key: crate::store::CacheKey,
}

impl Reader {
    pub(super) fn new(store: &KnowledgeStore) -> Result<Self, StoreError> {
        let snapshot = store.snapshot()?;
        Ok(Self {
            store: snapshot,
            location: store.location().to_owned(),
            owner: store.clone(),
            key: store.cache_key(),
        })
    }

    pub(super) fn err(&self, source: oxigraph::store::StorageError) -> StoreError {
        StoreError::Storage {
            location: self.location.clone(),
            source,
        }
    }

    /// Asserted triples about `subject`.
    pub(super) fn about(&self, subject: NamedNodeRef<'_>) -> Result<Vec<Triple>, StoreError> {
        let mut out = Vec::new();
        for quad in self
            .store
            .quads_for_pattern(Some(subject.into()), None, None, None)
        {
            let quad = quad.map_err(|e| self.err(e))?;
            if quad.graph_name.as_ref() != GraphNameRef::NamedNode(INFERRED_GRAPH) {
                out.push(Triple::from(quad));
            }
        }
        Ok(out)
    }

    /// Whether `node` has type `class`, asserted or entailed.
    pub(super) fn is_a(
        &self,
        node: NamedNodeRef<'_>,
        class: NamedNodeRef<'_>,
    ) -> Result<bool, StoreError> {
        let mut it = self.store.quads_for_pattern(
            Some(node.into()),
            Some(rdf::TYPE),
            Some(class.into()),
            None,
        );
        match it.next() {
            Some(Ok(_)) => Ok(true),
            Some(Err(e)) => Err(self.err(e)),
            None => Ok(false),
        }
    }

    /// Every individual of `class` (asserted or entailed), sorted.
    pub(super) fn instances(
        &self,
        class: NamedNodeRef<'_>,
    ) -> Result<BTreeSet<NamedNode>, StoreError> {
        let mut out = BTreeSet::new();
        for quad in self
            .store
            .quads_for_pattern(None, Some(rdf::TYPE), Some(class.into()), None)
        {
            let quad = quad.map_err(|e| self.err(e))?;
            if let oxigraph::model::NamedOrBlankNode::NamedNode(n) = quad.subject {
                out.insert(n);
            }
        }
        Ok(out)
    }

    /// `subject`'s triples and, recursively, those of the individuals it owns: descriptors
    /// (poses, shapes, boundary points, maps) and, when `parts` is set, robot parts. Nothing
    /// when `seen` holds `subject`; every node visited is added to `seen`.
    ///
    /// Each subject's closure is kept for the state of the graph it was read in (until the next
    /// write, [`KnowledgeStore::cached_closure`]): reading one decodes every term of every quad
    /// about it, inferred ones included (a RocksDB lookup per IRI), which was 60% of an
    /// on-demand database's time, and the missions of a fleet cross the same places again.
    pub(super) fn closure(
        &self,
        subject: NamedNodeRef<'_>,
        parts: bool,
        out: &mut HashSet<Triple>,
        seen: &mut BTreeSet<NamedNode>,
    ) -> Result<(), StoreError> {
        if seen.contains(&subject.into_owned()) {
            return Ok(());
        }
        let closure = match self.owner.cached_closure(self.key, subject.as_str(), parts) {
            Some(c) => c,
            None => {
                let (mut triples, mut visited) = (HashSet::new(), BTreeSet::new());
                self.walk(subject, parts, &mut triples, &mut visited)?;
                let c = Arc::new((triples.into_iter().collect(), visited.into_iter().collect()));
                self.owner
                    .cache_closure(self.key, subject.as_str(), parts, Arc::clone(&c));
                c
            }
        };
        out.extend(closure.0.iter().cloned());
        seen.extend(closure.1.iter().cloned());
        Ok(())
    }

    /// [`Self::closure`] read from the store, uncached.
    pub(super) fn walk(
        &self,
        subject: NamedNodeRef<'_>,
        parts: bool,
        out: &mut HashSet<Triple>,
        seen: &mut BTreeSet<NamedNode>,
    ) -> Result<(), StoreError> {
        if !seen.insert(subject.into_owned()) {
            return Ok(());
        }
        for triple in self.about(subject)? {
            if let Term::NamedNode(object) = &triple.object
                && triple.predicate.as_ref() != rdf::TYPE
                && (self.is_a(object.as_ref(), vocab::DESCRIPTOR)?
                    || (parts && self.is_a(object.as_ref(), vocab::ROBOT_PART)?))
            {
                self.walk(object.as_ref(), parts, out, seen)?;
            }
            out.insert(triple);
        }
        Ok(())
    }

    /// Whether `place` states an expected number of people or has a people estimate
    /// (asserted, in any graph but the inferred one).
    pub(super) fn knows_people_in(&self, place: &str) -> Result<bool, StoreError> {
        let node = NamedNodeRef::new_unchecked(place);
        for p in [
            vocab::EXPECTED_PEOPLE,
            vocab::HAS_HOURLY_PEOPLE_COUNT,
            vocab::HAS_PEOPLE_ESTIMATE,
        ] {
            for quad in self
                .store
                .quads_for_pattern(Some(node.into()), Some(p), None, None)
            {
                let quad = quad.map_err(|e| self.err(e))?;
                if quad.graph_name.as_ref() != GraphNameRef::NamedNode(INFERRED_GRAPH) {
                    return Ok(true);
                }
            }
        }
        Ok(false)
    }

    /// The named subjects asserted (not inferred) to be `property` of `object`.
    pub(super) fn asserted_subjects(
        &self,
        property: NamedNodeRef<'_>,
        object: NamedNodeRef<'_>,
    ) -> Result<BTreeSet<NamedNode>, StoreError> {
        let mut out = BTreeSet::new();
        for quad in self
            .store
            .quads_for_pattern(None, Some(property), Some(object.into()), None)
        {
            let quad = quad.map_err(|e| self.err(e))?;
            if quad.graph_name.as_ref() != GraphNameRef::NamedNode(INFERRED_GRAPH)
                && let oxigraph::model::NamedOrBlankNode::NamedNode(n) = quad.subject
            {
                out.insert(n);
            }
        }
        Ok(out)
    }

    /// The individual named `name`: an IRI, or the subject of `tosm:identifier "name"`.
    pub(super) fn resolve(&self, name: &str) -> Result<Option<NamedNode>, StoreError> {
        if name.contains("://") || name.starts_with("urn:") {
            return Ok(NamedNode::new(name).ok());
        }
        let literal = oxigraph::model::Literal::new_simple_literal(name);
        let mut it = self.store.quads_for_pattern(
            None,
            Some(vocab::IDENTIFIER),
            Some(TermRef::Literal(literal.as_ref())),
            None,
        );
        match it.next() {
            Some(Ok(q)) => Ok(match q.subject {
                oxigraph::model::NamedOrBlankNode::NamedNode(n) => Some(n),
                _ => None,
            }),
            Some(Err(e)) => Err(self.err(e)),
            None => Ok(None),
        }
    }
}
