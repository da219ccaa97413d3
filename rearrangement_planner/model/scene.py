"""The world the planner works in: table, static obstacles, movable objects and the goal
(docs/design.md "The world model"), and the YAML scene format that describes it.

A scene file is a public contract (docs/design.md "The world model", "Scene file")::

    robot: xarm7                        # a shipped robot config name or a path to one
    start_configuration: [0.0, -0.5, 0.0, 0.8, 0.0, 1.3, 0.0]       # optional; default: home
    table: {center: [0.55, 0.0], size: [0.8, 1.2], height: 0.0}
    obstacles:                          # optional
      - {name: post, shape: box, size: [0.05, 0.05, 0.30], pose: [0.75, 0.35, 0.0]}
    objects:
      - {name: target, shape: box, size: [0.06, 0.08, 0.12], pose: [0.50, 0.10, 0.3],
         mass: 0.4, support_friction: 0.4, pusher_friction: 0.3}   # mass/frictions optional
      - {name: can, shape: cylinder, radius: 0.035, height: 0.12, pose: [0.55, -0.05, 0.0]}
    goal: {object: target, position: [0.60, -0.30], radius: 0.10}

Frame and units: everything is in the robot base frame; lengths in metres, angles in radians,
masses in kilograms; frictions are dimensionless coefficients. The table is an axis-aligned
rectangle whose top face is at ``table.height``; obstacles and movable objects are vertical
prisms standing on that top face, so a planar pose (x, y, yaw) places them completely.

`read_scene` / `scene_from_dict` reject a malformed scene with ONE `SceneError` whose `field` is
the dotted path of the offending entry (``objects[1].pose``, ``goal.object``, ``table.size`` ...)
and whose `problem` says what is wrong and what would be right. This module is data and its
format only: the checks that need the geometry (objects apart, a start configuration clear of
the table, obstacles and objects) live with the physics, in `physics.validation`, whose
`load_scene` / `parse_scene` are what the CLI, the node and the benchmark call.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from rearrangement_planner.model.errors import RobotModelError, SceneError
from rearrangement_planner.model.files import FileProblem, is_file, load_yaml, quote
from rearrangement_planner.model.resources import robots_dir, scenes_dir
from rearrangement_planner.model.robot import RobotConfig, RobotModel
from rearrangement_planner.model.state import State

DEFAULT_MASS = 0.5               # kg
DEFAULT_SUPPORT_FRICTION = 0.4   # object-table coefficient mu_s
DEFAULT_PUSHER_FRICTION = 0.3    # arm-object coefficient mu_c
DEFAULT_GOAL_RADIUS = 0.1        # m
OBJECT_SHAPES = ("box", "cylinder")
# Depth (m) below which two touching bodies count as apart; absorbs the ~1e-6 m noise of the
# narrow phase so that objects placed exactly side by side are accepted.
TOUCH_TOLERANCE = 1e-6

BOUNDS: dict[str, tuple[float, float, str]] = {
    "table.center": (-3.0, 3.0, "m"),
    "table.size": (0.1, 5.0, "m"),
    "table.height": (-2.0, 2.0, "m"),
    "obstacle extent": (0.005, 5.0, "m"),
    "object extent": (0.005, 1.0, "m"),
    "object radius": (0.0025, 0.5, "m"),
    "mass": (0.001, 100.0, "kg"),
    "support_friction": (0.01, 2.0, ""),
    "pusher_friction": (0.0, 2.0, ""),
    "goal.radius": (0.001, 5.0, "m"),
}
"""Physical plausibility (docs/design.md, "Scene file"): values outside are refused at load time,
not found late. The goal radius is also at most the table's larger side, and obstacles, like
objects, stand on the table (their centre on its top)."""


def _readonly(values: Any) -> np.ndarray:
    a = np.array(values, dtype=float)
    a.setflags(write=False)
    return a


# --------------------------------------------------------------------------------------------
# Value types
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Table:
    """The table top (docs/design.md): an axis-aligned rectangle in the base frame.

    `center` (2,) and `size` (2,) are the rectangle's centre and full side lengths in x and y
    (m); `height` is the z of its top face (m).
    """

    center: np.ndarray
    size: np.ndarray
    height: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _readonly(self.center))
        object.__setattr__(self, "size", _readonly(self.size))
        object.__setattr__(self, "height", float(self.height))

    @cached_property
    def lower(self) -> np.ndarray:
        """(x_min, y_min) of the table top, m (read-only; the samplers ask it every draw)."""
        return _readonly(self.center - 0.5 * self.size)

    @cached_property
    def upper(self) -> np.ndarray:
        """(x_max, y_max) of the table top, m (read-only)."""
        return _readonly(self.center + 0.5 * self.size)

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """Whether points (..., 2) lie on the table rectangle (its edge counts as on)."""
        xy = np.asarray(xy, dtype=float)
        return np.all(np.abs(xy - self.center) <= 0.5 * self.size, axis=-1)

    def describe(self) -> str:
        lo, hi = self.lower, self.upper
        return f"x in [{lo[0]:.3f}, {hi[0]:.3f}], y in [{lo[1]:.3f}, {hi[1]:.3f}]"


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A static box standing on the table top (docs/design.md "The world model").

    `size` (3,) holds the full extents (x, y, z) in the box's own frame, m; `pose` (3,) is the
    planar pose (x, y, yaw) of its centre in the base frame (m, rad).
    """

    name: str
    size: np.ndarray
    pose: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "size", _readonly(self.size))
        object.__setattr__(self, "pose", _readonly(self.pose))

    @property
    def shape(self) -> str:
        return "box"

    @property
    def height(self) -> float:
        return float(self.size[2])

    @property
    def footprint_radius(self) -> float:
        """Radius of the smallest circle about the centre that contains the footprint, m."""
        return 0.5 * math.hypot(self.size[0], self.size[1])

    @property
    def bounding_radius(self) -> float:
        """Radius of the sphere about the box centre that contains the box (half diagonal)."""
        return 0.5 * float(np.linalg.norm(self.size))


