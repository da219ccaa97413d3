"""`rearrangement-robot fit URDF`: a robot config for a serial 7-DOF arm from its URDF alone.

    rearrangement-robot fit URDF [--name NAME] [--joints J1 ... J7] [--tool-frame F]
                                 [--base-frame F] [--package-dir DIR ...] [--max-capsules N]
                                 [--out YAML]

What it decides, and how (each step says what it could not decide as a one-line error naming
the flag that settles it):

1. **The planning joints**: the URDF's 1-DOF revolute joints (prismatic ones are grippers),
   which must be exactly 7 and form one serial chain; `--joints` names them instead.
   A continuous joint (Pinocchio models it with two coordinates) is refused: the planner needs
   joint limits.
2. **The base frame**: the root link. **The tool frame**: among the links fixed to the last
   joint, the one whose name says so (`tcp`, then `eef`, `end_effector`, `tool`), else the one
   farthest from the last joint's axis origin; `--tool-frame` names it instead.
3. **Contact capsules** per link, fitted to its collision geometry (meshes in any format
   Pinocchio's mesh loader reads, boxes, cylinders, spheres) as Pinocchio loads it. A link's
   geometry on a non-planning joint past the last one (gripper fingers) is fitted, at the
   joint's neutral position (fingers closed), to the link that carries that joint. A capsule is
   fitted to a point set by `fit_capsule`: its axis the points' principal axis, the axis line
   through the centre of their least enclosing circle across it, and the radius and end points
   the least-volume pair that covers every point. A link gets up to `--max-capsules` capsules:
   the largest is split in two (2-means of its points) while that shrinks the link's total
   capsule volume by at least `SPLIT_GAIN`. Every vertex of the collision geometry lies inside
   one of its link's capsules (to float rounding; tested with `COVER_TOLERANCE`).
   3b. **The tool's face.** A capsule's round cap reaches past a flat face by up to its
   radius, so a fitted flange or hand would touch an object centimetres before the real one
   and the push would fall short when executed. On links fixed to the last joint, the geometry
   within `FACE_DEPTH` of the front along the tool axis (tool frame z, the pushing direction)
   gets thin capsules laid across the face in strips `FACE_STRIP` wide, so that the shapes
   reach at most `FACE_TOLERANCE` past the real face (`fit_tool_link`).
4. **The pushing posture** (`search_posture`): the tool held at a height above the table with
   its approach axis horizontal (pitch pi/2), for each roll in `ROLLS`, at each height of
   `HEIGHTS`: the share of `posture_targets` (points across the benchmark's workspace, pushing
   outward, inward and sideways) that inverse kinematics reaches with every contact shape at
   least `CLEARANCE` above the table. The posture that reaches the most targets wins, the
   lowest height among equals (lower pushes are steadier), then the first roll. Refused when
   none reaches half of them.
5. **Home**: the middle of the joint limits (the arm's own "ready" pose is not in a URDF).

The config is written with the URDF's path as given (a `package://` URI stays one, resolved
by `model.files.resolve_uri` when loaded), so no robot file is copied.
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from rearrangement_planner.model.errors import RearrangementError

FACE_DEPTH = 0.02
FACE_STRIP = 0.02
FACE_TOLERANCE = 0.005
FACE_ROUNDS = 4
"""The tool's face (`fit_tool_link`): m deep, strips m wide, capsules reach at most m past
it, tries."""
SEARCH_POINTS = 800
"""A capsule's direction is searched on at most this many of its points."""
SPLIT_GAIN = 0.2
"""A split must shrink the link's capsule volume by this share to be kept."""
COVER_TOLERANCE = 1e-6
"""m: how far outside its capsules a vertex may lie (the fit's rounding)."""
ROLLS = (0.0, math.pi / 2, math.pi, -math.pi / 2)
HEIGHTS = tuple(round(0.03 + 0.01 * i, 2) for i in range(10))     # 0.03 ... 0.12 m
CLEARANCE = 0.005
"""m: the least gap between every contact shape and the table top in the pushing posture."""
MIN_REACH = 0.5
ROUNDING = 1e-4
"""m: the config's numbers are written to 0.1 mm."""
TOOL_WORDS = ("tcp", "eef", "end_effector", "tool")


