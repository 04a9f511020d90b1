//! TOSM vocabulary and typed model <-> RDF, with validation; no IO.
