"""The tables of docs/experiments.md, "Judged in 3D and mended, with candidates from both
planners", printed from the runs' summary.json files (each run holds both arms: the shipped request, judged in 3D,
and `pc-rrt:judge_worlds=0`, the model's answer as before).

    python docs/benchmark/judged/table.py
"""
import json
from pathlib import Path

HERE = Path(__file__).resolve().parent
RUNS = [("varied", HERE / "varied/summary.json"), ("fixed", HERE / "fixed/summary.json")]
ARMS = [("before: the model's answer (`judge_worlds=0`)", "pc-rrt:judge_worlds=0"),
        ("**after: judged in 3D and mended**", "pc-rrt")]


def share(k: int, n: int) -> str:
    return f"{k}/{n} ({100 * k / n:.0f} %)" if n else "–"


def main() -> None:
    print("| scene set, arm | requests | solved | reached, both engines | MuJoCo | PyBullet "
          "| plans toppling (either engine) | perturbed executions, both engines | request "
          "median / p90 | of it the 3D judge, median |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, path in RUNS:
        if not path.exists():
            print(f"| {name} | (not run) |")
            continue
        planners = json.loads(path.read_text())["planners"]
        for label, arm in ARMS:
            p = planners[arm]
            e2e, pert = p["end_to_end"], p["executed"]["perturbed"]
            top = p["toppled"]
            judged = p.get("judged") or {}
            cells = [f"{name}, {label}", str(p["trials"]), str(p["solved"]),
                     share(e2e["reached"], e2e["requests"]),
                     str(e2e["reached_mujoco"]), str(e2e["reached_pybullet"]),
                     share(top["plans_toppling"], top["checked"]),
                     share(pert["reached"], pert["executions"]),
                     f"{p['request_time_s']['median']:.1f} / {p['request_time_s']['p90']:.1f} s",
                     (f"{judged['judge_s']['median']:.1f} s" if judged else "–")]
            print("| " + " | ".join(cells) + " |")
    print()
    print("Calibration: per fifth of the robustness range, the plans' mean score / the share of "
          "their perturbed executions that reached in both engines (plans):")
    print()
    for name, path in RUNS:
        if not path.exists():
            continue
        planners = json.loads(path.read_text())["planners"]
        for label, arm in ARMS:
            cal = planners[arm]["calibration"]
            bins = ", ".join(f"{b['mean_score']:.2f} / {b['reached_share']:.2f} ({b['plans']})"
                             if b["plans"] else "– (0)" for b in cal["bins"])
            print(f"- {name}, {label.replace('*', '')}: {bins}; largest gap "
                  f"{cal['largest_bin_gap']}, Brier {cal['brier']}")
    print()
    for name, path in RUNS:
        if not path.exists():
            continue
        judged = json.loads(path.read_text())["planners"]["pc-rrt"].get("judged")
        if judged:
            print(f"- {name}: of {judged['answers']} judged answers, {judged['reached_nominal']} "
                  f"reached in the judge's nominal world; {judged['mended']} were mended; by "
                  f"planner {judged['by_planner']}; the judge's own time median "
                  f"{judged['judge_s']['median']} s, p90 {judged['judge_s']['p90']} s")


if __name__ == "__main__":
    main()
