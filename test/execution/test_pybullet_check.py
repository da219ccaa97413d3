"""The second execution engine, PyBullet (`execution.pybullet_check`): a straight push ends
where MuJoCo's servo arm puts the box and leaves a bystander alone, a tipping push topples a
tall box in both engines, perturbed executions run in the worlds MuJoCo's do and are
reproducible, every execution has its own client, and a robot without a usable collision URDF
is refused by name. Headless, CPU only."""

from __future__ import annotations

import dataclasses
import threading
from pathlib import Path

import numpy as np
import pytest
import yaml

from rearrangement_planner.execution.pybullet_check import (
    PybulletCheckError,
    PybulletOptions,
    check_execution_pybullet,
    check_perturbed_pybullet,
)
from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.perturbation import Perturbation
from rearrangement_planner.model.robot import RobotConfig, RobotModel
from rearrangement_planner.model.scene import SupportPressure
from rearrangement_planner.physics.validation import parse_scene
from rearrangement_planner.world3d.execution import (
    ExecutionReport,
    check_execution,
    check_perturbed,
)
from rearrangement_planner.world3d.mujoco_model import ExecutionCheckError, ExecutionOptions

BOX = {"name": "box", "shape": "box", "size": [0.06, 0.08, 0.12], "pose": [0.46, 0.0, 0.0],
       "mass": 0.4, "support_friction": 0.4, "pusher_friction": 0.3}
BYSTANDER = {"name": "bystander", "shape": "cylinder", "radius": 0.03, "height": 0.1,
             "pose": [0.5, 0.3, 0.0]}
SERVO = ExecutionOptions(arm="servo")


@pytest.fixture(scope="module")
def straight_push(pushed):
    """A box 3 cm ahead of the finger tips on the push line, a cylinder well aside."""
    return pushed([BOX, BYSTANDER])


@pytest.fixture(scope="module")
def pybullet_push(straight_push):
    scene, trajectory, predicted = straight_push
    return check_execution_pybullet(scene, trajectory, [predicted] * len(trajectory))


def test_a_straight_push_ends_where_mujoco_puts_the_box(straight_push, pybullet_push):
    """Pushed ~13 cm along x: the box ends within 1.5 cm of MuJoCo's servo arm's box (0.1 mm
    measured) and of the quasistatic prediction, not turned; the bystander is not moved."""
    scene, trajectory, predicted = straight_push
    mujoco = check_execution(scene, trajectory, None, SERVO)
    report = pybullet_push
    box, bystander = report.objects
    assert report.arm == "servo" and report.reached and report.reached == mujoco.reached
    assert box.moved_m > 0.10, box
    gap = np.hypot(*(np.asarray(box.pose[:2]) - mujoco.objects[0].pose[:2]))
    assert gap < 0.015, (box.pose, mujoco.objects[0].pose)
    assert abs(box.pose[2] - mujoco.objects[0].pose[2]) < 0.05
    assert box.final_error_m is not None and box.final_error_m < 0.015
    assert bystander.moved_m < 1e-3 and abs(bystander.pose[2]) < 0.01
    assert report.toppled == () and box.max_tilt_deg < 2.0 and bystander.max_tilt_deg < 2.0
    assert report.max_tracking_error_rad < 0.01
    assert report.object_contacts == () and report.arm_collisions == {}


@pytest.fixture(scope="module")
def off_centre(pushed):
    """The box 3 cm off the push line: the finger pads' edge meets it and it turns."""
    return pushed([{**BOX, "pose": [0.46, 0.03, 0.0]}])


def test_a_push_off_centre_turns_the_box_as_far_as_in_mujoco(off_centre):
    """Pushed 3 cm off its centre line the box turns by about a radian, in PyBullet within
    0.02 rad and 1.5 cm of MuJoCo (4 mrad, 0.9 mm measured). How far depends on the frictions
    each engine gives the arm-box and box-table pairs (module doc, Friction): with the
    arm-box coefficient the box-table one, 0.4 for 0.3, PyBullet turned it 0.033 rad less."""
    scene, trajectory, _ = off_centre
    ours = check_execution_pybullet(scene, trajectory).objects[0].pose
    theirs = check_execution(scene, trajectory, None, SERVO).objects[0].pose
    assert ours[2] > 0.8 and abs(ours[2] - theirs[2]) < 0.02, (ours, theirs)
    assert np.hypot(ours[0] - theirs[0], ours[1] - theirs[1]) < 0.015, (ours, theirs)


