import json, sys, collections
recs = [json.loads(l) for f in sys.argv[1:] for l in open(f)]
by = collections.defaultdict(list)
for r in recs: by[r["scene"]].append(r)
def choose(rs, key, budget=60.0, stop=None):
    spent, sol = 0.0, []
    for r in sorted(rs, key=lambda r: r["k"]):
        if budget - spent <= 0.001 or r["search_s"] > budget - spent: break
        spent += r["search_s"]
        if not r["solved"]: continue
        sol.append(r); spent += r["shortcut_s"] + r["rollouts_s"] + (r["mj_s"] if key in ("mj", "mjtr") else 0)
        if stop and stop(r): break
    if not sol: return None, spent
    if key == "first": return sol[0], spent
    if key == "model": return max(sol, key=lambda r: r["robustness"] - 0.5 * r["travel"]), spent
    if key == "mj": return max(sol, key=lambda r: (r["mj_score"], r["robustness"] - 0.5 * r["travel"])), spent
    if key == "mjtr": return max(sol, key=lambda r: r["mj_score"] - 0.5 * r["travel"]), spent
    if key == "oracle": return max(sol, key=lambda r: (r["reached"], r["eval_reached"])), spent
rules = {"first": ("first", None), "model(default)": ("model", lambda r: r["robustness"] >= 1.0),
         "mujoco": ("mj", lambda r: r["mj_score"] >= 1.0), "mujoco-travel": ("mjtr", lambda r: r["mj_score"] >= 1.0),
         "oracle": ("oracle", None)}
complete = [s for s, rs in by.items() if len(rs) == 3 or any(r["k"] == 2 for r in rs)]
print(len(by), "scenes", len(complete), "complete")
for name, (key, stop) in rules.items():
    reached = ev = n = top = 0; times = []
    for s in complete:
        c, t = choose(by[s], key if key != "mjtr" else "mjtr", stop=stop)
        times.append(t)
        if c: reached += c["reached"]; ev += c["eval_reached"]; n += 5; top += c["toppled"] > 0
    times.sort()
    print(f"{name:16s} reached {reached}/{len(complete)} perturbed {ev}/{len(complete)*5} toppled {top} median {times[len(times)//2]:.1f}s")
