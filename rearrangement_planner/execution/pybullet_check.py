"""A second, independent execution engine: a plan's joint trajectory played open loop in
PyBullet (Bullet's Featherstone multibodies, headless DIRECT mode), the way a user's joint
trajectory controller would play it, and what happened to every object. It answers the
question `world3d.execution.check_execution` answers in MuJoCo, with another contact model,
another solver and another servo, so that a plan judged good by both is not good only by one
engine's accident.

    report = check_execution_pybullet(output.scene, output.trajectory, output.trajectory_states)
    report.reached, report.goal_distance_m, report.objects[0].pose, report.toppled
    perturbed = check_perturbed_pybullet(scene, output.trajectory, trials=10, seed=0)

The world mirrors `world3d.mujoco_model`'s:
- the arm is the scene robot's URDF with its real collision meshes
  (`RobotConfig.geometry_urdf`, `package://` URIs resolved, visual meshes dropped, STL or OBJ
  read as their convex hulls as MuJoCo does), its base fixed at the origin; every joint but
  the planning joints is made fixed at its neutral position (the gripper closed, as the
  planner's hand); no self-collision; gravity compensated (each step's gravity torques of
  the measured configuration, `calculateInverseDynamics`, applied on top of the servo);
- the servo: Bullet's joint motors (POSITION_CONTROL) track the positions linearly
  interpolated between the trajectory points with the segment's slope as velocity
  feed-forward, within the URDF's effort limits. A Bullet motor is a velocity constraint
  solved with the contacts: it asks for qdot_ref + position_gain (q_ref - q) / dt, so a
  tracking error decays by (1 - position_gain) a step and, unlike MuJoCo's kp/kv servo, a
  contact does not deflect the arm until it needs more than the effort limit;
- the table is a static box whose top is at `table.height`, the obstacles static boxes
  standing on it, the objects free boxes and cylinders with their masses, their centres of
  mass moved over the drawn centre of friction (`SupportPressure.centre`) and the uniform
  prism's inertia about it.

Friction. Bullet combines two colliders' coefficients by multiplying them and has no
per-pair coefficient, while an object has one coefficient with the table (support_friction)
and another with the arm (pusher_friction). Each object is therefore one multibody with two
colliders of its full shape, rigidly joined and each carrying half its mass: its *side*
(lateral friction pusher_friction) meets the arm, the other objects and the obstacles, its
*foot* (support_friction) meets the table only (collision filter groups); the table and the
arm's links have friction 1. So object-table is support_friction and arm-object
pusher_friction exactly, as in MuJoCo. Object-object is pusher_a * pusher_b and
object-obstacle pusher_friction (MuJoCo: the larger of the two, and 1). No torsional or
rolling friction, no velocity damping (Bullet's default 0.04 removed), elliptic friction
cones (`enableConeFriction`), as in MuJoCo.

Contacts are Bullet's rigid constraints (no compliance: a finger stays within 0.1 mm of the
face it pushes, 0.05 mm measured), solved with up to `PybulletOptions.solver_iterations`
iterations a step to a tight residual (`SOLVER_RESIDUAL`), the objects' friction anchored
(`frictionAnchor`): so what nobody touches stays where it is, within 0.01 mm and 0.5 mrad
over 10-20 s (with Bullet's defaults a cylinder left alone turned 3.5 mrad in 10 s). The
joints' URDF damping is removed, as MuJoCo's model removes it.

Measured against MuJoCo's servo arm on the pushes of test/world3d/test_execution.py (some are
kept in test/execution/test_pybullet_check.py): the straight push ends 0.1 mm from MuJoCo's
box; a push 3 cm off centre turns it 1.021 rad to MuJoCo's 1.018, and with its centre of mass
1 cm towards or away from the finger 0.48 and 1.38 rad to 0.68 and 1.30 (how rigid contacts
share a box's weight among its corners is the least determined part of either model); a row
of two or three objects ends within 2 mm; a tall box topples in both. The plan of
default.yaml (seed 1, 20 s) reaches its goal in both, the goal object 1.7 cm and 0.23 rad
apart (a sliding push: 0.5 cm between this engine's own solver settings); one execution of
it takes 1.6 s (MuJoCo: 0.45 s).

Not here: the ideal (kinematic) arm and the closed loop's divergence watch
(`ExecutionOptions.arm`, `divergence_bound`); the report's arm is always "servo".

Every execution builds its world in a fresh `pybullet.connect(pybullet.DIRECT)` client and
disconnects it afterwards: nothing global is left behind, and executions can run in threads
or processes side by side. pybullet is imported when the first execution starts (it prints
its build time on import). Frames as in the scene: the robot base frame, the table top at
`table.height`. Units: m, rad, s, kg.
"""

