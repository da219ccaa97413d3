"""Plans of the shipped default (robust selection off: min_robustness 0) on easy_push,
default and clutter, seed 1, pickled for check_reports.py (clutter found no plan in the run).

    AMENT_PREFIX_PATH=.venv .venv/bin/python docs/benchmark/time/check_and_fit_speed/make_plans.py
"""
import pickle
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning import PlanRequest, plan_scene
from rearrangement_planner.planning.requests.robustness import RobustOptions
if __name__ == "__main__":
    out=[]
    for name in ("easy_push", "default", "clutter"):
        scene = load_scene(name)
        o = plan_scene(PlanRequest(scene=scene, seed=1, robust=RobustOptions(min_robustness=0)))
        print(name, o.outcome if hasattr(o,'outcome') else '', o.trajectory is not None)
        if o.trajectory is not None: out.append((name, o.trajectory, o.trajectory_states))
    pickle.dump(out, open("/tmp/mj_plans.pkl","wb"))
