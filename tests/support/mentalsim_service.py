"""The real binary for Python tests: `mentalsim serve` on a free port with a fresh data directory,
a suite's tokens and settings in a config file, its log in a file, stopped by SIGTERM.

Shared by tests/fuzz/run.py, tests/browser/run.py (which put tests/support on sys.path) and
clients/python/tests/conftest.py (clients/python/run_tests.sh puts tests/support on PYTHONPATH
for pytest and on MYPYPATH for `mypy --strict`, which checks this module with the tests).
Standard library only.

- The binary (:func:`default_binary`): MENTALSIM_BIN, else $CARGO_TARGET_DIR/release/mentalsim
  (CARGO_TARGET_DIR as scripts/env.sh sets it: ~/.cache/mentalsim/target by default).
- The shared maps (:func:`shared_maps`): MENTALSIM_SHARED_MAPS, else $MENTALSIM_SHARED/maps/ros,
  else ../shared/maps/ros beside the repository.
- A missing tool, file or binary is a skip, but a failure under CI=true or
  MENTALSIM_REQUIRE_ALL=1 (:func:`require_all`). :func:`missing` raises :class:`Missing`, which
  says which of the two it is, for the caller to report its own way (tests/browser/run.py: its
  exit status and closing line; conftest.py turns require_all() into pytest's fail or skip).
- The service: ``Service(binary, out, Config(tokens, ...))`` writes ``out/mentalsim.toml`` and
  makes ``out/data`` afresh; :meth:`Service.start` starts it, logging to ``out/mentalsim.log``,
  and waits for ``/readyz``; :meth:`Service.stop` sends SIGTERM, waits, kills it if it is still
  there, and returns an :class:`Exit` with its exit status and the panics in its log.

Example::

    service = Service(default_binary(), out, Config(engineer_and_robot(TOKENS, "my-engineer")))
    service.start()  # ServiceError if it exits or is not ready in time
    try:
        ...  # requests to service.url
    finally:
        stopped = service.stop()
    assert stopped.code == 0 and not stopped.panics, service.log_tail()
"""

from __future__ import annotations

import http.client
import os
import re
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import NoReturn, TypeAlias

#: The repository this file is in.
ROOT = Path(__file__).resolve().parents[2]
#: The sample robot: the name of every suite's robot token.
ROBOT_IRI = "https://mentalsim.dev/data/robots/differential-robot"


# --------------------------------------------------------------------------------------------
# What the tests need, and what happens when it is missing


def default_binary() -> Path:
    """MENTALSIM_BIN, else $CARGO_TARGET_DIR/release/mentalsim (CARGO_TARGET_DIR as
    scripts/env.sh sets it: $XDG_CACHE_HOME/mentalsim/target, ~/.cache/mentalsim/target by
    default). It may not exist: see :func:`executable`."""
    if os.environ.get("MENTALSIM_BIN"):
        return Path(os.environ["MENTALSIM_BIN"])
    target = os.environ.get("CARGO_TARGET_DIR")
    if not target:
        cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
        target = str(Path(cache) / "mentalsim" / "target")
    return Path(target) / "release" / "mentalsim"


def executable(path: Path) -> bool:
    """Whether ``path`` is a file this process may execute."""
    return path.is_file() and os.access(path, os.X_OK)


def require_all() -> bool:
    """Whether a missing tool, file or binary fails the tests instead of skipping them: under
    CI=true (as .ci/run sets it) or MENTALSIM_REQUIRE_ALL=1 (as scripts/test sets it)."""
    return os.environ.get("CI") == "true" or os.environ.get("MENTALSIM_REQUIRE_ALL") == "1"


class Missing(Exception):
    """``what`` is missing (``hint``: how to get it). ``required`` is :func:`require_all` when it
    was raised: the caller fails if it is true, and skips otherwise."""

    def __init__(self, what: str, hint: str = "") -> None:
        super().__init__(f"{what} ({hint})" if hint else what)
        self.what = what
        self.hint = hint
        self.required = require_all()


def missing(what: str, hint: str = "") -> NoReturn:
    """Raises :class:`Missing` for ``what``: a skip, or under CI=true (MENTALSIM_REQUIRE_ALL=1) a
    failure."""
    raise Missing(what, hint)


def shared_maps() -> Path:
    """The shared ROS maps (one folder per map, a .yaml beside its image): MENTALSIM_SHARED_MAPS,
    else maps/ros under MENTALSIM_SHARED (the shared data directory the Rust tests read), else
    ../shared/maps/ros beside the repository. It may not exist."""
    if os.environ.get("MENTALSIM_SHARED_MAPS"):
        return Path(os.environ["MENTALSIM_SHARED_MAPS"])
    if os.environ.get("MENTALSIM_SHARED"):
        return Path(os.environ["MENTALSIM_SHARED"]) / "maps" / "ros"
    return ROOT.parent / "shared" / "maps" / "ros"


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listened on a moment ago."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


