//! Materialised entailments. Oxigraph does no reasoning, so the consequences that queries rely
//! on are computed here and kept in one named graph, rebuilt after every write:
//! class hierarchy (`rdf:type` through `rdfs:subClassOf`), property hierarchy
//! (`rdfs:subPropertyOf`), `owl:inverseOf`, `owl:SymmetricProperty` and
//! `owl:TransitiveProperty` (e.g. containment of places).
//!
//! The rules read the schema from the store itself, so they follow whatever ontology is loaded.
//! A full rebuild costs one pass over the store; for the graphs the service holds (10⁵–10⁶
//! triples) that is milliseconds to a second, which keeps the code obviously right. Only its
//! difference from the graph as stored is written (nothing when nothing changed).

use std::collections::{HashMap, HashSet};

use oxigraph::model::vocab::{rdf, rdfs};
use oxigraph::model::{GraphNameRef, NamedNode, NamedNodeRef, Quad, Term, Triple};

use crate::graphs::INFERRED_GRAPH;
use crate::store::{KnowledgeStore, StoreError};

const OWL_INVERSE_OF: NamedNodeRef<'static> =
    NamedNodeRef::new_unchecked("http://www.w3.org/2002/07/owl#inverseOf");
const OWL_SYMMETRIC: NamedNodeRef<'static> =
    NamedNodeRef::new_unchecked("http://www.w3.org/2002/07/owl#SymmetricProperty");
const OWL_TRANSITIVE: NamedNodeRef<'static> =
    NamedNodeRef::new_unchecked("http://www.w3.org/2002/07/owl#TransitiveProperty");

/// What a rebuild found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Refreshed {
    /// Triples asserted in the store (all graphs but the inferred one).
    pub asserted: usize,
    /// Triples now in the inferred graph (entailed and not asserted).
    pub inferred: usize,
}

/// Rebuilds [`INFERRED_GRAPH`] from everything else in the store, in one transaction that
/// removes and adds only what changed (one update request for a remote store, which also gets
/// a new version marker). Blocking.
pub fn refresh(store: &KnowledgeStore) -> Result<Refreshed, StoreError> {
    if let Some(remote) = store.remote_store() {
        let quads: Vec<Quad> = remote
            .quads(None, None)?
            .into_iter()
            .filter(|q| q.graph_name.as_ref() != GraphNameRef::NamedNode(INFERRED_GRAPH))
            .collect();
        let asserted: HashSet<Triple> = quads.iter().cloned().map(Triple::from).collect();
        let inferred = entailed_only(&asserted);
        let count = remote.write_inferred(quads, &inferred)?;
        store.bump_generation();
        return Ok(Refreshed {
            asserted: asserted.len(),
            inferred: count,
        });
    }
    let storage = |source| store.storage(source);
    let inner = store.snapshot()?;
    let mut asserted: HashSet<Triple> = HashSet::new();
    for quad in inner.iter() {
        let quad = quad.map_err(storage)?;
        if quad.graph_name.as_ref() == GraphNameRef::NamedNode(INFERRED_GRAPH) {
            continue;
        }
        asserted.insert(Triple::from(quad));
    }
    let wanted: HashSet<Triple> = entailed_only(&asserted).into_iter().collect();
    let count = wanted.len();
    // Only the difference is written: clearing the graph and inserting it whole would leave
    // every inferred quad (and as many tombstones) in RocksDB's memtable after each write and
    // at every start, and reads that merge the memtable cost up to twice as much (the `bench
    // knowledge` ratio fell to 0.7 after a restart). An unchanged graph writes nothing.
    let mut transaction = inner.start_transaction().map_err(storage)?;
    let mut stale = Vec::new();
    let mut kept: HashSet<Triple> = HashSet::new();
    for quad in transaction.quads_for_pattern(None, None, None, Some(INFERRED_GRAPH.into())) {
        let quad = quad.map_err(storage)?;
        let triple = Triple::from(quad.clone());
        if wanted.contains(&triple) {
            kept.insert(triple);
        } else {
            stale.push(quad);
        }
    }
    let fresh: Vec<Quad> = wanted
        .into_iter()
        .filter(|t| !kept.contains(t))
        .map(|t| t.in_graph(INFERRED_GRAPH))
        .collect();
    if stale.is_empty() && fresh.is_empty() {
        drop(transaction);
    } else {
        for quad in &stale {
            transaction.remove(quad);
        }
        transaction.extend(fresh.iter());
        transaction.commit().map_err(storage)?;
    }
    store.bump_generation();
    Ok(Refreshed {
        asserted: asserted.len(),
        inferred: count,
    })
}

/// The triples entailed by `asserted` that are not asserted.
fn entailed_only(asserted: &HashSet<Triple>) -> Vec<Triple> {
    closure(asserted)
        .into_iter()
        .filter(|t| !asserted.contains(t))
        .collect()
}

