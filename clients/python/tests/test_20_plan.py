"""Plans through the client, against the real binary, on the imported shared map: the ROS path
from the start through the validated waypoints to the goal, every pose of the rehearsal on a
free cell of the floor's map, several goals with every option, the roadmap and its Nav2 route
graph, and the README's example script."""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import CLIENT_DIR, TOKENS, Service, read_pgm

from mentalsim_client import Client, MentalsimError, PlanOptions, Point, Roadmap


def far_apart(roadmap: Roadmap) -> tuple[Point, Point]:
    """Two roadmap nodes of the largest connected component, as far apart as any."""
    parent = list(range(len(roadmap.nodes)))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for e in roadmap.edges:
        parent[find(e.a)] = find(e.b)
    roots = [find(i) for i in range(len(roadmap.nodes))]
    biggest = max(set(roots), key=roots.count)
    members = [roadmap.nodes[i] for i, r in enumerate(roots) if r == biggest]
    a, b = max(itertools.combinations(members, 2), key=lambda p: math.dist((p[0].x, p[0].y), (p[1].x, p[1].y)))
    return a, b


@pytest.fixture(scope="module")
def mission(robot: Client, kitchen: str) -> tuple[Point, Point]:
    roadmap = robot.roadmap(kitchen, "R-001")
    assert roadmap.kind == "geometric" and roadmap.floor.endswith(f"/{kitchen}")
    assert len(roadmap.nodes) > 10 and roadmap.edges and roadmap.samples > 0
    return far_apart(roadmap)


def test_a_plan_is_a_ros_path_from_the_start_to_the_goal(robot: Client, kitchen: str, mission: tuple[Point, Point], tmp_path: Path) -> None:
    start, goal = mission
    plan = robot.plan("R-001", kitchen, (start.x, start.y, 0.0), goal)
    # No policy is trained yet: a classical controller (`auto`: Regulated Pure Pursuit)
    # validated it, and the answer says why.
    assert plan.controller == "classical" and plan.policy is None
    assert plan.controller_choice.controller == "rpp"
    assert "no trained policy" in plan.controller_choice.why
    assert plan.note and "follower" in plan.note
    assert [leg.controller for leg in plan.legs] == ["classical"]
    assert plan.attempts and plan.attempts[-1].outcome == "reached"
    assert all(a.handover_share == 0.0 for a in plan.attempts)  # the follower's own drives
    assert plan.floor.endswith(f"/{kitchen}") and plan.robot.endswith("differential-robot")
    path = plan.path
    assert path.frame_id == "map" and all(p.frame_id == "map" for p in path.poses)
    # The start, then every waypoint, ending at the goal.
    assert (path.poses[0].x, path.poses[0].y) == (start.x, start.y)
    assert path.points()[1:] == [(w.x, w.y) for w in plan.waypoints]
    assert math.dist(path.points()[-1], (goal.x, goal.y)) < 1e-9
    assert plan.goal_indices == [len(plan.waypoints) - 1]
    # Each pose faces the next one; quaternions are rotations about z.
    for here, there in zip(path.poses, path.poses[1:]):
        assert here.z == 0.0 and here.qx == 0.0 and here.qy == 0.0
        assert abs(here.qz**2 + here.qw**2 - 1.0) < 1e-9
        if math.dist((here.x, here.y), (there.x, there.y)) > 1e-3:
            assert abs(math.remainder(here.yaw - math.atan2(there.y - here.y, there.x - here.x), math.tau)) < 1e-6
    length = sum(math.dist(a, b) for a, b in zip(path.points(), path.points()[1:]))
    assert abs(length - plan.waypoint_path_length_m) < 1e-6
    assert plan.distance_m > 0.5 * math.dist((start.x, start.y), (goal.x, goal.y))
    assert plan.roadmap.kind == "geometric" and plan.simulated_time_s > 0
    # Every pose the simulated robot drove through is on a free cell of the floor's map.
    _, pgm = robot.download_map(kitchen, tmp_path)
    w, h, _, pixels = read_pgm(pgm.read_bytes())
    place = robot.place(kitchen)
    assert place.map is not None
    ox, oy = place.map.origin[0], place.map.origin[1]
    res = place.map.resolution
    assert len(plan.trajectory) > 10
    for pose in plan.trajectory:
        col, row_from_bottom = int((pose.x - ox) / res), int((pose.y - oy) / res)
        assert 0 <= col < w and 0 <= row_from_bottom < h
        assert pixels[(h - 1 - row_from_bottom) * w + col] == 254, pose
    # The ROS JSON of the path, as a Nav2 robot publishes it.
    ros = path.to_ros()
    assert ros["header"] == {"frame_id": "map"} and ros["poses"][0]["pose"]["position"]["x"] == start.x
    assert ros == plan.raw["path"]