class FitError(RearrangementError):
    """The URDF leaves something undecided; `flag` names the option that settles it."""

    def __init__(self, flag: str, problem: str):
        self.flag = flag
        super().__init__(f"{flag}: {problem}")


# -- capsules ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Capsule:
    a: np.ndarray
    b: np.ndarray
    radius: float

    @property
    def volume(self) -> float:
        length = float(np.linalg.norm(self.b - self.a))
        return math.pi * self.radius ** 2 * length + 4.0 / 3.0 * math.pi * self.radius ** 3

    def distance(self, points: np.ndarray) -> np.ndarray:
        """How far each point lies outside the capsule (negative inside), m."""
        axis = self.b - self.a
        length2 = float(axis @ axis)
        t = np.zeros(len(points)) if length2 == 0 else \
            np.clip((points - self.a) @ axis / length2, 0.0, 1.0)
        nearest = self.a + t[:, None] * axis
        return np.linalg.norm(points - nearest, axis=1) - self.radius


def _enclosing_circle(xy: np.ndarray, iterations: int = 400) -> np.ndarray:
    """The centre of an (approximately) least circle enclosing the 2-D points (Badoiu and
    Clarkson's iteration: step towards the farthest point by 1/(i+1)). The farthest point is
    always a corner of the points' convex hull, so the iteration looks at those alone."""
    centre = xy.mean(axis=0)
    corners = _hull_corners(xy)
    for i in range(iterations):
        far = corners[np.argmax(np.sum((corners - centre) ** 2, axis=1))]
        centre = centre + (far - centre) / (i + 2)
    return centre


def _hull_corners(xy: np.ndarray) -> np.ndarray:
    """The corners of the 2-D points' convex hull (all the points where it is degenerate)."""
    if len(xy) < 4:
        return xy
    try:
        return xy[ConvexHull(xy).vertices]
    except QhullError:                    # collinear or coincident points
        return xy


def _capsule_along(points: np.ndarray, axis: np.ndarray, thinnest: bool = False) -> Capsule:
    """The least-volume capsule with this axis direction that covers every point: the axis
    line through the centre of the points' least enclosing circle across it, then the radius
    (from the least that reaches every point to 1.6 times it, in 2 % steps; `thinnest`: the
    least) and the shortest segment that brings every point within it."""
    axis = axis / np.linalg.norm(axis)
    helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    mean = points.mean(axis=0)
    across = np.stack([(points - mean) @ u, (points - mean) @ v], axis=1)
    centre2 = _enclosing_circle(across)
    origin = mean + centre2[0] * u + centre2[1] * v
    t = (points - origin) @ axis
    d = np.linalg.norm(across - centre2, axis=1)
    best: Capsule | None = None
    for radius in float(d.max()) * (np.ones(1) if thinnest else np.linspace(1.0, 1.6, 31)):
        reach = np.sqrt(np.maximum(radius ** 2 - d ** 2, 0.0))
        # the axis segment [start, end] must meet every point's [t - reach, t + reach]
        start, end = float(np.min(t + reach)), float(np.max(t - reach))
        if start > end:                                   # one point meets them all
            start = end = (start + end) / 2
        capsule = Capsule(origin + start * axis, origin + end * axis, float(radius))
        if best is None or capsule.volume < best.volume:
            best = capsule
    assert best is not None
    return best


