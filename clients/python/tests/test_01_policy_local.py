"""Local inference of exported policies (no service needed): hand-built safetensors policies
against values computed by hand, the Rust runtime's own test cases (services/learning/src/
policy.rs and observation.rs) replayed, and the float32 arithmetic checked operation by operation
against the C library (fused multiply-add) and a scalar transcription of Rust's dot product."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from safetensors.numpy import save

from mentalsim_client import Action, Observation, Policy, PolicyError, Residual, RppResidual, Scaling, load_policy, residual_from_json
from mentalsim_client import _libm
from mentalsim_client.policy import _Dense

FOLLOWER = {"linear_max": 0.8, "angular_max": 0.5, "rotate_threshold": 0.35, "heading_gain": 2.0, "linear_min": 0.1, "slow_down_m": 0.8}
#: ``learning::Residual::rpp(&sim::RppParams::default())``: Nav2's defaults for the paper's robot.
RPP = {
    "desired_linear_vel": 0.8,
    "angular_max": 0.5,
    "lookahead_dist": 0.9,
    "rotate_to_heading_angular_vel": 0.5,
    "rotate_to_heading_min_angle": 0.785,
    "regulated_linear_scaling_min_radius": 0.9,
    "regulated_linear_scaling_min_speed": 0.25,
    "approach_velocity_scaling_dist": 0.6,
    "min_approach_linear_velocity": 0.05,
}


def scaling_json(beams: int = 23, layout: str = "extended") -> dict[str, Any]:
    return {
        "beams": beams,
        "range_horizon_m": 5.0,
        "goal_distance_scale_m": 10.0,
        "goal_distance_clip": 2.0,
        "linear_max": 0.8,
        "angular_max": 0.5,
        "layout": layout,
    }


def metadata(scaling: dict[str, Any], hidden: list[int], residual: dict[str, float] | None = None) -> dict[str, Any]:
    """What ``PolicyMetadata::new`` writes."""
    layout = [f"range[{i}] / range_horizon_m (rightmost beam first)" for i in range(scaling["beams"])]
    meta: dict[str, Any] = {
        "format": "mentalsim-td3-actor",
        "version": 1,
        "scaling": scaling,
        "observation_layout": layout,
        "hidden": hidden,
        "output_activations": ["sigmoid", "tanh"],
        "training": {},
    }
    if residual is not None:
        meta["residual"] = residual
    return meta


def write_policy(directory: Path, meta: dict[str, Any], layers: list[tuple[np.ndarray[Any, Any], np.ndarray[Any, Any]]]) -> Path:
    """A policy directory as ``learning::write_policy`` writes it."""
    directory.mkdir(parents=True, exist_ok=True)
    tensors = {}
    for i, (w, b) in enumerate(layers):
        tensors[f"layers.{i}.weight"] = np.ascontiguousarray(w, dtype=np.float32)
        tensors[f"layers.{i}.bias"] = np.ascontiguousarray(b, dtype=np.float32)
    (directory / "policy.safetensors").write_bytes(save(tensors))
    (directory / "policy.json").write_text(json.dumps(meta, indent=2))
    return directory


def sigmoid(x: float) -> float:
    return 1.0 / (1.0 + math.exp(-x))


# --------------------------------------------------------------------------------------------
# The arithmetic


def rust_dot(row: list[float], x: list[float]) -> np.float32:
    """services/learning/src/policy.rs `dot`, transcribed line by line in float32 scalars."""
    f = np.float32
    acc = [f(0.0)] * 8
    chunks = len(row) // 8
    for k in range(chunks):
        for i in range(8):
            acc[i] = f(acc[i] + f(f(row[8 * k + i]) * f(x[8 * k + i])))
    s = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]))
    for j in range(8 * chunks, len(row)):
        s = f(s + f(f(row[j]) * f(x[j])))
    return f(s)


@pytest.mark.parametrize("inputs", [3, 8, 13, 28, 64])
def test_a_dense_layer_sums_in_rusts_order(inputs: int) -> None:
    rng = np.random.default_rng(inputs)
    w = rng.standard_normal((5, inputs)).astype(np.float32)
    b = rng.standard_normal(5).astype(np.float32)
    x = rng.standard_normal((4, inputs)).astype(np.float32)
    got = _Dense(w, b).forward(x)
    for n in range(4):
        for o in range(5):
            want = np.float32(rust_dot([float(v) for v in w[o]], [float(v) for v in x[n]]) + b[o])
            assert got[n, o].view(np.uint32) == want.view(np.uint32), (n, o, got[n, o], want)


# --------------------------------------------------------------------------------------------
# Hand-built policies, hand-computed values


def test_the_rust_runtimes_tiny_policy_computes_by_hand(tmp_path: Path) -> None:
    """policy.rs `a_written_policy_loads_and_computes_by_hand`: 4 inputs -> 3 hidden -> 2."""
    w0 = np.array([(i - 6.0) / 10.0 for i in range(12)], dtype=np.float32).reshape(3, 4)
    b0 = np.array([0.1, -0.2, 0.3], dtype=np.float32)
    w1 = np.array([0.5, -0.5, 1.0, -1.0, 0.25, 0.75], dtype=np.float32).reshape(2, 3)
    b1 = np.array([0.0, 0.1], dtype=np.float32)
    d = write_policy(tmp_path / "tiny", metadata(scaling_json(2, "paper"), [3]), [(w0, b0), (w1, b1)])
    p = load_policy(d)
    assert p.input_len == 4 and p.hidden == (3,) and p.residual is None
    x = [0.5, 1.0, 0.2, -0.5]
    h = [max(0.0, sum(float(w0[r, c]) * x[c] for c in range(4)) + float(b0[r])) for r in range(3)]
    o0 = 0.5 * h[0] - 0.5 * h[1] + 1.0 * h[2]
    o1 = -h[0] + 0.25 * h[1] + 0.75 * h[2] + 0.1
    y = p.forward(x)
    assert y.dtype == np.float32 and y.shape == (2,)
    assert abs(y[0] - sigmoid(o0)) < 1e-6
    assert abs(y[1] - math.tanh(o1)) < 1e-6
    with pytest.raises(PolicyError):
        p.forward(x[:3])


def goal_seeking(directory: Path, beams: int) -> Policy:
    """``learning::write_goal_seeking_policy``: hidden units relu(a), relu(-a), 1 for the goal
    bearing a = θ/π; linear speed sigmoid(3 − 60 |a|), angular speed tanh(20 a)."""
    inputs = beams + 2
    w0 = np.zeros((3, inputs), dtype=np.float32)
    w0[0, inputs - 1] = 1.0
    w0[1, inputs - 1] = -1.0
    b0 = np.array([0.0, 0.0, 1.0], dtype=np.float32)
    w1 = np.array([[-60.0, -60.0, 3.0], [20.0, -20.0, 0.0]], dtype=np.float32)
    b1 = np.zeros(2, dtype=np.float32)
    return load_policy(write_policy(directory, metadata(scaling_json(beams, "paper"), [3]), [(w0, b0), (w1, b1)]))


@pytest.mark.parametrize("angle", [0.0, 0.02, -0.05, 0.3, -1.0, 3.0, -3.14159])
def test_the_goal_seeking_policy_turns_to_the_goal_and_drives(tmp_path: Path, angle: float) -> None:
    p = goal_seeking(tmp_path / "seek", 23)
    obs = Observation([2.0] * 23, 4.0, angle)
    x = p.encode(obs)
    a = float(np.float32(angle) / np.float32(math.pi))
    assert x[-1] == np.float32(a) and x[-2] == np.float32(0.4)
    y = p.forward(x)
    assert abs(float(y[0]) - sigmoid(3 - 60 * abs(a))) < 1e-6
    assert abs(float(y[1]) - math.tanh(20 * a)) < 1e-6
    act = p.act(obs)
    assert abs(act.linear - 0.8 * sigmoid(3 - 60 * abs(a))) < 1e-6
    assert abs(act.angular - 0.5 * math.tanh(20 * a)) < 1e-6


def silent_residual(directory: Path, layout: str, base: dict[str, float] = FOLLOWER) -> Policy:
    """A residual policy whose network outputs zero: it drives as its base (the follower)."""
    n = 23 + (5 if layout == "extended" else 2)
    meta = metadata(scaling_json(23, layout), [4], base)
    layers = [(np.zeros((4, n)), np.zeros(4)), (np.zeros((2, 4)), np.zeros(2))]
    return load_policy(write_policy(directory, meta, layers))


@pytest.mark.parametrize("layout", ["extended", "paper"])
def test_a_residual_policy_with_a_silent_network_is_the_follower(tmp_path: Path, layout: str) -> None:
    """policy.rs `a_residual_policy_with_a_silent_network_is_the_follower`, and the follower's
    law worked out by hand (sim/src/follower.rs): outputs are (linear / 0.8, angular / 0.5)."""
    p = silent_residual(tmp_path / layout, layout)
    assert p.residual == Residual(**FOLLOWER)
    # (distance, bearing) -> the follower's command in output units, by hand:
    cases = {
        # Goal ahead and far: full speed, no turn.
        (5.0, 0.0): (1.0, 0.0),
        # Goal left beyond the 0.35 rad threshold: turn on the spot at the angular limit.
        (3.0, 1.5): (0.0, 1.0),
        # Goal behind, right: turn right on the spot.
        (3.0, -2.5): (0.0, -1.0),
        # 0.5 m away at 0.2 rad: share 1 - 0.2/0.35 = 3/7, approach 0.5/0.8, speed
        # (0.1 + 0.7 * 3/7) * 0.625 = 0.25 m/s; turn rate 2 * 0.2 = 0.4 rad/s.
        (0.5, 0.2): (0.25 / 0.8, 0.4 / 0.5),
        # 1 m away at 0.3 rad: speed 0.1 + 0.7 * (1 - 0.3/0.35) = 0.2 m/s; turn 0.5 (limit).
        (1.0, 0.3): (0.2 / 0.8, 1.0),
    }
    for (d, angle), (lin, ang) in cases.items():
        obs = Observation([5.0] * 23, d, angle)
        x = p.encode(obs)
        assert p.residual is not None
        base = p.residual.output(p.scaling, x)
        assert abs(float(base[0]) - lin) < 1e-5 and abs(float(base[1]) - ang) < 1e-5, (d, angle, base)
        y = p.forward(x)
        # The base is kept 0.02 inside the outputs' ranges so its pre-activation is finite.
        want = (min(max(lin, 0.02), 0.98), min(max(ang, -0.98), 0.98))
        assert abs(float(y[0]) - want[0]) < 1e-5 and abs(float(y[1]) - want[1]) < 1e-5, (d, angle, y, want)
        assert abs(float(y[0]) - lin) <= 0.021 and abs(float(y[1]) - ang) <= 0.021
    # observation.rs: goal ahead and far, the pre-activation's sigmoid is the margin's 0.98.
    pre = p.residual.preactivation(p.scaling, p.encode(Observation([5.0] * 23, 5.0, 0.0)))
    assert abs(sigmoid(float(pre[0])) - 0.98) < 1e-4 and abs(float(pre[1])) < 1e-6


@pytest.mark.parametrize("layout", ["extended", "paper"])
def test_a_silent_rpp_residual_policy_drives_arcs(tmp_path: Path, layout: str) -> None:
    """observation.rs `an_untrained_rpp_residual_policy_drives_arcs_where_the_follower_turns_on_the_spot`,
    Regulated Pure Pursuit's law worked out by hand (sim/src/rpp.rs)."""
    p = silent_residual(tmp_path / layout, layout, RPP)
    assert p.residual == RppResidual(**RPP)
    k = 2 * 0.9 * math.sin(0.5) / 0.81
    cases = {
        # Ahead, far: full speed.
        (5.0, 0.0): (1.0, 0.0),
        # 0.5 rad left: an arc through the carrot 0.9 m away, as fast as the angular limit allows.
        (5.0, 0.5): (0.5 / k / 0.8, 1.0),
        # Beyond 0.785 rad: on the spot.
        (3.0, -1.0): (0.0, -1.0),
        # 0.3 m ahead: the approach, 0.8 * 0.3 / 0.6 m/s.
        (0.3, 0.0): (0.5, 0.0),
    }
    for (d, angle), (lin, ang) in cases.items():
        base = p.residual.output(p.scaling, p.encode(Observation([5.0] * 23, d, angle)))
        assert abs(float(base[0]) - lin) < 1e-4 and abs(float(base[1]) - ang) < 1e-4, (d, angle, base)
    with pytest.raises(PolicyError, match="lookahead_dist"):
        residual_from_json({key: v for key, v in RPP.items() if key != "lookahead_dist"})
    with pytest.raises(PolicyError, match="unknown"):
        residual_from_json({**RPP, "linear_max": 0.8})