from __future__ import annotations

import math
import tempfile
import time
import xml.etree.ElementTree as ElementTree
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from rearrangement_planner.model.command import Command
from rearrangement_planner.model.files import FileProblem, resolve_uri
from rearrangement_planner.model.perturbation import Perturbation
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.scene import MovableObject, Obstacle, Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.world3d.execution import (
    ERROR_THRESHOLD,
    ExecutionReport,
    ObjectOutcome,
    PerturbedReport,
    TimedPath,
    check_predicted,
    controller_command,
    perturbed_worlds,
)
from rearrangement_planner.world3d.mujoco_model import TABLE_THICKNESS, ExecutionCheckError

GRAVITY = 9.81
"""m/s^2, as MuJoCo's default."""
SOLVER_RESIDUAL = 1e-10
"""Bullet's constraint solver stops iterating once its residual is below this. Bullet's
default, 1e-7, stopped it early enough that untouched objects crept on the table (0.2 mm and
0.4 mrad over the 20 s plan of default.yaml, seed 1); at 1e-10 they stay within 0.01 mm, for
about 25 % more wall time (1e-12: 1 um, 50 % more)."""

ARM, OBJECT, FOOT, TABLE, OBSTACLE = 1, 2, 4, 8, 16
"""Collision filter groups. Bullet lets two colliders meet when each one's group is in the
other's mask."""
MASKS = {ARM: OBJECT | TABLE | OBSTACLE, OBJECT: ARM | OBJECT | OBSTACLE, FOOT: TABLE,
         TABLE: ARM | FOOT, OBSTACLE: ARM | OBJECT}
"""Arm: objects' sides and the static world, not itself. Object side: the arm, the other
objects' sides, the obstacles. Object foot: the table only. Table: the arm and the feet.
Obstacles: the arm and the objects' sides."""


class PybulletCheckError(ExecutionCheckError):
    """The PyBullet check cannot run: no usable URDF with collision geometry for the robot
    (missing or unreadable, a mesh PyBullet cannot find, planning joints it lacks), no
    positive effort limits, or pybullet is not installed. An `ExecutionCheckError`, so that
    what catches the MuJoCo check's refusals catches these."""


@dataclass(frozen=True)
class PybulletOptions:
    """How the PyBullet execution runs (module doc)."""

    timestep: float = 0.001
    """Bullet step, s (as MuJoCo's `ExecutionOptions.timestep`)."""
    settle: float = 0.3
    """Simulated time before the trajectory starts (the objects settle on the table), s."""
    hold: float = 0.5
    """Simulated time after its end (the objects come to rest), s."""
    tip_angle: float = math.radians(30.0)
    """An object whose axis ends tilted more than this (rad) has toppled."""
    position_gain: float = 0.2
    """The joint motors' position gain: the share of a tracking error the motor asks to
    undo in one step (0.2: a time constant of about 5 steps, 5 ms at 1 ms; 0.05 to 1 end
    a straight push within 0.1 mm of each other)."""
    velocity_gain: float = 1.0
    """The joint motors' velocity gain: 1 asks for the reference velocity (the
    feed-forward) plus the position term."""
    effort: tuple[float, ...] | None = None
    """Joint torque limits, N m (None: the URDF's, `RobotModel.effort_limits`)."""
    solver_iterations: int = 100
    """Bullet's constraint solver iterations a step, at most (`SOLVER_RESIDUAL`)."""

    def __post_init__(self) -> None:
        if not 0.0001 <= self.timestep <= 0.01:
            raise ValueError(f"timestep must be in [0.0001, 0.01] s, got {self.timestep}")
        if self.settle < 0.0 or self.hold < 0.0:
            raise ValueError(f"settle and hold must be >= 0 s, got {self.settle}, {self.hold}")
        if not 0.0 < self.position_gain <= 1.0:
            raise ValueError(f"position_gain must be in (0, 1], got {self.position_gain}")
        if not 0.0 < self.velocity_gain <= 1.0:
            raise ValueError(f"velocity_gain must be in (0, 1], got {self.velocity_gain}")
        if self.solver_iterations < 1:
            raise ValueError(f"solver_iterations must be >= 1, got {self.solver_iterations}")