def fit_capsule(points: np.ndarray, refinements: int = 24) -> Capsule:
    """The least-volume covering capsule (`_capsule_along`) over axis directions: the
    points' principal axes, the frame's axes, then `refinements` directions within 3 degrees
    of the best so far (module doc, step 3)."""
    points = np.asarray(points, dtype=float)
    mean = points.mean(axis=0)
    if len(points) < 2 or np.allclose(points, mean):
        return Capsule(mean, mean.copy(), 1e-4)
    _, _, vt = np.linalg.svd(points - mean, full_matrices=False)
    rng = np.random.default_rng(0)
    # the direction is searched on at most SEARCH_POINTS of them, the capsule fitted to all
    search = points if len(points) <= SEARCH_POINTS else \
        points[rng.choice(len(points), SEARCH_POINTS, replace=False)]
    best_axis = min([*vt, *np.eye(3)], key=lambda a: _capsule_along(search, a).volume)
    best = _capsule_along(search, best_axis)
    for _ in range(refinements):
        tilted = best_axis / np.linalg.norm(best_axis) + rng.normal(0.0, math.radians(3.0), 3)
        capsule = _capsule_along(search, tilted)
        if capsule.volume < best.volume:
            best, best_axis = capsule, tilted
    return _capsule_along(points, best_axis)


def _two_means(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split points in two by 2-means, started from the extremes of the principal axis."""
    mean = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - mean, full_matrices=False)
    t = (points - mean) @ vt[0]
    centres = np.stack([points[np.argmin(t)], points[np.argmax(t)]])
    labels = np.zeros(len(points), dtype=int)
    for _ in range(50):
        new = np.argmin(np.linalg.norm(points[:, None] - centres[None], axis=2), axis=1)
        if np.array_equal(new, labels) and _ > 0:
            break
        labels = new
        for k in range(2):
            if np.any(labels == k):
                centres[k] = points[labels == k].mean(axis=0)
    return points[labels == 0], points[labels == 1]


def fit_capsules(points: np.ndarray, max_capsules: int) -> list[Capsule]:
    """Up to `max_capsules` capsules covering every point (module doc, step 3)."""
    groups = [np.asarray(points, dtype=float)]
    capsules = [fit_capsule(groups[0])]
    while len(capsules) < max_capsules:
        k = int(np.argmax([c.volume for c in capsules]))
        if len(groups[k]) < 8:
            break
        left, right = _two_means(groups[k])
        if len(left) < 4 or len(right) < 4:
            break
        parts = [fit_capsule(left), fit_capsule(right)]
        if sum(p.volume for p in parts) > (1.0 - SPLIT_GAIN) * capsules[k].volume:
            break
        groups[k:k + 1] = [left, right]
        capsules[k:k + 1] = parts
    return capsules


# -- the URDF ------------------------------------------------------------------------------------


def _primitive_points(geometry, n: int = 24) -> np.ndarray:
    """Points on a primitive's surface in its own frame (boxes: corners; round shapes: rings)."""
    kind = type(geometry).__name__
    if kind == "Box":
        h = np.asarray(geometry.halfSide)
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    angles = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(angles), np.sin(angles), np.zeros(n)], axis=1)
    if kind == "Sphere":
        r = geometry.radius
        return np.concatenate([ring * r, ring[:, [0, 2, 1]] * r, ring[:, [2, 0, 1]] * r])
    if kind in ("Cylinder", "Capsule"):
        r, h = geometry.radius, geometry.halfLength
        caps = [ring * r + [0, 0, z] for z in (-h, h)]
        if kind == "Capsule":
            caps += [np.array([[0, 0, -h - r], [0, 0, h + r]])]
        return np.concatenate(caps)
    raise FitError("URDF", f"collision geometry of type {kind} is not supported")


def geometry_points(geometry) -> np.ndarray:
    if hasattr(geometry, "vertices"):
        return np.asarray(geometry.vertices(), dtype=float)
    return _primitive_points(geometry)


@dataclass(frozen=True)
class Arm:
    """What the URDF decides: the chain, frames, limits and each link's collision points."""

    name: str
    joints: tuple[str, ...]
    base_frame: str
    tool_frame: str
    lower: np.ndarray
    upper: np.ndarray
    points: dict[str, np.ndarray]
    """Collision geometry vertices per link, in the link's frame (links in chain order)."""
    notes: tuple[str, ...]
    tool_in_link: dict[str, np.ndarray]
    """The tool frame's 4x4 pose in each link fixed to the last joint (with geometry)."""


