"""The shipped default before (`b2d6091`) and after Project and a propagation's steps were
compiled without reference counting (`563f5ca`), then also with the damped solve by a
Cholesky factor (`7b33efc`), each from a clone of its commit on an otherwise idle machine,
two clones alternated seed by seed (docs/benchmark.md, "Project without reference counts;
its damped solve by a Cholesky factor"):
- fixed_s012_b2d6091 / fixed_s012_563f5ca: the first run, `b2d6091` against `563f5ca`;
- fixed_s012_b2d6091_run2 / fixed_s012_7b33efc: the second, `b2d6091` against `7b33efc`;
- varied_s9_s10_b2d6091 / varied_s9_s10_7b33efc: held-out varied seeds 9 + 10.
The table of ../../experiments/fragile_iterations/compare.py, then every candidate search
both runs of a pair made alike, its seconds after against before, by its iterations
(../nearest/compare.py), and the search seconds of all requests. `b2d6091`'s two runs
against each other say how far the machine drifted between them. Run from this folder:
python3 compare.py > compare.txt"""
import csv
import importlib.util
from pathlib import Path

spec = importlib.util.spec_from_file_location(
    "nearest_compare", Path(__file__).resolve().parent.parent / "nearest" / "compare.py")
nearest = importlib.util.module_from_spec(spec)
spec.loader.exec_module(nearest)

PAIRS = {"fixed 0-2, first run: b2d6091 -> 563f5ca": ("fixed_s012_b2d6091", "fixed_s012_563f5ca"),
         "fixed 0-2, second run: b2d6091 -> 7b33efc": ("fixed_s012_b2d6091_run2",
                                                       "fixed_s012_7b33efc"),
         "varied 9 + 10: b2d6091 -> 7b33efc": ("varied_s9_s10_b2d6091",
                                               "varied_s9_s10_7b33efc"),
         "b2d6091, first run -> second run": ("fixed_s012_b2d6091", "fixed_s012_b2d6091_run2")}


def search_seconds(folder: str) -> float:
    with open(f"{folder}/trials.csv") as f:
        return sum(float(c.rsplit(":", 1)[1]) for r in csv.DictReader(f)
                   for c in r["candidate_searches"].split())


if __name__ == "__main__":
    nearest.main(PAIRS)
    nearest.same_searches(PAIRS)
    print("\n| rows | search seconds, all requests |\n|---|---|")
    for folder in sorted({f for pair in PAIRS.values() for f in pair}):
        if Path(folder).exists():
            print(f"| {folder} | {search_seconds(folder):.0f} |")
