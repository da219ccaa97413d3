"""`rearrangement-bench candidates`: how well robust selection chooses among candidate plans
(docs/benchmark.md).

Robust selection (`pipeline.robust_search`, `planning.requests.robustness`) plans candidates one
after
the other and answers with the best ranked. Whether a ranking picks plans that work when
executed is measured here without re-planning for every rule:

- `record_request` makes, for one scene and seed, the candidates a robust search makes (with the
  pipeline's own `Candidates`: the same seeds, `pipeline.candidate_seed`; each the plan its seed
  gives alone, shortcut, scored with the same rollouts) and executes every one open loop in MuJoCo
  (`check_execution`, ideal arm). One record per candidate search: its search, shortcut and rollout
  seconds, its robustness, how far it pushes and turns the goal object, and the executed outcome.
- `choose` replays a selection `Rule` over a request's records within a time budget: a
  candidate counts if its search fits in what the budget has left when it starts (a search is
  determined by its seed: one that finished in t s finishes the same under any limit above t)
  and, with the rule's `effort`, within the iteration bound the first plan sets
  (`robustness.candidate_iterations`), up to the rule's number of candidates, stopping at one
  robust in every rollout, as `pipeline.robust_search` does.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np


def record_request(scene_path: Path, seed: int, candidates: int, time_limit: float,
                   settings: dict | None = None) -> list[dict]:
    """The candidates of a robust PC-RRT search of `scene_path` with `seed` (the default
    request with `settings`, one tree each), executed in MuJoCo: one record per candidate
    search, until `candidates` searches or `time_limit` s of searching, shortcutting and
    rollouts are spent."""
    from rearrangement_planner.physics.step import Physics
    from rearrangement_planner.physics.validation import load_scene
    from rearrangement_planner.planning.requests.pipeline import Candidates, candidate_seed
    from rearrangement_planner.planning.requests.request import PlanRequest
    from rearrangement_planner.planning.requests.robustness import goal_travel
    from rearrangement_planner.planning.requests.trajectory import time_parameterize
    from rearrangement_planner.planning.requests.warmup import warm_up
    from rearrangement_planner.world3d.execution import check_execution

    warm_up()               # compiling the core is not a search's time (as in `plan_scene`)
    scene = load_scene(scene_path)
    request = PlanRequest.from_settings(
        scene, "pc-rrt", {**(settings or {}), "time_limit": time_limit, "trees": 1}, seed)
    physics = Physics(scene, request.physics)
    g = scene.goal_index
    records: list[dict] = []
    spent = 0.0
    for k in range(candidates):
        if spent >= time_limit:
            break
        k_seed = candidate_seed(seed, k)
        search = Candidates(request, physics, request.options.termination())   # its own budget
        found = search.plan(k_seed)
        record: dict = {"scene": Path(scene_path).stem, "seed": seed, "k": k,
                        "solved": found.solved, "search_s": round(found.plan_time, 3),
                        "iterations": found.iterations}
        spent += found.plan_time
        if found.solved:
            candidate = search.shortcut(found, k_seed)
            states = candidate.result.states
            t0 = time.monotonic()
            score = search.score(candidate, k_seed)
            rollout_time = time.monotonic() - t0
            yaw = np.unwrap([s.objects[g, 2] for s in states])
            trajectory = time_parameterize(scene.robot, candidate.result.arm_path,
                                           request.timing)
            report = check_execution(scene, trajectory, None)
            record.update(
                shortcut_s=round(candidate.shortcut_time, 3), rollouts_s=round(rollout_time, 3),
                robustness=score, goal_travel_m=round(goal_travel(scene, states), 4),
                goal_turn_rad=round(float(np.abs(np.diff(yaw)).sum()), 4),
                reached=report.reached, goal_distance_m=round(report.goal_distance_m, 4),
                toppled=len(report.toppled))
            spent += candidate.shortcut_time + rollout_time
        records.append(record)
    return records


@dataclass(frozen=True)
class Rule:
    """A way to choose among candidates: the first plan, the best ranked of `candidates`
    (`robustness.candidate_rank` with `travel_penalty`), or the best by the executed outcome
    itself (`oracle`, a bound no ranking can beat)."""

    name: str
    candidates: int
    travel_penalty: float | None = 0.0
    """None: the first plan found (no rollouts, no early stop)."""
    oracle: bool = False
    effort: float = 0.0
    """The candidates after the first search at most this many times its iterations
    (`RobustOptions.candidate_effort`; 0: no bound but the budget)."""


def choose(records: Sequence[dict], rule: Rule, budget: float) -> dict | None:
    """The candidate `rule` answers with among one request's `records` within `budget` s, or
    None (no candidate solved in time)."""
    from rearrangement_planner.planning.requests.robustness import (
        RobustOptions,
        candidate_iterations,
        candidate_rank,
    )

    spent = 0.0
    solved: list[dict] = []
    bound: int | None = None
    for record in sorted(records, key=lambda r: r["k"]):
        left = budget - spent
        cut = bound is not None and record["iterations"] > bound
        search = record["search_s"] * bound / record["iterations"] if cut else \
            record["search_s"]                  # a search cut at its bound: that share of it
        if record["k"] >= rule.candidates or left <= 0.001 or search > left:
            break
        spent += search
        if cut or not record["solved"]:
            continue
        if not solved and rule.effort > 0:
            bound = candidate_iterations(RobustOptions(candidate_effort=rule.effort),
                                         record["iterations"])
        solved.append(record)
        if rule.travel_penalty is None:
            break
        spent += record["shortcut_s"] + record["rollouts_s"]
        if not rule.oracle and record["robustness"] >= 1.0:
            break
    if not solved:
        return None
    penalty = rule.travel_penalty
    if penalty is None:
        return solved[0]
    if rule.oracle:
        return max(solved, key=lambda r: (r["reached"], -r["toppled"], -r["goal_distance_m"]))
    return max(solved, key=lambda r: (candidate_rank(r["robustness"], r["goal_travel_m"],
                                                     penalty), -r["k"]))


def rules(candidates: int, travel_penalty: float, effort: float = 0.0) -> list[Rule]:
    """The first plan, then for 3 and `candidates` candidates: the most robust, the shipped
    ranking with `travel_penalty` (without, and with `effort`, the bound on the later
    searches), and the oracle."""
    out = [Rule("first plan", 1, None)]
    for n in sorted({min(3, candidates), candidates}):
        ranked = f"robustness - {travel_penalty:g} x push path, of {n}"
        out += [Rule(f"most robust of {n}", n, 0.0), Rule(ranked, n, travel_penalty)]
        if effort > 0:
            out.append(Rule(f"{ranked}, later searches <= {effort:g} x the first's iterations",
                            n, travel_penalty, effort=effort))
        out.append(Rule(f"best of {n} by MuJoCo (oracle)", n, oracle=True))
    return out


def replay_table(records: Iterable[dict], rule_list: Sequence[Rule], budget: float) -> str:
    """A Markdown table: per rule, requests solved, and the chosen plans that reached the goal
    in MuJoCo and that toppled an object."""
    requests: dict[tuple[str, int], list[dict]] = {}
    for record in records:
        requests.setdefault((record["scene"], record["seed"]), []).append(record)
    lines = [f"| rule ({len(requests)} requests, {budget:g} s) | solved | reached in MuJoCo "
             f"| toppled |", "|---|---|---|---|"]
    for rule in rule_list:
        chosen = [c for c in (choose(r, rule, budget) for r in requests.values()) if c]
        reached = sum(bool(c["reached"]) for c in chosen)
        share = f" ({100 * reached / len(chosen):.0f} %)" if chosen else ""
        lines.append(f"| {rule.name} | {len(chosen)}/{len(requests)} | {reached}/{len(chosen)}"
                     f"{share} | {sum(c['toppled'] > 0 for c in chosen)} |")
    return "\n".join(lines)


def read_records(path: Path) -> list[dict]:
    """The records of a candidates.jsonl (empty if it does not exist yet)."""
    if not path.is_file():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def record_all(requests: Sequence[tuple[Path, int]], out: Path, workers: int | None,
               candidates: int, time_limit: float, settings: dict | None = None,
               address: str | None = None) -> int:
    """Record the (scene file, seed) `requests` not yet in `out` (candidates.jsonl), appending
    each request's records as it finishes; each request a Ray task (`engine`: the embedded Ray
    or the cluster at `address`), at most `workers` at once; progress on stderr. Returns how
    many requests failed with an internal error (their tracebacks on stderr)."""
    from rearrangement_planner.tools.bench.engine import Engine, Job, Progress

    done = {(r["scene"], r["seed"]) for r in read_records(out)}
    jobs = [Job((path.stem, seed), (path, seed, candidates, time_limit, settings), 1,
                f"{path.stem} seed {seed}")
            for path, seed in requests if (path.stem, seed) not in done]
    failed = 0
    if not jobs:
        return 0
    out.parent.mkdir(parents=True, exist_ok=True)
    engine = Engine(address)
    progress = Progress(len(jobs), sys.stderr, unit="requests")
    try:
        with out.open("a") as f:
            for finished in engine.run(record_request, jobs, workers, tick=progress.tick):
                if finished.error:
                    failed += 1
                    progress.advance(False, f"{finished.job.label}: ERROR", failed=True)
                    print(finished.error, file=sys.stderr)
                    continue
                records = finished.result
                for record in records:
                    f.write(json.dumps(record) + "\n")
                f.flush()
                progress.advance(any(r["solved"] for r in records),
                                 f"{finished.job.label}: {sum(r['solved'] for r in records)} of "
                                 f"{len(records)} candidates solved, "
                                 f"{sum(bool(r.get('reached')) for r in records)} reached the "
                                 f"goal in MuJoCo")
    finally:
        progress.close()
    return failed