def test_several_goals_with_every_option(robot: Client, kitchen: str, mission: tuple[Point, Point]) -> None:
    start, goal = mission
    middle = Point((start.x + goal.x) / 2, (start.y + goal.y) / 2)
    roadmap = robot.roadmap(kitchen, "R-001", safety_margin_m=0.1)
    # A roadmap node near the middle: free, and joined to the others.
    via = min(roadmap.nodes, key=lambda n: math.dist((n.x, n.y), (middle.x, middle.y)))
    options = PlanOptions(
        max_attempts=3,
        max_replans=5,
        noise=False,
        roadmap="geometric",
        safety_margin_m=0.1,
        seed=4,
        shortcut=True,
        trace=True,
        trajectory_stride=4,
        waypoint_timeout_s=20.0,
    )
    plan = robot.plan("R-001", kitchen, (start.x, start.y, 1.0), goals=[via, goal], options=options)
    assert len(plan.goal_indices) == 2 and plan.goal_indices[-1] == len(plan.waypoints) - 1
    assert [leg.goal_index for leg in plan.legs] == [0, 1]
    assert plan.waypoints[plan.goal_indices[0]] == via
    assert plan.laser is not None and plan.laser["angles_rad"]
    traced = [a for a in plan.attempts if a.trace is not None]
    assert traced and traced[-1].trace is not None and traced[-1].trace["poses"]
    # The same request gives the same report (the seed fixes roadmaps and simulation).
    again = robot.plan("R-001", kitchen, (start.x, start.y, 1.0), goals=[via, goal], options=options)
    assert again.waypoints == plan.waypoints and again.distance_m == plan.distance_m


def test_the_roadmap_as_a_nav2_route_graph(robot: Client, kitchen: str) -> None:
    roadmap = robot.roadmap(kitchen, "R-001")
    graph = robot.route_graph(kitchen, "R-001")
    assert graph["type"] == "FeatureCollection"
    nodes = [f for f in graph["features"] if f["geometry"]["type"] == "Point"]
    edges = [f for f in graph["features"] if f["geometry"]["type"] == "MultiLineString"]
    assert len(nodes) == len(roadmap.nodes)
    assert len(edges) == 2 * len(roadmap.edges)  # one per direction
    ids = [f["properties"]["id"] for f in graph["features"]]
    assert len(ids) == len(set(ids))


