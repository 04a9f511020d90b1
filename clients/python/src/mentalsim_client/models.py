"""Typed values of the API: what the client sends and what it reads back.

Each result keeps the JSON it was read from in ``raw`` (fields a newer service adds are there
before this package knows them). Field names and meanings follow the OpenAPI schemas named in
each docstring.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from datetime import datetime
from typing import Any, Literal, TypeAlias

from .errors import MentalsimError

JsonObject: TypeAlias = dict[str, Any]


class ResponseShapeError(MentalsimError, ValueError):
    """An answer that does not have the documented shape (code ``bad_response``)."""

    def __init__(self, message: str) -> None:
        super().__init__(None, "bad_response", message)


# --------------------------------------------------------------------------------------------
# Reading JSON


def _obj(value: object, what: str) -> JsonObject:
    if not isinstance(value, dict):
        raise ResponseShapeError(f"{what}: expected an object, got {type(value).__name__}")
    return value


def _list(value: object, what: str) -> list[Any]:
    if not isinstance(value, list):
        raise ResponseShapeError(f"{what}: expected an array, got {type(value).__name__}")
    return value


def _float(d: Mapping[str, Any], key: str) -> float:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ResponseShapeError(f"`{key}`: expected a number, got {v!r}")
    return float(v)


def _opt_float(d: Mapping[str, Any], key: str) -> float | None:
    return None if d.get(key) is None else _float(d, key)


def _int(d: Mapping[str, Any], key: str) -> int:
    v = d.get(key)
    if isinstance(v, bool) or not isinstance(v, int):
        raise ResponseShapeError(f"`{key}`: expected an integer, got {v!r}")
    return v


def _str(d: Mapping[str, Any], key: str) -> str:
    v = d.get(key)
    if not isinstance(v, str):
        raise ResponseShapeError(f"`{key}`: expected a string, got {v!r}")
    return v


def _opt_str(d: Mapping[str, Any], key: str) -> str | None:
    return None if d.get(key) is None else _str(d, key)


def _bool(d: Mapping[str, Any], key: str) -> bool:
    v = d.get(key)
    if not isinstance(v, bool):
        raise ResponseShapeError(f"`{key}`: expected a boolean, got {v!r}")
    return v


def _opt_obj(d: Mapping[str, Any], key: str) -> JsonObject | None:
    return None if d.get(key) is None else _obj(d[key], key)


def _floats(value: object, what: str) -> list[float]:
    out: list[float] = []
    for v in _list(value, what):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ResponseShapeError(f"{what}: expected numbers, got {v!r}")
        out.append(float(v))
    return out


# --------------------------------------------------------------------------------------------
# Geometry


@dataclass(frozen=True, slots=True)
class Point:
    """A point in a floor's map frame, metres (schema ``Point``)."""

    x: float
    y: float

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> Point:
        return cls(_float(d, "x"), _float(d, "y"))

    def to_json(self) -> JsonObject:
        return {"x": self.x, "y": self.y}


@dataclass(frozen=True, slots=True)
class Pose:
    """A pose in a floor's map frame: metres, heading in radians counter-clockwise from +x
    (schema ``Pose``)."""

    x: float
    y: float
    yaw: float = 0.0

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> Pose:
        return cls(_float(d, "x"), _float(d, "y"), _opt_float(d, "yaw") or 0.0)

    def to_json(self) -> JsonObject:
        return {"x": self.x, "y": self.y, "yaw": self.yaw}


PointLike: TypeAlias = Point | tuple[float, float] | Sequence[float]
PoseLike: TypeAlias = Pose | Point | tuple[float, float] | tuple[float, float, float] | Sequence[float]


def as_point(p: PointLike) -> Point:
    """A :class:`Point` from a point or an ``(x, y)`` pair."""
    if isinstance(p, Point):
        return p
    if isinstance(p, Pose):
        return Point(p.x, p.y)
    values = [float(v) for v in p]
    if len(values) != 2:
        raise ValueError(f"a point is (x, y), got {p!r}")
    return Point(values[0], values[1])


def as_pose(p: PoseLike) -> Pose:
    """A :class:`Pose` from a pose, a point, or an ``(x, y)`` or ``(x, y, yaw)`` tuple."""
    if isinstance(p, Pose):
        return p
    if isinstance(p, Point):
        return Pose(p.x, p.y)
    values = [float(v) for v in p]
    if len(values) not in (2, 3):
        raise ValueError(f"a pose is (x, y) or (x, y, yaw), got {p!r}")
    return Pose(values[0], values[1], values[2] if len(values) == 3 else 0.0)


# --------------------------------------------------------------------------------------------
# ROS messages


