"""Would a 'tipping world' in the judge see what PyBullet topples? Every saved plan of a
benchmark run executed in MuJoCo by the judge (10-degree tilt bound) in its nominal world with
every object's support friction scaled by SCALE (the tipping rule's mu_s h grows with it), and
in PyBullet at the nominal friction.

    python docs/benchmark/experiments/tilt_bound/tip_world.py RUN_DIR SCALE > rows.jsonl
"""
import dataclasses
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "judge_timestep"))
from timestep import Plan  # noqa: E402

from rearrangement_planner.execution.pybullet_check import check_execution_pybullet  # noqa: E402
from rearrangement_planner.world3d.judge import judge  # noqa: E402


def main(run: Path, scale: float) -> None:
    for path in sorted((run / "plans").glob("*.npz")):
        plan = Plan(path)
        scene = plan.scene
        gripped = dataclasses.replace(scene, objects=tuple(
            dataclasses.replace(o, support_friction=o.support_friction * scale)
            for o in scene.objects))
        nominal, tipping = judge(scene, plan), judge(gripped, plan)
        report = check_execution_pybullet(scene, plan)
        print(json.dumps({"plan": path.name, "nominal_tipped": list(nominal.nominal.tipped),
                          "nominal_reached": nominal.nominal.reached,
                          "scaled_tipped": list(tipping.nominal.tipped),
                          "pybullet_toppled": list(report.toppled),
                          "pybullet_reached": report.reached}), flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[1]), float(sys.argv[2]))
