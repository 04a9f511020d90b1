"""Exported navigation policies, run locally with numpy: the forward pass of
``learning::Policy`` (services/learning/src/policy.rs), its observation scaling
(``learning::Scaling``, observation.rs) and its residual base, the classical follower or
Regulated Pure Pursuit (``learning::Residual`` over ``sim::follower::follow`` or
``sim::rpp_command``), operation for operation.

A policy directory holds ``policy.safetensors`` (``layers.{i}.weight`` ``[out, in]`` and
``layers.{i}.bias`` ``[out]``, float32, input layer first) and ``policy.json`` (the metadata:
scaling, hidden widths, output activations, the residual base). The network is
``input -> (linear, ReLU) x hidden -> linear``; with a residual base the base's command
for the same input, written as pre-activations, is added to the two raw outputs; then
``sigmoid`` (linear speed in [0, 1]) and ``tanh`` (angular speed in [-1, 1]).

The arithmetic is the Rust runtime's, in its order: each dot product accumulates products in
eight lanes over chunks of eight inputs (each product rounded to float32, then each sum), sums
the lanes pairwise, adds the remainder's products, then the bias, all in float32; the activations and the
follower's trigonometry call the C math library as Rust does (see ``_libm``). So for the same
input the outputs are the same float32 values as the service's.

What this module does not do is the rehearsal executor's part around the policy: turning on the
spot towards a waypoint far behind the robot, and the collision shield.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Literal

import numpy as np
import numpy.typing as npt
from safetensors.numpy import load as load_safetensors

from . import _libm
from ._libm import F32Array

#: Name of the weights file in a policy directory.
WEIGHTS_FILE: Final = "policy.safetensors"
#: Name of the metadata file in a policy directory.
METADATA_FILE: Final = "policy.json"
#: The metadata's ``format``.
FORMAT: Final = "mentalsim-td3-actor"
#: Outputs of the network: linear speed, angular speed.
ACTION_DIM: Final = 2

_F32_PI: Final = np.float32(math.pi)
_ZERO: Final = np.float32(0.0)
_ONE: Final = np.float32(1.0)
#: How far from 0 and 1 (linear) or ±1 (angular) the residual base is kept.
_RESIDUAL_MARGIN: Final = np.float32(0.02)
#: ``sim::follower::FollowerParams::default().lookahead_m``: the residual base keeps it.
_FOLLOWER_LOOKAHEAD_M: Final = 0.4


class PolicyError(ValueError):
    """A policy that cannot be loaded, or an input that does not fit it."""


def _clamp(v: np.float32, lo: np.float32, hi: np.float32) -> np.float32:
    """Rust's ``f32::clamp`` (NaN stays NaN)."""
    if v < lo:
        return lo
    if v > hi:
        return hi
    return v


def _clamp64(v: float, lo: float, hi: float) -> float:
    """Rust's ``f64::clamp``."""
    if v < lo:
        return lo
    if v > hi:
        return hi
    return v


def _f32(v: float) -> np.float32:
    return np.float32(v)


def _wrap_angle(angle: float) -> float:
    """``sim::kinematics::wrap_angle``: the angle in (-π, π]."""
    if -math.pi < angle <= math.pi:
        return angle
    r = math.fmod(angle + math.pi, math.tau)
    if r < 0.0:
        r += math.tau
    a = r - math.pi
    return a + math.tau if a <= -math.pi else a


@dataclass(frozen=True, slots=True)
class Observation:
    """What the policy sees (``sim::Observation``): laser ``ranges`` in metres from the
    rightmost beam to the leftmost, the goal's ``distance`` (metres) and bearing ``angle``
    (radians, counter-clockwise, robot frame), and the odometry ``velocity`` (linear m/s,
    angular rad/s)."""

    ranges: Sequence[float]
    goal_distance: float
    goal_angle: float
    velocity: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True, slots=True)
class Action:
    """A velocity command: linear (m/s, forward) and angular (rad/s, counter-clockwise)."""

    linear: float
    angular: float


