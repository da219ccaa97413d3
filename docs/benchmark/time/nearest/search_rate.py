"""Seconds one PC-RRT tree takes for 5,000 ... 60,000 iterations of a fixed-set scene (default
n4_s0, seed 100, no time limit to speak of), with its tree size and propagation steps: the
same search in every clone whose plans are the same, so two clones' seconds compare
(docs/benchmark.md, "Nearest skips far arrangements").

    PYTHONPATH=CLONE AMENT_PREFIX_PATH=.venv python search_rate.py [scene.yaml]
"""
import sys
import time
from pathlib import Path

from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.requests.pipeline import Candidates
from rearrangement_planner.planning.requests.request import PlanRequest
from rearrangement_planner.planning.requests.warmup import warm_up

warm_up()
path = sys.argv[1] if len(sys.argv) > 1 else "config/benchmark/scenes/n4_s0.yaml"
scene = load_scene(Path(path))
for cap in (5000, 15000, 30000, 60000):
    request = PlanRequest.from_settings(
        scene, "pc-rrt", {"time_limit": 300, "trees": 1, "max_iterations": cap}, 100)
    search = Candidates(request, Physics(scene, request.physics), request.options.termination())
    t0 = time.monotonic()
    result = search.plan(100)
    print(f"{cap} iterations: solved {result.solved}, {result.iterations} iterations, "
          f"{result.tree_size} nodes, {result.propagation_steps} steps, "
          f"{time.monotonic() - t0:.2f} s", flush=True)
