#!/bin/bash
# Fresh compile of the core (warm_up with an empty Numba cache) in clone $1.
for clone in "$@"; do
  d=$(mktemp -d)
  cd "$clone"
  s=$(date +%s.%N)
  NUMBA_CACHE_DIR=$d PYTHONPATH=$clone AMENT_PREFIX_PATH=/work/main/.venv /work/main/.venv/bin/python -c "from rearrangement_planner.planning.requests.warmup import warm_up; warm_up()"
  e=$(date +%s.%N)
  echo "$(git log --oneline -1 | cut -c1-7) fresh compile $(echo "$e - $s" | bc) s"
  rm -rf "$d"
done