@dataclass(frozen=True)
class SupportPressure:
    """How an object's weight rests on the table (Lynch, Maekawa & Tanie 1992): the pressure
    distribution over its footprint sets both the limit surface's c = m_max / f_max and the
    centre of friction about which the support's friction load is centred. A scene file cannot
    say it (the nominal object is `NOMINAL_SUPPORT`); `model.perturbation` draws it, because it
    is what decides how a pushed object turns and no camera sees it.

    `c_scale`: c as a multiple of the uniform-pressure value (about 0.8 when the weight rests
    near the centre, 1.5 on a disk's rim, 1.85 on a box's corners). `centre`: the centre of
    friction (x, y) in the object frame, m."""

    c_scale: float = 1.0
    centre: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.c_scale) and self.c_scale > 0.0):
            raise ValueError(f"support c_scale must be positive and finite, got {self.c_scale}")
        object.__setattr__(self, "centre", (float(self.centre[0]), float(self.centre[1])))


NOMINAL_C_SCALE = 1.3
"""The nominal object's c as a multiple of the uniform-pressure value: between centre-loaded
(0.8) and rim- or corner-loaded (1.5-1.85), the middle of `model.perturbation`'s range. Fitted
to single pushes in MuJoCo: under uniform pressure (1.0) the model turned a pushed object 1.21 x
as far as MuJoCo did, at 1.3 it turns it as far (docs/experiments.md, 2026-11-30)."""

NOMINAL_SUPPORT = SupportPressure(NOMINAL_C_SCALE)
"""The nominal object of every scene: c of `NOMINAL_C_SCALE`, the centre of friction at the
footprint's centre."""


