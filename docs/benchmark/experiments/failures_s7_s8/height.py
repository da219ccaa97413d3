"""A box pushed off-centre at several heights: its turn in MuJoCo against the model."""
import sys, dataclasses
import numpy as np
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.execution.mujoco_check import check_execution, ExecutionOptions
from rearrangement_planner.execution.open_loop import Command, OpenLoopExecution
from rearrangement_planner.physics.options import simulation_options
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import parse_scene
from rearrangement_planner.planning.requests.trajectory import Trajectory
from rearrangement_planner.planning.machinery.manifold import default_push_configuration, ik_on_manifold

panda = RobotModel.load("panda")
xs = np.arange(0.40, 0.55 + 1e-9, 0.005)
q = default_push_configuration(panda, 0.0); path = []
for x in xs:
    q = ik_on_manifold(panda, float(x), 0.0, 0.0, 0.0, q); path.append(q)
positions = np.vstack([path[:1], path]); times = np.concatenate([[0.0], 1.0 + np.arange(len(xs)) * 0.1])
size = [float(v) for v in sys.argv[1].split(",")] if len(sys.argv) > 1 else [0.06, 0.08, 0.16]
mu = float(sys.argv[2]) if len(sys.argv) > 2 else 0.4
for offset in (0.03,):
    for drop in [float(v) for v in sys.argv[3].split(",")]:
        box = {"name": "box", "shape": "box", "size": size, "pose": [0.46, offset, 0.0],
               "mass": 0.4, "support_friction": mu, "pusher_friction": 0.3}
        data = {"table": {"center": [0.55, 0.0], "size": [0.8, 1.2], "height": -drop},
                "start_configuration": positions[0].tolist(), "objects": [box],
                "goal": {"object": "box", "position": [0.59, 0.0], "radius": 0.02}}
        scene = parse_scene(data, robot=panda)
        traj = Trajectory(panda.joint_names, times, positions, np.zeros_like(positions))
        rep = check_execution(scene, traj)
        run = OpenLoopExecution(Physics(scene, dataclasses.replace(simulation_options(), max_substep=0.001)),
                                scene.initial_state(), Command(times, positions), period=0.01)
        run.run()
        e = rep.objects[0]; m = run.state.objects[0]
        print(f"offset {offset} drop {drop:.2f}: mujoco x {e.pose[0]:.3f} y {e.pose[1]:+.3f} yaw {e.pose[2]:+.2f} tilt {e.max_tilt_deg:4.1f} top {e.toppled} | model x {m[0]:.3f} y {m[1]:+.3f} yaw {m[2]:+.2f} | invalid {run.invalid}", flush=True)
