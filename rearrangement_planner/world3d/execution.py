"""The execution check (docs/design.md "Execution check"): a plan's joint trajectory played
open loop in the product's 3D world (`world3d.mujoco_model`), the way a user's joint trajectory
controller would play it, and what happened to every object.

    report = check_execution(output.scene, output.trajectory, output.trajectory_states)
    report.reached, report.goal_distance_m, report.objects[0].max_error_m, report.tipped

One execution steps in Python, so that it can record contacts, compare every object with its
prediction as it goes and stop the arm (the closed loop's watch); the planner's judge
(`world3d.judge`) runs many at once in MuJoCo's own threads instead.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import mujoco
import numpy as np

from rearrangement_planner.model.command import Command
from rearrangement_planner.model.perturbation import Perturbation
from rearrangement_planner.model.scene import MovableObject, Scene
from rearrangement_planner.model.state import State
from rearrangement_planner.world3d.mujoco_model import (
    ARM,
    STATIC,
    ExecutionCheckError,
    ExecutionOptions,
    build_model,
)

ERROR_THRESHOLD = 0.01
"""Predicted-vs-executed distance (m) past which an object's prediction counts as lost."""


class TimedPath(Protocol):
    """A timed joint trajectory (`planning.requests.trajectory.Trajectory`): the joint names in
    the column order of `positions` (N, n), and `times` (N,) s strictly increasing from 0."""

    @property
    def joint_names(self) -> tuple[str, ...]: ...

    @property
    def times(self) -> np.ndarray: ...

    @property
    def positions(self) -> np.ndarray: ...

    def __len__(self) -> int: ...


@dataclass(frozen=True)
class ObjectOutcome:
    """What happened to one object."""

    name: str
    pose: tuple[float, float, float]
    """Executed final pose (x, y, yaw)."""
    predicted: tuple[float, float, float] | None
    """The plan's final pose, if a prediction was given."""
    final_error_m: float | None
    """Executed vs predicted final centre distance."""
    max_error_m: float | None
    """Largest predicted-vs-executed centre distance at the trajectory points."""
    error_from_s: float | None
    """Trajectory time at which that distance first exceeded ERROR_THRESHOLD (None: never)."""
    moved_m: float
    max_tilt_deg: float
    toppled: bool


@dataclass(frozen=True)
class ExecutionReport:
    """One execution (docs/design.md "Execution check")."""

    arm: str
    reached: bool
    """The goal object ended inside its goal region and nothing toppled."""
    goal_distance_m: float
    goal_radius_m: float
    objects: tuple[ObjectOutcome, ...]
    object_contacts: tuple[str, ...]
    """Pairs 'a<->b' of objects that touched (the planner does not model it)."""
    arm_collisions: dict[str, float] = field(default_factory=dict)
    """'link->table' or 'link->obstacle': deepest penetration, m (the plan hits the world)."""
    max_tracking_error_rad: float = 0.0
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    executed_paths: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3)))
    """(T, M, 3) executed object poses (x, y, yaw) at the T trajectory points."""
    final_q: np.ndarray = field(default_factory=lambda: np.zeros(0))
    """The arm's configuration at the end (rad, planning-joint order)."""
    stopped: str = ""
    """Why the watch (`ExecutionOptions.divergence_bound`) stopped the arm ("" when it did
    not)."""
    stopped_at_s: float = 0.0
    """The trajectory time at which it stopped it."""

    @property
    def toppled(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.objects if o.toppled)

    def final_state(self) -> State:
        """Where the arm and the objects ended (x, y, yaw): what a closed loop observes."""
        return State(self.final_q, np.array([o.pose for o in self.objects], dtype=float))

    def to_dict(self) -> dict[str, Any]:
        record = {k: v for k, v in self.__dict__.items()
                  if k not in ("objects", "executed_paths", "final_q")}
        record["object_contacts"] = list(self.object_contacts)
        record["toppled"] = list(self.toppled)
        record["objects"] = {o.name: {k: v for k, v in o.__dict__.items() if k != "name"}
                             for o in self.objects}
        return record


