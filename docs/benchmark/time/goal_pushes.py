"""How the push policy's pushes of the goal object end (docs/experiments.md 2026-11-27): PC-RRT
with the shipped options, seed 0, for `seconds` on each varied scene; every push the policy
makes of the goal object (`PushPolicy.push`: the push bias's and the greedy goal pushes) is
counted by why it stopped and whether it moved the goal object by more than 1 mm.

    python docs/benchmark/time/goal_pushes.py v3_s2,v5_s4 10
"""

import collections
import sys
from pathlib import Path

import rearrangement_planner.planning.machinery.push_policy as push_policy
from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions
from rearrangement_planner.planning.requests.warmup import warm_up
from rearrangement_planner.tools.benchmark import load_trial_scene

warm_up()
endings: collections.Counter = collections.Counter()
original = push_policy.PushPolicy.push


def counted(self, x, obj, where, steps, nullspace, stop):
    result = original(self, x, obj, where, steps, nullspace, stop)
    if obj == self.scene.goal_index:
        moved = result.count and abs(result.objects[-1, obj, :2] - x.objects[obj, :2]).sum() > 1e-3
        endings[getattr(result.stopped, "name", str(result.stopped)), bool(moved)] += 1
    return result


push_policy.PushPolicy.push = counted
for name in sys.argv[1].split(","):
    endings.clear()
    scene = load_trial_scene(Path("config/benchmark/varied") / f"{name}.yaml")
    result = PCRRT(scene, PCRRTOptions(time_limit=float(sys.argv[2]))).plan(seed=0)
    total = sum(endings.values())
    print(f"{name} {result.outcome.name} {result.iterations} iterations, {total} goal pushes")
    for (why, moved), count in endings.most_common():
        print(f"   {why:20s} moved={moved}: {count} ({count / total:.0%})")
