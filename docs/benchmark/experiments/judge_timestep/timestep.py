"""Does the 3D judge's 2 ms step agree with the check's 1 ms? Every saved plan of a benchmark
run (plans/*.npz beside trials.csv) executed with the servo arm in its nominal world at both
steps: reached or not, and the goal distance.

    python docs/benchmark/experiments/judge_timestep/timestep.py RUN_DIR > rows.jsonl
"""
import json
import sys
import time
from pathlib import Path

import numpy as np

from rearrangement_planner.tools.benchmark import load_trial_scene
from rearrangement_planner.world3d.execution import check_execution
from rearrangement_planner.world3d.judge import judge_options


class Plan:
    def __init__(self, path: Path):
        data = np.load(path)
        self.times, self.positions = data["times"], data["positions"]
        self.scene = load_trial_scene(str(data["scene_path"]), str(data["robot"]))
        self.joint_names = self.scene.robot.joint_names

    def __len__(self):
        return len(self.times)


def main(run: Path) -> None:
    for path in sorted((run / "plans").glob("*.npz")):
        plan = Plan(path)
        row = {"plan": path.name}
        for dt in (0.001, 0.002):
            started = time.perf_counter()
            report = check_execution(plan.scene, plan, None, judge_options(dt))
            row[f"{dt * 1000:g}ms"] = {"reached": report.reached,
                                       "goal_distance_m": round(report.goal_distance_m, 4),
                                       "toppled": list(report.toppled),
                                       "wall_s": round(time.perf_counter() - started, 2)}
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
