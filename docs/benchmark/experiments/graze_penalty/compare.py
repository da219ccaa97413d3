"""The shipped default against `graze_penalty` 0.2 (docs/benchmark.md, "A grazed rim ranked
lower"): the table, sign tests and the requests whose candidates changed, of
../fragile_iterations/compare.py, and the requests whose answer changed. The fixed set's base
is `8d1379d`'s rows (the shipped plans); held-out varied seeds 15 + 16 ran from a clone of
`9a45c7b` (the shipped planner), then the change from a clone of `3298a2b`, each alone
(revive the change from `5882f03`, which adds its tests). Run from this folder: python3 compare.py > compare.txt"""
import importlib.util
from pathlib import Path

here = Path(__file__).resolve().parent
spec = importlib.util.spec_from_file_location(
    "compare", here.parent / "fragile_iterations" / "compare.py")
compare = importlib.util.module_from_spec(spec)
spec.loader.exec_module(compare)

PAIRS = {"fixed, seeds 0-2": (f"{here.parent}/fragile_search_iterations/fixed_s012_8d1379d",
                              "fixed_s012_3298a2b"),
         "varied, seeds 15 + 16 (held out)": ("varied_s15_s16_9a45c7b", "varied_s15_s16_3298a2b")}


def answers():
    """The requests whose answered plan changed (its goal distance or robustness)."""
    for name, (b, a) in PAIRS.items():
        before, after = compare.load(b), compare.load(a)
        if before is None or after is None:
            continue
        changed = [k for k in after if (before[k]["goal_distance_m"], before[k]["robustness"])
                   != (after[k]["goal_distance_m"], after[k]["robustness"])]
        print(f"\n{name}: {len(changed)} answers changed")
        for k in sorted(changed):
            print(f"- {k[0]} seed {k[1]}: robustness {before[k]['robustness']} -> "
                  f"{after[k]['robustness']}, reached {int(compare.reached(before[k]))} -> "
                  f"{int(compare.reached(after[k]))}, toppled {before[k]['executed_toppled']} -> "
                  f"{after[k]['executed_toppled']}")


if __name__ == "__main__":
    compare.main(PAIRS)
    answers()
