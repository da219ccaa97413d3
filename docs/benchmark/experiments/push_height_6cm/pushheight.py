"""Lowest contact-shape point on the pushing manifold at several push heights (shipped Panda shapes)."""
import dataclasses, math, sys, numpy as np
from rearrangement_planner.model.robot import RobotModel, PushPosture
from rearrangement_planner.planning.machinery.manifold import ik_on_manifold, lowest_point
base = RobotModel.load(sys.argv[1] if len(sys.argv) > 1 else "panda")
rng = np.random.default_rng(0)
targets = []
while len(targets) < 150:
    r, a = rng.uniform(0.30, 0.72), rng.uniform(-1.4, 1.4)
    x, y = r * math.cos(a), r * math.sin(a)
    if x >= 0.25: targets.append((x, y, rng.uniform(-math.pi, math.pi)))
p0 = base.config.push_posture
for h in (0.07, 0.065, 0.06, 0.055, 0.05, 0.045, 0.04):
    robot = RobotModel(dataclasses.replace(base.config, push_posture=PushPosture(h, p0.roll, p0.pitch)), urdf_xml=base.urdf_xml)
    found = clear = 0; lows = []
    for x, y, yaw in targets:
        q = ik_on_manifold(robot, x, y, yaw, 0.0, robot.home, restarts=8)
        if q is None: continue
        found += 1
        q2 = ik_on_manifold(robot, x, y, yaw, 0.0, robot.home, restarts=8, min_clearance=0.005)
        clear += q2 is not None
        lows.append(lowest_point(robot, q2 if q2 is not None else q)[0])
    print(f"h={h:.3f}: IK {found}/150, with 5 mm table clearance {clear}/150, lowest point median {np.median(lows)*1000:.1f} mm, min {min(lows)*1000:.1f} mm", flush=True)
# real meshes in MuJoCo: lowest arm vertex at the same IK solutions
import mujoco
from rearrangement_planner.execution.mujoco_check import arm_model
for h in (0.07, 0.065, 0.06):
    robot = RobotModel(dataclasses.replace(base.config, push_posture=PushPosture(h, p0.roll, p0.pitch)), urdf_xml=base.urdf_xml)
    m = arm_model(robot); d = mujoco.MjData(m)
    qadr = [m.joint(n).qposadr[0] for n in robot.joint_names]
    lows = []
    for x, y, yaw in targets:
        q = ik_on_manifold(robot, x, y, yaw, 0.0, robot.home, restarts=8, min_clearance=0.005)
        if q is None: continue
        d.qpos[qadr] = q; mujoco.mj_forward(m, d)
        low = math.inf
        for g in range(m.ngeom):
            if m.body_weldid[m.geom_bodyid[g]] == 0: continue
            if m.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
                mid = m.geom_dataid[g]; a, n = m.mesh_vertadr[mid], m.mesh_vertnum[mid]
                v = m.mesh_vert[a:a + n] @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g]
                low = min(low, v[:, 2].min())
            elif m.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
                R = d.geom_xmat[g].reshape(3, 3); low = min(low, d.geom_xpos[g][2] - np.abs(R[2]) @ m.geom_size[g])
        lows.append(low)
    lows = np.array(lows)
    print(f"MuJoCo meshes h={h:.3f}: lowest vertex median {np.median(lows)*1000:.1f} mm, min {lows.min()*1000:.1f} mm, below 0: {(lows < 0).sum()}/{len(lows)}, below 3 mm: {(lows < 0.003).sum()}", flush=True)
