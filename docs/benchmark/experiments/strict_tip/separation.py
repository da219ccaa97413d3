"""How well each score flags the plans that topple or miss in MuJoCo (`score_strict.py`'s
lines): the mean score of toppled and of reached plans, the AUC of a low score for toppling
and for missing (0.5: no better than chance), and the Brier score against reaching."""
import json, sys
def auc(pos, neg):
    # P(score of pos < score of neg): does a low score flag the positive class
    t = 0.0
    for p in pos:
        for n in neg:
            t += 1.0 if p < n else 0.5 if p == n else 0.0
    return t / (len(pos) * len(neg))
for f in sys.argv[1:]:
    ls = [json.loads(l) for l in open(f)]
    for key in ("robustness", "ship", "strict"):
        top = [d[key] for d in ls if d["toppled"]]
        ok = [d[key] for d in ls if d["reached"]]
        nontop = [d[key] for d in ls if not d["toppled"]]
        miss = [d[key] for d in ls if not d["reached"]]
        brier = sum((d[key] - d["reached"]) ** 2 for d in ls) / len(ls)
        print(f.split('/')[-1], key, "toppled mean %.2f" % (sum(top)/len(top)), "reached mean %.2f" % (sum(ok)/len(ok)),
              "AUC topple %.2f" % auc(top, nontop), "AUC miss %.2f" % auc(miss, ok), "Brier %.3f" % brier)
