"""Summary of touch.py's output: plans with an unmodelled arm touch of the goal object, and
those whose fitted shapes passed within 3 mm of it there."""
import json, sys, collections
for path in sys.argv[1:]:
    rows = [json.loads(l) for l in open(path) if l.startswith("{")]
    touched = [r for r in rows if r["unmodelled"]]
    close = [r for r in rows if any(g <= 0.003 for _, g in r["unmodelled"].values())]
    by = collections.Counter(b for r in rows for b in r["unmodelled"])
    print(f"{path}: {len(rows)} plans; {len(touched)} with an unmodelled arm touch of the goal "
          f"object; {len(close)} of them within 3 mm of the fitted shapes; by link {dict(by)}")
