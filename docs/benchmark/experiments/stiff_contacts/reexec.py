"""The same plans executed in MuJoCo with soft and stiff contacts (docs/experiments.md,
2026-11-27, "MuJoCo's contacts made stiff").

    python docs/benchmark/experiments/stiff_contacts/reexec.py TIMECONST ARM PLAN.npz ...

Each plan (a benchmark run's plans/<scene>__<planner>__<seed>.npz) is played open loop in
MuJoCo with `ExecutionOptions(arm=ARM, contact_timeconst=TIMECONST)` (the trajectory's
velocities by finite differences), and its arm path is replayed in the planner's model (the
rollouts' options). One JSON line per plan: reached, toppled objects, the goal object's
distance from the goal point, and the model's error (m) on the goal object's end position.
Scenes are read from config/benchmark/varied/ by the name the plan recorded.
"""

import json
import sys
from pathlib import Path

import numpy as np

from rearrangement_planner.execution.mujoco_check import ExecutionOptions, check_execution
from rearrangement_planner.physics.options import PhysicsOptions
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.requests.robustness import rollout_options
from rearrangement_planner.planning.requests.trajectory import Trajectory


def main(timeconst: float, arm: str, plans: list[str]) -> None:
    for plan in plans:
        z = np.load(plan)
        scene = load_scene(Path("config/benchmark/varied") / Path(str(z["scene_path"])).name)
        times, positions = z["times"], z["positions"]
        trajectory = Trajectory(scene.robot.joint_names, times, positions,
                                np.gradient(positions, times, axis=0))
        report = check_execution(scene, trajectory, None,
                                 ExecutionOptions(arm=arm, contact_timeconst=timeconst))
        physics = Physics(scene, rollout_options(PhysicsOptions()))
        state = scene.initial_state()
        for q in z["arm_path"][1:]:
            result = physics.step(state, q)
            if not result.valid:
                break
            state = result.state
        goal = scene.goal_index
        error = float(np.hypot(*(state.objects[goal, :2]
                                 - np.asarray(report.objects[goal].pose[:2]))))
        print(json.dumps({"plan": Path(plan).name, "reached": bool(report.reached),
                          "toppled": list(report.toppled),
                          "goal_distance_m": round(report.goal_distance_m, 4),
                          "model_error_m": round(error, 4)}), flush=True)


if __name__ == "__main__":
    main(float(sys.argv[1]), sys.argv[2], sys.argv[3:])
