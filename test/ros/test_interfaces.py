"""`make` builds rearrangement_interfaces/ (ament_cmake, rosidl wheels) into the venv prefix
before the Python package: what is installed is what the repository holds, and rclpy finds
and (de)serializes its types."""

from __future__ import annotations

import sys
from pathlib import Path

from rclpy.serialization import deserialize_message, serialize_message

from rearrangement_interfaces.action import PlanRearrangement
from rearrangement_interfaces.msg import ErrorCode

SOURCE = Path(__file__).resolve().parents[2] / "rearrangement_interfaces"
INSTALLED = Path(sys.prefix) / "share" / "rearrangement_interfaces"


def test_the_installed_interfaces_are_the_repositorys():
    sources = sorted(p.relative_to(SOURCE) for p in SOURCE.glob("*/*.*")
                     if p.suffix in (".msg", ".action"))
    assert sources, SOURCE
    for relative in sources:
        installed = INSTALLED / relative
        assert installed.is_file(), f"{installed} missing: run make"
        assert installed.read_text() == (SOURCE / relative).read_text(), \
            f"{installed} is stale: run make"
    index = Path(sys.prefix) / "share/ament_index/resource_index/rosidl_interfaces"
    assert (index / "rearrangement_interfaces").is_file()


def test_goal_and_result_round_trip_through_cdr():
    goal = PlanRearrangement.Goal(goal_object="target", settings=["rollouts=5"], seed=7,
                                  execute=True)
    goal.goal_point.x = 0.5
    assert deserialize_message(serialize_message(goal), PlanRearrangement.Goal) == goal
    assert (PlanRearrangement.Goal().seed, PlanRearrangement.Result().robustness) == (-1, -1.0)
    result = PlanRearrangement.Result(message="m", plan_id="p")
    result.error_code.val = ErrorCode.FRAGILE_PLAN
    assert deserialize_message(serialize_message(result), PlanRearrangement.Result) == result
