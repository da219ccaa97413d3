"""What touches an object as it topples in MuJoCo (servo arm): for every solved plan that
toppled an object, the arm bodies touching it in the 0.5 s before its tilt first passes
0.3 rad, and whether the model was pushing it then (it moved in the model within 0.3 s).
Usage: topple_links.py RUN_DIR PLANNER [PLANNER ...]"""
import sys, os, json, collections, csv
from pathlib import Path
import numpy as np

PHYSICS = json.loads(os.environ.get("PHYSICS", "{}"))

def main():
    import rearrangement_planner  # noqa
    from rearrangement_planner.tools.benchmark import load_trial_scene, plan_file
    from rearrangement_planner.planning.requests.trajectory import time_parameterize, DUPLICATE_TOLERANCE
    from rearrangement_planner.execution import mujoco_check as mc
    from rearrangement_planner.physics.step import Physics
    from rearrangement_planner.physics.options import PhysicsOptions
    from rearrangement_planner.planning.requests.robustness import rollout_options, rollout_kernel
    run = Path(sys.argv[1])
    for planner in sys.argv[2:]:
        rows = [r for r in csv.DictReader(open(run / "trials.csv"))
                if r["planner"] == planner and r["solved"] == "1" and int(r["executed_toppled"] or 0) > 0]
        for r in rows:
            plan = np.load(plan_file(run / "plans", r))
            p = str(plan["scene_path"]); scene = load_trial_scene(p[p.index("config/"):], "")
            arm = np.array(plan["arm_path"], dtype=float)
            keep = [0] + [i for i in range(1, len(arm)) if np.max(np.abs(arm[i] - arm[i - 1])) > DUPLICATE_TOLERANCE]
            traj = time_parameterize(scene.robot, arm)
            ph = Physics(scene, rollout_options(PhysicsOptions(**PHYSICS)))
            objects = np.empty((len(arm), *scene.object_poses.shape)); objects[0] = scene.object_poses
            rollout_kernel(arm, objects, ph.arrays, ph.flag_count)
            pred = objects[keep]
            opts = mc.ExecutionOptions(arm="servo")
            command = mc._command(traj, scene.robot.joint_names)
            ex = mc._Execution(mc.build_model(scene, opts), scene, command, None, opts)
            ex.begin()
            model, data = ex.model, ex.data
            recent = collections.deque()
            t, events, done = 0.0, [], set()
            while t < command.duration + 1.0:
                ex.advance(t + 0.01); t += 0.01
                n = data.ncon
                touching = collections.defaultdict(set)
                for k in range(n):
                    g1, g2 = data.contact.geom[k]
                    b1, b2 = model.geom_bodyid[g1], model.geom_bodyid[g2]
                    if ex.is_arm[g1] and not ex.is_arm[g2]:
                        touching[b2].add(model.body(b1).name)
                    elif ex.is_arm[g2] and not ex.is_arm[g1]:
                        touching[b1].add(model.body(b2).name)
                recent.append((t, touching))
                while recent and recent[0][0] < t - 0.5:
                    recent.popleft()
                tilt = ex.max_tilt
                for m, obj in enumerate(scene.objects):
                    if m in done or tilt[m] < 0.3:
                        continue
                    done.add(m)
                    body = ex.bodies[m]
                    links = sorted(set().union(*[tc.get(body, set()) for _, tc in recent]))
                    k = min(int(np.searchsorted(traj.times, t)), len(keep) - 1)
                    k0 = max(int(np.searchsorted(traj.times, t - 0.3)) - 1, 0)
                    pushed = bool(np.any(np.hypot(*np.diff(pred[k0:k + 1, m, :2], axis=0).T) > 1e-5)) if k > k0 else False
                    events.append({"object": obj.name, "goal": m == scene.goal_index, "t": round(t, 2),
                                   "links": links, "model_pushing": pushed,
                                   "height": float(obj.size[2]), "width": float(min(obj.size[0], obj.size[1]))})
            print(json.dumps({"planner": planner, "scene": r["scene"], "seed": r["seed"], "events": events}), flush=True)

if __name__ == "__main__":
    main()
