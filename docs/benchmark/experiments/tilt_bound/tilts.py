"""How far does MuJoCo tilt the objects that PyBullet topples? Every saved plan of a benchmark
run executed in its nominal world by the 3D judge (no tilt bound: the largest tilt of every
object) and by PyBullet (which objects end toppled).

    python docs/benchmark/experiments/tilt_bound/tilts.py RUN_DIR > rows.jsonl
"""
import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "judge_timestep"))
from timestep import Plan  # noqa: E402

from rearrangement_planner.execution.pybullet_check import check_execution_pybullet  # noqa: E402
from rearrangement_planner.world3d.judge import judge  # noqa: E402


def main(run: Path) -> None:
    for path in sorted((run / "plans").glob("*.npz")):
        plan = Plan(path)
        verdict = judge(plan.scene, plan, (), tilt_bound=math.pi)
        report = check_execution_pybullet(plan.scene, plan)
        names = [o.name for o in plan.scene.objects]
        print(json.dumps({
            "plan": path.name,
            "mujoco_max_tilt_deg": dict(zip(names, [round(math.degrees(t), 2) for t in
                                                    verdict.nominal.max_tilt])),
            "mujoco_reached": bool(verdict.nominal.goal_distance_m <= plan.scene.goal.radius),
            "pybullet_max_tilt_deg": {o.name: round(o.max_tilt_deg, 2) for o in report.objects},
            "pybullet_toppled": list(report.toppled), "pybullet_reached": report.reached}),
            flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
