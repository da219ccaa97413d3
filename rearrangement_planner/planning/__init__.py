"""Planning on the pushing manifold: PC-RRT, its baselines, shortcutting, trajectory timing and
the request pipeline. The public names, for `from rearrangement_planner.planning import ...`."""

from rearrangement_planner.planning.machinery.interface import (
    Outcome,
    Planner,
    PlannerOptions,
    PlanResult,
    Progress,
    PushingPlannerOptions,
    StopReason,
)
from rearrangement_planner.planning.planners.darrt import DARRT, DARRTOptions
from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions
from rearrangement_planner.planning.planners.slice_rrt import SliceRRT, SliceRRTOptions
from rearrangement_planner.planning.planners.static_rrt import StaticRRT
from rearrangement_planner.planning.requests.pipeline import PathMetrics, PlanOutput, plan_scene
from rearrangement_planner.planning.requests.registry import PLANNER_NAMES, PLANNERS, make_planner
from rearrangement_planner.planning.requests.request import PlanRequest
from rearrangement_planner.planning.requests.robustness import RobustOptions
from rearrangement_planner.planning.requests.shortcut import ShortcutOptions
from rearrangement_planner.planning.requests.trajectory import TimingOptions

__all__ = ["DARRT", "PCRRT", "PLANNERS", "PLANNER_NAMES", "DARRTOptions", "Outcome",
           "PCRRTOptions", "PathMetrics", "PlanOutput", "PlanRequest", "PlanResult", "Planner",
           "PlannerOptions", "Progress", "RobustOptions", "ShortcutOptions", "SliceRRT",
           "SliceRRTOptions", "StaticRRT", "PushingPlannerOptions", "StopReason", "TimingOptions",
           "make_planner", "plan_scene"]
