"""Scene format and validation (docs/design.md): every shipped scene loads, and every malformed
scene is rejected with one SceneError naming the field (dotted path) and the problem."""

from __future__ import annotations

import copy
import math
import os
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import yaml

from rearrangement_planner.model.errors import RearrangementError, SceneError
from rearrangement_planner.model.resources import robots_dir, scenes_dir
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.scene import (
    DEFAULT_GOAL_RADIUS,
    DEFAULT_MASS,
    DEFAULT_PUSHER_FRICTION,
    DEFAULT_SUPPORT_FRICTION,
    MovableObject,
    Scene,
)
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.validation import check_scene, load_scene, parse_scene

# The example of docs/design.md "The world model", verbatim.
BASE = yaml.safe_load("""
robot: panda
start_configuration: [0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.785]
table: {center: [0.55, 0.0], size: [0.8, 1.2], height: 0.0}
obstacles:
  - {name: post, shape: box, size: [0.05, 0.05, 0.30], pose: [0.75, 0.35, 0.0]}
objects:
  - {name: target, shape: box, size: [0.06, 0.08, 0.12], pose: [0.50, 0.10, 0.3],
     mass: 0.4, support_friction: 0.4, pusher_friction: 0.3}
  - {name: can, shape: cylinder, radius: 0.035, height: 0.12, pose: [0.55, -0.05, 0.0]}
goal: {object: target, position: [0.60, -0.30], radius: 0.10}
""")
# Lowering the shoulder (joint 2) by 1.1 rad from the start puts the hand into the table.
Q_INTO_TABLE = [0.0, 0.8, 0.0, -2.2, 0.0, 2.0, 0.785]
SHIPPED = sorted(p.name for p in scenes_dir().glob("*.yaml"))


@pytest.fixture
def base() -> dict:
    return copy.deepcopy(BASE)


def parse(data: dict, panda: RobotModel) -> Scene:
    return parse_scene(data, robot=panda)


# -- shipped scenes -----------------------------------------------------------------------------


def test_the_four_demo_scenes_are_shipped() -> None:
    assert {"default.yaml", "easy_push.yaml", "clutter.yaml", "seven_objects.yaml"} <= set(SHIPPED)


@pytest.mark.parametrize("filename", SHIPPED)
def test_shipped_scene_loads_and_is_valid(filename: str, panda: RobotModel) -> None:
    own_arm = "xarm7" in filename                 # the second arm's demo scene
    scene = load_scene(scenes_dir() / filename, robot=None if own_arm else panda)
    assert scene.robot.name == "xarm7" if own_arm else scene.robot is panda
    assert scene.source.endswith(filename)
    assert scene.objects and scene.goal.object in scene.object_names
    state = scene.initial_state()
    assert state.q.shape == (7,) and state.objects.shape == (len(scene.objects), 3)
    assert np.all(scene.table.contains(state.objects[:, :2]))
    assert not scene.goal.reached(state.objects[scene.goal_index, :2]), "goal already reached"
    # every shipped scene starts with the comment header that says what it tests
    assert (scenes_dir() / filename).read_text().startswith("#")


def test_shipped_scene_sizes() -> None:
    seven = load_scene("seven_objects")
    assert len(seven.objects) == 7
    assert {o.shape for o in seven.objects} == {"box", "cylinder"}
    assert len(load_scene("easy_push").objects) == 1


def test_load_scene_by_name_loads_the_robot_itself() -> None:
    scene = load_scene("easy_push")
    assert isinstance(scene.robot, RobotModel) and scene.robot.name == "panda"
    assert scene.source == str(scenes_dir() / "easy_push.yaml")


def test_clutter_blocks_the_straight_way(panda: RobotModel) -> None:
    """The straight push of the target to the goal point sweeps through the three blockers."""
    scene = load_scene("clutter", robot=panda)
    from rearrangement_planner.physics.collision import CollisionWorld

    world, poses, g = CollisionWorld(scene), scene.object_poses, scene.goal_index
    hit = set()
    for t in np.linspace(0.0, 1.0, 50):
        moved = poses.copy()
        moved[g, :2] = (1 - t) * poses[g, :2] + t * scene.goal.position
        hit |= {j for pair in world.object_overlaps(moved) for j in pair if j != g}
    assert len(hit) == 3


