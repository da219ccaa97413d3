"""The product's 3D world: a scene as a MuJoCo model (docs/design.md "The 3D world"). The arm
comes from its URDF with real collision meshes, the table and the obstacles are static boxes,
and the objects are free rigid bodies with their masses, frictions and centres of mass. Both
the planner's 3D judge (`world3d.judge`, `planning.requests.judging`) and the execution check
(`world3d.execution`, the CLI's `--check-execution`, the benchmark, world_sim) stand on it.

    model = build_model(scene, ExecutionOptions(arm="servo"))

The arm (`ExecutionOptions.arm`) follows the positions linearly interpolated between the
trajectory points, as a joint trajectory controller given positions does:
- "ideal": kinematic; before every step the arm's joint positions and velocities are written
  from the reference, and a huge joint armature keeps contact impulses from slowing it;
- "servo": position actuators (kp, kv, the URDF's effort limits, gravity compensated, a
  velocity feed-forward) that contacts can slow or deflect.

The robot model is the scene's robot as its URDF describes it with real collision meshes
(`RobotConfig.geometry_urdf`: a robot config's `collision_urdf`, or its URDF when that one has
the meshes, as for an arm fitted by `rearrangement-robot fit`): the
planner's own contact capsules are what is being checked, so they must not be reused here.
Joints other than the planning joints (gripper fingers) are welded at their neutral position
(closed). MuJoCo reads STL and OBJ meshes. Frames as in the scene: the robot base frame, the
table top at `table.height`. Units: m, rad, s, kg.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import mujoco
import numpy as np

from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.files import FileProblem, resolve_uri
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.scene import MovableObject, Obstacle, Scene

ARM, OBJECT, STATIC = 1, 2, 4
"""Collision classes (contype bits). Arm: hits objects and the static world, not itself.
Objects: hit the arm and each other; object-table contact is an explicit pair carrying the
object's support friction. Table: hits the arm. Obstacles: hit the arm and the objects."""
TABLE_THICKNESS = 0.05


class ExecutionCheckError(RearrangementError):
    """The check cannot run (no real-geometry model for the robot, a malformed trajectory)."""


@dataclass(frozen=True)
class ExecutionOptions:
    arm: str = "ideal"
    """'ideal' (kinematic arm) or 'servo' (position actuators)."""
    timestep: float = 0.001
    """MuJoCo step, s (1 and 2 ms agree within 1 mm on easy_push)."""
    settle: float = 0.3
    """Simulated time before the trajectory starts (the objects settle on the table), s."""
    hold: float = 0.5
    """Simulated time after its end (the objects come to rest), s."""
    tip_angle: float = math.radians(30.0)
    """An object whose axis ends tilted more than this (rad) has toppled."""
    kp: tuple[float, ...] | None = None
    """Servo stiffness per joint, N m/rad (None: `servo_gains`)."""
    kv: tuple[float, ...] | None = None
    """Servo damping per joint, N m s/rad (None: `servo_gains`)."""
    effort: tuple[float, ...] | None = None
    """Joint torque limits, N m (None: the URDF's)."""
    divergence_bound: float = 0.0
    """The closed loop's watch: once an object is farther than this (m) from its predicted
    pose at a trajectory point, the arm holds where it is (the trajectory is stopped); needs
    the predicted states. 0: never."""
    contact_timeconst: float = 0.005
    """s: the time constant of every contact's reference response (MuJoCo's solref), how
    soon a penetration is undone. MuJoCo's default, 0.02 s, let a finger run 9 mm into the
    cylinder it pushed and spin it in place, where a rigid finger meets a rigid object
    (docs/experiments.md, 2026-11-27). MuJoCo asks for at least twice the timestep."""

    def __post_init__(self) -> None:
        if self.arm not in ("ideal", "servo"):
            raise ValueError(f"arm must be 'ideal' or 'servo', not {self.arm!r}")
        if not 0.0001 <= self.timestep <= 0.01:
            raise ValueError(f"timestep must be in [0.0001, 0.01] s, got {self.timestep}")
        if not 2.0 * self.timestep <= self.contact_timeconst <= 0.1:
            raise ValueError(f"contact_timeconst must be in [2 timestep, 0.1] s = "
                             f"[{2.0 * self.timestep:g}, 0.1] s, got {self.contact_timeconst}")


