"""The client kept in step with the committed OpenAPI documents (no service needed).

1. Every operation of the client's table (``mentalsim_client.OPERATIONS``) exists in
   openapi/knowledge.json or openapi/fleet.json with that method, path, operationId, path,
   query and header parameters, request body schema and success media types; and every
   operation of the documents is in the table, so a new endpoint fails here until the client
   has it.
2. Every public method of ``Client`` is called with every optional argument, through a
   transport that records the requests: each request is an operation of the table, its query
   parameters and headers are documented, and its body has only fields of the referenced schema
   and every required one, and validates against it (JSON Schema 2020-12, as OpenAPI 3.1).
"""

from __future__ import annotations

import inspect
import json
from datetime import datetime, timedelta, timezone
from pathlib import Path
from typing import Any, Callable

import httpx
import pytest
from openapi_check import METHODS, document, request_problems, table_problems

from mentalsim_client import (
    OPERATIONS,
    Box,
    Client,
    Colour,
    Cylinder,
    MentalsimError,
    PeopleCount,
    PlanOptions,
    Sphere,
)

FLOOR_IRI = "https://mentalsim.dev/data/buildings/sample-building/floors/0"
JOB = "01900000-0000-7000-8000-000000000000"


def test_every_operation_of_the_table_is_documented_as_the_client_calls_it() -> None:
    problems = [p for op in OPERATIONS.values() for p in table_problems(op)]
    assert not problems, "\n".join(problems)


def test_every_documented_operation_is_in_the_table() -> None:
    documented = set()
    for name in ("knowledge", "fleet"):
        for path, item in document(name)["paths"].items():
            for method in METHODS:
                if method in item:
                    documented.add((method.upper(), path, item[method].get("operationId")))
    table = {(op.method, op.path, op.operation_id) for op in OPERATIONS.values()}
    assert documented - table == set(), f"documented operations the client lacks: {sorted(documented - table)}"
    assert table - documented == set(), f"operations the client calls that are not documented: {sorted(table - documented)}"


# --------------------------------------------------------------------------------------------
# Every method, every option, recorded


class Recording(httpx.BaseTransport):
    """Records each request; answers non-JSON operations with a tiny 200 (so methods that make
    several requests go on) and JSON ones with an error body (the client raises)."""

    def __init__(self) -> None:
        self.requests: list[httpx.Request] = []

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        request.read()
        self.requests.append(request)
        accept = request.headers.get("accept", "")
        if accept == "text/event-stream":
            return httpx.Response(200, headers={"content-type": accept}, content=b"")
        if "json" not in accept and accept not in ("text/turtle", "application/n-triples"):
            return httpx.Response(200, headers={"content-type": accept}, content=b"x")
        body = {"error": {"code": "bad_request", "message": "recorded", "details": None}}
        return httpx.Response(418, json=body, headers={"x-request-id": "test"})


