"""A plan as a ROS 2 recording (issue 18): ``POST /v1/plan`` with ``Accept: application/x-mcap``
against the real binary, every message decoded by the ``mcap`` and ``mcap-ros2-support``
packages from PyPI (what Foxglove's own Python tooling reads ROS 2 bags with), and checked
against the JSON answer to the same request: the map against the floor's map_server export,
the plan against ``path``, every attempt's poses, transforms and laser beams against its trace."""

from __future__ import annotations

import io
import json
import math
import struct
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import httpx
import pytest
from conftest import TOKENS, Service, read_pgm
from test_20_plan import far_apart
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from mentalsim_client import Client, PlanOptions, Point

STATIC_TOPICS = ("/map", "/plan", "/tf_static")
STEP_TOPICS = ("/rehearsal/pose", "/tf", "/rehearsal/scan")


def yaw_of(q: Any) -> float:
    assert q.x == 0.0 and q.y == 0.0
    return 2.0 * math.atan2(q.z, q.w)


def as_f32(x: float) -> float:
    value: float = struct.unpack("<f", struct.pack("<f", x))[0]
    return value


def stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


@pytest.fixture(scope="module")
def rehearsal(robot: Client, service: Service, kitchen: str) -> tuple[dict[str, Any], list[tuple[str, int, Any]]]:
    first, goal = far_apart(robot.roadmap(kitchen, "R-001"))
    start = (first.x, first.y, 0.5)
    options = PlanOptions(seed=3, trace=True)
    # The JSON answer as it comes, traces included, to check the recording against.
    raw = httpx.post(
        f"{service.url}/v1/plan",
        headers={"Authorization": f"Bearer {TOKENS['robot']}"},
        json={"robot": "R-001", "place": kitchen, "start": {"x": start[0], "y": start[1], "yaw": start[2]}, "goal": {"x": goal.x, "y": goal.y}, "options": {"seed": 3, "trace": True}},
        timeout=300,
    )
    assert raw.status_code == 200, raw.text
    answer: dict[str, Any] = raw.json()
    data = robot.plan_recording("R-001", kitchen, start, Point(goal.x, goal.y), options=options)
    reader = make_reader(io.BytesIO(data), decoder_factories=[DecoderFactory()])
    assert reader.get_header().profile == "ros2"
    messages = []
    for schema, channel, message, decoded in reader.iter_decoded_messages():
        assert schema is not None and schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
        assert message.log_time == message.publish_time
        messages.append((channel.topic, message.log_time, decoded))
    metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
    assert metadata["mentalsim"]["robot"] == answer["robot"]
    assert metadata["mentalsim"]["floor"] == answer["floor"]
    return answer, messages


def by_topic(messages: list[tuple[str, int, Any]], topic: str) -> list[tuple[int, Any]]:
    return [(t, m) for top, t, m in messages if top == topic]


def test_every_topic_carries_what_the_json_answer_says(rehearsal: tuple[dict[str, Any], list[tuple[str, int, Any]]]) -> None:
    answer, messages = rehearsal
    for topic in STATIC_TOPICS:
        assert len(by_topic(messages, topic)) == 1, topic
    steps = sum(len(a["trace"]["poses"]) for a in answer["attempts"])
    assert steps > 10
    for topic in STEP_TOPICS:
        assert len(by_topic(messages, topic)) == steps, topic
    assert len(by_topic(messages, "/rehearsal/attempt")) == len(answer["attempts"])
    assert len(by_topic(messages, "/rehearsal/attempt_path")) == len(answer["attempts"])

    # /plan is the answer's nav_msgs/Path, pose for pose.
    (_, plan), = by_topic(messages, "/plan")
    assert plan.header.frame_id == answer["path"]["header"]["frame_id"] == "map"
    assert len(plan.poses) == len(answer["path"]["poses"])
    for got, want in zip(plan.poses, answer["path"]["poses"]):
        assert got.header.frame_id == want["header"]["frame_id"]
        p, q = got.pose.position, got.pose.orientation
        wp, wq = want["pose"]["position"], want["pose"]["orientation"]
        assert (p.x, p.y, p.z) == (wp["x"], wp["y"], wp["z"])
        assert (q.x, q.y, q.z, q.w) == (wq["x"], wq["y"], wq["z"], wq["w"])