def test_inputs_are_bounded_whatever_the_sensor_says() -> None:
    """observation.rs `inputs_are_bounded_whatever_the_sensor_says`."""
    s = Scaling.from_json(scaling_json(3, "paper"))
    obs = Observation([math.inf, -1.0, 2.5], math.nan, 7.0, (math.nan, -9.0))
    assert s.encode(obs).tolist() == [1.0, 0.0, 0.5, 2.0, 1.0]
    e = Scaling.from_json(scaling_json(3, "extended")).encode(obs)
    assert e.dtype == np.float32 and len(e) == 8
    assert e[:4].tolist() == [1.0, 0.0, 0.5, 2.0]
    assert abs(e[4] - math.sin(7.0)) < 1e-6 and abs(e[5] - math.cos(7.0)) < 1e-6
    assert e[6:].tolist() == [0.0, -1.0]
    with pytest.raises(PolicyError):
        s.encode(Observation([1.0], 1.0, 0.0))


def test_files_without_a_layout_are_read_as_the_papers() -> None:
    old = {k: v for k, v in scaling_json().items() if k != "layout"}
    s = Scaling.from_json(old)
    assert s.layout == "paper" and s.input_len == 25
    assert Scaling.from_json(scaling_json()).input_len == 28


def test_commands_are_scaled_and_clamped() -> None:
    s = Scaling.from_json(scaling_json())
    a = s.command([1.0, -1.0])
    assert abs(a.linear - 0.8) < 1e-6 and abs(a.angular + 0.5) < 1e-6
    a = s.command([2.0, 0.5])
    assert abs(a.linear - 0.8) < 1e-6 and abs(a.angular - 0.25) < 1e-6
    assert [float(v) for v in s.output_of(a)] == [1.0, 0.5]
    assert [float(v) for v in s.output_of(Action(-1.0, 9.0))] == [0.0, 1.0]