# -- the parsed values ---------------------------------------------------------------------------


def test_parsed_values_defaults_and_helpers(base: dict, panda: RobotModel) -> None:
    scene = parse(base, panda)
    target, can = scene.objects
    assert (target.mass, target.support_friction, target.pusher_friction) == (0.4, 0.4, 0.3)
    assert (can.mass, can.support_friction, can.pusher_friction) == (
        DEFAULT_MASS, DEFAULT_SUPPORT_FRICTION, DEFAULT_PUSHER_FRICTION)
    assert can.shape == "cylinder" and can.radius == pytest.approx(0.035)
    assert np.allclose(can.size, [0.07, 0.07, 0.12]) and can.height == pytest.approx(0.12)
    assert target.radius is None and np.allclose(target.size, [0.06, 0.08, 0.12])
    assert target.footprint_radius == pytest.approx(0.05)
    assert target.bounding_radius == pytest.approx(math.sqrt(0.05**2 + 0.06**2))
    assert scene.obstacles[0].name == "post" and scene.obstacles[0].height == pytest.approx(0.3)
    assert scene.object_index("can") == 1 and scene.goal_index == 0
    assert np.allclose(scene.table.lower, [0.15, -0.6]) and np.allclose(scene.table.upper,
                                                                        [0.95, 0.6])
    state = scene.initial_state()
    assert isinstance(state, State)
    assert np.allclose(state.q, BASE["start_configuration"])
    assert np.allclose(state.objects, [[0.5, 0.1, 0.3], [0.55, -0.05, 0.0]])


def test_optional_keys_take_their_defaults(base: dict, panda: RobotModel) -> None:
    del base["start_configuration"], base["obstacles"], base["goal"]["radius"]
    scene = parse(base, panda)
    assert np.array_equal(scene.start_configuration, panda.home)
    assert scene.obstacles == () and scene.goal.radius == DEFAULT_GOAL_RADIUS


def test_numpy_values_are_accepted(base: dict, panda: RobotModel) -> None:
    """Scenes generated in code (e.g. the benchmark) may hold numpy arrays and scalars."""
    base["objects"][0]["pose"] = np.array([0.5, 0.1, 0.3])
    base["objects"][0]["mass"] = np.float32(0.25)
    base["table"]["height"] = np.int64(0)
    scene = parse(base, panda)
    assert scene.objects[0].mass == pytest.approx(0.25) and scene.table.height == 0.0


def test_zero_pusher_friction_is_allowed(base: dict, panda: RobotModel) -> None:
    base["objects"][0].update(pusher_friction=0.0)
    assert parse(base, panda).objects[0].pusher_friction == 0.0


def test_values_are_read_only(base: dict, panda: RobotModel) -> None:
    scene = parse(base, panda)
    for array in (scene.start_configuration, scene.table.center, scene.table.size,
                  scene.objects[0].pose, scene.objects[0].size, scene.obstacles[0].pose,
                  scene.goal.position):
        with pytest.raises(ValueError):
            array[0] = 1.0
    with pytest.raises(AttributeError):
        scene.objects[0].mass = 2.0  # type: ignore[misc]


def test_object_index_of_an_unknown_name(base: dict, panda: RobotModel) -> None:
    with pytest.raises(SceneError, match=r"no object named 'cup'; objects are \['target', 'can'\]"):
        parse(base, panda).object_index("cup")


def test_to_dict_round_trips(base: dict, panda: RobotModel) -> None:
    scene = parse(base, panda)
    data = scene.to_dict()
    assert data["robot"] == "panda"
    again = parse_scene(yaml.safe_load(yaml.safe_dump(data)), robot=panda)
    assert again.to_dict() == data
    assert np.array_equal(again.initial_state().objects, scene.initial_state().objects)


def test_movable_object_factories() -> None:
    can = MovableObject.cylinder("can", 0.03, 0.1, (0.5, 0.0, 0.0), mass=0.2)
    assert can.radius == 0.03 and np.allclose(can.size, [0.06, 0.06, 0.1]) and can.mass == 0.2
    box = MovableObject.box("box", (0.05, 0.06, 0.07), (0.5, 0.0, 0.1))
    assert box.shape == "box" and box.mass == DEFAULT_MASS
    with pytest.raises(ValueError, match="object shape 'sphere'"):
        MovableObject("ball", "sphere", (0.1, 0.1, 0.1), (0, 0, 0))


