"""Plans of the shipped default with robust selection off (min_robustness 0) on easy_push,
default and clutter, seed 1, pickled to /tmp/mj_plans.pkl for check_reports.py (clutter found
no plan in the run).

    AMENT_PREFIX_PATH=.venv .venv/bin/python docs/benchmark/time/check_and_fit_speed/make_plans.py
"""
import pickle

from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning import PlanRequest, plan_scene
from rearrangement_planner.planning.requests.robustness import RobustOptions

if __name__ == "__main__":
    plans = []
    for name in ("easy_push", "default", "clutter"):
        output = plan_scene(PlanRequest(scene=load_scene(name), seed=1,
                                        robust=RobustOptions(min_robustness=0)))
        print(name, "planned" if output.trajectory is not None else "no plan")
        if output.trajectory is not None:
            plans.append((name, output.trajectory, output.trajectory_states))
    with open("/tmp/mj_plans.pkl", "wb") as f:
        pickle.dump(plans, f)
