"""The shipped default before (`0ec5ff3`, which logs each candidate) and after a fragile
best's extra candidates were bounded by `fragile_iterations` 40,000 (`32976d7`), each set run
alone from a clone of its commit (docs/benchmark.md, "A fragile best's candidates within
40,000 iterations", not adopted). Run from this folder: python3 compare.py > compare.txt"""
import csv
from math import comb

import numpy as np

PAIRS = {"fixed, seeds 0-2": ("before_fixed_s012", "after_fixed_s012"),
         "varied, seeds 9 + 10": ("before_varied_s9_s10", "after_varied_s9_s10"),
         "varied, seeds 15 + 16 (held out)": ("before_varied_s15_s16", "after_varied_s15_s16")}


def load(folder):
    try:
        with open(f"{folder}/trials.csv") as f:
            return {(r["scene"], r["seed"]): r for r in csv.DictReader(f)}
    except FileNotFoundError:
        return None


def reached(r):
    return r["executed_servo"] == "1"


def toppled(r):
    return r["executed_toppled"] not in ("0", "")


def line(label, rows):
    times = np.array([float(r["plan_time_s"]) for r in rows])
    print(f"| {label} | {len(rows)} | {sum(r['solved'] == '1' for r in rows)} | "
          f"{sum(map(reached, rows))} | {sum(map(toppled, rows))} "
          f"({sum(r['executed_toppled_goal'] == '1' for r in rows)}) | "
          f"{np.median(times):.2f} / {np.percentile(times, 90):.1f} s | {(times > 20).sum()} | "
          f"{np.mean([int(r['candidates'] or 0) for r in rows]):.2f} |")


def searches(r):
    """A request's candidates without their search seconds (which vary run to run)."""
    return [c.rsplit(":", 1)[0] for c in r["candidate_searches"].split()]


def sign_test(before, after, test):
    only_before = sum(test(before[k]) and not test(after[k]) for k in before)
    only_after = sum(test(after[k]) and not test(before[k]) for k in before)
    n, low = only_before + only_after, min(only_before, only_after)
    p = min(1.0, 2 * sum(comb(n, i) for i in range(low + 1)) / 2 ** n) if n else 1.0
    return only_before, only_after, p


def main(pairs):
    """The before-and-after table of `pairs` ({set: (before folder, after folder)}), sign
    tests, and the requests that searched other candidates."""
    print("| set, commit | requests | solved | reached | plans toppling (the goal object) |"
          " median / p90 | over 20 s | candidates per request |")
    print("|---|---|---|---|---|---|---|---|")
    tests = []
    for name, (b, a) in pairs.items():
        before, after = load(b), load(a)
        if before is None or after is None:
            continue
        line(f"{name}, before", list(before.values()))
        line(f"{name}, after", list(after.values()))
        tests.append((name, before, after))
    for name, before, after in tests:
        print(f"\n{name}:")
        for label, test in (("reached", reached), ("toppling", toppled)):
            ob, oa, p = sign_test(before, after, test)
            print(f"- {label}: before only {ob}, after only {oa} (two-sided sign test p = {p:.2f})")
        changed = [k for k in before if searches(before[k]) != searches(after[k])]
        print(f"- {len(changed)} requests searched other candidates:")
        for k in sorted(changed):
            print(f"  - {k[0]} seed {k[1]}: reached {int(reached(before[k]))} -> "
                  f"{int(reached(after[k]))}, {before[k]['plan_time_s']} -> "
                  f"{after[k]['plan_time_s']} s; {before[k]['candidate_searches']} -> "
                  f"{after[k]['candidate_searches']}")


if __name__ == "__main__":
    main(PAIRS)
