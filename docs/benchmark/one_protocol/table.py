"""The one-protocol table of issue 39 from the runs' summary.json files (docs/benchmark.md,
"Plans that survive the world: the one protocol at the close").

    python docs/benchmark/one_protocol/table.py
"""
import json
import math
from pathlib import Path

HERE = Path(__file__).resolve().parent
BENCH = HERE.parent
ARMS = [  # label, summary, planner
    ("varied 0–2, PC-RRT before (`4d4222d`)", BENCH / "varied/before/summary.json", "pc-rrt"),
    ("varied 0–2, **PC-RRT now** (`f9ba799`)", HERE / "varied_pc_rrt/summary.json", "pc-rrt"),
    ("varied 0–2, slice-based RRT now (`f9ba799`)", HERE / "varied_slice_rrt/summary.json",
     "slice-rrt"),
    ("fixed 0–2, PC-RRT before (`41cc230`/`e70bd7c`)", BENCH / "default/summary.json", "pc-rrt"),
    ("fixed 0–2, **PC-RRT now** (`f9ba799`)", HERE / "fixed_pc_rrt/summary.json", "pc-rrt"),
]


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def row(label: str, path: Path, planner: str) -> str:
    if not path.exists():
        return f"| {label} | (not run) |"
    p = json.loads(path.read_text())["planners"][planner]
    e2e, ex = p["end_to_end"], p["executed"]
    lo, hi = wilson(e2e["reached"], e2e["requests"])
    reached = (f"{e2e['reached']} ({100 * e2e['share']:.0f} %; "
               f"{100 * lo:.0f}–{100 * hi:.0f} %)")
    pert = ex.get("perturbed")
    perturbed = (f"{pert['reached']}/{pert['executions']} ({100 * pert['share']:.0f} %)"
                 if pert else "not measured")
    contact = ex.get("plans_with_object_contact")
    cal = p.get("calibration")
    calibration = (f"{cal['brier']:.3f} / {cal['largest_bin_gap']:.2f}" if cal else "–")
    cells = [label, reached, str(p["solved"]), perturbed,
             f"{p['toppled']['plans_toppling']}/{p['toppled']['checked']}",
             f"{contact}/{ex['checked']}" if contact is not None else "–",
             f"{ex['goal_turn_rad_median']:.2f} rad", f"{ex['goal_push_path_ratio_median']:.2f}",
             f"{p['request_time_s']['median']:.1f} / {p['request_time_s']['p90']:.1f} s",
             calibration]
    return "| " + " | ".join(cells) + " |"


def bins(label: str, path: Path, planner: str) -> str:
    if not path.exists():
        return ""
    cal = json.loads(path.read_text())["planners"][planner].get("calibration")
    if not cal:
        return ""
    cells = [f"{b['mean_score']:.2f}/{b['reached_share']:.2f} ({b['plans']})" for b in cal["bins"]]
    return f"- {label}: " + ", ".join(cells)


def main() -> None:
    print("| requests (105 each) | reached, executed (95 %) | solved | perturbed executions "
          "reached | plans toppling | plans where objects touched | goal turn (median) | "
          "push path / straight | request time median / p90 | Brier / largest gap |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for arm in ARMS:
        print(row(*arm))
    print()
    print("Calibration, per fifth of the score: mean score / executed share (plans)")
    for arm in ARMS:
        line = bins(*arm)
        if line:
            print(line)


if __name__ == "__main__":
    main()