def test_the_readme_example_asks_for_a_plan_and_prints_the_path(service: Service) -> None:
    """examples/plan.py, the README's robot script, run as a robot would run it."""
    env = {**os.environ, "MENTALSIM_URL": service.url, "MENTALSIM_TOKEN": TOKENS["robot"]}
    env["PYTHONPATH"] = str(CLIENT_DIR / "src") + os.pathsep + env.get("PYTHONPATH", "")
    run = subprocess.run(
        [sys.executable, str(CLIENT_DIR / "examples" / "plan.py")],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    lines = run.stdout.strip().splitlines()
    assert "validated" in lines[0]
    poses = [line.split() for line in lines[1:]]
    assert len(poses) >= 2
    first = [float(v.split("=")[1].rstrip("°")) for v in poses[0]]
    last = [float(v.split("=")[1].rstrip("°")) for v in poses[-1]]
    assert first[:2] == [0.5, -2.0]  # the start
    assert last[:2] == [-12.0, -1.0]  # the goal


def test_the_readme_shows_the_example_script() -> None:
    readme = (CLIENT_DIR.parents[1] / "README.md").read_text()
    section = readme[readme.index("### Python client") :]
    shown = section[section.index("```python\n") + len("```python\n") :]
    shown = shown[: shown.index("```")]
    script = (CLIENT_DIR / "examples" / "plan.py").read_text()
    code = script[script.index('"""', 3) + 3 :].strip()
    assert shown.strip() == code, "README.md's Python client example and examples/plan.py differ"


def test_a_plan_among_people_says_how_close_they_came(robot: Client, kitchen: str, mission: tuple[Point, Point]) -> None:
    start, goal = mission
    plan = robot.plan("R-001", kitchen, (start.x, start.y, 0.0), goal, options=PlanOptions(people=5.0, seed=3))
    assert plan.people is not None and plan.people.source == "density"
    assert plan.people.people >= 1 and plan.people.attempts == len(plan.attempts)
    assert plan.people.attempts_reached >= 1
    assert all(a.min_person_clearance_m is not None for a in plan.attempts)
    # Driven again among three fresh draws: each reached or named as failed.
    again = robot.plan("R-001", kitchen, (start.x, start.y, 0.0), goal, options=PlanOptions(people=5.0, seed=3, people_draws=3))
    assert again.people is not None and again.people.draws is not None
    assert again.people.draws.draws == 3
    assert again.people.draws.reached + len(again.people.draws.failures) == 3
    # The empty building: nothing about people.
    empty = robot.plan("R-001", kitchen, (start.x, start.y, 0.0), goal, options=PlanOptions(people="none", seed=3))
    assert empty.people is None and all(a.min_person_clearance_m is None for a in empty.attempts)


def test_a_plan_takes_its_place_in_the_floors_traffic(robot: Client, engineer: Client, kitchen: str, mission: tuple[Point, Point]) -> None:
    start, goal = mission
    live = robot.traffic_events(kitchen, "R-001")
    first = next(live)
    assert first.kind == "snapshot" and first.traffic is not None and first.version == first.traffic.version
    plan = robot.plan("R-001", kitchen, (start.x, start.y, 0.0), goal, options=PlanOptions(seed=5, people="none", tolerance_s=1.5))
    s = plan.schedule
    assert s is not None and s.committed and s.tolerance_s == 1.5
    assert len(s.waypoint_times_ms) == len(plan.waypoints)
    assert s.waypoint_times_ms == sorted(s.waypoint_times_ms) and s.waypoint_times_ms[0] >= s.start_time_ms
    # The ROS path carries the schedule's times.
    assert all(p.stamp_ms is not None for p in plan.path.poses)
    committed = robot.traffic(kitchen, "R-001")
    # The live stream saw the commit (a robot's earlier plan, replaced, leaves first).
    seen = next(e for e in live if e.kind == "committed")
    assert seen.plan_id == s.plan_id and seen.version > first.version and seen.itinerary is not None
    live.close()
    assert [p.plan_id for p in committed.plans if p.robot.endswith("differential-robot")] == [s.plan_id]
    # The plan as its robot follows it: revision 1, tagged; unchanged while that tag is its.
    status = robot.plan_status(s.plan_id)
    assert status is not None and status.plan.revision == 1 and status.etag is not None
    assert status.acknowledged_revision == 1 and status.revisable_until_unix_ms <= status.departs_unix_ms
    assert robot.plan_status(s.plan_id, etag=status.etag) is None
    watch = robot.watch_plan(s.plan_id, poll_s=1.0)
    assert next(watch).plan.revision == 1
    with pytest.raises(MentalsimError) as never:
        robot.report_progress(s.plan_id, start.x, start.y, revision=2)
    assert never.value.status == 409 and never.value.field == "revision"
    # Still at its start 5 s after setting off: the rest of its schedule shifts.
    late = engineer.report_progress(s.plan_id, start.x, start.y, time_ms=s.start_time_ms + 5000, revision=1)
    assert late.plan_id == s.plan_id and late.delay_s > 0 and late.revision == 1
    # Alone on the floor: it passes after no one and may go to its goal.
    assert s.passes_after == [] and s.may_go_until_t_s is None
    assert late.passes_after == [] and late.may_go_until_t_s is None
    assert status.passes_after == [] and status.may_go_until_t_s is None
    assert engineer.cancel_plan(s.plan_id).plan_id == s.plan_id
    # The watch ends with the plan.
    assert list(watch) == []
    assert all(p.plan_id != s.plan_id for p in robot.traffic(kitchen, "R-001").plans)
    with pytest.raises(MentalsimError) as gone:
        engineer.cancel_plan(s.plan_id)
    assert gone.value.status == 404
    # Standing idle at its start: the schedule holds it there (one pose) until cancelled.
    standing = robot.stand(kitchen, "R-001", start.x, start.y, for_s=60.0)
    assert len(standing.trajectory) == 1 and standing.robot.endswith("differential-robot")
    assert (standing.trajectory[0]["x"], standing.trajectory[0]["y"]) == (start.x, start.y)
    assert any(p.plan_id == standing.plan_id for p in robot.traffic(kitchen, "R-001").plans)
    with pytest.raises(MentalsimError) as inside:
        robot.stand(kitchen, "R-001", -1000.0, -1000.0)
    assert inside.value.status == 422
    assert engineer.cancel_plan(standing.plan_id).plan_id == standing.plan_id