def test_the_map_is_the_floor_map_server_exports(rehearsal: tuple[dict[str, Any], list[tuple[str, int, Any]]], robot: Client, kitchen: str, tmp_path: Path) -> None:
    _, messages = rehearsal
    (_, grid), = by_topic(messages, "/map")
    _, pgm = robot.download_map(kitchen, tmp_path)
    w, h, _, pixels = read_pgm(pgm.read_bytes())
    place = robot.place(kitchen)
    assert place.map is not None
    assert grid.header.frame_id == "map"
    assert (grid.info.width, grid.info.height) == (w, h)
    assert abs(grid.info.resolution - place.map.resolution) < 1e-7  # float32
    assert (grid.info.origin.position.x, grid.info.origin.position.y) == (place.map.origin[0], place.map.origin[1])
    assert abs(yaw_of(grid.info.origin.orientation) - place.map.origin[2]) < 1e-12
    # nav_msgs/OccupancyGrid: row 0 at the bottom; the PGM's first row is the top.
    value = {254: 0, 0: 100, 205: -1}
    want = [value[pixels[(h - 1 - r) * w + c]] for r in range(h) for c in range(w)]
    assert list(grid.data) == want


def test_every_attempt_replays_step_by_step(rehearsal: tuple[dict[str, Any], list[tuple[str, int, Any]]], robot: Client) -> None:
    answer, messages = rehearsal
    (_, static), = by_topic(messages, "/tf_static")
    parents = {t.child_frame_id: t.header.frame_id for t in static.transforms}
    assert parents["base_link"] == "base_footprint"
    laser_frames = [child for child, parent in parents.items() if parent == "base_link"]
    assert len(laser_frames) == 1
    laser_frame = laser_frames[0]
    # The frames are the robot's URDF links.
    links = {link.get("name") for link in ET.fromstring(robot.robot_urdf("R-001")).iter("link")}
    assert {"base_footprint", "base_link", laser_frame} <= links
    mount_yaw = yaw_of(next(t for t in static.transforms if t.child_frame_id == laser_frame).transform.rotation)

    laser = answer["laser"]
    poses = by_topic(messages, "/rehearsal/pose")
    tfs = by_topic(messages, "/tf")
    scans = by_topic(messages, "/rehearsal/scan")
    infos = by_topic(messages, "/rehearsal/attempt")
    paths = by_topic(messages, "/rehearsal/attempt_path")
    k = 0
    previous_end = -1
    for n, attempt in enumerate(answer["attempts"]):
        trace = attempt["trace"]
        begin, info = infos[n]
        assert begin > previous_end  # attempts follow each other on the timeline
        reported = json.loads(info.data)
        assert reported == {key: v for key, v in attempt.items() if key != "trace"}
        assert paths[n][0] == begin
        assert [(p.pose.position.x, p.pose.position.y) for p in paths[n][1].poses] == [(p["x"], p["y"]) for p in trace["path"]]
        for i, (pose, t) in enumerate(zip(trace["poses"], trace["times_s"])):
            at, msg = poses[k]
            assert abs((at - begin) * 1e-9 - t) < 1e-6
            assert stamp_ns(msg.header) == at and msg.header.frame_id == "map"
            assert (msg.pose.position.x, msg.pose.position.y) == (pose["x"], pose["y"])
            assert abs(math.remainder(yaw_of(msg.pose.orientation) - pose["yaw"], math.tau)) < 1e-12
            tf_at, tf = tfs[k]
            (transform,) = tf.transforms
            assert tf_at == at and transform.header.frame_id == "map" and transform.child_frame_id == "base_footprint"
            assert (transform.transform.translation.x, transform.transform.translation.y) == (pose["x"], pose["y"])
            scan_at, scan = scans[k]
            assert scan_at == at and scan.header.frame_id == laser_frame
            assert scan.range_max == pytest.approx(laser["max_range_m"], rel=1e-6)
            # Each beam the controller read sits at its own sample; the others are NaN (no return).
            read = [(j, r) for j, r in enumerate(scan.ranges) if not math.isnan(r)]
            # The JSON writes each float32 as its shortest decimal: read back as float32, equal.
            assert [r for _, r in read] == [as_f32(r) for r in trace["ranges"][i]]
            for (j, _), angle in zip(read, laser["angles_rad"]):
                assert abs(scan.angle_min + j * scan.angle_increment + mount_yaw - angle) < 1e-5
            k += 1
        previous_end = poses[k - 1][0]
    assert k == len(poses)
