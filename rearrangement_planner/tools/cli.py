"""`rearrangement-plan SCENE.yaml`: plan one scene from the command line (docs/design.md, "CLI").

Exit codes: 0 solved, 1 not solved (timeout, start invalid, ...), 2 bad input (one line naming
the problem). The JSON result holds the fields the design lists; `--plot` writes a top view.
The plan request is the product's default (`planning.requests.request.PlanRequest`, the node's too),
changed by the options given.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from rearrangement_planner.io.live import DEFAULT_PORT, LiveView
from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.files import quote
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import SettingError, parse_assignments
from rearrangement_planner.physics.validation import load_scene
from rearrangement_planner.planning.machinery.interface import Progress
from rearrangement_planner.planning.requests.pipeline import PlanOutput, plan_scene
from rearrangement_planner.planning.requests.registry import PLANNERS, planner_spec
from rearrangement_planner.planning.requests.request import (
    DEFAULT_PLANNER,
    STAGES,
    PlanRequest,
    request_settings,
)

FLAGS = {"time_limit": "--time-limit", "trees": "--trees", "shortcut_time": "--shortcut",
         "shortcut_attempts": "--shortcut-attempts", "min_robustness": "--min-robustness",
         "rollouts": "--rollouts", "candidates": "--candidates",
         "travel_penalty": "--travel-penalty", "accept_best": "--accept-best"}
"""The request settings that have an option of their own (the rest: --set NAME=VALUE)."""


def _default(name: str) -> Any:
    """The product default of a request setting (`planning.requests.request`: written once)."""
    return next(s.default for s in request_settings() if s.name == name)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rearrangement-plan",
        description="Plan a nonprehensile whole-arm rearrangement for one scene: the arm pushes "
                    "objects (any link, several at once) until the goal object is inside its "
                    "goal region. Exit code 0 = solved, 1 = not solved, 2 = bad input.")
    parser.add_argument("scene", type=Path, nargs="?",
                        help="scene YAML file (docs/design.md format) or a shipped scene's name")
    parser.add_argument("--planner", choices=list(PLANNERS), default=DEFAULT_PLANNER,
                        help=f"planning algorithm (default {DEFAULT_PLANNER}): " + "; ".join(
                            f"{name}: {spec.summary}" for name, spec in PLANNERS.items()))
    parser.add_argument("--time-limit", type=float, metavar="S",
                        help="planning budget in seconds; running out is a failure (default "
                             f"{_default('time_limit'):g})")
    parser.add_argument("--seed", type=int, default=0, metavar="N",
                        help="random seed: the same scene, options and seed give the same plan "
                             "(default 0)")
    parser.add_argument("--trees", type=int, metavar="N",
                        help="independent trees grown at once, one process each; the plan "
                             "found in the fewest iterations wins, so the result does not "
                             "depend on the machine's speed (OR-parallel RRT; default "
                             f"{_default('trees')}; 1 = a single tree in this process)")
    parser.add_argument("--shortcut", type=float, metavar="S",
                        help="seconds of path shortcutting (King et al. 2015, §IV) after a plan "
                             f"is found (default {_default('shortcut_time'):g}; 0: none)")
    parser.add_argument("--shortcut-attempts", type=int, metavar="N",
                        help="stop shortcutting after N attempts even if time is left; a "
                             "bound that ends first makes the shortcut path reproducible "
                             f"(default {_default('shortcut_attempts')}; 0: time only)")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="set any setting of the request, e.g. --set push_bias=0 "
                             "--set max_turn=0 (darrt: --set transit_time_limit=5); a setting "
                             "the planner does not read is refused; repeatable; "
                             "`--list-settings` shows them")
    parser.add_argument("--list-settings", action="store_true",
                        help="print the chosen planner's settings (name, default, range, "
                             "description) and exit")
    parser.add_argument("--json", type=Path, metavar="OUT",
                        help="write the result as JSON to OUT ('-' for standard output)")
    parser.add_argument("--record", type=Path, metavar="OUT.mcap",
                        help="record the inputs, trajectory, predicted object poses, markers "
                             "and a metadata record to a rosbag2-compatible MCAP file")
    parser.add_argument("--plot", type=Path, metavar="OUT.png",
                        help="write a top view PNG: table, objects at start and end, their "
                             "paths, the end-effector path and the goal region")
    parser.add_argument("--min-robustness", type=float, metavar="R",
                        help="robust selection: a candidate plan that reaches the goal in this "
                             "share (0-1) of perturbed rollouts in the planner's physics ends "
                             "the search; else up to --candidates plans are planned and the "
                             "best ranked answers (--accept-best) or the request fails "
                             f"(default {_default('min_robustness'):g}; 0: off, the first plan)")
    parser.add_argument("--rollouts", type=int, metavar="N",
                        help=f"perturbed rollouts per candidate (default {_default('rollouts')})")
    parser.add_argument("--candidates", type=int, metavar="K",
                        help=f"most candidate plans (default {_default('candidates')})")
    parser.add_argument("--travel-penalty", type=float, metavar="P",
                        help="candidates are ranked by robustness less P per metre their goal "
                             f"object is pushed (default {_default('travel_penalty'):g}; 0: the "
                             "most robust)")
    parser.add_argument("--accept-best", action=argparse.BooleanOptionalAction,
                        help="when no candidate reaches --min-robustness, answer with the best "
                             "ranked one instead of failing (default: "
                             f"{'on' if _default('accept_best') else 'off'})")
    parser.add_argument("--check-execution", action="store_true",
                        help="execute the plan open loop in MuJoCo with the arm's real collision "
                             "meshes (ideal and servo-driven arm) and report whether the goal "
                             "object really reaches its region, each object's predicted-vs-"
                             "executed error, toppled objects and object contacts (JSON "
                             "'execution'; the plot shows the executed paths dotted)")
    parser.add_argument("--trials", type=int, default=0, metavar="N",
                        help="with --check-execution: also N executions in perturbed worlds "
                             "(friction x0.7-1.3, mass x0.8-1.2, pose noise 5 mm / 2 deg)")
    parser.add_argument("--replan", type=int, default=0, metavar="N",
                        help="with --check-execution: close the loop with the servo arm: "
                             "while the goal object misses its region upright, move the arm "
                             "back out of contact, observe, plan again from there and execute, "
                             "up to N times (JSON 'executions', one entry per attempt, and "
                             "'verdict'; with --trials, in each perturbed world too)")
    _add_output_options(parser)
    return parser


def _add_output_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quiet", action="store_true", help="no progress line on stderr")
    parser.add_argument("--live", nargs="?", type=int, const=DEFAULT_PORT, default=None,
                        metavar="PORT",
                        help=f"serve a live 3D view of the scene, the search, the answer and "
                             f"its executions for Foxglove on ws://127.0.0.1:PORT (default "
                             f"{DEFAULT_PORT}; 0: any free port); kept open until Enter when "
                             f"standard input is a terminal")


def _progress_printer(quiet: bool):
    if quiet:
        return None

    def show(p: Progress) -> None:
        print(f"\rplanning: {p.elapsed:5.1f} s, {p.iterations} iterations, tree {p.tree_size}, "
              f"best goal distance {p.best_goal_distance:.3f} m", end="", file=sys.stderr,
              flush=True)

    return show


def plan_request(args: argparse.Namespace, scene: Scene) -> PlanRequest:
    """The plan request of the command line: the product's default, changed by the options
    given and every --set NAME=VALUE. RearrangementError names the option at fault."""
    values: dict[str, Any] = {name: getattr(args, flag[2:].replace("-", "_"))
                              for name, flag in FLAGS.items()}
    values = {name: value for name, value in values.items() if value is not None}
    try:
        values.update(parse_assignments(request_settings(), args.set))
    except ValueError as exc:
        raise RearrangementError(f"--set {exc}") from None
    try:
        return PlanRequest.from_settings(scene, args.planner, values, seed=args.seed)
    except SettingError as exc:
        flag = {**FLAGS, "seed": "--seed", "planner": "--planner"}.get(exc.name, "--set")
        raise RearrangementError(f"{flag}: {exc}") from None


def _settings_table(planner: str) -> str:
    lines = [f"settings of {planner} (--set NAME=VALUE):"]
    stages = tuple(spec for stage in STAGES for spec in stage.describe())
    for s in planner_spec(planner).settings() + stages:
        bounds = f" in [{s.low:g}, {s.high:g}]" if s.low is not None else ""
        bounds += f" one of {', '.join(s.choices)}" if s.choices else ""
        lines.append(f"  {s.name} = {s.default!r}{bounds}: {s.description}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format="%(message)s")
    if args.list_settings:
        print(_settings_table(args.planner))
        return 0
    try:
        if args.scene is None:
            raise RearrangementError("give a scene: a scene .yaml file or a shipped scene name")
        if not 0 <= args.trials <= 1000 or (args.trials and not args.check_execution):
            raise RearrangementError(f"--trials must be between 0 and 1000 and goes with "
                                     f"--check-execution, got {args.trials}")
        if not 0 <= args.replan <= 20 or (args.replan and not args.check_execution):
            raise RearrangementError(f"--replan must be between 0 and 20 and goes with "
                                     f"--check-execution, got {args.replan}")
        for option, path in (("--json", args.json), ("--record", args.record),
                             ("--plot", args.plot)):
            _check_output(option, path)
        if args.live is not None and not 0 <= args.live <= 65535:
            raise RearrangementError(f"--live: a port is 0 to 65535, got {args.live}")
        scene = load_scene(args.scene)
        request = plan_request(args, scene)
        live = LiveView(args.live) if args.live is not None else None
    except RearrangementError as exc:
        print(f"rearrangement-plan: {exc}", file=sys.stderr)
        return 2
    try:
        return _plan_and_report(args, scene, request, live)
    finally:
        if live is not None:
            _hold(live)


def _hold(live: LiveView) -> None:
    """Keep the live view open until Enter when a person is at the terminal; then close it."""
    if sys.stdin.isatty():
        print(f"live view still on {live.url}; Enter closes it", file=sys.stderr)
        try:
            input()
        except (EOFError, KeyboardInterrupt):
            pass
    live.close()


def _plan_and_report(args: argparse.Namespace, scene: Scene, request: PlanRequest,
                     live: LiveView | None) -> int:
    """Plan `request`, print and write what was asked; the exit code."""
    progress = _progress_printer(args.quiet)
    if live is not None:
        print(f"live view: {live.url} (in Foxglove: Open connection; layout "
              f"config/foxglove_layout.json)", file=sys.stderr)
        live.scene(scene)
        progress = live.progress_of(scene, progress)
    started = time.monotonic()
    output = plan_scene(request, progress=progress)
    if live is not None:
        live.answer(output)
    result = output.result
    if not args.quiet:
        print(f"\r{result.outcome.value}: {result.message} "
              f"({time.monotonic() - started:.1f} s)", file=sys.stderr)
    if not args.quiet and output.judged is not None:
        judged = output.judged
        print(f"judged in 3D: {'reached' if judged.reached else judged.failure} in the "
              f"nominal world, reached in {round(judged.robustness * judged.worlds)} of "
              f"{judged.worlds} perturbed worlds (found by {judged.planner}, "
              f"{judged.mends} mends, {judged.seconds:.1f} s of judging)", file=sys.stderr)
    if output.unjudged:
        print(f"rearrangement-plan: {output.unjudged}", file=sys.stderr)
    if output.fragile:      # said even with --quiet: the plan is not to be trusted open loop
        print(f"rearrangement-plan: {output.fragile_note()}", file=sys.stderr)
    record = output.to_dict()
    executed = None
    check_failed = False
    if args.check_execution and output.trajectory is not None:
        from rearrangement_planner.world3d.mujoco_model import ExecutionCheckError

        try:
            record["execution"], executed = _check_execution(output, args)
            if live is not None and len(executed):
                live.execution(scene, output.trajectory.positions[-1], executed[-1],
                               output.trajectory_states[-1].objects,
                               "executed in MuJoCo (ideal arm): the objects where they "
                               "ended (cyan) and where the plan predicted them")
            if args.replan:
                record.update(_closed_loop(request, output, args))
        except ExecutionCheckError as exc:      # the plan stands; the check could not run
            print(f"rearrangement-plan: --check-execution: {exc}", file=sys.stderr)
            record["execution"] = {"error": str(exc)}
            check_failed = True
    text = json.dumps(record, indent=2)
    if args.json is not None:
        if str(args.json) == "-":
            print(text)
        else:
            try:
                args.json.write_text(text + "\n")
            except OSError as exc:
                print(f"rearrangement-plan: cannot write --json {args.json}: "
                      f"{exc.strerror or exc}; the result follows on standard output",
                      file=sys.stderr)
                print(text)
                return 2
    if args.plot is not None:
        _plot(output, args.plot, args.seed, executed)
    if args.record is not None:
        _record(output, request, args)
    if not args.quiet:
        summary = {k: record[k] for k in ("solved", "fragile", "plan_time_s", "iterations",
                                          "goal_distance_m")}
        print(json.dumps(summary), file=sys.stderr)
    if check_failed:
        return 2
    return 0 if result.solved else 1


def _check_output(option: str, path: Path | None) -> None:
    """Before planning: an output path must be a file we can create or overwrite, in an
    existing folder (--record creates missing folders), so a bad path costs no plan.
    RearrangementError names the option."""
    if path is None or (option == "--json" and str(path) == "-"):
        return
    shown = quote(str(path))
    try:
        if path.is_dir():
            raise RearrangementError(f"{option} {shown} is a folder; give a file path")
        if path.exists() and not os.access(path, os.W_OK):
            raise RearrangementError(f"{option} {shown}: the file is not writable")
        folder = path.absolute().parent
        if not folder.exists() and option != "--record":
            raise RearrangementError(f"{option} {shown}: the folder {quote(str(folder))} does "
                                     f"not exist")
        while not folder.exists():
            folder = folder.parent
        if not folder.is_dir():
            raise RearrangementError(f"{option} {shown}: {quote(str(folder))} is not a folder")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise RearrangementError(f"{option} {shown}: cannot write in {quote(str(folder))}")
    except OSError as exc:
        raise RearrangementError(f"{option} {shown}: {exc.strerror or exc}") from None


def _check_execution(output: PlanOutput, args: argparse.Namespace
                     ) -> tuple[dict[str, Any], np.ndarray]:
    """The execution check of the plan (JSON record) and the executed object paths: in MuJoCo
    (ideal and servo arm) and in PyBullet (servo), an engine the planner does not use; the
    plan reached (`reached`) when it reached in both with the servo arm."""
    from rearrangement_planner.execution.pybullet_check import (
        check_execution_pybullet,
        check_perturbed_pybullet,
    )
    from rearrangement_planner.world3d.execution import check_execution, check_perturbed
    from rearrangement_planner.world3d.mujoco_model import ExecutionOptions

    assert output.trajectory is not None
    record: dict[str, Any] = {}
    executed = np.zeros((0, len(output.scene.objects), 3))
    for arm in ("ideal", "servo"):
        report = check_execution(output.scene, output.trajectory, output.trajectory_states,
                                 ExecutionOptions(arm=arm))
        record[arm] = report.to_dict()
        if arm == "ideal":
            executed = report.executed_paths
        if not args.quiet:
            print(f"executed in MuJoCo ({arm} arm): goal object "
                  f"{'REACHED' if report.reached else 'MISSED'}, "
                  f"{report.goal_distance_m:.3f} m from the goal (radius "
                  f"{report.goal_radius_m:g} m); toppled: {list(report.toppled) or 'none'}",
                  file=sys.stderr)
    bullet = check_execution_pybullet(output.scene, output.trajectory,
                                      output.trajectory_states)
    record["pybullet"] = bullet.to_dict()
    record["reached"] = bool(bullet.reached and record["servo"]["reached"])
    if not args.quiet:
        print(f"executed in PyBullet (servo arm): goal object "
              f"{'REACHED' if bullet.reached else 'MISSED'}, {bullet.goal_distance_m:.3f} m "
              f"from the goal; toppled: {list(bullet.toppled) or 'none'}; reached in both "
              f"engines: {'yes' if record['reached'] else 'no'}", file=sys.stderr)
    if args.trials:
        perturbed = check_perturbed(output.scene, output.trajectory, args.trials, args.seed,
                                    ExecutionOptions(arm="servo"))
        bullets = check_perturbed_pybullet(output.scene, output.trajectory, args.trials,
                                           args.seed)
        both = sum(a.reached and b.reached
                   for a, b in zip(perturbed.reports, bullets.reports, strict=True))
        record["perturbed"] = perturbed.to_dict()
        record["perturbed_pybullet"] = bullets.to_dict()
        record["perturbed_both"] = both
        if not args.quiet:
            print(f"perturbed executions: {perturbed.reached} of {perturbed.trials} reached in "
                  f"MuJoCo, {bullets.reached} in PyBullet, {both} in both", file=sys.stderr)
    return record, executed


def _closed_loop(request: PlanRequest, output: PlanOutput, args: argparse.Namespace
                 ) -> dict[str, Any]:
    """The closed loop in MuJoCo (`execution.closed_loop`): the JSON's `executions` and
    `verdict`, and with --trials its share in the perturbed worlds."""
    from rearrangement_planner.execution.closed_loop import (
        execute_closed_loop,
        perturbed_closed_loops,
    )

    loop = execute_closed_loop(request, args.replan, first=output)
    if not args.quiet:
        for k, attempt in enumerate(loop.attempts, start=1):
            distance = attempt.to_dict()["goal_distance_m"]
            print(f"closed loop, execution {k}: {attempt.plan.result.outcome.value} in "
                  f"{attempt.plan.result.plan_time:.1f} s, "
                  + (f"goal object {distance:.3f} m from the goal, " if distance is not None
                     else "")
                  + f"{attempt.ended}{': ' + attempt.detail if attempt.detail else ''}",
                  file=sys.stderr)
    record = loop.to_dict()
    if args.trials:
        loops = perturbed_closed_loops(request, output, args.trials, args.seed, args.replan)
        record["perturbed_closed_loop"] = {
            "trials": len(loops), "reached": sum(x.reached for x in loops),
            "verdicts": [x.attempts[-1].ended for x in loops],
            "replans": [x.replans for x in loops]}
    return record


def _plot(output: PlanOutput, path: Path, seed: int,
          executed: np.ndarray | None = None) -> None:
    from rearrangement_planner.io.plot import plot_top_view  # matplotlib only when asked for

    scene, result = output.scene, output.result
    robot = scene.robot
    states = result.states or (scene.initial_state(),)
    ee = np.array([robot.tool_pose(s.q)[:2, 3] for s in states]) if result.states \
        else np.zeros((0, 2))
    plot_top_view(scene, np.array([s.objects for s in states]), ee, path,
                  title=f"{scene.source}: {output.planner}, {result.outcome.value.lower()}, "
                        f"seed {seed}",
                  start_states_only=not result.solved, executed_paths=executed)


def _record(output: PlanOutput, request: PlanRequest, args: argparse.Namespace) -> None:
    """Write the MCAP (the same recorder as the ROS node). A recording failure is reported on
    stderr and changes nothing else: the exit code still says whether the scene was solved, and
    the JSON and plot are already written."""
    from rearrangement_planner.io.plan_record import record_plan
    from rearrangement_planner.io.recording import RecordingError

    parameters = {"planner": output.planner, "seed": args.seed, "scene": str(args.scene),
                  **request.settings()}
    try:
        path = record_plan(args.record, output, plan_id=f"cli-{args.seed}",
                           parameters=parameters,
                           planning_frame="world")
    except RecordingError as exc:
        print(f"rearrangement-plan: recording failed: {exc}", file=sys.stderr)
        return
    if not args.quiet:
        print(f"recorded {path}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
