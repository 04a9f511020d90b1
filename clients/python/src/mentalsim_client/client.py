"""The synchronous client of Mentalsim's REST APIs (the knowledge service and the worker's plan,
jobs and policies endpoints), thin on httpx."""

from __future__ import annotations

import json
import os
import re
import string
import tempfile
import time
from collections.abc import Callable, Generator, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import TracebackType
from typing import Any, Final, Literal, TypeAlias
from urllib.parse import quote

import httpx
import rdflib

from ._operations import OPERATIONS, Operation
from .errors import MentalsimError
from .models import (
    Colour,
    FloorTraffic,
    TrafficEvent,
    Itinerary,
    Passing,
    PlanStatus,
    ProgressAnswer,
    ImportedMap,
    Job,
    JobEvent,
    JobKind,
    JobState,
    JsonObject,
    Me,
    PeopleCount,
    PeopleEstimates,
    Place,
    PlanOptions,
    PlanResult,
    PointLike,
    PolicySummary,
    PoseLike,
    ReportedObject,
    Roadmap,
    Robot,
    Shape,
    WorldObject,
    as_point,
    as_pose,
)
from .policy import Policy, load_policy
from .sse import parse_sse

__version__: Final = "0.1.0"

RdfFormat: TypeAlias = Literal["turtle", "ntriples", "jsonld"]
_RDF: Final[dict[str, tuple[str, str]]] = {
    # format -> (media type, rdflib parser)
    "turtle": ("text/turtle", "turtle"),
    "ntriples": ("application/n-triples", "nt"),
    "jsonld": ("application/ld+json", "json-ld"),
}
#: Seconds without a byte after which an event stream counts as dropped (the service sends a
#: keep-alive comment every 15 s).
EVENT_STREAM_IDLE_S: Final = 45.0

Waypoint: TypeAlias = str | PointLike
"""A waypoint of a mission: a place (IRI or identifier), or a point ``(x, y)`` on a floor."""


class OnDemandDatabase(rdflib.Graph):
    """An on-demand database: an :class:`rdflib.Graph` with what the service said about it."""

    #: Triples in it as the service counted them (``X-Triple-Count``).
    triple_count: int | None
    #: The IRIs of the places the mission's route crosses (``X-Route``; mission databases).
    route: list[str]
    #: The floor's IRI (``X-Floor``; floor databases).
    floor: str | None
    #: The robot's IRI (``X-Robot``; floor databases).
    robot: str | None
    #: The graph state's tag (``ETag``; floor databases).
    etag: str | None
    #: The media type it came in.
    media_type: str

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.triple_count = None
        self.route = []
        self.floor = None
        self.robot = None
        self.etag = None
        self.media_type = ""


