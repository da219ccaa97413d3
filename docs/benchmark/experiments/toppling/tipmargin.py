"""Per solved plan: the smallest tipping margin d - mu_s h over the steps that move each object (model replay), vs whether MuJoCo toppled it."""
import sys, math, numpy as np
from pathlib import Path
from rearrangement_planner.tools.benchmark import load_trial_scene, read_trials, plan_file
from rearrangement_planner.planning.requests.trajectory import remove_duplicates
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.options import simulation_options
from rearrangement_planner.physics.collision import CollisionWorld
from rearrangement_planner.model.state import State
from rearrangement_planner.execution.mujoco_check import check_execution, ExecutionOptions
from rearrangement_planner.planning.requests.trajectory import time_parameterize

for out in sys.argv[1:]:
    out = Path(out)
    for row in read_trials(out / "trials.csv"):
        if row["solved"] != "1":
            continue
        plan = np.load(plan_file(out / "plans", row))
        scene_path = str(plan["scene_path"])
        if not Path(scene_path).exists():   # a plan made in a clone: the same scene here
            scene_path = "config/" + scene_path.split("/config/", 1)[1]
        scene = load_trial_scene(scene_path, str(plan["robot"]))
        path = remove_duplicates(plan["arm_path"])
        phys = Physics(scene, simulation_options()); world = CollisionWorld(scene, scene.robot)
        st = State(np.array(path[0]), np.array(scene.object_poses))
        M = len(scene.objects); low = [math.inf] * M; lowh = [0.0] * M; hi_link = [""] * M
        for q in path[1:]:
            nxt = phys.step(st, q).state
            moved = [i for i in range(M) if np.linalg.norm(nxt.objects[i, :2] - st.objects[i, :2]) > 1e-4]
            if moved:
                cs = world.arm_object_contacts(scene.robot.shape_poses(nxt.q), nxt.objects, margin=0.002, objects=moved)
                for i in moved:
                    zs = [(c.point[2] - scene.table.height, scene.robot.config.contact_shapes[c.shape].link) for c in cs if c.obj == i]
                    if not zs:
                        continue
                    h, link = max(zs)
                    o = scene.objects[i]
                    dxy = nxt.objects[i, :2] - st.objects[i, :2]; yaw = st.objects[i, 2]
                    ux = math.cos(yaw) * dxy[0] + math.sin(yaw) * dxy[1]; uy = -math.sin(yaw) * dxy[0] + math.cos(yaw) * dxy[1]
                    n = math.hypot(ux, uy); ux, uy = ux / n, uy / n
                    d = 0.5 * o.size[0] if o.shape == "cylinder" else 0.5 * (abs(ux) * o.size[0] + abs(uy) * o.size[1])
                    mgn = d - o.support_friction * h
                    if mgn < low[i]:
                        low[i], lowh[i], hi_link[i] = mgn, h, link
            st = nxt
        rep = check_execution(scene, time_parameterize(scene.robot, plan["arm_path"]), None, ExecutionOptions(arm="servo"))
        for i, o in enumerate(scene.objects):
            if low[i] < math.inf:
                print(f"{out.name} {row['scene']} {o.name} toppled={int(o.name in rep.toppled)} margin={low[i]*1000:.1f}mm h={lowh[i]:.3f} H={o.size[2]:.3f} link={hi_link[i]} reached={int(rep.reached)}", flush=True)