def test_robot_path_is_relative_to_the_scene_file(base: dict, tmp_path: Path) -> None:
    base["robot"] = os.path.relpath(robots_dir() / "panda.yaml", tmp_path)
    path = tmp_path / "scene.yaml"
    path.write_text(yaml.safe_dump(base))
    scene = load_scene(path)
    assert scene.robot.name == "panda"
    assert scene.to_dict()["robot"] == "panda"   # a shipped config is written back by name


def test_check_scene_accepts_a_scene_built_in_code(base: dict, panda: RobotModel) -> None:
    import dataclasses

    scene = parse(base, panda)
    moved = dataclasses.replace(scene, start_configuration=np.array(Q_INTO_TABLE))
    with pytest.raises(SceneError) as info:
        check_scene(moved)
    assert info.value.field == "start_configuration"
    wrong = dataclasses.replace(scene, start_configuration=np.zeros(6))
    with pytest.raises(SceneError, match="expected 7 joint positions"):
        check_scene(wrong)


# -- rejections ----------------------------------------------------------------------------------

Mutation = Callable[[dict], None]


def _set(path: str, value: object) -> Mutation:
    """A mutation that sets a dotted path such as 'objects.1.pose' to `value`."""
    def apply(data: dict) -> None:
        *parents, last = path.split(".")
        node = data
        for key in parents:
            node = node[int(key)] if key.isdigit() else node[key]
        node[int(last) if last.isdigit() else last] = copy.deepcopy(value)
    return apply


def _delete(path: str) -> Mutation:
    def apply(data: dict) -> None:
        *parents, last = path.split(".")
        node = data
        for key in parents:
            node = node[int(key)] if key.isdigit() else node[key]
        del node[int(last) if last.isdigit() else last]
    return apply


def _add_object(entry: dict) -> Mutation:
    def apply(data: dict) -> None:
        data["objects"].append(copy.deepcopy(entry))
    return apply


TALL = {"name": "tall", "shape": "box", "size": [0.06, 0.06, 0.60], "pose": [0.47, 0.30, 0.0]}

