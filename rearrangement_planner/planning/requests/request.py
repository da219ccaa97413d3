"""One plan request: everything that decides a plan, as one value, with the product's defaults.

The CLI, the node and every benchmark command build a `PlanRequest` and hand it to
`pipeline.plan_scene`; a request they build from the same settings is the same request, so
they plan it identically. Its defaults are the settings dataclasses' own, written once:

    request = PlanRequest(scene)                                  # the product's default
    request = PlanRequest.from_settings(scene, "darrt", {"time_limit": 20.0}, seed=3)
    request = PlanRequest.first_plan(scene, "pc-rrt", PCRRTOptions(k_actions=5))
    output = plan_scene(request)

A request is checked when it is built: the planner's name is resolved once, every value is in
its range, and a setting the planner does not read (the pushing model's for DARRT, another
planner's own) must keep its default, or ValueError names it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import SettingError, Settings, SettingSpec
from rearrangement_planner.model.state import State
from rearrangement_planner.physics.options import PhysicsOptions
from rearrangement_planner.planning.machinery.interface import PlannerOptions
from rearrangement_planner.planning.requests.finish import NO_FINISH, FinishOptions
from rearrangement_planner.planning.requests.judging import NO_JUDGE, JudgeOptions
from rearrangement_planner.planning.requests.parallel import RaceOptions
from rearrangement_planner.planning.requests.registry import (
    PLANNERS,
    PlannerSpec,
    planner_settings,
    planner_spec,
)
from rearrangement_planner.planning.requests.robustness import FIRST_PLAN, RobustOptions
from rearrangement_planner.planning.requests.shortcut import NO_SHORTCUT, ShortcutOptions
from rearrangement_planner.planning.requests.trajectory import TimingOptions

DEFAULT_PLANNER = "pc-rrt"

STAGES: tuple[type[Settings], ...] = (RaceOptions, ShortcutOptions, FinishOptions,
                                      TimingOptions, RobustOptions, JudgeOptions)
"""The settings of a request around its planner, in pipeline order: the race, shortcutting,
the finishing push, trajectory timing, robust selection, the 3D judge and its mends."""


def request_settings() -> tuple[SettingSpec, ...]:
    """Every setting a request has, each once: the planners' (`registry.planner_settings`),
    then the stages'. The node declares these as parameters and the CLI's --set takes them."""
    return planner_settings() + tuple(s for stage in STAGES for s in stage.describe())


@dataclass(frozen=True)
class PlanRequest:
    """One plan request (module docstring)."""

    scene: Scene
    planner: PlannerSpec = field(default_factory=lambda: PLANNERS[DEFAULT_PLANNER])
    """The registered planner (a name is resolved on construction)."""
    options: PlannerOptions = None  # type: ignore[assignment]   # set in __post_init__
    """The planner's options (None or another planner's options: adopted, `PlannerSpec.options`)."""
    physics: PhysicsOptions = field(default_factory=PhysicsOptions)
    """The pushing model the planner plans in (planners that step the physics)."""
    race: RaceOptions = field(default_factory=RaceOptions)
    shortcut: ShortcutOptions = field(default_factory=ShortcutOptions)
    finish: FinishOptions = field(default_factory=FinishOptions)
    timing: TimingOptions = field(default_factory=TimingOptions)
    robust: RobustOptions = field(default_factory=RobustOptions)
    seed: int = 0
    """All randomness of the request comes from it: the same request gives the same plan."""
    start: State | None = None
    """The start state; None = the scene's initial state."""
    judge: JudgeOptions = field(default_factory=JudgeOptions)
    """The answer judged in 3D and mended before it is given (`judging`)."""

    def __post_init__(self) -> None:
        planner = self.planner
        if isinstance(planner, str):
            planner = planner_spec(planner)
            object.__setattr__(self, "planner", planner)
        object.__setattr__(self, "options", planner.options(self.options))
        if not planner.steps_physics and self.physics != PhysicsOptions():
            changed = [s.name for s in PhysicsOptions.describe()
                       if getattr(self.physics, s.name) != s.default]
            raise SettingError(changed[0] if changed else "physics",
                               f"{planner.name} does not read {', '.join(changed) or 'physics'}:"
                               f" it never steps the quasistatic pushing model")
        if not 0 <= self.seed < 2**63:
            raise SettingError("seed", f"seed must be a non-negative integer, got {self.seed}")
        planner.check(self.scene, self.options)

    @property
    def trees(self) -> int:
        return self.race.trees

    @classmethod
    def first_plan(cls, scene: Scene, planner: PlannerSpec | str = DEFAULT_PLANNER,
                   options: PlannerOptions | None = None, seed: int = 0,
                   **changes: Any) -> PlanRequest:
        """The planner alone through the pipeline: one tree, no shortcutting, no finishing
        push, the first plan found, not judged in 3D (`changes` replace any other field)."""
        fields: dict[str, Any] = dict(race=RaceOptions(trees=1), shortcut=NO_SHORTCUT,
                                      finish=NO_FINISH, robust=FIRST_PLAN, judge=NO_JUDGE)
        fields.update(changes)
        return cls(scene, planner, options, seed=seed, **fields)  # type: ignore[arg-type]

    @classmethod
    def from_settings(cls, scene: Scene, planner: str, values: Mapping[str, Any],
                      seed: int = 0, start: State | None = None) -> PlanRequest:
        """The request from a flat mapping of setting names to values (the node's parameters,
        the CLI's options): the settings of `request_settings()` found in `values`, the rest at
        their defaults; other keys are ignored. ValueError names a value out of range, or a
        setting that `planner` does not read given a value other than its default."""
        spec = planner_spec(planner)
        known = {s.name: s for s in request_settings()}
        reads = {s.name for s in spec.settings()} | {s.name for t in STAGES for s in t.describe()}
        for name, value in values.items():
            if name in known and name not in reads and value != known[name].default:
                raise SettingError(name, f"{name}: {spec.name} does not read it (its settings: "
                                         f"{', '.join(s.name for s in spec.settings())})")

        def pick(kind: type[Settings]) -> Any:
            return kind(**{s.name: values[s.name] for s in kind.describe() if s.name in values})

        return cls(scene, spec, pick(spec.options_type),
                   pick(PhysicsOptions) if spec.steps_physics else PhysicsOptions(),
                   pick(RaceOptions), pick(ShortcutOptions), pick(FinishOptions),
                   pick(TimingOptions), pick(RobustOptions), seed, start,
                   pick(JudgeOptions))

    def settings(self) -> dict[str, Any]:
        """Every setting the request reads, by name (the recording's metadata)."""
        parts: list[Settings] = [self.options]
        if self.planner.steps_physics:
            parts.append(self.physics)
        parts += [self.race, self.shortcut, self.finish, self.timing, self.robust, self.judge]
        return {s.name: getattr(part, s.name) for part in parts for s in part.describe()}
