"""At a topple under the wrist: the height of MuJoCo's arm-object contact points against the
model's (the fitted shapes at the planned configuration, object at the model's pose).
Usage: wrist_height.py RUN_DIR PLANNER SCENE SEED T_TOPPLE"""
import sys, json
from pathlib import Path
import numpy as np

def main():
    import rearrangement_planner  # noqa
    from rearrangement_planner.tools.benchmark import load_trial_scene, plan_file
    from rearrangement_planner.planning.requests.trajectory import time_parameterize, DUPLICATE_TOLERANCE
    from rearrangement_planner.execution import mujoco_check as mc
    from rearrangement_planner.physics.step import Physics
    from rearrangement_planner.physics.options import PhysicsOptions
    from rearrangement_planner.planning.requests.robustness import rollout_options, rollout_kernel
    from rearrangement_planner.physics.collision import CollisionWorld
    run, planner, scene_name, seed, t_top = Path(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4], float(sys.argv[5])
    plan = np.load(plan_file(run / "plans", {"planner": planner, "scene": scene_name, "seed": seed}))
    p = str(plan["scene_path"]); scene = load_trial_scene(p[p.index("config/"):], "")
    arm = np.array(plan["arm_path"], dtype=float)
    keep = [0] + [i for i in range(1, len(arm)) if np.max(np.abs(arm[i] - arm[i - 1])) > DUPLICATE_TOLERANCE]
    traj = time_parameterize(scene.robot, arm)
    ph = Physics(scene, rollout_options(PhysicsOptions()))
    objects = np.empty((len(arm), *scene.object_poses.shape)); objects[0] = scene.object_poses
    rollout_kernel(arm, objects, ph.arrays, ph.flag_count)
    opts = mc.ExecutionOptions(arm="servo")
    command = mc._command(traj, scene.robot.joint_names)
    ex = mc._Execution(mc.build_model(scene, opts), scene, command, None, opts)
    ex.begin()
    model, data = ex.model, ex.data
    world = CollisionWorld(scene)
    shapes = scene.robot.contact_shapes
    t = max(t_top - 1.5, 0.0)
    while t < t_top:
        ex.advance(t + 0.1); t += 0.1
        mj = []
        for k in range(data.ncon):
            g1, g2 = data.contact.geom[k]
            if ex.is_arm[g1] != ex.is_arm[g2]:
                armg = g1 if ex.is_arm[g1] else g2
                other = g2 if ex.is_arm[g1] else g1
                mj.append((model.body(model.geom_bodyid[armg]).name, model.body(model.geom_bodyid[other]).name,
                           round(float(data.contact.pos[k][2]), 3)))
        kk = min(int(np.searchsorted(traj.times, t)), len(keep) - 1)
        q = arm[keep[kk]]
        cs = world.arm_object_contacts(scene.robot.shape_poses(q), objects[keep[kk]], margin=0.005)
        mdl = [(shapes[c.shape].link, scene.objects[c.obj].name, round(float(c.point[2]), 3), round(-c.depth * 1000, 1)) for c in cs]
        print(round(t, 2), "tilt", np.round(ex.max_tilt, 2).tolist(), "| MuJoCo", sorted(set(mj)), "| model (link, object, z, gap mm)", mdl)

if __name__ == "__main__":
    main()
