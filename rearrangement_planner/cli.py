"""`rearrangement-plan`: the planning command line (DESIGN §8) arrives with the planner.

Until then it says so and exits with the "bad input" code instead of pretending to plan.
"""

import sys


def main() -> int:
    print("rearrangement-plan: the PC-RRT planner is not built yet; "
          "`python -m rearrangement_planner.demo SCENE.yaml` simulates one straight push",
          file=sys.stderr)
    return 2