# -- the model ------------------------------------------------------------------------------------


# -- the execution --------------------------------------------------------------------------------


def check_predicted(trajectory: TimedPath, predicted: Sequence[State] | None) -> None:
    """Raise ExecutionCheckError unless `predicted` (when given) has a state for every
    trajectory point."""
    if predicted is not None and len(predicted) != len(trajectory):
        raise ExecutionCheckError(f"{len(predicted)} predicted states for {len(trajectory)} "
                                  f"trajectory points")


def check_execution(scene: Scene, trajectory: TimedPath,
                    predicted: Sequence[State] | None = None,
                    options: ExecutionOptions | None = None) -> ExecutionReport:
    """Play `trajectory` open loop in MuJoCo on `scene` (module doc). `predicted`, the planner's
    state at every trajectory point (`PlanOutput.trajectory_states`), is compared with what
    happens, object by object."""
    options = options or ExecutionOptions()
    check_predicted(trajectory, predicted)
    started = time.perf_counter()
    command = controller_command(trajectory, scene.robot.joint_names)
    run = Execution(build_model(scene, options), scene, command, predicted, options)
    run.begin()
    run.advance(run.command.duration + options.hold)
    return run.report(time.perf_counter() - started)


def controller_command(trajectory: TimedPath, joints: Sequence[str]) -> Command:
    """The trajectory in the robot's joint order, as the controller plays it."""
    names = list(trajectory.joint_names)
    missing = [n for n in joints if n not in names]
    if missing:
        raise ExecutionCheckError(f"the trajectory has no {', '.join(missing)}")
    order = [names.index(n) for n in joints]
    return Command(np.asarray(trajectory.times, dtype=float),
                   np.asarray(trajectory.positions, dtype=float)[:, order])


