"""The knowledge service through the client, against the real binary: who a token is, places
and robots, a shared ROS map imported and downloaded again, SDF and URDF, on-demand databases
parsed into rdflib graphs and queried with SPARQL, object reports and people counts."""

from __future__ import annotations

from pathlib import Path

import pytest
import rdflib
from conftest import KITCHEN, ROBOT_IRI, read_pgm

from mentalsim_client import Box, Client, Colour, Cylinder, ImportedMap, MentalsimError, PeopleCount, Sphere

TOSM = rdflib.Namespace("https://mentalsim.dev/ontology/tosm#")
SAMPLE_F0 = "https://mentalsim.dev/data/buildings/sample-building/floors/0"


def test_a_token_says_who_holds_it(engineer: Client, robot: Client) -> None:
    assert engineer.me().role == "engineer"
    me = robot.me()
    assert me.role == "robot" and me.name == ROBOT_IRI


def test_places_and_robots(robot: Client) -> None:
    places = {p.id: p for p in robot.places()}
    assert places["F0"].kind == "floor" and places["F0"].iri == SAMPLE_F0
    assert places["F0-hall"].parent == SAMPLE_F0
    f0 = robot.place(SAMPLE_F0)  # by IRI, percent-encoded in the path
    assert f0.id == "F0" and f0.map is not None and f0.map.resolution > 0
    assert len(f0.boundary) >= 3
    robots = robot.robots()
    # The thesis's robot and the TIAGo-like base are bundled.
    assert sorted(r.iri for r in robots) == sorted([ROBOT_IRI, "https://mentalsim.dev/data/robots/tiago-base"])
    tiago = next(r for r in robots if r.id == "TB-001")
    assert tiago.footprint is not None and tiago.lasers >= 1
    r = robot.robot("R-001")
    assert r.iri == ROBOT_IRI and r.lasers >= 1 and r.footprint is not None and r.wheel_separation
    urdf = robot.robot_urdf("R-001")
    assert "<robot" in urdf and "base_link" in urdf
    # The same robot for gz-sim, and the bridge of its topics to ROS 2.
    sdf = robot.robot_sdf("R-001")
    assert '<sdf version="1.9">' in sdf and "gz-sim-diff-drive-system" in sdf and 'type="gpu_lidar"' in sdf
    bridge = robot.robot_bridge_yaml("R-001", world="kitchen")
    assert "ros_topic_name: /scan" in bridge.replace('"', "") and "/world/kitchen/clock" in bridge


def test_a_shared_ros_map_imports_as_a_floor(engineer: Client, kitchen: str, shared_map: Path) -> None:
    place = engineer.place(kitchen)
    assert place.kind == "floor" and place.iri.endswith(f"/{KITCHEN}")
    assert place.map is not None
    w, h, _, _ = read_pgm(shared_map.with_suffix(".pgm").read_bytes())
    assert (place.map.width, place.map.height, place.map.resolution) == (w, h, 0.05)
    assert place.map.origin[:2] == [-2.549999999999997, -6.25]


def test_a_downloaded_map_imports_to_the_same_grid(engineer: Client, kitchen: str, tmp_path: Path) -> None:
    yaml, pgm = engineer.download_map(kitchen, tmp_path / "kitchen")
    assert yaml.name == "map.yaml" and pgm.name == "map.pgm"
    assert "image: map.pgm" in yaml.read_text() and "mode: trinary" in yaml.read_text()
    w, h, maxval, pixels = read_pgm(pgm.read_bytes())
    assert (w, h) == (148, 238) and set(pixels) <= {0, 205, 254}
    again = engineer.import_map("kitchen-again", yaml)
    assert isinstance(again, ImportedMap)
    first = engineer.place(kitchen).map
    assert first is not None
    assert (again.width, again.height, again.resolution, again.free_area_m2) == (first.width, first.height, first.resolution, first.free_area_m2)
    _, pgm2 = engineer.download_map("kitchen-again", tmp_path / "again")
    assert pgm2.read_bytes() == pgm.read_bytes()
    assert engineer.map_png(kitchen).startswith(b"\x89PNG")


def test_a_floor_exports_as_an_sdf_world(robot: Client, kitchen: str) -> None:
    sdf = robot.world_sdf(kitchen)
    assert sdf.lstrip().startswith("<?xml") and "<sdf" in sdf and "<world" in sdf
    assert "gz-sim-diff-drive-system" not in sdf
    # With a pose, the robot's gz-sim model stands there.
    placed = robot.world_sdf(kitchen, robot="R-001", at=(1.0, -2.0, 0.5))
    assert "gz-sim-diff-drive-system" in placed and "<pose>1 -2 0 0 0 0.5</pose>" in placed


def test_a_missions_on_demand_database_is_an_rdflib_graph(robot: Client) -> None:
    db = robot.on_demand_database("R-001", "F0-living-room", ["F0-hall"])
    assert isinstance(db, rdflib.Graph)
    assert db.media_type == "text/turtle"
    assert len(db) == db.triple_count and len(db) > 100
    assert db.route[0].endswith("/living-room") and db.route[-1].endswith("/hall")
    rows = db.query(
        """
        PREFIX tosm: <https://mentalsim.dev/ontology/tosm#>
        SELECT ?place ?name WHERE { ?place tosm:name ?name ; tosm:isDirectlyInsideOf ?floor .
                                    ?floor a tosm:Floor . } ORDER BY ?place
        """
    )
    places = {str(r[0]) for r in rows}  # type: ignore[index]
    assert set(db.route) <= places, (db.route, places)
    assert (rdflib.URIRef(ROBOT_IRI), rdflib.RDF.type, None) in db


