"""`python -m rearrangement_planner.ros.sim.make_bags`: regenerate the input bags in `bags/` and the
reference plan recordings in `bags/plans/`.

Each input bag is what `ros2 bag record /joint_states /rearrangement_planner/object_poses
/rearrangement_planner/goal` would have written on the scene's robot cell running a perception
node, seconds before planning: rosbag2 MCAP (profile ros2, ros2msg schemas, cdr,
offered_qos_profiles; `recording.McapRecorder`), log times from a fixed epoch, with

- `/joint_states` (sensor_msgs/JointState, best-effort sensor QoS) at the bag's joint rate:
  the 7 arm joints and the 2 finger joints, as joint_state_broadcaster publishes them, with
  encoder-level noise on the positions and velocities, stamped a fraction of a millisecond
  before they are logged, with jitter;
- `/rearrangement_planner/object_poses` (geometry_msgs/PoseArray in `world`) at a perception
  rate:
  the objects' true poses plus perception noise (position, height, yaw, a slight tilt),
  stamped at capture time, ~35 ms before they are logged;
- `/rearrangement_planner/goal` (geometry_msgs/PoseStamped): the goal point, as clicked in RViz.

A metadata record `rearrangement_input` holds the planner node parameters to replay the bag
with (`planner_parameters`, JSON: scene, seed, time limit, goal margin), the ground truth it
was recorded from (`world`, a scene YAML: true arm and object poses, the bag's goal and the
acceptance radius) and a description. The planner plans for the acceptance radius minus its
`goal_margin` (the node's parameter): open-loop execution never reproduces the planner's
physics exactly (perception noise, a controller that interpolates at its own rate), so a plan
ending on the region's boundary would miss it.

Then every bag is replayed into a planner node in this process (`replay.run_bag`) and the
node's MCAP of the plan is kept as `bags/plans/<bag>.plan.mcap`: the reference the regression
test replays through the current physics.

Everything is seeded (one generator per bag, seeded from its name): the input bags are the same
bytes on every run with the same library versions. The plans are the planner's: the same as
long as the planner and the physics do not change (their MCAPs differ in plan ids and times).
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from rearrangement_planner.io.recording import McapRecorder
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.physics.validation import load_scene, parse_scene
from rearrangement_planner.planning.machinery.interface import PlannerOptions

EPOCH_NS = 1_700_000_000 * 1_000_000_000
"""Log time of the first message of every bag (2023-11-14 22:13:20 UTC)."""
FRAME = "world"
TOPICS = {"joint_states": "/joint_states", "object_poses": "/rearrangement_planner/object_poses",
          "goal": "/rearrangement_planner/goal"}
PERCEPTION_LATENCY = 0.035
"""Seconds from capture (header stamp) to publication of an object pose estimate."""


@dataclass(frozen=True)
class BagSpec:
    """One input bag: the recorded world, the streams' rates and noise, the planner settings."""

    name: str
    scene: str
    """Shipped scene the planner node is configured with (parameter `scene`)."""
    description: str
    seed: int
    """Planner seed (a plan in a few seconds)."""
    goal: tuple[float, float] | None = None
    """Goal point (m) published on ~/goal; None: the scene's."""
    objects: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    """True poses (x, y, yaw) overriding the scene's (the world moved since the scene file)."""
    duration: float = 3.0
    """Seconds of recording."""
    joint_rate: float = 250.0
    """Hz of /joint_states."""
    pose_rate: float = 30.0
    """Hz of object poses."""
    goal_time: float = 0.8
    """Log time (s from the start) of the goal."""
    joint_noise: float = 2e-5
    """Std dev of joint position noise, rad (velocity noise is 10x that, rad/s)."""
    pose_noise: float = 1.5e-3
    """Std dev of the perception error of x, y and z, m."""
    yaw_noise: float = 8e-3
    """Std dev of the perception error of yaw (and a tenth of it as tilt), rad."""
    goal_margin: float = PlannerOptions().goal_margin
    """The planner's `goal_margin` parameter, m (module docstring)."""
    time_limit: float = 20.0
    """Planner time limit, s."""
    glitches: bool = False
    """Drop, delay and reorder messages (`_glitch`)."""


