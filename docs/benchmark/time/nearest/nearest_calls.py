"""Microseconds per Nearest call on a real search tree: one PC-RRT tree of a fixed-set scene
(default n4_s0; seed 100, 40,000 iterations unless given, one tree), then 3,000 samples drawn
as PC-RRT draws them (every object and the tool uniform over the table), each answered by
`Tree.nearest` (the compiled `nearest_kernel` over the tree's own arrays). Prints the mean
call time and a checksum of the answers, which two clones must share (docs/benchmark.md,
"Nearest skips far arrangements").

    PYTHONPATH=CLONE AMENT_PREFIX_PATH=.venv python nearest_calls.py [scene.yaml [iterations]]
"""
import sys
import time
from pathlib import Path

import numpy as np

from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.machinery import tree as tree_module
from rearrangement_planner.planning.planners import pcrrt
from rearrangement_planner.planning.requests.pipeline import Candidates
from rearrangement_planner.planning.requests.request import PlanRequest
from rearrangement_planner.planning.requests.warmup import warm_up

warm_up()
trees = []


def recorded(*args, **kwargs):
    trees.append(tree_module.Tree(*args, **kwargs))
    return trees[-1]


pcrrt.Tree = recorded
scene = load_scene(Path(sys.argv[1] if len(sys.argv) > 1 else
                        "config/benchmark/scenes/n4_s0.yaml"))
iterations = int(sys.argv[2]) if len(sys.argv) > 2 else 40000
request = PlanRequest.from_settings(
    scene, "pc-rrt", {"time_limit": 300, "trees": 1, "max_iterations": iterations}, 100)
options = request.options
Candidates(request, Physics(scene, request.physics), options.termination()).plan(100)
tree = trees[-1]
m = len(scene.objects)
weights = np.full(m, options.object_weight)
weights[scene.goal_index] = options.goal_weight
(lo_x, lo_y) = scene.table.center - 0.5 * scene.table.size
(hi_x, hi_y) = scene.table.center + 0.5 * scene.table.size
rng = np.random.default_rng(1)
samples = [(np.array([rng.uniform(lo_x, hi_x), rng.uniform(lo_y, hi_y)]),
            np.column_stack([rng.uniform(lo_x, hi_x, m), rng.uniform(lo_y, hi_y, m),
                             rng.uniform(-np.pi, np.pi, m)])) for _ in range(3000)]


def call(arm, objects):
    return tree.nearest(arm, objects, options.arm_weight, weights)


call(*samples[0])
t0 = time.perf_counter()
answers = [call(arm, objects) for arm, objects in samples]
seconds = time.perf_counter() - t0
print(f"{tree.n} nodes, {int(tree.arrangements[0])} arrangements: "
      f"{seconds / len(samples) * 1e6:.1f} us per Nearest, answers' checksum "
      f"{sum((i + 1) * a for i, a in enumerate(answers))}")
