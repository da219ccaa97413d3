"""Per push: MuJoCo's turn and slide against the model's at several nominal c scales."""
import sys, dataclasses, json
import numpy as np
from rearrangement_planner.model.robot import RobotModel
from rearrangement_planner.model.scene import SupportPressure
from rearrangement_planner.execution.mujoco_check import check_execution
from rearrangement_planner.execution.open_loop import Command, OpenLoopExecution
from rearrangement_planner.physics.options import simulation_options
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import parse_scene
from rearrangement_planner.planning.requests.trajectory import Trajectory
from rearrangement_planner.planning.machinery.manifold import default_push_configuration, ik_on_manifold

panda = RobotModel.load("panda")
xs = np.arange(0.36, 0.52 + 1e-9, 0.005)
q = default_push_configuration(panda, 0.0); path = []
for x in xs:
    q = ik_on_manifold(panda, float(x), 0.0, 0.0, 0.0, q); path.append(q)
positions = np.vstack([path[:1], path]); times = np.concatenate([[0.0], 1.0 + np.arange(len(xs)) * 0.1])
rng = np.random.default_rng(int(sys.argv[1]) if len(sys.argv) > 1 else 0)
scales = (0.8, 1.0, 1.3, 1.6, 1.85)
for trial in range(int(sys.argv[2]) if len(sys.argv) > 2 else 20):
    shape = "cylinder" if rng.uniform() < 0.35 else "box"
    if shape == "box":
        size = [rng.uniform(0.04, 0.09), rng.uniform(0.04, 0.09), rng.uniform(0.05, 0.12)]
        half = 0.5 * size[0]
    else:
        d = rng.uniform(0.05, 0.09); size = [d, d, rng.uniform(0.05, 0.12)]; half = 0.5 * d
    yaw = rng.uniform(-0.5, 0.5) if shape == "box" else 0.0
    offset = rng.uniform(-0.035, 0.035)
    mu = rng.uniform(0.2, 0.5)
    obj = {"name": "o", "shape": shape, "pose": [0.44 + half, offset, yaw],
           "mass": float(rng.uniform(0.2, 0.8)), "support_friction": mu, "pusher_friction": float(rng.uniform(0.2, 0.5))}
    obj.update({"size": size} if shape == "box" else {"radius": half, "height": size[2]})
    data = {"table": {"center": [0.55, 0.0], "size": [0.8, 1.2], "height": 0.0},
            "start_configuration": positions[0].tolist(), "objects": [obj],
            "goal": {"object": "o", "position": [0.7, 0.0], "radius": 0.02}}
    scene = parse_scene(data, robot=panda)
    traj = Trajectory(panda.joint_names, times, positions, np.zeros_like(positions))
    rep = check_execution(scene, traj)
    e = rep.objects[0]
    row = {"shape": shape, "size": size, "yaw0": yaw, "offset": offset, "mu": mu,
           "mujoco": [float(v) for v in e.pose[:3]], "toppled": bool(e.toppled), "model": {}}
    for s in scales:
        o = dataclasses.replace(scene.objects[0], support=SupportPressure(s))
        sc = dataclasses.replace(scene, objects=(o,))
        run = OpenLoopExecution(Physics(sc, dataclasses.replace(simulation_options(), max_substep=0.001)),
                                sc.initial_state(), Command(times, positions), period=0.01)
        run.run()
        m = run.state.objects[0]
        row["model"][s] = [float(v) for v in m[:3]] + [bool(run.invalid)]
    print(json.dumps(row), flush=True)
