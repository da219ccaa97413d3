"""Every recorded benchmark request whose goal object the arm cannot push without tipping it
(`planning.machinery.search.unpushable`, at the shipped pushing plane): how many were solved,
and how many of those reached the goal in MuJoCo (servo arm, nothing toppled). Run from the
checkout: python docs/benchmark/experiments/unpushable/count.py"""
import csv
from collections import Counter
from pathlib import Path

from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.search import unpushable
from rearrangement_planner.tools.benchmark import load_trial_scene

scenes = {}
for set_name in ("varied", "scenes"):
    for path in sorted(Path("config/benchmark", set_name).glob("*.yaml")):
        scenes[path.stem] = unpushable(Physics(load_trial_scene(path))) is not None
print("scenes whose goal object the arm cannot push:", sorted(k for k, v in scenes.items() if v))
total, by_planner = Counter(), Counter()
for trials in sorted(Path("docs/benchmark").rglob("trials.csv")):
    for row in csv.DictReader(trials.open()):
        if not scenes.get(row["scene"]):
            continue
        total["requests"] += 1
        if row["solved"] == "1":
            total["solved"] += 1
            reached = row.get("executed_servo") == "1"
            total["reached"] += reached
            by_planner[(row["planner"], "reached" if reached else "missed")] += 1
print(dict(total))
for key, n in sorted(by_planner.items()):
    print(*key, n)
