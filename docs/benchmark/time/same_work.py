"""The same search, timed: PC-RRT with the shipped options, seed 0, for a fixed number of
iterations on varied scenes (docs/benchmark.md, "The same searches, faster"). A change that
keeps plans makes exactly the same iterations and propagation steps, so the time is the only
difference. Run from the checkout to measure:

    python docs/benchmark/time/same_work.py v1_s1,v2_s1 1500

prints the total search time and, per scene, iterations / propagation steps / seconds."""

import sys
import time
from pathlib import Path

from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions
from rearrangement_planner.planning.requests.warmup import warm_up
from rearrangement_planner.tools.benchmark import load_trial_scene

warm_up()
scenes, iterations = sys.argv[1].split(","), int(sys.argv[2])
total, parts = 0.0, []
for name in scenes:
    scene = load_trial_scene(Path("config/benchmark/varied") / f"{name}.yaml")
    planner = PCRRT(scene, PCRRTOptions(time_limit=1000, max_iterations=iterations))
    t = time.perf_counter()
    result = planner.plan(seed=0)
    seconds = time.perf_counter() - t
    total += seconds
    parts.append(f"{name}:{result.iterations}/{result.propagation_steps}/{seconds:.2f}")
print(f"total {total:.2f}s", " ".join(parts))
