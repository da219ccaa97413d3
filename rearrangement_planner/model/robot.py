"""The arm: URDF kinematics (Pinocchio) plus the robot config the planner needs on top of it.

A robot is a URDF (file or string: the ROS `robot_description` convention) and a small YAML
config (``config/robots/<name>.yaml``) naming the planning joints, the base and tool frames,
the home configuration, the pushing posture and the contact shapes of every link.

Frames: everything is expressed in the URDF root frame (the robot base), which is the planning
frame. Lengths in metres, angles in radians.

A `RobotModel` owns one `pinocchio.Data` and caches the last configuration it was evaluated at,
so it is not thread-safe: give each planning thread its own (`RobotModel.copy()`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pinocchio as pin

from rearrangement_planner.model.errors import RobotModelError
from rearrangement_planner.model.files import (
    FileProblem,
    is_file,
    load_yaml,
    quote,
    read_text,
    resolve_uri,
)
from rearrangement_planner.model.resources import robots_dir

SHAPE_KINDS = ("capsule", "sphere", "box", "cylinder")


def _readonly(a: np.ndarray | Sequence[float]) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), the URDF fixed-axis convention."""
    return pin.rpy.rpyToMatrix(roll, pitch, yaw)


LIMIT_TOLERANCE = 1e-3
"""rad: a measured joint position this far past a limit is the limit (`RobotModel.clamped`)."""


@dataclass(frozen=True)
class ContactShape:
    """A convex contact shape rigidly attached to `link`.

    `offset` is the 4x4 pose of the shape in the link frame. Capsules and cylinders have their
    axis along the shape's z axis and are centred on its origin; `dims` holds (radius, length)
    for them (length of the axis segment, without the capsule's end caps), (radius,) for a
    sphere and the full (x, y, z) extents for a box.
    """

    link: str
    kind: str
    dims: tuple[float, ...]
    offset: np.ndarray

    def grown(self, delta: float) -> ContactShape:
        """The shape with every surface moved outward by `delta` m (inward if negative): a
        radius changes by delta, a length or a box extent by 2 delta (kept above 0.1 mm)."""
        if self.kind == "box":
            dims = tuple(max(d + 2 * delta, 1e-4) for d in self.dims)
        elif self.kind == "sphere":
            dims = (max(self.dims[0] + delta, 1e-4),)
        elif self.kind == "capsule":
            dims = (max(self.dims[0] + delta, 1e-4), self.dims[1])
        else:
            dims = (max(self.dims[0] + delta, 1e-4), max(self.dims[1] + 2 * delta, 1e-4))
        return replace(self, dims=dims)

    @property
    def bounding_radius(self) -> float:
        """Radius of a sphere about the shape origin that contains the shape (broad phase)."""
        if self.kind == "capsule":
            return self.dims[0] + 0.5 * self.dims[1]
        if self.kind == "cylinder":
            return math.hypot(self.dims[0], 0.5 * self.dims[1])
        if self.kind == "sphere":
            return self.dims[0]
        return 0.5 * math.sqrt(sum(d * d for d in self.dims))


@dataclass(frozen=True)
class PushPosture:
    """The pushing manifold (docs/design.md, King et al. 2015, §V): the tool frame held at `height`
    above the table top with fixed roll and pitch; yaw is free."""

    height: float
    roll: float
    pitch: float

    @property
    def rotation(self) -> np.ndarray:
        """Tool orientation at yaw 0: Ry(pitch) Rx(roll)."""
        return rpy_matrix(self.roll, self.pitch, 0.0)