REJECTIONS: list[tuple[str, Mutation, str, str]] = [
    # (id, mutation, field, problem regex)
    # unknown keys
    ("unknown top-level key", _set("colour", "red"), "colour",
     r"unknown key; allowed keys are \['robot', 'start_configuration', 'table', 'obstacles', "
     r"'objects', 'goal'\]"),
    ("unknown table key", _set("table.colour", "oak"), "table.colour",
     r"unknown key; allowed keys are \['center', 'size', 'height'\]"),
    ("unknown object key", _set("objects.1.colour", "red"), "objects[1].colour",
     r"unknown key for a cylinder; allowed keys are \[.*'radius', 'height'\]"),
    ("radius on a box", _set("objects.0.radius", 0.03), "objects[0].radius",
     r"unknown key for a box; allowed keys are \[.*'size'\]"),
    ("unknown obstacle key", _set("obstacles.0.mass", 3.0), "obstacles[0].mass",
     r"unknown key; allowed keys are \['name', 'shape', 'size', 'pose'\]"),
    ("unknown goal key", _set("goal.tolerance", 0.1), "goal.tolerance",
     r"unknown key; allowed keys are \['object', 'position', 'radius'\]"),
    # missing required keys
    ("missing robot", _delete("robot"), "robot", "missing required key"),
    ("missing table", _delete("table"), "table", "missing required key"),
    ("empty table", _set("table", None), "table", "missing required key"),
    ("missing objects", _delete("objects"), "objects", "missing required key"),
    ("missing goal", _delete("goal"), "goal", "missing required key"),
    ("missing table size", _delete("table.size"), "table.size", "missing required key"),
    ("missing table height", _delete("table.height"), "table.height", "missing required key"),
    ("missing object pose", _delete("objects.0.pose"), "objects[0].pose",
     "missing required key"),
    ("missing object name", _delete("objects.0.name"), "objects[0].name",
     "missing required key"),
    ("missing object shape", _delete("objects.1.shape"), "objects[1].shape",
     r"missing required key; use one of \['box', 'cylinder'\]"),
    ("missing box size", _delete("objects.0.size"), "objects[0].size", "missing required key"),
    ("missing cylinder radius", _delete("objects.1.radius"), "objects[1].radius",
     "missing required key"),
    ("missing obstacle size", _delete("obstacles.0.size"), "obstacles[0].size",
     "missing required key"),
    ("missing goal object", _delete("goal.object"), "goal.object", "missing required key"),
    ("missing goal position", _delete("goal.position"), "goal.position",
     "missing required key"),
    # wrong types
    ("table not a mapping", _set("table", [0.55, 0.0]), "table",
     r"expected a mapping with keys \['center', 'size', 'height'\], got list"),
    ("objects not a list", _set("objects", {"name": "x"}), "objects",
     "expected a list of mappings, got dict"),
    ("object not a mapping", _set("objects.0", "target"), "objects[0]",
     r"expected a mapping \(name, shape, pose, \.\.\.\), got str 'target'"),
    ("height is a string", _set("table.height", "high"), "table.height",
     r"expected a number \(m\), got str 'high'"),
    ("mass is a bool", _set("objects.0.mass", True), "objects[0].mass",
     r"expected a number \(kg\), got bool True"),
    ("pose is a string", _set("objects.0.pose", "0.5 0.1 0"), "objects[0].pose",
     r"expected a list of 3 numbers: \[x, y, yaw\]"),
    ("pose entry is a string", _set("objects.0.pose", [0.5, "y", 0.0]), "objects[0].pose",
     r"entry 1 is str 'y'; expected 3 numbers"),
    ("exponent without a dot", _set("objects.0.mass", "1e-1"), "objects[0].mass",
     r"got str '1e-1' \(YAML reads this as text; write it with a dot, e.g. 1.0e-3\)"),
    ("name is a number", _set("objects.0.name", 7), "objects[0].name",
     "expected a non-empty string, got int 7"),
    ("empty name", _set("objects.0.name", " "), "objects[0].name", "non-empty string"),
    ("robot is a number", _set("robot", 7), "robot",
     r"expected a shipped robot name \(a file in config/robots\) or the path"),
    ("start is a string", _set("start_configuration", "home"), "start_configuration",
     r"expected a list of 7 numbers: joint positions \(rad\)"),
    # wrong lengths
    ("table size length", _set("table.size", [0.8]), "table.size",
     r"expected 2 numbers: \[size_x, size_y\] \(m\); got 1"),
    ("table center length", _set("table.center", [0.5, 0.0, 0.0]), "table.center",
     r"expected 2 numbers: \[x, y\] \(m\); got 3"),
    ("pose length", _set("objects.1.pose", [0.5, 0.1]), "objects[1].pose",
     r"expected 3 numbers: \[x, y, yaw\] \(m, m, rad\); got 2"),
    ("box size length", _set("objects.0.size", [0.06, 0.08]), "objects[0].size",
     r"expected 3 numbers: \[x, y, z\] extents \(m\); got 2"),
    ("goal position length", _set("goal.position", [0.6, -0.3, 0.0]), "goal.position",
     r"expected 2 numbers: \[x, y\] \(m\); got 3"),
    ("start length", _set("start_configuration", [0.0] * 6), "start_configuration",
     r"expected 7 numbers: joint positions \(rad\), one per joint \['panda_joint1'.*; got 6"),
    # NaN / inf
    ("nan in pose", _set("objects.0.pose", [0.5, math.nan, 0.0]), "objects[0].pose",
     "entry 1 is not a finite number; every entry must be one"),
    ("inf table height", _set("table.height", math.inf), "table.height",
     r"must be a finite number \(m\), got inf"),
    ("nan mass", _set("objects.1.mass", math.nan), "objects[1].mass",
     r"must be a finite number \(kg\), got nan"),
    ("inf goal radius", _set("goal.radius", math.inf), "goal.radius", "finite"),
    ("nan in start", _set("start_configuration", [0.0, math.nan, 0, -2.2, 0, 2.0, 0.785]),
     "start_configuration", "entry 1 is not a finite number"),
    ("inf in obstacle size", _set("obstacles.0.size", [0.05, math.inf, 0.3]),
     "obstacles[0].size", "entry 1 is not a finite number"),
    # non-positive sizes, masses; negative frictions
    ("zero box extent", _set("objects.0.size", [0.06, 0.0, 0.12]), "objects[0].size",
     r"every entry must be between 0.005 and 1 m \(scene bounds, docs/design.md\), got 0"),
    ("negative radius", _set("objects.1.radius", -0.01), "objects[1].radius",
     r"must be between 0.0025 and 0.5 m \(scene bounds, docs/design.md\), got -0.01"),
    ("zero cylinder height", _set("objects.1.height", 0), "objects[1].height",
     r"must be between 0.005 and 1 m \(scene bounds, docs/design.md\), got 0"),
    ("zero mass", _set("objects.0.mass", 0.0), "objects[0].mass",
     "must be between 0.001 and 100 kg"),
    ("negative table size", _set("table.size", [0.8, -1.2]), "table.size",
     "every entry must be between 0.1 and 5 m"),
    ("zero obstacle size", _set("obstacles.0.size", [0.05, 0.05, 0.0]), "obstacles[0].size",
     "every entry must be between 0.005 and 5 m"),
    ("zero goal radius", _set("goal.radius", 0), "goal.radius",
     "must be between 0.001 and 5 m"),
    ("negative support friction", _set("objects.0.support_friction", -0.1),
     "objects[0].support_friction", "must be between 0.01 and 2"),
    ("negative pusher friction", _set("objects.1.pusher_friction", -1),
     "objects[1].pusher_friction", "must be between 0 and 2"),
    # shapes
    ("unknown object shape", _set("objects.0.shape", "sphere"), "objects[0].shape",
     r"unknown shape 'sphere'; use one of \['box', 'cylinder'\]"),
    ("unknown obstacle shape", _set("obstacles.0.shape", "cylinder"), "obstacles[0].shape",
     "unknown obstacle shape 'cylinder'; obstacles are 'box'"),
    # names
    ("duplicate object names", _set("objects.1.name", "target"), "objects[1].name",
     r"duplicate name 'target' \(already used by objects\[0\]\)"),
    ("object named like an obstacle", _set("objects.1.name", "post"), "objects[1].name",
     r"duplicate name 'post' \(already used by obstacles\[0\]\)"),
    ("no objects", _set("objects", []), "objects", "expected a non-empty list"),
    # geometry
    ("objects overlap", _set("objects.1.pose", [0.52, 0.08, 0.0]), "objects[1].pose",
     r"object 'can' overlaps object 'target' \(objects\[0\]\); movable objects must not overlap"),
    ("object overlaps obstacle", _set("objects.1.pose", [0.76, 0.33, 0.0]), "objects[1].pose",
     "object 'can' overlaps obstacle 'post'; objects must stand clear of obstacles"),
    ("object off the table", _set("objects.0.pose", [1.0, 0.1, 0.0]), "objects[0].pose",
     r"object 'target' at \(1.000, 0.100\) is off the table; its centre must lie on the table "
     r"top \(x in \[0.150, 0.950\], y in \[-0.600, 0.600\]\)"),
    ("object off the table in y", _set("objects.1.pose", [0.5, -0.61, 0.0]), "objects[1].pose",
     "off the table"),
    # goal
    ("unknown goal object", _set("goal.object", "cup"), "goal.object",
     r"no object named 'cup'; objects are \['target', 'can'\]"),
    ("goal off the table", _set("goal.position", [0.55, 0.9]), "goal.position",
     r"goal point \(0.550, 0.900\) is off the table; it must lie on the table top"),
    # start configuration
    ("start outside limits", _set("start_configuration", [0.0, -0.3, 0.0, -3.2, 0.0, 2.0, 0.785]),
     "start_configuration",
     r"panda_joint4 = -3.2000 rad \(entry 3\) is outside its joint limits \[-3.0718, -0.0698\]"),
    ("start in the table", _set("start_configuration", Q_INTO_TABLE), "start_configuration",
     r"the arm is in collision: panda_\w+ \(contact shape \d+\) penetrates the table by "
     r"[\d.]+ mm; choose a configuration clear of"),
    ("start in an obstacle", _set("obstacles.0", {"name": "post", "size": [0.06, 0.06, 0.6],
                                                  "pose": [0.47, 0.0, 0.0]}),
     "start_configuration", r"penetrates obstacle 'post' by [\d.]+ mm"),
    ("start in an object", _add_object(TALL | {"pose": [0.47, 0.0, 0.0]}),
     "start_configuration", r"panda_\w+ \(contact shape \d+\) penetrates object 'tall'"),
    # robot
    ("unknown robot", _set("robot", "ur5"), "robot",
     r"unknown robot 'ur5'; shipped robots are \['panda', 'xarm7'\], or give the path"),
    ("missing robot file", _set("robot", "no/such/robot.yaml"), "robot", "does not exist"),
]


