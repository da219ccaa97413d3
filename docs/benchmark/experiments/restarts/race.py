"""Two raced trees, each restarting with a fresh seed every CUTOFF iterations (or never),
resampled from the sweep's per-scene run lengths: iterations until the first tree finds a
plan, mean and median over scenes, and the share of races still unsolved at the sweep's cap
(10,000 iterations per tree; beyond it a run is censored)."""
import json, sys, collections, statistics, random
rows = [json.loads(l) for l in open(sys.argv[1]) if l.startswith("{")]
by = collections.defaultdict(list)
for r in rows:
    by[r["scene"]].append(r["iterations"] if r["solved"] else None)
CAP = max(r["iterations"] for r in rows)
rng = random.Random(0)

def tree(runs, cutoff):
    """Iterations one tree takes, or None if it passes CAP."""
    used = 0
    while used < CAP:
        t = rng.choice(runs)
        limit = CAP - used if cutoff is None else min(cutoff, CAP - used)
        if t is not None and t <= limit:
            return used + t
        used += limit
    return None

for cutoff in [None, 1000, 2000, 3000, 4000, 6000]:
    means, unsolved = [], 0
    draws = 4000
    for runs in by.values():
        xs = []
        for _ in range(draws):
            a, b = tree(runs, cutoff), tree(runs, cutoff)
            done = [x for x in (a, b) if x is not None]
            xs.append(min(done) if done else CAP)
            unsolved += not done
        means.append(statistics.mean(xs))
    print(f"cutoff {cutoff}: race iterations per tree, mean over scenes {statistics.mean(means):.0f}, "
          f"median {statistics.median(means):.0f}; races past {CAP}: {unsolved / (draws * len(by)):.2%}")