# --------------------------------------------------------------------------------------------
# The configuration


#: A value of a top-level key of `mentalsim.toml`.
TomlValue: TypeAlias = str | int | float | bool


@dataclass(frozen=True)
class Token:
    """One ``[[tokens]]`` entry: a bearer token, the name it acts under, and its role."""

    token: str
    name: str
    role: str


def engineer_and_robot(tokens: Mapping[str, str], engineer_name: str) -> tuple[Token, Token]:
    """The two tokens every suite serves: ``tokens["engineer"]``, an engineer named
    ``engineer_name``, and ``tokens["robot"]``, a robot named as the sample robot (ROBOT_IRI)."""
    return (
        Token(tokens["engineer"], engineer_name, "engineer"),
        Token(tokens["robot"], ROBOT_IRI, "robot"),
    )


@dataclass(frozen=True)
class Config:
    """What a suite's `mentalsim.toml` holds besides ``bind`` (127.0.0.1 and the service's port),
    ``data_dir`` (the service's) and ``log_format = "text"``."""

    tokens: Sequence[Token]
    request_timeout_s: int = 300
    shutdown_grace_s: int = 10
    #: Jobs run in the serving process, this many at a time (0: none run; they stay queued).
    worker_concurrency: int = 1
    #: Further top-level keys, in this order (e.g. ``{"query_deadline_s": 10}``).
    settings: Mapping[str, TomlValue] = field(default_factory=dict)

    def toml(self, port: int, data_dir: Path) -> str:
        """The config file's text, for a service on ``port`` keeping its data in ``data_dir``."""
        keys: dict[str, TomlValue] = {
            "bind": f"127.0.0.1:{port}",
            "data_dir": str(data_dir),
            "request_timeout_s": self.request_timeout_s,
            "shutdown_grace_s": self.shutdown_grace_s,
            "worker_concurrency": self.worker_concurrency,
            "log_format": "text",
            **self.settings,
        }
        lines = [f"{key} = {toml_value(value)}" for key, value in keys.items()]
        for token in self.tokens:
            lines += [
                "",
                "[[tokens]]",
                f"token = {toml_value(token.token)}",
                f"name = {toml_value(token.name)}",
                f"role = {toml_value(token.role)}",
            ]
        return "\n".join(lines) + "\n"


def toml_value(value: TomlValue) -> str:
    """``value`` as a TOML value (a string as a basic string, escaped)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    escaped = value.replace("\\", "\\\\").replace('"', '\\"')
    return '"' + re.sub(r"[\x00-\x1f\x7f]", lambda m: f"\\u{ord(m.group()):04x}", escaped) + '"'


# --------------------------------------------------------------------------------------------
# The service


class ServiceError(RuntimeError):
    """`mentalsim serve` did not start: it exited, or was not ready in time (the message holds
    the end of its log)."""


@dataclass(frozen=True)
class Exit:
    """How the service ended, as :meth:`Service.stop` saw it."""

    #: Its exit status (negative: the signal that ended it); None if it was never started.
    code: int | None
    #: It was running, and was sent SIGTERM (False: it had exited already, or never started).
    terminated: bool
    #: It was still running when the wait after SIGTERM ran out, and was killed.
    killed: bool
    #: Seconds from SIGTERM to its exit (0 when it was not sent).
    elapsed_s: float
    #: The panics in its whole log: where (``panicked at <where>``) and how many times.
    panics: dict[str, int]

    @property
    def status(self) -> str:
        """The exit status, with the signal's name if one ended it (``-9, SIGKILL``)."""
        return f"{self.code}{signal_name(self.code)}"


def signal_name(code: int | None) -> str:
    """``", SIGKILL"`` for an exit status of -9 (a process ended by that signal), else ``""``."""
    if code is not None and code < 0:
        try:
            return f", {signal.Signals(-code).name}"
        except ValueError:
            pass
    return ""


def strip_ansi(text: str) -> str:
    """``text`` without terminal colours."""
    return re.sub(r"\x1b\[[0-9;]*m", "", text)


