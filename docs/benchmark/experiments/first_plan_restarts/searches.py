"""Iterations PC-RRT's first plan takes, one tree, per fixed-set scene and seed, within CAP
iterations (docs/experiments.md, "Restarts for the first plan, simulated"). Appends one JSON
line per search to OUT. From the checkout (two halves ran at once, one per core):

    PYTHONPATH=. AMENT_PREFIX_PATH=.venv python searches.py 30000 OUT 100 110 \\
        config/benchmark/scenes/n4_s*.yaml config/benchmark/scenes/n6_s*.yaml
"""
import json
import sys
import time
from pathlib import Path

from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.requests.pipeline import Candidates
from rearrangement_planner.planning.requests.request import PlanRequest
from rearrangement_planner.planning.requests.warmup import warm_up

warm_up()
cap, out = int(sys.argv[1]), open(sys.argv[2], "a")
seeds = range(int(sys.argv[3]), int(sys.argv[4]))
for path in sys.argv[5:]:
    scene = load_scene(Path(path))
    for seed in seeds:
        request = PlanRequest.from_settings(
            scene, "pc-rrt", {"time_limit": 120, "trees": 1, "max_iterations": cap}, seed)
        search = Candidates(request, Physics(scene, request.physics),
                            request.options.termination())
        t0 = time.monotonic()
        result = search.plan(seed)
        out.write(json.dumps({"scene": Path(path).stem, "seed": seed, "solved": result.solved,
                              "iterations": result.iterations,
                              "s": round(time.monotonic() - t0, 2)}) + "\n")
        out.flush()
