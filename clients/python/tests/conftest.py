"""The real service for the client's tests: `mentalsim serve` on a free port with a fresh data
directory, one in-process job worker and two tokens (an engineer's and a robot's), as
tests/fuzz/run.py and tests/browser/run.py start it (all three through
tests/support/mentalsim_service.py, which run_tests.sh puts on PYTHONPATH and MYPYPATH).

The binary is MENTALSIM_BIN, else $CARGO_TARGET_DIR/release/mentalsim (CARGO_TARGET_DIR as
scripts/env.sh sets it: ~/.cache/mentalsim/target by default). The shared maps are
MENTALSIM_SHARED_MAPS, else ../shared/maps/ros beside the repository. A missing binary or map
skips the tests that need it, naming what is missing; under CI=true (or
MENTALSIM_REQUIRE_ALL=1) it fails them instead.

Every request the live tests send goes through a recording transport: the last test checks that
every operation of the client's table was exercised against the real service, and that each
request fits the OpenAPI documents.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

import httpx
import pytest

from mentalsim_client import Client, Job, JobEvent
from mentalsim_service import (
    Config,
    ServiceError,
    default_binary,
    engineer_and_robot,
    executable,
    require_all,
    shared_maps,
)

# The tests import these from here.
from mentalsim_service import ROBOT_IRI as ROBOT_IRI
from mentalsim_service import Service as Service
from mentalsim_service import free_port as free_port

CLIENT_DIR = Path(__file__).resolve().parents[1]
TOKENS = {
    "engineer": "client-engineer-token-0123456789abcdef",
    "robot": "client-robot-token-0123456789abcdef",
}
#: The service's configuration: one job at a time in process (the trainings the tests submit
#: run there), the default limits.
CONFIG = Config(engineer_and_robot(TOKENS, "client-engineer"), worker_concurrency=1)
#: The shared map the tests import: small (148 x 238 cells), a real room (TUM's kitchen lab).
SHARED_MAP = ("strands_tum_kitchen", "tum_kitchen.yaml")
KITCHEN = "kitchen"
#: A training that finishes in seconds (as tests/api/jobs.rs trains).
TINY_TRAINING: dict[str, Any] = {
    "td3": {"hidden": [16, 16], "batch_size": 32},
    "envs": 2,
    "buffer_capacity": 20000,
    "random_steps": 100,
    "demo_steps": 500,
    "bc_steps": 100,
    "critic_warmup_steps": 100,
    "eval_every": 1000000,
    "eval_episodes": 3,
    "checkpoint_every_s": 1.0,
}


def missing(what: str) -> NoReturn:
    """Skips the test for want of ``what``; fails it under CI=true (MENTALSIM_REQUIRE_ALL=1)."""
    if require_all():
        pytest.fail(f"{what} (required under CI=true / MENTALSIM_REQUIRE_ALL=1)", pytrace=False)
    pytest.skip(what)


# --------------------------------------------------------------------------------------------
# Recording every request


@dataclass
class Recorded:
    method: str
    raw_path: str
    query: dict[str, list[str]]
    headers: dict[str, str]
    content_type: str
    body: bytes
    status: int = 0


@dataclass
class Recorder(httpx.BaseTransport):
    """Forwards requests to ``inner`` and keeps a copy of each."""

    inner: httpx.BaseTransport
    calls: list[Recorded] = field(default_factory=list)

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        body = request.read()
        raw = request.url.raw_path.decode("ascii")
        path, _, _ = raw.partition("?")
        query: dict[str, list[str]] = {}
        for k, v in request.url.params.multi_items():
            query.setdefault(k, []).append(v)
        recorded = Recorded(
            request.method,
            path,
            query,
            {k.lower(): v for k, v in request.headers.items()},
            request.headers.get("content-type", ""),
            body,
        )
        self.calls.append(recorded)
        response = self.inner.handle_request(request)
        recorded.status = response.status_code
        return response

    def close(self) -> None:
        self.inner.close()


#: Every request the live tests sent, and whether the live test modules all ran.
LIVE_CALLS: list[Recorded] = []


# --------------------------------------------------------------------------------------------
# The service


@pytest.fixture(scope="session")
def binary() -> Path:
    path = default_binary()
    if not executable(path):
        missing(f"no mentalsim binary at {path} (build it: scripts/test, or set MENTALSIM_BIN)")
    return path


@pytest.fixture(scope="session")
def service(binary: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Service]:
    svc = Service(binary, tmp_path_factory.mktemp("mentalsim"), CONFIG)
    try:
        try:
            svc.start()
        except ServiceError as e:
            pytest.fail(str(e), pytrace=False)
        yield svc
    finally:
        stopped = svc.stop()
    assert not stopped.panics, f"the service panicked:\n{svc.log_tail(60)}"
    assert stopped.code == 0, f"mentalsim serve exited with {stopped.status} after SIGTERM:\n{svc.log_tail(30)}"


def make_client(service: Service, role: str, transport: httpx.BaseTransport | None = None) -> Client:
    recorder = Recorder(transport or httpx.HTTPTransport(), LIVE_CALLS)
    return Client(service.url, TOKENS[role], timeout=300, transport=recorder)


@pytest.fixture(scope="session")
def engineer(service: Service) -> Iterator[Client]:
    with make_client(service, "engineer") as client:
        yield client


@pytest.fixture(scope="session")
def robot(service: Service) -> Iterator[Client]:
    with make_client(service, "robot") as client:
        yield client


@pytest.fixture(scope="session")
def shared_map() -> Path:
    folder, yaml = SHARED_MAP
    path = shared_maps() / folder / yaml
    if not path.is_file():
        missing(f"the shared map {path} (the shared maps directory is ../shared/maps/ros beside the repository, $MENTALSIM_SHARED/maps/ros, or MENTALSIM_SHARED_MAPS)")
    return path


@pytest.fixture(scope="session")
def kitchen(engineer: Client, shared_map: Path) -> str:
    """The shared kitchen map, imported as the floor ``kitchen``."""
    engineer.import_map(KITCHEN, shared_map)
    return KITCHEN


@dataclass
class Training:
    job: Job
    events: list[JobEvent]


@pytest.fixture(scope="session")
def training(engineer: Client) -> Training:
    """A training that finishes in seconds, followed through its event stream to the end."""
    submitted = engineer.submit_training("R-001", "F0", 0.05, config=TINY_TRAINING, seed=3)
    assert submitted.state == "queued" and submitted.kind == "train"
    assert submitted.payload["minutes"] == 0.05
    events = list(engineer.job_events(submitted.id))
    return Training(engineer.job(submitted.id), events)


def read_pgm(data: bytes) -> tuple[int, int, int, bytes]:
    """(width, height, maxval, pixels) of a binary PGM."""
    m = re.match(rb"P5\s+(?:#[^\n]*\n\s*)*(\d+)\s+(?:#[^\n]*\n\s*)*(\d+)\s+(?:#[^\n]*\n\s*)*(\d+)\s", data)
    assert m, data[:40]
    w, h, maxval = int(m.group(1)), int(m.group(2)), int(m.group(3))
    pixels = data[m.end() : m.end() + w * h]
    assert len(pixels) == w * h
    return w, h, maxval, pixels


def json_dumps(value: object) -> str:
    return json.dumps(value, indent=1, sort_keys=True)
