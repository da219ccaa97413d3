"""`robot_fit.capsules_per_link(arm, 3)` for the xArm7 and the Panda URDFs; writes the
capsules as JSON to argv[1] and prints the time. Run from a clone of each commit
(PYTHONPATH=CLONE) and compare the capsules.

    PYTHONPATH=CLONE AMENT_PREFIX_PATH=.venv .venv/bin/python fit_capsules.py OUT.json
"""
import json
import sys
import time

from rearrangement_planner.model.files import resolve_uri
from rearrangement_planner.tools.robot_fit import capsules_per_link, read_arm

ARMS = (("package://example-robot-data/robots/xarm_description/urdf/xarm7.urdf", "xarm7"),
        ("package://example-robot-data/robots/panda_description/urdf/panda.urdf", None))

if __name__ == "__main__":
    capsules = {}
    start = time.time()
    for uri, name in ARMS:
        arm = read_arm(resolve_uri(uri), name=name) if name else read_arm(resolve_uri(uri))
        capsules[uri] = {link: [[list(map(float, c.a)), list(map(float, c.b)), c.radius]
                                for c in fitted]
                         for link, fitted in capsules_per_link(arm, 3).items()}
    print("time", time.time() - start)
    with open(sys.argv[1], "w") as f:
        json.dump(capsules, f, sort_keys=True)
