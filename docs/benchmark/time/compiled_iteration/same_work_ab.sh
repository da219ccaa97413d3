#!/bin/bash
# The same 35 searches (1,500 iterations or the plan, varied scenes, seed 0) timed at two
# commits, alternated three times (docs/benchmark.md, "One compiled call per PC-RRT
# iteration"). Usage: same_work_ab.sh CLONE_BEFORE CLONE_AFTER PYTHON (a venv with the
# product's requirements; AMENT_PREFIX_PATH set to it).
before=$1 after=$2 python=$3
scenes=$(ls "$after"/config/benchmark/varied/ | grep -o "v[0-9]_s[0-9]" | paste -sd,)
for i in 1 2 3; do
  for arm in before after; do
    dir=${!arm}
    echo "$arm $(cd "$dir" && PYTHONPATH=$dir "$python" docs/benchmark/time/same_work.py "$scenes" 1500 2>&1 | tail -1)"
  done
done
