"""The first plan of one tree at `6eed008` and `bf558b4`, run at the same time with one worker
each (docs/benchmark.md, "Project without LAPACK or allocations"): solved, reached, the
median plan time (unsolved at the 20 s budget) and how many within 1 s. Run from this folder:
python3 first_plan.py > first_plan.txt"""
import csv
import statistics

for label in ('6eed008', 'bf558b4'):
    with open(f'first_plan_varied_s0_{label}/trials.csv') as f:
        rows = list(csv.DictReader(f))
    t = sorted(float(r['plan_time_s']) for r in rows)
    reached = sum(r['executed_servo'] == '1' and int(r['executed_toppled'] or 0) == 0
                  for r in rows)
    print(f"{label}: n {len(rows)} solved {sum(r['solved'] == '1' for r in rows)} "
          f"reached {reached} median {statistics.median(t):.2f} s within 1 s "
          f"{sum(x <= 1 for x in t)} within 5 s {sum(x <= 5 for x in t)}")
arms = {}
for label in ('6eed008', 'bf558b4'):
    with open(f'first_plan_varied_s0_{label}/trials.csv') as f:
        arms[label] = {r['scene']: r for r in csv.DictReader(f)}
both = [k for k in arms['6eed008'] if all(arms[n][k]['solved'] == '1' for n in arms)]
for n in arms:
    print(n, f"the {len(both)} solved by both: median "
             f"{statistics.median(float(arms[n][k]['plan_time_s']) for k in both):.2f} s, "
             f"iterations {sum(int(arms[n][k]['iterations']) for k in both)}")
print("GOAL_INVALID:", {n: sorted(k for k, r in a.items() if r['outcome'] == 'GOAL_INVALID')
                        for n, a in arms.items()})
