"""The shipped default (`8d1379d`'s rows; the top-clearance commits give its plans unchanged
with the clearance off: varied seed 9 run again from a clone of `668e5b3` gave the same 35
plans, varied_s9_base_rerun) against `--set top_clearance=0.02` (and `0.005` on the varied set) from a
clone of `85f60e5` (the arm behind the tool), each run alone (docs/experiments.md, "A top clearance for
the arm behind the tool"): the table, sign tests and the requests whose candidates changed, of
../fragile_iterations/compare.py. Run from this folder: python3 compare.py > compare.txt"""
import importlib.util
from pathlib import Path

here = Path(__file__).resolve().parent
spec = importlib.util.spec_from_file_location(
    "compare", here.parent / "fragile_iterations" / "compare.py")
compare = importlib.util.module_from_spec(spec)
spec.loader.exec_module(compare)

BASE = here.parent / "fragile_search_iterations"
PAIRS = {
    "fixed, seeds 0-2, 0.02": (f"{BASE}/fixed_s012_8d1379d", "fixed_s012_arm_002"),
    "varied, seeds 9 + 10, 0.02": (f"{BASE}/varied_s9_s10_8d1379d", "varied_s9_s10_arm_002"),
    "varied, seeds 9 + 10, 0.005": (f"{BASE}/varied_s9_s10_8d1379d", "varied_s9_s10_arm_0005"),
    "varied, seed 9, 0.02 on every shape (668e5b3)": ("varied_s9_base_rerun",
                                                      "varied_s9_every_002")}

if __name__ == "__main__":
    compare.main(PAIRS)
