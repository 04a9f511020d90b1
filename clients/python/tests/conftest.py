"""The real service for the client's tests: `mentalsim serve` on a free port with a fresh data
directory, one in-process job worker and two tokens (an engineer's and a robot's), as
tests/fuzz/run.py and tests/browser/run.py start it.

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

import http.client
import json
import os
import re
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn

import httpx
import pytest

from mentalsim_client import Client, Job, JobEvent

ROOT = Path(__file__).resolve().parents[3]
CLIENT_DIR = Path(__file__).resolve().parents[1]
ROBOT_IRI = "https://mentalsim.dev/data/robots/differential-robot"
TOKENS = {
    "engineer": "client-engineer-token-0123456789abcdef",
    "robot": "client-robot-token-0123456789abcdef",
}
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


def require_all() -> bool:
    return os.environ.get("CI") == "true" or os.environ.get("MENTALSIM_REQUIRE_ALL") == "1"


def missing(what: str) -> NoReturn:
    """Skips the test for want of ``what``; fails it under CI=true (MENTALSIM_REQUIRE_ALL=1)."""
    if require_all():
        pytest.fail(f"{what} (required under CI=true / MENTALSIM_REQUIRE_ALL=1)", pytrace=False)
    pytest.skip(what)


def default_binary() -> Path:
    if os.environ.get("MENTALSIM_BIN"):
        return Path(os.environ["MENTALSIM_BIN"])
    target = os.environ.get("CARGO_TARGET_DIR")
    if not target:
        cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
        target = str(Path(cache) / "mentalsim" / "target")
    return Path(target) / "release" / "mentalsim"


def shared_maps() -> Path:
    if os.environ.get("MENTALSIM_SHARED_MAPS"):
        return Path(os.environ["MENTALSIM_SHARED_MAPS"])
    return ROOT.parent / "shared" / "maps" / "ros"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


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


def config_toml(port: int, data_dir: Path) -> str:
    return f"""\
bind = "127.0.0.1:{port}"
data_dir = "{data_dir}"
request_timeout_s = 300
shutdown_grace_s = 10
# One job at a time in process: the trainings the tests submit run here.
worker_concurrency = 1
log_format = "text"

[[tokens]]
token = "{TOKENS["engineer"]}"
name = "client-engineer"
role = "engineer"

[[tokens]]
token = "{TOKENS["robot"]}"
name = "{ROBOT_IRI}"
role = "robot"
"""


@dataclass
class Service:
    url: str
    port: int
    data_dir: Path
    log_path: Path
    proc: subprocess.Popen[bytes]

    def log_tail(self, lines: int = 30) -> str:
        if not self.log_path.exists():
            return ""
        text = re.sub(r"\x1b\[[0-9;]*m", "", self.log_path.read_text(errors="replace"))
        return "\n".join(text.splitlines()[-lines:])


@pytest.fixture(scope="session")
def binary() -> Path:
    path = default_binary()
    if not path.is_file() or not os.access(path, os.X_OK):
        missing(f"no mentalsim binary at {path} (build it: scripts/test, or set MENTALSIM_BIN)")
    return path


@pytest.fixture(scope="session")
def service(binary: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Service]:
    out = tmp_path_factory.mktemp("mentalsim")
    port = free_port()
    data_dir = out / "data"
    config = out / "mentalsim.toml"
    config.write_text(config_toml(port, data_dir))
    log_path = out / "mentalsim.log"
    # Our configuration only: the caller's MENTALSIM_* variables would change what is tested.
    env = {k: v for k, v in os.environ.items() if not k.startswith("MENTALSIM_")}
    env["RUST_BACKTRACE"] = "1"
    with open(log_path, "ab") as log:
        proc = subprocess.Popen(
            [str(binary), "serve", "--config", str(config)],
            stdin=subprocess.DEVNULL,
            stdout=log,
            stderr=subprocess.STDOUT,
            env=env,
            cwd=out,
        )
    svc = Service(f"http://127.0.0.1:{port}", port, data_dir, log_path, proc)
    deadline = time.monotonic() + 120
    try:
        while True:
            if proc.poll() is not None:
                pytest.fail(f"mentalsim serve exited with {proc.returncode}:\n{svc.log_tail()}", pytrace=False)
            try:
                conn = http.client.HTTPConnection("127.0.0.1", port, timeout=2)
                conn.request("GET", "/healthz")
                if conn.getresponse().status == 200:
                    break
            except OSError:
                pass
            if time.monotonic() > deadline:
                pytest.fail("mentalsim serve did not answer /healthz within 120 s:\n" + svc.log_tail(), pytrace=False)
            time.sleep(0.1)
        yield svc
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
    text = svc.log_tail(100000)
    assert "panicked" not in text, f"the service panicked:\n{svc.log_tail(60)}"
    assert proc.returncode == 0, f"mentalsim serve exited with {proc.returncode} after SIGTERM:\n{svc.log_tail()}"


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
        missing(f"the shared map {path} (the shared maps directory is ../shared/maps/ros beside the repository, or MENTALSIM_SHARED_MAPS)")
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
