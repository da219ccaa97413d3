"""Which solve answers Project's steps (docs/benchmark.md, "Nearest skips far arrangements",
what is left of an iteration): one PC-RRT tree of a fixed-set scene (seed 100, ITERATIONS),
then one Project step from each of 3,000 of its nodes with a drawn planar action (up to
0.1 m/s, 0.5 rad/s) and nullspace velocity (up to 0.3 rad/s). Project runs as Python around
the compiled solves, so each solve is counted: the normal equations (`_solve_normal`, on a
wide or, with joints locked, a tall Jacobian) and their fallback, the Jacobi eigenvectors
(`_solve_gram`); for each failed wide solve, whether J's smallest singular value is below
SINGULAR_THRESHOLD (the damped zone) by NumPy's SVD. Run at `7d48fd9`: since `7b33efc`
the fallback is `_solve_damped` (../damped_solve/solve_time.py times both). From the checkout:

    PYTHONPATH=. AMENT_PREFIX_PATH=.venv python solve_count.py \\
        config/benchmark/scenes/n6_s1.yaml 10000
"""
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.machinery import manifold
from rearrangement_planner.planning.machinery import tree as tree_module
from rearrangement_planner.planning.planners import pcrrt
from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions

trees = []


def recorded(*args, **kwargs):
    trees.append(tree_module.Tree(*args, **kwargs))
    return trees[-1]


pcrrt.Tree = recorded
scene = load_scene(Path(sys.argv[1]))
PCRRT(scene, PCRRTOptions(time_limit=1000, max_iterations=int(sys.argv[2]))).plan(seed=100)
tree = trees[-1]
count: Counter = Counter()
normal, gram = manifold._solve_normal, manifold._solve_gram


def counted_normal(jac, xdot, h, qdot, scratch):
    solved = normal(jac, xdot, h, qdot, scratch)
    m, n = jac.shape
    count["normal equations, " + ("wide" if n >= m else "tall (joints locked)")
          + (", solved" if solved else ", failed")] += 1
    if not solved and n >= m:
        below = np.linalg.svd(jac, compute_uv=False).min() < manifold.SINGULAR_THRESHOLD
        count[f"  failed wide: smallest singular value below the threshold: {below}"] += 1
    return solved


def counted_gram(*args):
    solved = gram(*args)
    count["Jacobi eigenvectors" + (", solved" if solved else ", failed (to the SVD)")] += 1
    return solved


manifold._solve_normal, manifold._solve_gram = counted_normal, counted_gram
manifold._solve_into = manifold._solve_into.py_func
manifold._solve_within_limits = manifold._solve_within_limits.py_func
manifold.project_into = manifold.project_into.py_func
robot = scene.robot
arrays = manifold.project_arrays(robot, scene.table.height)
rng = np.random.default_rng(0)
for node in rng.choice(tree.n, 3000, replace=False):
    action = np.array([rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), rng.uniform(-0.5, 0.5)])
    manifold.project_kernel.py_func(tree.q[node].copy(), action, 0.1,
                                    rng.uniform(-0.3, 0.3, robot.nq), *arrays, 0.5, 1.0, 1.0)
print(f"{Path(sys.argv[1]).stem}, {tree.n} nodes, 3,000 Project steps:")
for what, times in sorted(count.items()):
    print(f"{what}: {times}")