@dataclass(frozen=True)
class RobotConfig:
    name: str
    urdf_path: Path | None
    joints: tuple[str, ...]
    tool_frame: str
    base_frame: str
    home: np.ndarray
    push_posture: PushPosture
    contact_shapes: tuple[ContactShape, ...]
    source: Path | None = field(default=None, compare=False)
    collision_urdf_path: Path | None = None
    """A URDF of the same arm with its real collision meshes, for the MuJoCo execution check
    (`collision_urdf`; default: `urdf_path`, when that one has them)."""

    @property
    def geometry_urdf(self) -> Path | None:
        """The URDF whose collision geometry stands for the real arm."""
        return self.collision_urdf_path or self.urdf_path

    @staticmethod
    def from_yaml(path: str | Path) -> RobotConfig:
        path = Path(path)
        try:
            data = load_yaml(path, "robot config")
        except FileProblem as exc:
            raise RobotModelError(str(exc)) from None
        return RobotConfig.from_dict(data, base_dir=path.parent, source=path)

    @staticmethod
    def from_dict(
        data: dict, base_dir: Path | None = None, source: Path | None = None
    ) -> RobotConfig:
        where = f"robot config {source}" if source else "robot config"
        if not isinstance(data, dict):
            raise RobotModelError(f"{where}: expected a mapping at the top level")
        known = {"name", "urdf", "collision_urdf", "base_frame", "joints", "tool_frame", "home",
                 "push_posture", "contact_shapes"}
        unknown = sorted(set(data) - known)
        if unknown:
            raise RobotModelError(
                f"{where}: unknown key(s) {unknown}; allowed: {sorted(known)}")
        for key in ("name", "joints", "tool_frame", "home", "push_posture", "contact_shapes"):
            if key not in data:
                raise RobotModelError(f"{where}: missing required key '{key}'")
        def urdf(key: str) -> Path | None:
            if data.get(key) is None:
                return None
            try:
                path = resolve_uri(str(data[key]))             # a path, or package://...
            except FileProblem as exc:
                raise RobotModelError(f"{where}: {key}: {exc}") from None
            return base_dir / path if not path.is_absolute() and base_dir is not None else path

        urdf_path = urdf("urdf")
        joints = tuple(str(j) for j in data["joints"])
        home = np.asarray(data["home"], dtype=float)
        if home.shape != (len(joints),):
            raise RobotModelError(
                f"{where}: home has {home.size} values, expected {len(joints)} (one per joint)")
        posture = data["push_posture"]
        try:
            push = PushPosture(float(posture["height"]), float(posture.get("roll", 0.0)),
                               float(posture.get("pitch", 0.0)))
        except (KeyError, TypeError, ValueError) as exc:
            raise RobotModelError(
                f"{where}: push_posture needs numbers height, roll, pitch ({exc})") from exc
        shapes = tuple(
            _parse_shape(entry, f"{where}: contact_shapes[{i}]")
            for i, entry in enumerate(data["contact_shapes"]))
        return RobotConfig(
            name=str(data["name"]), urdf_path=urdf_path, joints=joints,
            tool_frame=str(data["tool_frame"]), base_frame=str(data.get("base_frame", "")),
            home=_readonly(home), push_posture=push, contact_shapes=shapes, source=source,
            collision_urdf_path=urdf("collision_urdf"))


def _parse_shape(entry: dict, where: str) -> ContactShape:
    try:
        kind = entry["type"]
        link = str(entry["link"])
        if kind == "capsule":
            p1, p2 = (np.asarray(p, dtype=float) for p in entry["points"])
            axis = p2 - p1
            length = float(np.linalg.norm(axis))
            offset = np.eye(4)
            offset[:3, 3] = 0.5 * (p1 + p2)
            if length > 1e-12:
                offset[:3, :3] = _rotation_z_to(axis / length)
            return ContactShape(link, kind, (float(entry["radius"]), length), _readonly(offset))
        offset = np.eye(4)
        if kind == "sphere":
            offset[:3, 3] = np.asarray(entry["center"], dtype=float)
            return ContactShape(link, kind, (float(entry["radius"]),), _readonly(offset))
        origin = np.asarray(entry.get("origin", [0, 0, 0, 0, 0, 0]), dtype=float)
        offset[:3, 3] = origin[:3]
        offset[:3, :3] = rpy_matrix(*origin[3:6])
        if kind == "box":
            dims = tuple(float(d) for d in entry["size"])
            return ContactShape(link, kind, dims, _readonly(offset))
        if kind == "cylinder":
            dims = (float(entry["radius"]), float(entry["length"]))
            return ContactShape(link, kind, dims, _readonly(offset))
    except (KeyError, TypeError, ValueError) as exc:
        raise RobotModelError(f"{where}: malformed shape ({exc!r})") from exc
    raise RobotModelError(f"{where}: unknown type {kind!r}; use one of {SHAPE_KINDS}")