# -- the public checks ----------------------------------------------------------------------------


def check_execution_pybullet(scene: Scene, trajectory: TimedPath,
                             predicted: Sequence[State] | None = None,
                             options: PybulletOptions | None = None) -> ExecutionReport:
    """Play `trajectory` open loop in PyBullet on `scene` with the servo-driven arm (module
    doc). `predicted`, the planner's state at every trajectory point
    (`PlanOutput.trajectory_states`), is compared with what happens, object by object, as
    `world3d.execution.check_execution` does."""
    options = options or PybulletOptions()
    check_predicted(trajectory, predicted)
    started = time.perf_counter()
    command = controller_command(trajectory, scene.robot.joint_names)
    effort = _effort(scene.robot, options)
    urdf = _urdf_text(scene.robot)
    pybullet = _pybullet()
    client = pybullet.connect(pybullet.DIRECT)
    if client < 0:
        raise PybulletCheckError("cannot start a PyBullet DIRECT client")
    try:
        run = _Execution(pybullet, client, scene, urdf, command, effort, predicted, options)
        run.play()
        return run.report(time.perf_counter() - started)
    finally:
        pybullet.disconnect(physicsClientId=client)


def check_perturbed_pybullet(scene: Scene, trajectory: TimedPath, trials: int, seed: int = 0,
                             options: PybulletOptions | None = None,
                             perturbation: Perturbation | None = None) -> PerturbedReport:
    """`trials` executions of `trajectory` in the worlds `world3d.execution.check_perturbed`
    draws (`perturbed_worlds`, the same `seed` gives the same worlds): how often the goal
    object still reaches its region in PyBullet."""
    reports = tuple(check_execution_pybullet(world, trajectory, None, options)
                    for world in perturbed_worlds(scene, trials, seed, perturbation))
    return PerturbedReport(trials, sum(r.reached for r in reports), reports)


# -- the arm's URDF -------------------------------------------------------------------------------


def _pybullet() -> ModuleType:
    try:
        import pybullet
    except ImportError:
        raise PybulletCheckError("the PyBullet check needs the pybullet package "
                                 "(requirements.txt)") from None
    return pybullet


def _effort(robot: RobotModel, options: PybulletOptions) -> np.ndarray:
    effort = np.asarray(options.effort if options.effort is not None else robot.effort_limits,
                        dtype=float)
    if effort.shape != (len(robot.joint_names),) or np.any(effort <= 0.0):
        raise PybulletCheckError(f"robot '{robot.name}': the servo arm needs a positive effort "
                                 f"limit on each of its {len(robot.joint_names)} planning "
                                 f"joints, got {effort.tolist()}")
    return effort


