#!/bin/bash
# same_work.py from clone $1 on three varied scenes, 1,500 iterations each; appends its line to $2.
cd "$1" && PYTHONPATH="$1" AMENT_PREFIX_PATH=/work/main/.venv exec /work/main/.venv/bin/python docs/benchmark/time/same_work.py v6_s3,v4_s1,v7_s4 1500 >> "$2" 2>&1
