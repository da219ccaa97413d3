"""Which fragile_below to ship, replayed from measured rows (docs/experiments.md, "More
candidates for a fragile best"): the shipped rows of seeds 0-1 where their best scored at least
the threshold, else the rows of the run with fragile_candidates 3 below 0.5 (which searched
on wherever the shipped best was below 0.5). An approximation: below 0.5 that run searched
on past a best the threshold would have stopped at. Prints per threshold: reached, toppling,
perturbed executions reached, request time median and mean.

    python docs/benchmark/varied/fragile_candidates/threshold_replay.py   # from the checkout
"""
import csv, statistics
A={(r['scene'],r['seed']):r for r in csv.DictReader(open('docs/benchmark/varied/second_candidate/trials.csv')) if r['planner']=='pc-rrt'}
B={(r['scene'],r['seed']):r for r in csv.DictReader(open('docs/benchmark/varied/fragile_candidates/seeds01_below05/trials.csv'))}
ok=lambda r: r['solved']=='1' and r['executed_servo']=='1' and int(r['executed_toppled'] or 0)==0
for th in (0.5,0.4,0.3,0.25,0.2):
    rows=[]
    for k,a in A.items():
        use_b = a['solved']=='1' and float(a['robustness'])<th
        rows.append(B[k] if use_b else a)
    t=sorted(float(r['plan_time_s']) for r in rows)
    pr=sum(int(r['perturbed_reached'] or 0) for r in rows); pt=sum(int(r['perturbed_trials'] or 0) for r in rows)
    print(th, sum(map(ok,rows)), sum(int(r['executed_toppled'] or 0)>0 for r in rows), f"{pr}/{pt}", round(statistics.median(t),2), round(statistics.mean(t),1))