def calls(tmp: Path) -> dict[str, Callable[[Client], Any]]:
    yaml = tmp / "in" / "map.yaml"
    yaml.parent.mkdir()
    yaml.write_text("image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    (tmp / "in" / "map.pgm").write_bytes(b"P5\n1 1\n255\n\xfe")
    options = PlanOptions(
        max_attempts=2,
        max_replans=3,
        noise=False,
        roadmap="geometric",
        safety_margin_m=0.2,
        samples=300,
        seed=7,
        shortcut=True,
        trace=True,
        trajectory_stride=5,
        waypoint_timeout_s=20.0,
        people=1.5,
        people_hour=12,
        people_draws=2,
        controller="mppi",
        commit=False,
        start_time_ms=1_800_000_000_000,
        tolerance_s=3.0,
        max_wait_s=60.0,
        hold_s=10.0,
    )
    config = {"td3": {"hidden": [16, 16]}}
    return {
        "me": lambda c: c.me(),
        "places": lambda c: c.places(),
        "place": lambda c: c.place(FLOOR_IRI),
        "robots": lambda c: c.robots(),
        "robot": lambda c: c.robot("R-001"),
        "robot_urdf": lambda c: c.robot_urdf("R-001"),
        "robot_sdf": lambda c: c.robot_sdf("R-001"),
        "robot_bridge_yaml": lambda c: c.robot_bridge_yaml("R-001"),
        "robot_bridge_yaml (world)": lambda c: c.robot_bridge_yaml("R-001", world="F0"),
        "world_sdf": lambda c: c.world_sdf("F0"),
        "world_sdf (robot)": lambda c: c.world_sdf("F0", robot="R-001", at=(0.5, -2.0, 1.0)),
        "map_png": lambda c: c.map_png("F0"),
        "download_map": lambda c: c.download_map("F0-hall", tmp / "map"),
        "import_map": lambda c: c.import_map("a-map", yaml),
        "objects": lambda c: c.objects("F0"),
        "report_object": lambda c: c.report_object(
            "F0-hall", "Table", (1.0, 2.0, 0.5), Box(1.2, 0.8, 0.75), z=0.4, id="t-1", name="A table", colour=Colour(0.5, 0.3, 0.1, 1.0), mass_kg=12.5
        ),
        "report_object (cylinder)": lambda c: c.report_object("F0-hall", "Bin", (1.0, 2.0), Cylinder(0.3, 0.5)),
        "report_object (sphere)": lambda c: c.report_object("F0-hall", "Object", (1.0, 2.0), Sphere(0.2), colour=Colour(1, 0, 0)),
        "report_people": lambda c: c.report_people(
            "F0-hall", [PeopleCount(2, datetime(2025, 5, 6, 12, 30, tzinfo=timezone(timedelta(hours=2)))), PeopleCount(1.5, "2025-05-06T12:40:00Z"), 3]
        ),
        "on_demand_database": lambda c: c.on_demand_database("R-001", "F0-living-room", ["F0-hall", (1.0, 2.0)], floor="F0", format="jsonld"),
        "floor_database": lambda c: c.floor_database("F0", "R-001", format="ntriples"),
        "plan": lambda c: c.plan("R-001", "F0", (0.5, -2.0, 1.57), (-12.0, -1.0), policy="p-1", options=options),
        "plan (goals)": lambda c: c.plan("R-001", "F0", (0.5, -2.0), goals=[(-12.0, -1.0), (0.0, 0.0)], options=PlanOptions()),
        "plan_recording": lambda c: c.plan_recording("R-001", "F0", (0.5, -2.0, 1.57), (-12.0, -1.0), options=options),
        "roadmap": lambda c: c.roadmap("F0", "R-001", policy="p-1", safety_margin_m=0.2),
        "route_graph": lambda c: c.route_graph("F0", "R-001", policy="p-1"),
        "traffic": lambda c: c.traffic("F0", "R-001"),
        "traffic_events": lambda c: list(c.traffic_events("F0", "R-001", reconnect=False)),
        "cancel_plan": lambda c: c.cancel_plan("plan-1"),
        "report_progress": lambda c: c.report_progress("plan-1", 1.0, 2.0, time_ms=5, revision=2),
        "plan_status": lambda c: c.plan_status("plan-1", etag='W/"2-00000000000000ff"', wait_s=5.0),
        "watch_plan": lambda c: list(c.watch_plan("plan-1", poll_s=5.0)),
        "stand": lambda c: c.stand("F0", "R-001", 1.0, 2.0, yaw=0.5, time_ms=5, for_s=60.0),
        "submit_job": lambda c: c.submit_job("train", {"robot": "R-001", "place": "F0", "minutes": 1}, priority=3, max_attempts=2),
        "submit_training": lambda c: c.submit_training("R-001", "F0", 0.5, config=config, seed=3, priority=1, max_attempts=1),
        "submit_evaluation": lambda c: c.submit_evaluation("p-1", "F0", episodes=4, seed=2, robot="R-001", goals_in_view=False, priority=1, max_attempts=1),
        "submit_roadmap": lambda c: c.submit_roadmap("p-1", "F0", robot="R-001", rollouts=2, keep_threshold=0.8, safety_margin_m=0.2, priority=1, max_attempts=1),
        "submit_validation": lambda c: c.submit_validation("R-001", "F0", (0.5, -2.0, 1.0), goals=[(-12.0, -1.0)], policy="p-1", options=options, priority=1, max_attempts=1),
        "job": lambda c: c.job(JOB),
        "jobs": lambda c: c.jobs(state="succeeded", kind="train", limit=10),
        "cancel_job": lambda c: c.cancel_job(JOB),
        "job_curves": lambda c: c.job_curves(JOB),
        "job_curves_png": lambda c: c.job_curves_png(JOB),
        "job_events": lambda c: list(c.job_events(JOB, after=3)),
        "wait_for_job": lambda c: c.wait_for_job(JOB, on_progress=print, on_event=print, timeout=5),
        "policies": lambda c: c.policies(),
        "policy": lambda c: c.policy("p-1"),
        "download_policy": lambda c: c.download_policy("p-1", tmp / "policy"),
    }


def test_every_request_the_client_sends_fits_the_documents(tmp_path: Path) -> None:
    transport = Recording()
    client = Client("http://mentalsim.invalid", "t", transport=transport)
    table = calls(tmp_path)
    # Every public request-making method is in the table above.
    public = {
        name
        for name, fn in inspect.getmembers(Client, predicate=inspect.isfunction)
        if not name.startswith("_") and name not in ("close", "load_policy")
    }
    assert public <= {k.split(" ")[0] for k in table}, f"methods this test does not call: {sorted(public - set(table))}"
    for name, call in table.items():
        try:
            call(client)
        except MentalsimError as e:
            assert e.status == 418 and e.message == "recorded", f"{name}: {e}"
    problems = []
    used = set()
    for r in transport.requests:
        raw = r.url.raw_path.decode()
        path = raw.partition("?")[0]
        query: dict[str, list[str]] = {}
        for k, v in r.url.params.multi_items():
            query.setdefault(k, []).append(v)
        headers = {k.lower(): v for k, v in r.headers.items()}
        op, p = request_problems(r.method, path, query, headers, r.headers.get("content-type", ""), r.content)
        problems += p
        if op is not None:
            used.add(op.operation_id)
    assert not problems, "\n".join(problems)
    assert used == set(OPERATIONS), f"operations no method called: {sorted(set(OPERATIONS) - used)}"


def test_ids_and_iris_travel_percent_encoded_in_paths(tmp_path: Path) -> None:
    transport = Recording()
    client = Client("http://mentalsim.invalid/", "t", transport=transport)
    with pytest.raises(MentalsimError):
        client.place(FLOOR_IRI)
    assert transport.requests[0].url.raw_path.decode() == "/v1/places/https%3A%2F%2Fmentalsim.dev%2Fdata%2Fbuildings%2Fsample-building%2Ffloors%2F0"
    assert transport.requests[0].headers["authorization"] == "Bearer t"


def test_the_request_bodies_are_what_the_api_documents(tmp_path: Path) -> None:
    """The JSON the main methods send, written out: a change shows here as a readable diff."""
    transport = Recording()
    client = Client("http://mentalsim.invalid", "t", transport=transport)
    with pytest.raises(MentalsimError):
        client.plan("R-001", "F0", (0.5, -2.0), (-12.0, -1.0), options=PlanOptions(seed=3, trace=True))
    with pytest.raises(MentalsimError):
        client.report_object("F0-hall", "Chair", (1.0, 2.0, 0.25), Box(0.5, 0.5, 0.9), id="c-1")
    with pytest.raises(MentalsimError):
        client.on_demand_database("R-001", (1.0, 2.0), ["F0-hall"], floor="F0")
    with pytest.raises(MentalsimError):
        client.report_people("F0-hall", [PeopleCount(2, datetime(2025, 5, 6, 12, 30, tzinfo=timezone.utc)), 0.5])
    bodies = [json.loads(r.content) for r in transport.requests]
    assert bodies == [
        {"robot": "R-001", "place": "F0", "start": {"x": 0.5, "y": -2.0, "yaw": 0.0}, "goal": {"x": -12.0, "y": -1.0}, "options": {"seed": 3, "trace": True}},
        {"class": "Chair", "pose": {"x": 1.0, "y": 2.0, "yaw": 0.25}, "shape": {"type": "box", "length": 0.5, "width": 0.5, "height": 0.9}, "id": "c-1"},
        {"robot": "R-001", "start": {"x": 1.0, "y": 2.0, "floor": "F0"}, "goals": [{"place": "F0-hall"}]},
        {"observations": [{"count": 2, "observed_at": "2025-05-06T12:30:00+00:00"}, {"count": 0.5}]},
    ]


def test_bad_arguments_are_refused_before_anything_is_sent() -> None:
    transport = Recording()
    client = Client("http://mentalsim.invalid", "t", transport=transport)
    with pytest.raises(ValueError):
        client.plan("R-001", "F0", (0, 0), (1, 1), goals=[(1, 1)])
    with pytest.raises(ValueError):
        client.plan("R-001", "F0", (0, 0))
    with pytest.raises(ValueError):
        client.plan("R-001", "F0", (0, 0, 0, 0), (1, 1))
    with pytest.raises(ValueError):
        client.on_demand_database("R-001", "F0-hall", [])
    with pytest.raises(ValueError):
        client.place("")
    assert transport.requests == []
