"""The shipped default on held-out varied seeds 9 + 10 at `62c1471` (before) and `0a50c89`
(one forward kinematics a step, Nearest by arrangement), run one after the other on the same
day (docs/benchmark.md, "One forward kinematics a step; Nearest by arrangement"), beside
`6ade336`'s run of 2026-11-29: reached (servo arm, nothing toppled), solved, toppling, request
time, and the requests whose outcome differs. Seeds 11 + 12 were run the same way, without an
earlier run beside them. Run from this folder:
python3 compare.py s9_s10 > compare_s9_s10.txt; python3 compare.py s11_s12 > compare_s11_s12.txt"""
import csv
import statistics
import sys

seeds = sys.argv[1]
runs = {'6ade336 (2026-11-29)': f'../project_gram/varied_{seeds}_6ade336/trials.csv',
        '62c1471': f'varied_{seeds}_62c1471/trials.csv',
        '0a50c89': f'varied_{seeds}_0a50c89/trials.csv'}
arms = {}
for label, path in runs.items():
    try:
        with open(path) as f:
            arms[label] = {(r['scene'], r['seed']): r for r in csv.DictReader(f)}
    except FileNotFoundError:
        pass


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
names = list(arms)
before, after = names[-2], names[-1]
print(f"requests whose outcome or reached differs ({before}, {after}):")
for k in sorted(arms[before]):
    a, b = arms[before][k], arms[after][k]
    if ok(a) != ok(b) or a['outcome'] != b['outcome']:
        print(k, a['outcome'], ok(a), a['plan_time_s'], '|', b['outcome'], ok(b),
              b['plan_time_s'])
both = [k for k in arms[before] if all(arms[n][k]['solved'] == '1' for n in names)]
for n in names:
    print(n, f"the {len(both)} solved by all: median request "
             f"{statistics.median(float(arms[n][k]['plan_time_s']) for k in both):.2f} s, "
             f"search iterations {sum(int(arms[n][k]['iterations']) for k in both)}")
print(f"over 20 s at {after}:")
for k, r in sorted(arms[after].items(), key=lambda kv: float(kv[1]['plan_time_s'])):
    if float(r['plan_time_s']) > 20:
        print(k, r['outcome'], r['plan_time_s'], 'candidates', r['candidates'],
              'robustness', r['robustness'], 'reached', ok(r))
