"""Expected time to a first plan with restarts at a fixed iteration cutoff, from the sweep's
empirical per-scene run-length distributions (each restart an independent draw)."""
import json, sys, collections, statistics
rows = [json.loads(l) for l in open(sys.argv[1]) if l.startswith("{")]
by = collections.defaultdict(list)
for r in rows:
    by[r["scene"]].append((r["iterations"] if r["solved"] else None, r["time"] / max(r["iterations"], 1)))
CAP = max(r["iterations"] for r in rows)
def expected(runs, cutoff):
    """E[iterations to a plan] restarting every `cutoff` iterations (None: never), or inf."""
    n = len(runs)
    solved = [i for i, _ in runs if i is not None and (cutoff is None or i <= cutoff)]
    p = len(solved) / n
    if cutoff is None:
        return (sum(solved) + (n - len(solved)) * CAP) / n, p  # a lower bound: censored at CAP
    if p == 0:
        return float("inf"), 0
    return cutoff * (1 - p) / p + statistics.mean(solved), p
for cutoff in [None, 500, 1000, 1500, 2000, 3000, 4000, 6000]:
    e = [min(expected(v, cutoff)[0], 99999) for v in by.values()]
    print(cutoff, "mean over scenes", round(statistics.mean(e)), "median", round(statistics.median(e)),
          "per scene", [round(x) for x in e])