def read_arm(urdf: Path, joints: list[str] | None = None, tool_frame: str | None = None,
             base_frame: str | None = None, package_dirs: list[Path] | None = None,
             name: str | None = None) -> Arm:
    import pinocchio as pin

    from rearrangement_planner.model.files import package_search_dirs

    dirs = [str(d) for d in (package_dirs or [])] + [str(d) for d in package_search_dirs()]
    try:
        model = pin.buildModelFromUrdf(str(urdf))
        geometry = pin.buildGeomFromUrdf(model, str(urdf), pin.COLLISION, package_dirs=dirs)
    except (RuntimeError, ValueError, OSError) as exc:
        raise FitError("URDF", f"{urdf} does not load ({exc})") from None
    notes: list[str] = []
    chain = _planning_joints(model, joints)
    last = model.getJointId(chain[-1])
    data = model.createData()
    q = pin.neutral(model)
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    frames = model.frames
    body = pin.FrameType.BODY

    base = base_frame or next(f.name for f in frames if f.type == body)
    if not model.existFrame(base):
        raise FitError("--base-frame", f"no frame {base!r} in {urdf.name}")
    tool = tool_frame or _tool_frame(model, data, last, notes)
    if not model.existFrame(tool):
        raise FitError("--tool-frame", f"no frame {tool!r} in {urdf.name}")

    chain_ids = {model.getJointId(j) for j in chain}

    def carrier(frame_index: int) -> int:
        """The link frame a geometry's points are fitted to."""
        frame = frames[frame_index]
        joint = frame.parentJoint
        if joint == 0 or joint in chain_ids:
            return frame_index
        while model.parents[joint] not in chain_ids and model.parents[joint] != 0:
            joint = model.parents[joint]
        joint_frame = model.getFrameId(model.names[joint], pin.FrameType.JOINT)
        return frames[joint_frame].parentFrame

    points: dict[str, list[np.ndarray]] = {}
    for obj in geometry.geometryObjects:
        local = geometry_points(obj.geometry)
        if not len(local):
            continue
        target = carrier(obj.parentFrame)
        world = data.oMi[obj.parentJoint].act(obj.placement)      # geometry in the world
        in_world = local @ world.rotation.T + world.translation
        link = data.oMf[target]
        in_link = (in_world - link.translation) @ link.rotation
        name_ = frames[target].name
        points.setdefault(name_, []).append(in_link)
        if target != obj.parentFrame:
            notes.append(f"{frames[obj.parentFrame].name}'s geometry fitted to {name_} "
                         f"(its joint at the neutral position)")
    order = {f.name: i for i, f in enumerate(frames)}
    joined = {k: np.concatenate(v) for k, v in sorted(points.items(), key=lambda kv: order[kv[0]])}
    index = [model.getJointId(j) for j in chain]
    lower = np.array([model.lowerPositionLimit[model.joints[i].idx_q] for i in index])
    upper = np.array([model.upperPositionLimit[model.joints[i].idx_q] for i in index])
    # the links that carry the tool's face: fixed to the last joint, their geometry reaching
    # within FACE_DEPTH of the frontmost point along the tool axis
    tool_pose = data.oMf[model.getFrameId(tool)]
    fixed = {link: (data.oMf[model.getFrameId(link)].inverse() * tool_pose).homogeneous
             for link in joined if frames[model.getFrameId(link)].parentJoint == last}
    fronts = {link: float(((joined[link] - t[:3, 3]) @ t[:3, :3])[:, 2].max())
              for link, t in fixed.items()}
    tool_in_link = {link: fixed[link] for link in fixed
                    if fronts[link] >= max(fronts.values()) - FACE_DEPTH}
    return Arm(name or urdf.stem, tuple(chain), base, tool, lower, upper, joined, tuple(notes),
               tool_in_link)