class Client:
    """A client of one Mentalsim service.

    ``base_url`` is the service's URL (``http://127.0.0.1:8080``), ``token`` a bearer token (an
    engineer's or a robot's: each method needs what the API says its operation needs),
    ``timeout`` the seconds a request may take (plans rehearse in the simulation: keep it at
    least the service's ``request_timeout_s``, 120 by default). ``transport`` replaces httpx's
    (tests, proxies). Use it as a context manager, or call :meth:`close`.

    Every failed request raises :class:`MentalsimError`.
    """

    def __init__(
        self,
        base_url: str,
        token: str,
        *,
        timeout: float = 120.0,
        transport: httpx.BaseTransport | None = None,
    ) -> None:
        self.base_url = base_url.rstrip("/")
        self.timeout = timeout
        self._http = httpx.Client(
            base_url=self.base_url,
            headers={"Authorization": f"Bearer {token}", "User-Agent": f"mentalsim-client/{__version__}"},
            timeout=timeout,
            transport=transport,
        )

    # ---- lifecycle ----

    def close(self) -> None:
        """Closes the connections."""
        self._http.close()

    def __enter__(self) -> Client:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    # ---- plumbing: every request goes through the operation table ----

    @staticmethod
    def _url(op: Operation, path: Mapping[str, str] | None) -> str:
        names = [n for _, n, _, _ in string.Formatter().parse(op.path) if n]
        given = dict(path or {})
        if sorted(names) != sorted(given):
            raise ValueError(f"{op.operation_id}: path parameters {names}, got {sorted(given)}")
        if any(v == "" for v in given.values()):
            raise ValueError(f"{op.operation_id}: an empty path parameter")
        return op.path.format_map({k: quote(v, safe="") for k, v in given.items()})

    @staticmethod
    def _params(op: Operation, query: Mapping[str, object] | None) -> dict[str, str]:
        params: dict[str, str] = {}
        for key, value in (query or {}).items():
            if key not in op.query:
                raise ValueError(f"{op.operation_id}: no query parameter `{key}`")
            if value is None:
                continue
            params[key] = json.dumps(value) if isinstance(value, bool) else str(value)
        return params

    @staticmethod
    def _headers(op: Operation, headers: Mapping[str, str] | None, accept: str | None) -> dict[str, str]:
        out = {"Accept": accept or op.accept[0]}
        if accept is not None and accept not in op.accept:
            raise ValueError(f"{op.operation_id}: answers {op.accept}, not {accept}")
        for key, value in (headers or {}).items():
            if key not in op.headers:
                raise ValueError(f"{op.operation_id}: no header `{key}`")
            out[key] = value
        return out

    def _send(
        self,
        operation_id: str,
        *,
        path: Mapping[str, str] | None = None,
        query: Mapping[str, object] | None = None,
        headers: Mapping[str, str] | None = None,
        json_body: object = None,
        files: Mapping[str, tuple[str | None, bytes | str, str]] | None = None,
        accept: str | None = None,
    ) -> httpx.Response:
        op = OPERATIONS[operation_id]
        if (json_body is not None or files is not None) != (op.body is not None):
            raise ValueError(f"{operation_id}: a body {'is' if op.body else 'is not'} expected")
        request = self._http.build_request(
            op.method,
            self._url(op, path),
            params=self._params(op, query),
            headers=self._headers(op, headers, accept),
            json=json_body,
            files=dict(files) if files is not None else None,
        )
        try:
            response = self._http.send(request)
        except httpx.TransportError as e:
            raise MentalsimError.from_transport(e, operation_id) from e
        if response.is_error:
            raise MentalsimError.from_response(response, operation_id)
        return response

    def _json(self, operation_id: str, **kwargs: Any) -> Any:
        response = self._send(operation_id, **kwargs)
        try:
            return response.json()
        except ValueError as e:
            raise MentalsimError(
                response.status_code,
                "bad_response",
                f"the answer is not JSON: {response.text[:200]!r}",
                operation=operation_id,
            ) from e

    def _object(self, operation_id: str, **kwargs: Any) -> JsonObject:
        value = self._json(operation_id, **kwargs)
        if not isinstance(value, dict):
            raise MentalsimError(None, "bad_response", f"expected a JSON object, got {type(value).__name__}", operation=operation_id)
        return value

    def _array(self, operation_id: str, **kwargs: Any) -> list[JsonObject]:
        value = self._json(operation_id, **kwargs)
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise MentalsimError(None, "bad_response", "expected a JSON array of objects", operation=operation_id)
        return value

    @contextmanager
    def _stream(
        self,
        operation_id: str,
        *,
        path: Mapping[str, str],
        query: Mapping[str, object] | None = None,
        headers: Mapping[str, str] | None = None,
    ) -> Iterator[httpx.Response]:
        op = OPERATIONS[operation_id]
        request = self._http.build_request(
            op.method,
            self._url(op, path),
            params=self._params(op, query),
            headers=self._headers(op, headers, None),
            timeout=httpx.Timeout(self.timeout, read=EVENT_STREAM_IDLE_S),
        )
        try:
            response = self._http.send(request, stream=True)
        except httpx.TransportError as e:
            raise MentalsimError.from_transport(e, operation_id) from e
        try:
            if response.is_error:
                response.read()
                raise MentalsimError.from_response(response, operation_id)
            yield response
        finally:
            response.close()

    # ---- who am I ----

    def me(self) -> Me:
        """The token's holder and role (``engineer`` or ``robot``)."""
        return Me.from_json(self._object("me"))

    # ---- knowledge: places, robots, maps, objects, people counts ----

    def places(self) -> list[Place]:
        """Every place, buildings to rooms."""
        return [Place.from_json(p) for p in self._array("list_places")]

    def place(self, place: str) -> Place:
        """One place by IRI or identifier."""
        return Place.from_json(self._object("get_place", path={"id": place}))

    def robots(self) -> list[Robot]:
        """Every robot model."""
        return [Robot.from_json(r) for r in self._array("list_robots")]

    def robot(self, robot: str) -> Robot:
        """One robot by IRI or identifier."""
        return Robot.from_json(self._object("get_robot", path={"id": robot}))

    def robot_urdf(self, robot: str) -> str:
        """The robot as URDF (ROS, Gazebo)."""
        return self._send("robot_urdf", path={"id": robot}).text

    def robot_sdf(self, robot: str) -> str:
        """The robot as an SDF 1.9 model for gz-sim (diff-drive system, ``gpu_lidar``)."""
        return self._send("robot_sdf", path={"id": robot}).text

    def robot_bridge_yaml(self, robot: str, world: str | None = None) -> str:
        """The ``ros_gz_bridge`` configuration (YAML) for the robot's topics in gz-sim; with
        ``world`` (the name of the gz-sim world it runs in) the clock is that world's."""
        query = {"world": world} if world is not None else None
        return self._send("bridge_yaml", path={"id": robot}, query=query).text

    def world_sdf(self, place: str, *, robot: str | None = None, at: PoseLike | None = None) -> str:
        """The SDF 1.9 world of the floor ``place`` is on, for gz-sim; with ``at`` (``(x, y)``
        or ``(x, y, yaw)`` in the map frame) ``robot`` (default: the first one) stands in it."""
        query: dict[str, object] = {}
        if robot is not None:
            query["robot"] = robot
        if at is not None:
            pose = as_pose(at)
            query.update(x=pose.x, y=pose.y, yaw=pose.yaw)
        return self._send("world_sdf", path={"id": place}, query=query or None).text

    def map_png(self, place: str) -> bytes:
        """A floor's occupancy grid as a PNG (free 254, occupied 0, unknown 205)."""
        return self._send("place_map", path={"id": place}).content

    def download_map(self, place: str, directory: str | os.PathLike[str]) -> tuple[Path, Path]:
        """Writes the floor ``place`` is on as nav2's ``map_server`` loads it: ``map.yaml`` and
        ``map.pgm`` in ``directory`` (created). Returns their paths."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        yaml = self._send("place_map_yaml", path={"id": place}).content
        pgm = self._send("place_map_pgm", path={"id": place}).content
        return _write_atomic(out / "map.yaml", yaml), _write_atomic(out / "map.pgm", pgm)

    def import_map(
        self,
        name: str,
        yaml: str | os.PathLike[str],
        image: str | os.PathLike[str] | None = None,
    ) -> ImportedMap:
        """Imports a ROS ``map_server`` map as a floor named ``name`` (a-z, 0-9, ``-``, ``_``;
        importing a name again replaces that floor). ``yaml`` is the map's YAML file; ``image``
        its PGM or PNG, by default the file the YAML's ``image`` key names beside it. Engineers
        only."""
        yaml_path = Path(yaml)
        yaml_text = yaml_path.read_text(encoding="utf-8")
        if image is None:
            m = re.search(r"^image:\s*(.+?)\s*$", yaml_text, re.M)
            if not m:
                raise ValueError(f"{yaml_path}: no `image` key; pass the image")
            image_path = yaml_path.parent / m.group(1).strip("'\"")
        else:
            image_path = Path(image)
        files: dict[str, tuple[str | None, bytes | str, str]] = {
            "name": (None, name, "text/plain"),
            "yaml": (yaml_path.name, yaml_text.encode("utf-8"), "application/yaml"),
            "image": (image_path.name, image_path.read_bytes(), "application/octet-stream"),
        }
        return ImportedMap.from_json(self._object("import_map", files=files))

    def objects(self, place: str) -> list[WorldObject]:
        """Every object on the floor ``place`` is on, as the simulation builds it."""
        return [WorldObject.from_json(o) for o in self._array("list_objects", path={"id": place})]

    def report_object(
        self,
        place: str,
        cls: str,
        pose: PoseLike,
        shape: Shape,
        *,
        z: float | None = None,
        id: str | None = None,
        name: str | None = None,
        colour: Colour | None = None,
        mass_kg: float | None = None,
    ) -> ReportedObject:
        """Reports an object the robot perceived in ``place`` (a floor, room, corridor or hall):
        its TOSM class (``Table``, ``Chair``, ``Door``, ... or a class IRI), pose ``(x, y, yaw)``
        in the floor frame (``z``: height of its centre, default resting on the floor), shape
        (:class:`Box`, :class:`Cylinder`, :class:`Sphere`). Reporting the same ``id`` again
        updates it (``updated`` says so). Robots and engineers."""
        p = as_pose(pose)
        pose_json: JsonObject = {"x": p.x, "y": p.y, "yaw": p.yaw}
        if z is not None:
            pose_json["z"] = z
        body: JsonObject = {"class": cls, "pose": pose_json, "shape": shape.to_json()}
        if id is not None:
            body["id"] = id
        if name is not None:
            body["name"] = name
        if colour is not None:
            body["colour"] = colour.to_json()
        if mass_kg is not None:
            body["mass_kg"] = mass_kg
        return ReportedObject.from_json(self._object("report_object", path={"id": place}, json_body=body))

    def report_people(self, place: str, counts: Sequence[PeopleCount | float]) -> PeopleEstimates:
        """Reports how many people the robot saw in ``place`` (a floor, room, corridor or hall):
        1 to 100 counts, in the order they were made, each a :class:`PeopleCount` or a bare
        number (made now). The service keeps a running estimate per place, over the whole day and
        per hour of day: each count moves it max(1/n, 0.2) of the way, n the counts so far (the
        mean of the first five, then an exponentially weighted mean); simulations of the floor use
        it instead of the engineer's figure. Returns the place's estimates. Robots (20 counts per
        second, bursts of 100) and engineers."""
        observations = [(c if isinstance(c, PeopleCount) else PeopleCount(c)).to_json() for c in counts]
        body: JsonObject = {"observations": observations}
        return PeopleEstimates.from_json(self._object("report_people_observations", path={"id": place}, json_body=body))

    # ---- on-demand databases ----

    @staticmethod
    def _waypoint(w: Waypoint, floor: str | None) -> JsonObject:
        if isinstance(w, str):
            return {"place": w}
        p = as_point(w)
        out: JsonObject = {"x": p.x, "y": p.y}
        if floor is not None:
            out["floor"] = floor
        return out

    @staticmethod
    def _database(response: httpx.Response, fmt: RdfFormat) -> OnDemandDatabase:
        media, parser = _RDF[fmt]
        db = OnDemandDatabase()
        db.parse(data=response.content, format=parser)
        count = response.headers.get("x-triple-count")
        db.triple_count = int(count) if count is not None and count.isdigit() else None
        db.route = response.headers.get("x-route", "").split()
        db.floor = response.headers.get("x-floor")
        db.robot = response.headers.get("x-robot")
        db.etag = response.headers.get("etag")
        db.media_type = media
        return db

    def on_demand_database(
        self,
        robot: str,
        start: Waypoint,
        goals: Sequence[Waypoint],
        *,
        floor: str | None = None,
        format: RdfFormat = "turtle",
    ) -> OnDemandDatabase:
        """The on-demand database of a mission (thesis §3.4): the places of the route from
        ``start`` through ``goals`` with their maps and boundaries, their objects, and the robot,
        parsed into an :class:`rdflib.Graph`. A waypoint is a place (IRI or identifier) or a point
        ``(x, y)``; ``floor`` is given with every point (needed where floors overlap). ``format``
        is what travels: ``turtle``, ``ntriples`` or ``jsonld``."""
        if isinstance(goals, str):
            raise TypeError("goals is a sequence of waypoints")
        if not goals:
            raise ValueError("a mission needs at least one goal")
        body = {
            "robot": robot,
            "start": self._waypoint(start, floor),
            "goals": [self._waypoint(g, floor) for g in goals],
        }
        response = self._send("on_demand_database", json_body=body, accept=_RDF[format][0])
        return self._database(response, format)

    def floor_database(
        self,
        place: str,
        robot: str | None = None,
        *,
        format: RdfFormat = "turtle",
    ) -> OnDemandDatabase:
        """The on-demand database of the whole floor ``place`` is on, for ``robot`` (default:
        the first robot), parsed into an :class:`rdflib.Graph`: what workers build their
        simulations from."""
        response = self._send(
            "floor_on_demand_database",
            path={"id": place},
            query={"robot": robot},
            accept=_RDF[format][0],
        )
        return self._database(response, format)

    # ---- plans and roadmaps ----

    @staticmethod
    def _plan_request(
        robot: str,
        place: str,
        start: PoseLike,
        goal: PointLike | None,
        goals: Sequence[PointLike] | None,
        policy: str | None,
        options: PlanOptions | None,
    ) -> JsonObject:
        if (goal is None) == (goals is None):
            raise ValueError("give one goal (`goal`) or a sequence of goals (`goals`), not both")
        body: JsonObject = {"robot": robot, "place": place, "start": as_pose(start).to_json()}
        if goal is not None:
            body["goal"] = as_point(goal).to_json()
        else:
            assert goals is not None
            if not goals:
                raise ValueError("`goals` is empty")
            body["goals"] = [as_point(g).to_json() for g in goals]
        if policy is not None:
            body["policy"] = policy
        if options is not None:
            opts = options.to_json()
            if opts:
                body["options"] = opts
        return body

    def plan(
        self,
        robot: str,
        place: str,
        start: PoseLike,
        goal: PointLike | None = None,
        *,
        goals: Sequence[PointLike] | None = None,
        policy: str | None = None,
        options: PlanOptions | None = None,
    ) -> PlanResult:
        """Asks for a plan validated in the mental simulation before the robot moves.

        ``robot`` and ``place`` (its floor, or a place on it) by identifier or IRI; ``start`` the
        robot's pose ``(x, y, yaw)`` in the floor's map frame; one ``goal`` ``(x, y)`` or a
        sequence of ``goals``; ``policy`` the policy to drive with (default: the robot's newest);
        ``options`` how to validate. The result's ``path`` is a ROS ``nav_msgs/Path``.
        A goal in an obstacle or out of reach raises ``MentalsimError`` 422 ``unprocessable``;
        a plan no attempt validated 409 ``conflict`` (the attempts in ``details``)."""
        body = self._plan_request(robot, place, start, goal, goals, policy, options)
        return PlanResult.from_json(self._object("plan", json_body=body))

    def plan_recording(
        self,
        robot: str,
        place: str,
        start: PoseLike,
        goal: PointLike | None = None,
        *,
        goals: Sequence[PointLike] | None = None,
        policy: str | None = None,
        options: PlanOptions | None = None,
    ) -> bytes:
        """As :meth:`plan`, the whole rehearsal as a ROS 2 recording (MCAP, CDR): ``/map``,
        ``/plan``, ``/tf_static``, and for every attempt ``/rehearsal/attempt``,
        ``/rehearsal/attempt_path``, and per simulated step ``/rehearsal/pose``, ``/tf`` and
        ``/rehearsal/scan``. Foxglove opens it; the ``mcap`` and ``mcap-ros2-support`` packages
        read it."""
        body = self._plan_request(robot, place, start, goal, goals, policy, options)
        return self._send("plan", json_body=body, accept="application/x-mcap").content

    def roadmap(
        self,
        place: str,
        robot: str,
        *,
        policy: str | None = None,
        safety_margin_m: float | None = None,
    ) -> Roadmap:
        """The roadmap a plan on the floor ``place`` is on starts from, for ``robot``; with a
        ``policy``, each edge's measured success where its policy-aware roadmap is stored."""
        query = {"place": place, "robot": robot, "policy": policy, "safety_margin_m": safety_margin_m}
        return Roadmap.from_json(self._object("get_roadmap", query=query))

    def route_graph(self, place: str, robot: str, *, policy: str | None = None) -> JsonObject:
        """That roadmap as Nav2 Route Server's GeoJSON graph (a ``FeatureCollection``)."""
        return self._object("route_graph", path={"id": place}, query={"robot": robot, "policy": policy})

    # ---- the fleet's traffic schedule ----

    def traffic(self, place: str, robot: str | None = None) -> FloorTraffic:
        """Every plan committed on the floor ``place`` is on, now (``place`` a floor's IRI, or a
        place with ``robot`` to find its floor)."""
        return FloorTraffic.from_json(self._object("floor_traffic", path={"id": place}, query={"robot": robot}))

    def traffic_events(
        self,
        place: str,
        robot: str | None = None,
        *,
        reconnect: bool = True,
        max_reconnects: int = 10,
        retry_delay_s: float = 0.5,
    ) -> Generator[TrafficEvent, None, None]:
        """The floor's traffic live, from its server-sent event stream: a ``snapshot`` first,
        then every commit, progress report and removal as it happens. The stream has no end:
        stop iterating (or close the generator) when done.

        A stream that drops is opened again (after ``retry_delay_s``, doubling, at most
        ``max_reconnects`` failures in a row) and starts with a fresh ``snapshot``; with
        ``reconnect=False`` the generator ends (or raises) when the stream does."""
        failures = 0
        while True:
            try:
                with self._stream("floor_traffic_events", path={"id": place}, query={"robot": robot}) as response:
                    for sse in parse_sse(response.iter_lines()):
                        if sse.id is None:
                            continue
                        try:
                            version = int(sse.id)
                            data = json.loads(sse.data)
                        except ValueError as e:
                            raise MentalsimError(None, "bad_response", f"traffic event {sse.id!r}: {e}", operation="floor_traffic_events") from e
                        failures = 0
                        yield TrafficEvent.from_sse(version, sse.event, data)
            except (httpx.TransportError, MentalsimError) as e:
                transport = isinstance(e, httpx.TransportError) or (
                    isinstance(e, MentalsimError)
                    and (e.status == 503 or (e.status is None and e.code in ("unreachable", "timeout")))
                )
                if not transport or not reconnect or failures >= max_reconnects:
                    if isinstance(e, httpx.TransportError):
                        raise MentalsimError.from_transport(e, "floor_traffic_events") from e
                    raise
            if not reconnect:
                return
            failures += 1
            if failures > max_reconnects:
                raise MentalsimError(None, "unreachable", "the traffic stream keeps ending", operation="floor_traffic_events")
            time.sleep(min(retry_delay_s * 2 ** (failures - 1), 10.0))

    def stand(
        self,
        place: str,
        robot: str,
        x: float,
        y: float,
        *,
        yaw: float = 0.0,
        time_ms: int | None = None,
        for_s: float | None = None,
    ) -> Itinerary:
        """Records where ``robot`` stands with no plan (from ``time_ms``, default now, for
        ``for_s`` seconds, default 300), replacing its itinerary: other robots' plans keep
        clear of it, routed around it or waiting for its next plan. Answers the robot standing
        as the schedule holds it (its ``plan_id`` cancels it)."""
        body: JsonObject = {"robot": robot, "x": x, "y": y, "yaw": yaw}
        if time_ms is not None:
            body["time_ms"] = time_ms
        if for_s is not None:
            body["for_s"] = for_s
        return Itinerary.from_json(self._object("stand", path={"id": place}, json_body=body))

    def cancel_plan(self, plan_id: str) -> Itinerary:
        """Cancels a committed plan (its robot's token, or an engineer's): the robot's place in
        the schedule is freed at once. Answers the plan as it was committed."""
        return Itinerary.from_json(self._object("cancel_plan", path={"id": plan_id}))

    def report_progress(
        self,
        plan_id: str,
        x: float,
        y: float,
        *,
        time_ms: int | None = None,
        revision: int | None = None,
    ) -> ProgressAnswer:
        """Reports where the plan's robot is (at ``time_ms``, default now): the rest of its
        schedule shifts by its observed delay (``Itinerary.delay_s``). ``revision``: the revision
        the robot drives, which acknowledges it (409 for one the plan never had). The answer's
        ``revision`` is the plan's: newer than the robot's where it was revised meanwhile; its
        ``may_go_until_t_s`` says how far the robot may go now (``None``: to its goal), up to
        the first place it passes after a robot that has not passed yet."""
        body: JsonObject = {"x": x, "y": y}
        if time_ms is not None:
            body["time_ms"] = time_ms
        if revision is not None:
            body["revision"] = revision
        return ProgressAnswer.from_json(self._object("report_progress", path={"id": plan_id}, json_body=body))

    def plan_status(self, plan_id: str, *, etag: str | None = None, wait_s: float | None = None) -> PlanStatus | None:
        """A committed plan as its robot follows it: its revision, what the robot acknowledged,
        whether it may still be revised. With ``etag`` (a ``PlanStatus.etag``): ``None`` while
        that is still the plan's revision, after waiting up to ``wait_s`` seconds (at most 30)
        for a new one."""
        headers = {"If-None-Match": etag} if etag is not None else None
        response = self._send(
            "get_plan",
            path={"id": plan_id},
            query={"wait_s": wait_s},
            headers=headers,
        )
        if response.status_code == 304:
            return None
        try:
            body = response.json()
        except ValueError as e:
            raise MentalsimError(response.status_code, "bad_response", f"the answer is not JSON: {e}", operation="get_plan") from e
        if not isinstance(body, dict):
            raise MentalsimError(response.status_code, "bad_response", "expected a JSON object", operation="get_plan")
        return PlanStatus.from_json(body, response.headers.get("etag"))

    def watch_plan(self, plan_id: str, *, poll_s: float = 25.0) -> Generator[PlanStatus, None, None]:
        """The plan's revisions as they happen: first the plan as it is, then each new revision
        (a long poll on ``GET /v1/plans/{id}``, ``poll_s`` seconds at a time, at most 30). Ends
        when the plan does (cancelled, replaced or expired: 404). Acknowledge what it yields with
        ``report_progress(..., revision=status.plan.revision)``."""
        etag: str | None = None
        while True:
            try:
                status = self.plan_status(plan_id, etag=etag, wait_s=poll_s if etag else None)
            except MentalsimError as e:
                if e.status == 404:
                    return
                raise
            if status is None:
                continue
            etag = status.etag
            yield status

    # ---- jobs ----

    def submit_job(
        self,
        kind: JobKind,
        payload: Mapping[str, Any],
        *,
        priority: int | None = None,
        max_attempts: int | None = None,
    ) -> Job:
        """Creates a job of ``kind`` with its ``payload`` (engineers only). The payload is checked
        at once: 422 naming the field, 404 for an unknown robot, place or policy."""
        body: JsonObject = {"kind": kind, "payload": dict(payload)}
        if priority is not None:
            body["priority"] = priority
        if max_attempts is not None:
            body["max_attempts"] = max_attempts
        return Job.from_json(self._object("create_job", json_body=body))

    def submit_training(
        self,
        robot: str,
        place: str,
        minutes: float,
        *,
        config: Mapping[str, Any] | None = None,
        seed: int | None = None,
        priority: int | None = None,
        max_attempts: int | None = None,
    ) -> Job:
        """Trains a navigation policy (TD3) for ``robot`` on the whole floor ``place`` is on, for
        ``minutes`` of wall-clock time; ``config`` overrides keys of ``learning::TrainConfig``.
        The result names the exported policy (``policy_id``)."""
        payload = _given(robot=robot, place=place, minutes=minutes, config=dict(config) if config is not None else None, seed=seed)
        return self.submit_job("train", payload, priority=priority, max_attempts=max_attempts)

    def submit_evaluation(
        self,
        policy: str,
        place: str,
        *,
        episodes: int | None = None,
        seed: int | None = None,
        robot: str | None = None,
        goals_in_view: bool | None = None,
        priority: int | None = None,
        max_attempts: int | None = None,
    ) -> Job:
        """Evaluates ``policy`` on random missions on the floor ``place`` is on."""
        payload = _given(policy=policy, place=place, episodes=episodes, seed=seed, robot=robot, goals_in_view=goals_in_view)
        return self.submit_job("evaluate", payload, priority=priority, max_attempts=max_attempts)

    def submit_roadmap(
        self,
        policy: str,
        place: str,
        *,
        robot: str | None = None,
        rollouts: int | None = None,
        keep_threshold: float | None = None,
        safety_margin_m: float | None = None,
        priority: int | None = None,
        max_attempts: int | None = None,
    ) -> Job:
        """Builds the policy-aware roadmap (PRM-RL) of ``policy`` on the floor ``place`` is on."""
        payload = _given(
            policy=policy, place=place, robot=robot, rollouts=rollouts, keep_threshold=keep_threshold, safety_margin_m=safety_margin_m
        )
        return self.submit_job("roadmap", payload, priority=priority, max_attempts=max_attempts)

    def submit_validation(
        self,
        robot: str,
        place: str,
        start: PoseLike,
        goal: PointLike | None = None,
        *,
        goals: Sequence[PointLike] | None = None,
        policy: str | None = None,
        options: PlanOptions | None = None,
        priority: int | None = None,
        max_attempts: int | None = None,
    ) -> Job:
        """Rehearses a plan as :meth:`plan` does, as a job (its result is the plan report)."""
        payload = self._plan_request(robot, place, start, goal, goals, policy, options)
        return self.submit_job("validate", payload, priority=priority, max_attempts=max_attempts)

    def job(self, job_id: str) -> Job:
        """One job."""
        return Job.from_json(self._object("get_job", path={"id": job_id}))

    def jobs(
        self,
        *,
        state: JobState | None = None,
        kind: JobKind | None = None,
        limit: int | None = None,
    ) -> list[Job]:
        """Jobs, newest first (at most ``limit``, 1-1000, default 50)."""
        query = {"state": state, "kind": kind, "limit": limit}
        return [Job.from_json(j) for j in self._array("list_jobs", query=query)]

    def cancel_job(self, job_id: str) -> Job:
        """Asks a job to stop (engineers only): a queued job is cancelled at once, a running one
        at its next progress report (a training checkpoints first). 409 ``conflict`` when it has
        already finished."""
        return Job.from_json(self._object("cancel_job", path={"id": job_id}))

    def job_curves(self, job_id: str) -> str:
        """A training job's learning curves as CSV, one row per episode (reward, outcome, moving
        mean, spread and success over 100 episodes); from its latest checkpoint while it runs."""
        return self._send("job_curves_csv", path={"id": job_id}).text

    def job_curves_png(self, job_id: str) -> bytes:
        """A training job's learning curve as a PNG (reward per episode, moving mean ± one
        standard deviation over 100 episodes)."""
        return self._send("job_curves_png", path={"id": job_id}).content

    def job_events(
        self,
        job_id: str,
        *,
        after: int | None = None,
        reconnect: bool = True,
        max_reconnects: int = 10,
        retry_delay_s: float = 0.5,
    ) -> Generator[JobEvent, None, None]:
        """The job's events from its server-sent event stream, in order, until it has finished
        (events after the id ``after`` only, when given).

        A stream that drops (a network error, a stall of more than 45 s, an end before the
        job's final state, a 503 while the service restarts) is resumed where it stopped: the
        client reconnects with ``Last-Event-ID`` set to the last event it yielded, so no event
        is lost or repeated. It gives up after ``max_reconnects`` failed attempts in a row
        (raising ``MentalsimError``); with ``reconnect=False`` a drop raises at once."""
        last = after
        failures = 0
        while True:
            headers = {"Last-Event-ID": str(last)} if last is not None else None
            got = 0
            final = False
            try:
                with self._stream("job_events", path={"id": job_id}, headers=headers) as response:
                    for sse in parse_sse(response.iter_lines()):
                        if sse.id is None:
                            continue
                        try:
                            event_id = int(sse.id)
                        except ValueError as e:
                            raise MentalsimError(None, "bad_response", f"event id {sse.id!r} is not an integer", operation="job_events") from e
                        event = JobEvent.from_sse(event_id, sse.event, sse.data)
                        last = event.id
                        got += 1
                        failures = 0
                        final = event.state in ("succeeded", "failed", "cancelled")
                        yield event
            except (httpx.TransportError, MentalsimError) as e:
                # Worth retrying: no answer, or 503 (a service starting or shedding load).
                transport = isinstance(e, httpx.TransportError) or (
                    isinstance(e, MentalsimError)
                    and (e.status == 503 or (e.status is None and e.code in ("unreachable", "timeout")))
                )
                if not transport or not reconnect:
                    if isinstance(e, httpx.TransportError):
                        raise MentalsimError.from_transport(e, "job_events") from e
                    raise
                failures += 1
                if failures > max_reconnects:
                    if isinstance(e, httpx.TransportError):
                        raise MentalsimError.from_transport(e, "job_events") from e
                    raise
                time.sleep(min(retry_delay_s * 2 ** (failures - 1), 10.0))
                continue
            if final or not reconnect:
                return
            # The stream ended without the final state: the service stopped, or a proxy cut it.
            if got == 0 and self.job(job_id).is_finished:
                return
            if got == 0:
                failures += 1
                if failures > max_reconnects:
                    raise MentalsimError(None, "unreachable", "the event stream keeps ending early", operation="job_events")
                time.sleep(min(retry_delay_s * 2 ** (failures - 1), 10.0))

    def wait_for_job(
        self,
        job_id: str,
        *,
        on_progress: Callable[[JobEvent], None] | None = None,
        on_event: Callable[[JobEvent], None] | None = None,
        timeout: float | None = None,
    ) -> Job:
        """Follows the job's event stream until it has finished and returns the job.
        ``on_progress`` is called with each ``progress`` event (a training's about every 2 s),
        ``on_event`` with every event. ``timeout`` (seconds) is checked between events: past it,
        ``MentalsimError`` with code ``timeout``. The job's own failure is not an error: look at
        ``state``, ``error`` and ``result``."""
        deadline = None if timeout is None else time.monotonic() + timeout
        events = self.job_events(job_id)
        try:
            for event in events:
                if on_event is not None:
                    on_event(event)
                if on_progress is not None and event.kind == "progress":
                    on_progress(event)
                if deadline is not None and time.monotonic() > deadline:
                    raise MentalsimError(None, "timeout", f"job {job_id} did not finish within {timeout} s", operation="wait_for_job")
        finally:
            events.close()
        return self.job(job_id)

    # ---- policies ----

    def policies(self) -> list[PolicySummary]:
        """Exported policies, newest first."""
        return [PolicySummary.from_json(p) for p in self._array("list_policies")]

    def policy(self, policy_id: str) -> PolicySummary:
        """One policy, with its metadata (``policy.json``)."""
        return PolicySummary.from_json(self._object("get_policy", path={"id": policy_id}))

    def download_policy(self, policy_id: str, directory: str | os.PathLike[str]) -> Path:
        """Writes the policy's two files, ``policy.safetensors`` and ``policy.json``, into
        ``directory`` (created) and returns it: :func:`load_policy` runs them."""
        out = Path(directory)
        out.mkdir(parents=True, exist_ok=True)
        weights = self._send("policy_weights", path={"id": policy_id}).content
        meta = self._send("policy_metadata", path={"id": policy_id}).content
        _write_atomic(out / "policy.safetensors", weights)
        _write_atomic(out / "policy.json", meta)
        return out

    @staticmethod
    def load_policy(directory: str | os.PathLike[str]) -> Policy:
        """The policy in ``directory`` (as :meth:`download_policy` writes it), run locally."""
        return load_policy(directory)


def _write_atomic(path: Path, data: bytes) -> Path:
    """Writes ``data`` to ``path`` through a temporary file renamed over it."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _given(**values: Any) -> JsonObject:
    """A job payload of the values given (``None`` ones left out: the server's defaults)."""
    return {key: value for key, value in values.items() if value is not None}