@dataclass(frozen=True, eq=False)
class MovableObject:
    """A movable vertical prism standing on the table top (docs/design.md "The world model").

    `shape` is ``'box'`` or ``'cylinder'``. `size` (3,) holds the full extents (x, y, z) in the
    object frame, m; for a cylinder it is (2r, 2r, height), so that `size` always bounds the
    prism and `size[2]` is always its height. `pose` (3,) is the initial planar pose (x, y, yaw)
    of its centre in the base frame (m, rad). `mass` in kg; `support_friction` is the
    object-table coefficient mu_s and `pusher_friction` the arm-object coefficient mu_c
    (docs/design.md "Quasistatic pushing physics"). `support` is how its weight rests on the
    table (`SupportPressure`; `NOMINAL_SUPPORT` unless a perturbation drew another).
    """

    name: str
    shape: str
    size: np.ndarray
    pose: np.ndarray
    mass: float = DEFAULT_MASS
    support_friction: float = DEFAULT_SUPPORT_FRICTION
    pusher_friction: float = DEFAULT_PUSHER_FRICTION
    support: SupportPressure = NOMINAL_SUPPORT

    def __post_init__(self) -> None:
        if self.shape not in OBJECT_SHAPES:
            raise ValueError(f"object shape {self.shape!r}; use one of {OBJECT_SHAPES}")
        object.__setattr__(self, "size", _readonly(self.size))
        object.__setattr__(self, "pose", _readonly(self.pose))

    @classmethod
    def cylinder(cls, name: str, radius: float, height: float, pose: Sequence[float],
                 **kwargs: Any) -> MovableObject:
        """A cylinder of `radius` and `height` (m); keyword args as in the class."""
        return cls(name, "cylinder", np.array([2 * radius, 2 * radius, height]), np.asarray(pose),
                   **kwargs)

    @classmethod
    def box(cls, name: str, size: Sequence[float], pose: Sequence[float],
            **kwargs: Any) -> MovableObject:
        """A box of full extents `size` (x, y, z) (m); keyword args as in the class."""
        return cls(name, "box", np.asarray(size), np.asarray(pose), **kwargs)

    @property
    def radius(self) -> float | None:
        """The cylinder radius (m); None for a box."""
        return 0.5 * float(self.size[0]) if self.shape == "cylinder" else None

    @property
    def height(self) -> float:
        return float(self.size[2])

    @property
    def footprint_radius(self) -> float:
        """Radius of the smallest circle about the centre that contains the footprint, m."""
        if self.shape == "cylinder":
            return 0.5 * float(self.size[0])
        return 0.5 * math.hypot(self.size[0], self.size[1])

    @property
    def bounding_radius(self) -> float:
        """Radius of the sphere about the prism centre that contains the prism (broad phase):
        the half diagonal of the prism."""
        return math.hypot(self.footprint_radius, 0.5 * self.height)


@dataclass(frozen=True, eq=False)
class Goal:
    """The goal region (docs/design.md): object `object`'s centre within `radius` (m) of
    `position` (2,), a point (x, y) on the table in the base frame."""

    object: str
    position: np.ndarray
    radius: float = DEFAULT_GOAL_RADIUS

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", _readonly(self.position))
        object.__setattr__(self, "radius", float(self.radius))

    def distance(self, xy: np.ndarray) -> float:
        """Distance (m) of a centre (x, y) from the goal point."""
        return float(np.hypot(*(np.asarray(xy, dtype=float)[:2] - self.position)))

    def reached(self, xy: np.ndarray) -> bool:
        return self.distance(xy) <= self.radius