def test_a_centre_of_mass_off_the_push_line_turns_the_box_the_same_way_in_both(off_centre):
    """The box's weight resting 1 cm towards the finger or away from it
    (`SupportPressure.centre`, where both engines put the centre of mass): away from the
    finger it turns more, in PyBullet as in MuJoCo (0.48 and 1.38 rad; MuJoCo 0.68 and 1.30),
    and its reported pose is its geometric centre's, not its centre of mass's."""
    scene, trajectory, _ = off_centre
    turns = {}
    for side in (-1.0, 1.0):        # the finger meets the box at y = -3 cm in its frame
        obj = dataclasses.replace(scene.objects[0],
                                  support=SupportPressure(1.0, (0.0, 0.01 * side)))
        world = dataclasses.replace(scene, objects=(obj,))
        ours = check_execution_pybullet(world, trajectory).objects[0]
        theirs = check_execution(world, trajectory, None, SERVO).objects[0]
        turns[side] = (ours.pose[2], theirs.pose[2])
        assert np.hypot(ours.pose[0] - theirs.pose[0], ours.pose[1] - theirs.pose[1]) < 0.015
    for which in (0, 1):            # PyBullet, then MuJoCo
        assert turns[1.0][which] > turns[-1.0][which] + 0.3, turns


def test_the_report_follows_the_trajectory_point_by_point(straight_push, pybullet_push):
    """The executed poses at every trajectory point (the box starts still and ends where the
    outcome says), the final configuration the trajectory's last, the simulated time the
    settling, the trajectory and the hold, the goal distance the goal object's."""
    scene, trajectory, _ = straight_push
    report = pybullet_push
    paths = report.executed_paths
    assert paths.shape == (len(trajectory), 2, 3)
    np.testing.assert_allclose(paths[0, 0, :2], scene.objects[0].pose[:2], atol=1e-3)
    np.testing.assert_allclose(paths[-1, 0, :2], report.objects[0].pose[:2], atol=2e-3)
    assert np.all(np.diff(paths[:, 0, 0]) > -1e-4)        # pushed along +x, never back
    np.testing.assert_allclose(report.final_q, trajectory.positions[-1], atol=0.01)
    options = PybulletOptions()
    assert report.sim_time_s == pytest.approx(
        options.settle + trajectory.times[-1] + options.hold, abs=2 * options.timestep)
    assert report.goal_distance_m == pytest.approx(
        scene.goal.distance(np.asarray(report.objects[0].pose[:2])))
    record = report.to_dict()
    assert set(record["objects"]["box"]) >= {"final_error_m", "moved_m", "toppled"}


def test_a_tipping_push_topples_the_tall_box_in_both_engines(straight_push, panda):
    """A tall, light box on a grippy table, pushed at the tool's height, falls over in
    PyBullet as in MuJoCo (both lie at ~90 deg, 6 mm apart); the goal is not reached."""
    scene, trajectory, _ = straight_push
    data = yaml.safe_load(yaml.safe_dump(scene.to_dict()))
    data["objects"][0].update(size=[0.04, 0.08, 0.25], support_friction=1.0, mass=0.2)
    tall = parse_scene(data, robot=panda)
    mujoco = check_execution(tall, trajectory, None, SERVO)
    report = check_execution_pybullet(tall, trajectory)
    for run in (mujoco, report):
        assert run.objects[0].toppled and run.toppled == ("box",) and not run.reached
    assert report.objects[0].max_tilt_deg > 60.0
    assert not report.objects[1].toppled and report.objects[1].moved_m < 1e-3


