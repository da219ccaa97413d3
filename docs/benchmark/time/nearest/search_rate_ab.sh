#!/bin/bash
# search_rate.py from two clones, alternated, three rounds (docs/benchmark.md, "Nearest by
# arrangement"). Run from the repository's root:
#   BEFORE=/path/to/clone/of/794b4ac AFTER=/path/to/clone/of/7d48fd9 \
#     docs/benchmark/time/nearest/search_rate_ab.sh [scene.yaml]
# Each clone compiles its core on its first run (a few minutes): run it once before.
here=$(cd "$(dirname "$0")" && pwd)
scene=$(realpath "${1:-config/benchmark/scenes/n4_s0.yaml}")
for round in 1 2 3; do
  for clone in "$BEFORE" "$AFTER"; do
    echo "== $(git -C "$clone" log --oneline -1 | cut -c1-7) round $round"
    (cd "$clone" && PYTHONPATH="$clone" python "$here/search_rate.py" "$scene" 2>/dev/null)
  done
done