def test_on_demand_databases_come_in_three_formats(robot: Client, kitchen: str) -> None:
    graphs = {fmt: robot.floor_database(kitchen, "R-001", format=fmt) for fmt in ("turtle", "ntriples", "jsonld")}
    for fmt, g in graphs.items():
        assert len(g) == g.triple_count, fmt
        assert g.floor is not None and g.floor.endswith(f"/{KITCHEN}") and g.robot == ROBOT_IRI
        assert g.etag
    assert set(graphs["turtle"]) == set(graphs["ntriples"]) == set(graphs["jsonld"])
    # A mission between two points of the kitchen floor: its route is the floor.
    db = robot.on_demand_database("R-001", (3.4, -5.2), [(-0.44, 4.26)], floor=kitchen, format="jsonld")
    assert db.route == [graphs["turtle"].floor]
    assert len(db) == db.triple_count


def test_a_robot_reports_objects_and_they_reach_the_database(robot: Client, kitchen: str) -> None:
    first = robot.report_object(
        kitchen, "Table", (1.5, -4.5, 0.3), Box(1.2, 0.8, 0.75), id="table-1", name="Kitchen table", colour=Colour(0.5, 0.3, 0.1), mass_kg=20.0
    )
    assert not first.updated and first.iri.endswith("/objects/table-1") and first.reported_by == ROBOT_IRI
    again = robot.report_object(kitchen, "Table", (1.6, -4.5, 0.3), Box(1.2, 0.8, 0.75), id="table-1")
    assert again.updated and again.iri == first.iri
    robot.report_object(kitchen, "Bin", (4.3, 5.2), Cylinder(0.3, 0.5), id="bin-1")
    robot.report_object(kitchen, "Object", (-2.0, 5.1), Sphere(0.2), z=0.1, id="ball-1", colour=Colour(1.0, 0.0, 0.0, 0.5))
    seen = {o.iri.rsplit("/", 1)[-1]: o for o in robot.objects(kitchen)}
    assert {"table-1", "bin-1", "ball-1"} <= set(seen)
    table = seen["table-1"]
    assert table.shape == "box" and table.size == [1.2, 0.8, 0.75]
    assert table.pose[0] == 1.6 and table.cls is not None and table.cls.endswith("Table")
    assert seen["bin-1"].shape == "cylinder" and seen["ball-1"].shape == "sphere"
    db = robot.floor_database(kitchen)
    rows = list(
        db.query(
            """
            PREFIX tosm: <https://mentalsim.dev/ontology/tosm#>
            SELECT ?o ?by WHERE { ?o a tosm:Table ; tosm:identifier "table-1" ; tosm:reportedBy ?by . }
            """
        )
    )
    assert [(str(r[0]), str(r[1])) for r in rows] == [(first.iri, ROBOT_IRI)]  # type: ignore[index]


def test_a_robot_reports_people_counts_and_the_estimate_reaches_the_database(robot: Client) -> None:
    # Counts in the sample building's office: 3 at 09:15 local time, then 1 made now.
    first = robot.report_people("F0-office", [PeopleCount(3, "2025-05-06T09:15:00+02:00"), 1])
    office = f"{SAMPLE_F0}/office"
    assert first.place == office and first.accepted == 2
    assert (first.estimate.people, first.estimate.observations, first.estimate.hour) == (2.0, 2, None)
    assert [(h.hour, h.people, h.observations) for h in first.by_hour] == [(9, 3.0, 1)]
    assert first.by_hour[0].last_observed_at == "2025-05-06T09:15:00+02:00"
    # The mean of the first five counts, then each new one weighs 0.2.
    then = robot.report_people("F0-office", [2, 6, 3, 13])
    assert then.estimate.observations == 6 and abs(then.estimate.people - (3.0 + 0.2 * 10.0)) < 1e-9
    # The floor's database carries the estimate to the simulation.
    db = robot.floor_database("F0")
    rows = list(
        db.query(
            """
            PREFIX tosm: <https://mentalsim.dev/ontology/tosm#>
            SELECT ?n ?count WHERE { ?place tosm:hasPeopleEstimate ?e . ?e tosm:estimatedPeople ?n ;
                                     tosm:observationCount ?count . FILTER NOT EXISTS { ?e tosm:hourOfDay ?h } }
            """,
            initBindings={"place": rdflib.URIRef(office)},
        )
    )
    assert [(str(r[0]), str(r[1])) for r in rows] == [("5", "6")]  # type: ignore[index]
    # A negative count is refused, naming it, and changes nothing.
    with pytest.raises(MentalsimError) as e:
        robot.report_people("F0-office", [1, -2])
    assert (e.value.status, e.value.code) == (422, "unprocessable")
    assert "observations[1].count" in e.value.message
    assert robot.report_people("F0-office", [5]).estimate.observations == 7
