#!/bin/bash
# `rearrangement-bench physics --seconds 3` from two clones, alternated, three rounds
# (docs/benchmark.md, "Physics at the targets: a replay's states made whole").
#   BEFORE=/path/to/clone/of/549f4d7 AFTER=/path/to/clone/of/55a4723 ./physics_ab.sh
# Each clone compiles its core on its first run (a few minutes): run it once before.
for round in 1 2 3; do
  for clone in "$BEFORE" "$AFTER"; do
    echo "== $(git -C "$clone" log --oneline -1 | cut -c1-7) round $round"
    (cd "$clone" && PYTHONPATH="$clone" /work/main/.venv/bin/python -m rearrangement_planner.tools.bench physics --seconds 3 2>/dev/null) |
      python3 -c "
import json, sys
d = json.load(sys.stdin)
print(' '.join(f\"{r['objects']}obj: {r['steps_per_second']:.0f} step / \"
               f\"{r['compiled_steps_per_second']:.0f} compiled\" for r in d['results']))"
  done
done
