"""The learned oracle of the slice-based RRT (Haustein et al. 2018, §II "Learning the Policy" and
"Learning the generative model"), as the planner runs it: NumPy inference of the shipped
weights (`config/models/<robot>_oracle.npz`, made by `rearrangement-train`), so that planning
needs no training framework.

Everything is in the frame of the object to push (its pose is the origin, yaw 0):

- x_r (3,): the tool's planar pose (x, y, yaw) relative to the object;
- x_o^d (2,): where the object should go, relative to itself;
- ν_o (7,): `PROPERTY_NAMES`;
- u (3,): the tool's planar velocity (v_x, v_y) in m/s and the push's duration in s.

Four multilayer perceptrons (`Network`): the forward models f_μ and f_σ² (the object's
expected successor state and its variance after u, Eq. 3-4), the policy π_θ(x_r, x_o^d, ν_o)
→ u, trained by deterministic policy gradient through them on the loss of Eq. 2, and the
generator G(z, x_o^d, ν_o) → x_r, a conditional GAN trained on MCMC samples of
p(x_r) ∝ exp(-λ L_θ) (Eq. 5-7). The feature encodings below are shared with the training code
(`tools/training/command.py`), which runs the same functions on JAX arrays.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from rearrangement_planner.model.resources import config_dir
from rearrangement_planner.model.scene import MovableObject, Scene
from rearrangement_planner.planning.machinery.propagation import Action

PROPERTY_NAMES = ("cylinder", "size_x", "size_y", "size_z", "mass", "support_friction",
                  "pusher_friction")
"""ν_o, the object's physical parameters the models take: 1 for a cylinder, its full extents
(m), mass (kg) and the support and pusher friction coefficients."""
NOISE_SIZE = 4
"""Dimensions of the generator's latent input z ~ N(0, I)."""
POSITION_SCALE = 0.1
"""m: positions are divided by this in the networks' inputs and outputs."""
MIN_DURATION = 0.2
"""s: the shortest push the policy makes."""


def object_properties(obj: MovableObject) -> np.ndarray:
    """ν_o of `obj` (`PROPERTY_NAMES`)."""
    return np.array([float(obj.shape == "cylinder"), *obj.size, obj.mass, obj.support_friction,
                     obj.pusher_friction])


# -- feature encodings (NumPy or JAX: `xp` is the array module) ---------------------------------

def tool_features(tool: Any, xp: ModuleType = np) -> Any:
    """x_r (..., 3) → (..., 4): scaled position, cos and sin of the yaw."""
    return xp.concatenate([tool[..., :2] / POSITION_SCALE, xp.cos(tool[..., 2:3]),
                           xp.sin(tool[..., 2:3])], axis=-1)


def property_features(props: Any, xp: ModuleType = np) -> Any:
    """ν_o (..., 7) → (..., 7): sizes in units of POSITION_SCALE, the rest as they are."""
    return xp.concatenate([props[..., :1], props[..., 1:4] / POSITION_SCALE, props[..., 4:]],
                          axis=-1)


def action_features(action: Any, max_speed: float, max_duration: float,
                    xp: ModuleType = np) -> Any:
    """u (..., 3) → (..., 5): velocity in units of `max_speed`, duration in units of
    `max_duration`, and the tool's travel (velocity × duration) in units of POSITION_SCALE."""
    travel = action[..., :2] * action[..., 2:] / POSITION_SCALE
    return xp.concatenate([action[..., :2] / max_speed, action[..., 2:] / max_duration, travel],
                          axis=-1)


def forward_inputs(tool: Any, props: Any, action: Any, max_speed: float, max_duration: float,
                   xp: ModuleType = np) -> Any:
    """The forward models' input: x_r, ν_o and u encoded, and where the tool ends up relative
    to the object after u (the pushed object ends near it)."""
    end = (tool[..., :2] + action[..., :2] * action[..., 2:]) / POSITION_SCALE
    return xp.concatenate([tool_features(tool, xp), property_features(props, xp),
                           action_features(action, max_speed, max_duration, xp), end], axis=-1)


