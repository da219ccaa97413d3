"""Per push segment of the goal object (contiguous steps that move it, nominal replay), the
spread of its end yaw and position when its centre of friction sits 0.25 of the footprint's
half extents to either side of its displacement: does the summed spread separate the plans
that reached in MuJoCo from those that missed?"""
import sys, json, math, dataclasses
from pathlib import Path
import numpy as np
from rearrangement_planner.tools.benchmark import plan_file, load_trial_scene, read_trials
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.options import PhysicsOptions
from rearrangement_planner.model.scene import SupportPressure
from rearrangement_planner.planning.machinery.propagation import replay
OPTS = PhysicsOptions(tipping=False, max_turn=0.0)
SHARE = float(sys.argv[2]) if len(sys.argv) > 2 else 0.25

def world(scene, g, centre, c=1.0):
    objs = list(scene.objects)
    objs[g] = dataclasses.replace(objs[g], support=SupportPressure(c, centre))
    return Physics(dataclasses.replace(scene, objects=tuple(objs)), OPTS)

def segments(ph, scene, path):
    st = scene.initial_state(); g = scene.goal_index; segs = []; cur = None; states = [st]
    for i, q in enumerate(path[1:], start=1):
        r = ph.step(st, q)
        moving = r.valid and g in r.moved_objects
        if moving and cur is None: cur = [i - 1, i]
        elif moving: cur[1] = i
        elif cur is not None: segs.append(tuple(cur)); cur = None
        st = r.state; states.append(st)
    if cur is not None: segs.append(tuple(cur))
    return segs, states

out = Path(sys.argv[1])
for row in read_trials(out / "trials.csv"):
    if row["solved"] != "1": continue
    p = plan_file(out / "plans", row)
    if not p.is_file(): continue
    plan = np.load(p)
    scene = load_trial_scene(str(plan["scene_path"]).replace("/work/clones/k2/", "/work/main/"), str(plan["robot"]))
    g = scene.goal_index; obj = scene.objects[g]
    ph = Physics(scene, OPTS); path = plan["arm_path"]
    segs, states = segments(ph, scene, path)
    yaw_spread, pos_spread, worst = 0.0, 0.0, 0.0
    for a, b in segs:
        s0 = states[a]; o0 = s0.objects[g]; o1 = states[b].objects[g]
        c, s = math.cos(o0[2]), math.sin(o0[2])
        d = np.array([c * (o1[0] - o0[0]) + s * (o1[1] - o0[1]), -s * (o1[0] - o0[0]) + c * (o1[1] - o0[1])])
        n = np.hypot(*d)
        if n < 1e-3: continue
        perp = np.array([-d[1], d[0]]) / n
        half = 0.5 * np.asarray(obj.size[:2])
        ends = []
        for sign in (1, -1):
            centre = tuple(sign * SHARE * half * perp)
            st, why = replay(world(scene, g, centre), s0, path[a:b + 1])
            ends.append(st[-1].objects[g])
        dyaw = abs(math.remainder(ends[0][2] - ends[1][2], 2 * math.pi))
        yaw_spread += dyaw; worst = max(worst, dyaw)
        pos_spread += float(np.hypot(*(ends[0][:2] - ends[1][:2])))
    print(json.dumps({"scene": row["scene"], "seed": row["seed"], "planner": row["planner"],
                      "reached": row["executed_servo"], "toppled": row["executed_toppled"],
                      "segments": len(segs), "yaw_spread": round(yaw_spread, 4),
                      "worst": round(worst, 4), "pos_spread": round(pos_spread, 4),
                      "turn": row["goal_turn_rad"], "robustness": row["robustness"]}), flush=True)
