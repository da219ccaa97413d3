"""Replay robust selection over logged candidates under rules that bound the candidates after
the first plan more tightly than the logged run did (docs/benchmark.md, "A fragile best's
candidates within 40,000 iterations", not adopted).

The rows come from `rearrangement-bench run` at a commit that logs `candidate_searches` (each
candidate's iterations:robustness:goal travel m:search s, `pipeline.Phases.log_candidate`).
A search is determined by its seed, so a tighter bound is replayed exactly: a candidate that
planned within the tighter bound plans the same, one that did not ends unsolved at it. The
time saved is the search time beyond the bound (pro rata) and, for a candidate no longer
judged, the request's mean shortcut and rollout time per judged candidate. Where the rule
answers with another candidate, its execution in MuJoCo is unknown: "reached, answer kept"
counts only the requests whose answer stays.

    python replay.py trials.csv [trials.csv ...]
"""
import csv
import sys

import numpy as np

CANDIDATES, FRAGILE_BELOW, MIN_ROBUSTNESS, PENALTY, MIN_ITERATIONS = 2, 0.3, 1.0, 0.5, 100
"""The shipped selection at the logged commit (`RobustOptions`, `MIN_CANDIDATE_ITERATIONS`)."""


def parse(row):
    out = []
    for entry in row["candidate_searches"].split():
        iterations, score, travel, seconds = entry.split(":")
        out.append((int(iterations), None if score == "-" else float(score),
                    None if travel == "-" else float(travel), float(seconds)))
    return out


def replay(candidates, rule):
    """(answer index, search seconds saved, judged candidates dropped). `rule(k, first,
    spent)` bounds later candidate k given the first plan's iterations and what the later
    ones took so far (below MIN_ITERATIONS: not searched); None is the logged run (each later
    candidate within the first plan's iterations, at least MIN_ITERATIONS)."""
    best, best_rank, most = None, None, 0.0
    first, spent, saved, dropped = None, 0, 0.0, 0
    for k, (iterations, score, travel, seconds) in enumerate(candidates):
        if k >= CANDIDATES and (best is None or most >= FRAGILE_BELOW):
            break
        if first is not None:
            logged = max(MIN_ITERATIONS, first)
            if score is None:       # a race's unsolved search logs its trees' sum
                iterations = min(iterations, logged)
            bound = logged if rule is None else min(logged, rule(k, first, spent))
            if bound < MIN_ITERATIONS:
                saved += seconds
                dropped += score is not None
                continue
            if iterations > bound or (score is None and bound < logged):
                saved += seconds * (1 - bound / max(iterations, 1))
                dropped += score is not None
                spent += bound
                continue
            spent += iterations
        if score is None:
            continue
        if first is None:
            first = iterations
        if score >= MIN_ROBUSTNESS:
            return k, saved, dropped
        rank = score - PENALTY * travel
        if best is None or rank > best_rank:
            best, best_rank = k, rank
        most = max(most, score)
    return best, saved, dropped


UNBOUNDED = 10**9


def pool(effort):
    """Every later candidate within what is left of `effort` x the first plan's iterations."""
    return lambda k, first, spent: max(MIN_ITERATIONS, int(np.ceil(effort * first))) - spent


def quick_first(n):
    """Extra candidates for a fragile best only after a first plan found within n
    iterations."""
    return lambda k, first, spent: UNBOUNDED if k < CANDIDATES or first <= n else 0


def within(n):
    """Extra candidates for a fragile best only within n iterations in all, the first plan's
    included (the bound tried at `32976d7`)."""
    return lambda k, first, spent: UNBOUNDED if k < CANDIDATES else n - spent - first


def extra_each(effort, n=None):
    """Each extra candidate for a fragile best within `effort` x the first plan's iterations
    (and, with n, all of them within n iterations in all)."""
    def rule(k, first, spent):
        if k < CANDIDATES:
            return UNBOUNDED
        bound = max(MIN_ITERATIONS, int(np.ceil(effort * first)))
        return bound if n is None else min(bound, n - spent - first)
    return rule


def within_floor(n, floor):
    """`within(n)`, but every extra candidate may search at least `floor` iterations."""
    return lambda k, first, spent: (UNBOUNDED if k < CANDIDATES
                                    else max(floor, n - spent - first))


RULES = {"logged": None,
         **{f"extra ones within {n} in all, each {f}": within_floor(n, f)
            for n in (20000, 40000) for f in (1000, 2000, 5000, 10000)},
         **{f"extra ones each within {e} x the first": extra_each(e) for e in (0.5, 0.3, 0.2)},
         **{f"extra ones each within {e} x, all within {n}": extra_each(e, n)
            for e in (0.5, 0.3) for n in (40000, 60000)},
         **{f"every later one within {e} x the first": pool(e) for e in (3, 2, 1.5)},
         **{f"extra ones after a first within {n}": quick_first(n) for n in (2000, 5000, 10000)},
         **{f"extra ones within {n} in all": within(n)
            for n in (10000, 20000, 30000, 40000, 50000)}}


def main(paths):
    rows = [r for p in paths for r in csv.DictReader(open(p)) if r["planner"] == "pc-rrt"]
    print(f"{len(rows)} requests ({', '.join(paths)})")
    print(f"{'rule':42s} {'median':>7s} {'p90':>6s} {'>20 s':>6s} {'reached, answer kept':>21s} "
          f"{'answers changed':>16s}")
    for name, rule in RULES.items():
        times, reached, changed = [], 0, 0
        for r in rows:
            candidates = parse(r)
            t = float(r["plan_time_s"])
            if r["solved"] != "1" or not candidates:
                times.append(t)
                continue
            logged, _, _ = replay(candidates, None)
            answer, saved, dropped = replay(candidates, rule)
            judged = sum(1 for c in candidates if c[1] is not None)
            per = (float(r["shortcuts_s"]) + float(r["rollouts_s"])) / max(judged, 1)
            times.append(max(t - saved - per * dropped, 0.0))
            if answer == logged:
                reached += int(r["executed_servo"] == "1")
            else:
                changed += 1
        times = np.array(times)
        print(f"{name:42s} {np.median(times):6.2f}s {np.percentile(times, 90):5.1f}s "
              f"{(times > 20).sum():6d} {reached:21d} {changed:16d}")


if __name__ == "__main__":
    main(sys.argv[1:])