# -- networks ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Network:
    """A multilayer perceptron: ReLU hidden layers, a linear output. `weights[i]` is (in, out)."""

    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return mlp(self.weights, self.biases, x)


def mlp(weights: Any, biases: Any, x: Any, xp: ModuleType = np) -> Any:
    """The perceptron's output for inputs x (..., in): ReLU between layers, linear at the end."""
    for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
        x = x @ w + b
        if i < len(weights) - 1:
            x = xp.maximum(x, 0.0)
    return x


def policy_output(raw: Any, max_speed: float, max_duration: float, xp: ModuleType = np) -> Any:
    """The policy network's raw output (..., 3) → u: each velocity component within
    ±max_speed (tanh), the duration in [MIN_DURATION, max_duration] (a logistic)."""
    velocity = max_speed * xp.tanh(raw[..., :2])
    duration = MIN_DURATION + (max_duration - MIN_DURATION) / (
        1.0 + xp.exp(-xp.clip(raw[..., 2:], -30.0, 30.0)))
    return xp.concatenate([velocity, duration], axis=-1)


def generator_output(raw: Any, xp: ModuleType = np) -> Any:
    """The generator's raw output (..., 4) → x_r (x, y, yaw): position scaled back, the yaw
    the angle of the last two outputs."""
    return xp.concatenate([raw[..., :2] * POSITION_SCALE,
                           xp.arctan2(raw[..., 3:4], raw[..., 2:3])], axis=-1)


NETWORKS = ("f_mu", "f_var", "policy", "generator")
"""The networks of one oracle file."""


