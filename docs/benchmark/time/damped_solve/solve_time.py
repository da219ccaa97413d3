"""Project's solves, timed on recorded problems (docs/benchmark.md, "Project's damped solve
by a Cholesky factor"). `record` grows one PC-RRT tree of a fixed-set scene (seed 100,
ITERATIONS), then takes one Project step from each of 3,000 of its nodes with a drawn planar
action (up to 0.1 m/s, 0.5 rad/s) and nullspace velocity (up to 0.3 rad/s), as
../project_solves/solve_count.py does, and saves every (J, xdot, h) the solver is asked, with
whether the normal equations answered it. `time` solves them with the checkout's compiled
`_solve_into`, ROUNDS times over in one compiled loop, and prints the µs per solve, for all
of them and for those the normal equations leave to the fallback, and the largest difference
from LAPACK's SVD solution (`solve_task`'s equation). From a checkout:

    PYTHONPATH=. AMENT_PREFIX_PATH=.venv python solve_time.py record problems.npz \\
        config/benchmark/scenes/n6_s1.yaml 10000
    PYTHONPATH=. AMENT_PREFIX_PATH=.venv python solve_time.py time problems.npz
"""
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

from rearrangement_planner.planning.machinery import manifold

ROUNDS = 20


def record(out: str, scene_path: str, iterations: int) -> None:
    from rearrangement_planner.physics.validation import load_scene
    from rearrangement_planner.planning.machinery import tree as tree_module
    from rearrangement_planner.planning.planners import pcrrt
    from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions

    trees = []

    def recorded(*args, **kwargs):
        trees.append(tree_module.Tree(*args, **kwargs))
        return trees[-1]

    pcrrt.Tree = recorded
    scene = load_scene(Path(scene_path))
    PCRRT(scene, PCRRTOptions(time_limit=1000, max_iterations=iterations)).plan(seed=100)
    tree = trees[-1]
    problems: list[tuple] = []
    normal = manifold._solve_normal

    def kept(jac, xdot, h, qdot, scratch):
        solved = normal(jac, xdot, h, qdot, scratch)
        problems.append((jac.copy(), xdot.copy(), h.copy(), solved))
        return solved

    manifold._solve_normal = kept
    manifold._solve_into = manifold._solve_into.py_func
    manifold._solve_within_limits = manifold._solve_within_limits.py_func
    manifold.project_into = manifold.project_into.py_func
    arrays = manifold.project_arrays(scene.robot, scene.table.height)
    rng = np.random.default_rng(0)
    for node in rng.choice(tree.n, 3000, replace=False):
        action = np.array([rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1),
                           rng.uniform(-0.5, 0.5)])
        manifold.project_kernel.py_func(tree.q[node].copy(), action, 0.1,
                                        rng.uniform(-0.3, 0.3, scene.robot.nq), *arrays,
                                        0.5, 1.0, 1.0)
    shapes = np.array([p[0].shape for p in problems])
    jacs = np.zeros((len(problems), 6, 7))
    hs, xdots = np.zeros((len(problems), 7)), np.zeros((len(problems), 6))
    for i, (jac, xdot, h, _) in enumerate(problems):
        jacs[i, :jac.shape[0], :jac.shape[1]] = jac
        xdots[i, :len(xdot)], hs[i, :len(h)] = xdot, h
    np.savez(out, shapes=shapes, jacs=jacs, xdots=xdots, hs=hs,
             normal=np.array([p[3] for p in problems]))
    print(f"{len(problems)} solves recorded, {int(np.sum(~np.array([p[3] for p in problems])))}"
          " left to the fallback")


@njit   # not cached: a cache keyed by this file would keep another checkout's solver
def _solve_all(shapes, jacs, xdots, hs, which, rounds, out):
    scratch, flat = np.empty(manifold.solver_scratch_size(6, 7)), np.empty(42)
    for _ in range(rounds):
        for i in which:
            m, n = shapes[i, 0], shapes[i, 1]
            jac = flat[:m * n].reshape((m, n))             # contiguous, as Project's are
            for r in range(m):
                for c in range(n):
                    jac[r, c] = jacs[i, r, c]
            manifold._solve_into(jac, xdots[i, :m], hs[i, :n], out[i, :n], scratch)


def svd_solution(jac, xdot, h):
    u, s, vt = np.linalg.svd(jac)
    damping2 = manifold._damping2(s[-1])
    rank = int(np.sum(s > manifold.RANK_TOLERANCE))
    gains = s[:rank] / (s[:rank] ** 2 + damping2)
    return vt[:rank].T @ (gains * (u[:, :rank].T @ xdot)) + vt[rank:].T @ (vt[rank:] @ h)


def timing(path: str) -> None:
    d = np.load(path)
    shapes, jacs, xdots, hs = d["shapes"], d["jacs"], d["xdots"], d["hs"]
    out = np.zeros((len(shapes), 7))
    for name, which in (("all", np.arange(len(shapes))),
                        ("left to the fallback", np.flatnonzero(~d["normal"]))):
        _solve_all(shapes, jacs, xdots, hs, which, 1, out)       # compiled, and warm
        best = np.inf
        for _ in range(5):
            t = time.perf_counter()
            _solve_all(shapes, jacs, xdots, hs, which, ROUNDS, out)
            best = min(best, (time.perf_counter() - t) / (ROUNDS * len(which)))
        error = max(np.abs(out[i, :shapes[i, 1]] - svd_solution(
            jacs[i, :shapes[i, 0], :shapes[i, 1]], xdots[i, :shapes[i, 0]],
            hs[i, :shapes[i, 1]])).max() for i in which)
        print(f"{name}: {len(which)} solves, {best * 1e6:.3f} µs a solve (best of 5), "
              f"largest difference from LAPACK's SVD {error:.1e} rad/s")


if __name__ == "__main__":
    if sys.argv[1] == "record":
        record(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    else:
        timing(sys.argv[2])