def _urdf_text(robot: RobotModel) -> str:
    """The robot's collision URDF as PyBullet loads it: mesh file names absolute (`package://`
    URIs resolved, as `world3d.mujoco_model` does), visual elements dropped, every joint but
    the planning joints made fixed at its neutral position (0: the gripper closed) and its
    <mimic> removed."""
    path = robot.config.geometry_urdf
    if path is None:
        raise PybulletCheckError(f"robot '{robot.name}' has no URDF with collision geometry")
    try:
        root = ElementTree.fromstring(path.read_text())
    except OSError as exc:
        raise PybulletCheckError(f"cannot read the arm's URDF {path} ({exc.strerror})") \
            from None
    except ElementTree.ParseError as exc:
        raise PybulletCheckError(f"the arm's URDF {path} is not valid XML ({exc})") from None
    for link in root.iter("link"):
        for visual in link.findall("visual"):
            link.remove(visual)
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        try:
            file = resolve_uri(name)
        except FileProblem as exc:
            raise PybulletCheckError(f"{path}: {exc}") from None
        file = file if file.is_absolute() else path.parent / file
        if not file.is_file():
            raise PybulletCheckError(f"{path}: collision mesh {name} not found ({file})")
        if file.suffix.lower() not in (".stl", ".obj"):
            raise PybulletCheckError(f"{path}: collision mesh {file.name}: the PyBullet check "
                                     f"reads STL and OBJ meshes")
        mesh.set("filename", str(file))
    joints = {joint.get("name", ""): joint for joint in root.iter("joint")}
    missing = [n for n in robot.joint_names if n not in joints]
    if missing:
        raise PybulletCheckError(f"robot '{robot.name}': {path.name} lacks the planning "
                                 f"joints {missing}")
    for name, joint in joints.items():
        if name not in robot.joint_names and joint.get("type") != "fixed":
            joint.set("type", "fixed")
            for tag in ("mimic", "axis", "limit", "dynamics", "calibration",
                        "safety_controller"):
                for element in joint.findall(tag):
                    joint.remove(element)
    return ElementTree.tostring(root, encoding="unicode")


# -- the execution --------------------------------------------------------------------------------


