"""Toppling: MuJoCo's contacts in the 0.5 s before the final topple vs the planner's model at the same trajectory time."""
import sys, math, numpy as np, mujoco
from pathlib import Path
from rearrangement_planner.tools.benchmark import load_trial_scene, read_trials, plan_file
from rearrangement_planner.planning.requests.trajectory import time_parameterize
from rearrangement_planner.execution import mujoco_check as mc
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.options import simulation_options
from rearrangement_planner.physics.collision import CollisionWorld
from rearrangement_planner.model.state import State

out = Path(sys.argv[1]); only = sys.argv[2].split(",") if len(sys.argv) > 2 else None
for row in read_trials(out / "trials.csv"):
    if row["solved"] != "1" or (only and row["scene"] not in only):
        continue
    if not only and row["executed_toppled"] in ("0", ""):
        continue
    plan = np.load(plan_file(out / "plans", row))
    scene = load_trial_scene(str(plan["scene_path"]), str(plan["robot"]))
    traj = time_parameterize(scene.robot, plan["arm_path"])
    # the model's states at the trajectory points
    phys = Physics(scene, simulation_options())
    st = State(np.array(traj.positions[0]), np.array(scene.object_poses))
    pred = [st]
    for q in traj.positions[1:]:
        st = phys.step(st, q).state
        pred.append(st)
    world = CollisionWorld(scene, scene.robot)
    shapes = scene.robot.config.contact_shapes if hasattr(scene.robot, "config") else None
    opts = mc.ExecutionOptions(arm="servo")
    run = mc._Execution(mc.build_model(scene, opts), scene, mc._command(traj, scene.robot.joint_names), None, opts)
    run.begin(); m, d = run.model, run.data
    hist = []  # (t, tilts, poses, contacts[(obj, bodyname, z)])
    end = run.command.duration + opts.hold
    while run.steps * opts.timestep - opts.settle < end:
        run.advance(run.steps * opts.timestep - opts.settle + 0.02)
        t = run.steps * opts.timestep - opts.settle
        tilts = [mc._tilt(d, b) for b in run.bodies]
        cons = []
        for c in range(d.ncon):
            g1, g2 = d.contact.geom[c]
            b1, b2 = m.geom_bodyid[g1], m.geom_bodyid[g2]
            for b, other in ((b1, b2), (b2, b1)):
                if b in set(run.bodies.tolist()) and m.body(other).name != "world":
                    cons.append((list(run.bodies).index(b), m.body(other).name, float(d.contact.pos[c][2])))
        hist.append((t, tilts, run.poses().copy(), cons))
    rep = run.report(0.0)
    print(f"== {row['scene']} toppled {rep.toppled}")
    for name in rep.toppled:
        i = [o.name for o in scene.objects].index(name); o = scene.objects[i]
        # last time tilt < 2 deg
        k = max(j for j, h in enumerate(hist) if h[1][i] < math.radians(2))
        t0 = hist[k][0]
        win = [h for h in hist if t0 - 0.6 <= h[0] <= t0 + 0.3]
        seen = {}
        for h in win:
            for (oi, b, z) in h[3]:
                if oi == i:
                    seen[b] = max(seen.get(b, 0), z - scene.table.height)
        kk = int(np.searchsorted(traj.times, t0))
        kk = min(kk, len(pred) - 1)
        pp = pred[kk].objects[i]; mj = hist[k][2][i]
        print(f" {name} {o.shape} size {np.round(o.size,3)} mu_s {o.support_friction:.2f} mu_c {o.pusher_friction:.2f}; tips at t={t0:.2f} (traj {run.command.duration:.1f}s, point {kk}/{len(pred)})")
        print(f"   MuJoCo contacts in window: " + ", ".join(f"{b} z={z:.3f}({z/o.size[2]:.2f}h)" for b, z in seen.items()))
        print(f"   pose MuJoCo {np.round(mj,3)} model {np.round(pp,3)} err {np.hypot(*(mj[:2]-pp[:2])):.3f} m, yaw err {abs((mj[2]-pp[2]+math.pi)%(2*math.pi)-math.pi):.2f}")
        for j in range(max(0, kk - 8), min(len(pred), kk + 3)):
            cs = world.arm_object_contacts(scene.robot.shape_poses(pred[j].q), pred[j].objects, margin=0.01, objects=[i])
            print(f"   model pt {j} t={traj.times[j]:.2f}: " + ", ".join(f"s{c.shape}:{shapes[c.shape].link if shapes else ''} z={c.point[2]-scene.table.height:.3f} d={c.depth:.3f}" for c in cs))
