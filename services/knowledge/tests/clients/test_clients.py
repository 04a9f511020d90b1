"""Real SPARQL clients against a running knowledge service, used exactly as their users do.

Run by `cargo test -p knowledge --test knowledge clients`, which starts the service and sets:
  MENTALSIM_SPARQL_URL  the service's base URL (e.g. http://127.0.0.1:4321)
  MENTALSIM_TOKEN       an engineer's bearer token

Standalone: `MENTALSIM_SPARQL_URL=... MENTALSIM_TOKEN=... python test_clients.py`.
"""

import os
import unittest
import uuid

import rdflib
from rdflib import Dataset, Graph, Literal, URIRef
from rdflib.graph import DATASET_DEFAULT_GRAPH_ID
from rdflib.plugins.stores.sparqlstore import SPARQLStore, SPARQLUpdateStore
from SPARQLWrapper import (
    CSV,
    JSON,
    JSONLD,
    N3,
    POST,
    POSTDIRECTLY,
    RDFXML,
    TSV,
    TURTLE,
    XML,
    SPARQLWrapper,
)
from SPARQLWrapper.SPARQLExceptions import QueryBadFormed

BASE = os.environ["MENTALSIM_SPARQL_URL"].rstrip("/")
TOKEN = os.environ.get("MENTALSIM_TOKEN", "")
ENDPOINT = BASE + "/sparql"
AUTH = {"Authorization": "Bearer " + TOKEN} if TOKEN else {}
EX = "http://example.org/clients/"


def wrapper(return_format=JSON):
    sparql = SPARQLWrapper(ENDPOINT, updateEndpoint=ENDPOINT, returnFormat=return_format)
    for name, value in AUTH.items():
        sparql.addCustomHttpHeader(name, value)
    return sparql


def fresh_graph_iri():
    return URIRef(EX + "graph/" + uuid.uuid4().hex)


class SPARQLWrapperTest(unittest.TestCase):
    """SPARQLWrapper adds format/output/results parameters and its own Accept headers."""

    @classmethod
    def setUpClass(cls):
        sparql = wrapper()
        sparql.setMethod(POST)
        sparql.setQuery(
            f"""PREFIX ex: <{EX}>
            INSERT DATA {{ GRAPH <{EX}wrapper> {{
                ex:kitchen a ex:Room ; ex:name "Kitchen" ; ex:area 12.5 .
                ex:hall a ex:Room ; ex:name "Hall" .
            }} }}"""
        )
        sparql.query()

    select = f"SELECT ?name FROM <{EX}wrapper> WHERE {{ ?r <{EX}name> ?name }} ORDER BY ?name"

    def test_select_in_every_results_format(self):
        for fmt in (JSON, XML, CSV, TSV):
            sparql = wrapper(fmt)
            sparql.setQuery(self.select)
            result = sparql.query()
            converted = result.convert()
            if fmt == JSON:
                names = [b["name"]["value"] for b in converted["results"]["bindings"]]
                self.assertEqual(names, ["Hall", "Kitchen"])
            elif fmt == XML:
                literals = [n.firstChild.data for n in converted.getElementsByTagName("literal")]
                self.assertEqual(literals, ["Hall", "Kitchen"])
            else:
                text = converted.decode("utf-8")
                self.assertIn("Kitchen", text, fmt)

    def test_select_by_post_form_and_post_direct(self):
        for request_method in (None, POSTDIRECTLY):
            sparql = wrapper(JSON)
            sparql.setMethod(POST)
            if request_method:
                sparql.setRequestMethod(request_method)
            sparql.setQuery(self.select)
            bindings = sparql.queryAndConvert()["results"]["bindings"]
            self.assertEqual(len(bindings), 2)

    def test_ask(self):
        sparql = wrapper(JSON)
        sparql.setQuery(f"ASK {{ GRAPH <{EX}wrapper> {{ <{EX}kitchen> a <{EX}Room> }} }}")
        self.assertIs(sparql.queryAndConvert()["boolean"], True)

    def test_construct_in_graph_formats(self):
        query = f"CONSTRUCT {{ ?r <{EX}label> ?n }} WHERE {{ GRAPH <{EX}wrapper> {{ ?r <{EX}name> ?n }} }}"
        for fmt in (TURTLE, N3, RDFXML, JSONLD, XML):
            sparql = wrapper(fmt)
            sparql.setQuery(query)
            converted = sparql.queryAndConvert()
            if isinstance(converted, bytes):
                graph = Graph().parse(data=converted, format="turtle")
            else:
                graph = converted
            self.assertEqual(len(graph), 2, fmt)

    def test_malformed_query_is_reported(self):
        sparql = wrapper(JSON)
        sparql.setQuery("SELECT * WHERE { ?s ?p ")
        with self.assertRaises(QueryBadFormed):
            sparql.query()


