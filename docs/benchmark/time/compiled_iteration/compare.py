"""The three request runs of docs/benchmark.md "PC-RRT's iterations compiled" side by side:
reached (servo arm, nothing toppled), solved, toppling, request time, and the requests whose
outcome differs. Run from this folder: python3 compare.py > compare_s9_s10.txt"""
import csv
import statistics

arms = {}
for label in ('fc8e11c', 'd0324a2', '6eed008'):
    with open(f'varied_s9_s10_{label}/trials.csv') as f:
        arms[label] = {(r['scene'], r['seed']): r for r in csv.DictReader(f)}


def ok(r):
    return r['solved'] == '1' and r['executed_servo'] == '1' and int(r['executed_toppled'] or 0) == 0


for n, a in arms.items():
    rs = list(a.values())
    t = sorted(float(r['plan_time_s']) for r in rs)
    solved = [float(r['plan_time_s']) for r in rs if r['solved'] == '1']
    print(f"{n}: n {len(rs)} reached {sum(map(ok, rs))} solved {len(solved)} "
          f"toppling {sum(int(r['executed_toppled'] or 0) > 0 for r in rs)} "
          f"request median {statistics.median(t):.2f} p90 {t[int(0.9 * len(t)) - 1]:.1f} "
          f"solved-request median {statistics.median(solved):.2f} "
          f"candidates {statistics.mean(float(r['candidates'] or 0) for r in rs):.2f}")
print("requests where reached differs (fc8e11c, d0324a2, 6eed008):")
for k in sorted(arms['fc8e11c']):
    v = [ok(arms[n][k]) for n in arms]
    if len(set(v)) > 1:
        print(k, v, [arms[n][k]['plan_time_s'] for n in arms])
