"""The benchmark's trials as OMPL benchmark log files, so that `ompl_benchmark_statistics.py`
turns them into a database that Planner Arena (plannerarena.org) plots.

The format is OMPL's "benchmark logfile format" (its doc/markdown/benchmark.md gives the grammar
in EBNF): a preamble (library and version, experiment name, experiment properties, host, date,
setup and CPU text blocks, random seed, time and memory limit, runs per planner, total time,
enum types, planner count), then per planner its name, its common properties
(`name = value`), the run properties (`name TYPE`, TYPE one of BOOLEAN, INTEGER, REAL), and one
line per run of values each followed by "; ", then a line ".". An empty value is a missing
measurement.

One log per scene set: the scenes with the same number of movable objects (`n3.log`: the five
3-object scenes; in OMPL's terms one experiment), every planner's trials of it as runs. Each run
carries OMPL's own `time REAL` (the plan time, s), `solved BOOLEAN`, `graph states INTEGER`
(tree size) and `solution length REAL` (arm path, rad, after shortcutting), and ours:
`executed BOOLEAN` (the end-to-end figure: the plan, executed open loop with the servo arm in
MuJoCo, put the goal object in its region with nothing toppled; false when not solved),
`goal_distance REAL` (m, the goal object's final distance from the goal point in the model, or
the least reached when not solved) and the rest of `RUN_PROPERTIES`.
"""

from __future__ import annotations

import platform
import socket
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path

from rearrangement_planner.tools.bench.trials import scene_name

LIBRARY = "rearrangement_planner"
VERSION = "0.1.0"


def _value(column: str, kind: str = "REAL") -> Callable[[dict], str]:
    def get(row: dict) -> str:
        text = row.get(column, "")
        if text == "" or kind == "REAL":
            return text
        return str(int(float(text)))
    return get


RUN_PROPERTIES: tuple[tuple[str, str, Callable[[dict], str]], ...] = (
    ("time", "REAL", _value("plan_time_s")),
    ("solved", "BOOLEAN", _value("solved", "BOOLEAN")),
    ("executed", "BOOLEAN", lambda r: "1" if r["executed_servo"] == "1" else "0"),
    ("executed ideal arm", "BOOLEAN", _value("executed_ideal", "BOOLEAN")),
    ("goal_distance", "REAL", _value("goal_distance_m")),
    ("executed goal distance", "REAL", _value("executed_goal_distance_m")),
    ("toppled objects", "INTEGER", _value("executed_toppled", "INTEGER")),
    ("graph states", "INTEGER", _value("tree_size", "INTEGER")),
    ("iterations", "INTEGER", _value("iterations", "INTEGER")),
    ("solution length", "REAL", _value("path_length_rad_before")),
    ("simplified solution length", "REAL", _value("path_length_rad_after")),
    ("simplification time", "REAL", _value("shortcut_time_s")),
    ("goal push path", "REAL", _value("goal_push_path_m")),
    ("goal turn", "REAL", _value("goal_turn_rad")),
    ("scene", "INTEGER", lambda r: r["scene"].rsplit("_s", 1)[-1]),
    ("seed", "INTEGER", _value("seed", "INTEGER")),
)
"""(name, type, value of a trials.csv row) of every run. `solution length` is the arm path
(rad) as planned, `simplified solution length` after shortcutting; `scene` is the scene's index
within its set (n3_s4: 4)."""


def write_logs(rows: Sequence[dict], protocol: dict, out: Path) -> list[Path]:
    """One log per scene set in `out` (`n<objects>.log`), from trials.csv `rows` of one protocol
    (`benchmark.summarize`'s `protocol`); returns the paths written."""
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for objects in sorted({int(r["objects"]) for r in rows}):
        group = [r for r in rows if int(r["objects"]) == objects]
        path = out / f"n{objects}.log"
        path.write_text(log_text(group, protocol, objects))
        paths.append(path)
    return paths


def log_text(rows: Sequence[dict], protocol: dict, objects: int) -> str:
    """The log of one scene set: `rows` are its trials (every planner)."""
    planners = [p for p in protocol["planners"] if any(r["planner"] == p for r in rows)]
    runs = max((sum(r["planner"] == p for r in rows) for p in planners), default=0)
    scenes = sorted({r["scene"] for r in rows})
    settings = protocol.get("request_settings") or {}
    lines = [f"{LIBRARY} version {VERSION}",
             f"Experiment {scene_name(objects, 0).split('_')[0]}_objects",
             "1 experiment properties",
             f"objects INTEGER={objects}",
             f"Running on {socket.gethostname().replace(' ', '_') or 'localhost'}",
             f"Starting at {datetime.now(UTC).strftime('%Y-%m-%d %H:%M:%S')}",
             "<<<|",
             f"scenes: {' '.join(scenes)}",
             f"seeds: {' '.join(str(s) for s in protocol['seeds'])}",
             "request settings changed from the product default: "
             + (", ".join(f"{k}={v}" for k, v in sorted(settings.items())) or "none"),
             "|>>>",
             "<<<|",
             f"{platform.machine()} {platform.processor() or platform.platform()}",
             "|>>>",
             f"{min(int(s) for s in protocol['seeds']) if protocol['seeds'] else 0} is the "
             f"random seed",
             f"{float(protocol['time_limit']):g} seconds per run",
             "0 MB per run",
             f"{runs} runs per planner",
             f"{sum(float(r['trial_wall_s'] or 0) for r in rows):.3f} seconds spent to collect "
             f"the data",
             "0 enum types",
             f"{len(planners)} planners"]
    for planner in planners:
        own = [r for r in rows if r["planner"] == planner]
        name, _, variant = planner.partition(":")
        common = [f"planner = {name}"] + ([f"settings = {variant}"] if variant else [])
        if protocol.get("robot"):
            common.append(f"robot = {protocol['robot']}")
        lines.append(planner)
        lines.append(f"{len(common)} common properties")
        lines += common
        lines.append(f"{len(RUN_PROPERTIES)} properties for each run")
        lines += [f"{prop} {kind}" for prop, kind, _ in RUN_PROPERTIES]
        lines.append(f"{len(own)} runs")
        for row in own:
            lines.append("".join(f"{get(row)}; " for _, _, get in RUN_PROPERTIES))
        lines.append(".")
    return "\n".join(lines) + "\n"