@dataclass(frozen=True, slots=True)
class Scaling:
    """``learning::Scaling``: how an observation becomes the network's input and its output a
    command."""

    beams: int
    range_horizon_m: float
    goal_distance_scale_m: float
    goal_distance_clip: float
    linear_max: float
    angular_max: float
    layout: Literal["paper", "extended"] = "paper"

    @property
    def input_len(self) -> int:
        """Length of the network's input: the ranges, then 2 (paper) or 5 (extended) values."""
        return self.beams + (2 if self.layout == "paper" else 5)

    @classmethod
    def from_json(cls, d: object) -> Scaling:
        if not isinstance(d, dict):
            raise PolicyError("policy metadata: `scaling` is not an object")
        known = {"beams", "range_horizon_m", "goal_distance_scale_m", "goal_distance_clip", "linear_max", "angular_max", "layout"}
        unknown = sorted(set(d) - known)
        if unknown:
            raise PolicyError(f"policy metadata: unknown field(s) {unknown} in `scaling`")
        try:
            beams = d["beams"]
            if isinstance(beams, bool) or not isinstance(beams, int) or beams < 0:
                raise PolicyError(f"policy metadata: `scaling.beams` is {beams!r}")
            floats = [float(_number(d[k], f"scaling.{k}")) for k in ("range_horizon_m", "goal_distance_scale_m", "goal_distance_clip", "linear_max", "angular_max")]
        except KeyError as e:
            raise PolicyError(f"policy metadata: missing field `scaling.{e.args[0]}`") from e
        layout = d.get("layout", "paper")
        if layout not in ("paper", "extended"):
            raise PolicyError(f"policy metadata: unknown input layout {layout!r}")
        # The Rust side holds these as f32: keep the values it computes with.
        f = [float(np.float32(v)) for v in floats]
        return cls(beams, f[0], f[1], f[2], f[3], f[4], layout)

    def encode(self, obs: Observation) -> F32Array:
        """The network input for one observation (``Scaling::encode``)."""
        if len(obs.ranges) != self.beams:
            raise PolicyError(f"{len(obs.ranges)} laser ranges for a policy trained on {self.beams}")
        out = np.zeros(self.input_len, dtype=np.float32)
        h = _f32(self.range_horizon_m)
        for i, r in enumerate(np.asarray(obs.ranges, dtype=np.float64).astype(np.float32)):
            rr = _clamp(r, _ZERO, h) if np.isfinite(r) else h
            out[i] = rr / h
        gd = _f32(obs.goal_distance)
        clip = _f32(self.goal_distance_clip)
        d = _clamp(gd / _f32(self.goal_distance_scale_m), _ZERO, clip) if np.isfinite(gd) else clip
        ga = _f32(obs.goal_angle)
        angle = ga if np.isfinite(ga) else _ZERO
        rest = self.beams
        out[rest] = d
        if self.layout == "paper":
            out[rest + 1] = _clamp(angle / _F32_PI, -_ONE, _ONE)
        else:

            def ratio(v: np.float32, mx: np.float32) -> np.float32:
                if np.isfinite(v) and mx > 0.0:
                    return _clamp(v / mx, -_ONE, _ONE)
                return _ZERO

            out[rest + 1] = _f32(_libm.sinf(float(angle)))
            out[rest + 2] = _f32(_libm.cosf(float(angle)))
            out[rest + 3] = ratio(_f32(obs.velocity[0]), _f32(self.linear_max))
            out[rest + 4] = ratio(_f32(obs.velocity[1]), _f32(self.angular_max))
        return out

    def command(self, output: Sequence[float] | F32Array) -> Action:
        """The velocity command for a network output (``Scaling::command``)."""
        lin = _clamp(_f32(output[0]), _ZERO, _ONE) * _f32(self.linear_max)
        ang = _clamp(_f32(output[1]), -_ONE, _ONE) * _f32(self.angular_max)
        return Action(float(lin), float(ang))

    def output_of(self, action: Action) -> tuple[np.float32, np.float32]:
        """The network output :meth:`command` turns into ``action`` (``Scaling::output_of``)."""
        return (
            _clamp(_f32(action.linear / float(np.float32(self.linear_max))), _ZERO, _ONE),
            _clamp(_f32(action.angular / float(np.float32(self.angular_max))), -_ONE, _ONE),
        )