/// The schema the rules use, read from the triples.
#[derive(Default)]
struct Schema {
    super_classes: HashMap<Term, Vec<Term>>,
    super_properties: HashMap<NamedNode, Vec<NamedNode>>,
    inverses: HashMap<NamedNode, Vec<NamedNode>>,
    symmetric: HashSet<NamedNode>,
    transitive: HashSet<NamedNode>,
}

impl Schema {
    fn read(triples: &HashSet<Triple>) -> Self {
        let mut direct_classes: HashMap<Term, Vec<Term>> = HashMap::new();
        let mut direct_properties: HashMap<NamedNode, Vec<NamedNode>> = HashMap::new();
        let mut schema = Schema::default();
        for t in triples {
            let p = t.predicate.as_ref();
            if p == rdfs::SUB_CLASS_OF {
                direct_classes
                    .entry(t.subject.clone().into())
                    .or_default()
                    .push(t.object.clone());
            } else if p == rdfs::SUB_PROPERTY_OF {
                if let (Some(s), Term::NamedNode(o)) = (named(&t.subject.clone().into()), &t.object)
                {
                    direct_properties.entry(s).or_default().push(o.clone());
                }
            } else if p == OWL_INVERSE_OF {
                if let (Some(s), Term::NamedNode(o)) = (named(&t.subject.clone().into()), &t.object)
                {
                    schema
                        .inverses
                        .entry(s.clone())
                        .or_default()
                        .push(o.clone());
                    schema.inverses.entry(o.clone()).or_default().push(s);
                }
            } else if p == rdf::TYPE
                && let Some(s) = named(&t.subject.clone().into())
            {
                if t.object == Term::NamedNode(OWL_SYMMETRIC.into_owned()) {
                    schema.symmetric.insert(s);
                } else if t.object == Term::NamedNode(OWL_TRANSITIVE.into_owned()) {
                    schema.transitive.insert(s);
                }
            }
        }
        schema.super_classes = transitive_closure(&direct_classes);
        schema.super_properties = transitive_closure(&direct_properties);
        schema
    }
}

fn named(term: &Term) -> Option<NamedNode> {
    match term {
        Term::NamedNode(n) => Some(n.clone()),
        _ => None,
    }
}

/// For each key, every node reachable through one or more edges (cycles are fine).
fn transitive_closure<T: Clone + Eq + std::hash::Hash>(
    direct: &HashMap<T, Vec<T>>,
) -> HashMap<T, Vec<T>> {
    let mut out = HashMap::new();
    for start in direct.keys() {
        let mut seen: HashSet<T> = HashSet::new();
        let mut stack: Vec<T> = direct.get(start).cloned().unwrap_or_default();
        while let Some(next) = stack.pop() {
            if seen.insert(next.clone())
                && let Some(more) = direct.get(&next)
            {
                stack.extend(more.iter().cloned());
            }
        }
        out.insert(start.clone(), seen.into_iter().collect());
    }
    out
}

/// Everything entailed by `asserted` under the rules, including `asserted` itself.
fn closure(asserted: &HashSet<Triple>) -> HashSet<Triple> {
    let schema = Schema::read(asserted);
    let mut all: HashSet<Triple> = asserted.clone();
    let mut frontier: Vec<Triple> = asserted.iter().cloned().collect();
    // Local rules (type, sub-property, inverse, symmetric) to a fixpoint; each new triple is
    // processed once. Transitivity is then closed per property, and its consequences fed back
    // through the local rules until nothing changes.
    loop {
        while let Some(t) = frontier.pop() {
            for derived in local_consequences(&schema, &t) {
                if all.insert(derived.clone()) {
                    frontier.push(derived);
                }
            }
        }
        for p in &schema.transitive {
            for derived in transitive_consequences(&all, p) {
                if all.insert(derived.clone()) {
                    frontier.push(derived);
                }
            }
        }
        if frontier.is_empty() {
            return all;
        }
    }
}

fn local_consequences(schema: &Schema, t: &Triple) -> Vec<Triple> {
    let mut out = Vec::new();
    if t.predicate.as_ref() == rdf::TYPE
        && let Some(supers) = schema.super_classes.get(&t.object)
    {
        for c in supers {
            out.push(Triple::new(t.subject.clone(), rdf::TYPE, c.clone()));
        }
    }
    if let Some(supers) = schema.super_properties.get(&t.predicate) {
        for q in supers {
            out.push(Triple::new(t.subject.clone(), q.clone(), t.object.clone()));
        }
    }
    // Inverse and symmetric rules need the object to be a resource that can be a subject.
    let object_as_subject = match &t.object {
        Term::NamedNode(n) => Some(oxigraph::model::NamedOrBlankNode::from(n.clone())),
        Term::BlankNode(b) => Some(oxigraph::model::NamedOrBlankNode::from(b.clone())),
        _ => None,
    };
    if let Some(o) = object_as_subject {
        let s: Term = t.subject.clone().into();
        if schema.symmetric.contains(&t.predicate) {
            out.push(Triple::new(o.clone(), t.predicate.clone(), s.clone()));
        }
        if let Some(inverses) = schema.inverses.get(&t.predicate) {
            for q in inverses {
                out.push(Triple::new(o.clone(), q.clone(), s.clone()));
            }
        }
    }
    out
}

