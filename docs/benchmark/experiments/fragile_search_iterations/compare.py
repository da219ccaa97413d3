"""The shipped default before (`46112b5`) and after each of a fragile best's extra candidates
was bounded at `fragile_search_iterations` 10,000 (`8d1379d`), each from a clone of its commit,
the two alternated seed by seed on an otherwise idle machine (docs/benchmark.md, "A fragile
best's extra candidates within 10,000 iterations each"): the table, sign tests and the
requests that searched other candidates of ../fragile_iterations/compare.py. `8d1379d` ran the
fixed set a second time, alone, right after (fixed_s012_8d1379d_run2): the same plans, and
its spread in time. Run from this folder: python3 compare.py > compare.txt"""
import importlib.util
from pathlib import Path

spec = importlib.util.spec_from_file_location(
    "compare", Path(__file__).resolve().parent.parent / "fragile_iterations" / "compare.py")
compare = importlib.util.module_from_spec(spec)
spec.loader.exec_module(compare)

PAIRS = {"fixed, seeds 0-2": ("fixed_s012_46112b5", "fixed_s012_8d1379d"),
         "varied, seeds 9 + 10": ("varied_s9_s10_46112b5", "varied_s9_s10_8d1379d"),
         "fixed, seeds 0-2, 8d1379d again": ("fixed_s012_8d1379d", "fixed_s012_8d1379d_run2")}

if __name__ == "__main__":
    compare.main(PAIRS)