@pytest.mark.parametrize(("mutate", "field", "problem"),
                         [pytest.param(*r[1:], id=r[0]) for r in REJECTIONS])
def test_malformed_scene_is_rejected(mutate: Mutation, field: str, problem: str,
                                     base: dict, panda: RobotModel) -> None:
    mutate(base)
    # The robot key decides which robot is loaded, so those cases load it themselves.
    robot = None if field == "robot" else panda
    with pytest.raises(SceneError) as info:
        parse_scene(base, robot=robot)
    error = info.value
    assert isinstance(error, RearrangementError)
    assert error.field == field, str(error)
    assert re.search(problem, error.problem), str(error)
    assert str(error) == f"{field}: {error.problem}"


def test_a_tall_object_clear_of_the_arm_is_fine(base: dict, panda: RobotModel) -> None:
    _add_object(TALL)(base)
    assert parse(base, panda).object_names[-1] == "tall"


def test_robot_mismatch_with_the_given_model(base: dict, panda: RobotModel) -> None:
    base["robot"] = "ur5"
    with pytest.raises(SceneError, match="the scene is for robot 'ur5' but robot 'panda' was"):
        parse(base, panda)


def test_scene_must_be_a_mapping(panda: RobotModel) -> None:
    with pytest.raises(SceneError) as info:
        parse_scene([BASE], robot=panda)
    assert info.value.field == "" and "a scene must be a mapping with keys" in str(info.value)


