"""Jobs and policies through the client, against the real binary: a short training watched
through its server-sent events to success (and the same stream cut twice mid-event, resumed
with Last-Event-ID), evaluation, roadmap and validation jobs waited for with progress,
cancellation, learning curves, and the trained policy downloaded and run locally with numpy."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import httpx
import numpy as np
import pytest
from conftest import TINY_TRAINING, Service, Training, make_client

from mentalsim_client import Client, JobEvent, MentalsimError, Observation, PlanOptions, load_policy


def test_a_training_is_watched_through_its_events_to_success(training: Training) -> None:
    events = training.events
    ids = [e.id for e in events]
    assert ids == sorted(set(ids)), ids
    assert events[0].kind == "state" and events[0].state == "queued"
    assert "running" in [e.state for e in events]
    progress = [e for e in events if e.kind == "progress"]
    assert progress, events
    assert all(0.0 <= (e.fraction_done or 0.0) <= 1.0 for e in progress)
    assert progress[-1].data["env_steps"] > 0 and progress[-1].eta_s is not None
    assert events[-1].kind == "state" and events[-1].state == "succeeded"
    job = training.job
    assert job.state == "succeeded" and job.is_finished and job.attempts == 1
    assert job.result is not None and job.result["policy_id"]
    assert job.finished is not None and job.finished.endswith("Z")


def test_jobs_are_listed_and_filtered(engineer: Client, robot: Client, training: Training) -> None:
    trains = engineer.jobs(kind="train", state="succeeded", limit=5)
    assert training.job.id in [j.id for j in trains]
    assert all(j.kind == "train" and j.state == "succeeded" for j in trains)
    assert len(engineer.jobs(limit=1)) == 1
    # Robots read jobs too.
    assert robot.job(training.job.id).state == "succeeded"


def test_resuming_after_an_event_replays_only_what_followed(engineer: Client, training: Training) -> None:
    events = training.events
    rest = list(engineer.job_events(training.job.id, after=events[1].id))
    assert [e.id for e in rest] == [e.id for e in events[2:]]
    assert list(engineer.job_events(training.job.id, after=events[-1].id)) == []


class CutStream(httpx.SyncByteStream):
    """An event stream that breaks after ``events`` complete events and half of the next."""

    def __init__(self, inner: httpx.SyncByteStream, events: int) -> None:
        self.inner = inner
        self.events = events

    def __iter__(self) -> Iterator[bytes]:
        buffered = b""
        for chunk in self.inner:
            buffered += chunk
            if buffered.count(b"\n\n") > self.events:
                cut = 0
                for _ in range(self.events):
                    cut = buffered.index(b"\n\n", cut) + 2
                following = buffered.index(b"\n\n", cut)
                yield buffered[: cut + (following - cut) // 2]
                raise httpx.ReadError("connection reset (cut by the test)")
        yield buffered

    def close(self) -> None:
        self.inner.close()


class Flaky(httpx.BaseTransport):
    """Cuts the first ``cuts`` event streams, each after two events."""

    def __init__(self, cuts: int) -> None:
        self.inner = httpx.HTTPTransport()
        self.cuts = cuts
        self.last_event_ids: list[str | None] = []

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        response = self.inner.handle_request(request)
        if request.url.path.endswith("/events"):
            self.last_event_ids.append(request.headers.get("last-event-id"))
            if self.cuts > 0 and response.status_code == 200:
                self.cuts -= 1
                assert isinstance(response.stream, httpx.SyncByteStream)
                return httpx.Response(response.status_code, headers=response.headers, stream=CutStream(response.stream, 2), extensions=response.extensions)
        return response

    def close(self) -> None:
        self.inner.close()


def test_a_dropped_event_stream_resumes_with_last_event_id(service: Service, training: Training) -> None:
    flaky = Flaky(cuts=2)
    with make_client(service, "engineer", flaky) as client:
        events = list(client.job_events(training.job.id, retry_delay_s=0.05))
    assert [e.id for e in events] == [e.id for e in training.events]
    assert [e.data for e in events] == [e.data for e in training.events]
    first, second = training.events[1].id, training.events[3].id
    assert flaky.last_event_ids == [None, str(first), str(second)]
    # Without reconnecting, the drop is an error.
    with make_client(service, "engineer", Flaky(cuts=1)) as client, pytest.raises(MentalsimError) as e:
        list(client.job_events(training.job.id, reconnect=False))
    assert e.value.status is None and e.value.code == "unreachable"


def test_a_trainings_learning_curves(engineer: Client, training: Training) -> None:
    csv = engineer.job_curves(training.job.id)
    assert csv.startswith("episode,env_steps,wall_s,reward,outcome")
    assert len(csv.splitlines()) > 1
    assert engineer.job_curves_png(training.job.id).startswith(b"\x89PNG")


def test_the_trained_policy_downloads_and_runs_locally(engineer: Client, robot: Client, training: Training, tmp_path: Path) -> None:
    assert training.job.result is not None
    policy_id = training.job.result["policy_id"]
    listed = {p.id: p for p in robot.policies()}
    assert policy_id in listed and listed[policy_id].job_id == training.job.id
    assert listed[policy_id].eval["episodes"] == 3
    one = robot.policy(policy_id)
    assert one.metadata is not None and one.metadata["format"] == "mentalsim-td3-actor"
    directory = robot.download_policy(policy_id, tmp_path / "policy")
    assert sorted(p.name for p in directory.iterdir()) == ["policy.json", "policy.safetensors"]
    policy = load_policy(directory)
    assert policy.hidden == (16, 16)
    assert policy.scaling.beams == 23 and policy.scaling.layout == "extended"
    assert policy.residual is not None  # the fast preset trains a residual actor
    assert policy.metadata == one.metadata
    rng = np.random.default_rng(7)
    observations = [
        Observation(
            [float(r) for r in rng.uniform(0.1, 6.0, 23)],
            float(rng.uniform(0.0, 12.0)),
            float(rng.uniform(-math.pi, math.pi)),
            (float(rng.uniform(0.0, 0.8)), float(rng.uniform(-0.5, 0.5))),
        )
        for _ in range(64)
    ]
    x = np.stack([policy.encode(o) for o in observations])
    y = policy.forward(x)
    assert y.shape == (64, 2) and np.all((y[:, 0] >= 0) & (y[:, 0] <= 1)) and np.all(np.abs(y[:, 1]) <= 1)
    for o, row in zip(observations[:8], y[:8]):
        a = policy.act(o)
        assert 0.0 <= a.linear <= 0.8 + 1e-6 and abs(a.angular) <= 0.5 + 1e-6
        assert a == policy.scaling.command(row)


def test_wait_for_an_evaluation_with_progress(engineer: Client, training: Training) -> None:
    assert training.job.result is not None
    policy_id = training.job.result["policy_id"]
    job = engineer.submit_evaluation(policy_id, "F0", episodes=3, seed=2, goals_in_view=True)
    progress: list[JobEvent] = []
    events: list[JobEvent] = []
    done = engineer.wait_for_job(job.id, on_progress=progress.append, on_event=events.append, timeout=240)
    assert done.state == "succeeded", done.error
    assert done.result is not None and done.result["episodes"] == 3
    assert progress and all(e.kind == "progress" for e in progress)
    assert events[-1].state == "succeeded"


def test_the_policy_aware_roadmap_of_the_trained_policy(engineer: Client, robot: Client, training: Training, kitchen: str) -> None:
    assert training.job.result is not None
    policy_id = training.job.result["policy_id"]
    # The training enqueued its policy's roadmap job on F0.
    follow_up = engineer.wait_for_job(training.job.result["roadmap_job"], timeout=600)
    assert follow_up.kind == "roadmap" and follow_up.state == "succeeded", follow_up.error
    roadmap = robot.roadmap("F0", "R-001", policy=policy_id)
    assert roadmap.policy == policy_id and roadmap.kind == "policy"
    assert any(e.success is not None for e in roadmap.edges)
    graph = robot.route_graph("F0", "R-001", policy=policy_id)
    measured = [f for f in graph["features"] if "success_probability" in (f["properties"].get("metadata") or {})]
    assert measured
    # One built on request, on the kitchen, with one rollout per edge direction.
    job = engineer.submit_roadmap(policy_id, kitchen, robot="R-001", rollouts=1, keep_threshold=0.5, safety_margin_m=0.1)
    done = engineer.wait_for_job(job.id, timeout=600)
    assert done.state == "succeeded", done.error
    assert done.result is not None and done.result["rollouts"] == 1


def test_a_plan_validated_as_a_job(engineer: Client, kitchen: str) -> None:
    roadmap = engineer.roadmap(kitchen, "R-001")
    a, b = roadmap.nodes[roadmap.edges[0].a], roadmap.nodes[roadmap.edges[0].b]
    job = engineer.submit_validation("R-001", kitchen, (a.x, a.y, 0.0), b, options=PlanOptions(roadmap="geometric", seed=1))
    done = engineer.wait_for_job(job.id, timeout=600)
    assert done.state == "succeeded", done.error
    assert done.result is not None


def test_a_job_is_cancelled_once(engineer: Client) -> None:
    job = engineer.submit_training("R-001", "F0", 10, config=TINY_TRAINING, priority=-10, max_attempts=1)
    cancelled = engineer.cancel_job(job.id)
    assert cancelled.id == job.id and (cancelled.cancel_requested or cancelled.state == "cancelled")
    done = engineer.wait_for_job(job.id, timeout=120)
    assert done.state == "cancelled"
    with pytest.raises(MentalsimError) as e:
        engineer.cancel_job(job.id)
    assert e.value.status == 409 and e.value.code == "conflict"


def test_a_refused_job_names_the_field_at_fault(engineer: Client) -> None:
    with pytest.raises(MentalsimError) as e:
        engineer.submit_evaluation("p-1", "F0", episodes=0)
    assert e.value.status == 422 and e.value.code == "unprocessable"
    assert e.value.field == "payload.episodes", e.value
    assert "episodes" in e.value.message
