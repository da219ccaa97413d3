"""Summary of first_plan_sweep.py's rows: per setting, the searches solved within 4,000
iterations and within a wall time t (comparable up to the least time of the setting's
unsolved searches). Usage: python3 sweep_summary.py ROWS.jsonl"""
import collections
import json
import statistics
import sys

rows = [json.loads(line) for line in open(sys.argv[1])]
by = collections.defaultdict(list)
for r in rows:
    by[r["setting"]].append(r)
for name, runs in by.items():
    unsolved = [r["time"] for r in runs if not r["solved"]]
    within = ", ".join(f"{t:g} s: {sum(r['solved'] and r['time'] <= t for r in runs)}"
                       for t in (0.5, 1.0, 1.5, 2.0, 3.0))
    print(f"{name}: {len(runs)} searches, solved {sum(r['solved'] for r in runs)}; "
          f"mean steps {statistics.mean(r['steps'] for r in runs):.0f}, mean time "
          f"{statistics.mean(r['time'] for r in runs):.2f} s; solved within {within} "
          f"(least unsolved time {min(unsolved, default=float('nan')):.2f} s)")