class Execution:
    """One simulated execution and its bookkeeping."""

    def __init__(self, model: mujoco.MjModel, scene: Scene, command: Command,
                 predicted: Sequence[State] | None, options: ExecutionOptions):
        self.model, self.scene, self.options = model, scene, options
        self.data = mujoco.MjData(model)
        self.command = command
        self.predicted = predicted
        joints = scene.robot.joint_names
        self.qadr = np.array([model.joint(n).qposadr[0] for n in joints])
        self.vadr = np.array([model.joint(n).dofadr[0] for n in joints])
        self.bodies = np.array([model.body(o.name).id for o in scene.objects], dtype=int)
        # Views into the simulation's arrays, taken once: MjData keeps its buffers for its
        # lifetime, and each attribute access through the bindings costs microseconds a step.
        self.qpos, self.ctrl = self.data.qpos, self.data.ctrl
        self.body_z_up = self.data.xmat[:, 8]
        """The z component of every body's own z axis (the last entry of its rotation)."""
        self.geom_body = model.geom_bodyid
        self.is_arm = model.geom_contype == ARM
        self.is_static = model.geom_contype == STATIC
        # The geom pairs `_contacts` records: arm-obstacle collisions and objects that touch
        # (the rest, objects on the table, are most of every step's contacts).
        kind = np.where(self.is_arm, 1, np.where(self.is_static, 2, 0))
        self.recorded = ((kind[:, None] == 1) & (kind[None, :] == 2)) \
            | ((kind[:, None] == 2) & (kind[None, :] == 1)) \
            | ((kind[:, None] == 0) & (kind[None, :] == 0))
        # kv/kp of the servos as compiled (a position actuator's bias is -kp q - kv qdot).
        self.feedforward = -model.actuator_biasprm[:, 2] / model.actuator_gainprm[:, 0]
        m = len(scene.objects)
        self.max_error = np.zeros(m)
        self.body_up = np.ones(model.nbody)
        """The least z component of each body's own z axis so far (for an object, the cosine
        of its largest tilt, `tilt`); every body's, so that a step updates it without
        gathering the objects' rows."""
        self.joint_error = np.zeros(len(joints))
        """Each joint's largest tracking error so far (`tracking`)."""
        self._error = np.zeros(len(joints))
        self.error_from: list[float | None] = [None] * m
        self.next_point = 0
        self.executed: list[list[tuple[float, float, float]]] = []
        self.contacts: set[str] = set()
        self.touching: set[tuple[int, int]] = set()
        """The body pairs behind `contacts`."""
        self.collisions: dict[str, float] = {}
        self.steps = 0
        self.hold: np.ndarray | None = None
        """Where the arm holds once the watch stopped it."""
        self.stopped, self.stopped_at = "", 0.0
        self.reference, self.slope = self._sampled(command, options)
        self.servo = (self.reference[:-1] + self.feedforward * self.slope
                      if options.arm == "servo" else self.reference[:-1])
        """The servo's set point at every sampled step (`_drive`)."""
        self._quiet_contacts: bytes | None = None
        """The last step's contact geom pairs when none of them was to be recorded."""

    @staticmethod
    def _sampled(command: Command, options: ExecutionOptions) -> tuple[np.ndarray, np.ndarray]:
        """The command at every step's start time, from the settling to the end of the hold
        (`Command.sample`, `Command.velocity`): positions (K + 1, n) and segment slopes (K, n),
        sampled once instead of at every step."""
        dt = options.timestep
        count = int(math.ceil((options.settle + command.duration + options.hold) / dt)) + 2
        t = np.arange(count + 1) * dt - options.settle
        times, positions = command.times, command.positions
        reference = np.stack([np.interp(t, times, positions[:, j])
                              for j in range(positions.shape[1])], axis=1)
        slope = np.zeros((count, positions.shape[1]))
        if times.size > 1:
            segment = np.clip(np.searchsorted(times, t[:-1], side="right") - 1, 0,
                              times.size - 2)
            rates = np.diff(positions, axis=0) / np.diff(times)[:, None]
            moving = (t[:-1] >= 0.0) & (t[:-1] < command.duration)
            slope[moving] = rates[segment[moving]]
        return reference, slope

    @property
    def max_tilt(self) -> np.ndarray:
        """Each object's largest tilt so far (rad)."""
        return np.arccos(np.clip(self.body_up[self.bodies], -1.0, 1.0))

    @property
    def tracking(self) -> float:
        """The largest joint tracking error while the trajectory played (rad)."""
        return float(self.joint_error.max(initial=0.0))

    def begin(self) -> None:
        """The arm at the trajectory's first point, the objects where the scene has them."""
        self.data.qpos[self.qadr] = self.command.sample(0.0)
        mujoco.mj_forward(self.model, self.data)
        if self.options.arm == "servo":
            self.data.ctrl[:] = self.command.sample(0.0)

    def advance(self, until: float) -> int:
        """Step until trajectory time `until` (the first `settle` s hold the start); returns
        the steps taken."""
        opts, taken = self.options, 0
        while self.steps * opts.timestep - opts.settle < until - 1e-9:
            t = self.steps * opts.timestep - opts.settle    # trajectory time at the step's start
            if self.hold is not None and t > self.stopped_at + opts.hold:
                break                     # stopped by the watch, and the objects have settled
            self._drive(self.steps, t)
            mujoco.mj_step(self.model, self.data)
            self.steps += 1
            taken += 1
            self._observe(self.steps, t + opts.timestep)
        return taken

    def poses(self) -> np.ndarray:
        """(M, 3) object poses (x, y, yaw) now."""
        return np.array([planar_pose(self.data, body) for body in self.bodies]).reshape(-1, 3)

    def _drive(self, k: int, t: float) -> None:
        """Step k (at trajectory time t). Ideal: jump to the reference and move along it
        through the step. Servo: track q_ref + kv/kp * qdot_ref (the feed-forward cancels the
        damping's lag)."""
        command, data, dt = self.command, self.data, self.options.timestep
        if self.hold is not None:
            if self.options.arm == "ideal":
                data.qpos[self.qadr], data.qvel[self.vadr] = self.hold, 0.0
            else:
                data.ctrl[:] = self.hold
            return
        sampled = k < len(self.slope)
        if self.options.arm == "ideal":
            here, there = ((self.reference[k], self.reference[k + 1]) if sampled
                           else (command.sample(t), command.sample(t + dt)))
            data.qpos[self.qadr] = here
            data.qvel[self.vadr] = (there - here) / dt
        elif sampled:
            self.ctrl[:] = self.servo[k]
        else:
            data.ctrl[:] = command.sample(t) + self.feedforward * command.velocity(t)

    def _observe(self, k: int, t: float) -> None:
        """After step k - 1, at trajectory time t."""
        data = self.data
        if 0.0 <= t <= self.command.duration and self.hold is None:
            reference = self.reference[k] if k < len(self.reference) else self.command.sample(t)
            error = self._error
            np.subtract(self.qpos[self.qadr], reference, out=error)
            np.abs(error, out=error)
            np.maximum(self.joint_error, error, out=self.joint_error)
        np.minimum(self.body_up, self.body_z_up, out=self.body_up)
        if data.ncon:
            self._contacts()
        times = self.command.times       # predicted[i] is the state at times[i]
        while self.next_point < len(times) and times[self.next_point] <= t:
            self.executed.append([planar_pose(data, body) for body in self.bodies])
            if self.predicted is not None:
                self._compare(self.next_point, t)
            self.next_point += 1

    def _compare(self, point: int, t: float) -> None:
        """Executed vs predicted object positions at trajectory point `point`."""
        assert self.predicted is not None
        expected = self.predicted[point].objects[:, :2]
        bound = self.options.divergence_bound
        for i, body in enumerate(self.bodies):
            error = float(np.hypot(*(self.data.xpos[body][:2] - expected[i])))
            self.max_error[i] = max(self.max_error[i], error)
            if error > ERROR_THRESHOLD and self.error_from[i] is None:
                self.error_from[i] = round(t, 3)
            if 0.0 < bound < error and self.hold is None:
                self.hold, self.stopped_at = self.data.qpos[self.qadr].copy(), t
                self.stopped = (f"'{self.scene.objects[i].name}' strayed {error:.3f} m from "
                                f"its predicted pose at trajectory point {point} of "
                                f"{len(self.predicted)} ({t:.2f} s)")

    def _contacts(self) -> None:
        """Records this step's arm-obstacle collisions (deepest penetration per pair) and the
        object pairs that touch. Most steps hold only the objects' contacts with the table, so
        those are filtered out with array operations first, and a step whose contact pairs
        are those of a step that had none to record is skipped at once."""
        model, body_of, n = self.model, self.geom_body, self.data.ncon
        geoms = self.data.contact.geom[:n]
        pairs = geoms.tobytes()
        if pairs == self._quiet_contacts:
            return                        # the same pairs as last step, none to record
        g1, g2 = geoms[:, 0], geoms[:, 1]
        if not self.recorded[g1, g2].any():
            self._quiet_contacts = pairs
            return
        self._quiet_contacts = None
        arm1, arm2 = self.is_arm[g1], self.is_arm[g2]
        static1, static2 = self.is_static[g1], self.is_static[g2]
        collide = (arm1 & static2) | (arm2 & static1)
        touch = ~(arm1 | arm2 | static1 | static2)
        if collide.any():
            depth = -self.data.contact.dist[:n]
            for i in np.flatnonzero(collide):
                arm, other = (g1[i], g2[i]) if arm1[i] else (g2[i], g1[i])
                key = f"{model.body(body_of[arm]).name}->{model.geom(other).name}"
                self.collisions[key] = max(self.collisions.get(key, 0.0), float(depth[i]))
        for i in np.flatnonzero(touch):
            a, b = body_of[g1[i]], body_of[g2[i]]
            pair = (a, b) if a < b else (b, a)
            if pair not in self.touching:
                self.touching.add(pair)
                self.contacts.add("<->".join(sorted((model.body(a).name, model.body(b).name))))

    def report(self, wall_time: float) -> ExecutionReport:
        scene, data, opts = self.scene, self.data, self.options
        outcomes = tuple(self._outcome(i, obj) for i, obj in enumerate(scene.objects))
        goal = outcomes[scene.goal_index]
        distance = scene.goal.distance(np.asarray(goal.pose[:2]))
        reached = distance <= scene.goal.radius and not any(o.toppled for o in outcomes)
        sim_time = float(data.time)
        paths = np.array(self.executed, dtype=float).reshape(-1, len(self.bodies), 3)
        return ExecutionReport(opts.arm, bool(reached), distance, scene.goal.radius, outcomes,
                               tuple(sorted(self.contacts)), dict(self.collisions),
                               self.tracking, sim_time, wall_time, paths,
                               data.qpos[self.qadr].copy(), self.stopped, self.stopped_at)

    def _outcome(self, i: int, obj: MovableObject) -> ObjectOutcome:
        body = self.bodies[i]
        pose = planar_pose(self.data, body)
        predicted = final = largest = None
        if self.predicted is not None:
            x, y, yaw = (float(v) for v in self.predicted[-1].objects[i])
            predicted = (x, y, yaw)
            final = float(math.hypot(pose[0] - predicted[0], pose[1] - predicted[1]))
            largest = max(float(self.max_error[i]), final)
        angle = tilt(self.data, body)
        return ObjectOutcome(obj.name, pose, predicted, final, largest, self.error_from[i],
                             float(math.hypot(pose[0] - obj.pose[0], pose[1] - obj.pose[1])),
                             math.degrees(float(self.max_tilt[i])),
                             angle > self.options.tip_angle)


