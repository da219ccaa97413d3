"""What PC-RRT's searches report when they end without a plan (`Search.why_unsolved`): the
shipped options bounded at 1,000 iterations, seed 0, on the varied scenes the shipped default
left unsolved on held-out seeds 4-8. Usage: python3 unsolved_reasons.py [SCENE ...]"""
import sys

from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions
from rearrangement_planner.planning.requests.warmup import warm_up

warm_up()
for name in sys.argv[1:] or ["v2_s2", "v2_s3", "v4_s0", "v5_s0", "v6_s3", "v6_s4", "v7_s0",
                             "v7_s2", "v7_s3"]:
    scene = load_scene(f"config/benchmark/varied/{name}.yaml")
    result = PCRRT(scene, PCRRTOptions(max_iterations=1000)).plan(seed=0)
    print(f"{name}: {result.outcome.value}: {result.message}", flush=True)
