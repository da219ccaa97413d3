"""Diagnostic (docs/experiments.md, "Candidates from one tree"): one PC-RRT tree of the shipped
options, continued after its first plan for up to as many iterations again, collecting up to
four more plans. Each plan is shortcut, finished and judged as robust selection judges a
candidate (`pipeline.Candidates`, 20 rollouts, the seed of candidate k). After each plan:

- keep:  its goal node is never nearest again (its arrangement's places set far away);
- reset: the same, and the search's best goal distance set back to the start's, so that greedy
         goal pushes start again from every new best;
- prune: the whole subtree from the plan's first node that moved the goal object is never
         nearest again, and the best reset: the next plan must find another route for it.

From the checkout: python docs/benchmark/experiments/shared_tree/continue_tree.py n6_s2 2 keep
Prints one JSON line: per plan [iterations, seconds, robustness, goal travel (m)]."""
import json, sys, time
import numpy as np
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.requests.request import PlanRequest
from rearrangement_planner.planning.requests.parallel import RaceOptions
from rearrangement_planner.planning.requests.pipeline import Candidates, candidate_seed
from rearrangement_planner.planning.requests.robustness import goal_travel
from rearrangement_planner.planning.planners.pcrrt import PCRRT, _Run
from rearrangement_planner.planning.machinery.termination import Termination
from rearrangement_planner.planning.requests.warmup import warm_up

warm_up()
scene_name, seed, mode = sys.argv[1], int(sys.argv[2]), sys.argv[3]
extra = int(sys.argv[4]) if len(sys.argv) > 4 else 4
scene = load_scene(f"config/benchmark/scenes/{scene_name}.yaml")
request = PlanRequest(scene, "pc-rrt", race=RaceOptions(trees=1), seed=seed)
physics = Physics(scene, request.physics)
cands = Candidates(request, physics, request.options.termination())
planner = PCRRT(scene, request.options, physics)

def judge(result, k_seed):
    c = cands.shortcut(result, k_seed)
    return cands.judge(c, k_seed), goal_travel(scene, c.result.states)

out = {"scene": scene_name, "seed": seed, "mode": mode, "plans": []}
t0 = time.monotonic()
run = _Run(planner, seed, Termination.within(60.0), None)
run.begin(scene.initial_state())
first_it = None
while len(out["plans"]) < 1 + extra:
    ended = run.check()
    if ended is not None:
        break
    if first_it is not None and run.iterations - first_it > first_it:
        break
    found = planner._iterations(run)
    if found is None:
        continue
    node = run.tree.n - 1
    tree = run.tree
    if mode == "prune":
        path = []
        i = node
        while i >= 0:
            path.append(i); i = int(tree.parent[i])
        path.reverse()
        g = scene.goal_index
        root_goal = tree.objects[0, g, :2]
        cut = next(i for i in path if np.any(tree.objects[i, g, :2] != root_goal))
        gone = np.zeros(tree.n, bool); gone[cut] = True
        for i in range(cut + 1, tree.n):
            gone[i] = gone[tree.parent[i]]
        for a in np.unique(tree.arrangement[:tree.n][gone]):
            tree.places[:, :, a] = 1e6
        run.best = run.start_distance
    else:
        a = run.tree.arrangement[node]
        run.tree.places[:, :, a] = 1e6          # the goal node is never nearest
    if mode == "reset":
        run.best = run.start_distance
    k = len(out["plans"])
    score, travel = judge(found, candidate_seed(seed, k))
    out["plans"].append([run.iterations, round(time.monotonic() - t0, 2), score, round(travel, 3)])
    if first_it is None:
        first_it = run.iterations
print(json.dumps(out), flush=True)
