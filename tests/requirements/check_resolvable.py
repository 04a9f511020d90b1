#!/usr/bin/env python3
"""Every requirements set in requirements/ resolves: pip can pick one version of each package.

For each requirements/*.txt (or the files given), an EMPTY virtual environment is created in a
temporary directory and pip resolves the file there from the index's metadata without
installing anything:

    pip install --dry-run --quiet --ignore-installed --report REPORT.json -r FILE

A set that pins one package twice with different versions (bench.txt's numpy 2.3.5 against
test.txt's 2.4.6, which broke `scripts/bench` on fresh machines), or pins versions whose
dependencies conflict, fails here with pip's own error, naming the file.

The index must be reachable (PIP_INDEX_URL or pip's configured index-url, else PyPI). Without
it the check says so and exits 0, except under CI=true or MENTALSIM_REQUIRE_ALL=1, where a
missing network is a failure, never a skip.

Usage: python3 tests/requirements/check_resolvable.py [requirements/FILE.txt ...]
"""

import json
import os
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
# --dry-run arrived in pip 22.2 and --report in 22.2 (stable since 23.0); 23.2 has both.
MIN_PIP = (23, 2)


def strict():
    return os.environ.get("CI") == "true" or os.environ.get("MENTALSIM_REQUIRE_ALL") == "1"


def fail(message):
    print(f"check_resolvable: FAILED: {message}", file=sys.stderr)
    sys.exit(1)


def index_url(python):
    """The index pip will ask: PIP_INDEX_URL, else pip's configuration, else PyPI."""
    url = os.environ.get("PIP_INDEX_URL")
    if url:
        return url
    out = subprocess.run(
        [python, "-m", "pip", "config", "list"], capture_output=True, text=True, check=False
    ).stdout
    for line in out.splitlines():
        key, _, value = line.partition("=")
        if key.strip().endswith(".index-url"):
            return value.strip().strip("'\"")
    return "https://pypi.org/simple/"


def index_reachable(url):
    """None when the index answers, else why not."""
    try:
        with urllib.request.urlopen(url.rstrip("/") + "/pip/", timeout=20) as answer:
            answer.read(1)
        return None
    except (urllib.error.URLError, OSError) as e:
        return f"{url} unreachable ({e})"


def pip_version(python):
    out = subprocess.run(
        [python, "-m", "pip", "--version"], capture_output=True, text=True, check=True
    ).stdout
    return tuple(int(p) for p in out.split()[1].split(".")[:2])


def empty_venv(directory):
    """A fresh virtual environment in `directory`; returns its python."""
    subprocess.run([sys.executable, "-m", "venv", str(directory)], check=True)
    python = str(directory / "bin" / "python")
    if pip_version(python) < MIN_PIP:
        subprocess.run(
            [python, "-m", "pip", "install", "--quiet", "--disable-pip-version-check",
             f"pip>={MIN_PIP[0]}.{MIN_PIP[1]}"],
            check=True,
        )
    return python


def resolve(requirements, tmp):
    """Resolves one file in its own empty venv: (file, {package: version} or pip's error, seconds)."""
    started = time.monotonic()
    venv = tmp / f"venv-{requirements.stem}"
    python = empty_venv(venv)
    report = tmp / f"report-{requirements.stem}.json"
    cmd = [
        python, "-m", "pip", "install", "--dry-run", "--quiet", "--ignore-installed",
        "--disable-pip-version-check", "--report", str(report), "-r", str(requirements),
    ]
    # -r paths inside the file (test.txt's `-r serve.txt`) are relative to the file itself.
    done = subprocess.run(cmd, capture_output=True, text=True, check=False, cwd=ROOT)
    rel = requirements.relative_to(ROOT) if requirements.is_relative_to(ROOT) else requirements
    seconds = time.monotonic() - started
    if done.returncode != 0:
        return rel, (
            f"{rel} does not resolve (pip exited {done.returncode}):\n"
            f"{(done.stdout + done.stderr).strip()}"
        ), seconds
    install = json.loads(report.read_text())["install"]
    packages = {i["metadata"]["name"].lower(): i["metadata"]["version"] for i in install}
    return rel, packages, seconds


def main(argv):
    files = [Path(a).resolve() for a in argv] or sorted((ROOT / "requirements").glob("*.txt"))
    if not files:
        fail("no requirements/*.txt found")
    for f in files:
        if not f.is_file():
            fail(f"{f} is not a file")
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="mentalsim-requirements-") as tmp:
        tmp = Path(tmp)
        # The index pip will use, as an empty venv's pip sees it (pip's configuration files,
        # PIP_INDEX_URL), probed once so that "no network" is told apart from "does not resolve".
        probe = empty_venv(tmp / "venv-probe")
        why = index_reachable(index_url(probe))
        if why is not None:
            if strict():
                fail(f"cannot check that requirements resolve: {why} (CI: no skipping)")
            print(f"check_resolvable: SKIPPED: {why}", file=sys.stderr)
            return 0
        # The sets resolve side by side (pip mostly waits on the index).
        with ThreadPoolExecutor(max_workers=len(files)) as pool:
            results = list(pool.map(lambda f: resolve(f, tmp), files))
    errors = []
    for rel, packages, seconds in results:
        if isinstance(packages, str):
            errors.append(packages)
            continue
        pins = ", ".join(f"{n} {packages[n]}" for n in ("torch", "numpy") if n in packages)
        print(f"{rel}: {len(packages)} packages resolve ({pins}) in {seconds:.1f} s")
    if errors:
        fail("\n\n".join(errors))
    print(f"every requirements set resolves ({time.monotonic() - started:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