def _number(v: object, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise PolicyError(f"policy metadata: `{what}` is {v!r}, not a number")
    return float(v)


def _fields(d: object, names: tuple[str, ...]) -> list[float]:
    """The numbers of a residual base's JSON object, all of ``names`` and nothing else."""
    if not isinstance(d, dict):
        raise PolicyError("policy metadata: `residual` is not an object")
    unknown = sorted(set(d) - set(names))
    if unknown:
        raise PolicyError(f"policy metadata: unknown field(s) {unknown} in `residual`")
    missing = [n for n in names if n not in d]
    if missing:
        raise PolicyError(f"policy metadata: missing field(s) {missing} in `residual`")
    return [_number(d[n], f"residual.{n}") for n in names]


class _Base:
    """What both residual bases share: the goal read back from an input row, and the command
    written as pre-activations (``Residual::output``, ``Residual::preactivation``)."""

    __slots__ = ()

    def command(self, goal: tuple[float, float]) -> Action:
        raise NotImplementedError

    def output(self, scaling: Scaling, row: F32Array) -> tuple[np.float32, np.float32]:
        """The base's command for one input row, in output units (``Residual::output``)."""
        rest = row[min(scaling.beams, len(row)) :]

        def at(i: int, default: float) -> float:
            return float(rest[i]) if i < len(rest) else default

        distance = at(0, 0.0) * float(np.float32(scaling.goal_distance_scale_m))
        if scaling.layout == "paper":
            angle = at(1, 0.0) * math.pi
        else:
            angle = _libm.atan2(at(1, 0.0), at(2, 1.0))
        goal = (distance * _libm.cos(angle), distance * _libm.sin(angle))
        return scaling.output_of(self.command(goal))

    def preactivation(self, scaling: Scaling, row: F32Array) -> tuple[np.float32, np.float32]:
        """:meth:`output` as the pre-activations the raw outputs are added to."""
        linear, angular = self.output(scaling, row)
        m = _RESIDUAL_MARGIN
        linear = _clamp(linear, m, _ONE - m)
        angular = _clamp(angular, -_ONE + m, _ONE - m)
        logit = _f32(_libm.logf(float(linear / (_ONE - linear))))
        # Rust's f32::atanh: 0.5 * ((2 x) / (1 - x)).ln_1p()
        atanh = np.float32(0.5) * _f32(_libm.log1pf(float((np.float32(2.0) * angular) / (_ONE - angular))))
        return logit, atanh


_FOLLOWER_FIELDS: Final = ("linear_max", "angular_max", "rotate_threshold", "heading_gain", "linear_min", "slow_down_m")
_RPP_FIELDS: Final = (
    "desired_linear_vel",
    "angular_max",
    "lookahead_dist",
    "rotate_to_heading_angular_vel",
    "rotate_to_heading_min_angle",
    "regulated_linear_scaling_min_radius",
    "regulated_linear_scaling_min_speed",
    "approach_velocity_scaling_dist",
    "min_approach_linear_velocity",
)


@dataclass(frozen=True, slots=True)
class Residual(_Base):
    """``learning::Residual::Follower``: a residual policy's base, the classical follower
    steering straight at the goal, computed from the network's input alone."""

    linear_max: float
    angular_max: float
    rotate_threshold: float
    heading_gain: float
    linear_min: float
    slow_down_m: float

    @classmethod
    def from_json(cls, d: object) -> Residual:
        return cls(*_fields(d, _FOLLOWER_FIELDS))

    def command(self, goal: tuple[float, float]) -> Action:
        return self.follow(goal)

    def follow(self, goal: tuple[float, float]) -> Action:
        """``sim::follower::follow`` from the origin facing +x on the segment origin → ``goal``
        (with the follower's default look-ahead)."""
        from_ = (0.0, 0.0)
        px, py, pyaw = 0.0, 0.0, 0.0
        # carrot()
        dx, dy = goal[0] - from_[0], goal[1] - from_[1]
        length = _libm.hypot(dx, dy)
        if length < 1e-9:
            carrot = goal
        else:
            ux, uy = dx / length, dy / length
            t = _clamp64((px - from_[0]) * ux + (py - from_[1]) * uy, 0.0, length)
            s = min(t + _FOLLOWER_LOOKAHEAD_M, length)
            carrot = (from_[0] + s * ux, from_[1] + s * uy)
        d = _libm.hypot(goal[0] - px, goal[1] - py)
        target = goal if _libm.hypot(carrot[0] - px, carrot[1] - py) < 1e-6 else carrot
        bearing = _libm.atan2(target[1] - py, target[0] - px)
        e = _wrap_angle(bearing - pyaw)
        angular = _clamp64(self.heading_gain * e, -self.angular_max, self.angular_max)
        if abs(e) > self.rotate_threshold:
            return Action(0.0, angular)
        share = 1.0 - abs(e) / self.rotate_threshold
        approach = min(d / self.slow_down_m, 1.0)
        linear = (self.linear_min + (self.linear_max - self.linear_min) * share) * approach
        return Action(max(linear, min(self.linear_min, d)), angular)


@dataclass(frozen=True, slots=True)
class RppResidual(_Base):
    """``learning::Residual::Rpp``: a residual policy's base, Nav2's Regulated Pure Pursuit on
    the straight line to the goal (``sim::rpp_command``), computed from the network's input
    alone."""

    desired_linear_vel: float
    angular_max: float
    lookahead_dist: float
    rotate_to_heading_angular_vel: float
    rotate_to_heading_min_angle: float
    regulated_linear_scaling_min_radius: float
    regulated_linear_scaling_min_speed: float
    approach_velocity_scaling_dist: float
    min_approach_linear_velocity: float

    @classmethod
    def from_json(cls, d: object) -> RppResidual:
        return cls(*_fields(d, _RPP_FIELDS))

    def command(self, goal: tuple[float, float]) -> Action:
        """The arc through the carrot on the line to ``goal`` (robot frame), regulated by its
        curvature and the approach to the goal, within the angular limit."""
        d = _libm.hypot(goal[0], goal[1])
        if d > self.lookahead_dist:
            k = self.lookahead_dist / d
            x, y = goal[0] * k, goal[1] * k
        else:
            x, y = goal
        angle = _libm.atan2(y, x)
        if abs(angle) > self.rotate_to_heading_min_angle:
            return Action(0.0, math.copysign(1.0, angle) * self.rotate_to_heading_angular_vel)
        curvature = 2.0 * y / max(x * x + y * y, 1e-9)
        desired = self.desired_linear_vel
        curvature_vel = desired
        radius = 1.0 / max(abs(curvature), 1e-9)
        if radius < self.regulated_linear_scaling_min_radius:
            curvature_vel *= radius / self.regulated_linear_scaling_min_radius
        linear = min(max(min(curvature_vel, desired), self.regulated_linear_scaling_min_speed), desired)
        if d < self.approach_velocity_scaling_dist:
            approach = desired * d / self.approach_velocity_scaling_dist
            linear = min(linear, max(approach, self.min_approach_linear_velocity))
        if abs(curvature) > 1e-9:
            linear = min(linear, self.angular_max / abs(curvature))
        return Action(linear, _clamp64(linear * curvature, -self.angular_max, self.angular_max))


def residual_from_json(d: object) -> Residual | RppResidual:
    """The base a policy file names by its fields: Regulated Pure Pursuit's, or the follower's."""
    if isinstance(d, dict) and "desired_linear_vel" in d:
        return RppResidual.from_json(d)
    return Residual.from_json(d)


@dataclass(frozen=True, slots=True)
class _Dense:
    weight: F32Array  # [out, in]
    bias: F32Array  # [out]

    def forward(self, x: F32Array) -> F32Array:
        """``x`` ``[n, in]`` → ``[n, out]``, as ``Dense::forward`` and ``dot`` compute it."""
        n, inputs = x.shape
        outputs = self.weight.shape[0]
        chunks = inputs // 8
        w = self.weight[np.newaxis, :, :]
        xs = x[:, np.newaxis, :]
        acc = np.zeros((n, outputs, 8), dtype=np.float32)
        for k in range(chunks):
            acc = acc + w[:, :, 8 * k : 8 * k + 8] * xs[:, :, 8 * k : 8 * k + 8]
        a = [acc[:, :, i] for i in range(8)]
        s: F32Array = ((a[0] + a[4]) + (a[1] + a[5])) + ((a[2] + a[6]) + (a[3] + a[7]))
        for j in range(8 * chunks, inputs):
            s = s + w[:, :, j] * xs[:, :, j]
        out: F32Array = (s + self.bias[np.newaxis, :]).astype(np.float32)
        return out


@dataclass(frozen=True)
class Policy:
    """A trained actor, run locally (``learning::Policy``)."""

    #: The whole ``policy.json``.
    metadata: dict[str, Any]
    scaling: Scaling
    hidden: tuple[int, ...]
    residual: Residual | RppResidual | None
    _layers: tuple[_Dense, ...] = field(repr=False)

    @classmethod
    def load(cls, directory: str | os.PathLike[str]) -> Policy:
        """Loads ``policy.safetensors`` and ``policy.json`` from ``directory``."""
        d = Path(directory)
        try:
            meta = (d / METADATA_FILE).read_bytes()
            weights = (d / WEIGHTS_FILE).read_bytes()
        except OSError as e:
            raise PolicyError(f"{e.filename}: {e.strerror}") from e
        return cls.from_bytes(meta, weights)

    @classmethod
    def from_bytes(cls, metadata_json: bytes, safetensors: bytes) -> Policy:
        """A policy from the two files' contents, checked as ``Policy::from_bytes`` checks them."""
        try:
            meta = json.loads(metadata_json)
        except ValueError as e:
            raise PolicyError(f"policy metadata: {e}") from e
        if not isinstance(meta, dict):
            raise PolicyError("policy metadata: not a JSON object")
        for key in ("format", "version", "scaling", "observation_layout", "hidden", "output_activations"):
            if key not in meta:
                raise PolicyError(f"policy metadata: missing field `{key}`")
        if meta["format"] != FORMAT or meta["version"] != 1:
            raise PolicyError(f"policy metadata: format `{meta['format']}` version {meta['version']} is not `{FORMAT}` version 1")
        if meta["output_activations"] != ["sigmoid", "tanh"]:
            raise PolicyError(f"policy metadata: output activations {meta['output_activations']} are not [sigmoid, tanh]")
        scaling = Scaling.from_json(meta["scaling"])
        hidden_raw = meta["hidden"]
        if not isinstance(hidden_raw, list) or not all(isinstance(h, int) and not isinstance(h, bool) and h >= 0 for h in hidden_raw):
            raise PolicyError(f"policy metadata: `hidden` is {hidden_raw!r}")
        hidden = tuple(int(h) for h in hidden_raw)
        if scaling.beams == 0 or 0 in hidden:
            raise PolicyError("policy metadata: beam count and hidden widths must be positive")
        residual = residual_from_json(meta["residual"]) if meta.get("residual") is not None else None
        try:
            tensors = load_safetensors(safetensors)
        except Exception as e:  # the parser raises its own error types
            raise PolicyError(f"policy weights: {e}") from e
        widths = [scaling.input_len, *hidden, ACTION_DIM]
        layers = []
        for i in range(len(widths) - 1):
            inputs, outputs = widths[i], widths[i + 1]
            weight = _tensor(tensors, f"layers.{i}.weight", (outputs, inputs))
            bias = _tensor(tensors, f"layers.{i}.bias", (outputs,))
            layers.append(_Dense(weight, bias))
        if len(tensors) != 2 * len(layers):
            raise PolicyError(f"policy weights: {len(tensors)} tensors for {len(layers)} layers: the file holds another network")
        return cls(meta, scaling, hidden, residual, tuple(layers))

    @property
    def input_len(self) -> int:
        """Length of the network's input."""
        return self.scaling.input_len

    def encode(self, obs: Observation) -> F32Array:
        """The network input for ``obs``."""
        return self.scaling.encode(obs)

    def forward(self, inputs: npt.ArrayLike) -> F32Array:
        """The network's output for already scaled inputs (one row, or ``[n, input_len]``):
        linear in [0, 1], angular in [-1, 1], float32, shaped like the input's rows."""
        x = np.asarray(inputs, dtype=np.float32)
        single = x.ndim == 1
        if single:
            x = x[np.newaxis, :]
        if x.ndim != 2 or x.shape[1] != self.input_len:
            raise PolicyError(f"inputs of shape {np.shape(inputs)} for a policy that takes {self.input_len}")
        x = np.ascontiguousarray(x)
        a = x
        last = len(self._layers) - 1
        for i, layer in enumerate(self._layers):
            a = layer.forward(a)
            if i < last:
                a = np.fmax(a, _ZERO).astype(np.float32)  # f32::max: NaN gives the other operand
        if self.residual is not None:
            base = np.array([self.residual.preactivation(self.scaling, row) for row in x], dtype=np.float32)
            a = (a + base).astype(np.float32)
        # sigmoid(x) = 1 / (1 + exp(-x)), tanh: float32 operations and the C library's functions.
        e = _libm.map_f32(_libm.expf, (-a[:, 0]).astype(np.float32))
        linear = (_ONE / (_ONE + e)).astype(np.float32)
        angular = _libm.map_f32(_libm.tanhf, a[:, 1].astype(np.float32))
        out = np.stack([linear, angular], axis=1).astype(np.float32)
        return out[0] if single else out

    def act(self, obs: Observation) -> Action:
        """The velocity command for an observation (``Policy::act``)."""
        return self.scaling.command(self.forward(self.encode(obs)))


def _tensor(tensors: dict[str, npt.NDArray[Any]], name: str, shape: tuple[int, ...]) -> F32Array:
    t = tensors.get(name)
    if t is None:
        raise PolicyError(f"policy weights: missing tensor `{name}`")
    if t.dtype != np.float32:
        raise PolicyError(f"policy weights: `{name}` is {t.dtype}, not float32")
    if tuple(t.shape) != shape:
        raise PolicyError(f"policy weights: `{name}` has shape {list(t.shape)}, expected {list(shape)}")
    return np.ascontiguousarray(t, dtype=np.float32)


def load_policy(directory: str | os.PathLike[str]) -> Policy:
    """The policy in ``directory`` (``policy.safetensors`` + ``policy.json``)."""
    return Policy.load(directory)