def _planning_joints(model, joints: list[str] | None) -> list[str]:
    kinds = {model.names[i]: model.joints[i].shortname() for i in range(1, model.njoints)}
    continuous = [n for n, k in kinds.items()
                  if k.startswith("JointModelRUB") or "RevoluteUnbounded" in k]
    revolute = [n for n, k in kinds.items() if n in continuous or k in (
        "JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")]
    if joints is None:
        bounded = [j for j in revolute if j not in continuous]
        if continuous:
            raise FitError("--joints", f"{', '.join(continuous)} are continuous joints "
                                       f"(no limits; the planner needs them); this arm has "
                                       f"{len(bounded)} revolute joints with limits, 7 needed")
        if len(bounded) != 7:
            raise FitError("--joints", f"the URDF has {len(bounded)} revolute joints "
                                       f"({', '.join(bounded)}), not 7; name the 7 planning "
                                       f"joints")
        joints = bounded
    for j in joints:
        if not model.existJointName(j):
            raise FitError("--joints", f"no joint {j!r} in the URDF")
        if j not in revolute or j in continuous:
            raise FitError("--joints", f"{j} is not a revolute joint with limits")
    if len(joints) != 7:
        raise FitError("--joints", f"{len(joints)} joints given, 7 needed")
    ids = [model.getJointId(j) for j in joints]
    for parent, child in zip(ids, ids[1:], strict=False):
        walk = model.parents[child]
        while walk not in (0, parent):
            walk = model.parents[walk]
        if walk != parent:
            raise FitError("--joints", f"{model.names[child]} does not follow "
                                       f"{model.names[parent]} in one serial chain")
    return list(joints)


def _tool_frame(model, data, last: int, notes: list[str]) -> str:
    import pinocchio as pin

    candidates = [f for f in model.frames
                  if f.type == pin.FrameType.BODY and f.parentJoint == last]
    if not candidates:
        raise FitError("--tool-frame", "no link is fixed to the last planning joint")
    for word in TOOL_WORDS:
        named = [f for f in candidates if word in f.name.lower()]
        if len(named) == 1:
            notes.append(f"tool frame {named[0].name}: its name says '{word}'")
            return named[0].name
    far = max(candidates, key=lambda f: float(np.linalg.norm(f.placement.translation)))
    notes.append(f"tool frame {far.name}: the link fixed to the last joint farthest from it")
    return far.name


# -- the config ----------------------------------------------------------------------------------


def _front(capsules: list[Capsule], rotation: np.ndarray, origin: np.ndarray) -> float:
    """How far the capsules reach along the tool axis (tool frame z), m."""
    return max(max(float((c.a - origin) @ rotation[:, 2]), float((c.b - origin) @ rotation[:, 2]))
               + c.radius for c in capsules)


def fit_tool_link(points: np.ndarray, tool: np.ndarray, max_capsules: int
                  ) -> tuple[list[Capsule], float]:
    """Capsules for a link fixed to the tool (module doc, step 3b): the geometry within
    FACE_DEPTH of its front along the tool axis (the face that pushes) in strips FACE_STRIP
    wide across the face, one capsule along each; the rest as any link. The face grows by
    FACE_DEPTH while a capsule reaches more than FACE_TOLERANCE past the front (at most
    FACE_ROUNDS times). Returns the capsules and how far past the front they reach, m."""
    rotation, origin = tool[:3, :3], tool[:3, 3]
    local = (points - origin) @ rotation                      # in the tool frame
    front = float(local[:, 2].max())
    capsules: list[Capsule] = []
    past = math.inf
    for depth in FACE_DEPTH * np.arange(1, FACE_ROUNDS + 1):
        face = local[:, 2] >= front - depth
        extent = np.ptp(local[face, :2], axis=0)
        u = int(np.argmax(extent))                              # strips across the longer side
        along = rotation[:, 1 - u]
        edges = local[face, u].min() + FACE_STRIP * np.arange(
            int(np.ceil(extent[u] / FACE_STRIP)) + 1)
        strips = np.clip(np.searchsorted(edges, local[face, u], side="right") - 1, 0,
                         max(len(edges) - 2, 0))
        capsules = [_capsule_along(points[face][strips == k], along, thinnest=True)
                    for k in np.unique(strips)]
        if np.any(~face):
            capsules += fit_capsules(points[~face], max_capsules)
        past = _front(capsules, rotation, origin) - front
        if past <= FACE_TOLERANCE:
            break
    return capsules, past


