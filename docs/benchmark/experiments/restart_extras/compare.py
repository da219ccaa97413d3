"""The shipped default (`0ec5ff3`, its rows in ../fragile_iterations/) against a restart
schedule for a fragile best's extra candidates: 6 of them, each within 0.25 x the first
plan's iterations, instead of 3 within 1 x (restart_extras_3c1954d.diff; docs/experiments.md,
2026-11-30). Each run alone from a clone of its commit. Run from this folder:
python3 compare.py > compare.txt"""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "fragile_iterations"))
from compare import main  # noqa: E402  (the same table, for other pairs)

PAIRS = {"fixed, seeds 0-2": ("../fragile_iterations/before_fixed_s012", "fixed_s012"),
         "varied, seeds 15 + 16": ("../fragile_iterations/before_varied_s15_s16",
                                   "varied_s15_s16")}

if __name__ == "__main__":
    main(PAIRS)
