"""`robot_fit.capsules_per_link(arm, 3)` for the xArm7 and the Panda URDFs; writes the
capsules as JSON to argv[1] and prints the time. Run from a clone of each commit
(PYTHONPATH=CLONE) and compare the capsules.

    PYTHONPATH=CLONE AMENT_PREFIX_PATH=.venv .venv/bin/python fit_capsules.py OUT.json
"""
import sys, json, time
from rearrangement_planner.model.files import resolve_uri
from rearrangement_planner.tools.robot_fit import read_arm, capsules_per_link, config_dict
out = {}
t = time.time()
for uri, name in (("package://example-robot-data/robots/xarm_description/urdf/xarm7.urdf", "xarm7"), ("package://example-robot-data/robots/panda_description/urdf/panda.urdf", None)):
    arm = read_arm(resolve_uri(uri), name=name) if name else read_arm(resolve_uri(uri))
    caps = capsules_per_link(arm, 3)
    out[uri] = {k: [[list(map(float, c.a)), list(map(float, c.b)), c.radius] for c in v] for k, v in caps.items()}
print("time", time.time() - t)
json.dump(out, open(sys.argv[1], "w"), sort_keys=True)