def test_yaml_syntax_error(tmp_path: Path) -> None:
    path = tmp_path / "broken.yaml"
    path.write_text("robot: panda\ntable: {center: [0.5, 0.0], size: [0.8, 1.2]\n")
    with pytest.raises(SceneError, match=r"broken.yaml is not valid YAML at line \d+, column"):
        load_scene(path)


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.yaml"
    path.write_text("# nothing\n")
    with pytest.raises(SceneError, match="a scene must be a mapping"):
        load_scene(path)


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(SceneError, match=r"scene file .*nope.yaml does not exist"):
        load_scene(tmp_path / "nope.yaml")


def test_unknown_shipped_scene_name() -> None:
    with pytest.raises(SceneError, match=r"unknown scene 'nope'; shipped scenes are \[.*'default'"):
        load_scene("nope")


def test_observed_objects_that_overlap_are_moved_apart(base: dict, panda: RobotModel) -> None:
    """Two cans 1 cm into each other (as touching objects are observed): each moves half a
    centimetre apart along the line between them; 10 cm into each other is no state to plan
    from; objects apart stay where they are."""
    from rearrangement_planner.physics.validation import SEPARATION_GAP, separate_objects

    data = base
    can = {"shape": "cylinder", "radius": 0.04, "height": 0.1}
    data["objects"] = [{**can, "name": "a", "pose": [0.5, 0.0, 0.0]},
                       {**can, "name": "b", "pose": [0.5, 0.2, 0.0]}]
    data["goal"]["object"] = "a"
    scene = parse(data, panda)
    observed = np.array([[0.5, 0.0, 0.3], [0.5, 0.07, 0.0]])
    apart = separate_objects(scene, observed)
    assert apart is not None
    np.testing.assert_allclose(apart[:, 1], [-0.005 - SEPARATION_GAP / 2,
                                             0.075 + SEPARATION_GAP / 2], atol=1e-9)
    np.testing.assert_array_equal(apart[:, [0, 2]], observed[:, [0, 2]])
    check_scene(scene.with_start(scene.start_configuration, apart))
    assert separate_objects(scene, np.array([[0.5, 0.0, 0.0], [0.5, -0.02, 0.0]])) is None
    np.testing.assert_array_equal(separate_objects(scene, scene.object_poses),
                                  scene.object_poses)
