"""Side by side: two reexec.py outputs on the same plans (soft.jsonl, stiff.jsonl)."""

import json
import sys

import numpy as np

a = [json.loads(line) for line in open(sys.argv[1])]
b = [json.loads(line) for line in open(sys.argv[2])]
assert [x["plan"] for x in a] == [y["plan"] for y in b]
for x, y in zip(a, b):
    print(f"{x['plan']:24s} reached {int(x['reached'])} {int(y['reached'])}   toppled "
          f"{','.join(x['toppled']) or '-':14s} {','.join(y['toppled']) or '-':14s} model error "
          f"{100 * x['model_error_m']:5.1f} {100 * y['model_error_m']:5.1f} cm")
for name, rows in ((sys.argv[1], a), (sys.argv[2], b)):
    errors = np.array([r["model_error_m"] for r in rows])
    print(f"{name}: {len(rows)} plans, reached {sum(r['reached'] for r in rows)}, toppling "
          f"{sum(bool(r['toppled']) for r in rows)}, model error median "
          f"{100 * np.median(errors):.1f} cm, within 2 cm {int((errors < 0.02).sum())}")
