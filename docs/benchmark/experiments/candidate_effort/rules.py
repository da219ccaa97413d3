"""Replay robust selection's stopping rules over candidates.jsonl records (one request = the
candidates its seeds give, each searched alone, with its iterations when recorded).

    python rules.py candidates.jsonl [...]

Rules: the first plan; the shipped ranking of up to n candidates (stop at robustness >= floor);
and later searches bounded by `effort` x the first plan's iterations, at least `least` (exact in
iterations when the records have them, else by search time as a proxy)."""
import json
import math
import statistics
import sys

from rearrangement_planner.planning.requests.robustness import candidate_rank


def choose(records, n=3, floor=1.0, penalty=0.5, budget=60.0, effort=None, least=0):
    spent, solved, bound = 0.0, [], None
    for r in sorted(records, key=lambda r: r["k"]):
        if r["k"] >= n or budget - spent <= 0.001:
            break
        cost, cut = r["search_s"], False
        if bound is not None:
            size = r.get("iterations")
            if size is None:                      # time as a proxy for iterations
                cut = r["search_s"] > bound
                cost = min(cost, bound)
            elif size > bound:
                cut, cost = True, r["search_s"] * bound / size
        if cost > budget - spent:
            spent = budget
            break
        spent += cost
        if cut or not r["solved"]:
            continue
        spent += r["shortcut_s"] + r["rollouts_s"]
        if not solved and effort is not None:
            size = r.get("iterations")
            bound = (max(least, math.ceil(effort * size)) if size is not None
                     else effort * r["search_s"])
        solved.append(r)
        if r["robustness"] >= floor:
            break
    if not solved:
        return None, spent
    return max(solved, key=lambda r: (candidate_rank(r["robustness"], r["goal_travel_m"],
                                                     penalty), -r["k"])), spent


def table(paths):
    recs = [json.loads(line) for p in paths for line in open(p) if line.strip()]
    reqs = {}
    for r in recs:
        reqs.setdefault((r["scene"], r["seed"]), []).append(r)
    rules = [("first plan", dict(n=1)), ("up to 3, no bound", {})]
    for effort in (0.5, 1.0, 2.0, 4.0):
        for least in (0, 100, 500, 1000, 2000):
            rules.append((f"effort {effort:g}, at least {least}", dict(effort=effort, least=least)))
    print(f"{len(reqs)} requests")
    print("| rule | solved | reached (ideal arm) | toppled | robustness sum | median s | mean s |")
    print("|---|---|---|---|---|---|---|")
    for name, kw in rules:
        out = [choose(v, **kw) for v in reqs.values()]
        times = sorted(t for _, t in out)
        chosen = [c for c, _ in out if c]
        print(f"| {name} | {len(chosen)} | "
              f"{sum(bool(c['reached']) and not c['toppled'] for c in chosen)} | "
              f"{sum(c['toppled'] > 0 for c in chosen)} | "
              f"{sum(c['robustness'] for c in chosen):.1f} | {statistics.median(times):.1f} | "
              f"{sum(times) / len(times):.1f} |")


if __name__ == "__main__":
    table(sys.argv[1:])