@dataclass(frozen=True, eq=False)
class Scene:
    """A complete planning problem (docs/design.md): robot, start state, table, obstacles, objects
    and goal. Build it with `load_scene` / `parse_scene`; a scene assembled in code should go
    through `check_scene` before use.

    `start_configuration` (nq,) is in rad; `source` names where the scene came from (a file
    path or the name given to `parse_scene`).
    """

    robot: RobotModel
    start_configuration: np.ndarray
    table: Table
    obstacles: tuple[Obstacle, ...]
    objects: tuple[MovableObject, ...]
    goal: Goal
    source: str = field(default="<scene>")

    def __post_init__(self) -> None:
        object.__setattr__(self, "start_configuration", _readonly(self.start_configuration))
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        object.__setattr__(self, "objects", tuple(self.objects))

    @property
    def object_names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.objects)

    @property
    def object_poses(self) -> np.ndarray:
        """(M, 3) initial object poses (x, y, yaw), base frame, a fresh writable array."""
        return np.array([o.pose for o in self.objects], dtype=float).reshape(-1, 3)

    def object_index(self, name: str) -> int:
        """Index of the movable object called `name` (its row in `State.objects`)."""
        for i, obj in enumerate(self.objects):
            if obj.name == name:
                return i
        raise SceneError("objects", f"no object named {name!r}; objects are "
                                    f"{list(self.object_names)}")

    @property
    def goal_index(self) -> int:
        """Index of the goal object in `objects` / `State.objects`."""
        return self.object_index(self.goal.object)

    def with_start(self, start_configuration: np.ndarray, object_poses: np.ndarray) -> Scene:
        """The same scene from another start: arm configuration (nq,) and object poses (M, 3).
        Not checked: `physics.validation.check_scene` does that."""
        poses = np.asarray(object_poses, dtype=float).reshape(len(self.objects), 3)
        objects = tuple(dataclasses.replace(o, pose=p) for o, p in zip(self.objects, poses,
                                                                         strict=True))
        return dataclasses.replace(self, start_configuration=np.asarray(start_configuration,
                                                                        dtype=float),
                                   objects=objects)

    def initial_state(self) -> State:
        """x_0 = (q_start, o^1 ... o^M) of King et al. 2015, §II-A."""
        return State(self.start_configuration, self.object_poses)

    def to_dict(self) -> dict[str, Any]:
        """The scene in the YAML format of docs/design.md (plain lists and floats), such that
        ``parse_scene(scene.to_dict())`` rebuilds it. A shipped robot is written by name, any
        other by the absolute path of its config."""
        def floats(a: np.ndarray) -> list[float]:
            return [float(v) for v in a]

        objects: list[dict[str, Any]] = []
        for o in self.objects:
            entry: dict[str, Any] = {"name": o.name, "shape": o.shape}
            if o.shape == "cylinder":
                entry.update(radius=o.radius, height=o.height)
            else:
                entry["size"] = floats(o.size)
            entry.update(pose=floats(o.pose), mass=o.mass, support_friction=o.support_friction,
                         pusher_friction=o.pusher_friction)
            objects.append(entry)
        return {
            "robot": _robot_reference(self.robot),
            "start_configuration": floats(self.start_configuration),
            "table": {"center": floats(self.table.center), "size": floats(self.table.size),
                      "height": self.table.height},
            "obstacles": [{"name": b.name, "shape": "box", "size": floats(b.size),
                           "pose": floats(b.pose)} for b in self.obstacles],
            "objects": objects,
            "goal": {"object": self.goal.object, "position": floats(self.goal.position),
                     "radius": self.goal.radius},
        }


def _robot_reference(robot: RobotModel) -> str:
    source = robot.config.source
    if source is None:
        return robot.name
    source = Path(source).resolve()
    try:
        if source.parent == robots_dir().resolve():
            return source.stem
    except FileNotFoundError:
        pass
    return str(source)


# --------------------------------------------------------------------------------------------
# Loading and structural validation
# --------------------------------------------------------------------------------------------

_TOP_KEYS = ("robot", "start_configuration", "table", "obstacles", "objects", "goal")
_TABLE_KEYS = ("center", "size", "height")
_OBSTACLE_KEYS = ("name", "shape", "size", "pose")
_COMMON_OBJECT_KEYS = ("name", "shape", "pose", "mass", "support_friction", "pusher_friction")
_OBJECT_KEYS = {"box": _COMMON_OBJECT_KEYS + ("size",),
                "cylinder": _COMMON_OBJECT_KEYS + ("radius", "height")}
_GOAL_KEYS = ("object", "position", "radius")


def read_scene(path: str | Path, robot: RobotModel | None = None) -> Scene:
    """Read a scene file (docs/design.md) and check its structure (`scene_from_dict`).

    `path` is a YAML file, or the name of a shipped scene in ``config/scenes/`` (``'default'``).
    A relative robot config path in the file is resolved against the file's folder. `robot`,
    when given, is used instead of loading the robot the file names (see `parse_scene`).
    Raises `SceneError` for a missing file, invalid YAML or any invalid content.
    """
    path = Path(path)
    if path.suffix not in (".yaml", ".yml") and not is_file(path):
        shipped = scenes_dir() / f"{path}.yaml"
        if not is_file(shipped):
            known = sorted(p.stem for p in scenes_dir().glob("*.yaml"))
            raise SceneError("", f"unknown scene {quote(str(path))}; shipped scenes are "
                                 f"{known}, or give the path of a scene .yaml file")
        path = shipped
    try:
        data = load_yaml(path, "scene file")
    except FileProblem as exc:
        raise SceneError("", str(exc)) from None
    return scene_from_dict(data, base_dir=path.parent, name=str(path), robot=robot)