def capsules_per_link(arm: Arm, max_capsules: int) -> dict[str, list[Capsule]]:
    """Every link's capsules (module doc, step 3); those of links fixed to the tool keep its
    face (`fit_tool_link`)."""
    out = {}
    for link, points in arm.points.items():
        if link in arm.tool_in_link:
            out[link], _ = fit_tool_link(points, arm.tool_in_link[link], max_capsules)
        else:
            out[link] = fit_capsules(points, max_capsules)
    return out


def config_dict(arm: Arm, urdf: str, capsules: dict[str, list[Capsule]],
                posture: tuple[float, float, float] = (0.07, 0.0, math.pi / 2)) -> dict:
    height, roll, pitch = posture
    # written to 0.1 mm; the radius rounded up by the end points' rounding, so still covering
    shapes = [{"link": link, "type": "capsule",
               "radius": round(math.ceil((c.radius + ROUNDING) / ROUNDING) * ROUNDING, 4),
               "points": [[round(float(v), 4) for v in c.a], [round(float(v), 4) for v in c.b]]}
              for link, caps in capsules.items() for c in caps]
    home = (arm.lower + arm.upper) / 2
    return {"name": arm.name, "urdf": urdf, "base_frame": arm.base_frame,
            "joints": list(arm.joints), "tool_frame": arm.tool_frame,
            "home": [round(float(v), 6) for v in home],
            "push_posture": {"height": height, "roll": round(roll, 6), "pitch": round(pitch, 6)},
            "contact_shapes": shapes}


def volume_inside(first: list[Capsule], second: list[Capsule], samples: int = 200_000,
                  seed: int = 0) -> float:
    """The share of the volume `first` encloses that `second` encloses too (Monte Carlo)."""
    ends = np.concatenate([np.stack([c.a, c.b]) for c in first])
    pad = max(c.radius for c in first)
    lo, hi = ends.min(axis=0) - pad, ends.max(axis=0) + pad
    points = np.random.default_rng(seed).uniform(lo, hi, size=(samples, 3))

    def inside(capsules: list[Capsule]) -> np.ndarray:
        return np.min(np.stack([c.distance(points) for c in capsules]), axis=0) <= 0

    a = inside(first)
    return float(np.sum(a & inside(second)) / max(np.sum(a), 1))


def posture_targets() -> list[tuple[float, float, float]]:
    """(x, y, yaw) tool poses across the benchmark's workspace (`tools.bench.trials`: the
    annulus REACH_MIN..REACH_MAX in front of the base): radii 0.35, 0.5, 0.65 m at bearings
    -45, 0, 45 degrees, each pushing outward, inward and sideways."""
    targets = []
    for r in (0.35, 0.5, 0.65):
        for bearing in (-math.pi / 4, 0.0, math.pi / 4):
            for turn in (0.0, math.pi, math.pi / 2):
                targets.append((r * math.cos(bearing), r * math.sin(bearing), bearing + turn))
    return targets