BAGS: tuple[BagSpec, ...] = (
    BagSpec("easy_push_1obj", "easy_push",
            "easy_push: 1 box, the scene's goal; joint states 100 Hz, poses 15 Hz, 3 s.",
            seed=1, joint_rate=100.0, pose_rate=15.0),
    BagSpec("easy_push_moved_1obj", "easy_push",
            "easy_push with the box elsewhere than in the scene file (and rotated) and a goal "
            "other than the scene's; joint states 200 Hz, poses 30 Hz, 2.5 s, the goal late "
            "(1.5 s).", seed=6, goal=(0.47, -0.04), objects={"target": (0.47, 0.16, 0.35)},
            duration=2.5, joint_rate=200.0, goal_time=1.5),
    BagSpec("default_3obj", "default",
            "default: 3 objects and the post, the scene's goal; joint states 250 Hz, poses "
            "30 Hz, 3 s.", seed=5),
    BagSpec("default_3obj_glitches", "default",
            "default with a goal nearer the target and a bad connection: joint states 250 Hz "
            "with a 0.25 s gap and 25 messages delivered late in one burst, poses 30 Hz with "
            "random drops, a 0.5 s tracking gap and 5 stale estimates (stamps 0.2-0.4 s old), "
            "a misclicked goal corrected 0.8 s later, messages not in log-time order in the "
            "file; 4 s.", seed=3, goal=(0.44, 0.0), duration=4.0, glitches=True),
    BagSpec("clutter_4obj", "clutter",
            "clutter: the target, two blockers and a can; a goal beside the blockers (the "
            "scene's, behind them, is not planned in 20 s with the tighter planning radius); "
            "joint states 200 Hz, poses 20 Hz, 3 s.",
            seed=0, goal=(0.62, 0.16), joint_rate=200.0, pose_rate=20.0),
    BagSpec("seven_objects_7obj", "seven_objects",
            "seven_objects: 7 objects, a goal nearer than the scene's (which the planner does "
            "not reach in a minute); joint states 250 Hz, poses 30 Hz, 3 s.",
            seed=17, goal=(0.50, 0.32)),
    BagSpec("default_xarm7_3obj", "default_xarm7",
            "default_xarm7: the default scene with the xArm7 (a second arm, fitted from its "
            "URDF); joint states 250 Hz, poses 30 Hz, 3 s.", seed=2),
)


# --------------------------------------------------------------------------------------------
# The recorded world and its messages
# --------------------------------------------------------------------------------------------


def ground_truth(spec: BagSpec, scene: Scene) -> Scene:
    """The world the bag was recorded in: the scene with the spec's object poses and goal."""
    data = scene.to_dict()
    unknown = set(spec.objects) - set(scene.object_names)
    if unknown:
        raise ValueError(f"bag {spec.name}: objects {sorted(unknown)} are not in scene "
                         f"{spec.scene} ({', '.join(scene.object_names)})")
    for entry in data["objects"]:
        if entry["name"] in spec.objects:
            entry["pose"] = [float(v) for v in spec.objects[entry["name"]]]
    if spec.goal is not None:
        data["goal"]["position"] = [float(v) for v in spec.goal]
    return parse_scene(data, name=f"{spec.name} ground truth", robot=scene.robot)


