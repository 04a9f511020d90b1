//! Knowledge service: TOSM graph store, SPARQL and Graph Store protocols, on-demand databases, map import.
