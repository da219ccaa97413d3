"""The benchmark of King et al. 2015, §V, and a harder set beside it: seeded random scenes,
each planner run on each scene with several seeds under a time budget.

Two scene sets (`SCENE_SETS`), each 5 scenes for each number of movable objects 1 ... 7:

- ``fixed`` (``n<M>_s<i>``, config/benchmark/scenes): the paper's set (§V: "35 randomly
  generated scenes ... between 1 and 7 movable objects in the robot's reachable workspace ...
  the same goal object ... the starting pose of the goal object is randomly selected. The goal
  region is placed in the same location across all scenes"). Every scene has the same goal
  object (`GOAL_OBJECT`, a box) and the same goal region (`GOAL_POSITION`, `GOAL_RADIUS`). It is
  kept as it is: the record of where we were.
- ``varied`` (``v<M>_s<i>``, config/benchmark/varied): what a user meets. The goal object is
  drawn like the clutter (box or cylinder, size, height, mass, frictions), the goal point
  anywhere in the reachable workspace on both sides of the arm, and in about half of the scenes
  with other objects (`BLOCKER_SHARE`) one of them stands between the goal object and its goal.

The goal object starts at least `MIN_GOAL_OFFSET` from the goal point; the other objects are
boxes and cylinders of random size, mass and frictions (`BOX_SIDE`, `CYLINDER_RADIUS`, `HEIGHT`,
`MASS`, ...) at random poses. Every object lies in the arm's reach (`in_workspace`: an annulus
about the base that the tool reaches on the pushing plane, wholly on the table); scenes are
drawn by rejection until `scene.parse_scene` accepts them (no overlaps, start configuration
collision-free). `generate_scene(M, i, seed, scene_set=...)` is a pure function of its
arguments: each scene draws from its own generator, so the scenes do not depend on each other.
The files are committed and a test checks they equal a fresh generation.

A trial is one (scene, planner, seed, time limit): the product's default plan request for it
(`trial_request`: raced trees, shortcutting, robust selection, changed by the command's --set)
through `pipeline.plan_scene`, then a replay of the path through the physics to find which arm
links pushed objects, then the plan executed in MuJoCo (ideal and servo arm). `run_trials` runs
the trials as Ray tasks (`engine`), appends one CSV row per finished trial (complete rows only,
flushed at once), skips trials already in the CSV (resumable), and `summarize` turns the rows
into the JSON summary, headed by the end-to-end figure: the share of requests whose plan,
executed open loop with the servo arm, puts the goal object in its region with nothing toppled.
"""

from __future__ import annotations

import csv
import io
import logging
import math
import os
import sys
import textwrap
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.resources import config_dir, default_robot, default_start
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.physics.validation import parse_scene
from rearrangement_planner.planning.requests.registry import PLANNERS

log = logging.getLogger(__name__)

# --------------------------------------------------------------------------------------------
# The scene set
# --------------------------------------------------------------------------------------------

SCENE_SET_SEED = 0
OBJECT_COUNTS = tuple(range(1, 8))          # movable objects per scene, goal object included
SCENES_PER_COUNT = 5

# The table of config/scenes/default.yaml (a test keeps them equal); its robot and start
# configuration are read from it (`default_robot`, `default_start`).
TABLE = {"center": (0.55, 0.0), "size": (0.8, 1.2), "height": 0.0}  # m

GOAL_POSITION = (0.55, -0.20)   # m, the goal point of every scene
GOAL_RADIUS = 0.10              # m (King et al. 2015, §V: "a goal region of radius 0.1m")
MIN_GOAL_OFFSET = 0.25          # m, least distance of the goal object's start from the goal point
GOAL_OBJECT = {"name": "target", "shape": "box", "size": (0.06, 0.08, 0.12), "mass": 0.4,
               "support_friction": 0.4, "pusher_friction": 0.3}   # the same in every scene

# The workspace: object centres at a distance from the base (the z axis of the base frame) in
# [REACH_MIN, REACH_MAX] and at least WORKSPACE_MIN_X in front of it, and the whole footprint on
# the table. The default robot's tool reaches the pushing plane (6 cm above the table) out to
# about 0.88 m; REACH_MAX leaves room for the hand to get behind an object and push it
# back towards the base. A test checks the tool reaches every object's centre by IK.
REACH_MIN = 0.30                # m
REACH_MAX = 0.72                # m
WORKSPACE_MIN_X = 0.25          # m

# Clutter objects: uniform in these ranges (m, kg, dimensionless friction coefficients).
BOX_SIDE = (0.04, 0.10)
CYLINDER_RADIUS = (0.025, 0.05)
HEIGHT = (0.09, 0.16)           # taller than the hand's underside, so the arm pushes, not presses
MASS = (0.2, 0.8)
SUPPORT_FRICTION = (0.3, 0.6)   # object-table mu_s
PUSHER_FRICTION = (0.2, 0.5)    # arm-object mu_c
MIN_GAP = 0.01                  # m, least gap between the footprint circles of two objects
MAX_DRAWS = 1000                # draws per scene before giving up (never reached in practice)
DECIMALS = 3                    # values are written rounded to mm / mrad
BLOCKER_SHARE = 0.5             # varied set: share of scenes with others with a blocker placed
BLOCKER_ALONG = (0.35, 0.65)    # where along the start-goal segment the blocker stands (share)
BLOCKER_ACROSS = 0.03           # m, its largest offset across that segment


@dataclass(frozen=True)
class SceneSet:
    """One benchmark scene set: its scenes ``<prefix><M>_s<i>`` in `folder` (under
    config/benchmark/), drawn by `varied_goal` rules or the paper's fixed goal."""

    name: str
    prefix: str
    folder: str
    varied_goal: bool
    about: str

    def scene_name(self, objects: int, index: int) -> str:
        """``n3_s2``: the scene with 3 movable objects, third of its group."""
        return f"{self.prefix}{objects}_s{index}"

    def directory(self) -> Path:
        """The folder of the set's committed files (in the checkout or installed package)."""
        return config_dir() / "benchmark" / self.folder

    def names(self, quick: bool = False) -> list[str]:
        """Scene names in set order; `quick`: the first two of each object count."""
        per_count = 2 if quick else SCENES_PER_COUNT
        return [self.scene_name(n, i) for n in OBJECT_COUNTS for i in range(per_count)]


FIXED = SceneSet(
    "fixed", "n", "scenes", False,
    "of the 35-scene set (King et al. 2015, §V; docs/benchmark.md): {count}. The goal object "
    "`target` (the same box in every scene) starts at random, at least {offset:g} m from the "
    "goal point; the goal region is the same in every scene.")
VARIED = SceneSet(
    "varied", "v", "varied", True,
    "of the varied set (docs/benchmark.md): {count}. The goal object `target` is drawn like "
    "the others (box or cylinder, size, mass, frictions) and starts at random, the goal point "
    "anywhere in reach on either side of the arm, at least {offset:g} m from it.{blocker}")
SCENE_SETS = {s.name: s for s in (FIXED, VARIED)}
"""The benchmark's scene sets by name (`rearrangement-bench run --scene-set`)."""


def scene_name(objects: int, index: int) -> str:
    """``n3_s2``: the fixed set's scene with 3 movable objects, third of its group."""
    return FIXED.scene_name(objects, index)


def scene_set_dir() -> Path:
    """``config/benchmark/scenes`` (the fixed set) of the checkout or the installed package."""
    return FIXED.directory()


def scene_set_of(name: str) -> SceneSet | None:
    """The set a scene name (``v3_s2``) belongs to, by its prefix; None if none."""
    for scene_set in SCENE_SETS.values():
        rest = name[len(scene_set.prefix):]
        if name.startswith(scene_set.prefix) and "_s" in rest \
                and rest.replace("_s", "", 1).isdigit():
            return scene_set
    return None


def _round(value: float) -> float:
    return float(round(float(value), DECIMALS)) + 0.0   # + 0.0 turns -0.0 into 0.0


def _footprint_radius(entry: dict) -> float:
    if entry["shape"] == "cylinder":
        return float(entry["radius"])
    return 0.5 * math.hypot(entry["size"][0], entry["size"][1])


def in_workspace(x: float, y: float, footprint_radius: float) -> bool:
    """Whether an object centred at (x, y) (m, base frame) with this footprint radius lies in
    the benchmark workspace: within reach of the arm and wholly on the table."""
    r = math.hypot(x, y)
    lo = np.asarray(TABLE["center"]) - 0.5 * np.asarray(TABLE["size"]) + footprint_radius
    hi = np.asarray(TABLE["center"]) + 0.5 * np.asarray(TABLE["size"]) - footprint_radius
    return (REACH_MIN <= r <= REACH_MAX and x >= WORKSPACE_MIN_X
            and bool(lo[0] <= x <= hi[0]) and bool(lo[1] <= y <= hi[1]))


