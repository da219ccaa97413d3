"""Planning on the pushing manifold: PC-RRT, its baselines, shortcutting, trajectory timing and
the request pipeline. The public names, for `from rearrangement_planner.planning import ...`."""

from rearrangement_planner.planning.darrt import DARRT, DARRTOptions
from rearrangement_planner.planning.interface import (
    Outcome,
    Planner,
    PlannerOptions,
    PlanResult,
    Progress,
    PushingPlannerOptions,
    StopReason,
)
from rearrangement_planner.planning.pcrrt import PCRRT, PCRRTOptions
from rearrangement_planner.planning.pipeline import PathMetrics, PlanOutput, plan_scene
from rearrangement_planner.planning.registry import PLANNER_NAMES, PLANNERS, make_planner
from rearrangement_planner.planning.request import PlanRequest
from rearrangement_planner.planning.robustness import RobustOptions
from rearrangement_planner.planning.shortcut import ShortcutOptions
from rearrangement_planner.planning.slice_rrt import SliceRRT, SliceRRTOptions
from rearrangement_planner.planning.static_rrt import StaticRRT
from rearrangement_planner.planning.trajectory import TimingOptions

__all__ = ["DARRT", "PCRRT", "PLANNERS", "PLANNER_NAMES", "DARRTOptions", "Outcome",
           "PCRRTOptions", "PathMetrics", "PlanOutput", "PlanRequest", "PlanResult", "Planner",
           "PlannerOptions", "Progress", "RobustOptions", "ShortcutOptions", "SliceRRT",
           "SliceRRTOptions", "StaticRRT", "PushingPlannerOptions", "StopReason", "TimingOptions",
           "make_planner", "plan_scene"]
