"""The shipped default before (`0ec5ff3`; its rows in ../../experiments/fragile_iterations/,
the same searches as `794b4ac`) and after Nearest skips far arrangements (`7d48fd9`), each
set run alone from a clone of its commit (docs/benchmark.md, "Nearest skips far
arrangements"). Besides the table of ../../experiments/fragile_iterations/compare.py: every
candidate search that both runs made alike (the same seed, iterations and outcome), its
seconds after against before, by its iterations. Run from this folder:
python3 compare.py > compare.txt"""
import sys
from pathlib import Path

import numpy as np

EXPERIMENTS = Path(__file__).resolve().parents[2] / "experiments"
sys.path.insert(0, str(EXPERIMENTS / "fragile_iterations"))
from compare import load, main  # noqa: E402  (the same table, for other pairs)

BEFORE = "../../experiments/fragile_iterations/"
PAIRS = {"fixed, seeds 0-2": (BEFORE + "before_fixed_s012", "fixed_s012_7d48fd9"),
         "varied, seeds 9 + 10": (BEFORE + "before_varied_s9_s10", "varied_s9_s10_7d48fd9"),
         "varied, seeds 15 + 16": (BEFORE + "before_varied_s15_s16",
                                   "varied_s15_s16_7d48fd9")}
BANDS = ((0, 10_000), (10_000, 30_000), (30_000, 60_000), (60_000, 10**9))


def same_searches(pairs) -> None:
    """Seconds after / before of the candidate searches both runs made alike (over 1 s)."""
    print("\n| set | iterations of the search | searches | seconds after / before, median |")
    print("|---|---|---|---|")
    for name, (b, a) in pairs.items():
        before, after = load(b), load(a)
        if before is None or after is None:
            continue
        ratios = []
        for key, row in before.items():
            for old, new in zip(row["candidate_searches"].split(),
                                after[key]["candidate_searches"].split(), strict=False):
                (alike_old, s_old), (alike_new, s_new) = old.rsplit(":", 1), new.rsplit(":", 1)
                if alike_old == alike_new and float(s_old) > 1.0:
                    ratios.append((int(alike_old.split(":")[0]), float(s_new) / float(s_old)))
        for low, high in BANDS:
            band = [r for i, r in ratios if low <= i < high]
            if band:
                print(f"| {name} | {low:,}-{high:,} | {len(band)} | {np.median(band):.2f} |")


if __name__ == "__main__":
    main(PAIRS)
    same_searches(PAIRS)
