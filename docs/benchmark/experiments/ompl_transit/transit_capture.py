"""Capture DARRT's RRTTransit queries (q_a, q_b, objects) on some scenes."""
import sys, pickle, numpy as np
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.planners import darrt as D
from rearrangement_planner.planning.requests.warmup import warm_up
from rearrangement_planner.tools.benchmark import load_trial_scene
warm_up()
queries = []
orig = D.DARRT._rrt_connect
def spy(self, q_a, q_b, objects, rng, stop, step=0.2):
    queries.append((self.scene_path, np.array(q_a), np.array(q_b), np.array(objects)))
    return orig(self, q_a, q_b, objects, rng, stop, step)
D.DARRT._rrt_connect = spy
for path in sys.argv[2:]:
    scene = load_trial_scene(path)
    for seed in range(2):
        planner = D.DARRT(scene, D.DARRTOptions(time_limit=20.0))
        planner.scene_path = path
        r = planner.plan(seed=seed)
        print(path, seed, r.outcome.name, len(queries), flush=True)
        if len(queries) > 60: break
pickle.dump(queries, open(sys.argv[1], "wb"))