def _time(t_ns: int) -> dict[str, int]:
    return {"sec": t_ns // 1_000_000_000, "nanosec": t_ns % 1_000_000_000}


def _ns(seconds: float) -> int:
    return EPOCH_NS + round(seconds * 1e9)


def _quaternion(roll: float, pitch: float, yaw: float) -> dict[str, float]:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return {"x": sr * cp * cy - cr * sp * sy, "y": cr * sp * cy + sr * cp * sy,
            "z": cr * cp * sy - sr * sp * cy, "w": cr * cp * cy + sr * sp * sy}


@dataclass
class _Message:
    topic: str
    type_name: str
    data: dict
    log_time: float
    """s from the start of the bag."""
    qos: str


def _other_joints(robot) -> tuple[list[str], list[float]]:
    """The joints a real cell publishes beside the planning joints: the arm's other 1-DOF joints
    in its collision URDF (a gripper's fingers), open (at their upper limit)."""
    import pinocchio as pin

    names: list[str] = []
    values: list[float] = []
    path = robot.config.geometry_urdf
    if path is None:
        return names, values
    model = pin.buildModelFromUrdf(str(path))
    for i in range(1, model.njoints):
        joint = model.joints[i]
        if model.names[i] not in robot.joint_names and joint.nq == 1:
            names.append(model.names[i])
            values.append(float(model.upperPositionLimit[joint.idx_q]))
    return names, values


def _joint_states(spec: BagSpec, world: Scene, rng: np.random.Generator) -> list[_Message]:
    others, opening = _other_joints(world.robot)
    names = list(world.robot.joint_names) + others
    q = np.concatenate([world.start_configuration, opening])
    messages = []
    for k in range(int(spec.duration * spec.joint_rate)):
        stamp = k / spec.joint_rate + rng.normal(0.0, 5e-5)
        log = stamp + 2e-4 + abs(rng.normal(0.0, 1e-4))
        position = q + rng.normal(0.0, spec.joint_noise, q.shape)
        velocity = rng.normal(0.0, 10 * spec.joint_noise, q.shape)
        messages.append(_Message(TOPICS["joint_states"], "sensor_msgs/msg/JointState", {
            "header": {"stamp": _time(_ns(stamp)), "frame_id": ""}, "name": names,
            "position": position.tolist(), "velocity": velocity.tolist(), "effort": []},
            log, "sensor"))
    return messages


def _object_poses(spec: BagSpec, world: Scene, rng: np.random.Generator) -> list[_Message]:
    heights = [world.table.height + 0.5 * o.height for o in world.objects]
    messages = []
    for k in range(int(spec.duration * spec.pose_rate)):
        capture = k / spec.pose_rate + 0.01
        poses = []
        for obj, z in zip(world.objects, heights, strict=True):
            x, y, yaw = np.asarray(obj.pose) + rng.normal(0.0, 1.0, 3) * [
                spec.pose_noise, spec.pose_noise, spec.yaw_noise]
            roll, pitch = rng.normal(0.0, 0.1 * spec.yaw_noise, 2)
            poses.append({"position": {"x": float(x), "y": float(y),
                                       "z": float(z + rng.normal(0.0, spec.pose_noise))},
                          "orientation": _quaternion(roll, pitch, yaw)})
        log = capture + PERCEPTION_LATENCY + abs(rng.normal(0.0, 3e-3))
        messages.append(_Message(TOPICS["object_poses"], "geometry_msgs/msg/PoseArray", {
            "header": {"stamp": _time(_ns(capture)), "frame_id": FRAME}, "poses": poses},
            log, "sensor"))
    return messages


def _goal(position, t: float, height: float) -> _Message:
    return _Message(TOPICS["goal"], "geometry_msgs/msg/PoseStamped", {
        "header": {"stamp": _time(_ns(t - 1e-3)), "frame_id": FRAME},
        "pose": {"position": {"x": float(position[0]), "y": float(position[1]),
                              "z": float(height)},
                 "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}, t, "reliable")


def _glitch(joints: list[_Message], poses: list[_Message], rng: np.random.Generator
            ) -> tuple[list[_Message], list[_Message]]:
    """A bad connection: joint states lost for 0.25 s (1.20-1.45 s) and 25 delivered late in
    one burst at 2.10 s (stamps up to 0.1 s older than their log time); object poses randomly
    dropped (8 %), lost for 0.5 s (1.80-2.30 s, tracking lost), 5 of them stale (stamped
    0.2-0.4 s before they were logged). Data is regular again well before the end."""
    kept = [m for m in joints if not 1.20 <= m.log_time < 1.45]
    burst = [m for m in kept if 2.00 <= m.log_time < 2.10]
    for i, m in enumerate(burst):
        m.log_time = 2.10 + i * 2e-5
    stale = set(rng.choice(len(poses), size=5, replace=False).tolist())
    out = []
    for i, m in enumerate(poses):
        if 1.80 <= m.log_time < 2.30:
            continue
        if m.log_time < 3.2 and rng.random() < 0.08:
            continue
        if i in stale and m.log_time < 3.2:
            capture = m.log_time - rng.uniform(0.2, 0.4)
            m.data["header"]["stamp"] = _time(_ns(capture))
        out.append(m)
    return kept, out


def bag_messages(spec: BagSpec, world: Scene) -> list[_Message]:
    """Every message of the bag in the order it is written to the file."""
    rng = np.random.default_rng(zlib.crc32(spec.name.encode()))
    joints = _joint_states(spec, world, rng)
    poses = _object_poses(spec, world, rng)
    goals = [_goal(world.goal.position, spec.goal_time, world.table.height)]
    if spec.glitches:
        joints, poses = _glitch(joints, poses, rng)
        # A misclicked goal first, corrected 0.8 s later: the node must plan for the last.
        misclick = world.goal.position + [0.12, 0.25]
        goals = [_goal(misclick, spec.goal_time, world.table.height),
                 _goal(world.goal.position, spec.goal_time + 0.8, world.table.height)]
        # A recorder that flushes per-topic buffers: object poses written after the joint
        # states of each 0.5 s block, so the file is not in log-time order.
        ordered = sorted(joints + goals, key=lambda m: m.log_time)
        blocks: dict[int, list[_Message]] = {}
        for m in ordered + poses:
            blocks.setdefault(int(m.log_time / 0.5), []).append(m)
        return [m for b in sorted(blocks) for m in blocks[b]]
    return sorted(joints + poses + goals, key=lambda m: m.log_time)


def input_metadata(spec: BagSpec, world: Scene) -> dict[str, str]:
    parameters = {"scene": spec.scene, "seed": spec.seed, "time_limit": spec.time_limit,
                  "goal_margin": spec.goal_margin}
    return {"planner_parameters": json.dumps(parameters, sort_keys=True),
            "world": yaml.safe_dump(world.to_dict(), sort_keys=False),
            "description": spec.description}


def write_bag(spec: BagSpec, out_dir: Path) -> Path:
    """Write `<out_dir>/<spec.name>.mcap`; returns its path."""
    world = ground_truth(spec, load_scene(spec.scene))
    path = out_dir / f"{spec.name}.mcap"
    with McapRecorder(path) as recorder:
        for m in bag_messages(spec, world):
            recorder.write(m.topic, m.type_name, m.data, _ns(m.log_time), m.qos)
        recorder.metadata("rearrangement_input", input_metadata(spec, world))
    return path


# --------------------------------------------------------------------------------------------
# Reference plans
# --------------------------------------------------------------------------------------------


def record_reference_plans(paths: list[Path], plans_dir: Path, rate: float = 4.0) -> list[str]:
    """Replay every bag into a planner node (in this process) and keep the node's MCAP of the
    plan as `<plans_dir>/<bag>.plan.mcap`. Returns one summary line per bag."""
    from rearrangement_planner.ros.sim.replay import Session, run_bag

    plans_dir.mkdir(parents=True, exist_ok=True)
    lines = []
    with Session(name="make_bags") as session, tempfile.TemporaryDirectory() as tmp:
        for i, path in enumerate(paths):
            run = run_bag(path, session, rate=rate, namespace=f"/make_bags_{i}",
                          record_dir=tmp)
            if not run.plan.success or run.plan.mcap is None:
                raise RuntimeError(f"{path.name}: no plan: {run.plan.message}")
            target = plans_dir / f"{path.stem}.plan.mcap"
            shutil.copyfile(run.plan.mcap, target)
            lines.append(f"{target}: {run.plan.outcome} in {run.plan.plan_time:.2f} s, "
                         f"{run.plan.iterations} iterations")
    return lines


def search_seeds(paths: list[Path], seeds: range, rate: float = 4.0) -> None:
    """For choosing a bag's `seed`: replay every bag with each seed into a planner node and
    execute each plan open loop in world_sim on the ground truth; print one line per run."""
    from rearrangement_planner.ros.sim.replay import Session, run_bag

    with Session(name="make_bags") as session, tempfile.TemporaryDirectory() as tmp:
        for i, path in enumerate(paths):
            for seed in seeds:
                run = run_bag(path, session, rate=rate, namespace=f"/seeds_{i}_{seed}",
                              record_dir=tmp, overrides={"seed": seed, "time_limit": 10.0},
                              execute=True,
                              time_scale=20.0)
                line = f"{path.stem} seed {seed}: {run.plan.outcome} in " \
                       f"{run.plan.plan_time:.2f} s"
                if run.outcome is not None:
                    goal = run.outcome["goal"]
                    line += (f"; open loop {run.outcome['status']}, goal distance "
                             f"{goal['distance_m']:.4f} m (radius {goal['radius_m']:g} m)")
                print(line, flush=True)


def _seed_range(text: str) -> range:
    first, _, last = text.partition("-")
    try:
        return range(int(first), int(last or first) + 1)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected N or N-M, got {text!r}") from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m rearrangement_planner.ros.sim.make_bags",
        description="Regenerate the input bags (bags/*.mcap) and the reference plan "
                    "recordings (bags/plans/*.plan.mcap).")
    parser.add_argument("--out", type=Path, default=Path("bags"),
                        help="folder of the bags (default: bags/)")
    parser.add_argument("--only", action="append", metavar="NAME",
                        help="only this bag (repeatable); names: "
                             + ", ".join(s.name for s in BAGS))
    parser.add_argument("--no-plans", action="store_true",
                        help="write the input bags only, not the reference plans")
    parser.add_argument("--search-seeds", type=_seed_range, metavar="N-M",
                        help="instead: plan the (existing) bags with seeds N..M and execute "
                             "each plan in world_sim; prints plan time and open-loop outcome "
                             "to choose a bag's seed (BAGS in this file)")
    args = parser.parse_args(argv)
    specs = [s for s in BAGS if not args.only or s.name in args.only]
    unknown = set(args.only or ()) - {s.name for s in BAGS}
    if unknown:
        print(f"make_bags: unknown bags {sorted(unknown)}; known: "
              f"{', '.join(s.name for s in BAGS)}", file=sys.stderr)
        return 2
    if args.search_seeds is not None:
        search_seeds([args.out / f"{s.name}.mcap" for s in specs], args.search_seeds)
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    paths = []
    for spec in specs:
        path = write_bag(spec, args.out)
        paths.append(path)
        print(f"{path}: {path.stat().st_size / 1024:.0f} KiB", flush=True)
    if not args.no_plans:
        for line in record_reference_plans(paths, args.out / "plans"):
            print(line, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
