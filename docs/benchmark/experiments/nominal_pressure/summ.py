import json, sys, statistics, collections
rows = [json.loads(l) for l in open(sys.argv[1]) if l.startswith("{")]
S = ("0.8", "1.0", "1.3", "1.6", "1.85")
for group, sel in (("all", lambda r: True), ("box", lambda r: r["shape"] == "box"),
                   ("cylinder", lambda r: r["shape"] == "cylinder")):
    rs = [r for r in rows if sel(r) and all(r[f"c{s}"]["code"] == 0 for s in S)]
    print(group, len(rs), "plans replayed by every scale")
    for s in S:
        c = [r[f"c{s}"] for r in rs]
        agree = sum(x["reached"] == r["mj_reached"] for x, r in zip(c, rs))
        print(f"  c x{s}: final pos err median {statistics.median(x['pos'] for x in c):.3f} mean {statistics.mean(x['pos'] for x in c):.3f}"
              f" | yaw err median {statistics.median(x['yaw'] for x in c):.3f} mean {statistics.mean(x['yaw'] for x in c):.3f}"
              f" | path err median {statistics.median(x['path'] for x in c):.3f}"
              f" | reached agrees with MuJoCo {agree}/{len(rs)}; model reached {sum(x['reached'] for x in c)}")
    best = collections.Counter(min(S, key=lambda s: r[f"c{s}"]["pos"]) for r in rs)
    print("  best scale by final position:", dict(best))
print("MuJoCo reached", sum(r["mj_reached"] for r in rows), "of", len(rows))