def _draw_position(rng: np.random.Generator, footprint_radius: float,
                   accept: Callable[[float, float], bool]) -> tuple[float, float] | None:
    """A position (rounded) uniform over the workspace and accepted by `accept`, by rejection
    from the workspace's bounding box; None after MAX_DRAWS draws."""
    for _ in range(MAX_DRAWS):
        x = _round(rng.uniform(WORKSPACE_MIN_X, REACH_MAX))
        y = _round(rng.uniform(-REACH_MAX, REACH_MAX))
        if in_workspace(x, y, footprint_radius) and accept(x, y):
            return x, y
    return None


def _draw_clutter(rng: np.random.Generator, k: int, name: str | None = None) -> dict:
    """Object k: a box or cylinder (equally likely; named ``box<k>`` / ``cylinder<k>``, or
    `name`) of random size, mass and frictions; no pose yet."""
    if rng.random() < 0.5:
        entry: dict[str, Any] = {"name": name or f"box{k}", "shape": "box",
                                 "size": [_round(rng.uniform(*BOX_SIDE)),
                                          _round(rng.uniform(*BOX_SIDE)),
                                          _round(rng.uniform(*HEIGHT))]}
    else:
        entry = {"name": name or f"cylinder{k}", "shape": "cylinder",
                 "radius": _round(rng.uniform(*CYLINDER_RADIUS)),
                 "height": _round(rng.uniform(*HEIGHT))}
    entry["mass"] = _round(rng.uniform(*MASS))
    entry["support_friction"] = _round(rng.uniform(*SUPPORT_FRICTION))
    entry["pusher_friction"] = _round(rng.uniform(*PUSHER_FRICTION))
    return entry


def _blocker_position(rng: np.random.Generator, start: tuple[float, float],
                      goal: np.ndarray, radius: float,
                      clear: Callable[[float, float, float], bool]) -> tuple[float, float] | None:
    """A position on the way from the goal object's `start` to the `goal` point (a share
    BLOCKER_ALONG of the way, up to BLOCKER_ACROSS to either side), in the workspace and
    `clear` of the objects placed; None if the drawn one is not."""
    a = np.asarray(start, dtype=float)
    along = rng.uniform(*BLOCKER_ALONG)
    across = rng.uniform(-BLOCKER_ACROSS, BLOCKER_ACROSS)
    direction = (goal - a) / max(float(np.linalg.norm(goal - a)), 1e-9)
    x, y = a + along * (goal - a) + across * np.array([-direction[1], direction[0]])
    x, y = _round(x), _round(y)
    return (x, y) if in_workspace(x, y, radius) and clear(x, y, radius) else None


def _draw_scene(rng: np.random.Generator, objects: int, scene_set: SceneSet = FIXED,
                blocked: bool = False) -> dict | None:
    """One candidate scene mapping (docs/design.md), or None if the objects did not fit;
    `blocked` (varied set): object 1 stands on the goal object's way to its goal."""
    entries: list[dict] = []
    placed: list[tuple[float, float, float]] = []   # x, y, footprint radius

    def clear(x: float, y: float, radius: float) -> bool:
        return all(math.hypot(x - px, y - py) >= radius + pr + MIN_GAP for px, py, pr in placed)

    if scene_set.varied_goal:
        target = _draw_clutter(rng, 0, name=str(GOAL_OBJECT["name"]))
        goal_xy = _draw_position(rng, _footprint_radius(target), lambda x, y: True)
        if goal_xy is None:
            return None
        goal = np.asarray(goal_xy)
    else:
        target = {key: (list(v) if isinstance(v, tuple) else v)
                  for key, v in GOAL_OBJECT.items()}
        goal, blocked = np.asarray(GOAL_POSITION), False
    for k in range(objects):
        entry = target if k == 0 else _draw_clutter(rng, k)
        radius = _footprint_radius(entry)
        if k == 0:
            xy = _draw_position(rng, radius, lambda x, y: math.hypot(x - goal[0], y - goal[1])
                                >= MIN_GOAL_OFFSET)
        elif k == 1 and blocked:
            xy = None
            for _ in range(50):
                xy = _blocker_position(rng, (placed[0][0], placed[0][1]), goal, radius, clear)
                if xy is not None:
                    break
        else:
            def accept(x: float, y: float, r: float = radius) -> bool:
                return clear(x, y, r)

            xy = _draw_position(rng, radius, accept)
        if xy is None:
            return None
        yaw = _round(rng.uniform(-math.pi, math.pi))
        pose = {"pose": [xy[0], xy[1], yaw]}
        # keys in the order of the scene format: name, shape, dimensions, pose, mass, frictions
        dims = ("size",) if entry["shape"] == "box" else ("radius", "height")
        entries.append({"name": entry["name"], "shape": entry["shape"],
                        **{d: entry[d] for d in dims}, **pose,
                        **{key: entry[key] for key in ("mass", "support_friction",
                                                       "pusher_friction")}})
        placed.append((xy[0], xy[1], radius))
    return {
        "robot": default_robot(),
        "start_configuration": default_start(),
        "table": {key: (list(v) if isinstance(v, tuple) else v) for key, v in TABLE.items()},
        "objects": entries,
        "goal": {"object": GOAL_OBJECT["name"], "position": [float(v) for v in goal],
                 "radius": GOAL_RADIUS},
        **({"blocked": True} if blocked else {}),
    }


def generate_scene(objects: int, index: int, seed: int = SCENE_SET_SEED,
                   robot: RobotModel | None = None, scene_set: SceneSet = FIXED) -> dict:
    """The scene mapping of scene ``<prefix><objects>_s<index>`` of `scene_set` drawn with
    `seed`: candidates are drawn until `parse_scene` accepts one (rejection sampling). A
    varied scene with a blocker says so (key ``blocked``, kept out of the scene file's own
    keys: `scene_file_text` writes it as a comment)."""
    if objects < 1:
        raise ValueError(f"a scene needs at least the goal object, got objects={objects}")
    # The fixed set's generators are seeded (seed, M, i) as when it was made; the varied
    # set's streams carry one more word, so that no scene repeats another set's draws.
    key = [seed, objects, index] + ([1] if scene_set.varied_goal else [])
    rng = np.random.default_rng(key)
    blocked = scene_set.varied_goal and objects > 1 and bool(rng.random() < BLOCKER_SHARE)
    robot = robot or RobotModel.load(default_robot())
    for _ in range(MAX_DRAWS):
        data = _draw_scene(rng, objects, scene_set, blocked)
        if data is None:
            continue
        try:
            parse_scene({k: v for k, v in data.items() if k != "blocked"},
                        name=scene_set.scene_name(objects, index), robot=robot)
        except RearrangementError:
            continue
        return data
    raise RuntimeError(f"no valid scene with {objects} objects in {MAX_DRAWS} draws; the "
                       f"workspace is too small for them")


def _number(value: float) -> str:
    return repr(float(value))


def _flow(value: Any) -> str:
    """A value in YAML flow style: numbers as Python reprs, lists in brackets."""
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_flow(v) for v in value) + "]"
    if isinstance(value, float | int) and not isinstance(value, bool):
        return _number(value)
    return str(value)


def scene_file_text(name: str, data: dict, seed: int = SCENE_SET_SEED,
                    scene_set: SceneSet = FIXED) -> str:
    """The scene file of `data`: a header comment saying how it was made, then the scene in
    the style of config/scenes/ (one flow mapping per object)."""
    objects = data["objects"]
    others = len(objects) - 1
    count = f"{len(objects)} movable object{'s' if len(objects) > 1 else ''}"
    blocker = (f" `{objects[1]['name']}` stands on the way from the goal object to the goal."
               if data.get("blocked") else "")
    about = (f"Benchmark scene {name} "
             + scene_set.about.format(count=count, offset=MIN_GOAL_OFFSET, blocker=blocker)
             + (" The other objects are boxes and cylinders of random size, mass and "
                "frictions." if others else "")
             + " Every object stands in the arm's reach, clear of the others. Generated by "
             f"`rearrangement-bench generate --seed {seed}"
             + ("" if scene_set is FIXED else f" --scene-set {scene_set.name}")
             + "` (rearrangement_planner/tools/bench/trials.py); do not edit: "
               "test/tools/test_benchmark.py checks that the files equal a fresh generation.")
    lines = [
        *textwrap.wrap(about, width=98, initial_indent="# ", subsequent_indent="# ",
                       break_on_hyphens=False),
        f"robot: {data['robot']}",
        f"start_configuration: {_flow(data['start_configuration'])}",
        "table: {" + ", ".join(f"{k}: {_flow(v)}" for k, v in data["table"].items()) + "}",
        "objects:",
    ]
    for entry in objects:
        head = ", ".join(f"{k}: {_flow(entry[k])}" for k in entry
                         if k not in ("mass", "support_friction", "pusher_friction"))
        tail = ", ".join(f"{k}: {_flow(entry[k])}" for k in ("mass", "support_friction",
                                                              "pusher_friction"))
        lines += [f"  - {{{head},", f"     {tail}}}"]
    goal = data["goal"]
    lines.append(f"goal: {{object: {goal['object']}, position: {_flow(goal['position'])}, "
                 f"radius: {_flow(goal['radius'])}}}")
    return "\n".join(lines) + "\n"


