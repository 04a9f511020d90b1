#!/usr/bin/env python3
"""Runs the HermiT reasoner over the TOSM ontology, the bundled robots and environments.

Exits 0 when the merged ontology is consistent and has no unsatisfiable classes; non-zero
otherwise, naming what is wrong. Needs the PyPI packages `owlready2` (which ships HermiT) and
`rdflib`, and Java 17 or newer on PATH.

Usage: python3 tests/hermit/check_consistency.py [FILE.ttl ...]
(with no arguments: ontologies/tosm.ttl, ontologies/robots/*.ttl, ontologies/environments/*.ttl,
and tests/hermit/perceived-people.ttl: robots' people counts as the knowledge service stores them)
"""

import sys
import tempfile
from pathlib import Path

import rdflib
from rdflib.namespace import OWL

ROOT = Path(__file__).resolve().parents[2]


def default_files():
    ontologies = ROOT / "ontologies"
    files = [ontologies / "tosm.ttl"]
    files += sorted((ontologies / "robots").glob("*.ttl"))
    files += sorted((ontologies / "environments").glob("*.ttl"))
    # What robots' reports add to the graph, written by the service's own writer.
    files.append(ROOT / "tests" / "hermit" / "perceived-people.ttl")
    return files


def merged_graph(files):
    graph = rdflib.Graph()
    for path in files:
        graph.parse(path, format="turtle")
    # The data files import the TOSM ontology by IRI; every file is merged here instead, so
    # the reasoner must not try to fetch imports from the network.
    graph.remove((None, OWL.imports, None))
    return graph


def main(argv):
    import owlready2

    files = [Path(a) for a in argv[1:]] or default_files()
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        print("missing input files: " + ", ".join(missing), file=sys.stderr)
        return 2
    graph = merged_graph(files)
    print(f"loaded {len(graph)} triples from {len(files)} files:")
    for f in files:
        print(f"  {f}")

    with tempfile.TemporaryDirectory() as tmp:
        # Owlready2 reads RDF/XML and N-Triples best.
        merged = Path(tmp) / "merged.nt"
        graph.serialize(destination=merged, format="nt", encoding="utf-8")
        world = owlready2.World()
        onto = world.get_ontology(merged.as_uri()).load()
        try:
            with onto:
                owlready2.sync_reasoner_hermit(
                    world, infer_property_values=False, debug=0
                )
        except owlready2.OwlReadyInconsistentOntologyError as error:
            print(f"FAIL: the ontology is inconsistent: {error}", file=sys.stderr)
            print("0 passed, 1 failed")
            return 1
        unsatisfiable = [
            c for c in world.inconsistent_classes() if c is not owlready2.Nothing
        ]
        if unsatisfiable:
            print("FAIL: unsatisfiable classes:", file=sys.stderr)
            for cls in unsatisfiable:
                print(f"  {cls.iri}", file=sys.stderr)
            print("0 passed, 1 failed")
            return 1
    classes = len(list(world.classes()))
    individuals = len(list(world.individuals()))
    print(f"HermiT: consistent, {classes} classes all satisfiable, {individuals} individuals")
    print("1 passed, 0 failed")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