fn transitive_consequences(all: &HashSet<Triple>, p: &NamedNode) -> Vec<Triple> {
    let mut edges: HashMap<Term, Vec<Term>> = HashMap::new();
    for t in all.iter().filter(|t| &t.predicate == p) {
        edges
            .entry(t.subject.clone().into())
            .or_default()
            .push(t.object.clone());
    }
    let reach = transitive_closure(&edges);
    let mut out = Vec::new();
    for (s, targets) in reach {
        let subject = match s {
            Term::NamedNode(n) => oxigraph::model::NamedOrBlankNode::from(n),
            Term::BlankNode(b) => oxigraph::model::NamedOrBlankNode::from(b),
            _ => continue,
        };
        for o in targets {
            out.push(Triple::new(subject.clone(), p.clone(), o));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use oxigraph::io::RdfFormat;

    const DATA: &str = r#"
        @prefix rdfs: <http://www.w3.org/2000/01/rdf-schema#> .
        @prefix owl: <http://www.w3.org/2002/07/owl#> .
        @prefix : <http://example.org/> .
        :Room rdfs:subClassOf :Place . :Place rdfs:subClassOf :Thing .
        :isDirectlyInsideOf rdfs:subPropertyOf :isInsideOf .
        :isInsideOf a owl:TransitiveProperty ; owl:inverseOf :contains .
        :isConnectedTo a owl:SymmetricProperty .
        :kitchen a :Room ; :isDirectlyInsideOf :floor1 ; :isConnectedTo :hall .
        :floor1 :isDirectlyInsideOf :building .
    "#;

    fn ask(store: &KnowledgeStore, pattern: &str) -> bool {
        let q = format!("PREFIX : <http://example.org/> ASK {{ GRAPH ?g {{ {pattern} }} }}");
        match oxigraph::sparql::SparqlEvaluator::new()
            .parse_query(&q)
            .unwrap()
            .on_store(store.embedded().unwrap())
            .execute()
            .unwrap()
        {
            oxigraph::sparql::QueryResults::Boolean(b) => b,
            _ => panic!("not a boolean"),
        }
    }

    #[test]
    fn entailments_are_materialised_and_rebuilt() {
        let store = KnowledgeStore::in_memory().unwrap();
        store
            .embedded()
            .unwrap()
            .load_from_slice(
                oxigraph::io::RdfParser::from_format(RdfFormat::Turtle)
                    .with_default_graph(NamedNodeRef::new_unchecked("http://example.org/g")),
                DATA.as_bytes(),
            )
            .unwrap();
        let r = refresh(&store).unwrap();
        assert!(r.inferred > 0);
        assert!(ask(&store, ":kitchen a :Thing"));
        assert!(ask(&store, ":kitchen :isInsideOf :building"));
        assert!(ask(&store, ":building :contains :kitchen"));
        assert!(ask(&store, ":hall :isConnectedTo :kitchen"));
        // A second refresh is idempotent.
        assert_eq!(refresh(&store).unwrap(), r);
        // Removing the assertion removes its consequences.
        store
            .embedded()
            .unwrap()
            .update("PREFIX : <http://example.org/> DELETE WHERE { GRAPH ?g { :floor1 :isDirectlyInsideOf :building } }")
            .unwrap();
        refresh(&store).unwrap();
        assert!(!ask(&store, ":kitchen :isInsideOf :building"));
        assert!(ask(&store, ":kitchen :isInsideOf :floor1"));
    }

    #[test]
    fn a_refresh_removes_what_is_no_longer_entailed_and_adds_what_is_missing() {
        let store = KnowledgeStore::in_memory().unwrap();
        let embedded = store.embedded().unwrap();
        embedded
            .load_from_slice(
                oxigraph::io::RdfParser::from_format(RdfFormat::Turtle)
                    .with_default_graph(NamedNodeRef::new_unchecked("http://example.org/g")),
                DATA.as_bytes(),
            )
            .unwrap();
        let first = refresh(&store).unwrap();
        let inferred = || {
            embedded
                .quads_for_pattern(None, None, None, Some(INFERRED_GRAPH.into()))
                .map(|q| q.unwrap())
                .collect::<HashSet<_>>()
        };
        let before = inferred();
        assert_eq!(before.len(), first.inferred);
        // Unchanged: the same graph.
        assert_eq!(refresh(&store).unwrap(), first);
        assert_eq!(inferred(), before);
        // A stray quad goes, a lost one comes back.
        let lost = before.iter().next().unwrap().clone();
        embedded.remove(&lost).unwrap();
        let stray = Quad::new(
            NamedNode::new_unchecked("http://example.org/stray"),
            rdf::TYPE,
            NamedNode::new_unchecked("http://example.org/Thing"),
            INFERRED_GRAPH,
        );
        embedded.insert(&stray).unwrap();
        assert_eq!(refresh(&store).unwrap(), first);
        assert_eq!(inferred(), before);
    }
}