def generate_scene_set(seed: int = SCENE_SET_SEED,
                       scene_set: SceneSet = FIXED) -> dict[str, str]:
    """{scene name: scene file text} of `scene_set` drawn with `seed`, in set order."""
    robot = RobotModel.load(default_robot())
    texts = {}
    for objects in OBJECT_COUNTS:
        for index in range(SCENES_PER_COUNT):
            name = scene_set.scene_name(objects, index)
            texts[name] = scene_file_text(
                name, generate_scene(objects, index, seed, robot, scene_set), seed, scene_set)
    return texts


def write_scene_set(out: Path, seed: int = SCENE_SET_SEED,
                    scene_set: SceneSet = FIXED) -> list[Path]:
    """Write `scene_set` drawn with `seed` into `out` (created if needed); returns the files.
    Earlier scene files of the set's naming scheme that are not in the set are removed."""
    out.mkdir(parents=True, exist_ok=True)
    texts = generate_scene_set(seed, scene_set)
    for stale in out.glob(f"{scene_set.prefix}*_s*.yaml"):
        if stale.stem not in texts:
            stale.unlink()
    paths = []
    for name, text in texts.items():
        path = out / f"{name}.yaml"
        path.write_text(text)
        paths.append(path)
    return paths


def set_scene_names(quick: bool = False, scene_set: SceneSet = FIXED) -> list[str]:
    """Scene names of `scene_set` in set order; `quick`: the first two of each object count."""
    return scene_set.names(quick)


# --------------------------------------------------------------------------------------------
# Trials
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Trial:
    """One planner run: `scene` is the scene's name (file stem), `path` its file."""

    scene: str
    path: str
    objects: int
    planner: str
    seed: int
    time_limit: float
    robot: str = ""
    """The arm that plans (a shipped robot name or a robot config path); "": the scene's own."""
    perturbed: int = 5
    """Perturbed MuJoCo executions of a solved plan (servo arm; `PERTURBED_EXECUTIONS`,
    defined below, is the same default)."""
    replan: int = 0
    """Re-plans of the closed loop (`execution.closed_loop`) after each execution that misses
    (nominal and perturbed); 0: open loop only."""
    divergence_bound: float = 0.0
    """The closed loop's watch (`ExecutionOptions.divergence_bound`), m; 0: off."""

    @property
    def key(self) -> tuple[str, str, int, float]:
        """What identifies a trial in the CSV (resume skips trials whose key is there)."""
        return self.scene, self.planner, self.seed, self.time_limit


def make_trials(scene_files: Sequence[Path], planners: Sequence[str], seeds: Sequence[int],
                time_limit: float, objects: dict[str, int], robot: str = "",
                perturbed: int = 5, replan: int = 0,
                divergence_bound: float = 0.0) -> list[Trial]:
    """Every (scene, planner, seed) at `time_limit`, scene-major; `objects` maps a scene name
    to its number of movable objects; `robot` plans them all ("": each scene's own);
    `perturbed` executions of each solved plan in perturbed MuJoCo worlds, each closed with up
    to `replan` re-plans (watched with `divergence_bound`)."""
    return [Trial(p.stem, str(p), objects[p.stem], planner, seed, float(time_limit), robot,
                  perturbed, replan, divergence_bound)
            for p in scene_files for planner in planners for seed in seeds]


def load_trial_scene(path: str | Path, robot: str = ""):
    """A benchmark scene, with `robot` in place of its own arm (starting at that arm's home
    configuration, as the scene's start configuration is its own arm's)."""
    from rearrangement_planner.physics.validation import load_scene, parse_scene

    if not robot:
        return load_scene(path)
    import yaml

    path = Path(path)
    data = yaml.safe_load(path.read_text())
    data["robot"] = robot
    data.pop("start_configuration", None)
    return parse_scene(data, base_dir=path.parent, name=str(path))


CSV_COLUMNS = (
    "scene", "objects", "planner", "seed", "time_limit", "solved", "outcome", "plan_time_s",
    "iterations", "tree_size", "propagation_steps", "goal_distance_m",
    "path_length_rad_before", "path_length_rad_after",
    "ee_path_length_m_before", "ee_path_length_m_after",
    "object_displacement_m_before", "object_displacement_m_after",
    "shortcut_time_s", "pushing_links", "non_goal_objects_moved",
    "goal_start_distance_m", "goal_push_path_m", "goal_turn_rad",
    "executed_ideal", "executed_servo", "executed_goal_distance_m", "executed_toppled",
    "executed_toppled_goal", "trial_wall_s", "ray_node", "robot",
    "robustness", "executed_object_contacts", "perturbed_reached", "perturbed_trials",
    "trajectory_s", "replan", "replan_reached", "replans_made", "time_to_goal_s",
    "perturbed_replan_reached", "closed_loop_endings",
    "search_s", "shortcuts_s", "rollouts_s", "timing_s", "warm_up_s", "candidates",
    "candidate_searches",
    "executed_pybullet", "executed_pybullet_goal_distance_m", "executed_pybullet_toppled",
    "executed_both", "perturbed_reached_pybullet", "perturbed_reached_both",
    "judge_s", "model_robustness", "judged_nominal", "judged_planner", "judged_mends",
    "judged_candidates",
)
"""trials.csv: one row per trial. goal_distance_m: the goal object's final distance from the
goal point (solved) or the least distance reached (not solved). *_before / *_after: of the path
before and after shortcutting (equal when not shortcut; empty when not solved). pushing_links:
the arm links that moved objects along the final path, ';'-separated (docs/design.md "Planners").
non_goal_objects_moved: how many objects other than the goal object the path moves (> 1 mm).
executed_ideal / executed_servo: 1 when the solved plan, executed open loop in MuJoCo
(`world3d.execution`, ideal / servo-driven arm), reaches the goal region with nothing
toppled, else 0 (empty when not solved); executed_goal_distance_m: the goal object's final
distance there (ideal arm); executed_toppled: how many objects toppled in the servo arm's
execution; executed_toppled_goal: 1 when the goal object is one of them.
goal_start_distance_m: the goal object's start distance from the goal point; goal_push_path_m
and goal_turn_rad: how far its centre travels and how much it turns (sum of |Δyaw|) along the
final path (empty when not solved).
trial_wall_s: the whole trial (planning, shortcutting, timing, replay) on the wall clock.
ray_node: the Ray node the trial ran on (its node id's first 12 hex digits, `engine`).
robot: the arm that planned (the robot config's name).
robustness: the returned plan's robustness score (its share of perturbed rollouts in the
planner's physics that reach the goal; empty when not measured).
executed_object_contacts: how many pairs of objects touched in the servo arm's execution.
perturbed_reached / perturbed_trials: of the executions (`--perturbed`, PERTURBED_EXECUTIONS by
default) with the servo arm in
MuJoCo worlds perturbed as `model.perturbation.Perturbation` draws them (seeded by the trial's
seed), how many reached the goal with nothing toppled.
trajectory_s: the solved plan's trajectory duration (s).
replan: the re-plans allowed (`--replan`; 0 or empty: open loop only, and the next four are
empty). replan_reached: 1 when the closed loop (`execution.closed_loop`, servo arm, nominal
world) reached the goal with nothing toppled within that many re-plans; replans_made: the
re-plans it made; time_to_goal_s: all its plan times, retreats and trajectories (trajectory
time; reached or not); perturbed_replan_reached: of the perturbed worlds, how many the closed
loop reached (each loop's first execution is that world's open-loop execution).
With --divergence-bound the closed loop's executions are watched (`ExecutionOptions`): its
first executions are made again, watched, so they may differ from the open-loop columns.
closed_loop_endings: how each attempt ended (`execution.closed_loop`), '>'-joined per loop, the
nominal loop first, then the perturbed ones, ';'-separated ("missed>reached;toppled").
search_s, shortcuts_s, rollouts_s, timing_s, warm_up_s: the request's wall time by phase
(`pipeline.Phases`: every candidate's search with its raced trees, every shortcut, the
robustness rollouts, trajectory timing, loading the compiled core); candidates: the searches
it made. candidate_searches: robust selection's candidates in order, space-separated, each
iterations:robustness:goal travel (m):search seconds (`pipeline.Phases.log_candidate`).
executed_pybullet: 1 when the solved plan, executed open loop with the servo arm in PyBullet
(`execution.pybullet_check`, an engine the planner does not use), reaches the goal with nothing
toppled; executed_pybullet_goal_distance_m and executed_pybullet_toppled as in MuJoCo;
executed_both: 1 when it reached in both engines (MuJoCo's servo arm and PyBullet), the
headline's "reached". perturbed_reached_pybullet: of the same perturbed worlds executed in
PyBullet, how many reached; perturbed_reached_both: how many reached in both engines.
judge_s: the 3D judge's own wall time in the request (`pipeline.Phases.judge`);
model_robustness: the quasistatic rollouts' robustness of the first candidate when the 3D
judge gave `robustness`; judged_nominal: 1 when the answer reached in the judge's nominal 3D
world; judged_planner: the planner that found the answer; judged_mends: the re-plans it
splices; judged_candidates: every judged candidate, '|'-separated (`judging.Judging.log`).
A CSV written before a column existed is read with that column empty."""

