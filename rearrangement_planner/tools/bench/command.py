"""`rearrangement-bench`: benchmarks.

    rearrangement-bench [run] [--quick] [--scenes SCENE ...] [--planners P ...] [--seeds N ...]
                        [--time-limit S] [--set NAME=VALUE ...] [--robot ROBOT]
                        [--address HOST:PORT] [--workers N] [--out DIR] [--resume]
    rearrangement-bench generate [--seed S] [--out DIR]
    rearrangement-bench physics [--seconds S] [--json OUT]
    rearrangement-bench scenes [--scenes NAME ...] [--planners P ...] [--seeds N ...]
                               [--time-limit S] [--set NAME=VALUE ...] [--address HOST:PORT]
                               [--workers N] [--jsonl OUT]
    rearrangement-bench candidates [--scenes SCENE ...] [--seeds N ...] [--candidates K]
                                   [--time-limit S] [--set NAME=VALUE ...]
                                   [--address HOST:PORT] [--workers N] [--out DIR]
    rearrangement-bench states [--weights NPZ] [--out PNG]
    rearrangement-bench calibrate [--out DIR] [--rollouts N] [--perturb NAME=VALUE ...]
    rearrangement-bench report SUMMARY.json [SUMMARY.json ...]

`run` (the default) is the benchmark of King et al. 2015, §V (`benchmark.py`): each planner on each
of the 35 scenes of config/benchmark/scenes with each seed, each trial the product's default plan
request (`planning.requests.request`; `--set NAME=VALUE` changes any of its settings, e.g. `--set
min_robustness=0 --set trees=1` for the first plan of one tree; `--robot` plans with another
arm, from its home configuration). Each trial is a Ray task with
its raced trees' worth of CPUs (`engine.py`), on an embedded local Ray or on the cluster at
`--address`; trials.csv gets a row as each finishes, then summary.json, the plots of Figs. 4, 7
and 8 and the end-to-end plot (`bench_plots.py`) and OMPL benchmark logs (`ompl_log.py`) in
--out. `--resume` continues a run: trials already in trials.csv are skipped (without it an
--out that holds trials is refused). Ctrl-C stops it, keeps every finished trial and prints
the command that resumes (exit code 130). `--quick` is the reduced protocol (14 scenes, seed 0,
20 s budget; about half an hour on 2 cores). `generate` rewrites the scene set. Exit codes: 0
done, 1 some trials failed with an internal error, 2 bad input (one line naming the option),
130 interrupted.

`scenes` runs each planner on the shipped demo scenes with the default request, each run a Ray
task as in `run`, and prints one line of JSON per run in the order asked for.

`candidates` measures robust selection (`candidates.py`): per scene and seed it records the
candidate plans a robust search makes, each executed in MuJoCo, into --out/candidates.jsonl
(resumable), then replays selection rules over them within the time limit and prints how many
chosen plans reached the goal (docs/benchmark.md).

`states` draws the learned generator's manipulation states (Fig. 2a of Haustein et al. 2018)
from the default robot's shipped weights or --weights.

`calibrate` scores the plans of a finished run (trials.csv and plans/ in --out) again with
perturbed rollouts, under the shipped perturbation or one changed by --perturb, and prints how
well the score predicts the plans' perturbed MuJoCo executions (Brier score, reliability bins):
the instrument for tuning the perturbation set.

`report` prints the results table of finished runs from their summary.json files (`report.py`):
one Markdown row per run and planner. README.md and docs/benchmark.md carry it verbatim.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import shlex
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.resources import default_robot, scenes_dir
from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import parse_assignments
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.options import simulation_options
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.physics.validation import load_scene, parse_scene
from rearrangement_planner.planning.requests.parallel import RaceOptions
from rearrangement_planner.planning.requests.registry import PLANNER_NAMES as PLANNERS
from rearrangement_planner.planning.requests.request import request_settings
from rearrangement_planner.planning.requests.robustness import RobustOptions
from rearrangement_planner.tools.bench import ompl_log
from rearrangement_planner.tools.bench import trials as benchmark
from rearrangement_planner.tools.bench.engine import EngineError

COMMANDS = ("run", "generate", "physics", "scenes", "candidates", "states", "calibrate",
            "report")

PHYSICS_DOC = """`rearrangement-bench physics` measures the throughput of the quasistatic physics
step on the default scene's arm and table: the arm, folded low so that forearm and
wrist sweep at object height, rotates about joint 1 through 1 and through 7 objects placed in
its path, again and again. It prints a JSON record: physics steps per second (one
`Physics.step` call moving joint 1 by `STEP_RAD`), substeps per second, the share of the time
spent in contact and collision queries, and how many steps moved an object (so that the figure
is measured in contact, not in free space); and `compiled_steps_per_second`, the same sweeps
stepped in one compiled call each (`propagation.replay`), as the planner's propagation, its
replays and the robustness rollouts step: the kernel without a Python call per step.
"""

# Joint configuration with the forearm sloping down to 7 cm and the wrist at object height.
LOW_ARM = (-0.7677, 1.6127, 1.0578, -1.7876, 1.2966, 0.8244, -0.8218)
STEP_RAD = 0.005        # joint-1 motion per physics step: about 2.5 mm at the wrist
SWEEP_STEPS = 150       # steps per sweep, then the sweep starts again from the start state

# Objects in the sweep's path: (radius from the base, angle ahead of the arm), metres/radians.
ONE_OBJECT = [(0.43, 0.45)]
SEVEN_OBJECTS = [(0.43, 0.45), (0.56, 0.78), (0.36, 0.80), (0.50, 1.02), (0.65, 0.60),
                 (0.42, 1.18), (0.64, 1.00)]


def sweep_scene(placements: list[tuple[float, float]]) -> Scene:
    """The default scene's robot and table with cylinders at the given polar placements."""
    default = load_scene(scenes_dir() / "default.yaml")
    data = default.to_dict()
    data["start_configuration"] = list(LOW_ARM)
    data.pop("obstacles", None)
    data["objects"] = [
        {"name": f"object{i}", "shape": "cylinder", "radius": 0.03, "height": 0.12,
         "pose": [r * math.cos(a), r * math.sin(a), 0.0]}
        for i, (r, a) in enumerate(placements)]
    data["goal"] = {"object": "object0", "position": [0.5, 0.0], "radius": 0.1}
    return parse_scene(data, name=f"physics sweep, {len(placements)} objects",
                       robot=default.robot)


