"""The shipped default before (`b2d6091`) and after Project and a propagation's steps were
compiled without reference counting (`563f5ca`), the fixed set's seeds 0-2 run from a clone
of each commit, the two clones alternated seed by seed on an idle machine (docs/benchmark.md,
"Project without reference counts"). The table of ../../experiments/fragile_iterations/
compare.py, then every candidate search both runs made alike, its seconds after against
before, by its iterations (../nearest/compare.py). Run from this folder:
python3 compare.py > compare.txt"""
import importlib.util
from pathlib import Path

spec = importlib.util.spec_from_file_location(
    "nearest_compare", Path(__file__).resolve().parent.parent / "nearest" / "compare.py")
nearest = importlib.util.module_from_spec(spec)
spec.loader.exec_module(nearest)

PAIRS = {"fixed, seeds 0-2": ("fixed_s012_b2d6091", "fixed_s012_563f5ca")}

if __name__ == "__main__":
    nearest.main(PAIRS)
    nearest.same_searches(PAIRS)