def test_perturbed_executions_are_reproducible_counted_and_in_mujocos_worlds(straight_push):
    """The same seed draws the same worlds: repeated, the executions end alike; each trial's
    world differs; and each ends within 1.5 cm of MuJoCo's execution in the same world."""
    scene, trajectory, _ = straight_push
    small = Perturbation(friction=0.1, mass=0.1, pose_noise=0.002, yaw_noise=0.01)
    first = check_perturbed_pybullet(scene, trajectory, trials=2, seed=3, perturbation=small)
    again = check_perturbed_pybullet(scene, trajectory, trials=2, seed=3, perturbation=small)
    assert first.trials == 2 and len(first.reports) == 2
    assert first.reached == sum(r.reached for r in first.reports)
    assert [r.goal_distance_m for r in first.reports] == [r.goal_distance_m
                                                          for r in again.reports]
    assert first.reports[0].goal_distance_m != first.reports[1].goal_distance_m
    mujoco = check_perturbed(scene, trajectory, trials=2, seed=3, options=SERVO,
                             perturbation=small)
    for ours, theirs in zip(first.reports, mujoco.reports, strict=True):
        gap = np.hypot(*(np.asarray(ours.objects[0].pose[:2]) - theirs.objects[0].pose[:2]))
        assert gap < 0.015, (ours.objects[0].pose, theirs.objects[0].pose)
    assert set(first.to_dict()) >= {"trials", "reached", "success_rate"}


def test_executions_in_threads_do_not_share_a_world(straight_push, pybullet_push):
    """Each execution builds its world in its own PyBullet client: two at once on two
    threads end exactly as one alone."""
    scene, trajectory, predicted = straight_push
    results: dict[int, ExecutionReport] = {}

    def run(i: int) -> None:
        results[i] = check_execution_pybullet(scene, trajectory, [predicted] * len(trajectory))

    threads = [threading.Thread(target=run, args=(i,)) for i in range(2)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60.0)
    for report in results.values():
        assert report.objects == pybullet_push.objects
    assert len(results) == 2


def _robot_with(panda: RobotModel, urdf: Path) -> RobotModel:
    data = yaml.safe_load(panda.config.source.read_text())
    data["collision_urdf"] = str(urdf)
    return RobotModel(RobotConfig.from_dict(data, base_dir=panda.config.source.parent))


def test_a_robot_without_a_usable_collision_urdf_is_refused_by_name(straight_push, tmp_path):
    """A missing URDF, one whose collision mesh is gone and one without the planning joints
    are each refused with `PybulletCheckError` (a `RearrangementError`, and an
    `ExecutionCheckError` as MuJoCo's refusals are), naming the file."""
    scene, trajectory, _ = straight_push
    panda = scene.robot
    gone = _robot_with(panda, tmp_path / "gone.urdf")
    with pytest.raises(PybulletCheckError, match=r"cannot read the arm's URDF .*gone\.urdf"):
        check_execution_pybullet(dataclasses.replace(scene, robot=gone), trajectory)
    assert issubclass(PybulletCheckError, ExecutionCheckError)
    assert issubclass(PybulletCheckError, RearrangementError)

    text = panda.config.geometry_urdf.read_text()
    meshless = tmp_path / "meshless.urdf"
    meshless.write_text(text.replace("collision/link3.stl", "collision/nowhere.stl"))
    with pytest.raises(PybulletCheckError, match=r"meshless\.urdf.*nowhere\.stl"):
        check_execution_pybullet(dataclasses.replace(scene, robot=_robot_with(panda, meshless)),
                                 trajectory)

    renamed = tmp_path / "renamed.urdf"
    renamed.write_text(text.replace('name="panda_joint4"', 'name="elbow"'))
    with pytest.raises(PybulletCheckError, match=r"renamed\.urdf lacks the planning joints "
                                                 r"\['panda_joint4'\]"):
        check_execution_pybullet(dataclasses.replace(scene, robot=_robot_with(panda, renamed)),
                                 trajectory)


def test_the_check_refuses_what_it_cannot_run(straight_push):
    scene, trajectory, predicted = straight_push
    with pytest.raises(ExecutionCheckError, match="3 predicted states for"):
        check_execution_pybullet(scene, trajectory, [predicted] * 3)
    with pytest.raises(PybulletCheckError, match="positive effort limit"):
        check_execution_pybullet(scene, trajectory, options=PybulletOptions(effort=(87.0,) * 6))
    with pytest.raises(ValueError, match="position_gain"):
        PybulletOptions(position_gain=0.0)
    with pytest.raises(ValueError, match="timestep"):
        PybulletOptions(timestep=0.1)
