"""Shared fixtures. Robots and scenes are built once per session (Pinocchio models are cheap to
query but not free to build)."""

import dataclasses
import gc
import threading
import time
from collections.abc import Callable

import numpy as np
import pytest

from rearrangement_planner.model.robot import RobotModel


@pytest.fixture(scope="session", autouse=True)
def compiled_core() -> float:
    """Compile the Numba kernels (or load them from the disk cache) before any test, so that
    no test's timing includes the compiler (about half a minute on a fresh machine)."""
    from rearrangement_planner.planning.requests.warmup import warm_up

    return warm_up()


@pytest.fixture(scope="module", autouse=True)
def garbage_collected_after_each_file():
    """A test file's garbage is collected when the file ends, its fixtures torn down. rclpy
    prints "The following exception was never retrieved" to stderr when it collects a future
    whose exception nobody read (a callback that met an entity being destroyed); left to the
    collector's own moment, the line landed in what a later file's test captured (a
    clean-clone run failed test_deep_nesting_is_refused so). About 60 ms a file."""
    yield
    gc.collect()


@pytest.fixture(scope="session")
def panda() -> RobotModel:
    return RobotModel.load("panda")


@pytest.fixture(scope="session")
def default_scene(panda: RobotModel):
    """config/scenes/default.yaml (docs/design.md demo scene), sharing the session's Panda model."""
    from rearrangement_planner.physics.validation import load_scene

    return load_scene("default", robot=panda)


@pytest.fixture
def cancel_after() -> Callable:
    """`cancel_after(plan, delay)`: runs `plan(cancel)` on a thread, sets `cancel` after
    `delay` s and returns (the plan's result, whether it was still running when cancelled,
    seconds from the cancel to the plan's return)."""
    def run(plan: Callable[[threading.Event], object], delay: float):
        cancel = threading.Event()
        box = {}

        def target():
            box["result"] = plan(cancel)
            box["done"] = time.monotonic()

        thread = threading.Thread(target=target)
        thread.start()
        time.sleep(delay)
        running = "result" not in box
        sent = time.monotonic()
        cancel.set()
        thread.join(5.0)
        return box["result"], running, box["done"] - sent
    return run


ROS_FILES = {"test_node.py", "test_node_start.py", "test_world_sim.py", "test_bag_replay.py"}
"""Test files that start rclpy nodes over DDS (marker `ros`)."""
SLOW_FILES = {"test_golden_plans.py", "test_parallel.py", "test_benchmark.py",
              "test_bench.py", "test_baselines.py", "test_engine.py",
              "test_robot_fit.py"}
"""Test files whose tests plan whole scenes or spawn worker processes (marker `slow`)."""


RAY_FILES = {"test_bench.py", "test_benchmark.py", "test_engine.py"}
"""Test files that start Ray clusters: one process runs them all, one after another."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Marks by file, so that `pytest -m "not slow and not ros"` is the quick loop; `make test`
    runs everything."""
    for item in items:
        name = item.path.name
        if name in ROS_FILES:
            item.add_marker(pytest.mark.ros)
        if name in SLOW_FILES:
            item.add_marker(pytest.mark.slow)


def pytest_configure(config: pytest.Config) -> None:
    """With several test processes (`make test`: pytest-xdist, `-n 2`), the main process
    compiles the core before it starts them, so that they load it from the disk cache instead
    of each compiling it at once."""
    if config.getoption("numprocesses", None) and not hasattr(config, "workerinput"):
        from rearrangement_planner.planning.requests.warmup import warm_up

        warm_up()