PERTURBED_EXECUTIONS = 5
"""Perturbed MuJoCo executions (servo arm) per solved trial, by default (docs/benchmark.md)."""

MOVED_TOLERANCE = 1e-3   # m, an object counts as moved beyond this distance from its start


def goal_push(states, goal_index: int) -> tuple[float, float]:
    """How far object `goal_index`'s centre travels along `states` (m) and how much it turns
    (rad, the sum of |Δyaw|)."""
    poses = np.array([s.objects[goal_index] for s in states])
    steps = np.diff(poses, axis=0)
    turns = np.arctan2(np.sin(steps[:, 2]), np.cos(steps[:, 2]))
    return float(np.hypot(steps[:, 0], steps[:, 1]).sum()), float(np.abs(turns).sum())


def pushing_links(physics, states) -> set[str]:
    """Arm links that push an object somewhere along `states` (consecutive states one physics
    step apart): each step is replayed from its planned state with `Physics.step`, and the links
    of the steps that moved an object are collected (`StepResult.pushing_links`).

    DARRT's Push primitive carries the object rigidly at the tool instead; for its paths the
    replay names the links that meet the object as the arm moves on from each planned state
    (the hand, as the primitive intends)."""
    links: set[str] = set()
    for a, b in zip(states[:-1], states[1:], strict=True):
        if np.array_equal(a.objects, b.objects):
            continue   # nothing moved in this step
        result = physics.step(a, b.q)
        if result.moved_objects:
            links |= result.pushing_links
    return links


def objects_moved(scene, states, skip: int | None = None) -> list[str]:
    """Names of the objects (except object index `skip`) that leave their start by more than
    MOVED_TOLERANCE somewhere along `states`."""
    start = states[0].objects[:, :2]
    far = np.zeros(len(scene.objects), dtype=bool)
    for s in states:
        far |= np.hypot(*(s.objects[:, :2] - start).T) > MOVED_TOLERANCE
    return [o.name for i, o in enumerate(scene.objects) if far[i] and i != skip]


def _num(value: float | None, digits: int = 6) -> str:
    return "" if value is None else repr(round(float(value), digits))


def planner_variant(label: str) -> tuple[str, list[str]]:
    """A `--planners` entry: PLANNER, or PLANNER:NAME=VALUE[,NAME=VALUE ...], a planner with
    settings of its own (`slice-rrt:oracle=hand`); the whole label names its trials' rows."""
    name, _, rest = label.partition(":")
    return name, [item for item in rest.split(",") if item]


