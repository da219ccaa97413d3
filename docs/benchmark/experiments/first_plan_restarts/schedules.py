"""Restart schedules for PC-RRT's first plan, simulated on measured searches
(docs/experiments.md, "Restarts for the first plan, simulated").

searches_30000.jsonl holds, per fixed-set scene n4-n7, the iterations one tree took to its
first plan with seeds 100-109, or a failure within 30,000 (`searches.py`). A request's first
plan is a race of two trees: each search draws two of the scene's searches, and its
iterations are the fewer of the two. A schedule bounds the k-th search by L(k) iterations and
starts the next seed when it fails; its cost is every search's iterations until one finds a
plan (a failure costs its bound). Without a measurement beyond 30,000 iterations, every
schedule here bounds each search by at most 30,000; "30,000 each" is the schedule closest to no
restarts that the data can say anything about. The mean cost per scene is printed beside the
first searches of the shipped rows (fixed set, seeds 0-2, `0ec5ff3`; per tree).

    python schedules.py > schedules.txt
"""
import csv
import json
import random
import statistics
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).parent
CAP = 30000
SCHEDULES = {
    "30,000 each": lambda k: CAP,
    "1,000 doubling": lambda k: min(1000 * 2 ** k, CAP),
    "2,000 doubling": lambda k: min(2000 * 2 ** k, CAP),
    "4,000 doubling": lambda k: min(4000 * 2 ** k, CAP),
    "1,000 x 1.5": lambda k: min(1000 * 1.5 ** k, CAP),
    "5,000 each": lambda k: 5000,
    "10,000 each": lambda k: 10000,
}


def searches() -> dict[str, list[float]]:
    found: dict[str, list[float]] = defaultdict(list)
    for line in open(HERE / "searches_30000.jsonl"):
        row = json.loads(line)
        found[row["scene"]].append(row["iterations"] if row["solved"] else float("inf"))
    return found


def shipped_first_searches() -> dict[str, list[int]]:
    first: dict[str, list[int]] = defaultdict(list)
    rows = HERE.parent / "fragile_iterations" / "before_fixed_s012" / "trials.csv"
    for row in csv.DictReader(open(rows)):
        logged = row["candidate_searches"].split()
        if logged:
            iterations, score = logged[0].split(":")[:2]
            first[row["scene"]].append(int(iterations) if score != "-"
                                       else int(iterations) // 2)
    return first


def mean_cost(found: list[float], schedule, draws: int = 4000) -> float:
    rng = random.Random(0)
    costs = []
    for _ in range(draws):
        total = 0.0
        for k in range(1000):
            bound = schedule(k)
            race = min(rng.choice(found), rng.choice(found))
            if race <= bound:
                total += race
                break
            total += bound
            if total > 150000:          # about the 60 s budget
                break
        costs.append(total)
    return statistics.mean(costs)


def main() -> None:
    found, shipped = searches(), shipped_first_searches()
    sums = dict.fromkeys(SCHEDULES, 0.0)
    for scene in sorted(found):
        costs = []
        for name, schedule in SCHEDULES.items():
            cost = mean_cost(found[scene], schedule)
            sums[name] += cost
            costs.append(f"{name} {cost:.0f}")
        print(f"{scene}: shipped first searches {shipped[scene]}; " + ", ".join(costs))
    print("sum of the scenes' mean costs: "
          + ", ".join(f"{name} {total:.0f}" for name, total in sums.items()))


if __name__ == "__main__":
    main()