# -- the model ------------------------------------------------------------------------------------


LARGE_JOINT = 50.0
"""N m: joints with at least this effort limit get the large servo gains (`servo_gains`)."""


def servo_gains(robot: RobotModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(kp, kv, effort) per planning joint: the effort limits from the URDF; kp 3000 N m/rad
    and kv 150 N m s/rad for a joint whose effort limit is at least LARGE_JOINT, else 1000 and
    40 (the gains tuned on the first shipped arm, whose shoulder and elbow joints take 87 N m
    and wrist joints 12 N m)."""
    effort = np.array(robot.effort_limits, dtype=float)
    if np.any(effort <= 0):
        raise ExecutionCheckError(f"robot '{robot.name}': the servo arm needs a positive "
                                  f"effort limit on every planning joint in its URDF")
    large = effort >= LARGE_JOINT
    return np.where(large, 3000.0, 1000.0), np.where(large, 150.0, 40.0), effort


def _urdf_for_mujoco(path: Path) -> str:
    """The URDF with every mesh file name made absolute (package:// URIs resolved) and a
    <mujoco><compiler> element: visual meshes dropped, links kept as bodies."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise ExecutionCheckError(f"cannot read the arm's URDF {path} ({exc.strerror})") \
            from None

    def absolute(match: re.Match) -> str:
        name = match.group(1)
        try:
            file = resolve_uri(name)
        except FileProblem as exc:
            raise ExecutionCheckError(str(exc)) from None
        return f'filename="{file if file.is_absolute() else path.parent / file}"'

    text = re.sub(r'filename="([^"]+)"', absolute, text)
    compiler = ('<mujoco><compiler discardvisual="true" balanceinertia="true" '
                'fusestatic="false" autolimits="true"/></mujoco>')
    head, tag, tail = text.partition("<robot ")
    end = tail.index(">") + 1
    return head + tag + tail[:end] + "\n" + compiler + tail[end:]


def _arm_spec(robot: RobotModel) -> mujoco.MjSpec:
    """The arm alone from its collision URDF: planning joints free, every other joint (and its
    <mimic> equality) removed, which welds gripper fingers at their neutral position."""
    path = robot.config.geometry_urdf
    if path is None:
        raise ExecutionCheckError(f"robot '{robot.name}' has no URDF with collision geometry")
    try:
        spec = mujoco.MjSpec.from_string(_urdf_for_mujoco(path))
    except ValueError as exc:
        raise ExecutionCheckError(f"robot '{robot.name}': MuJoCo cannot load {path.name} "
                                  f"({exc}); it reads STL and OBJ collision meshes") from None
    for equality in list(spec.equalities):
        spec.delete(equality)
    keep = set(robot.joint_names)
    missing = keep - {j.name for j in spec.joints}
    if missing:
        raise ExecutionCheckError(f"robot '{robot.name}': {path.name} lacks the planning "
                                  f"joints {sorted(missing)}")
    for joint in list(spec.joints):
        if joint.name not in keep:
            spec.delete(joint)
    return spec


def arm_model(robot: RobotModel) -> mujoco.MjModel:
    """The arm alone as `build_model` loads it (real collision meshes, planning joints free):
    what the planner's contact shapes are fitted to."""
    return _arm_spec(robot).compile()


def build_model(scene: Scene, options: ExecutionOptions) -> mujoco.MjModel:
    """The arm (real collision meshes, gripper closed and rigid as the planner's hand), the
    table, the obstacles and the objects as free bodies."""
    spec = _arm_spec(scene.robot)
    spec.option.timestep = options.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    _set_up_arm(spec, scene.robot, options)
    _add_world(spec, scene)
    model = spec.compile()
    model.geom_solref[:, 0] = options.contact_timeconst     # arm-object, object-object
    model.pair_solref[:, 0] = options.contact_timeconst     # object-table (explicit pairs)
    return model


def _set_up_arm(spec: mujoco.MjSpec, robot: RobotModel, options: ExecutionOptions) -> None:
    kp, kv, effort = servo_gains(robot)
    kp = np.asarray(options.kp if options.kp is not None else kp)
    kv = np.asarray(options.kv if options.kv is not None else kv)
    effort = np.asarray(options.effort if options.effort is not None else effort)
    for body in spec.bodies:
        if body.name != "world":
            body.gravcomp = 1.0
            for geom in body.geoms:
                geom.contype, geom.conaffinity = ARM, OBJECT | STATIC
                geom.friction = [0.01, 0.005, 0.0001]   # max() mixing: the object's friction
    for i, name in enumerate(robot.joint_names):
        joint = spec.joint(name)
        joint.damping = [0.0, 0.0, 0.0]
        joint.armature = 1e4 if options.arm == "ideal" else 0.1
        if options.arm == "servo":
            actuator = spec.add_actuator(name=f"servo_{name}", target=name,
                                         trntype=mujoco.mjtTrn.mjTRN_JOINT)
            actuator.set_to_position(kp=kp[i], kv=kv[i])
            actuator.forcelimited = True
            actuator.forcerange = [-effort[i], effort[i]]


def _add_world(spec: mujoco.MjSpec, scene: Scene) -> None:
    world, table, top = spec.worldbody, scene.table, scene.table.height
    slab = world.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_BOX,
                          size=[table.size[0] / 2, table.size[1] / 2, TABLE_THICKNESS / 2],
                          pos=[table.center[0], table.center[1], top - TABLE_THICKNESS / 2])
    slab.contype, slab.conaffinity = STATIC, ARM
    for box in scene.obstacles:
        geom = _prism(world, box, at=(box.pose[0], box.pose[1], top + box.height / 2))
        geom.contype, geom.conaffinity = STATIC, ARM | OBJECT
    for obj in scene.objects:
        body = world.add_body(name=obj.name, pos=[obj.pose[0], obj.pose[1], top + obj.height / 2],
                              quat=_yaw_quaternion(obj.pose[2]))
        body.add_freejoint(name=obj.name)
        geom = _prism(body, obj, at=None)
        geom.mass = obj.mass
        if obj.support.centre != (0.0, 0.0):
            _shift_centre_of_mass(body, obj)
        geom.contype, geom.conaffinity = OBJECT, ARM | OBJECT
        geom.friction = [obj.pusher_friction, 0.005, 0.0001]
        spec.add_pair(geomname1="table", geomname2=obj.name, condim=3,
                      friction=[obj.support_friction] * 2 + [0.005, 0.0001, 0.0001])


def _shift_centre_of_mass(body: Any, obj: MovableObject) -> None:
    """The object's mass centred over its drawn centre of friction (`SupportPressure.centre`):
    its weight then rests off the footprint's centre, the support contacts carry it unequally
    and the friction load is centred there too. The inertia is the uniform prism's about its
    own centre (a few mm of offset change it by under 5 %)."""
    sx, sy, sz = (float(v) for v in obj.size)
    m = float(obj.mass)
    if obj.shape == "cylinder":
        r2 = (0.5 * sx) ** 2
        inertia = [m * (3 * r2 + sz * sz) / 12, m * (3 * r2 + sz * sz) / 12, m * r2 / 2]
    else:
        inertia = [m * (sy * sy + sz * sz) / 12, m * (sx * sx + sz * sz) / 12,
                   m * (sx * sx + sy * sy) / 12]
    body.explicitinertial = True
    body.mass = m
    body.ipos = [obj.support.centre[0], obj.support.centre[1], 0.0]
    body.inertia = inertia


def _prism(parent: Any, prism: MovableObject | Obstacle, at: Sequence[float] | None) -> Any:
    kwargs: dict[str, Any] = {"name": prism.name}
    if at is not None:
        kwargs.update(pos=list(at), quat=_yaw_quaternion(prism.pose[2]))
    half = np.asarray(prism.size, dtype=float) / 2
    if prism.shape == "box":
        return parent.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=half.tolist(), **kwargs)
    return parent.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                           size=[half[0], half[2], 0.0], **kwargs)


def _yaw_quaternion(yaw: float) -> list[float]:
    return [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