def scene_from_dict(data: Any, base_dir: Path | None = None, name: str = "<scene>",
                    robot: RobotModel | None = None) -> Scene:
    """Build a scene from its YAML mapping (docs/design.md), checking structure, types and units.

    `base_dir` resolves a relative robot config path (default: the working directory); `name`
    becomes `Scene.source`. `robot`, when given, is used instead of loading the robot again
    (e.g. one model shared by many generated scenes); the scene's ``robot`` key may then be
    omitted, and if present it must name the same robot.

    Raises one `SceneError(field, problem)` for the first problem found. The semantic checks
    that need the geometry (overlaps, a start in collision) are `physics.validation.check_scene`;
    `physics.validation.parse_scene` does both.
    """
    if not isinstance(data, Mapping):
        raise SceneError("", f"a scene must be a mapping with keys {list(_TOP_KEYS)}, got "
                             f"{_type_name(data)}")
    required = ("table", "objects", "goal") if robot is not None \
        else ("robot", "table", "objects", "goal")
    _check_keys(data, "", _TOP_KEYS, required)
    model = _resolve_robot(data.get("robot"), base_dir, robot)
    start = (model.home if data.get("start_configuration") is None
             else _vector(data["start_configuration"], "start_configuration", model.nq,
                          f"joint positions (rad), one per joint {list(model.joint_names)}"))
    table = _parse_table(data["table"])
    obstacles = _parse_list(data.get("obstacles", []), "obstacles", _parse_obstacle,
                            allow_empty=True)
    objects = _parse_list(data["objects"], "objects", _parse_object, allow_empty=False)
    _check_unique_names([("obstacles", o.name) for o in obstacles]
                        + [("objects", o.name) for o in objects])
    goal = _parse_goal(data["goal"], [o.name for o in objects])
    _check_on_table(table, obstacles, goal)
    return Scene(model, start, table, tuple(obstacles), tuple(objects), goal, source=name)


def _fail(path: str, problem: str) -> NoReturn:
    raise SceneError(path, problem)


def _join(parent: str, key: str) -> str:
    return f"{parent}.{key}" if parent else key


def _type_name(value: Any) -> str:
    if value is None:
        return "nothing (null)"
    return f"{type(value).__name__} {quote(value)}" \
        if isinstance(value, str | bool | int | float) else type(value).__name__


def _check_keys(data: Mapping, path: str, allowed: Sequence[str], required: Sequence[str],
                what: str = "") -> None:
    for key in data:
        if key not in allowed:
            _fail(_join(path, str(key)), f"unknown key{what}; allowed keys are {list(allowed)}")
    for key in required:
        if data.get(key) is None:   # absent, or present with an empty value
            _fail(_join(path, key), "missing required key")


def _mapping(value: Any, path: str, allowed: Sequence[str], required: Sequence[str],
             what: str = "") -> Mapping:
    if not isinstance(value, Mapping):
        _fail(path, f"expected a mapping with keys {list(allowed)}, got {_type_name(value)}")
    _check_keys(value, path, allowed, required, what)
    return value


def _is_number(value: Any) -> bool:
    """A real number, not a bool (YAML's yes/no/true/false); numpy scalars count."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def _not_a_number(value: Any) -> str:
    """What a non-number is, with a hint for PyYAML's reading of 1e-3 as text (YAML 1.1
    floats need a dot: 1.0e-3)."""
    described = _type_name(value)
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return described
        return f"{described} (YAML reads this as text; write it with a dot, e.g. 1.0e-3)"
    return described


def _number(value: Any, path: str, unit: str = "") -> float:
    if not _is_number(value):
        _fail(path, f"expected a number{unit}, got {_not_a_number(value)}")
    x = _float(value)
    if not math.isfinite(x):
        _fail(path, f"must be a finite number{unit}, got {quote(value)}")
    return x


def _float(value: Any) -> float:
    """float(value), inf for an integer too large for a float (400 digits)."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def _bounded(value: Any, path: str, bound: str) -> float:
    """A finite number within BOUNDS[bound]."""
    low, high, unit = BOUNDS[bound]
    x = _number(value, path, f" ({unit})" if unit else "")
    if not low <= x <= high:
        _fail(path, f"must be between {low:g} and {high:g}{' ' + unit if unit else ''} "
                    f"(scene bounds, docs/design.md), got {x:.6g}")
    return x


