"""The shipped default on held-out varied seeds 9 + 10 at `6eed008` (docs/benchmark.md "PC-RRT's
iterations compiled") and at `6ade336` (this section: unpushable goal objects refused, Project
without LAPACK or allocations) side by side: reached (servo arm, nothing toppled), solved,
toppling, request time, and the requests whose outcome differs. Run from this folder:
python3 compare.py > compare_s9_s10.txt"""
import csv
import statistics

runs = {'6eed008': '../compiled_iteration/varied_s9_s10_6eed008/trials.csv',
        '6ade336': 'varied_s9_s10_6ade336/trials.csv'}
arms = {}
for label, path in runs.items():
    with open(path) as f:
        arms[label] = {(r['scene'], r['seed']): r for r in csv.DictReader(f)}


def ok(r):
    return r['solved'] == '1' and r['executed_servo'] == '1' and int(r['executed_toppled'] or 0) == 0


for n, a in arms.items():
    rs = list(a.values())
    t = sorted(float(r['plan_time_s']) for r in rs)
    print(f"{n}: n {len(rs)} reached {sum(map(ok, rs))} solved "
          f"{sum(r['solved'] == '1' for r in rs)} "
          f"toppling {sum(int(r['executed_toppled'] or 0) > 0 for r in rs)} "
          f"request median {statistics.median(t):.2f} p90 {t[int(0.9 * len(t)) - 1]:.1f} "
          f"within 1/5/10/20 s {[sum(x <= b for x in t) for b in (1, 5, 10, 20)]} "
          f"GOAL_INVALID {sum(r['outcome'] == 'GOAL_INVALID' for r in rs)}")
print("requests whose outcome or reached differs (6eed008, 6ade336):")
for k in sorted(arms['6eed008']):
    a, b = arms['6eed008'][k], arms['6ade336'][k]
    if ok(a) != ok(b) or a['outcome'] != b['outcome']:
        print(k, a['outcome'], ok(a), a['plan_time_s'], '|', b['outcome'], ok(b),
              b['plan_time_s'])
both = [k for k in arms['6eed008'] if all(arms[n][k]['solved'] == '1' for n in arms)]
for n in arms:
    print(n, f"the {len(both)} solved by both: median request "
             f"{statistics.median(float(arms[n][k]['plan_time_s']) for k in both):.2f} s")
