"""Every HTTP operation the client calls, in one table.

The client sends requests only through this table (``Client._send`` looks the operation up by
its OpenAPI ``operationId``), and ``tests/test_openapi_in_step.py`` reads it: each operation must
exist in ``openapi/knowledge.json`` or ``openapi/fleet.json`` with the same method, path,
operation id, parameters, request body schema and response media types, so a change of the API
that the client does not follow fails a test.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final, Literal

JSON: Final = "application/json"
MULTIPART: Final = "multipart/form-data"


@dataclass(frozen=True, slots=True)
class Operation:
    """One operation of the REST API as the client calls it."""

    #: The OpenAPI ``operationId``.
    operation_id: str
    #: HTTP method, upper case.
    method: str
    #: The OpenAPI path template, with ``{id}`` style parameters.
    path: str
    #: Which committed OpenAPI document describes it.
    document: Literal["knowledge", "fleet"]
    #: Query parameters the client may send.
    query: tuple[str, ...] = ()
    #: Request headers the client may send besides ``Authorization`` and ``Accept``.
    headers: tuple[str, ...] = ()
    #: The request body's component schema, when there is a body.
    body: str | None = None
    #: The request body's media type.
    body_type: str | None = None
    #: Media types the client accepts in a successful answer (the first is the default).
    accept: tuple[str, ...] = (JSON,)


def _op(
    operation_id: str,
    method: str,
    path: str,
    document: Literal["knowledge", "fleet"],
    *,
    query: tuple[str, ...] = (),
    headers: tuple[str, ...] = (),
    body: str | None = None,
    body_type: str | None = None,
    accept: tuple[str, ...] = (JSON,),
) -> tuple[str, Operation]:
    return operation_id, Operation(
        operation_id, method, path, document, query, headers, body, body_type, accept
    )


RDF_TYPES: Final = ("text/turtle", "application/n-triples", "application/ld+json")

OPERATIONS: Final[dict[str, Operation]] = dict(
    [
        # The knowledge service (openapi/knowledge.json).
        _op("me", "GET", "/v1/me", "knowledge"),
        _op("list_places", "GET", "/v1/places", "knowledge"),
        _op("get_place", "GET", "/v1/places/{id}", "knowledge"),
        _op("place_map_yaml", "GET", "/v1/places/{id}/map.yaml", "knowledge", accept=("application/yaml",)),
        _op("place_map_pgm", "GET", "/v1/places/{id}/map.pgm", "knowledge", accept=("image/x-portable-graymap",)),
        _op("place_map", "GET", "/v1/places/{id}/map.png", "knowledge", accept=("image/png",)),
        _op("world_sdf", "GET", "/v1/places/{id}/world.sdf", "knowledge", query=("robot", "x", "y", "yaw"), accept=("application/xml",)),
        _op("list_objects", "GET", "/v1/places/{id}/objects", "knowledge"),
        _op("report_object", "POST", "/v1/places/{id}/objects", "knowledge", body="ObjectReport", body_type=JSON),
        _op("report_people_observations", "POST", "/v1/places/{id}/observations", "knowledge", body="PeopleObservations", body_type=JSON),
        _op("floor_on_demand_database", "GET", "/v1/places/{id}/on-demand", "knowledge", query=("robot",), accept=RDF_TYPES),
        _op("on_demand_database", "POST", "/v1/on-demand", "knowledge", body="OnDemandRequest", body_type=JSON, accept=RDF_TYPES),
        _op("import_map", "POST", "/v1/maps", "knowledge", body="MapUpload", body_type=MULTIPART),
        _op("list_robots", "GET", "/v1/robots", "knowledge"),
        _op("get_robot", "GET", "/v1/robots/{id}", "knowledge"),
        _op("robot_urdf", "GET", "/v1/robots/{id}/robot.urdf", "knowledge", accept=("application/xml",)),
        _op("robot_sdf", "GET", "/v1/robots/{id}/robot.sdf", "knowledge", accept=("application/xml",)),
        _op("bridge_yaml", "GET", "/v1/robots/{id}/bridge.yaml", "knowledge", query=("world",), accept=("application/yaml",)),
        # Plans, roadmaps, jobs and policies (openapi/fleet.json).
        _op("plan", "POST", "/v1/plan", "fleet", body="PlanApiRequest", body_type=JSON, accept=(JSON, "application/x-mcap")),
        _op("get_roadmap", "GET", "/v1/roadmaps", "fleet", query=("place", "robot", "policy", "safety_margin_m")),
        _op("route_graph", "GET", "/v1/places/{id}/route-graph.geojson", "fleet", query=("robot", "policy"), accept=("application/geo+json",)),
        _op("floor_traffic", "GET", "/v1/places/{id}/traffic", "fleet", query=("robot",)),
        _op("floor_traffic_events", "GET", "/v1/places/{id}/traffic/events", "fleet", query=("robot",), accept=("text/event-stream",)),
        _op("stand", "POST", "/v1/places/{id}/traffic/standing", "fleet", body="Standing", body_type=JSON),
        _op("get_plan", "GET", "/v1/plans/{id}", "fleet", query=("wait_s",), headers=("If-None-Match",)),
        _op("cancel_plan", "DELETE", "/v1/plans/{id}", "fleet"),
        _op("report_progress", "POST", "/v1/plans/{id}/progress", "fleet", body="Progress", body_type=JSON),
        _op("create_job", "POST", "/v1/jobs", "fleet", body="NewJobRequest", body_type=JSON),
        _op("list_jobs", "GET", "/v1/jobs", "fleet", query=("state", "kind", "limit")),
        _op("get_job", "GET", "/v1/jobs/{id}", "fleet"),
        _op("cancel_job", "POST", "/v1/jobs/{id}/cancel", "fleet"),
        _op("job_events", "GET", "/v1/jobs/{id}/events", "fleet", query=("after",), headers=("Last-Event-ID",), accept=("text/event-stream",)),
        _op("job_curves_csv", "GET", "/v1/jobs/{id}/curves.csv", "fleet", accept=("text/csv",)),
        _op("job_curves_png", "GET", "/v1/jobs/{id}/curves.png", "fleet", accept=("image/png",)),
        _op("list_policies", "GET", "/v1/policies", "fleet"),
        _op("get_policy", "GET", "/v1/policies/{id}", "fleet"),
        _op("policy_metadata", "GET", "/v1/policies/{id}/policy.json", "fleet"),
        _op("policy_weights", "GET", "/v1/policies/{id}/policy.safetensors", "fleet", accept=("application/octet-stream",)),
    ]
)