def measure_physics(scene: Scene, seconds: float) -> dict:
    physics = Physics(scene, simulation_options())
    start_state = scene.initial_state()
    steps = substeps = pushing_steps = invalid = 0
    links: set[str] = set()
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        state = start_state
        for _ in range(SWEEP_STEPS):
            q = state.q.copy()
            q[0] += STEP_RAD
            result = physics.step(state, q)
            steps += 1
            substeps += result.substeps
            if not result.valid:
                invalid += 1
                break
            if result.moved_objects:
                pushing_steps += 1
                links |= result.pushing_links
            state = result.state
    elapsed = time.perf_counter() - t0
    return {
        "objects": len(scene.objects),
        "steps": steps,
        "steps_per_second": round(steps / elapsed, 1),
        "compiled_steps_per_second": round(compiled_rate(physics, start_state, seconds), 1),
        "substeps_per_second": round(substeps / elapsed, 1),
        "steps_pushing_share": round(pushing_steps / steps, 3),
        "invalid_steps": invalid,
        "pushing_links": sorted(links),
    }


def compiled_rate(physics: Physics, start: State, seconds: float) -> float:
    """Steps per second of the benchmark's sweep stepped in one compiled call per sweep
    (`propagation.replay`, up to the first invalid step, as `measure_physics` stops)."""
    from rearrangement_planner.planning.machinery.propagation import replay

    sweep = np.array([start.q + np.eye(len(start.q))[0] * STEP_RAD * k
                      for k in range(SWEEP_STEPS + 1)])
    steps = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        states, _ = replay(physics, start, sweep)
        steps += max(len(states) - 1, 1)
    return steps / (time.perf_counter() - t0)


def physics_benchmark(seconds: float) -> dict:
    from rearrangement_planner.planning.requests.warmup import warm_up

    compile_s = warm_up()          # compile (or load) the core first: not part of the rate
    return {
        "benchmark": "physics",
        "step": f"Physics.step moving joint 1 by {STEP_RAD} rad (arm folded low, sweeping)",
        "python": platform.python_version(),
        "machine": platform.machine(),
        "warm_up_s": round(compile_s, 2),
        "results": [measure_physics(sweep_scene(ONE_OBJECT), seconds),
                    measure_physics(sweep_scene(SEVEN_OBJECTS), seconds)],
    }