@dataclass(frozen=True, slots=True)
class RosPoseStamped:
    """``geometry_msgs/PoseStamped`` as ``PlanResult.path`` writes it (schema ``RosPoseStamped``)."""

    frame_id: str
    x: float
    y: float
    z: float
    qx: float
    qy: float
    qz: float
    qw: float
    #: When the plan has the robot at this pose (a pose it waits at: when it may go on), ms
    #: since the Unix epoch, from the header's ``builtin_interfaces/Time`` stamp; ``None``
    #: without a schedule.
    stamp_ms: int | None = None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> RosPoseStamped:
        header = _obj(d.get("header"), "header")
        pose = _obj(d.get("pose"), "pose")
        position = _obj(pose.get("position"), "position")
        q = _obj(pose.get("orientation"), "orientation")
        stamp = header.get("stamp")
        stamp_ms = None
        if isinstance(stamp, dict):
            stamp_ms = _int(stamp, "sec") * 1000 + _int(stamp, "nanosec") // 1_000_000
        return cls(
            _str(header, "frame_id"),
            _float(position, "x"),
            _float(position, "y"),
            _float(position, "z"),
            _float(q, "x"),
            _float(q, "y"),
            _float(q, "z"),
            _float(q, "w"),
            stamp_ms,
        )

    @property
    def yaw(self) -> float:
        """The heading the quaternion encodes, radians."""
        return math.atan2(
            2.0 * (self.qw * self.qz + self.qx * self.qy),
            1.0 - 2.0 * (self.qy * self.qy + self.qz * self.qz),
        )

    def to_ros(self) -> JsonObject:
        """The message as ROS JSON (rosbridge, ``ros2 topic pub``)."""
        header: JsonObject = {"frame_id": self.frame_id}
        if self.stamp_ms is not None:
            header["stamp"] = {"sec": self.stamp_ms // 1000, "nanosec": (self.stamp_ms % 1000) * 1_000_000}
        return {
            "header": header,
            "pose": {
                "position": {"x": self.x, "y": self.y, "z": self.z},
                "orientation": {"x": self.qx, "y": self.qy, "z": self.qz, "w": self.qw},
            },
        }


@dataclass(frozen=True, slots=True)
class RosPath:
    """``nav_msgs/Path`` in the floor's ``map`` frame (schema ``RosPath``): the start, then every
    waypoint, each facing along the path."""

    frame_id: str
    poses: list[RosPoseStamped]

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> RosPath:
        header = _obj(d.get("header"), "path.header")
        poses = [RosPoseStamped.from_json(_obj(p, "path.poses[]")) for p in _list(d.get("poses"), "path.poses")]
        return cls(_str(header, "frame_id"), poses)

    def to_ros(self) -> JsonObject:
        """The message as ROS JSON, ready for rosbridge or ``ros2 topic pub /plan nav_msgs/Path``."""
        return {"header": {"frame_id": self.frame_id}, "poses": [p.to_ros() for p in self.poses]}

    def points(self) -> list[tuple[float, float]]:
        """``(x, y)`` of every pose."""
        return [(p.x, p.y) for p in self.poses]


# --------------------------------------------------------------------------------------------
# Plans


RoadmapChoice: TypeAlias = Literal["auto", "policy", "geometric"]
#: A controller by name, or ``auto`` (schema ``ControllerOption``).
ControllerOption: TypeAlias = Literal["auto", "hybrid", "hybrid_rpp", "hybrid_path", "rpp", "mppi", "follower", "shielded_follower"]


@dataclass(frozen=True, slots=True)
class PlanOptions:
    """How a plan is validated (schema ``PlanOptions``); ``None`` leaves the service's default."""

    #: Simulated runs at most, each on a re-sampled roadmap, 1-50 (default 5).
    max_attempts: int | None = None
    #: Replans allowed within one attempt, 0-1000 (default 5).
    max_replans: int | None = None
    #: Gaussian noise on observations and commands, as in training (default true).
    noise: bool | None = None
    #: ``auto`` (default), ``policy`` or ``geometric``.
    roadmap: RoadmapChoice | None = None
    #: Clearance beyond the robot's radius, metres, 0-5 (default 0.1).
    safety_margin_m: float | None = None
    #: PRM samples, 1-10 000 000 (default: the paper's n*).
    samples: int | None = None
    #: Seed of the roadmaps and the simulation (default 0).
    seed: int | None = None
    #: Remove detours from the roadmap path (default false).
    shortcut: bool | None = None
    #: Answer every attempt's drive step by step (default false).
    trace: bool | None = None
    #: Keep every n-th pose of the trajectory (default 1; 0: none).
    trajectory_stride: int | None = None
    #: Simulated seconds per waypoint before replanning, (0, 600] (default 15).
    waypoint_timeout_s: float | None = None
    #: People walking about in the rehearsal: ``"auto"`` (default: as many as the knowledge
    #: expects), ``"none"``, or people per 100 m² of free region (0-50).
    people: Literal["auto", "none"] | float | None = None
    #: With ``people="auto"``: the hour of day (0-23, the building's local time) whose expected
    #: numbers to use where the knowledge has them by hour (default: the all-day figures).
    people_hour: int | None = None
    #: Drive the validated plan again among this many fresh draws of the people, 0-20
    #: (default 0): how robust it is across crowds (``PeopleReport.draws``).
    people_draws: int | None = None
    #: The controller that drives the rehearsal: ``"auto"`` (default: the one measured best on
    #: the floor state), ``"hybrid"``, ``"hybrid_rpp"``, ``"hybrid_path"``, ``"rpp"``, ``"mppi"``, ``"follower"``
    #: or ``"shielded_follower"``; ``PlanResult.controller_choice`` says which drove and why.
    controller: ControllerOption | None = None
    #: Commit the plan to the floor's traffic schedule (default true); false only checks it.
    commit: bool | None = None
    #: When the robot sets off, ms since the Unix epoch (default: now).
    start_time_ms: int | None = None
    #: How early or late the robot may be on its schedule, seconds, 0-3600 (default 2).
    tolerance_s: float | None = None
    #: Most waiting for other robots the plan may take, seconds, 0-3600 (default 120).
    max_wait_s: float | None = None
    #: How long the robot is held at its last goal after arriving, seconds (default 30).
    hold_s: float | None = None

    def to_json(self) -> JsonObject:
        out: JsonObject = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if value is not None:
                out[f.name] = value
        return out


@dataclass(frozen=True, slots=True)
class LegReport:
    """One leg of a validated plan (schema ``LegReport``)."""

    goal_index: int
    controller: str
    roadmap: str
    attempts: int
    roadmap_seed: int
    simulated_time_s: float
    distance_m: float
    min_clearance_m: float
    replans: int

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> LegReport:
        return cls(
            _int(d, "goal_index"),
            _str(d, "controller"),
            _str(d, "roadmap"),
            _int(d, "attempts"),
            _int(d, "roadmap_seed"),
            _float(d, "simulated_time_s"),
            _float(d, "distance_m"),
            _float(d, "min_clearance_m"),
            _int(d, "replans"),
        )


@dataclass(frozen=True, slots=True)
class AttemptReport:
    """One simulated run (schema ``AttemptReport``); ``trace`` with ``PlanOptions(trace=True)``."""

    attempt: int
    leg: int
    controller: str
    roadmap_seed: int
    outcome: Literal["reached", "collision", "stalled"] | str
    reason: str
    simulated_time_s: float
    distance_m: float
    min_clearance_m: float
    replans: int
    waypoints_reached: int
    goals_reached: int
    prm_path_length_m: float
    end_pose: Pose
    trace: JsonObject | None
    #: Share of the control steps the classical follower drove inside the policy controller
    #: (its handover near obstacles); 0 for the follower's own attempts.
    handover_share: float = 0.0
    #: Closest approach of the footprint to a person, metres; ``None`` without people.
    min_person_clearance_m: float | None = None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> AttemptReport:
        return cls(
            _int(d, "attempt"),
            _int(d, "leg"),
            _str(d, "controller"),
            _int(d, "roadmap_seed"),
            _str(d, "outcome"),
            _str(d, "reason"),
            _float(d, "simulated_time_s"),
            _float(d, "distance_m"),
            _float(d, "min_clearance_m"),
            _int(d, "replans"),
            _int(d, "waypoints_reached"),
            _int(d, "goals_reached"),
            _float(d, "prm_path_length_m"),
            Pose.from_json(_obj(d.get("end_pose"), "end_pose")),
            _opt_obj(d, "trace"),
            _float(d, "handover_share"),
            _opt_float(d, "min_person_clearance_m"),
        )


@dataclass(frozen=True, slots=True)
class RoadmapInfo:
    """The roadmap a plan's first leg planned on (schema ``RoadmapInfo``)."""

    kind: str
    samples: int
    nodes: int
    seed: int
    inflation_m: float
    cached: bool

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> RoadmapInfo:
        return cls(
            _str(d, "kind"),
            _int(d, "samples"),
            _int(d, "nodes"),
            _int(d, "seed"),
            _float(d, "inflation_m"),
            _bool(d, "cached"),
        )


@dataclass(frozen=True, slots=True)
class PeopleDraws:
    """The validated plan driven again among fresh draws of the people (schema ``PeopleDraws``)."""

    #: Draws driven; of those, reached every goal, hit a person, came within 10 cm of one.
    draws: int
    reached: int
    hit_person: int
    near_miss: int
    #: Closest approach to a person over all draws, metres.
    min_person_clearance_m: float | None
    #: Why each failed draw failed (``draw K, leg L: ...``).
    failures: list[str]

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> PeopleDraws:
        return cls(
            _int(d, "draws"),
            _int(d, "reached"),
            _int(d, "hit_person"),
            _int(d, "near_miss"),
            _opt_float(d, "min_person_clearance_m"),
            [str(f) for f in _list(d.get("failures"), "failures")],
        )


@dataclass(frozen=True, slots=True)
class PeopleReport:
    """Who walked about in a plan's rehearsal and how it fared (schema ``PeopleReport``)."""

    #: ``knowledge`` (``people="auto"``) or ``density``.
    source: str
    #: People drawn in each attempt.
    people: int
    #: Closest approach to a person in the validating runs, metres.
    min_person_clearance_m: float | None
    #: Attempts, each its own draw of people; of those reached, hit a person, near misses.
    attempts: int
    attempts_reached: int
    attempts_hit_person: int
    attempts_near_miss: int
    #: The plan driven again among fresh draws, with ``PlanOptions.people_draws``.
    draws: PeopleDraws | None = None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> PeopleReport:
        return cls(
            _str(d, "source"),
            _int(d, "people"),
            _opt_float(d, "min_person_clearance_m"),
            _int(d, "attempts"),
            _int(d, "attempts_reached"),
            _int(d, "attempts_hit_person"),
            _int(d, "attempts_near_miss"),
            None if d.get("draws") is None else PeopleDraws.from_json(_obj(d["draws"], "draws")),
        )


@dataclass(frozen=True, slots=True)
class ControllerChoice:
    """The controller that validated a plan and why (schema ``ControllerChoiceReport``)."""

    #: Its name (never ``auto``).
    controller: str
    #: Asked for, or ``auto``'s figures and verdict on the floor state.
    why: str
    #: What ``auto`` measured it against (``"rpp"`` unless the robot cannot run it);
    #: ``None`` when the controller was asked for or nothing was measured.
    compared_with: str | None = None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> ControllerChoice:
        return cls(_str(d, "controller"), _str(d, "why"), _opt_str(d, "compared_with"))


@dataclass(frozen=True, slots=True)
class PlanWait:
    """A wait in a plan so that other robots can pass (schema ``PlanWait``)."""

    #: The waypoint waited at (index into ``PlanResult.waypoints``); ``None``: at the start.
    waypoint: int | None
    wait_s: float
    #: When the robot may go on, ms since the Unix epoch.
    not_before_ms: int
    #: The robots it lets pass (IRIs).
    for_robots: list[str]

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> PlanWait:
        w = d.get("waypoint")
        return cls(
            None if w is None else int(w),
            _float(d, "wait_s"),
            _int(d, "not_before_ms"),
            [str(r) for r in _list(d.get("for_robots"), "for_robots")],
        )


@dataclass(frozen=True, slots=True)
class PlanAmongFleet:
    """The plan driven again with its waits among the other robots' committed plans (schema
    ``PlanAmongFleet``)."""

    robots: int
    arrived: bool
    reason: str
    time_s: float
    #: Closest approach to another robot, metres; ``None`` when none was on the floor.
    min_robot_clearance_m: float | None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> PlanAmongFleet:
        c = d.get("min_robot_clearance_m")
        return cls(
            _int(d, "robots"),
            _bool(d, "arrived"),
            _str(d, "reason"),
            _float(d, "time_s"),
            None if c is None else float(c),
        )


@dataclass(frozen=True, slots=True)
class Passing:
    """A place where a plan passes after another plan (schema ``PassingView``): the robot goes
    no further than ``t_s`` of its trajectory until the other one has ``passed``."""

    #: The plan passing first, and its robot.
    plan_id: str
    robot: str
    #: Where the paths first overlap, metres.
    x: float
    y: float
    #: This plan's trajectory time there, seconds.
    t_s: float
    passed: bool

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> Passing:
        return cls(_str(d, "plan_id"), _str(d, "robot"), _float(d, "x"), _float(d, "y"), _float(d, "t_s"), _bool(d, "passed"))


def _passings(d: Mapping[str, Any]) -> list[Passing]:
    return [Passing.from_json(_obj(p, "passes_after[]")) for p in _list(d.get("passes_after"), "passes_after")]


@dataclass(frozen=True, slots=True)
class PlanSchedule:
    """A plan in the floor's traffic schedule (schema ``PlanSchedule``)."""

    #: ``Client.cancel_plan`` and ``Client.report_progress`` take it.
    plan_id: str
    committed: bool
    version: int | None
    #: When the robot sets off (after any wait at the start), ms since the Unix epoch.
    start_time_ms: int
    #: When the robot reaches each waypoint, ms since the Unix epoch.
    waypoint_times_ms: list[int]
    waits: list[PlanWait]
    others_checked: int
    tolerance_s: float
    expires_ms: int
    #: ``None`` when no other robot's plan was committed on the floor.
    among_fleet: PlanAmongFleet | None = None
    #: Where the plan passes after other plans (the schedule's order), along the plan.
    passes_after: list[Passing] = field(default_factory=list)
    #: How far the robot may go now, seconds of its trajectory; ``None``: to its goal.
    may_go_until_t_s: float | None = None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> PlanSchedule:
        v = d.get("version")
        among = d.get("among_fleet")
        return cls(
            _str(d, "plan_id"),
            _bool(d, "committed"),
            None if v is None else int(v),
            _int(d, "start_time_ms"),
            [int(t) for t in _list(d.get("waypoint_times_ms"), "waypoint_times_ms")],
            [PlanWait.from_json(_obj(w, "waits[]")) for w in _list(d.get("waits"), "waits")],
            _int(d, "others_checked"),
            _float(d, "tolerance_s"),
            _int(d, "expires_ms"),
            None if among is None else PlanAmongFleet.from_json(_obj(among, "among_fleet")),
            _passings(d),
            _opt_float(d, "may_go_until_t_s"),
        )


@dataclass(frozen=True, slots=True)
class Itinerary:
    """A robot's committed plan as the schedule holds it (schema ``Itinerary``)."""

    plan_id: str
    robot: str
    floor: str
    start_unix_ms: int
    #: ``{"t_s", "x", "y", "yaw"}`` per pose, ``t_s`` after the start.
    trajectory: list[JsonObject]
    radius_m: float
    tolerance_s: float
    expires_unix_ms: int
    #: How late the robot is (its progress reports), seconds.
    delay_s: float
    #: The plan's revision: 1 when committed, one more each time the service revised it before
    #: the robot set off. Drive the newest.
    revision: int

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> Itinerary:
        return cls(
            _str(d, "plan_id"),
            _str(d, "robot"),
            _str(d, "floor"),
            _int(d, "start_unix_ms"),
            [_obj(p, "trajectory[]") for p in _list(d.get("trajectory"), "trajectory")],
            _float(d, "radius_m"),
            _float(d, "tolerance_s"),
            _int(d, "expires_unix_ms"),
            _float(d, "delay_s"),
            _int(d, "revision"),
        )


@dataclass(frozen=True, slots=True)
class PlanStatus:
    """A committed plan as its robot follows it (schema ``PlanStatus``), with the entity tag of
    its revision (``etag``, for ``If-None-Match``)."""

    plan: Itinerary
    #: The revision the robot last acknowledged in a progress report.
    acknowledged_revision: int
    #: Whether the robot may have set off: from then on the plan is never revised.
    set_off: bool
    departs_unix_ms: int
    #: Until when the service may still revise the plan, Unix ms.
    revisable_until_unix_ms: int
    #: Where the plan passes after other plans, along the plan, and whether each has passed.
    passes_after: list[Passing] = field(default_factory=list)
    #: How far the robot may go now, seconds of its trajectory; ``None``: to its goal.
    may_go_until_t_s: float | None = None
    etag: str | None = None

    @classmethod
    def from_json(cls, d: Mapping[str, Any], etag: str | None = None) -> PlanStatus:
        set_off = d.get("set_off")
        if not isinstance(set_off, bool):
            raise ResponseShapeError(f"`set_off`: expected a boolean, got {set_off!r}")
        return cls(
            Itinerary.from_json(_obj(d.get("plan"), "plan")),
            _int(d, "acknowledged_revision"),
            set_off,
            _int(d, "departs_unix_ms"),
            _int(d, "revisable_until_unix_ms"),
            _passings(d),
            _opt_float(d, "may_go_until_t_s"),
            etag,
        )


@dataclass(frozen=True, slots=True)
class ProgressAnswer(Itinerary):
    """What a progress report answers (schema ``ProgressAnswer``): the plan as now scheduled
    (an ``Itinerary``), and how far its robot may go now."""

    #: Where the plan passes after other plans, along the plan, and whether each has passed.
    passes_after: list[Passing]
    #: How far the robot may go now, seconds of its trajectory; ``None``: to its goal.
    may_go_until_t_s: float | None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> ProgressAnswer:
        p = Itinerary.from_json(d)
        return cls(
            p.plan_id,
            p.robot,
            p.floor,
            p.start_unix_ms,
            p.trajectory,
            p.radius_m,
            p.tolerance_s,
            p.expires_unix_ms,
            p.delay_s,
            p.revision,
            _passings(d),
            _opt_float(d, "may_go_until_t_s"),
        )


@dataclass(frozen=True, slots=True)
class FloorTraffic:
    """Every plan committed on a floor now (schema ``FloorTraffic``)."""

    floor: str
    version: int
    plans: list[Itinerary]

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> FloorTraffic:
        return cls(
            _str(d, "floor"),
            _int(d, "version"),
            [Itinerary.from_json(_obj(p, "plans[]")) for p in _list(d.get("plans"), "plans")],
        )


@dataclass(frozen=True, slots=True)
class TrafficEvent:
    """One event of a floor's traffic stream. ``kind`` is ``snapshot`` (``traffic`` holds every
    plan committed on the floor), ``committed``, ``revised`` (a new revision before the robot set
    off) or ``progressed`` (``itinerary`` is the plan as now scheduled), or ``removed`` (``plan_id``, ``robot`` and ``reason``: ``cancelled`` or
    ``replaced``). ``version`` is the floor's version after it."""

    kind: str
    version: int
    traffic: FloorTraffic | None = None
    itinerary: Itinerary | None = None
    plan_id: str | None = None
    robot: str | None = None
    reason: str | None = None

    @classmethod
    def from_sse(cls, version: int, kind: str, d: Mapping[str, Any]) -> TrafficEvent:
        if kind == "snapshot":
            return cls(kind, version, traffic=FloorTraffic.from_json(d))
        if kind in ("committed", "revised", "progressed"):
            it = Itinerary.from_json(_obj(d.get("itinerary"), "itinerary"))
            return cls(kind, version, itinerary=it, plan_id=it.plan_id, robot=it.robot)
        return cls(kind, version, plan_id=_str(d, "plan_id"), robot=_str(d, "robot"), reason=_str(d, "reason"))


@dataclass(frozen=True, slots=True)
class PlanResult:
    """A plan validated in the mental simulation (schema ``PlanApiResponse``)."""

    #: The robot's IRI.
    robot: str
    #: The floor's IRI.
    floor: str
    #: The robot's policy, if it has one (it drove when ``controller_choice`` is a hybrid).
    policy: str | None
    #: The controller that validated the plan and why it was the one.
    controller_choice: ControllerChoice
    #: Why a classical controller was used, when one was.
    note: str | None
    service_ms: float
    #: The start and the waypoints as a ROS 2 ``nav_msgs/Path`` in the ``map`` frame.
    path: RosPath
    #: The waypoints to follow, ending with the last goal (the start is not repeated).
    waypoints: list[Point]
    #: Index into ``waypoints`` of each goal.
    goal_indices: list[int]
    controller: str
    controller_description: str
    legs: list[LegReport]
    attempts: list[AttemptReport]
    simulated_time_s: float
    distance_m: float
    min_clearance_m: float
    prm_path_length_m: float
    waypoint_path_length_m: float
    replans: int
    trajectory: list[Pose]
    roadmap: RoadmapInfo
    #: The laser the traces read (``PlanOptions(trace=True)``).
    laser: JsonObject | None
    raw: JsonObject = field(repr=False, compare=False)
    #: Who walked about in the rehearsal; ``None`` when nobody did.
    people: PeopleReport | None = None
    #: The plan in the floor's traffic schedule; ``None`` where the service keeps none.
    schedule: PlanSchedule | None = None

    @classmethod
    def from_json(cls, d: JsonObject) -> PlanResult:
        return cls(
            robot=_str(d, "robot"),
            floor=_str(d, "floor"),
            policy=_opt_str(d, "policy"),
            controller_choice=ControllerChoice.from_json(_obj(d.get("controller_choice"), "controller_choice")),
            note=_opt_str(d, "note"),
            service_ms=_float(d, "service_ms"),
            path=RosPath.from_json(_obj(d.get("path"), "path")),
            waypoints=[Point.from_json(_obj(p, "waypoints[]")) for p in _list(d.get("waypoints"), "waypoints")],
            goal_indices=[int(i) for i in _list(d.get("goal_indices"), "goal_indices")],
            controller=_str(d, "controller"),
            controller_description=_str(d, "controller_description"),
            legs=[LegReport.from_json(_obj(x, "legs[]")) for x in _list(d.get("legs"), "legs")],
            attempts=[AttemptReport.from_json(_obj(x, "attempts[]")) for x in _list(d.get("attempts"), "attempts")],
            simulated_time_s=_float(d, "simulated_time_s"),
            distance_m=_float(d, "distance_m"),
            min_clearance_m=_float(d, "min_clearance_m"),
            prm_path_length_m=_float(d, "prm_path_length_m"),
            waypoint_path_length_m=_float(d, "waypoint_path_length_m"),
            replans=_int(d, "replans"),
            trajectory=[Pose.from_json(_obj(p, "trajectory[]")) for p in _list(d.get("trajectory"), "trajectory")],
            roadmap=RoadmapInfo.from_json(_obj(d.get("roadmap"), "roadmap")),
            laser=_opt_obj(d, "laser"),
            raw=d,
            people=None if d.get("people") is None else PeopleReport.from_json(_obj(d["people"], "people")),
            schedule=None if d.get("schedule") is None else PlanSchedule.from_json(_obj(d["schedule"], "schedule")),
        )


@dataclass(frozen=True, slots=True)
class RoadmapEdge:
    """One undirected roadmap edge (schema ``EdgeView``)."""

    a: int
    b: int
    length_m: float
    success: float | None
    mean_time_s: float | None
    kept: bool | None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> RoadmapEdge:
        kept = d.get("kept")
        return cls(
            _int(d, "a"),
            _int(d, "b"),
            _float(d, "length_m"),
            _opt_float(d, "success"),
            _opt_float(d, "mean_time_s"),
            kept if isinstance(kept, bool) else None,
        )


@dataclass(frozen=True, slots=True)
class Roadmap:
    """A floor's roadmap for a robot (schema ``RoadmapView``)."""

    kind: str
    floor: str
    samples: int
    seed: int
    inflation_m: float
    nodes: list[Point]
    edges: list[RoadmapEdge]
    policy: str | None
    note: str | None

    @classmethod
    def from_json(cls, d: JsonObject) -> Roadmap:
        nodes = []
        for n in _list(d.get("nodes"), "nodes"):
            xy = _floats(n, "nodes[]")
            nodes.append(Point(xy[0], xy[1]))
        return cls(
            _str(d, "kind"),
            _str(d, "floor"),
            _int(d, "samples"),
            _int(d, "seed"),
            _float(d, "inflation_m"),
            nodes,
            [RoadmapEdge.from_json(_obj(e, "edges[]")) for e in _list(d.get("edges"), "edges")],
            _opt_str(d, "policy"),
            _opt_str(d, "note"),
        )


# --------------------------------------------------------------------------------------------
# Knowledge


@dataclass(frozen=True, slots=True)
class Me:
    """Who a token belongs to (schema ``Me``)."""

    name: str
    role: str

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> Me:
        return cls(_str(d, "name"), _str(d, "role"))


@dataclass(frozen=True, slots=True)
class MapInfo:
    """A floor's metric map (schema ``MapView``)."""

    width: int
    height: int
    resolution: float
    origin: list[float]
    free_area_m2: float

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> MapInfo:
        return cls(
            _int(d, "width"),
            _int(d, "height"),
            _float(d, "resolution"),
            _floats(d.get("origin"), "origin"),
            _float(d, "free_area_m2"),
        )


@dataclass(frozen=True, slots=True)
class Place:
    """A building, floor, room, corridor or hall (schema ``PlaceView``)."""

    iri: str
    id: str | None
    name: str
    kind: str
    parent: str | None
    connected: list[str]
    boundary: list[tuple[float, float]]
    complexity: float | None
    map: MapInfo | None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> Place:
        boundary = []
        for p in _list(d.get("boundary"), "boundary"):
            xy = _floats(p, "boundary[]")
            boundary.append((xy[0], xy[1]))
        m = _opt_obj(d, "map")
        return cls(
            _str(d, "iri"),
            _opt_str(d, "id"),
            _str(d, "name"),
            _str(d, "kind"),
            _opt_str(d, "parent"),
            [str(c) for c in _list(d.get("connected"), "connected")],
            boundary,
            _opt_float(d, "complexity"),
            MapInfo.from_json(m) if m is not None else None,
        )


@dataclass(frozen=True, slots=True)
class Robot:
    """A robot model (schema ``RobotView``)."""

    iri: str
    id: str | None
    name: str
    wheels: int
    joints: int
    lasers: int
    cameras: int
    footprint: list[float] | None
    wheel_separation: float | None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> Robot:
        fp = d.get("footprint")
        return cls(
            _str(d, "iri"),
            _opt_str(d, "id"),
            _str(d, "name"),
            _int(d, "wheels"),
            _int(d, "joints"),
            _int(d, "lasers"),
            _int(d, "cameras"),
            _floats(fp, "footprint") if fp is not None else None,
            _opt_float(d, "wheel_separation"),
        )


@dataclass(frozen=True, slots=True)
class ImportedMap:
    """The floor a map import made (schema ``ImportedMap``)."""

    floor: str
    graph: str
    width: int
    height: int
    resolution: float
    free_area_m2: float
    triples: int

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> ImportedMap:
        return cls(
            _str(d, "floor"),
            _str(d, "graph"),
            _int(d, "width"),
            _int(d, "height"),
            _float(d, "resolution"),
            _float(d, "free_area_m2"),
            _int(d, "triples"),
        )


@dataclass(frozen=True, slots=True)
class Box:
    """A box, metres: extents along the object's x, y and z."""

    length: float
    width: float
    height: float

    def to_json(self) -> JsonObject:
        return {"type": "box", "length": self.length, "width": self.width, "height": self.height}


@dataclass(frozen=True, slots=True)
class Cylinder:
    """An upright cylinder, metres."""

    diameter: float
    height: float

    def to_json(self) -> JsonObject:
        return {"type": "cylinder", "diameter": self.diameter, "height": self.height}


@dataclass(frozen=True, slots=True)
class Sphere:
    """A sphere, metres."""

    diameter: float

    def to_json(self) -> JsonObject:
        return {"type": "sphere", "diameter": self.diameter}


Shape: TypeAlias = Box | Cylinder | Sphere


@dataclass(frozen=True, slots=True)
class Colour:
    """A colour, components in [0, 1] (schema ``ColourInput``)."""

    r: float
    g: float
    b: float
    a: float | None = None

    def to_json(self) -> JsonObject:
        out: JsonObject = {"r": self.r, "g": self.g, "b": self.b}
        if self.a is not None:
            out["a"] = self.a
        return out


@dataclass(frozen=True, slots=True)
class ReportedObject:
    """What the service stored for an object report (schema ``ReportedObject``)."""

    iri: str
    place: str
    reported_by: str
    reported_at: str
    #: Whether an earlier report of the same id was replaced.
    updated: bool

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> ReportedObject:
        return cls(
            _str(d, "iri"),
            _str(d, "place"),
            _str(d, "reported_by"),
            _str(d, "reported_at"),
            _bool(d, "updated"),
        )


@dataclass(frozen=True, slots=True)
class PeopleCount:
    """How many people a robot saw in a place (schema ``PeopleObservation``): ``count``, 0 to
    10000, and when (``observed_at``: a timezone-aware :class:`datetime.datetime` or an
    ``xsd:dateTime`` string such as ``2025-05-06T12:30:00+02:00``). The hour of day of
    ``observed_at``, as written, also moves that hour's estimate: give the building's local time;
    without it the count moves the all-day estimate only."""

    count: float
    observed_at: datetime | str | None = None

    def to_json(self) -> JsonObject:
        out: JsonObject = {"count": self.count}
        if isinstance(self.observed_at, datetime):
            out["observed_at"] = self.observed_at.isoformat()
        elif self.observed_at is not None:
            out["observed_at"] = self.observed_at
        return out


@dataclass(frozen=True, slots=True)
class PeopleEstimate:
    """A running estimate of the people in a place (schema ``EstimateView``): over the whole day
    (``hour`` None) or for one hour of day."""

    people: float
    #: How many counts it is made of.
    observations: int
    hour: int | None = None
    last_observed_at: str | None = None

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> PeopleEstimate:
        hour = d.get("hour")
        if hour is not None and (isinstance(hour, bool) or not isinstance(hour, int)):
            raise ResponseShapeError(f"`hour`: expected an integer, got {hour!r}")
        return cls(_float(d, "people"), _int(d, "observations"), hour, _opt_str(d, "last_observed_at"))


@dataclass(frozen=True, slots=True)
class PeopleEstimates:
    """A place's people estimates after a robot's counts (schema ``PeopleEstimates``)."""

    place: str
    #: How many counts the request added.
    accepted: int
    #: Over the whole day.
    estimate: PeopleEstimate
    #: For every hour of day robots have counted in, sorted by hour.
    by_hour: list[PeopleEstimate]

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> PeopleEstimates:
        return cls(
            _str(d, "place"),
            _int(d, "accepted"),
            PeopleEstimate.from_json(_obj(d.get("estimate"), "estimate")),
            [PeopleEstimate.from_json(_obj(h, "by_hour[]")) for h in _list(d.get("by_hour"), "by_hour")],
        )


@dataclass(frozen=True, slots=True)
class WorldObject:
    """An object as the simulation builds it (schema ``ObjectView``)."""

    iri: str
    cls: str | None
    shape: str
    size: list[float]
    pose: tuple[float, float, float, float]
    colour: str
    placeholder: bool
    open: bool

    @classmethod
    def from_json(cls, d: Mapping[str, Any]) -> WorldObject:
        pose = _obj(d.get("pose"), "pose")
        return cls(
            _str(d, "iri"),
            _opt_str(d, "class"),
            _str(d, "shape"),
            _floats(d.get("size"), "size"),
            (_float(pose, "x"), _float(pose, "y"), _float(pose, "z"), _float(pose, "yaw")),
            _str(d, "colour"),
            _bool(d, "placeholder"),
            _bool(d, "open"),
        )


# --------------------------------------------------------------------------------------------
# Jobs and policies

JobKind: TypeAlias = Literal["train", "evaluate", "validate", "roadmap"]
JobState: TypeAlias = Literal["queued", "running", "succeeded", "failed", "cancelled"]
FINISHED_STATES: frozenset[str] = frozenset({"succeeded", "failed", "cancelled"})


@dataclass(frozen=True, slots=True)
class Job:
    """A job (schema ``JobView``)."""

    id: str
    kind: str
    state: str
    payload: JsonObject
    priority: int
    attempts: int
    max_attempts: int
    cancel_requested: bool
    created: str
    updated: str
    run_after: str
    started: str | None
    finished: str | None
    worker: str | None
    progress: JsonObject | None
    checkpoint: JsonObject | None
    result: JsonObject | None
    error: str | None
    raw: JsonObject = field(repr=False, compare=False)

    @property
    def is_finished(self) -> bool:
        """Succeeded, failed for good, or cancelled."""
        return self.state in FINISHED_STATES

    @classmethod
    def from_json(cls, d: JsonObject) -> Job:
        return cls(
            id=_str(d, "id"),
            kind=_str(d, "kind"),
            state=_str(d, "state"),
            payload=_obj(d.get("payload"), "payload"),
            priority=_int(d, "priority"),
            attempts=_int(d, "attempts"),
            max_attempts=_int(d, "max_attempts"),
            cancel_requested=_bool(d, "cancel_requested"),
            created=_str(d, "created"),
            updated=_str(d, "updated"),
            run_after=_str(d, "run_after"),
            started=_opt_str(d, "started"),
            finished=_opt_str(d, "finished"),
            worker=_opt_str(d, "worker"),
            progress=_opt_obj(d, "progress"),
            checkpoint=_opt_obj(d, "checkpoint"),
            result=_opt_obj(d, "result"),
            error=_opt_str(d, "error"),
            raw=d,
        )


@dataclass(frozen=True, slots=True)
class JobEvent:
    """One event of a job's event stream: ``kind`` is ``state``, ``progress``, ``checkpoint`` or
    ``cancel_requested``; ``data`` its JSON. Training progress carries ``env_steps``,
    ``episodes``, ``grad_steps``, ``success_rate_100``, ``mean_reward_100``, ``fraction_done``,
    ``eta_s``, ``wall_s``, ...; a roadmap job's ``edges`` and ``fraction_done``."""

    #: The event's id in the job's event log (increasing; resume after it).
    id: int
    kind: str
    created: str
    data: JsonObject

    @property
    def state(self) -> str | None:
        """The job's new state, for a ``state`` event."""
        v = self.data.get("state") if self.kind == "state" else None
        return v if isinstance(v, str) else None

    @property
    def fraction_done(self) -> float | None:
        """How much of the job is done, in [0, 1], for a ``progress`` event."""
        v = self.data.get("fraction_done") if self.kind == "progress" else None
        return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None

    @property
    def eta_s(self) -> float | None:
        """Seconds left, for a training's ``progress`` event."""
        v = self.data.get("eta_s") if self.kind == "progress" else None
        return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None

    @classmethod
    def from_sse(cls, event_id: int, event: str, data: str) -> JobEvent:
        try:
            body = json.loads(data)
        except ValueError as e:
            raise ResponseShapeError(f"event {event_id}: data is not JSON: {data[:200]!r}") from e
        body = _obj(body, f"event {event_id}")
        inner = body.get("data")
        return cls(
            event_id,
            str(body.get("kind") or event),
            str(body.get("created") or ""),
            inner if isinstance(inner, dict) else {"value": inner},
        )


@dataclass(frozen=True, slots=True)
class PolicySummary:
    """An exported policy (schema ``PolicySummary``); ``metadata`` (its ``policy.json``) only from
    :meth:`Client.policy`."""

    id: str
    robot: str | None
    place: str | None
    floor: str | None
    job_id: str | None
    created: str | None
    eval: JsonObject
    metadata: JsonObject | None
    raw: JsonObject = field(repr=False, compare=False)

    @classmethod
    def from_json(cls, d: JsonObject) -> PolicySummary:
        return cls(
            _str(d, "id"),
            _opt_str(d, "robot"),
            _opt_str(d, "place"),
            _opt_str(d, "floor"),
            _opt_str(d, "job_id"),
            _opt_str(d, "created"),
            _obj(d.get("eval"), "eval"),
            _opt_obj(d, "metadata"),
            d,
        )
