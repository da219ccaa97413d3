"""Which judge step predicts the other engine? Every saved plan of a benchmark run executed in
its nominal world by the 3D judge (`world3d.judge`, 10-degree tilt bound) at 1 and 2 ms, and by
PyBullet (`execution.pybullet_check`, the engine the planner does not use).

    python docs/benchmark/experiments/judge_timestep/against_pybullet.py RUN_DIR > rows.jsonl
"""
import json
import sys
from pathlib import Path

from timestep import Plan

from rearrangement_planner.execution.pybullet_check import check_execution_pybullet
from rearrangement_planner.world3d.judge import judge


def main(run: Path) -> None:
    for path in sorted((run / "plans").glob("*.npz")):
        plan = Plan(path)
        row = {"plan": path.name}
        for dt in (0.001, 0.002):
            verdict = judge(plan.scene, plan, (), timestep=dt)
            row[f"judge_{dt * 1000:g}ms"] = {"reached": verdict.nominal.reached,
                                             "tipped": list(verdict.nominal.tipped),
                                             "goal_distance_m": round(
                                                 verdict.nominal.goal_distance_m, 4),
                                             "wall_s": round(verdict.wall_time_s, 2)}
        report = check_execution_pybullet(plan.scene, plan)
        row["pybullet"] = {"reached": report.reached, "toppled": list(report.toppled),
                           "goal_distance_m": round(report.goal_distance_m, 4)}
        print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