def scene_trial(scene_name: str, planner: str, seed: int, time_limit: float,
                settings: dict[str, Any] | None = None) -> dict:
    """One plan request on one shipped scene (the product's default, with `settings`):
    outcome, plan time and which objects moved."""
    from rearrangement_planner.planning.requests.pipeline import plan_scene
    from rearrangement_planner.planning.requests.request import PlanRequest

    scene = load_scene(scene_name)
    request = PlanRequest.from_settings(scene, planner,
                                        {**(settings or {}), "time_limit": time_limit}, seed)
    result = plan_scene(request).result
    trees = request.trees
    moved: list[str] = []
    if result.states:
        first = result.states[0].objects
        moved = [o.name for i, o in enumerate(scene.objects)
                 if any(not (s.objects[i] == first[i]).all() for s in result.states)]
    return {"scene": scene_name, "planner": planner, "seed": seed, "trees": trees,
            "outcome": result.outcome.value, "plan_time_s": round(result.plan_time, 2),
            "iterations": result.iterations, "moved": moved,
            "best_goal_distance_m": round(result.best_goal_distance, 3)}


QUICK: dict[str, Any] = {"seeds": [0], "time_limit": 20.0}
"""--quick: 2 scenes per object count (14), seed 0, 20 s budget: 14 trials per planner, each
the product's default request (at most about 35 s each: the budget, shortcutting, rollouts)."""
DEFAULTS: dict[str, Any] = {"seeds": [0, 1, 2], "time_limit": 60.0}
"""The full protocol: the 35 scenes, every planner, seeds 0-2, 60 s budget (105 trials per
planner), each the product's default request (shortcutting, robust selection and raced trees
as the CLI and the node plan)."""