class RdflibStoreTest(unittest.TestCase):
    """rdflib's SPARQLStore and SPARQLUpdateStore, as a Graph and as a Dataset."""

    def update_store(self):
        store = SPARQLUpdateStore(headers=dict(AUTH))
        store.open((ENDPOINT, ENDPOINT))
        return store

    def test_named_graph_read_write(self):
        identifier = fresh_graph_iri()
        graph = Graph(store=self.update_store(), identifier=identifier)
        kitchen = URIRef(EX + "kitchen")
        graph.add((kitchen, rdflib.RDF.type, URIRef(EX + "Room")))
        graph.add((kitchen, URIRef(EX + "name"), Literal("Kitchen")))
        self.assertEqual(len(graph), 2)
        self.assertEqual(graph.value(kitchen, URIRef(EX + "name")), Literal("Kitchen"))
        rows = list(graph.query(f"SELECT ?n WHERE {{ ?s <{EX}name> ?n }}"))
        self.assertEqual([str(r[0]) for r in rows], ["Kitchen"])
        graph.remove((kitchen, URIRef(EX + "name"), None))
        self.assertEqual(len(graph), 1)

        # The read-only store sees the same graph.
        reader = SPARQLStore(ENDPOINT, headers=dict(AUTH))
        read_graph = Graph(store=reader, identifier=identifier)
        self.assertEqual(len(list(read_graph.triples((None, None, None)))), 1)

    def test_dataset_default_graph(self):
        # rdflib sends default-graph-uri=urn:x-rdflib:default for a Dataset's default graph.
        dataset = Dataset(store=self.update_store())
        subject = URIRef(EX + "dataset/" + uuid.uuid4().hex)
        dataset.add((subject, URIRef(EX + "p"), Literal(1)))
        rows = list(dataset.query(f"SELECT ?o WHERE {{ <{subject}> <{EX}p> ?o }}"))
        self.assertEqual([r[0].toPython() for r in rows], [1])
        self.assertIn((subject, URIRef(EX + "p"), Literal(1)), dataset.graph(DATASET_DEFAULT_GRAPH_ID))
        dataset.update(f"INSERT DATA {{ <{subject}> <{EX}q> 2 }}")
        rows = list(dataset.query(f"SELECT ?o WHERE {{ <{subject}> <{EX}q> ?o }}"))
        self.assertEqual([r[0].toPython() for r in rows], [2])
        # Named graphs of the dataset stay reachable through GRAPH.
        named = fresh_graph_iri()
        dataset.graph(named).add((subject, URIRef(EX + "r"), Literal(3)))
        rows = list(dataset.query(f"SELECT ?g WHERE {{ GRAPH ?g {{ <{subject}> <{EX}r> 3 }} }}"))
        self.assertEqual([r[0] for r in rows], [named])

    def test_sparql_store_select_ask_construct(self):
        store = SPARQLStore(ENDPOINT, headers=dict(AUTH))
        graph = Graph(store=store)
        self.assertTrue(graph.query("ASK {}").askAnswer)
        rows = list(graph.query("SELECT (1 + 1 AS ?two) WHERE {}"))
        self.assertEqual(rows[0][0].toPython(), 2)
        constructed = graph.query(f"CONSTRUCT {{ <{EX}s> <{EX}p> 1 }} WHERE {{}}").graph
        self.assertEqual(len(constructed), 1)


if __name__ == "__main__":
    unittest.main(verbosity=2)