def naive_forward(p: Policy, x: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
    """The forward pass in float64, the obvious way: the exact one must be within rounding."""
    a = x.astype(np.float64)
    layers = p._layers
    for i, layer in enumerate(layers):
        a = a @ layer.weight.astype(np.float64).T + layer.bias.astype(np.float64)
        if i < len(layers) - 1:
            a = np.maximum(a, 0.0)
    if p.residual is not None:
        base = np.array([[float(v) for v in p.residual.preactivation(p.scaling, row)] for row in x])
        a = a + base
    return np.stack([1.0 / (1.0 + np.exp(-a[:, 0])), np.tanh(a[:, 1])], axis=1)


def random_residual_policy(directory: Path, seed: int) -> Policy:
    rng = np.random.default_rng(seed)
    widths = [28, 32, 32, 2]
    layers = [(rng.standard_normal((o, i)) / math.sqrt(i), rng.standard_normal(o) * 0.1) for i, o in zip(widths, widths[1:])]
    return load_policy(write_policy(directory, metadata(scaling_json(), [32, 32], FOLLOWER), layers))


def random_observations(n: int, seed: int) -> list[Observation]:
    rng = np.random.default_rng(seed)
    return [
        Observation(
            [float(r) for r in rng.uniform(0.05, 7.0, 23)],
            float(rng.uniform(0.0, 25.0)),
            float(rng.uniform(-math.pi, math.pi)),
            (float(rng.uniform(-0.2, 0.9)), float(rng.uniform(-0.6, 0.6))),
        )
        for _ in range(n)
    ]


def test_the_exact_forward_pass_is_the_obvious_one_up_to_rounding(tmp_path: Path) -> None:
    p = random_residual_policy(tmp_path / "r", 5)
    x = np.stack([p.encode(o) for o in random_observations(300, 6)])
    y = p.forward(x)
    assert y.shape == (300, 2) and y.dtype == np.float32
    assert np.max(np.abs(y - naive_forward(p, x))) < 1e-5
    # One row at a time gives the same bits as the batch.
    for i in range(0, 300, 37):
        assert np.array_equal(p.forward(x[i]).view(np.uint32), y[i].view(np.uint32))


def test_broken_policy_files_are_errors(tmp_path: Path) -> None:
    d = write_policy(
        tmp_path / "ok",
        metadata(scaling_json(2, "paper"), [3]),
        [(np.zeros((3, 4)), np.zeros(3)), (np.zeros((2, 3)), np.zeros(2))],
    )
    meta = (d / "policy.json").read_bytes()
    weights = (d / "policy.safetensors").read_bytes()
    Policy.from_bytes(meta, weights)

    def broken(change: dict[str, Any]) -> bytes:
        m = json.loads(meta)
        m.update(change)
        return json.dumps(m).encode()

    with pytest.raises(PolicyError):
        Policy.from_bytes(b"{", weights)
    with pytest.raises(PolicyError):
        Policy.from_bytes(meta, weights[: len(weights) // 2])
    with pytest.raises(PolicyError, match="shape"):
        Policy.from_bytes(broken({"hidden": [4]}), weights)
    with pytest.raises(PolicyError, match="format"):
        Policy.from_bytes(broken({"format": "other"}), weights)
    with pytest.raises(PolicyError, match="activations"):
        Policy.from_bytes(broken({"output_activations": ["tanh", "tanh"]}), weights)
    with pytest.raises(PolicyError, match="unknown"):
        Policy.from_bytes(broken({"scaling": {**scaling_json(2, "paper"), "extra": 1}}), weights)
    with pytest.raises(PolicyError, match="positive"):
        Policy.from_bytes(broken({"hidden": [0]}), weights)
    extra = save(
        {
            "layers.0.weight": np.zeros((3, 4), dtype=np.float32),
            "layers.0.bias": np.zeros(3, dtype=np.float32),
            "layers.1.weight": np.zeros((2, 3), dtype=np.float32),
            "layers.1.bias": np.zeros(2, dtype=np.float32),
            "layers.2.bias": np.zeros(2, dtype=np.float32),
        }
    )
    with pytest.raises(PolicyError, match="another network"):
        Policy.from_bytes(meta, extra)
    doubles = save({"layers.0.weight": np.zeros((3, 4)), "layers.0.bias": np.zeros(3), "layers.1.weight": np.zeros((2, 3)), "layers.1.bias": np.zeros(2)})
    with pytest.raises(PolicyError, match="float32"):
        Policy.from_bytes(meta, doubles)
    with pytest.raises(PolicyError):
        load_policy(tmp_path / "nowhere")