class _Parser(argparse.ArgumentParser):
    """Usage errors as one line naming the option, exit code 2."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="rearrangement-bench",
        description="Benchmarks of the rearrangement planner. Without a command: `run`.",
        formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_run_parser(sub)
    gen = sub.add_parser(
        "generate", help="(re)write the 35 scene files of a benchmark scene set",
        description="Draw a 35-scene set (5 scenes with each of 1..7 movable objects) from "
                    "the seed and write it as scene files.")
    _add_scene_set_option(gen, "the set to write")
    gen.add_argument("--seed", type=int, default=benchmark.SCENE_SET_SEED, metavar="S",
                     help=f"scene set seed (default {benchmark.SCENE_SET_SEED}: the committed "
                          f"set)")
    gen.add_argument("--out", type=Path, metavar="DIR",
                     help="folder for the scene files (default the set's own: "
                          "config/benchmark/scenes or config/benchmark/varied)")
    phys = sub.add_parser(
        "physics", help="physics steps per second with 1 and 7 objects in contact range",
        description=PHYSICS_DOC, formatter_class=argparse.RawDescriptionHelpFormatter)
    phys.add_argument("--seconds", type=float, default=5.0,
                      help="measuring time per scene, s (default 5)")
    phys.add_argument("--json", type=Path, help="also write the JSON record to this file")
    scenes = sub.add_parser(
        "scenes", help="each planner on each shipped scene with several seeds (one line of "
                       "JSON per run: outcome, plan time, objects moved)")
    scenes.add_argument("--scenes", nargs="+", default=["easy_push", "default", "clutter",
                                                        "seven_objects"],
                        help="shipped scene names or scene files")
    scenes.add_argument("--planners", nargs="+", default=list(PLANNERS), choices=PLANNERS)
    scenes.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    scenes.add_argument("--time-limit", type=float, default=60.0, metavar="S",
                        help="planning budget per run, s (default 60)")
    _add_set_option(scenes)
    _add_engine_options(scenes, "runs")
    scenes.add_argument("--jsonl", type=Path, help="also append the lines to this file")
    _add_candidates_parser(sub)
    cal = sub.add_parser(
        "calibrate", help="score a run's plans again under a perturbation set and say how "
                          "well the score predicts their perturbed MuJoCo executions",
        description="Read trials.csv and the plans of a finished `run` in --out, score every "
                    "solved plan again with perturbed rollouts (the shipped perturbation, or "
                    "the one the options describe) and print its calibration as JSON: the "
                    "Brier score and the reliability diagram's bins (docs/benchmark.md).")
    cal.add_argument("--out", type=Path, default=Path("out/benchmark"), metavar="DIR",
                     help="the run's folder (default out/benchmark)")
    cal.add_argument("--rollouts", type=int, default=RobustOptions().rollouts, metavar="N",
                     help=f"rollouts per plan (default {RobustOptions().rollouts})")
    cal.add_argument("--perturb", action="append", default=[], metavar="NAME=VALUE",
                     help="change a field of the perturbation (model/perturbation.py "
                          "Perturbation: friction, mass, pose_noise, yaw_noise, "
                          "contact_offset, centre_offset; pressure=LOW,HIGH); repeatable")
    rep = sub.add_parser(
        "report", help="the results table of finished runs, from their summary.json files",
        description="Print a Markdown table, one row per run and planner in the order given: "
                    "scenes and seeds, solved, reached when executed (both engines, MuJoCo, "
                    "PyBullet), plans toppling, perturbed executions reached, calibration, "
                    "request median / p90 and the closed loop's time to goal; '–' where a "
                    "summary does not hold the figure.")
    rep.add_argument("summaries", nargs="+", type=Path, metavar="SUMMARY.json",
                     help="summary.json files written by `rearrangement-bench run`")
    states = sub.add_parser(
        "states", help="Fig. 2a of Haustein et al. 2018: the learned generator's manipulation "
                       "states around an object")
    states.add_argument("--weights", type=Path, default=None,
                        help="a learned oracle .npz (default: the default robot's shipped one)")
    states.add_argument("--out", type=Path, default=Path("manipulation_states.png"),
                        help="the PNG to write (default manipulation_states.png)")
    return parser


def _add_run_parser(sub) -> None:
    run = sub.add_parser(
        "run", help="the benchmark of King et al. 2015, §V: planners x scenes x seeds (the default "
                    "command)",
        description="Run each planner on each benchmark scene with each seed under a time "
                    "budget, each trial a Ray task; write trials.csv (one row per trial, "
                    "appended as it finishes), summary.json, PNG plots and OMPL benchmark logs "
                    "into --out. With --resume, trials already in trials.csv are skipped, so "
                    "an interrupted run resumes.")
    run.add_argument("--quick", action="store_true",
                     help="reduced protocol: 2 scenes per object count (14 scenes), seed 0, "
                          "20 s budget (14 trials per planner); options given "
                          "explicitly override it")
    run.add_argument("--scenes", nargs="+", metavar="SCENE",
                     help="benchmark scene names (n3_s2 = 3 objects, third scene of the fixed "
                          "set; v3_s2 of the varied set) or scene .yaml files (default: the 35 "
                          "scenes of --scene-set)")
    _add_scene_set_option(run, "the scenes to run (unless --scenes names them)")
    run.add_argument("--planners", nargs="+", default=list(PLANNERS), metavar="PLANNER",
                     help=f"any of {', '.join(PLANNERS)} (default: all), each optionally with "
                          "settings of its own: PLANNER:NAME=VALUE[,NAME=VALUE] "
                          "(slice-rrt:oracle=hand)")
    run.add_argument("--seeds", nargs="+", type=int, metavar="N",
                     help="planner seeds (default 0 1 2; --quick: 0)")
    run.add_argument("--robot", default="", metavar="ROBOT",
                     help="plan every scene with this arm (a shipped robot name or a robot "
                          "config .yaml), starting at its home configuration (default: each "
                          "scene's own arm and start)")
    run.add_argument("--time-limit", type=float, metavar="S",
                     help="planning budget per trial, s (default 60; --quick: 20)")
    run.add_argument("--perturbed", type=int, default=benchmark.PERTURBED_EXECUTIONS,
                     metavar="N",
                     help=f"executions of each solved plan in perturbed MuJoCo worlds (servo "
                          f"arm; default {benchmark.PERTURBED_EXECUTIONS}; 0: none)")
    run.add_argument("--replan", type=int, default=0, metavar="N",
                     help="also close the loop in MuJoCo (servo arm), nominal and perturbed: "
                          "after an execution that misses with nothing toppled, retreat, "
                          "observe and plan again, up to N times; the summary reports reached "
                          "within N re-plans and the time to goal (default 0: open loop only)")
    run.add_argument("--divergence-bound", type=float, default=0.0, metavar="M",
                     help="with --replan: watch each execution of the closed loop, stopping "
                          "the arm once an object strays M metres from its predicted pose "
                          "(default 0: not watched)")
    _add_set_option(run)
    _add_engine_options(run, "trials")
    run.add_argument("--out", type=Path, default=Path("out/benchmark"), metavar="DIR",
                     help="output folder (default out/benchmark)")
    run.add_argument("--resume", action="store_true",
                     help="continue the run whose trials.csv is in --out: trials already "
                          "there are skipped (without it, an --out holding trials is refused)")


def _add_engine_options(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--address", metavar="HOST:PORT",
                        help=f"run the {what} on the Ray cluster at this address (as `ray start "
                             f"--head` prints it; every node needs this package installed); "
                             f"default: an embedded local Ray on this machine's cores")
    parser.add_argument("--workers", type=int, metavar="N",
                        help=f"{what} at once, each a Ray task with its request's raced trees' "
                             f"worth of CPUs (default: this machine's "
                             f"{benchmark.usable_cores()} cores over the trees; with "
                             f"--address: as many as the cluster's CPUs take)")


def _add_scene_set_option(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--scene-set", choices=list(benchmark.SCENE_SETS), default="fixed",
                        help=f"{what}: 'fixed', the 35 scenes of King et al. 2015, §V, with one "
                             f"goal object and goal region (config/benchmark/scenes), or "
                             f"'varied', whose goal object, goal point and blockers vary "
                             f"(config/benchmark/varied); default fixed")


def _add_set_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="change a setting of every trial's plan request from the product "
                             "default (repeatable; `rearrangement-plan --list-settings` shows "
                             "them), e.g. --set min_robustness=0 --set trees=1")


def _add_candidates_parser(sub) -> None:
    cands = sub.add_parser(
        "candidates", help="robust selection measured: candidate plans recorded and executed "
                           "in MuJoCo, selection rules replayed over them",
        description="For each scene and seed, record up to --candidates candidate plans as "
                    "a robust search makes them (PC-RRT, one tree each, shortcut, scored by "
                    "perturbed rollouts, with the default request's settings and --set), each "
                    "executed open loop in MuJoCo, into --out/candidates.jsonl (requests "
                    "already there are skipped); then print per selection rule how many chosen "
                    "plans reach the goal.")
    cands.add_argument("--scenes", nargs="+", metavar="SCENE",
                       help="benchmark scene names or scene .yaml files (default: the 35)")
    cands.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2], metavar="N",
                       help="request seeds (default 0 1 2)")
    cands.add_argument("--candidates", type=int, default=6, metavar="K",
                       help="candidates recorded per request (default 6)")
    cands.add_argument("--time-limit", type=float, default=60.0, metavar="S",
                       help="a request's budget, s (default 60)")
    _add_set_option(cands)
    _add_engine_options(cands, "requests")
    cands.add_argument("--out", type=Path, default=Path("out/candidates"), metavar="DIR",
                       help="output folder (default out/candidates)")


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] not in COMMANDS + ("-h", "--help"):
        argv = ["run", *argv]
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.command == "run":
            return run_command(args, argv)
        if args.command == "generate":
            scene_set = benchmark.SCENE_SETS[args.scene_set]
            out = args.out or scene_set.directory()
            paths = benchmark.write_scene_set(out, args.seed, scene_set)
            print(f"wrote {len(paths)} scenes to {out}")
            return 0
        if args.command == "scenes":
            return scenes_command(args)
        if args.command == "candidates":
            return candidates_command(args)
        if args.command == "states":
            return states_command(args)
        if args.command == "calibrate":
            return calibrate_command(args)
        if args.command == "report":
            from rearrangement_planner.tools.bench.report import report_command

            return report_command(args.summaries)
        return physics_command(args)
    except benchmark.BenchmarkError as exc:
        print(f"rearrangement-bench: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\nrearrangement-bench: interrupted", file=sys.stderr)
        return 130


def states_command(args: argparse.Namespace) -> int:
    from rearrangement_planner.planning.planners.learned_oracle import load_models, model_path
    from rearrangement_planner.tools.bench.plots import plot_manipulation_states

    weights = args.weights or model_path(default_robot())
    try:
        models = load_models(weights)
    except (OSError, ValueError) as exc:
        raise benchmark.BenchmarkError("--weights", str(exc)) from None
    print(f"wrote {plot_manipulation_states(models, args.out)}")
    return 0


def physics_command(args: argparse.Namespace) -> int:
    if not args.seconds > 0:
        raise benchmark.BenchmarkError("--seconds", f"must be positive, got {args.seconds}")
    record = physics_benchmark(args.seconds)
    text = json.dumps(record, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")
    return 0


def calibrate_command(args: argparse.Namespace) -> int:
    import dataclasses

    from rearrangement_planner.model.perturbation import Perturbation

    if not 1 <= args.rollouts <= 1000:
        raise benchmark.BenchmarkError("--rollouts", f"must be between 1 and 1000, got "
                                                     f"{args.rollouts}")
    if not (args.out / "trials.csv").is_file():
        raise benchmark.BenchmarkError("--out", f"{args.out} holds no trials.csv of a run")
    fields = {f.name for f in dataclasses.fields(Perturbation)}
    values: dict[str, Any] = {}
    for item in args.perturb:
        name, _, text = item.partition("=")
        if name not in fields:
            raise benchmark.BenchmarkError("--perturb", f"{item!r}: no field {name!r}; fields "
                                                        f"are {', '.join(sorted(fields))}")
        try:
            values[name] = tuple(float(v) for v in text.split(",")) if name == "pressure" \
                else float(text)
        except ValueError:
            raise benchmark.BenchmarkError("--perturb", f"{item!r}: not a number") from None
    try:
        perturbation = Perturbation(**values)
    except (TypeError, ValueError) as exc:
        raise benchmark.BenchmarkError("--perturb", str(exc)) from None
    rows = benchmark.rescore(args.out, args.rollouts, perturbation)
    result = {"perturbation": dataclasses.asdict(perturbation), "rollouts": args.rollouts,
              **benchmark.calibration(rows)}
    print(json.dumps(result, indent=2))
    return 0


def scenes_command(args: argparse.Namespace) -> int:
    if not args.time_limit > 0:
        raise benchmark.BenchmarkError("--time-limit", f"must be positive, got "
                                                       f"{args.time_limit}")
    from rearrangement_planner.tools.bench.engine import Engine, EngineError, Job

    settings = request_overrides(args.set, args.planners)
    trees = RaceOptions(**{k: v for k, v in settings.items() if k == "trees"}).trees
    jobs = [Job((scene_name, planner, seed), (scene_name, planner, seed, args.time_limit,
                                              settings), trees,
                f"{scene_name} {planner} seed {seed}")
            for scene_name in args.scenes for planner in args.planners for seed in args.seeds]
    try:
        engine = Engine(args.address)
    except EngineError as exc:
        raise benchmark.BenchmarkError("--address", str(exc)) from None
    done = {job.key: job for job in jobs}
    results: dict = {}
    failed = 0
    for finished in engine.run(scene_trial, jobs, _workers(args, trees)):
        if finished.error:
            failed += 1
            print(f"{finished.job.label} failed:\n{finished.error}", file=sys.stderr)
            continue
        results[finished.job.key] = finished.result
    for key in done:                 # in the order asked for, whichever finished first
        if key in results:
            line = json.dumps(results[key])
            print(line, flush=True)
            if args.jsonl:
                with args.jsonl.open("a") as f:
                    f.write(line + "\n")
    return 1 if failed else 0


def candidates_command(args: argparse.Namespace) -> int:
    from rearrangement_planner.tools.bench import candidates

    for option, ok, problem in (
            ("--time-limit", 0 < args.time_limit < math.inf, "a positive number of seconds"),
            ("--candidates", 1 <= args.candidates <= 20, "between 1 and 20"),
            ("--seeds", all(seed >= 0 for seed in args.seeds), "seeds >= 0")):
        if not ok:
            value = getattr(args, option[2:].replace("-", "_"))
            raise benchmark.BenchmarkError(option, f"must be {problem}, got {value}")
    workers = _workers(args, trees=1)
    settings = request_overrides(args.set, ["pc-rrt"])
    scenes = _resolve_scenes(args.scenes or benchmark.set_scene_names())
    out = args.out / "candidates.jsonl"
    requests = [(path, seed) for seed in dict.fromkeys(args.seeds) for path, _ in scenes]
    print(f"candidates: {_count(len(requests), 'request')}, up to {args.candidates} candidates "
          f"each, {args.time_limit:g} s, {_engine_text(args.address, workers)} -> {out}",
          file=sys.stderr, flush=True)
    failed = candidates.record_all(requests, out, workers, args.candidates, args.time_limit,
                                   settings, args.address)
    wanted = {(path.stem, seed) for path, seed in requests}
    records = [r for r in candidates.read_records(out) if (r["scene"], r["seed"]) in wanted]
    robust = RobustOptions(**{k: v for k, v in settings.items()
                              if k in RobustOptions.__dataclass_fields__})
    # Records made before the tool recorded iterations cannot replay the candidate bound.
    effort = robust.candidate_effort if all("iterations" in r for r in records) else 0.0
    print(candidates.replay_table(records, candidates.rules(args.candidates,
                                                            robust.travel_penalty, effort),
                                  args.time_limit))
    if failed:
        print(f"rearrangement-bench: {failed} requests failed with an internal error (not in "
              f"{out}; run again to retry them)", file=sys.stderr)
        return 1
    return 0


def request_overrides(items: list[str], planners: list[str]) -> dict[str, Any]:
    """The settings of --set NAME=VALUE items, checked by building each planner's request with
    them on a small scene; BenchmarkError names the item at fault."""
    from rearrangement_planner.planning.requests.request import PlanRequest

    try:
        settings: dict[str, Any] = dict(parse_assignments(request_settings(), items))
    except ValueError as exc:
        raise benchmark.BenchmarkError("--set", str(exc)) from None
    scene = load_scene("easy_push")
    for label in planners:
        name, _ = benchmark.planner_variant(label)
        if name not in PLANNERS:
            raise benchmark.BenchmarkError(
                "--planners", f"{label!r}: no planner {name!r}; use one of {', '.join(PLANNERS)}")
        try:
            name, values = benchmark.variant_settings(label, settings)
        except ValueError as exc:
            raise benchmark.BenchmarkError("--planners", f"{label}: {exc}") from None
        try:
            PlanRequest.from_settings(scene, name, values)
        except ValueError as exc:
            option = "--planners" if values != settings else "--set"
            raise benchmark.BenchmarkError(option, f"{' '.join(items) or label}: {exc}") \
                from None
    return settings


def _resolve_scenes(names: list[str]) -> list[tuple[Path, Scene]]:
    """The scene files of --scenes (names in config/benchmark/scenes, or .yaml paths), loaded
    and validated."""
    out: list[tuple[Path, Scene]] = []
    seen: dict[str, Path] = {}
    for name in names:
        path = Path(name)
        if path.suffix not in (".yaml", ".yml"):
            scene_set = benchmark.scene_set_of(name)
            path = (scene_set or benchmark.FIXED).directory() / f"{name}.yaml"
            if not path.is_file():
                raise benchmark.BenchmarkError(
                    "--scenes", f"no benchmark scene {name!r}; names are n<objects>_s<index> "
                                f"(the fixed set, n1_s0 ... n7_s4), v<objects>_s<index> (the "
                                f"varied set) or give a scene .yaml file")
        if path.stem in seen and seen[path.stem] != path:
            raise benchmark.BenchmarkError(
                "--scenes", f"two scenes are called {path.stem!r} ({seen[path.stem]} and "
                            f"{path}); trials are keyed by the scene's file name")
        if path.stem in seen:
            continue
        seen[path.stem] = path
        try:
            out.append((path, load_scene(path)))
        except RearrangementError as exc:
            raise benchmark.BenchmarkError("--scenes", str(exc)) from None
    return out


def _workers(args: argparse.Namespace, trees: int) -> int | None:
    """Tasks at once: --workers (checked), else this machine's cores over `trees` for the
    embedded Ray, else None (the cluster's CPUs decide)."""
    cores = benchmark.usable_cores()
    if args.workers is None:
        return max(1, cores // trees) if args.address is None else None
    if args.address is None and not 1 <= args.workers <= cores:
        raise benchmark.BenchmarkError("--workers", f"must be between 1 and the {cores} "
                                                    f"cores of this machine, got {args.workers}")
    if args.workers < 1:
        raise benchmark.BenchmarkError("--workers", f"must be at least 1, got {args.workers}")
    return args.workers


def _engine_text(address: str | None, workers: int | None) -> str:
    where = "embedded Ray" if address is None else f"Ray at {address}"
    return f"{where}, {f'{workers} at a time' if workers else 'as its CPUs take'}"


def _check_run_options(args: argparse.Namespace) -> None:
    if not args.time_limit > 0 or not math.isfinite(args.time_limit):
        raise benchmark.BenchmarkError("--time-limit", f"must be a positive number of seconds, "
                                                       f"got {args.time_limit}")
    if not 0 <= args.perturbed <= 100:
        raise benchmark.BenchmarkError("--perturbed", f"must be between 0 and 100 executions, "
                                                      f"got {args.perturbed}")
    if not 0 <= args.divergence_bound <= 10 or (args.divergence_bound and not args.replan):
        raise benchmark.BenchmarkError("--divergence-bound", f"must be in [0, 10] m and goes "
                                                             f"with --replan, got "
                                                             f"{args.divergence_bound}")
    if not 0 <= args.replan <= 20:
        raise benchmark.BenchmarkError("--replan", f"must be between 0 and 20 re-plans, "
                                                   f"got {args.replan}")
    if any(seed < 0 for seed in args.seeds):
        raise benchmark.BenchmarkError("--seeds", f"seeds must be >= 0, got {args.seeds}")
    if args.out.exists() and not args.out.is_dir():
        raise benchmark.BenchmarkError("--out", f"{args.out} exists and is not a folder")


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def resolve_run(args: argparse.Namespace) -> tuple[list[tuple[Path, Scene]],
                                                    list[benchmark.Trial]]:
    """The scenes and trials of a `run`: --quick's protocol or the full one, with the options
    given explicitly on top. Raises `BenchmarkError` naming a bad option."""
    base = QUICK if args.quick else DEFAULTS
    args.seeds = list(dict.fromkeys(args.seeds if args.seeds is not None else base["seeds"]))
    if args.time_limit is None:
        args.time_limit = base["time_limit"]
    args.planners = list(dict.fromkeys(args.planners))
    args.settings = request_overrides(args.set, args.planners)
    trees = RaceOptions(**{k: v for k, v in args.settings.items() if k == "trees"}).trees
    args.workers = _workers(args, trees)
    _check_run_options(args)
    scenes = _resolve_scenes(args.scenes or benchmark.set_scene_names(
        quick=args.quick, scene_set=benchmark.SCENE_SETS[args.scene_set]))
    if args.robot:
        try:
            scenes = [(path, benchmark.load_trial_scene(path, args.robot))
                      for path, _ in scenes]
        except RearrangementError as exc:
            raise benchmark.BenchmarkError("--robot", str(exc)) from None
    objects = {path.stem: len(scene.objects) for path, scene in scenes}
    trials = benchmark.make_trials([p for p, _ in scenes], args.planners, args.seeds,
                                   args.time_limit, objects, args.robot, args.perturbed,
                                   args.replan, args.divergence_bound)
    return scenes, trials


def run_command(args: argparse.Namespace, argv: list[str]) -> int:
    scenes, trials = resolve_run(args)
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise benchmark.BenchmarkError("--out", f"cannot create {args.out} ({exc.strerror})") \
            from None
    csv_path = args.out / "trials.csv"
    earlier = benchmark.read_trials(csv_path)
    if earlier and not args.resume:
        raise benchmark.BenchmarkError(
            "--out", f"{csv_path} already holds {_count(len(earlier), 'trial')} of an earlier "
                     f"run; add --resume to continue it (its finished trials are skipped) or "
                     f"choose another --out")
    arms = {r["robot"] for r in earlier if r["robot"]}
    robot = scenes[0][1].robot.name
    if arms - {robot}:
        raise benchmark.BenchmarkError(
            "--out", f"{csv_path} holds trials planned with {', '.join(sorted(arms))}, not "
                     f"{robot}; give each arm its own --out")
    print(f"benchmark: {_count(len(scenes), 'scene')} x {_count(len(args.planners), 'planner')}"
          f" x {_count(len(args.seeds), 'seed')} = {_count(len(trials), 'trial')}, "
          f"{args.time_limit:g} s budget, {_engine_text(args.address, args.workers)} -> "
          f"{csv_path}", file=sys.stderr, flush=True)
    try:
        report = benchmark.run_trials(trials, csv_path, args.workers, args.settings,
                                      address=args.address)
    except EngineError as exc:
        raise benchmark.BenchmarkError("--address", str(exc)) from None
    if report.interrupted:
        resume = argv if "--resume" in argv else [*argv, "--resume"]
        print(f"interrupted: {csv_path} holds every finished trial ({report.finished} new). "
              f"Resume with: rearrangement-bench {shlex.join(resume)}", file=sys.stderr)
        return 130
    wanted = {t.key for t in trials}
    rows = [r for r in benchmark.read_trials(csv_path) if benchmark.row_key(r) in wanted]
    sets = {getattr(benchmark.scene_set_of(p.stem), "name", "file") for p, _ in scenes}
    protocol = {"scenes": [p.stem for p, _ in scenes], "scene_sets": sorted(sets),
                "planners": args.planners, "seeds": args.seeds, "time_limit": args.time_limit,
                "request_settings": args.settings, "quick": args.quick, "robot": robot}
    summary = benchmark.summarize(rows, protocol,
                                  benchmark.end_effector_links(scenes[0][1].robot))
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    from rearrangement_planner.tools.bench.plots import plot_all  # matplotlib only here

    plots = plot_all(rows, summary, args.out)
    logs = ompl_log.write_logs(rows, protocol, args.out / "ompl")
    print(benchmark.summary_table(summary))
    closed = benchmark.closed_loop_table(summary)
    if closed:
        print("\nclosed loop (servo arm in MuJoCo):\n" + closed)
    print(f"wrote {csv_path}, {args.out / 'summary.json'}, "
          + ", ".join(str(p) for p in plots)
          + f", OMPL benchmark logs {', '.join(p.name for p in logs)} in {args.out / 'ompl'}",
          file=sys.stderr)
    if report.failed:
        print(f"rearrangement-bench: {report.failed} trials failed with an internal error "
              f"(not in the CSV; run again to retry them)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
