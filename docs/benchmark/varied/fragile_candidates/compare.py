"""Two arms of one interleaved benchmark run, request by request (docs/benchmark.md, "More
candidates for a fragile best"): reached (servo arm, nothing toppled), solved, toppling,
perturbed executions, request time, and the requests where the arms differ.

    python docs/benchmark/varied/fragile_candidates/compare.py .../seed2_ab/trials.csv
"""
import csv, sys, statistics
rows=list(csv.DictReader(open(sys.argv[1])))
arms={}
for r in rows: arms.setdefault(r['planner'],{})[(r['scene'],r['seed'])]=r
ok=lambda r: r['solved']=='1' and r['executed_servo']=='1' and int(r['executed_toppled'] or 0)==0
names=list(arms)
common=set.intersection(*[set(a) for a in arms.values()])
for n in names:
    rs=[arms[n][k] for k in common]
    t=sorted(float(r['plan_time_s']) for r in rs)
    both=[k for k in common if all(arms[m][k]['solved']=='1' for m in names)]
    tb=statistics.median(float(arms[n][k]['plan_time_s']) for k in both) if both else 0
    pr=sum(int(r['perturbed_reached'] or 0) for r in rs); pt=sum(int(r['perturbed_trials'] or 0) for r in rs)
    print(f"{n}: n {len(rs)} reached {sum(map(ok,rs))} solved {sum(r['solved']=='1' for r in rs)} toppling {sum(int(r['executed_toppled'] or 0)>0 for r in rs)} perturbed {pr}/{pt} median {statistics.median(t):.1f} p90 {t[int(0.9*len(t))-1]:.1f} both-solved({len(both)}) median {tb:.1f} cand {statistics.mean(float(r['candidates'] or 0) for r in rs):.2f}")
a,b=names[0],names[1]
for k in sorted(common):
    x,y=arms[a][k],arms[b][k]
    if ok(x)!=ok(y) or x['robustness']!=y['robustness']:
        print(k,'A',ok(x),x['robustness'],x['plan_time_s'],x['candidates'],'| B',ok(y),y['robustness'],y['plan_time_s'],y['candidates'])