class _Execution:
    """One world in one PyBullet client, the command played in it, and the bookkeeping."""

    def __init__(self, pybullet: ModuleType, client: int, scene: Scene, urdf: str,
                 command: Command, effort: np.ndarray, predicted: Sequence[State] | None,
                 options: PybulletOptions):
        self.p, self.client = pybullet, client
        self.scene, self.command, self.effort = scene, command, effort
        self.predicted, self.options = predicted, options
        self._functions: dict[str, Callable[..., Any]] = {}
        call = self.call
        call("setGravity")(0.0, 0.0, -GRAVITY)
        call("setPhysicsEngineParameter")(fixedTimeStep=options.timestep, numSubSteps=0,
                                          numSolverIterations=options.solver_iterations,
                                          solverResidualThreshold=SOLVER_RESIDUAL,
                                          enableConeFriction=1,
                                          deterministicOverlappingPairs=1)
        self.arm, self.joints = self._load_arm(urdf)
        self.table = self._add_table()
        self.obstacles = [self._add_obstacle(box) for box in scene.obstacles]
        self.bodies = [self._add_object(obj) for obj in scene.objects]
        self.offsets = np.array([[*obj.support.centre, 0.0] for obj in scene.objects],
                                dtype=float).reshape(-1, 3)
        """Each object's centre of mass in its own frame (Bullet reports the base's centre
        of mass, the scene its geometric centre)."""
        self.static = {self.table: "table"}
        self.static.update(zip(self.obstacles, (box.name for box in scene.obstacles),
                               strict=True))
        self.names = dict(zip(self.bodies, scene.object_names, strict=True))
        self.reference, self.slope = _sampled(command, options)
        m = len(scene.objects)
        self.min_up = np.ones(m)
        """The least z component of each object's own z axis so far (cos of its largest
        tilt)."""
        self.max_error = np.zeros(m)
        self.error_from: list[float | None] = [None] * m
        self.joint_error = np.zeros(len(self.joints))
        self.executed: list[list[tuple[float, float, float]]] = []
        self.next_point = 0
        self.contacts: set[str] = set()
        self.collisions: dict[str, float] = {}
        self.link_names = {-1: self._link_name(-1)}
        self.steps = 0
        self.q = np.asarray(command.sample(0.0), dtype=float)

    def call(self, name: str) -> Callable[..., Any]:
        """pybullet's function `name` bound to this execution's client."""
        bound = self._functions.get(name)
        if bound is None:
            function, client = getattr(self.p, name), self.client

            def bound(*args: Any, **kwargs: Any) -> Any:
                return function(*args, physicsClientId=client, **kwargs)
            self._functions[name] = bound
        return bound

    # -- the world --

    def _load_arm(self, urdf: str) -> tuple[int, list[int]]:
        p, call, robot = self.p, self.call, self.scene.robot
        with tempfile.TemporaryDirectory(prefix="pybullet_check_") as folder:
            file = Path(folder) / "arm.urdf"
            file.write_text(urdf)
            try:
                arm = call("loadURDF")(str(file), basePosition=[0.0, 0.0, 0.0],
                                       useFixedBase=True, flags=p.URDF_USE_INERTIA_FROM_FILE)
            except p.error as exc:
                raise PybulletCheckError(
                    f"robot '{robot.name}': PyBullet cannot load "
                    f"{robot.config.geometry_urdf} ({exc})") from None
        index = {call("getJointInfo")(arm, j)[1].decode(): j
                 for j in range(call("getNumJoints")(arm))}
        joints = [index[name] for name in robot.joint_names]
        for link in range(-1, call("getNumJoints")(arm)):
            call("changeDynamics")(arm, link, lateralFriction=1.0, spinningFriction=0.0,
                                   rollingFriction=0.0, restitution=0.0, linearDamping=0.0,
                                   angularDamping=0.0, jointDamping=0.0)
            call("setCollisionFilterGroupMask")(arm, link, ARM, MASKS[ARM])
        for j, q in zip(joints, self.command.sample(0.0), strict=True):
            call("resetJointState")(arm, j, float(q), 0.0)
        return arm, joints

    def _add_table(self) -> int:
        table, call = self.scene.table, self.call
        shape = call("createCollisionShape")(
            self.p.GEOM_BOX, halfExtents=[table.size[0] / 2, table.size[1] / 2,
                                          TABLE_THICKNESS / 2])
        body = call("createMultiBody")(
            baseMass=0.0, baseCollisionShapeIndex=shape,
            basePosition=[table.center[0], table.center[1], table.height - TABLE_THICKNESS / 2])
        self._surface(body, -1, 1.0, TABLE)
        return int(body)

    def _add_obstacle(self, box: Obstacle) -> int:
        call = self.call
        body = call("createMultiBody")(
            baseMass=0.0, baseCollisionShapeIndex=self._shape(box),
            basePosition=[box.pose[0], box.pose[1], self.scene.table.height + box.height / 2],
            baseOrientation=_yaw_quaternion(box.pose[2]))
        self._surface(body, -1, 1.0, OBSTACLE)
        return int(body)

    def _add_object(self, obj: MovableObject) -> int:
        """The side (base) and the foot (a link on a fixed joint) of one object (module doc,
        Friction), half its mass each, both centred over its centre of friction."""
        call, p = self.call, self.p
        centre = [obj.support.centre[0], obj.support.centre[1], 0.0]
        half = 0.5 * float(obj.mass)
        body = call("createMultiBody")(
            baseMass=half, baseCollisionShapeIndex=self._shape(obj),
            basePosition=[obj.pose[0], obj.pose[1], self.scene.table.height + obj.height / 2],
            baseOrientation=_yaw_quaternion(obj.pose[2]), baseInertialFramePosition=centre,
            linkMasses=[half], linkCollisionShapeIndices=[self._shape(obj)],
            linkVisualShapeIndices=[-1], linkPositions=[[0.0, 0.0, 0.0]],
            linkOrientations=[[0.0, 0.0, 0.0, 1.0]], linkInertialFramePositions=[centre],
            linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]], linkParentIndices=[0],
            linkJointTypes=[p.JOINT_FIXED], linkJointAxis=[[0.0, 0.0, 1.0]])
        self._surface(body, -1, obj.pusher_friction, OBJECT)
        self._surface(body, 0, obj.support_friction, FOOT)
        for link in (-1, 0):
            call("changeDynamics")(body, link, linearDamping=0.0, angularDamping=0.0,
                                   frictionAnchor=1,
                                   activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING)
        return int(body)

    def _shape(self, prism: MovableObject | Obstacle) -> int:
        size = np.asarray(prism.size, dtype=float)
        if prism.shape == "box":
            return int(self.call("createCollisionShape")(self.p.GEOM_BOX,
                                                         halfExtents=(size / 2).tolist()))
        return int(self.call("createCollisionShape")(self.p.GEOM_CYLINDER,
                                                     radius=float(size[0] / 2),
                                                     height=float(size[2])))

    def _surface(self, body: int, link: int, friction: float, group: int) -> None:
        self.call("changeDynamics")(body, link, lateralFriction=float(friction),
                                    spinningFriction=0.0, rollingFriction=0.0, restitution=0.0)
        self.call("setCollisionFilterGroupMask")(body, link, group, MASKS[group])

    def _link_name(self, link: int) -> str:
        if link == -1:
            return str(self.call("getBodyInfo")(self.arm)[0].decode())
        return str(self.call("getJointInfo")(self.arm, link)[12].decode())

    # -- the play --

    def play(self) -> None:
        """Settle, the trajectory, the hold (`PybulletOptions`), one Bullet step at a time:
        gravity compensated, the motors given the reference and its slope at the step's
        start (`_sampled`)."""
        p, call, opts = self.p, self.call, self.options
        step, states = call("stepSimulation"), call("getJointStates")
        motors, dynamics = call("setJointMotorControlArray"), call("calculateInverseDynamics")
        arm, joints, n = self.arm, self.joints, len(self.joints)
        zeros = [0.0] * n
        gains_p, gains_v = [opts.position_gain] * n, [opts.velocity_gain] * n
        forces = self.effort.tolist()
        duration, dt = self.command.duration, opts.timestep
        total = len(self.slope)
        q = self.q.tolist()
        for k in range(total):
            gravity = dynamics(arm, q, zeros, zeros)
            motors(arm, joints, p.POSITION_CONTROL, targetPositions=self.reference[k].tolist(),
                   targetVelocities=self.slope[k].tolist(), forces=forces,
                   positionGains=gains_p, velocityGains=gains_v)
            motors(arm, joints, p.TORQUE_CONTROL, forces=gravity)
            step()
            self.steps = k + 1
            t = (k + 1) * dt - opts.settle                      # trajectory time now
            q = [s[0] for s in states(arm, joints)]
            if 0.0 <= t <= duration:
                error = np.abs(np.asarray(q) - self.reference[k + 1])
                np.maximum(self.joint_error, error, out=self.joint_error)
            self._observe(t)
        self.q = np.asarray(q, dtype=float)

    def _observe(self, t: float) -> None:
        poses, up = self._poses()
        np.minimum(self.min_up, up, out=self.min_up)
        self._contacts()
        times = self.command.times
        while self.next_point < len(times) and times[self.next_point] <= t + 1e-9:
            self.executed.append([(float(x), float(y), float(yaw)) for x, y, yaw in poses])
            if self.predicted is not None:
                self._compare(self.next_point, poses, t)
            self.next_point += 1

    def _poses(self) -> tuple[np.ndarray, np.ndarray]:
        """(M, 3) object poses (x, y, yaw) of their geometric centres and (M,) the z component
        of each one's own z axis."""
        get = self.call("getBasePositionAndOrientation")
        m = len(self.bodies)
        poses, up = np.zeros((m, 3)), np.ones(m)
        for i, body in enumerate(self.bodies):
            position, (x, y, z, w) = get(body)
            rotation = np.array([
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
            centre = np.asarray(position) - rotation @ self.offsets[i]
            poses[i] = (centre[0], centre[1], math.atan2(rotation[1, 0], rotation[0, 0]))
            up[i] = rotation[2, 2]
        return poses, up

    def _contacts(self) -> None:
        """This step's arm-table and arm-obstacle penetrations (deepest per pair) and the
        object pairs that touch (contacts with a distance of at most 0)."""
        points = self.call("getContactPoints")
        for contact in points(bodyA=self.arm):
            other, depth = contact[2], -float(contact[8])
            if other in self.static and depth > 0.0:
                link = contact[3]
                if link not in self.link_names:
                    self.link_names[link] = self._link_name(link)
                key = f"{self.link_names[link]}->{self.static[other]}"
                self.collisions[key] = max(self.collisions.get(key, 0.0), depth)
        for body in self.bodies:
            for contact in points(bodyA=body, linkIndexA=-1):
                other = contact[2]
                if other in self.names and other > body and contact[8] <= 0.0:
                    self.contacts.add("<->".join(sorted((self.names[body],
                                                         self.names[other]))))

    def _compare(self, point: int, poses: np.ndarray, t: float) -> None:
        assert self.predicted is not None
        expected = self.predicted[point].objects[:, :2]
        errors = np.hypot(*(poses[:, :2] - expected).T)
        for i, error in enumerate(errors):
            self.max_error[i] = max(self.max_error[i], float(error))
            if error > ERROR_THRESHOLD and self.error_from[i] is None:
                self.error_from[i] = round(t, 3)

    # -- the report --

    def report(self, wall_time: float) -> ExecutionReport:
        scene = self.scene
        poses, up = self._poses()
        outcomes = tuple(self._outcome(i, obj, poses[i], float(up[i]))
                         for i, obj in enumerate(scene.objects))
        goal = outcomes[scene.goal_index]
        distance = scene.goal.distance(np.asarray(goal.pose[:2]))
        reached = distance <= scene.goal.radius and not any(o.toppled for o in outcomes)
        paths = np.array(self.executed, dtype=float).reshape(-1, len(self.bodies), 3)
        return ExecutionReport(
            "servo", bool(reached), distance, scene.goal.radius, outcomes,
            tuple(sorted(self.contacts)), dict(self.collisions),
            float(self.joint_error.max(initial=0.0)), self.steps * self.options.timestep,
            wall_time, paths, self.q.copy())

    def _outcome(self, i: int, obj: MovableObject, pose: np.ndarray,
                 up: float) -> ObjectOutcome:
        x, y, yaw = (float(v) for v in pose)
        predicted = final = largest = None
        if self.predicted is not None:
            px, py, pyaw = (float(v) for v in self.predicted[-1].objects[i])
            predicted = (px, py, pyaw)
            final = float(math.hypot(x - px, y - py))
            largest = max(float(self.max_error[i]), final)
        tilt = math.acos(max(-1.0, min(1.0, up)))
        worst = math.acos(max(-1.0, min(1.0, float(self.min_up[i]))))
        return ObjectOutcome(obj.name, (x, y, yaw), predicted, final, largest,
                             self.error_from[i],
                             float(math.hypot(x - obj.pose[0], y - obj.pose[1])),
                             math.degrees(worst), tilt > self.options.tip_angle)


def _sampled(command: Command, options: PybulletOptions) -> tuple[np.ndarray, np.ndarray]:
    """The command at every step's start time, from the settling to the end of the hold:
    positions (K + 1, n) and the segment slopes (K, n), as `world3d.execution` samples it."""
    dt = options.timestep
    count = int(math.ceil((options.settle + command.duration + options.hold) / dt - 1e-9))
    t = np.arange(count + 1) * dt - options.settle
    times, positions = command.times, command.positions
    reference = np.stack([np.interp(t, times, positions[:, j])
                          for j in range(positions.shape[1])], axis=1)
    slope = np.zeros((count, positions.shape[1]))
    if times.size > 1:
        segment = np.clip(np.searchsorted(times, t[:-1], side="right") - 1, 0, times.size - 2)
        rates = np.diff(positions, axis=0) / np.diff(times)[:, None]
        moving = (t[:-1] >= 0.0) & (t[:-1] < command.duration)
        slope[moving] = rates[segment[moving]]
    return reference, slope


def _yaw_quaternion(yaw: float) -> list[float]:
    """Bullet's (x, y, z, w) quaternion of a rotation by `yaw` about z."""
    return [0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)]