def _bounded_vector(value: Any, path: str, length: int, what: str, bound: str) -> np.ndarray:
    out = _vector(value, path, length, what)
    low, high, unit = BOUNDS[bound]
    bad = [float(v) for v in out if not low <= v <= high]
    if bad:
        _fail(path, f"every entry must be between {low:g} and {high:g} {unit} (scene bounds, "
                    f"docs/design.md), got {bad[0]:.6g}")
    return out






def _vector(value: Any, path: str, length: int, what: str) -> np.ndarray:
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, str | bytes) or not isinstance(value, Sequence):
        _fail(path, f"expected a list of {length} numbers: {what}; got {_type_name(value)}")
    if len(value) != length:
        _fail(path, f"expected {length} numbers: {what}; got {len(value)}")
    out = np.empty(length)
    for i, item in enumerate(value):
        if not _is_number(item):
            _fail(path, f"entry {i} is {_not_a_number(item)}; expected {length} numbers: {what}")
        out[i] = _float(item)
    if not np.all(np.isfinite(out)):
        _fail(path, f"entry {int(np.flatnonzero(~np.isfinite(out))[0])} is not a finite "
                    f"number; every entry must be one")
    return out




def _name(value: Any, path: str) -> str:
    if not isinstance(value, str) or not value.strip():
        _fail(path, f"expected a non-empty string, got {_type_name(value)}")
    return value


def _resolve_robot(value: Any, base_dir: Path | None, robot: RobotModel | None) -> RobotModel:
    if value is None and robot is not None:
        return robot
    if not isinstance(value, str):
        _fail("robot", f"expected a shipped robot name (a file in config/robots) or the path "
                       f"of a robot config .yaml, got {_type_name(value)}")
    if len(value) > 255 or "\x00" in value:
        _fail("robot", f"{quote(value)} is not a robot name or a robot config path")
    target: str | Path = value
    is_path = Path(value).suffix in (".yaml", ".yml")
    if is_path:
        target = Path(value)
        if not target.is_absolute() and base_dir is not None:
            target = Path(base_dir) / target
    if robot is not None:
        try:
            wanted = RobotConfig.from_yaml(target).name if is_path else value
        except RobotModelError as exc:
            raise SceneError("robot", str(exc)) from None
        if wanted != robot.name:
            _fail("robot", f"the scene is for robot '{wanted}' but robot '{robot.name}' was "
                           f"given")
        return robot
    try:
        return RobotModel.load(target)
    except RobotModelError as exc:
        raise SceneError("robot", str(exc)) from None


def _parse_table(value: Any) -> Table:
    data = _mapping(value, "table", _TABLE_KEYS, _TABLE_KEYS)
    return Table(
        center=_bounded_vector(data["center"], "table.center", 2, "[x, y] (m)", "table.center"),
        size=_bounded_vector(data["size"], "table.size", 2, "[size_x, size_y] (m)",
                             "table.size"),
        height=_bounded(data["height"], "table.height", "table.height"))


def _parse_list(value: Any, path: str, parse_one: Any, allow_empty: bool) -> list:
    if value is None and allow_empty:
        return []
    if isinstance(value, str | bytes) or not isinstance(value, Sequence):
        _fail(path, f"expected a list of mappings, got {_type_name(value)}")
    if not value and not allow_empty:
        _fail(path, "expected a non-empty list: a scene needs at least the goal object")
    return [parse_one(item, f"{path}[{i}]") for i, item in enumerate(value)]


def _parse_obstacle(value: Any, path: str) -> Obstacle:
    data = _mapping(value, path, _OBSTACLE_KEYS, ("name", "size", "pose"))
    name = _name(data["name"], f"{path}.name")
    shape = data.get("shape", "box")
    if shape != "box":
        _fail(f"{path}.shape", f"unknown obstacle shape {quote(shape)}; obstacles are 'box'")
    return Obstacle(name,
                    _bounded_vector(data["size"], f"{path}.size", 3, "[x, y, z] extents (m)",
                                    "obstacle extent"),
                    _vector(data["pose"], f"{path}.pose", 3, "[x, y, yaw] (m, m, rad)"))