def _rotation_z_to(axis: np.ndarray) -> np.ndarray:
    """A rotation whose z column is the unit vector `axis`."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, axis)
    x /= np.linalg.norm(x)
    y = np.cross(axis, x)
    return np.column_stack([x, y, axis])


def _check_xml(urdf_xml: str, robot: str) -> None:
    """RobotModelError unless `urdf_xml` is well-formed XML with a <robot> root (checked before
    Pinocchio, whose URDF parser prints its own errors to the terminal)."""
    try:
        root = ElementTree.fromstring(urdf_xml)
    except ElementTree.ParseError as exc:
        raise RobotModelError(f"robot '{robot}': the URDF is not XML ({exc})") from None
    if root.tag != "robot":
        raise RobotModelError(f"robot '{robot}': the URDF's root element is <{quote(root.tag)}>, "
                              f"not <robot>")


class RobotModel:
    """Forward kinematics, Jacobians and contact-shape poses of a serial arm."""

    def __init__(self, config: RobotConfig, urdf_xml: str | None = None,
                 contact_offset: float = 0.0):
        if urdf_xml is None:
            if config.urdf_path is None:
                raise RobotModelError(f"robot '{config.name}': no URDF given")
            try:
                urdf_xml = read_text(config.urdf_path, f"robot '{config.name}': URDF")
            except FileProblem as exc:
                raise RobotModelError(str(exc)) from None
        _check_xml(urdf_xml, config.name)
        try:
            self.model = pin.buildModelFromXML(urdf_xml)
        except (RuntimeError, ValueError) as exc:
            raise RobotModelError(f"robot '{config.name}': URDF does not parse ({exc})") from exc
        self.config = config
        self.urdf_xml = urdf_xml
        self.contact_offset = contact_offset
        """m by which `grown` grew every contact shape (0 for a loaded robot)."""
        self.data = self.model.createData()
        model = self.model
        idx_q, idx_v = [], []
        for name in config.joints:
            if not model.existJointName(name):
                movable = [n for n in model.names[1:]]
                raise RobotModelError(
                    f"joint '{name}' not in the URDF of '{config.name}'; its joints are {movable}")
            joint = model.joints[model.getJointId(name)]
            if joint.nq != 1:
                raise RobotModelError(f"joint '{name}' is not a 1-DOF joint")
            idx_q.append(joint.idx_q)
            idx_v.append(joint.idx_v)
        self._idx_q = np.array(idx_q)
        self._idx_v = np.array(idx_v)
        self._q_full = pin.neutral(model)
        self._point_data, self._point_q = model.createData(), pin.neutral(model)  # frame_position
        self.lower = _readonly(model.lowerPositionLimit[self._idx_q])
        self.upper = _readonly(model.upperPositionLimit[self._idx_q])
        self.velocity_limits = _readonly(model.velocityLimit[self._idx_v])
        self.effort_limits = _readonly(model.effortLimit[self._idx_v])
        if np.any(self.velocity_limits <= 0):
            raise RobotModelError(
                f"robot '{config.name}': every planning joint needs a positive velocity limit")
        self.tool_frame_id = self.frame_id(config.tool_frame)
        self._shape_frame_ids = np.array([self.frame_id(s.link) for s in config.contact_shapes])
        # Shapes share links: fetch each link pose once, then index (hot path of the physics).
        shape_links, self._shape_link_index = np.unique(self._shape_frame_ids,
                                                        return_inverse=True)
        self._shape_links = [int(f) for f in shape_links]
        self._shape_offsets = np.stack([s.offset for s in config.contact_shapes]) \
            if config.contact_shapes else np.zeros((0, 4, 4))
        self.shape_bounding_radii = _readonly(
            [s.bounding_radius for s in config.contact_shapes])
        if not self.within_limits(config.home):
            raise RobotModelError(
                f"robot '{config.name}': home configuration {list(config.home)} is outside "
                f"the joint limits")
        self._cached_q: bytes | None = None
        self._jacobians_ready = False
        self._cached_shape_poses: np.ndarray | None = None
        self._tool_reach: float | None = None

    # -- construction -----------------------------------------------------------------------

    @classmethod
    def load(cls, name_or_path: str | Path, urdf_xml: str | None = None) -> RobotModel:
        """A shipped robot by name (config/robots/NAME.yaml) or a robot config YAML by path.
        `urdf_xml`, when given (e.g. the `robot_description` parameter), replaces the config's
        URDF file."""
        path = Path(name_or_path)
        if path.suffix not in (".yaml", ".yml"):
            path = robots_dir() / f"{name_or_path}.yaml"
            if not is_file(path):
                known = sorted(p.stem for p in robots_dir().glob("*.yaml"))
                raise RobotModelError(
                    f"unknown robot {quote(str(name_or_path))}; shipped robots are {known}, "
                    f"or give the path of a robot config .yaml")
        return cls(RobotConfig.from_yaml(path), urdf_xml=urdf_xml)

    def copy(self) -> RobotModel:
        """An independent model (own Pinocchio data) for another thread."""
        return RobotModel(self.config, urdf_xml=self.urdf_xml,
                          contact_offset=self.contact_offset)

    def grown(self, delta: float) -> RobotModel:
        """The same arm with every contact shape grown by `delta` m (`ContactShape.grown`): a
        contact-geometry offset of the robustness rollouts (`model.perturbation`), where the
        links meet the objects. `contact_offset` keeps the total, so the physics can keep the
        table and obstacles against the shapes as they were (`physics.step`)."""
        shapes = tuple(s.grown(delta) for s in self.config.contact_shapes)
        return RobotModel(replace(self.config, contact_shapes=shapes), urdf_xml=self.urdf_xml,
                          contact_offset=self.contact_offset + delta)

    # -- basic facts ------------------------------------------------------------------------

    @property
    def name(self) -> str:
        return self.config.name

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.config.joints

    @property
    def nq(self) -> int:
        return len(self.config.joints)

    @property
    def home(self) -> np.ndarray:
        return self.config.home

    @property
    def contact_shapes(self) -> tuple[ContactShape, ...]:
        return self.config.contact_shapes

    def frame_id(self, name: str) -> int:
        if not self.model.existFrame(name):
            raise RobotModelError(f"frame '{name}' not in the URDF of '{self.config.name}'")
        return self.model.getFrameId(name)

    def within_limits(self, q: np.ndarray, tol: float = 0.0) -> bool:
        """Every joint within its limits widened by `tol` rad (narrowed when negative)."""
        q = np.asarray(q, dtype=float)
        return bool(((q >= self.lower - tol) & (q <= self.upper + tol)).all())

    def clamped(self, q: np.ndarray, tol: float = LIMIT_TOLERANCE) -> np.ndarray:
        """`q` with every joint at most `tol` rad past a limit moved onto it; a joint farther
        out is left as it is (a start check then names it). A controller reports positions a
        hair past a limit (encoder noise, tracking error at a limit): they are the limit."""
        q = np.array(q, dtype=float)
        low = (q < self.lower) & (q >= self.lower - tol)
        high = (q > self.upper) & (q <= self.upper + tol)
        q[low], q[high] = self.lower[low], self.upper[high]
        return q

    @property
    def tool_reach(self) -> float:
        """How far (m) the contact shapes that move rigidly with the tool frame reach past the
        tool point along the tool's z axis, 0 if none does (finger pads that end a little past
        a tool frame between the finger tips, say). A pusher that should stop short of an
        object stops by this much more than the tool point."""
        if self._tool_reach is None:
            self._tool_reach = self._reach_past_tool()
        return self._tool_reach

    def _reach_past_tool(self) -> float:
        tool_joint = self.model.frames[self.tool_frame_id].parentJoint
        tool_inv = np.linalg.inv(self.tool_pose(self.home))
        reach = 0.0
        for s, fid, pose in zip(self.contact_shapes, self._shape_frame_ids,
                                self.shape_poses(self.home), strict=True):
            if self.model.frames[int(fid)].parentJoint != tool_joint:
                continue
            local = tool_inv @ pose
            if s.kind == "capsule":
                ends = local[2, 3] + np.array([-0.5, 0.5]) * s.dims[1] * local[2, 2]
                reach = max(reach, float(ends.max()) + s.dims[0])
            else:
                reach = max(reach, float(local[2, 3]) + s.bounding_radius)
        return reach

    # -- kinematics -------------------------------------------------------------------------

    def _update(self, q: np.ndarray, jacobians: bool = False) -> None:
        q = np.asarray(q, dtype=float)
        if q.shape != (self.nq,):
            raise ValueError(f"configuration has shape {q.shape}, expected ({self.nq},)")
        # The cache key is q's bytes: one C-level comparison, far cheaper than
        # np.array_equal on this hot path (every physics substep asks for the shape poses).
        key = q.tobytes()
        if key != self._cached_q:
            self._q_full[self._idx_q] = q
            pin.framesForwardKinematics(self.model, self.data, self._q_full)
            self._cached_q = key
            self._jacobians_ready = False
            self._cached_shape_poses = None
        if jacobians and not self._jacobians_ready:
            pin.computeJointJacobians(self.model, self.data, self._q_full)
            self._jacobians_ready = True

    def frame_pose(self, q: np.ndarray, frame: str | int) -> np.ndarray:
        """4x4 pose of `frame` in the base frame at configuration q."""
        self._update(q)
        fid = frame if isinstance(frame, int) else self.frame_id(frame)
        return self.data.oMf[fid].homogeneous.copy()

    def frame_position(self, q: np.ndarray, frame: int) -> np.ndarray:
        """Position (3,) of frame id `frame` in the base frame at q: `frame_pose`'s
        translation, the same numbers for less than half its time (the joints' kinematics
        and this one frame, in data of its own: `frame_pose`'s cache stays as it is). The
        search's metric asks it of every state it compares."""
        self._point_q[self._idx_q] = q
        pin.forwardKinematics(self.model, self._point_data, self._point_q)
        return pin.updateFramePlacement(self.model, self._point_data, frame).translation.copy()

    def tool_pose(self, q: np.ndarray) -> np.ndarray:
        return self.frame_pose(q, self.tool_frame_id)

    def frame_jacobian(
        self, q: np.ndarray, frame: str | int, point: np.ndarray | None = None
    ) -> np.ndarray:
        """6 x nq Jacobian [linear; angular] in base-frame axes of the point `point` (base-frame
        coordinates, rigidly attached to `frame`; default: the frame origin):
        v_p = v_o + w x (p - o)  =>  J_p = J_o,lin - [p - o]x J_ang."""
        self._update(q, jacobians=True)
        fid = frame if isinstance(frame, int) else self.frame_id(frame)
        full = pin.getFrameJacobian(self.model, self.data, fid, pin.LOCAL_WORLD_ALIGNED)
        jac = full[:, self._idx_v]
        if point is not None:
            r = np.asarray(point, dtype=float) - self.data.oMf[fid].translation
            jac = jac.copy()
            jac[:3] -= np.cross(r[:, None], jac[3:], axis=0)
        return jac

    def shape_jacobian(self, q: np.ndarray, shape_index: int, point: np.ndarray) -> np.ndarray:
        """Jacobian of a point on contact shape `shape_index` (its link moves it)."""
        return self.frame_jacobian(q, int(self._shape_frame_ids[shape_index]), point)

    def shape_poses(self, q: np.ndarray) -> np.ndarray:
        """(S, 4, 4) world poses of the contact shapes, in config order (read-only; the
        last result is reused while q does not change)."""
        self._update(q)
        if self._cached_shape_poses is None:
            oMf = self.data.oMf
            link_poses = np.array([oMf[f].homogeneous for f in self._shape_links])
            poses = link_poses[self._shape_link_index] @ self._shape_offsets
            poses.setflags(write=False)
            self._cached_shape_poses = poses
        return self._cached_shape_poses