def planar_pose(data: mujoco.MjData, body: int) -> tuple[float, float, float]:
    """(x, y, yaw) of a body; yaw of its x axis projected on the table."""
    rotation = data.xmat[body]
    return (float(data.xpos[body][0]), float(data.xpos[body][1]),
            math.atan2(float(rotation[3]), float(rotation[0])))


def tilt(data: mujoco.MjData, body: int) -> float:
    """Angle (rad) between a body's z axis and the vertical."""
    return math.acos(max(-1.0, min(1.0, float(data.xmat[body][8]))))


# -- perturbed executions -------------------------------------------------------------------------


@dataclass(frozen=True)
class PerturbedReport:
    """`trials` perturbed executions of one trajectory."""

    trials: int
    reached: int
    reports: tuple[ExecutionReport, ...]

    @property
    def success_rate(self) -> float:
        return self.reached / self.trials if self.trials else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {"trials": self.trials, "reached": self.reached,
                "success_rate": self.success_rate,
                "goal_distance_m": [r.goal_distance_m for r in self.reports],
                "toppled": [list(r.toppled) for r in self.reports]}


def check_perturbed(scene: Scene, trajectory: TimedPath, trials: int, seed: int = 0,
                    options: ExecutionOptions | None = None,
                    perturbation: Perturbation | None = None) -> PerturbedReport:
    """`trials` executions of `trajectory` in worlds perturbed by `perturbation` (drawn from
    `seed`): how often the goal object still reaches its region. The contact offset is left
    out: MuJoCo executes with the real meshes, not the planner's contact shapes. Each object's
    drawn support pressure moves its centre of mass over the drawn centre of friction
    (`_shift_centre_of_mass`); its c is MuJoCo's own (the box's corners, the cylinder's rim
    carry it), which lies inside the drawn range."""
    reports = tuple(check_execution(world, trajectory, None, options)
                    for world in perturbed_worlds(scene, trials, seed, perturbation))
    return PerturbedReport(trials, sum(r.reached for r in reports), reports)


def perturbed_worlds(scene: Scene, trials: int, seed: int = 0,
                     perturbation: Perturbation | None = None) -> list[Scene]:
    """The `trials` worlds `check_perturbed` executes in (the closed loop uses the same)."""
    rng = np.random.default_rng(seed)
    perturbation = dataclasses.replace(perturbation or Perturbation(), contact_offset=0.0)
    return [perturbation.apply(scene, rng) for _ in range(trials)]
