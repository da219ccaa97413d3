"""`rearrangement-bench report SUMMARY.json ...`: the benchmark's results table, printed from the
summary.json files of finished runs (`rearrangement-bench run` writes them, `benchmark.summarize`).

One Markdown row per run and planner, in the order given: the scene set and seeds, the planner,
solved, reached when executed open loop (in every engine that executed the plans, and in MuJoCo
and PyBullet apart), plans toppling, perturbed executions reached, the robustness score's
calibration (largest gap per fifth of its range, Brier score), the request time's median and p90,
and the closed loop (reached within its re-plans, median time to goal) where the run closed it.
A figure a summary does not hold (one written before PyBullet judged plans, or before perturbed
executions) is "–". The table depends on the files' contents alone, so README.md and
docs/benchmark.md carry it verbatim and a test holds them to it (test/test_docs.py).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from rearrangement_planner.tools.bench.trials import BenchmarkError

MISSING = "–"
HEAD = ["scenes, seeds, budget", "planner", "solved", "reached, executed", "in MuJoCo",
        "in PyBullet", "plans toppling", "perturbed executions reached",
        "calibration: largest gap / Brier", "request median / p90",
        "closed loop: reached / time to goal"]
BOTH = "mujoco+pybullet"
"""`end_to_end.engines` of a run whose plans were executed in MuJoCo and in PyBullet."""


def load_summary(path: Path) -> dict[str, Any]:
    """The summary.json at `path`; `BenchmarkError` when it is missing or no run's summary."""
    try:
        summary = json.loads(Path(path).read_text())
    except OSError as exc:
        raise BenchmarkError("SUMMARY.json", f"{path}: {exc.strerror}") from None
    except ValueError as exc:
        raise BenchmarkError("SUMMARY.json", f"{path}: not JSON ({exc})") from None
    if not isinstance(summary, dict) or not isinstance(summary.get("planners"), dict) \
            or not isinstance(summary.get("protocol"), dict):
        raise BenchmarkError("SUMMARY.json", f"{path}: not the summary.json of a "
                                             f"`rearrangement-bench run` (no protocol and "
                                             f"planners)")
    return summary


def _share(k: int, n: int) -> str:
    return f"{k}/{n} ({100 * k / n:.0f} %)" if n else MISSING


def _number(value: Any, digits: int) -> str:
    return MISSING if value is None else f"{value:.{digits}f}"


def _seeds(seeds: Sequence[int]) -> str:
    """0 1 2 as "seeds 0–2", 9 10 as "seeds 9, 10", 0 as "seed 0"."""
    seeds = sorted(seeds)
    if len(seeds) > 2 and seeds == list(range(seeds[0], seeds[-1] + 1)):
        return f"seeds {seeds[0]}–{seeds[-1]}"
    return ("seed " if len(seeds) == 1 else "seeds ") + ", ".join(str(s) for s in seeds)


def protocol_cell(protocol: dict[str, Any]) -> str:
    """The run's scenes (how many, of which set), seeds, budget and any --set of its requests."""
    sets = protocol.get("scene_sets") or [protocol.get("scene_set") or "file"]
    scenes = len(protocol.get("scenes") or [])
    kinds = " + ".join(s for s in sets if s != "file")     # "file": scenes named by file
    named = f"{kinds} " if kinds else ""
    text = f"{scenes} {named}scenes{' (quick)' if protocol.get('quick') else ''}, " \
           f"{_seeds(protocol.get('seeds') or [])}"
    if protocol.get("time_limit") is not None:
        text += f", {float(protocol['time_limit']):g} s"
    settings = protocol.get("request_settings") or {}
    if settings:
        text += ", " + " ".join(f"{name}={value}" for name, value in settings.items())
    return text


def planner_row(protocol: dict[str, Any], label: str, p: dict[str, Any]) -> list[str]:
    """The cells of one planner of one run."""
    e2e = p.get("end_to_end") or {}
    both = e2e.get("engines") == BOTH
    requests = e2e.get("requests", 0)
    reached = (f"{_share(e2e['reached'], requests)}, {'both engines' if both else 'MuJoCo'}"
               if "reached" in e2e and requests else MISSING)
    mujoco = _share(e2e["reached_mujoco"], requests) if "reached_mujoco" in e2e else MISSING
    pybullet = _share(e2e["reached_pybullet"], requests) if both else MISSING

    top = p.get("toppled") or {}
    toppling = _share(top["plans_toppling"], top["checked"]) if top.get("checked") else MISSING
    if both and toppling != MISSING and "plans_toppling_pybullet" in top:
        toppling += (f"; MuJoCo {top['plans_toppling_mujoco']}, "
                     f"PyBullet {top['plans_toppling_pybullet']}")

    pert = (p.get("executed") or {}).get("perturbed") or {}
    perturbed = _share(pert["reached"], pert["executions"]) if pert.get("executions") \
        else MISSING
    if both and perturbed != MISSING and "reached_pybullet" in pert:
        perturbed += f"; MuJoCo {pert['reached_mujoco']}, PyBullet {pert['reached_pybullet']}"

    cal = p.get("calibration") or {}
    calibration = (f"{_number(cal.get('largest_bin_gap'), 2)} / {_number(cal.get('brier'), 3)}"
                   if cal.get("brier") is not None else MISSING)
    times = p.get("request_time_s") or {}
    request = (f"{_number(times.get('median'), 1)} / {_number(times.get('p90'), 1)} s"
               if times else MISSING)

    loop = p.get("closed_loop")
    closed = MISSING
    if loop:
        to_goal = loop.get("time_to_goal_s_median") or {}
        replans = f"{loop['replan']} re-plan{'' if loop['replan'] == 1 else 's'}"
        closed = (f"{_share(loop['reached_closed_loop'], loop['requests'])} within {replans} "
                  f"/ {_number(to_goal.get('closed_loop'), 1)} s "
                  f"(open loop {_number(to_goal.get('open_loop'), 1)} s)")
    return [protocol_cell(protocol), label, str(p.get("solved", MISSING)), reached, mujoco,
            pybullet, toppling, perturbed, calibration, request, closed]


def report(paths: Sequence[Path]) -> str:
    """The results table of the summaries at `paths`: a Markdown table, one row per run and
    planner in the order given (the planners in their summary's order), without a final newline.
    The same files give the same text."""
    lines = ["| " + " | ".join(HEAD) + " |", "|" + "---|" * len(HEAD)]
    for path in paths:
        summary = load_summary(path)
        for label, planner in summary["planners"].items():
            lines.append("| " + " | ".join(planner_row(summary["protocol"], label, planner))
                         + " |")
    return "\n".join(lines)


def report_command(summaries: Sequence[Path]) -> int:
    """`rearrangement-bench report`: print the table; exit code 0 (`BenchmarkError` on a file
    that is no run's summary)."""
    print(report(summaries))
    return 0