def search_posture(config: dict, base_dir: Path, heights: tuple[float, ...] = HEIGHTS,
                   rolls: tuple[float, ...] = ROLLS
                   ) -> tuple[tuple[float, float, float], float]:
    """The pushing posture (module doc, step 4) over `heights` x `rolls` and the share of
    targets it reaches."""
    from rearrangement_planner.model.robot import RobotConfig, RobotModel
    from rearrangement_planner.planning.machinery.manifold import ik_on_manifold

    best: tuple[float, tuple[float, float, float]] | None = None
    targets = posture_targets()
    for height in heights:
        for roll in rolls:
            posture = {"height": height, "roll": roll, "pitch": math.pi / 2}
            robot = RobotModel(RobotConfig.from_dict({**config, "push_posture": posture},
                                                     base_dir=base_dir))
            reached = 0
            q = robot.home
            for x, y, yaw in targets:
                found = ik_on_manifold(robot, x, y, yaw, 0.0, q, np.random.default_rng(0),
                                       restarts=8, min_clearance=CLEARANCE)
                if found is not None:
                    reached += 1
                    q = found
            share = reached / len(targets)
            if best is None or share > best[0] + 1e-9:
                best = (share, (height, roll, math.pi / 2))
    assert best is not None
    if best[0] < MIN_REACH:
        raise FitError("--joints", f"no pushing posture reaches half the workspace (best "
                                   f"{best[0]:.0%}): the tool cannot be held horizontal at "
                                   f"object height across the table")
    return best[1], best[0]


def write_config(config: dict, out: Path, notes: list[str]) -> None:
    import yaml

    header = ["# Robot config written by `rearrangement-robot fit` (rearrangement_planner/tools/",
              "# robot_fit.py says how each value was decided). Capsules cover every vertex of",
              "# their link's collision geometry.", *(f"# - {n}" for n in notes)]
    out.write_text("\n".join(header) + "\n" + yaml.safe_dump(config, sort_keys=False,
                                                                    default_flow_style=None))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="rearrangement-robot",
                                     description="Robot configs from URDFs.")
    sub = parser.add_subparsers(dest="command", required=True)
    fit = sub.add_parser("fit", help="write a robot config for a 7-DOF arm from its URDF")
    fit.add_argument("urdf", help="the URDF file (a path or a package:// URI)")
    fit.add_argument("--name", help="the robot's name (default: the URDF's file name)")
    fit.add_argument("--joints", nargs=7, metavar="J", help="the 7 planning joints")
    fit.add_argument("--tool-frame", help="the tool frame (default: decided, module doc)")
    fit.add_argument("--base-frame", help="the base frame (default: the root link)")
    fit.add_argument("--package-dir", nargs="+", type=Path, default=[],
                     help="folders that hold the packages package:// URIs name")
    fit.add_argument("--max-capsules", type=int, default=3, help="capsules per link (1-5)")
    fit.add_argument("--no-posture-search", action="store_true",
                     help="keep the default posture (height 0.07 m, hand horizontal)")
    fit.add_argument("--out", type=Path, help="the config to write (default: print it)")
    args = parser.parse_args(argv)
    from rearrangement_planner.model.files import resolve_uri

    try:
        if not 1 <= args.max_capsules <= 5:
            raise FitError("--max-capsules", f"must be 1 to 5, got {args.max_capsules}")
        path = resolve_uri(args.urdf)
        arm = read_arm(path, args.joints, args.tool_frame, args.base_frame, args.package_dir,
                       args.name)
        capsules = capsules_per_link(arm, args.max_capsules)
        config = config_dict(arm, args.urdf if args.urdf.startswith("package://")
                             else str(path.resolve()), capsules)
        notes = list(dict.fromkeys(arm.notes))
        if not args.no_posture_search:
            posture, share = search_posture(config, path.parent)
            config = config_dict(arm, config["urdf"], capsules, posture)
            notes.append(f"pushing posture: height {posture[0]} m, roll {posture[1]:.3f}, "
                         f"pitch {posture[2]:.3f}: reaches {share:.0%} of the targets")
    except (RearrangementError, OSError) as exc:
        print(f"rearrangement-robot: {exc}", file=sys.stderr)
        return 2
    if args.out:
        write_config(config, args.out, notes)
        print(f"wrote {args.out}", file=sys.stderr)
    else:
        import yaml

        print(yaml.safe_dump(config, sort_keys=False, default_flow_style=None))
    for note in notes:
        print(f"note: {note}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
