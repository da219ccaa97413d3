#!/bin/bash
# CLI request, whole process: HEAD (workers start with the warm-up) against f37750e (worker starts in the first race)
rm -rf /tmp/fbw && mkdir -p /tmp/fbw
farm-bench -n 6 --timeout 900 --vs "sh -c 'cd /work/clones/base && PYTHONPATH=/work/clones/base AMENT_PREFIX_PATH=/work/main/.venv exec /work/main/.venv/bin/python -m rearrangement_planner.tools.cli $1 --seed $2 --json \$(mktemp /tmp/fbw/b.XXXX.json) --quiet'" -- sh -c "cd /work/clones/head && PYTHONPATH=/work/clones/head AMENT_PREFIX_PATH=/work/main/.venv exec /work/main/.venv/bin/python -m rearrangement_planner.tools.cli $1 --seed $2 --json \$(mktemp /tmp/fbw/a.XXXX.json) --quiet"
python3 - <<'PY'
import json, glob, statistics as st
for arm in "ab":
    runs=[json.load(open(f)) for f in glob.glob(f"/tmp/fbw/{arm}.*.json")]
    pt=[r["plan_time_s"] for r in runs]; wu=[r["phases"]["warm_up_s"] for r in runs]
    print(arm, len(runs), "plan_time median %.2f (%.2f-%.2f)"%(st.median(pt),min(pt),max(pt)), "warm_up median %.2f"%st.median(wu), "iterations", sorted(set(r["iterations"] for r in runs)))
PY