class Service:
    """`mentalsim serve` of ``binary`` with ``config``, everything of it under ``out``:
    ``mentalsim.toml``, ``data/`` (made afresh here) and ``mentalsim.log`` (appended to by every
    start). ``port``: a free one unless given. ``env``: variables for the process besides the
    caller's (whose MENTALSIM_* ones are left out)."""

    def __init__(
        self,
        binary: Path,
        out: Path,
        config: Config,
        *,
        port: int | None = None,
        env: Mapping[str, str] | None = None,
    ) -> None:
        self.binary = binary
        self.out = out
        self.config = config
        self.port = free_port() if port is None else port
        self.url = f"http://127.0.0.1:{self.port}"
        self.data_dir = out / "data"
        self.config_path = out / "mentalsim.toml"
        self.log_path = out / "mentalsim.log"
        self.env = dict(env or {})
        self.proc: subprocess.Popen[bytes] | None = None
        #: How many times it was started (a suite may restart it after a crash).
        self.starts = 0
        out.mkdir(parents=True, exist_ok=True)
        if self.data_dir.exists():
            shutil.rmtree(self.data_dir)
        self.data_dir.mkdir()
        self.config_path.write_text(config.toml(self.port, self.data_dir))

    def start(self, timeout_s: float = 120) -> None:
        """Starts the process and waits until ``/readyz`` answers 200. Raises ServiceError if it
        exits first, or is not ready within ``timeout_s`` (then it is stopped first)."""
        self.starts += 1
        # Our own configuration only: a MENTALSIM_* variable of the caller's shell (a store URL,
        # a database URL) would change what is tested, and one that is no configuration key
        # (MENTALSIM_BIN) would stop `serve`.
        env = {k: v for k, v in os.environ.items() if not k.startswith("MENTALSIM_")}
        env["RUST_BACKTRACE"] = "1"
        env.update(self.env)
        with open(self.log_path, "ab") as log:
            log.write(f"\n===== start {self.starts} =====\n".encode())
            log.flush()
            proc = subprocess.Popen(
                [str(self.binary), "serve", "--config", str(self.config_path)],
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                env=env,
                cwd=self.out,
            )
        self.proc = proc
        deadline = time.monotonic() + timeout_s
        last = "no answer"
        while True:
            if proc.poll() is not None:
                raise ServiceError(
                    f"mentalsim serve exited with {proc.returncode}{signal_name(proc.returncode)} "
                    f"while starting:\n{self.log_tail(30)}"
                )
            status, body = self.get("/readyz", timeout=2)
            if status == 200:
                return
            if status is not None:
                last = f"{status} {body[:300]}"
            if time.monotonic() > deadline:
                tail = self.log_tail(30)
                self.stop()
                raise ServiceError(
                    f"mentalsim serve was not ready within {timeout_s:.0f} s (/readyz: {last}):\n{tail}"
                )
            time.sleep(0.2)

    def get(self, path: str, timeout: float = 10) -> tuple[int | None, str]:
        """GET ``path`` without a token: the status and body, or (None, "") with no answer."""
        try:
            conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=timeout)
            try:
                conn.request("GET", path)
                response = conn.getresponse()
                return response.status, response.read().decode("utf-8", "replace")
            finally:
                conn.close()
        except (OSError, http.client.HTTPException):
            return None, ""

    def alive(self) -> bool:
        """Whether the process is running."""
        return self.proc is not None and self.proc.poll() is None

    def healthy(self, timeout: float = 10) -> bool:
        """Whether ``/healthz`` answers 200 within ``timeout`` seconds."""
        return self.get("/healthz", timeout)[0] == 200

    def log_size(self) -> int:
        """The log's size in bytes: an offset for :meth:`log_since`."""
        return self.log_path.stat().st_size if self.log_path.exists() else 0

    def log_since(self, offset: int) -> str:
        """What the log gained after ``offset`` (from :meth:`log_size`), without colours."""
        with open(self.log_path, "rb") as f:
            f.seek(offset)
            return strip_ansi(f.read().decode("utf-8", "replace"))

    def log_text(self) -> str:
        """The whole log (every start), without colours."""
        if not self.log_path.exists():
            return ""
        return strip_ansi(self.log_path.read_text(errors="replace"))

    def log_tail(self, lines: int = 20) -> str:
        """The log's last ``lines`` lines, without colours."""
        return "\n".join(self.log_text().splitlines()[-lines:])

    def panics(self) -> dict[str, int]:
        """Every panic in the log, including those the service survived (caught by a task or a
        layer): where (what follows ``panicked at``; in another line that says ``panicked``,
        the line from there on) and how many times."""
        seen: dict[str, int] = {}
        for line in self.log_text().splitlines():
            if "panicked" in line:
                m = re.search(r"panicked at (.*)", line)
                where = m.group(1) if m else line[line.index("panicked") :]
                seen[where] = seen.get(where, 0) + 1
        return seen

    def stop(self, timeout_s: float = 30) -> Exit:
        """SIGTERM; if it has not exited ``timeout_s`` seconds later (its shutdown grace period
        plus some slack), SIGKILL. How it ended, and the panics in its log."""
        proc = self.proc
        if proc is None or proc.poll() is not None:
            code = None if proc is None else proc.returncode
            return Exit(code, False, False, 0.0, self.panics())
        started = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        killed = False
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
            killed = True
        return Exit(proc.returncode, True, killed, time.monotonic() - started, self.panics())
