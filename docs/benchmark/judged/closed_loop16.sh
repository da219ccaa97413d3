#!/usr/bin/env bash
# The closed loop in a world whose objects lie 1 cm from where they are published: 16 varied
# scenes (s0-s2 of v1-v5, and v6_s0), one goal each through the action (execute, 2 re-plans),
# world_sim's MuJoCo engine with pose noise 0.01 m (world seed 1). Prints one line per scene:
# the scene, node_demo's exit code (0: the goal object ended inside its region) and the last
# outcome. Run from a clone of the commit measured:
#   bash docs/benchmark/judged/closed_loop16.sh OUT_DIR > closed_loop16.txt
set -u
out=${1:-out/closed_loop16}
mkdir -p "$out"
for scene in v1_s0 v1_s1 v1_s2 v2_s0 v2_s1 v2_s2 v3_s0 v3_s1 v3_s2 v4_s0 v4_s1 v4_s2 \
             v5_s0 v5_s1 v5_s2 v6_s0; do
  log="$out/$scene.log"
  .venv/bin/python -m rearrangement_planner.ros.sim.node_demo \
      --scene "config/benchmark/varied/$scene.yaml" --seed 0 --time-limit 60 --time-scale 10 \
      --record-dir "$out/$scene" --pose-noise 0.01 --world-seed 1 --replan 2 > "$log" 2>&1
  code=$?
  echo "$scene exit $code $(grep '^outcome:' "$log" | tail -1)"
done
