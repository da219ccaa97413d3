#!/bin/bash
# The same 35 searches (1,500 iterations or the plan, varied scenes, seed 0) timed at several
# commits, alternated three times (docs/benchmark.md, "One compiled call per PC-RRT
# iteration"). Usage: same_work_ab.sh VENV CLONE... (VENV: a virtual environment with the
# product's requirements; each CLONE a clone of one commit).
venv=$1
shift
scenes=$(ls "$1"/config/benchmark/varied/ | grep -o "v[0-9]_s[0-9]" | paste -sd,)
for i in 1 2 3; do
  for dir in "$@"; do
    echo "$(git -C "$dir" rev-parse --short HEAD) $(cd "$dir" && PYTHONPATH=$dir AMENT_PREFIX_PATH=$venv "$venv"/bin/python docs/benchmark/time/same_work.py "$scenes" 1500 2>&1 | tail -1)"
  done
done
