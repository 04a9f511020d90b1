"""The numpy forward pass against Rust's own, bit for bit: the same observations through
``learning::Policy`` in the binary (``mentalsim policy act``) and through ``mentalsim_client``,
for the policy the live service trained and for hand-built ones (residual and not, both input
layouts).

``mentalsim policy act --policy DIR`` reads JSON lines from standard input, each an observation
``{"ranges": [...], "goal_distance": d, "goal_angle": a, "velocity": [v, w]}`` or an input row
``{"input": [...]}``, and writes one JSON line per line read:
``{"input": [...], "output": [linear, angular], "action": {"linear": v, "angular": w}}``
(``Scaling::encode``, ``Policy::forward``, ``Scaling::command``; float32 values printed as the
shortest decimal that reads back to the same float32).
"""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import Training
from test_01_policy_local import FOLLOWER, RPP, goal_seeking, metadata, random_observations, scaling_json, write_policy

from mentalsim_client import Client, Observation, Policy, load_policy


@pytest.fixture(scope="module")
def policy_act(binary: Path) -> list[str]:
    command = [str(binary), "policy", "act"]
    probe = subprocess.run([*command, "--help"], capture_output=True, text=True, timeout=60)
    # The binary these tests start has the command: its absence is a failure, never a skip.
    said = (probe.stderr.strip().splitlines() or [""])[0]
    assert probe.returncode == 0, f"{binary} has no `policy act` command ({said})"
    return command


def rust(command: list[str], directory: Path, lines: list[dict[str, Any]]) -> list[dict[str, Any]]:
    run = subprocess.run(
        [*command, "--policy", str(directory)],
        input="".join(json.dumps(line) + "\n" for line in lines),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    out = [json.loads(line) for line in run.stdout.splitlines() if line.strip()]
    assert len(out) == len(lines)
    return out


def f32(values: list[float]) -> np.ndarray[Any, Any]:
    return np.array([np.float32(v) for v in values], dtype=np.float32)


def edge_observations(beams: int) -> list[Observation]:
    return [
        Observation([0.0] * beams, 0.0, 0.0),
        Observation([100.0] * beams, 1000.0, math.pi, (2.0, -3.0)),
        Observation([0.01 * (i + 1) for i in range(beams)], 0.3, -math.pi, (-0.5, 0.5)),
        Observation([5.0] * beams, 0.05, 0.35, (0.8, 0.0)),
        Observation([5.0] * beams, 0.05, -0.3499, (0.1, 0.2)),
        Observation([2.5] * beams, 3.0, 1.75, (0.0, 0.5)),
    ]


def compare(command: list[str], policy_dir: Path) -> None:
    policy: Policy = load_policy(policy_dir)
    beams = policy.scaling.beams
    if beams == 23:
        observations = random_observations(400, 11)
    else:
        rng = np.random.default_rng(3)
        observations = [
            Observation([float(r) for r in rng.uniform(0, 6, beams)], float(rng.uniform(0, 12)), float(rng.uniform(-3.2, 3.2)), (0.3, -0.1))
            for _ in range(400)
        ]
    observations += edge_observations(beams)
    lines: list[dict[str, Any]] = [
        {"ranges": [float(np.float32(r)) for r in o.ranges], "goal_distance": float(np.float32(o.goal_distance)), "goal_angle": float(np.float32(o.goal_angle)), "velocity": [float(np.float32(v)) for v in o.velocity]}
        for o in observations
    ]
    # Raw input rows too: values an observation cannot produce.
    rng = np.random.default_rng(5)
    rows = rng.uniform(-1.5, 2.5, (100, policy.input_len)).astype(np.float32)
    lines += [{"input": [float(v) for v in row]} for row in rows]
    answers = rust(command, policy_dir, lines)
    mismatches = []
    for line, answer in zip(lines, answers):
        if "input" in line:
            x = f32(line["input"])
        else:
            obs = Observation(line["ranges"], line["goal_distance"], line["goal_angle"], tuple(line["velocity"]))
            x = policy.encode(obs)
            if not np.array_equal(x.view(np.uint32), f32(answer["input"]).view(np.uint32)):
                mismatches.append(f"input of {line}: numpy {x.tolist()} rust {answer['input']}")
                continue
        y = policy.forward(x)
        if not np.array_equal(y.view(np.uint32), f32(answer["output"]).view(np.uint32)):
            mismatches.append(f"output for {x.tolist()}: numpy {y.tolist()} rust {answer['output']}")
            continue
        act = policy.scaling.command(y)
        if (act.linear, act.angular) != (answer["action"]["linear"], answer["action"]["angular"]):
            mismatches.append(f"action for {x.tolist()}: numpy {act} rust {answer['action']}")
    assert not mismatches, f"{len(mismatches)} of {len(lines)} differ:\n" + "\n".join(mismatches[:10])


def test_the_trained_policy_computes_what_rust_computes(policy_act: list[str], robot: Client, training: Training, tmp_path: Path) -> None:
    assert training.job.result is not None
    compare(policy_act, robot.download_policy(training.job.result["policy_id"], tmp_path / "trained"))


@pytest.mark.parametrize("base", ["follower", "rpp"])
@pytest.mark.parametrize("layout", ["extended", "paper"])
def test_a_random_residual_policy_computes_what_rust_computes(policy_act: list[str], tmp_path: Path, layout: str, base: str) -> None:
    rng = np.random.default_rng(len(layout))
    widths = [scaling_json(23, layout)["beams"] + (5 if layout == "extended" else 2), 64, 13, 2]
    layers = [(rng.standard_normal((o, i)) / math.sqrt(i), rng.standard_normal(o) * 0.2) for i, o in zip(widths, widths[1:])]
    residual = FOLLOWER if base == "follower" else RPP
    compare(policy_act, write_policy(tmp_path / f"{layout}-{base}", metadata(scaling_json(23, layout), [64, 13], residual), layers))


def test_the_goal_seeking_policy_computes_what_rust_computes(policy_act: list[str], tmp_path: Path) -> None:
    goal_seeking(tmp_path / "seek", 5)
    compare(policy_act, tmp_path / "seek")
