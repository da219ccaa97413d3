import csv, sys, statistics as st
ok=lambda r: r["executed_servo"]=="1" and r["executed_toppled"]=="0"
arms={}
for name, paths in (("old", sys.argv[1].split(",")), ("new", sys.argv[2].split(","))):
    rows=[]
    for p in paths:
        try: rows += list(csv.DictReader(open(p)))
        except FileNotFoundError: pass
    arms[name]={(r["scene"],r["seed"]):r for r in rows}
pc={(r["scene"],r["seed"]):r for r in csv.DictReader(open("docs/benchmark/experiments/hand_pushes_goal/varied_s6_s8/trials.csv")) if r["planner"]=="pc-rrt"}
keys=sorted(set(arms["old"])&set(arms["new"]))
print("paired requests", len(keys))
for name, d in list(arms.items())+[("pc-rrt (hand_pushes_goal control)", pc)]:
    rs=[d[k] for k in keys]
    print(f"{name:36s} reached {sum(ok(r) for r in rs):3d} solved {sum(r['solved']=='1' for r in rs):3d} toppled {sum(r['executed_toppled']=='1' for r in rs):2d} median {st.median(float(r['plan_time_s']) for r in rs):.1f} s")
both=[k for k in keys if ok(arms['old'][k]) != ok(arms['new'][k])]
print("differ", len(both), "new better", sum(ok(arms['new'][k]) for k in both))