@dataclass(frozen=True)
class OracleModels:
    """The learned models of one robot, as read from `path` (an .npz of `save_models`)."""

    networks: dict[str, Network]
    max_speed: float
    max_duration: float
    reach: float

    def policy(self, tool: np.ndarray, desired: np.ndarray, props: np.ndarray) -> np.ndarray:
        """π_θ: u (..., 3) for x_r (..., 3), x_o^d (..., 2), ν_o (..., 7)."""
        x = np.concatenate([tool_features(tool), desired / POSITION_SCALE,
                            property_features(props)], axis=-1)
        return policy_output(self.networks["policy"](x), self.max_speed, self.max_duration)

    def generate(self, noise: np.ndarray, desired: np.ndarray, props: np.ndarray) -> np.ndarray:
        """G: x_r (..., 3) for z (..., NOISE_SIZE), x_o^d (..., 2), ν_o (..., 7)."""
        x = np.concatenate([noise, desired / POSITION_SCALE, property_features(props)], axis=-1)
        return generator_output(self.networks["generator"](x))

    def forward(self, tool: np.ndarray, props: np.ndarray, action: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """f_μ and f_σ²: the object's expected successor (x, y, yaw) and its variance."""
        x = forward_inputs(tool, props, action, self.max_speed, self.max_duration)
        return forward_output(self.networks["f_mu"](x), self.networks["f_var"](x))


def forward_output(mu_raw: Any, var_raw: Any, xp: ModuleType = np) -> tuple[Any, Any]:
    """The forward models' raw outputs → successor mean (x, y in m, yaw in rad) and variance
    (the network predicts the log variance in scaled units, read within [-12, 4] so that an
    input far from the data cannot overflow it)."""
    scale = xp.asarray([POSITION_SCALE, POSITION_SCALE, 1.0])
    return mu_raw * scale, xp.exp(xp.clip(var_raw, -12.0, 4.0)) * scale ** 2


def model_path(robot: str) -> Path:
    """Where the shipped models of robot `robot` live."""
    return config_dir() / "models" / f"{robot}_oracle.npz"


def save_models(path: str | Path, params: dict[str, tuple[list, list]], max_speed: float,
                max_duration: float, reach: float) -> None:
    """Write the networks `params` (name → (weights, biases)) as float32 arrays."""
    arrays: dict[str, Any] = {"meta": np.array([max_speed, max_duration, reach])}
    for name, (weights, biases) in params.items():
        for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
            arrays[f"{name}/w{i}"] = np.asarray(w, dtype=np.float32)
            arrays[f"{name}/b{i}"] = np.asarray(b, dtype=np.float32)
    np.savez_compressed(path, **arrays)


def load_models(path: str | Path) -> OracleModels:
    """The models written by `save_models`; a clear error if the file is missing or partial."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no learned oracle at {path}: train one with "
                                f"`rearrangement-train --out {path}`")
    with np.load(path) as data:
        networks = {}
        for name in NETWORKS:
            layers = sum(1 for k in data.files if k.startswith(f"{name}/w"))
            if layers == 0:
                raise ValueError(f"{path}: the network '{name}' is missing")
            networks[name] = Network(
                tuple(data[f"{name}/w{i}"].astype(float) for i in range(layers)),
                tuple(data[f"{name}/b{i}"].astype(float) for i in range(layers)))
        max_speed, max_duration, reach = (float(v) for v in data["meta"])
    return OracleModels(networks, max_speed, max_duration, reach)


@functools.cache
def shipped_models(robot: str) -> OracleModels:
    """The shipped models of robot `robot`, read once per process."""
    return load_models(model_path(robot))


def to_local(frame: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """`pose` (x, y[, yaw]) of the base frame in `frame` (x, y, yaw)."""
    c, s = math.cos(frame[2]), math.sin(frame[2])
    dx, dy = pose[0] - frame[0], pose[1] - frame[1]
    local = [c * dx + s * dy, -s * dx + c * dy]
    if len(pose) > 2:
        local.append(math.atan2(math.sin(pose[2] - frame[2]), math.cos(pose[2] - frame[2])))
    return np.array(local)


def to_base(frame: np.ndarray, local: np.ndarray) -> np.ndarray:
    """`local` (x, y[, yaw]) given in `frame` (x, y, yaw), in the base frame."""
    c, s = math.cos(frame[2]), math.sin(frame[2])
    pose = [frame[0] + c * local[0] - s * local[1], frame[1] + s * local[0] + c * local[1]]
    if len(local) > 2:
        pose.append(math.atan2(math.sin(frame[2] + local[2]), math.cos(frame[2] + local[2])))
    return np.array(pose)


class LearnedOracle:
    """The slice-based RRT's `Oracle` from learned models: the generator's manipulation state
    and the policy's push, both in the pushed object's frame. Targets farther than one push
    reaches (`max_speed` × `max_duration`) are brought that close along their direction."""

    def __init__(self, scene: Scene, models: OracleModels, nq: int):
        self.models = models
        self.nq = nq
        self.props = np.array([object_properties(o) for o in scene.objects])
        self.reach = models.max_speed * models.max_duration

    def _desired(self, pose: np.ndarray, target: np.ndarray) -> np.ndarray | None:
        local = to_local(pose, target)
        distance = float(np.hypot(*local))
        if distance < 1e-3:
            return None
        return local * min(1.0, self.reach / distance)

    def manipulation_state(self, objects: np.ndarray, t: int, target: np.ndarray,
                           rng: np.random.Generator) -> np.ndarray | None:
        desired = self._desired(objects[t], target)
        if desired is None:
            return None
        tool = self.models.generate(rng.standard_normal(NOISE_SIZE), desired, self.props[t])
        return to_base(objects[t], tool)

    def push(self, tool: np.ndarray, objects: np.ndarray, t: int, target: np.ndarray
             ) -> Action | None:
        desired = self._desired(objects[t], target)
        if desired is None:
            return None
        u = self.models.policy(to_local(objects[t], tool), desired, self.props[t])
        c, s = math.cos(objects[t, 2]), math.sin(objects[t, 2])
        velocity = np.array([c * u[0] - s * u[1], s * u[0] + c * u[1], 0.0])
        # The policy bounds each component in the object's frame; the planner bounds them in
        # the base frame: slow down and push longer, the same travel.
        over = max(1.0, float(np.abs(velocity[:2]).max()) / self.models.max_speed)
        return Action(velocity / over, float(u[2]) * over, np.zeros(self.nq))
