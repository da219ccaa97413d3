"""DARRT's RRTTransit queries: our RRT-Connect vs OMPL 2's RRTConnect, same validity checker."""
import sys, pickle, time, numpy as np
from ompl import base as ob, geometric as og, util as ou
from rearrangement_planner.planning.planners import darrt as D
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.tools.benchmark import load_trial_scene
ou.setLogLevel(ou.LogLevel.LOG_NONE) if hasattr(ou, "setLogLevel") else None
queries = pickle.load(open(sys.argv[1], "rb"))
limit = float(sys.argv[2]); every = int(sys.argv[3])
planners = {}
rows = []
for qi, (path, q_a, q_b, objects) in enumerate(queries[::every]):
    if path not in planners:
        scene = load_trial_scene(path)
        planners[path] = D.DARRT(scene, D.DARRTOptions(time_limit=20.0))
    p = planners[path]
    robot = p.robot
    for seed in range(2):
        rng = np.random.default_rng(seed)
        t = time.perf_counter()
        ours = p._rrt_connect(q_a, q_b, objects, rng, Termination.within(limit))
        t_ours = time.perf_counter() - t
        n = robot.nq
        space = ob.RealVectorStateSpace(n)
        b = ob.RealVectorBounds(n)
        for j in range(n):
            b.setLow(j, float(robot.lower[j])); b.setHigh(j, float(robot.upper[j]))
        space.setBounds(b)
        ss = og.SimpleSetup(space)
        checks = [0]
        def valid(s, p=p, objects=objects):
            checks[0] += 1
            return p._free(np.array([s[j] for j in range(n)]), objects)
        ss.setStateValidityChecker(valid)
        si = ss.getSpaceInformation()
        space.setup()
        si.setStateValidityCheckingResolution(D.TRANSIT_STEP / space.getMaximumExtent())
        planner = og.RRTConnect(si); planner.setRange(0.2); ss.setPlanner(planner)
        st, gl = space.allocState(), space.allocState()
        for j in range(n):
            st[j] = float(q_a[j]); gl[j] = float(q_b[j])
        ss.setStartAndGoalStates(st, gl)
        ou.RNG.setSeed(seed + 1) if hasattr(ou.RNG, "setSeed") else None
        t = time.perf_counter()
        solved = ss.solve(limit)
        t_ompl = time.perf_counter() - t
        ok = bool(ss.haveExactSolutionPath())
        valid_path = None
        if ok:
            states = ss.getSolutionPath().getStates()
            wps = [np.array([s[j] for j in range(n)]) for s in states]
            valid_path = all(p._line_free(a, c, objects) for a, c in zip(wps[:-1], wps[1:]))
        rows.append((qi, seed, ours is not None, t_ours, ok, t_ompl, valid_path, checks[0]))
        print(f"q{qi} s{seed} ours {'ok' if ours is not None else '--'} {t_ours:6.3f}s  ompl {'ok' if ok else '--'} {t_ompl:6.3f}s valid={valid_path} checks={checks[0]}", flush=True)
r = np.array([(a, b, c, d, e, f) for a, b, c, d, e, f, g, h in rows], dtype=float)
print("ours solved", int(r[:, 2].sum()), "of", len(r), "median", np.median(r[:, 3]), "mean", r[:, 3].mean())
print("ompl solved", int(r[:, 4].sum()), "of", len(r), "median", np.median(r[:, 5]), "mean", r[:, 5].mean())
print("ompl invalid by our check:", sum(1 for x in rows if x[6] is False))
