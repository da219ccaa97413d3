"""Replay robust selection over logged candidates with each of a fragile best's extra
candidates bounded at N iterations (`RobustOptions.fragile_search_iterations`; docs/benchmark.md,
"A fragile best's extra candidates within 10,000 iterations each"), with the replay of
../fragile_iterations/replay.py: a search is determined by its seed, so a candidate that
planned within the bound plans the same and one that did not ends unsolved at it; where the
answer changes, its execution in MuJoCo is unknown ("reached, answer kept" counts only the
requests whose answer stays). Then the answers that came from an extra candidate, by the
iterations their search took. Run from the repository's root:

    python3 docs/benchmark/experiments/fragile_search_iterations/replay_each.py ROWS/trials.csv ...
"""
import csv
import importlib.util
import sys
from pathlib import Path

spec = importlib.util.spec_from_file_location(
    "replay", Path(__file__).resolve().parent.parent / "fragile_iterations" / "replay.py")
replay = importlib.util.module_from_spec(spec)
spec.loader.exec_module(replay)


def each(n):
    """Every extra candidate (k >= CANDIDATES) within n iterations (and the logged bound)."""
    return lambda k, first, spent: replay.UNBOUNDED if k < replay.CANDIDATES else n


replay.RULES = {"logged": None, **{f"each extra one within {n}": each(n)
                                   for n in (5000, 8000, 10000, 12000, 15000, 20000)}}


def rescues(paths, bound=10000):
    """The answers robust selection took from an extra candidate, by their search's
    iterations, and how many reached."""
    found = []
    for path in paths:
        for r in csv.DictReader(open(path)):
            candidates = replay.parse(r) if r["candidate_searches"] else []
            if r["solved"] != "1" or not candidates:
                continue
            answer, _, _ = replay.replay(candidates, None)
            if answer is not None and answer >= replay.CANDIDATES:
                found.append((candidates[answer][0], r["executed_servo"] == "1"))
    quick = [ok for iterations, ok in found if iterations <= bound]
    slow = [ok for iterations, ok in found if iterations > bound]
    print(f"\n{len(found)} answers from an extra candidate: {len(quick)} found within {bound} "
          f"iterations ({sum(quick)} reached), {len(slow)} beyond ({sum(slow)} reached)")
    print("their iterations:", sorted(iterations for iterations, _ in found))


if __name__ == "__main__":
    for p in sys.argv[1:]:
        replay.main([p])
    rescues(sys.argv[1:])