def _parse_object(value: Any, path: str) -> MovableObject:
    if not isinstance(value, Mapping):
        _fail(path, f"expected a mapping (name, shape, pose, ...), got {_type_name(value)}")
    if "shape" not in value:
        _fail(f"{path}.shape", f"missing required key; use one of {list(OBJECT_SHAPES)}")
    shape = value["shape"]
    if shape not in OBJECT_SHAPES:
        _fail(f"{path}.shape", f"unknown shape {quote(shape)}; use one of {list(OBJECT_SHAPES)}")
    dims = ("size",) if shape == "box" else ("radius", "height")
    data = _mapping(value, path, _OBJECT_KEYS[shape], ("name", "pose") + dims,
                    what=f" for a {shape}")
    name = _name(data["name"], f"{path}.name")
    if shape == "box":
        size = _bounded_vector(data["size"], f"{path}.size", 3, "[x, y, z] extents (m)",
                               "object extent")
    else:
        radius = _bounded(data["radius"], f"{path}.radius", "object radius")
        size = np.array([2 * radius, 2 * radius,
                         _bounded(data["height"], f"{path}.height", "object extent")])
    return MovableObject(
        name=name, shape=shape, size=size,
        pose=_vector(data["pose"], f"{path}.pose", 3, "[x, y, yaw] (m, m, rad)"),
        mass=_bounded(data.get("mass", DEFAULT_MASS), f"{path}.mass", "mass"),
        support_friction=_bounded(data.get("support_friction", DEFAULT_SUPPORT_FRICTION),
                                  f"{path}.support_friction", "support_friction"),
        pusher_friction=_bounded(data.get("pusher_friction", DEFAULT_PUSHER_FRICTION),
                                 f"{path}.pusher_friction", "pusher_friction"))


def _check_on_table(table: Table, obstacles: list[Obstacle], goal: Goal) -> None:
    """Obstacles stand on the table (centre on its top); the goal region is no larger than
    the table."""
    for i, box in enumerate(obstacles):
        if not bool(table.contains(box.pose[:2])):
            _fail(f"obstacles[{i}].pose", f"obstacle '{box.name}' at ({box.pose[0]:.3g}, "
                                          f"{box.pose[1]:.3g}) is off the table; its centre "
                                          f"must lie on the table top ({table.describe()})")
    check_goal_radius(table, goal)


def check_goal_radius(table: Table, goal: Goal) -> None:
    """SceneError unless the goal radius is within BOUNDS["goal.radius"] and at most the
    table's larger side: what loading a scene checks, for a goal given later (a node's
    parameter, an action goal), so that no later step (a raced tree's worker re-reading the
    scene) meets it first."""
    _bounded(goal.radius, "goal.radius", "goal.radius")
    largest = float(max(table.size))
    if goal.radius > largest:
        _fail("goal.radius", f"{goal.radius:g} m is larger than the table ({largest:g} m); the "
                             f"goal region must be at most the table's size")


def _check_unique_names(entries: list[tuple[str, str]]) -> None:
    seen: dict[str, str] = {}
    counters = {"obstacles": 0, "objects": 0}
    for group, name in entries:
        where = f"{group}[{counters[group]}]"
        counters[group] += 1
        if name in seen:
            _fail(f"{where}.name", f"duplicate name '{name}' (already used by {seen[name]}); "
                                   f"obstacle and object names must be unique")
        seen[name] = where


def _parse_goal(value: Any, object_names: list[str]) -> Goal:
    data = _mapping(value, "goal", _GOAL_KEYS, ("object", "position"))
    name = _name(data["object"], "goal.object")
    if name not in object_names:
        _fail("goal.object", f"no object named '{name}'; objects are {object_names}")
    return Goal(name, _vector(data["position"], "goal.position", 2, "[x, y] (m)"),
                _bounded(data.get("radius", DEFAULT_GOAL_RADIUS), "goal.radius", "goal.radius"))
