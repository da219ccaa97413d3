#!/usr/bin/env bash
# The live view's cost when nobody watches: one plan of SCENE (seed 0, the default request) with
# `--live` (the server up, no client) and without, alternating, PAIRS times; prints
# "<arm> <plan_time_s> <iterations>" per plan. Run from the repository root of a clone:
#   bash docs/benchmark/live_view/live_ab.sh config/benchmark/varied/v2_s4.yaml 5
set -eu
scene=${1:-default}
pairs=${2:-5}
once() {
  json=$(mktemp)
  .venv/bin/rearrangement-plan "$scene" --seed 0 --quiet --json "$json" "$@" > /dev/null 2>&1 || true
  .venv/bin/python -c 'import json, sys; d = json.load(open(sys.argv[1])); print(d["plan_time_s"], d["iterations"])' "$json"
  rm -f "$json"
}
for _ in $(seq "$pairs"); do
  echo "live $(once --live 8799)"
  echo "off $(once)"
done