def variant_settings(label: str, settings: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """The planner of `label` and the settings of its request: `settings` (the command's
    --set), then the label's own. ValueError names a bad setting."""
    from rearrangement_planner.model.settings import parse_assignments
    from rearrangement_planner.planning.requests.request import request_settings

    name, items = planner_variant(label)
    return name, {**settings, **dict(parse_assignments(request_settings(), items))}


def trial_request(trial: Trial, settings: dict[str, Any]):
    """The plan request of a trial: the product's default request (`planning.requests.request`) with
    `settings` (the command's --set), the planner label's settings, and the trial's planner,
    time limit and seed."""
    from rearrangement_planner.planning.requests.request import PlanRequest

    name, values = variant_settings(trial.planner, settings)
    return PlanRequest.from_settings(load_trial_scene(trial.path, trial.robot), name,
                                     {**values, "time_limit": trial.time_limit},
                                     seed=trial.seed)


def run_trial(trial: Trial, settings: dict[str, Any]) -> dict:
    """Plan one trial (`trial_request`) and measure it: the CSV row (column -> text) of
    `CSV_COLUMNS`."""
    from rearrangement_planner.planning.requests.pipeline import plan_scene

    t0 = time.monotonic()
    request = trial_request(trial, settings)
    scene = request.scene
    output = plan_scene(request)
    result = output.result
    row: dict[str, Any] = {
        "scene": trial.scene, "objects": str(trial.objects), "planner": trial.planner,
        "seed": str(trial.seed), "time_limit": repr(trial.time_limit),
        "solved": str(int(result.solved)), "outcome": result.outcome.value,
        "plan_time_s": _num(result.plan_time, 3), "iterations": str(result.iterations),
        "tree_size": str(result.tree_size), "propagation_steps": str(result.propagation_steps)}
    before = after = None
    links: set[str] = set()
    moved: list[str] = []
    if result.solved:
        final = result.states[-1].objects[scene.goal_index, :2]
        row["goal_distance_m"] = _num(scene.goal.distance(final))
        after = output.metrics
        before = output.metrics_before_shortcut or after
        links = pushing_links(_replay_physics(scene), result.states)
        moved = objects_moved(scene, result.states, skip=scene.goal_index)
        path, turn = goal_push(result.states, scene.goal_index)
        row["goal_push_path_m"], row["goal_turn_rad"] = _num(path), _num(turn)
    else:
        row["goal_distance_m"] = _num(result.best_goal_distance)
        row["goal_push_path_m"] = row["goal_turn_rad"] = ""
    for field in ("path_length_rad", "ee_path_length_m", "object_displacement_m"):
        row[f"{field}_before"] = _num(getattr(before, field) if before else None)
        row[f"{field}_after"] = _num(getattr(after, field) if after else None)
    row["goal_start_distance_m"] = _num(scene.goal.distance(
        scene.object_poses[scene.goal_index, :2]))
    row["shortcut_time_s"] = _num(output.shortcut_time, 3)
    phases = output.phases
    row.update(search_s=_num(phases.search, 3), shortcuts_s=_num(phases.shortcut, 3),
               rollouts_s=_num(phases.rollouts, 3), timing_s=_num(phases.timing, 3),
               warm_up_s=_num(phases.warm_up, 3), candidates=str(phases.candidates),
               candidate_searches=" ".join(phases.searches))
    row["pushing_links"] = ";".join(sorted(links))
    row["non_goal_objects_moved"] = str(len(moved)) if result.solved else ""
    executions = _executions(output, trial.seed, trial.perturbed)
    row.update(_executed(executions, scene.objects[scene.goal_index].name))
    row.update(_closed_loop(request, output, trial, executions))
    row["robustness"] = _num(output.robustness)
    row["model_robustness"] = _num(output.model_robustness)
    row["judge_s"] = _num(phases.judge, 3)
    judged = output.judged
    row.update(judged_nominal=str(int(judged.reached)) if judged else "",
               judged_planner=judged.planner if judged else "",
               judged_mends=str(judged.mends) if judged else "",
               judged_candidates="|".join(judged.candidates) if judged else "")
    row["trajectory_s"] = _num(output.trajectory.duration if output.trajectory else None, 3)
    if result.solved and output.trajectory is not None:
        row[PLAN_KEY] = {"arm_path": np.array([s.q for s in result.states]),
                         "times": output.trajectory.times,
                         "positions": output.trajectory.positions,
                         "scene_path": trial.path, "robot": trial.robot}
    row["trial_wall_s"] = _num(time.monotonic() - t0, 3)
    row["ray_node"] = ""                       # the engine's to fill in
    row["robot"] = scene.robot.name
    return row


PLAN_KEY = "_plan"
"""The row key (not a column) that carries a solved trial's plan to the driver, which saves it
as plans/<scene>__<planner>__<seed>.npz beside trials.csv (`save_plan`): the planned arm path,
the timed trajectory, the scene file and the arm it was planned with (`Trial.path`,
`Trial.robot`), so that its rollouts and executions can be replayed later."""


def plan_file(folder: Path, row: dict) -> Path:
    """Where `save_plan` keeps the plan of trial `row` in `folder`."""
    label = row["planner"].replace(":", "_").replace("=", "-").replace(",", "_")
    return folder / f"{row['scene']}__{label}__{row['seed']}.npz"


def save_plan(folder: Path, row: dict, plan: dict[str, Any]) -> Path:
    """Write a trial's plan (`PLAN_KEY`) into `folder`; returns the file."""
    folder.mkdir(parents=True, exist_ok=True)
    path = plan_file(folder, row)
    np.savez_compressed(path, arm_path=plan["arm_path"], times=plan["times"],
                        positions=plan["positions"], scene_path=np.array(plan["scene_path"]),
                        robot=np.array(plan["robot"]))
    return path


def _executions(output, seed: int, perturbed_executions: int):
    """The solved plan played open loop in MuJoCo, both arms, and in PyBullet, then
    `perturbed_executions` times with the servo arm in perturbed worlds drawn from `seed`, in
    both engines: ({arm or 'pybullet': report}, MuJoCo's PerturbedReport, PyBullet's), or None
    when not solved."""
    if output.trajectory is None:
        return None
    from rearrangement_planner.execution.pybullet_check import (
        check_execution_pybullet,
        check_perturbed_pybullet,
    )
    from rearrangement_planner.world3d.execution import check_execution, check_perturbed
    from rearrangement_planner.world3d.mujoco_model import ExecutionOptions

    reports = {arm: check_execution(output.scene, output.trajectory, None,
                                    ExecutionOptions(arm=arm)) for arm in ("ideal", "servo")}
    reports["pybullet"] = check_execution_pybullet(output.scene, output.trajectory)
    perturbed = check_perturbed(output.scene, output.trajectory, perturbed_executions, seed,
                                ExecutionOptions(arm="servo"))
    return reports, perturbed, check_perturbed_pybullet(output.scene, output.trajectory,
                                                        perturbed_executions, seed)


def _executed(executions, goal_name: str) -> dict[str, str]:
    """The executed_* and perturbed_* columns of `_executions` (`goal_name`: the goal object's)."""
    if executions is None:
        return {"executed_ideal": "", "executed_servo": "", "executed_goal_distance_m": "",
                "executed_toppled": "", "executed_toppled_goal": "",
                "executed_object_contacts": "",
                "perturbed_reached": "", "perturbed_trials": "", "executed_pybullet": "",
                "executed_pybullet_goal_distance_m": "", "executed_pybullet_toppled": "",
                "executed_both": "", "perturbed_reached_pybullet": "",
                "perturbed_reached_both": ""}
    reports, perturbed, bullet = executions
    pybullet = reports["pybullet"]
    both = sum(a.reached and b.reached
               for a, b in zip(perturbed.reports, bullet.reports, strict=True))
    return {"executed_pybullet": str(int(pybullet.reached)),
            "executed_pybullet_goal_distance_m": _num(pybullet.goal_distance_m),
            "executed_pybullet_toppled": str(len(pybullet.toppled)),
            "executed_both": str(int(pybullet.reached and reports["servo"].reached)),
            "perturbed_reached_pybullet": str(bullet.reached),
            "perturbed_reached_both": str(both),
            "executed_ideal": str(int(reports["ideal"].reached)),
            "executed_servo": str(int(reports["servo"].reached)),
            "executed_goal_distance_m": _num(reports["ideal"].goal_distance_m),
            "executed_toppled": str(len(reports["servo"].toppled)),
            "executed_toppled_goal": str(int(goal_name in reports["servo"].toppled)),
            "executed_object_contacts": str(len(reports["servo"].object_contacts)),
            "perturbed_reached": str(perturbed.reached),
            "perturbed_trials": str(perturbed.trials)}


def _closed_loop(request, output, trial: Trial, executions) -> dict[str, str]:
    """The replan_* columns: the closed loop with up to `trial.replan` re-plans in the nominal
    world and in the `trial.perturbed` perturbed worlds, starting from `_executions`'s
    open-loop executions there."""
    row = {"replan": str(trial.replan), "replan_reached": "", "replans_made": "",
           "time_to_goal_s": "", "perturbed_replan_reached": "", "closed_loop_endings": ""}
    if output.trajectory is None or trial.replan == 0:
        return row
    from rearrangement_planner.execution.closed_loop import (
        execute_closed_loop,
        perturbed_closed_loops,
    )
    from rearrangement_planner.world3d.mujoco_model import ExecutionOptions

    reports, perturbed, _ = executions
    watched = trial.divergence_bound > 0      # then the first executions are watched too
    options = ExecutionOptions(arm="servo", divergence_bound=trial.divergence_bound)
    loop = execute_closed_loop(request, trial.replan, options=options, first=output,
                               executed=None if watched else reports["servo"])
    loops = perturbed_closed_loops(request, output, trial.perturbed, trial.seed, trial.replan,
                                   options=options,
                                   executed=() if watched else perturbed.reports)
    row.update({"replan_reached": str(int(loop.reached)), "replans_made": str(loop.replans),
                "time_to_goal_s": _num(loop.time_to_goal_s, 3),
                "perturbed_replan_reached": str(sum(x.reached for x in loops)),
                "closed_loop_endings": ";".join(">".join(a.ended for a in x.attempts)
                                                for x in (loop, *loops))})
    return row


def _replay_physics(scene):
    """The physics the pushing links are replayed in: the scene's own, every object movable
    (Static RRT's paths never touch its static objects, so the replay is the same)."""
    from rearrangement_planner.physics.options import simulation_options
    from rearrangement_planner.physics.step import Physics

    return Physics(scene, simulation_options())


# --------------------------------------------------------------------------------------------
# The CSV
# --------------------------------------------------------------------------------------------


class BenchmarkError(RearrangementError):
    """A benchmark input is unusable; `option` names the command-line option it came from."""

    def __init__(self, option: str, problem: str):
        self.option = option
        self.problem = problem
        super().__init__(f"{option}: {problem}")


def read_trials(path: Path) -> list[dict]:
    """The rows of an existing trials.csv ([] if there is none). Raises `BenchmarkError` (for
    ``--out``) if it cannot be read, has other columns than `CSV_COLUMNS`, or a row is
    incomplete."""
    if not path.exists():
        return []
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise BenchmarkError("--out", f"cannot read {path} to resume ({exc}); move it away or "
                                      f"choose another --out") from None
    if not text:
        return []
    reader = csv.reader(io.StringIO(text))
    header = next(reader, None)
    if header is None or not set(ROW_KEY) <= set(header) <= set(CSV_COLUMNS):
        raise BenchmarkError("--out", f"{path} is not a trials CSV of this benchmark (its "
                                      f"columns differ from {', '.join(CSV_COLUMNS)}); move it "
                                      f"away or choose another --out")
    rows = []
    for line, values in enumerate(reader, start=2):
        if len(values) != len(header):
            raise BenchmarkError("--out", f"{path} line {line} has {len(values)} fields, not "
                                          f"{len(header)}; fix or remove that row")
        row = dict.fromkeys(CSV_COLUMNS, "")
        row.update(zip(header, values, strict=True))
        rows.append(row)
    if not text.endswith("\n"):
        raise BenchmarkError("--out", f"{path} ends in an incomplete row; remove the last "
                                      f"line and run again")
    return rows


ROW_KEY = ("scene", "planner", "seed", "time_limit")
"""The columns of a row's `row_key`."""


def row_key(row: dict) -> tuple[str, str, int, float]:
    """The `Trial.key` of a CSV row."""
    try:
        return row["scene"], row["planner"], int(row["seed"]), float(row["time_limit"])
    except ValueError:
        raise BenchmarkError("--out", f"trials CSV row {row} has a seed or time limit that is "
                                      f"not a number") from None


class TrialWriter:
    """Appends rows to trials.csv, each written whole and flushed at once, so that the file
    only ever holds complete rows however the run ends."""

    def __init__(self, path: Path):
        self.path = path
        new = not path.exists() or path.stat().st_size == 0
        if not new and path.read_text().split("\n", 1)[0] != ",".join(CSV_COLUMNS):
            self._upgrade(path)
        self._file = path.open("a", newline="")
        if new:
            self._write(CSV_COLUMNS)

    @staticmethod
    def _upgrade(path: Path) -> None:
        """Rewrite a CSV of an earlier version with today's columns (new ones empty), in one
        rename, so that its rows and the new ones share a header."""
        rows = read_trials(path)
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(CSV_COLUMNS)
        writer.writerows([r[c] for c in CSV_COLUMNS] for r in rows)
        temporary = path.with_suffix(".csv.tmp")
        temporary.write_text(buffer.getvalue())
        os.replace(temporary, path)

    def _write(self, values: Iterable[str]) -> None:
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n").writerow(values)
        self._file.write(buffer.getvalue())
        self._file.flush()
        os.fsync(self._file.fileno())

    def write(self, row: dict) -> None:
        self._write(row[c] for c in CSV_COLUMNS)

    def close(self) -> None:
        self._file.close()


# --------------------------------------------------------------------------------------------
# The runner
# --------------------------------------------------------------------------------------------


def usable_cores() -> int:
    """Cores this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def trial_cpus(trial: Trial, settings: dict[str, Any]) -> int:
    """The cores a trial occupies: its request's raced trees."""
    from rearrangement_planner.planning.requests.parallel import RaceOptions

    _, values = variant_settings(trial.planner, settings)
    return RaceOptions(**{k: v for k, v in values.items() if k == "trees"}).trees


@dataclass(frozen=True)
class RunReport:
    """What `run_trials` did: trials finished now, skipped (already in the CSV), failed with an
    internal error (not written), and whether Ctrl-C stopped it."""

    finished: int
    skipped: int
    failed: int
    interrupted: bool


def run_trials(trials: Sequence[Trial], csv_path: Path, workers: int | None,
               settings: dict[str, Any], stream=None, address: str | None = None) -> RunReport:
    """Run the trials not yet in `csv_path` as Ray tasks (`engine.Engine`: the embedded Ray, or
    the cluster at `address`), at most `workers` at once (None: as many as the cluster's CPUs
    take), each trial's request `trial_request` with `settings`; append a row per finished
    trial as it finishes. Ctrl-C (KeyboardInterrupt) cancels the running trials and returns
    with `interrupted` set; the CSV then holds every trial finished so far."""
    from rearrangement_planner.tools.bench.engine import Engine, Job, Progress

    stream = stream or sys.stderr
    done = {row_key(r) for r in read_trials(csv_path)}
    todo = [t for t in trials if t.key not in done]
    skipped = len(trials) - len(todo)
    if skipped:
        print(f"resuming: {skipped} of {len(trials)} trials already in {csv_path}",
              file=stream, flush=True)
    if not todo:
        return RunReport(0, skipped, 0, False)
    try:
        writer = TrialWriter(csv_path)
    except OSError as exc:
        raise BenchmarkError("--out", f"cannot write {csv_path} ({exc.strerror})") from None
    finished = failed = 0
    interrupted = False
    progress = None
    try:
        engine = Engine(address)
        progress = Progress(len(todo), stream)
        jobs = [Job(t.key, (t, settings), trial_cpus(t, settings),
                    f"{t.scene} {t.planner} seed {t.seed}") for t in todo]
        for done_job in engine.run(run_trial, jobs, workers, tick=progress.tick):
            label = done_job.job.label
            if done_job.error:
                failed += 1
                progress.advance(False, f"{label}: ERROR", failed=True)
                print(f"trial {label} failed with an internal error (not written; a rerun "
                      f"retries it):\n{done_job.error}", file=stream, flush=True)
                continue
            row = {**done_job.result, "ray_node": done_job.node}
            plan = row.pop(PLAN_KEY, None)
            if plan is not None:
                save_plan(csv_path.parent / "plans", row, plan)
            writer.write(row)
            finished += 1
            progress.advance(row["solved"] == "1",
                             f"{label}: {row['outcome']} {row['plan_time_s']} s")
    except KeyboardInterrupt:
        interrupted = True
    finally:
        writer.close()
        if progress is not None:
            progress.close()
    return RunReport(finished, skipped, failed, interrupted)


# --------------------------------------------------------------------------------------------
# The summary
# --------------------------------------------------------------------------------------------

SHORTCUT_PLANNERS = tuple(name for name, spec in PLANNERS.items() if spec.shortcut)
"""Planners whose paths are shortcut (`pipeline.plan_scene` leaves DARRT's paths alone: its
Push primitive follows a different world model than the physics the shortcut re-simulates)."""

TARGETS = {"solved_share_at_60s": 0.95, "median_plan_time_s": 5.0,
           "shortcut_arm_path_reduction": 0.25, "shortcut_time_s": 5.0}
"""The targets set for PC-RRT when the benchmark was built (reported beside the results)."""

PAPER: dict[str, Any] = {"solved_share_at_300s": {"pc-rrt": 0.75, "darrt": 0.39},
                         "shortcut_arm_path_reduction": 0.14,
                         "executed_real_robot_share": {"pc-rrt": 0.78}}
"""King et al. 2015, §V: PC-RRT 75 % and DARRT 39 % solved at 300 s (Fig. 7), Static RRT below
PC-RRT (Fig. 4), shortcutting -14 % manipulator path length (Fig. 8a); PC-RRT plans of four
scenes executed open loop on the real robot reached the goal in 31 of 40 trials (Table I)."""


def budgets(time_limit: float) -> list[float]:
    """The budgets the summary reports success at: 1, 2, 5, 10, 20, 30, 60, 120, 300 s up to
    the time limit, and the time limit itself."""
    grid = [b for b in (1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 60.0, 120.0, 300.0) if b < time_limit]
    return grid + [float(time_limit)]


def success_at(rows: Sequence[dict], budget: float) -> float:
    """Share of the trials solved with a plan time of at most `budget` s (Fig. 7 of King et
    al.: the success to expect at that budget)."""
    if not rows:
        return float("nan")
    return sum(1 for r in rows if r["solved"] == "1" and float(r["plan_time_s"]) <= budget) \
        / len(rows)


def _median(values: Sequence[float]) -> float | None:
    return float(np.median(values)) if len(values) else None


def _percentile(values: Sequence[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if values else None


def _rounded(value: float | None, digits: int = 4) -> float | None:
    return None if value is None or not math.isfinite(value) else round(float(value), digits)


PHASES = ("search_s", "shortcuts_s", "rollouts_s", "timing_s", "judge_s", "warm_up_s")
"""The phase columns of trials.csv (`pipeline.Phases`)."""


def time_breakdown(rows: Sequence[dict]) -> dict:
    """Where the requests' time went: each phase's total (s) and share of all phases, over
    the trials that recorded them (docs/experiments.md, "Where the time goes")."""
    timed = [r for r in rows if r.get("search_s", "") != ""]
    totals = {p: sum(float(r.get(p) or 0.0) for r in timed) for p in PHASES}
    whole = sum(totals.values())
    return {"trials": len(timed),
            "candidates_mean": _rounded(float(np.mean([int(r["candidates"]) for r in timed])),
                                        2) if timed else None,
            **{p.removesuffix("_s"): {"total_s": _rounded(t, 1),
                                      "share": _rounded(t / whole, 3) if whole else None}
               for p, t in totals.items()}}


def deadline_overrun(rows: Sequence[dict]) -> dict:
    """How far past its time limit a request's plan time ran (s; 0 within it): p99 and max
    over all trials, and over the searches that ended TIMEOUT (pure search, no rollouts)."""
    def overruns(group: Sequence[dict]) -> list[float]:
        return [max(float(r["plan_time_s"]) - float(r["time_limit"]), 0.0) for r in group]

    every, timeouts = overruns(rows), overruns([r for r in rows if r["outcome"] == "TIMEOUT"])
    return {"p99": _rounded(_percentile(every, 99), 3),
            "max": _rounded(max(every), 3) if every else None,
            "timeout_p99": _rounded(_percentile(timeouts, 99), 3),
            "timeout_max": _rounded(max(timeouts), 3) if timeouts else None}


def _shortcut_summary(solved: Sequence[dict], budget: float) -> dict:
    """Means before/after shortcutting over the solved trials (Fig. 8 of King et al. shows the
    means) and the reduction of the means, 1 - mean(after) / mean(before). `budget` is the
    shortcut time (s): a shortcut that ran that long ended by time, not by its attempt bound,
    so it is not reproducible (the count says how many)."""
    out: dict[str, Any] = {"trials": len(solved)}
    for field in ("path_length_rad", "ee_path_length_m", "object_displacement_m"):
        before = [float(r[f"{field}_before"]) for r in solved]
        after = [float(r[f"{field}_after"]) for r in solved]
        mean_before = float(np.mean(before)) if before else None
        mean_after = float(np.mean(after)) if after else None
        out[field] = {
            "mean_before": _rounded(mean_before), "mean_after": _rounded(mean_after),
            "reduction": _rounded(1.0 - mean_after / mean_before)
            if mean_before and mean_after is not None else None,
            "median_trial_reduction": _rounded(_median(
                [1.0 - a / b for a, b in zip(after, before, strict=True) if b > 0])),
        }
    times = [float(r["shortcut_time_s"]) for r in solved]
    out["shortcut_time_s"] = {"median": _rounded(_median(times), 3),
                              "max": _rounded(max(times), 3) if times else None,
                              "ended_by_time_limit": sum(t >= budget for t in times)}
    return out


def _shortcut_time(protocol: dict) -> float:
    """The shortcutting budget of the run's requests, s (its --set, else the default)."""
    from rearrangement_planner.planning.requests.shortcut import ShortcutOptions

    settings = protocol.get("request_settings", {})
    return float(settings.get("shortcut_time", ShortcutOptions().shortcut_time))


def _planner_summary(rows: Sequence[dict], planner: str, protocol: dict,
                     end_effector: frozenset[str]) -> dict:
    time_limit = float(protocol["time_limit"])
    solved = [r for r in rows if r["solved"] == "1"]
    times = [float(r["plan_time_s"]) for r in solved]
    by_objects: dict[str, dict] = {}
    for n in sorted({int(r["objects"]) for r in rows}):
        group = [r for r in rows if int(r["objects"]) == n]
        group_solved = [float(r["plan_time_s"]) for r in group if r["solved"] == "1"]
        by_objects[str(n)] = {"trials": len(group),
                              "solved_share": _rounded(len(group_solved) / len(group)),
                              "median_plan_time_s": _rounded(_median(group_solved), 3)}
    link_counts: dict[str, int] = {}
    pushed = whole_arm = 0
    for r in solved:
        links = [name for name in r["pushing_links"].split(";") if name]
        for name in links:
            link_counts[name] = link_counts.get(name, 0) + 1
        pushed += bool(links)
        whole_arm += any(name not in end_effector for name in links)
    reached = sum(reached_open_loop(r) for r in rows)
    all_times = [float(r["plan_time_s"]) for r in rows]
    checked = [r for r in solved if r["executed_toppled"] != ""]
    summary: dict[str, Any] = {
        "trials": len(rows),
        # the headline: requests whose plan, executed open loop with the servo arm in MuJoCo
        # and in PyBullet, puts the goal object in its region with nothing toppled in both
        "end_to_end": {"requests": len(rows), "reached": reached,
                       "share": _rounded(reached / len(rows)) if rows else None,
                       "reached_mujoco": sum(r["executed_servo"] == "1" for r in rows),
                       "reached_pybullet": sum(r.get("executed_pybullet") == "1" for r in rows),
                       "engines": ("mujoco+pybullet" if any(r.get("executed_both")
                                                            for r in rows) else "mujoco")},
        "request_time_s": {"median": _rounded(_median(all_times), 3),
                           "p90": _rounded(_percentile(all_times, 90), 3)},
        "time_breakdown": time_breakdown(rows),
        "deadline_overrun_s": deadline_overrun(rows),
        "toppled": {"checked": len(checked),
                    "plans_toppling": sum(int(r["executed_toppled"]) > 0
                                          or int(r.get("executed_pybullet_toppled") or 0) > 0
                                          for r in checked),
                    "plans_toppling_mujoco": sum(int(r["executed_toppled"]) > 0
                                                 for r in checked),
                    "plans_toppling_pybullet": sum(
                        int(r.get("executed_pybullet_toppled") or 0) > 0 for r in checked),
                    "objects": sum(int(r["executed_toppled"]) for r in checked),
                    # rows written before the column: unknown, not counted
                    "goal_object": sum(r.get("executed_toppled_goal") == "1" for r in checked)},
        "solved": len(solved),
        "solved_share": _rounded(len(solved) / len(rows)) if rows else None,
        # a plan found by an iteration that began within the budget but ended after it: solved
        # for the planner, not within the budget for success_at_budget
        "solved_after_time_limit": sum(float(r["plan_time_s"]) > time_limit for r in solved),
        "plan_time_s": {"median": _rounded(_median(times), 3),
                        "p90": _rounded(_percentile(times, 90), 3),
                        "mean": _rounded(float(np.mean(times)), 3) if times else None,
                        "max": _rounded(max(times), 3) if times else None},
        "iterations_median": _rounded(_median([float(r["iterations"]) for r in solved]), 1),
        "success_at_budget": {f"{b:g}": _rounded(success_at(rows, b))
                              for b in budgets(time_limit)},
        "by_objects": by_objects,
        "executed": _executed_summary(solved),
        "closed_loop": _closed_loop_summary(rows),
        "calibration": calibration(solved),
        "judged": _judged_summary(rows),
        "non_goal_objects_moved_mean": _rounded(float(np.mean(
            [int(r["non_goal_objects_moved"]) for r in solved]))) if solved else None,
        "pushing_links": {
            "trials_pushing": pushed,
            "beyond_end_effector": whole_arm,
            "per_link": dict(sorted(link_counts.items())),
        },
        "shortcut": (_shortcut_summary(solved, _shortcut_time(protocol))
                     if planner_variant(planner)[0] in SHORTCUT_PLANNERS
                     else "not shortcut"),
    }
    return summary


CALIBRATION_BINS = 5
"""The reliability diagram's bins: fifths of the robustness score's range."""


def calibration(rows: Sequence[dict]) -> dict[str, Any]:
    """How well the robustness score predicts execution (docs/benchmark.md, "How to read
    them"): over the solved plans with a score and perturbed MuJoCo executions, the Brier score
    (the mean of (score - outcome)^2 over every perturbed execution, 0 for a perfect forecast,
    0.25 for a constant 0.5 on a fair coin) and a reliability diagram: per fifth of the score
    range the plans' mean score, the share of their executions that reached the goal and how
    many plans and executions it holds. A calibrated score has the share within 0.15 of the
    mean score in every bin. An execution reached when it reached in every engine that executed it
    (`perturbed_reached`)."""
    scored = [{**r, "perturbed_reached": perturbed_reached(r)} for r in rows
              if r.get("robustness") and r.get("perturbed_trials")
              and int(r["perturbed_trials"]) > 0]
    bins: list[dict[str, Any]] = []
    for b in range(CALIBRATION_BINS):
        lo, hi = b / CALIBRATION_BINS, (b + 1) / CALIBRATION_BINS
        group = [r for r in scored if lo <= float(r["robustness"]) < hi
                 or (b == CALIBRATION_BINS - 1 and float(r["robustness"]) == 1.0)]
        trials = sum(int(r["perturbed_trials"]) for r in group)
        reached = sum(int(r["perturbed_reached"]) for r in group)
        bins.append({"range": [lo, hi], "plans": len(group), "executions": trials,
                     "mean_score": _rounded(float(np.mean([float(r["robustness"])
                                                           for r in group]))) if group else None,
                     "reached_share": _rounded(reached / trials) if trials else None})
    squared = [(float(r["robustness"]) - outcome) ** 2 for r in scored
               for outcome in [1.0] * int(r["perturbed_reached"])
               + [0.0] * (int(r["perturbed_trials"]) - int(r["perturbed_reached"]))]
    gaps = [abs(b["mean_score"] - b["reached_share"]) for b in bins
            if b["mean_score"] is not None and b["reached_share"] is not None]
    return {"plans": len(scored), "brier": _rounded(float(np.mean(squared))) if squared
            else None, "largest_bin_gap": _rounded(max(gaps)) if gaps else None, "bins": bins}


def rescore(out: Path, rollouts: int, perturbation: Any = None) -> list[dict]:
    """The solved trials of the run in `out` (trials.csv and the plans beside it, `save_plan`)
    with their robustness scored again: `rollouts` perturbed rollouts of each plan's arm path
    (seeded by its trial's seed) in worlds drawn by `perturbation` (None: the shipped one), in
    the planner's default physics. With the plans' perturbed MuJoCo executions, which stay as
    they were, `calibration` then says how honest that perturbation set makes the score: the
    instrument for tuning it (docs/benchmark.md, "How to read them")."""
    from rearrangement_planner.planning.requests.robustness import arm_path_robustness

    rows = []
    for row in read_trials(out / "trials.csv"):
        path = plan_file(out / "plans", row)
        if row["solved"] != "1" or not row["perturbed_trials"] or not path.is_file():
            continue
        plan = np.load(path)
        scene = load_trial_scene(str(plan["scene_path"]), str(plan["robot"]))
        arm_path = plan["arm_path"]
        score = arm_path_robustness(scene, arm_path, rollouts, int(row["seed"]), perturbation)
        rows.append({**row, "robustness": repr(score)})
    return rows


def _executed_summary(solved: Sequence[dict]) -> dict[str, Any]:
    """Solved plans that also reach the goal executed open loop in MuJoCo (docs/design.md),
    and how the goal object is pushed: the median of its push path over its start distance
    from the goal point, and of its turn."""
    ideal = [r for r in solved if r["executed_ideal"] != ""]
    pushed = [r for r in solved if r.get("goal_push_path_m")]
    ratios = [float(r["goal_push_path_m"]) / max(float(r["goal_start_distance_m"]), 1e-6)
              for r in pushed]
    return {"checked": len(ideal),
            "reached_ideal": sum(r["executed_ideal"] == "1" for r in ideal),
            "reached_servo": sum(r["executed_servo"] == "1" for r in ideal),
            "reached_ideal_share": _rounded(sum(r["executed_ideal"] == "1" for r in ideal)
                                            / len(ideal)) if ideal else None,
            "reached_servo_share": _rounded(sum(r["executed_servo"] == "1" for r in ideal)
                                            / len(ideal)) if ideal else None,
            "goal_push_path_ratio_median": _rounded(_median(ratios)),
            "goal_turn_rad_median": _rounded(_median([float(r["goal_turn_rad"])
                                                      for r in pushed])),
            "plans_with_object_contact": sum(int(r["executed_object_contacts"]) > 0
                                             for r in ideal if r["executed_object_contacts"]),
            "perturbed": _perturbed_summary(ideal)}


def _perturbed_summary(checked: Sequence[dict]) -> dict[str, Any]:
    """The perturbed executions of the checked plans: how many reached the goal (in every
    engine, `perturbed_reached`; and in each)."""
    done = [r for r in checked if r["perturbed_trials"]]
    trials = sum(int(r["perturbed_trials"]) for r in done)
    reached = sum(int(perturbed_reached(r)) for r in done)
    return {"plans": len(done), "executions": trials, "reached": reached,
            "share": _rounded(reached / trials) if trials else None,
            "reached_mujoco": sum(int(r["perturbed_reached"]) for r in done),
            "reached_pybullet": sum(int(r.get("perturbed_reached_pybullet") or 0)
                                    for r in done)}


def reached_open_loop(row: dict) -> bool:
    """A trial's plan reached the goal executed open loop with nothing toppled: in both
    engines (MuJoCo's servo arm and PyBullet) where both executed it, else in MuJoCo (rows
    from before the second engine)."""
    if row.get("executed_both"):
        return row["executed_both"] == "1"
    return row["executed_servo"] == "1"


def perturbed_reached(row: dict) -> str:
    """A trial's perturbed executions that reached: in both engines where both executed
    them, else in MuJoCo."""
    both = row.get("perturbed_reached_both")
    return both if both else row["perturbed_reached"]


def _judged_summary(rows: Sequence[dict]) -> dict[str, Any] | None:
    """The 3D judge within the requests (`judging`): the answers that reached in its nominal
    world, how many were mended or found by the other planner, and the judge's own time.
    None when no request was judged."""
    judged = [r for r in rows if r.get("judged_nominal")]
    if not judged:
        return None
    seconds = [float(r["judge_s"]) for r in judged if r.get("judge_s")]
    return {"answers": len(judged),
            "reached_nominal": sum(r["judged_nominal"] == "1" for r in judged),
            "mended": sum(int(r["judged_mends"] or 0) > 0 for r in judged),
            "by_planner": {p: sum(r["judged_planner"] == p for r in judged)
                           for p in sorted({r["judged_planner"] for r in judged})},
            "judge_s": {"median": _rounded(_median(seconds), 3),
                        "p90": _rounded(_percentile(seconds, 90), 3)}}


def _closed_loop_summary(rows: Sequence[dict]) -> dict[str, Any] | None:
    """Open loop beside the closed loop (`--replan N`), over every request: reached with the
    servo arm in the nominal world, of the first executions that missed upright how many the
    loop mended, the perturbed executions, and the median time to goal (plan time plus
    trajectory time for the open loop; `time_to_goal_s` for the closed loop) over the solved
    requests. None when no trial closed the loop."""
    looped = [r for r in rows if r.get("replan") not in (None, "", "0")]
    if not looped:
        return None
    solved = [r for r in looped if r["solved"] == "1"]
    upright_misses = [r for r in solved
                      if r["executed_servo"] == "0" and r["executed_toppled"] == "0"]
    open_times = [float(r["plan_time_s"]) + float(r["trajectory_s"]) for r in solved
                  if r.get("trajectory_s")]
    executions = sum(int(r["perturbed_trials"] or 0) for r in solved)
    return {"replan": max(int(r["replan"]) for r in looped), "requests": len(looped),
            "reached_open_loop": sum(r["executed_servo"] == "1" for r in looped),
            "reached_closed_loop": sum(r["replan_reached"] == "1" for r in looped),
            "upright_misses": len(upright_misses),
            "upright_misses_mended": sum(r["replan_reached"] == "1" for r in upright_misses),
            "perturbed_executions": executions,
            "perturbed_reached_open_loop": sum(int(r["perturbed_reached"] or 0)
                                               for r in solved),
            "perturbed_reached_closed_loop": sum(int(r["perturbed_replan_reached"] or 0)
                                                 for r in solved),
            "time_to_goal_s_median": {
                "open_loop": _rounded(_median(open_times), 3),
                "closed_loop": _rounded(_median([float(r["time_to_goal_s"]) for r in solved]),
                                        3)}}


def closed_loop_table(summary: dict) -> str:
    """The closed-loop summaries as a Markdown table beside the open loop, one row per planner
    that closed the loop ("" when none did)."""
    head = ["planner", "re-plans", "reached, open loop", "reached within the re-plans",
            "upright misses mended", "perturbed, open loop", "perturbed, within the re-plans",
            "time to goal median, open / closed"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, p in summary["planners"].items():
        c = p.get("closed_loop")
        if not c:
            continue
        n, e = c["requests"], c["perturbed_executions"]
        times = c["time_to_goal_s_median"]
        lines.append("| " + " | ".join([
            name, str(c["replan"]), f"{c['reached_open_loop']}/{n}",
            f"{c['reached_closed_loop']}/{n}",
            f"{c['upright_misses_mended']}/{c['upright_misses']}",
            f"{c['perturbed_reached_open_loop']}/{e}", f"{c['perturbed_reached_closed_loop']}/{e}",
            f"{times['open_loop']} / {times['closed_loop']} s"]) + " |")
    return "\n".join(lines) if len(lines) > 2 else ""


def _beats(a: dict, b: dict) -> dict[str, bool]:
    """Per budget: planner a solves a larger share than b."""
    return {k: a["success_at_budget"][k] > b["success_at_budget"][k]
            for k in a["success_at_budget"] if float(k) >= 5.0}


def summarize(rows: Sequence[dict], protocol: dict, end_effector: Iterable[str] = ()) -> dict:
    """The JSON summary of the trial rows of one protocol (one time limit): per planner the
    solved share, plan times, success at budgets, per object count, pushing links and the
    shortcut figures; PC-RRT against the others and against its targets (`TARGETS`) and the
    paper's figures. `end_effector`: links that count as the hand (moved only by the last
    joint); a push by any other link is a whole-arm push."""
    time_limit = float(protocol["time_limit"])
    end_effector = frozenset(end_effector)
    planners = {p: _planner_summary([r for r in rows if r["planner"] == p], p, protocol,
                                    end_effector)
                for p in protocol["planners"] if any(r["planner"] == p for r in rows)}
    summary: dict[str, Any] = {"protocol": protocol, "trials": len(rows),
                               "end_effector_links": sorted(end_effector),
                               "planners": planners}
    pc = planners.get("pc-rrt")
    if pc is not None:
        comparison = {other: {"solves_more_at_budget": _beats(pc, planners[other]),
                              "lower_median_plan_time": (
                                  pc["plan_time_s"]["median"] is not None
                                  and (planners[other]["plan_time_s"]["median"] is None
                                       or pc["plan_time_s"]["median"]
                                       < planners[other]["plan_time_s"]["median"]))}
                      for other in planners if other != "pc-rrt"}
        shortcut = pc["shortcut"]["path_length_rad"]["reduction"] if pc["solved"] else None
        at_60 = success_at([r for r in rows if r["planner"] == "pc-rrt"], 60.0)
        summary["pc_rrt_vs"] = comparison
        summary["targets"] = {
            "solved_share_at_60s": {"target": TARGETS["solved_share_at_60s"],
                                    "measured": _rounded(at_60) if time_limit >= 60 else None,
                                    "note": None if time_limit >= 60 else
                                    f"time limit {time_limit:g} s < 60 s: not measured"},
            "median_plan_time_s": {"target": TARGETS["median_plan_time_s"],
                                   "measured": pc["plan_time_s"]["median"]},
            "shortcut_arm_path_reduction": {"target": TARGETS["shortcut_arm_path_reduction"],
                                            "measured": shortcut,
                                            "shortcut_time_s": _shortcut_time(protocol)},
        }
    summary["paper"] = PAPER
    return summary


def end_effector_links(robot: RobotModel) -> frozenset[str]:
    """Contact-shape links moved by the same joint as the tool frame (the hand and the flange
    it is mounted on): a push by any other link is a whole-arm push
    (docs/design.md: pushes by the hand alone would mean the whole-arm part is missing)."""
    model = robot.model
    tool_joint = model.frames[robot.tool_frame_id].parentJoint
    return frozenset(s.link for s in robot.contact_shapes
                     if model.frames[robot.frame_id(s.link)].parentJoint == tool_joint)


def summary_table(summary: dict) -> str:
    """The summary as a Markdown table, one row per planner: the end-to-end figure first (the
    share of requests whose plan reaches the goal executed open loop with the servo arm in
    MuJoCo, nothing toppled), then solved in the model, plan times and how plans push."""
    protocol = summary["protocol"]
    marks = [b for b in budgets(float(protocol["time_limit"])) if b in (5.0, 20.0, 60.0,
                                                                         300.0)]
    head = (["planner", "reached the goal, executed", "solved in the model",
             "plan time median / p90 (all requests)"]
            + [f"solved ≤ {b:g} s" for b in marks]
            + ["push path / straight line", "plans toppling", "perturbed executions reached",
               "plans with object contact", "robustness Brier",
               "arm path before → after shortcut", "pushes beyond the hand"])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, p in summary["planners"].items():
        end = p["end_to_end"]
        times = p["request_time_s"]
        cells = [name, f"{end['reached']}/{end['requests']} ({100 * end['share']:.0f} %)",
                 f"{p['solved']}/{p['trials']} ({100 * p['solved_share']:.0f} %)",
                 f"{times['median']:.1f} / {times['p90']:.1f} s"]
        cells += [f"{100 * p['success_at_budget'][f'{b:g}']:.0f} %" for b in marks]
        ratio = p["executed"]["goal_push_path_ratio_median"]
        cells.append("–" if ratio is None else f"{ratio:.2f}")
        toppled = p["toppled"]
        cells.append(f"{toppled['plans_toppling']}/{toppled['checked']}")
        perturbed = p["executed"]["perturbed"]
        cells.append(f"{perturbed['reached']}/{perturbed['executions']}"
                     + (f" ({100 * perturbed['share']:.0f} %)" if perturbed["executions"]
                        else ""))
        cells.append(f"{p['executed']['plans_with_object_contact']}/{toppled['checked']}")
        brier = p["calibration"]["brier"]
        cells.append("–" if brier is None else f"{brier:.3f}")
        shortcut = p["shortcut"]
        if isinstance(shortcut, dict) and shortcut["trials"]:
            arm = shortcut["path_length_rad"]
            cells.append(f"{arm['mean_before']:.1f} → {arm['mean_after']:.1f} rad "
                         f"({-100 * arm['reduction']:+.0f} %)")
        else:
            cells.append("–" if isinstance(shortcut, dict) else shortcut)
        links = p["pushing_links"]
        cells.append(f"{links['beyond_end_effector']}/{links['trials_pushing']}")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
