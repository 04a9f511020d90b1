#!/usr/bin/env python3
"""Attacks and faults from issue 16, tried on release binaries side by side; prints a Markdown
table: probe | binary | status | wall time | server CPU | peak RSS.

    python tests/fuzz/probe_bounds.py --bin before=/path/to/old --bin after=target/release/mentalsim

Each probe starts a fresh `mentalsim serve` (fresh data directory, an engineer and a robot
token) so that the kernel's peak-RSS figure (VmHWM) belongs to that probe alone. Linux only.
"""

from __future__ import annotations

import argparse
import concurrent.futures as futures
import os
import signal
import socket
import subprocess
import tempfile
import time
import zlib
import struct
from pathlib import Path

import httpx

ENGINEER = "probe-engineer-token-0001"
ROBOT = "probe-robot-token-00000001"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def png(width: int, height: int) -> bytes:
    """A grey PNG of width x height whose pixels are all 254 (free), compressed hard."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    row = b"\x00" + b"\xfe" * width
    comp = zlib.compressobj(9)
    parts = [comp.compress(row) for _ in range(height)]
    parts.append(comp.flush())
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", b"".join(parts)) + chunk(b"IEND", b"")


class Server:
    def __init__(self, binary: str):
        self.dir = tempfile.TemporaryDirectory(prefix="probe-")
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        config = Path(self.dir.name) / "config.toml"
        config.write_text(
            f'[[tokens]]\ntoken = "{ENGINEER}"\nname = "alice"\nrole = "engineer"\n'
            f'[[tokens]]\ntoken = "{ROBOT}"\nname = "robot-1"\nrole = "robot"\n'
        )
        env = {k: v for k, v in os.environ.items() if not k.startswith("MENTALSIM_")}
        env["MENTALSIM_WORKER_CONCURRENCY"] = "0"
        self.proc = subprocess.Popen(
            [binary, "serve", "--config", str(config), "--bind", f"127.0.0.1:{self.port}",
             "--data-dir", str(Path(self.dir.name) / "data")],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            try:
                if httpx.get(self.url + "/healthz", timeout=1).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            time.sleep(0.2)
        else:
            raise SystemExit(f"{binary} did not start")
        self.cpu0 = self.cpu()

    def status(self, key: str) -> int:
        for line in Path(f"/proc/{self.proc.pid}/status").read_text().splitlines():
            if line.startswith(key + ":"):
                return int(line.split()[1])
        return 0

    def cpu(self) -> float:
        fields = Path(f"/proc/{self.proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def stop(self, grace: float = 20.0) -> str:
        self.proc.send_signal(signal.SIGTERM)
        started = time.monotonic()
        try:
            self.proc.wait(timeout=grace)
            exit_note = f"exited {time.monotonic() - started:.1f} s after SIGTERM"
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            exit_note = f"still running {grace:.0f} s after SIGTERM (killed)"
        self.dir.cleanup()
        return exit_note


def auth(token: str) -> dict:
    return {"Authorization": f"Bearer {token}"}


def probe_uploads(s: Server, method: str = "POST", path: str = "/v1/maps",
                  content_type: str = "multipart/form-data; boundary=x") -> str:
    body = b"x" * (60 * 1024 * 1024)

    def one(_):
        try:
            return httpx.request(method, s.url + path, content=body, timeout=120,
                                 headers={"Content-Type": content_type}).status_code
        except httpx.HTTPError as e:
            return type(e).__name__

    with futures.ThreadPoolExecutor(8) as pool:
        codes = list(pool.map(one, range(8)))
    return "statuses " + ",".join(sorted({str(c) for c in codes}))


def probe_cross_product(s: Server) -> str:
    q = "SELECT * WHERE { GRAPH ?g { ?a ?b ?c } GRAPH ?h { ?d ?e ?f } GRAPH ?i { ?x ?y ?z } }"
    try:
        r = httpx.post(s.url + "/sparql", content=q, timeout=120,
                       headers={**auth(ROBOT), "Content-Type": "application/sparql-query",
                                "Accept": "application/sparql-results+json"})
        return f"{r.status_code} ({len(r.content)} bytes)"
    except httpx.HTTPError as e:
        return type(e).__name__


def probe_bomb(s: Server, bomb: bytes) -> str:
    yaml = b"image: bomb.png\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    try:
        r = httpx.post(s.url + "/v1/maps", headers=auth(ENGINEER), timeout=300,
                       files={"yaml": ("bomb.yaml", yaml), "image": ("bomb.png", bomb)},
                       data={"name": "bomb"})
        return f"{r.status_code}"
    except httpx.HTTPError as e:
        return type(e).__name__


def probe_resolution(s: Server) -> str:
    yaml = b"image: m.png\nresolution: 1.0e306\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    r = httpx.post(s.url + "/v1/maps", headers=auth(ENGINEER), timeout=60,
                   files={"yaml": ("m.yaml", yaml), "image": ("m.png", png(40, 40))},
                   data={"name": "huge"})
    return f"{r.status_code}"


def probe_cycle(s: Server) -> str:
    update = """PREFIX tosm: <https://mentalsim.dev/ontology/tosm#>
        DELETE { GRAPH ?g { ?a tosm:isDirectlyInsideOf ?f . ?b tosm:isDirectlyInsideOf ?f } }
        INSERT { GRAPH ?g { ?a tosm:isDirectlyInsideOf ?b . ?b tosm:isDirectlyInsideOf ?a } }
        WHERE { GRAPH ?g { ?a tosm:identifier "F0-office" ; tosm:isDirectlyInsideOf ?f .
                           ?b tosm:identifier "F0-storage" ; tosm:isDirectlyInsideOf ?f } }"""
    httpx.post(s.url + "/sparql", content=update, timeout=60,
               headers={**auth(ENGINEER), "Content-Type": "application/sparql-update"})
    try:
        r = httpx.get(s.url + "/v1/places/F0-office/world.sdf", headers=auth(ROBOT), timeout=10)
        return f"{r.status_code}"
    except httpx.HTTPError as e:
        return f"no answer in 10 s ({type(e).__name__})"


def probe_methods(s: Server) -> str:
    before = len(httpx.get(s.url + "/metrics").text.splitlines())
    for i in range(300):
        try:
            httpx.request(f"BREW{i}", s.url + "/v1/robots", timeout=10)
        except httpx.HTTPError:
            pass
    after = len(httpx.get(s.url + "/metrics").text.splitlines())
    return f"+{after - before} /metrics lines"


def probe_readyz(s: Server) -> str:
    with futures.ThreadPoolExecutor(30) as pool:
        codes = list(pool.map(lambda _: httpx.get(s.url + "/readyz", timeout=30).status_code, range(30)))
    return f"{codes.count(503)} of 30 answered 503"


def probe_nesting(s: Server) -> str:
    q = "SELECT * WHERE " + "{" * 1000 + "}" * 1000
    try:
        r = httpx.post(s.url + "/sparql", content=q, timeout=30,
                       headers={**auth(ROBOT), "Content-Type": "application/sparql-query"})
        status = str(r.status_code)
    except httpx.HTTPError as e:
        status = type(e).__name__
    alive = s.proc.poll() is None
    return f"{status}; process {'alive' if alive else 'DEAD (exit ' + str(s.proc.returncode) + ')'}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bin", action="append", required=True, help="label=path, repeatable")
    parser.add_argument("--only", action="append", help="run only these probes")
    args = parser.parse_args()
    binaries = [b.split("=", 1) for b in args.bin]
    bomb_path = Path(tempfile.gettempdir()) / "probe-bomb-23000.png"
    if not bomb_path.exists():
        bomb_path.write_bytes(png(23000, 23000))
    bomb = bomb_path.read_bytes()
    probes = {
        "8 concurrent 60 MB map uploads, no token": probe_uploads,
        "8 concurrent 60 MB Graph Store PUTs, no token":
            lambda s: probe_uploads(s, "PUT", "/store?graph=urn:x:g", "text/turtle"),
        "8 concurrent 60 MB SPARQL POSTs, no token":
            lambda s: probe_uploads(s, "POST", "/sparql", "application/sparql-query"),
        "robot's cross-product SELECT": probe_cross_product,
        f"{len(bomb) // 1024} kB PNG declaring 23,000 x 23,000 px as a map": lambda s: probe_bomb(s, bomb),
        "map YAML with resolution 1.0e306": probe_resolution,
        "two rooms inside each other, then world.sdf": probe_cycle,
        "300 requests with invented methods": probe_methods,
        "30 concurrent /readyz": probe_readyz,
        "SPARQL with 1000 nested groups": probe_nesting,
    }
    print("| probe | binary | outcome | wall | server CPU | RSS before → peak | after SIGTERM |")
    print("|---|---|---|---|---|---|---|")
    for name, probe in probes.items():
        if args.only and not any(o in name for o in args.only):
            continue
        for label, binary in binaries:
            s = Server(binary)
            rss0 = s.status("VmRSS")
            started = time.monotonic()
            try:
                outcome = probe(s)
            except Exception as e:  # noqa: BLE001 - a probe that breaks is a finding too
                outcome = f"probe failed: {e!r}"
            wall = time.monotonic() - started
            cpu = s.cpu() - s.cpu0 if s.proc.poll() is None else float("nan")
            peak = s.status("VmHWM") if s.proc.poll() is None else 0
            exit_note = s.stop()
            print(f"| {name} | {label} | {outcome} | {wall:.1f} s | {cpu:.1f} s | "
                  f"{rss0 // 1024} → {peak // 1024} MB | {exit_note} |", flush=True)


if __name__ == "__main__":
    main()