def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """pytest-xdist's scheduling by file (`--dist loadfile`: a file's tests in one process, in
    their order, sharing its fixtures), except that the files that start Ray clusters run in
    the same process, one after another."""
    from xdist.scheduler import LoadScopeScheduling

    class ByFile(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            file = nodeid.split("::", 1)[0]
            return "ray clusters" if file.rsplit("/", 1)[-1] in RAY_FILES else file

    return ByFile(config, log)


# -- a straight push (the execution tests) ---------------------------------------------------


@pytest.fixture(scope="module")
def push_path(panda):
    """The tool on the pushing manifold moving along +x from 0.40 to 0.55 m at 5 cm/s (IK
    every 5 mm), after a 1 s hold: times and positions."""
    from rearrangement_planner.planning.machinery.manifold import (
        default_push_configuration,
        ik_on_manifold,
    )

    xs = np.arange(0.40, 0.55 + 1e-9, 0.005)
    q = default_push_configuration(panda, 0.0)
    path = []
    for x in xs:
        q = ik_on_manifold(panda, float(x), 0.0, 0.0, 0.0, q)
        path.append(q)
    positions = np.vstack([path[:1], path])
    times = np.concatenate([[0.0], 1.0 + np.arange(len(xs)) * 0.1])
    return times, positions


@pytest.fixture(scope="module")
def pushed(panda, push_path):
    """pushed(objects, options=None): (scene, trajectory, final state), as below."""
    return lambda objects, options=None: _pushed(panda, push_path, objects, options)


def _pushed(panda, push_path, objects, options=None):
    """The scene with `objects` on the table, the push as a trajectory, and the quasistatic
    prediction (world_sim's physics with `options`, 1 mm substeps)."""
    from rearrangement_planner.execution.open_loop import OpenLoopExecution
    from rearrangement_planner.model.command import Command
    from rearrangement_planner.physics.options import simulation_options
    from rearrangement_planner.physics.step import Physics
    from rearrangement_planner.physics.validation import parse_scene
    from rearrangement_planner.planning.requests.trajectory import Trajectory

    times, positions = push_path
    data = {"table": {"center": [0.55, 0.0], "size": [0.8, 1.2], "height": 0.0},
            "start_configuration": positions[0].tolist(), "objects": objects,
            "goal": {"object": objects[0]["name"], "position": [0.59, 0.0], "radius": 0.02}}
    scene = parse_scene(data, robot=panda)
    trajectory = Trajectory(panda.joint_names, times, positions, np.zeros_like(positions))
    options = dataclasses.replace(options or simulation_options(), max_substep=0.001)
    execution = OpenLoopExecution(Physics(scene, options),
                                  scene.initial_state(), Command(times, positions), period=0.01)
    execution.run()
    assert execution.invalid is None
    return scene, trajectory, execution.state


# -- the 3D judge, scripted ----------------------------------------------------------------


@pytest.fixture
def judge_says(monkeypatch):
    """`judge_says(reached, share, tipped=())`: the request's 3D judge (`judging.judge`)
    replaced by one that says the nominal world reached the goal (`reached`; else the objects
    `tipped` fell, or it missed) and `share` of the perturbed worlds did; the objects stay
    where the scene has them. Returns the list of the trajectories it was asked about."""
    from rearrangement_planner.model.state import State
    from rearrangement_planner.planning.requests import judging
    from rearrangement_planner.world3d.judge import Judgement, WorldOutcome

    asked: list = []

    def script(reached: bool, share: float, tipped: tuple[str, ...] = ()):
        def judge(scene, trajectory, worlds=(), nominal_decides=False, **_):
            asked.append(trajectory)
            poses = np.repeat(scene.object_poses[None], len(trajectory), axis=0)
            nominal = WorldOutcome(reached, 0.0 if reached else 0.3, tipped,
                                   1.0 if tipped else None, 0.5 if tipped else None,
                                   np.zeros(len(scene.objects)), poses,
                                   State(trajectory.positions[-1], scene.object_poses))
            if nominal_decides and not reached:          # the perturbed worlds stopped
                return Judgement(nominal, (), 0.01, complete=not worlds)
            worlds = tuple(dataclasses.replace(nominal, reached=k < round(share * len(worlds)))
                           for k in range(len(worlds)))
            return Judgement(nominal, worlds, 0.01)

        monkeypatch.setattr(judging, "judge", judge)
        return asked

    return script
