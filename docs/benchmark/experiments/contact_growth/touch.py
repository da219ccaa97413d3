"""Unmodelled arm contacts in MuJoCo: for every solved plan, the MuJoCo steps (servo arm) in
which an arm geom touches the goal object while the model leaves the goal object still (no
model push within 0.3 s), by arm body, with the model's gap between the contact shapes and the
goal object (at the executed object pose) at that moment. Usage: touch.py RUN_DIR PLANNER OUT"""
import sys, os, json, math, collections, multiprocessing as mp

PHYSICS = json.loads(os.environ.get("PHYSICS", "{}"))
"""The planner arm's physics settings, e.g. PHYSICS='{"contact_growth": 0.003}' (run with that commit's code)."""
from pathlib import Path
import numpy as np

def work(job):
    import rearrangement_planner  # noqa
    import mujoco
    from rearrangement_planner.tools.benchmark import load_trial_scene
    from rearrangement_planner.planning.requests.trajectory import time_parameterize, DUPLICATE_TOLERANCE
    from rearrangement_planner.execution import mujoco_check as mc
    from rearrangement_planner.physics.step import Physics
    from rearrangement_planner.physics.options import PhysicsOptions
    from rearrangement_planner.physics.collision import CollisionWorld
    from rearrangement_planner.planning.requests.robustness import rollout_options, rollout_kernel
    out = []
    for path in job:
        plan = np.load(path)
        p = str(plan["scene_path"]); scene = load_trial_scene(p[p.index("config/"):], "")
        arm = np.array(plan["arm_path"], dtype=float)
        keep = [0] + [i for i in range(1, len(arm)) if np.max(np.abs(arm[i] - arm[i - 1])) > DUPLICATE_TOLERANCE]
        traj = time_parameterize(scene.robot, arm)
        ph = Physics(scene, rollout_options(PhysicsOptions(**PHYSICS)))
        objects = np.empty((len(arm), *scene.object_poses.shape)); objects[0] = scene.object_poses
        if rollout_kernel(arm, objects, ph.arrays, ph.flag_count) != 0:
            continue
        g = scene.goal_index
        pred = objects[keep, g]
        moving = np.r_[False, np.hypot(*np.diff(pred[:, :2], axis=0).T) > 1e-5]
        push_times = traj.times[moving]
        opts = mc.ExecutionOptions(arm="servo")
        command = mc._command(traj, scene.robot.joint_names)
        run = mc._Execution(mc.build_model(scene, opts), scene, command, None, opts)
        run.begin()
        model, data = run.model, run.data
        gbody = model.body(scene.objects[g].name).id
        world = CollisionWorld(scene)
        shapes = scene.robot.contact_shapes
        found = collections.defaultdict(lambda: [0, 1e9])   # body -> [steps, least model gap]
        dt, end = opts.timestep, command.duration
        t = 0.0
        while t < end:
            run.advance(t + 0.01)
            t += 0.01
            n = data.ncon
            if n == 0:
                continue
            geoms = data.contact.geom[:n]
            bodies = model.geom_bodyid[geoms]
            hit = set()
            for k in range(n):
                a, b = bodies[k]
                if a == gbody and run.is_arm[geoms[k, 1]]:
                    hit.add(b)
                elif b == gbody and run.is_arm[geoms[k, 0]]:
                    hit.add(a)
            if not hit:
                continue
            if push_times.size and np.min(np.abs(push_times - t)) <= 0.3:
                continue
            # the model's gap at this moment: planned q at t, executed object pose
            q = command.sample(t)
            k = min(int(np.searchsorted(traj.times, t)), len(keep) - 1)
            poses = np.array(objects[keep[k]], dtype=float)   # the model's poses there
            sp = scene.robot.shape_poses(q)
            near = world.arm_object_contacts(sp, poses, margin=0.05, objects=[g])
            gap = min((-c.depth for c in near), default=0.05)
            for b in hit:
                name = model.body(b).name
                found[name][0] += 1
                found[name][1] = min(found[name][1], gap)
        row = {"plan": Path(path).name, "unmodelled": {k: [v[0], round(v[1], 4)] for k, v in found.items()}}
        print(json.dumps(row), flush=True)
        out.append(row)
    return out

if __name__ == "__main__":
    import csv
    from rearrangement_planner.tools.benchmark import plan_file
    run = Path(sys.argv[1])
    rows = [r for r in csv.DictReader(open(run / "trials.csv")) if r["planner"] == sys.argv[2] and r["solved"] == "1"]
    paths = [str(plan_file(run / "plans", r)) for r in rows]
    if len(sys.argv) > 4:
        paths = [p for p in paths if sys.argv[4] in p]
    with mp.get_context("spawn").Pool(2) as pool:
        parts = pool.map(work, [paths[0::2], paths[1::2]])
    with open(sys.argv[3], "w") as f:
        for part in parts:
            for r in part: f.write(json.dumps(r) + "\n")
