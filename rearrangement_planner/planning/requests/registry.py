"""The planners by name (like OMPL's planner registry): each entry says which class plans, which
options it takes, the physics it plans in, whether it reads the pushing model's settings and
whether its paths may be shortcut. The CLI, the node, the benchmark, the race and the pipeline
look planners up here; nothing branches on a name.

    spec = PLANNERS["darrt"]
    planner = spec.make(scene, spec.options(time_limit=10))
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rearrangement_planner.model.scene import Scene
from rearrangement_planner.model.settings import SettingError, Settings, SettingSpec
from rearrangement_planner.physics.options import PhysicsOptions
from rearrangement_planner.physics.step import Physics
from rearrangement_planner.planning.machinery.interface import Planner, PlannerOptions
from rearrangement_planner.planning.planners.darrt import DARRT, DARRTOptions
from rearrangement_planner.planning.planners.pcrrt import PCRRT, PCRRTOptions
from rearrangement_planner.planning.planners.slice_rrt import (
    SliceRRT,
    SliceRRTOptions,
    check_oracle,
)
from rearrangement_planner.planning.planners.static_rrt import StaticRRT, static_physics


def _own_physics(scene: Scene, physics: Physics | None) -> Physics:
    return physics or Physics(scene)


def _plans_any(scene: Scene, options: PlannerOptions) -> None:
    return None


@dataclass(frozen=True)
class PlannerSpec:
    """One registered planner."""

    name: str
    planner: Callable[..., Planner]
    """The class: `planner(scene, options, physics)`."""
    options_type: type[PlannerOptions]
    physics: Callable[[Scene, Physics | None], Physics] = _own_physics
    """The world the planner plans in, from the scene's physics: also the one its paths are
    shortcut in (a Static RRT path must not push the objects it treats as obstacles)."""
    steps_physics: bool = True
    """Whether the planner steps the quasistatic pushing model, and so reads `PhysicsOptions`
    (DARRT carries objects rigidly and never does: a request refuses physics settings for
    it)."""
    shortcut: bool = True
    """Whether its paths may be shortcut: shortcutting re-simulates the pushes in the
    quasistatic physics, which DARRT's rigid carrying does not follow."""
    summary: str = ""
    check: Callable[[Scene, PlannerOptions], None] = _plans_any
    """Raises ValueError, naming the setting, when the planner cannot plan the scene with the
    options (the slice-based RRT's learned oracle has no weights for the scene's arm); a
    request calls it when it is made."""

    def options(self, base: PlannerOptions | None = None, **values: Any) -> PlannerOptions:
        """This planner's options: `base` (any `PlannerOptions`: its shared fields; a field
        this planner does not have must be at its default), then `values`; the rest at their
        defaults. ValueError names a setting out of range or one this planner does not read."""
        fields = {f.name for f in dataclasses.fields(self.options_type)}
        unknown = sorted(set(values) - fields)
        if unknown:
            raise SettingError(unknown[0], f"{self.name} has no setting {', '.join(unknown)}; "
                                           f"its settings are {', '.join(sorted(fields))}")
        if base is not None and not isinstance(base, self.options_type):
            ignored = [f.name for f in dataclasses.fields(base) if f.name not in fields
                       and getattr(base, f.name) != f.default]
            if ignored:
                raise ValueError(f"{self.name} does not read {', '.join(ignored)} (set in "
                                 f"{type(base).__name__})")
        return dataclasses.replace(self.options_type.adopt(base), **values)

    def settings(self) -> tuple[SettingSpec, ...]:
        """The settings this planner reads: its options', then the pushing model's when it
        steps the physics."""
        own = self.options_type.describe()
        return own + (PhysicsOptions.describe() if self.steps_physics else ())

    def make(self, scene: Scene, options: PlannerOptions | None = None,
             physics: Physics | None = None) -> Planner:
        """The planner on `scene`, in its own physics built from `physics` (or the scene)."""
        return self.planner(scene, self.options(options), self.physics(scene, physics))


PLANNERS: dict[str, PlannerSpec] = {
    "pc-rrt": PlannerSpec("pc-rrt", PCRRT, PCRRTOptions,
                          summary="physics-constrained kinodynamic RRT (King et al. 2015, "
                                  "Alg. 1)"),
    "static-rrt": PlannerSpec("static-rrt", StaticRRT, PCRRTOptions, static_physics,
                              summary="PC-RRT with every non-goal object a static obstacle"),
    "slice-rrt": PlannerSpec("slice-rrt", SliceRRT, SliceRRTOptions,
                             summary="slice-based RRT with manipulation states and pushes "
                                     "from an oracle (Haustein et al. 2018, Alg. 1)",
                             check=check_oracle),
    "darrt": PlannerSpec("darrt", DARRT, DARRTOptions, steps_physics=False, shortcut=False,
                         summary="DARRT primitives: transit, RRT transit, rigid straight push"),
}
PLANNER_NAMES = tuple(PLANNERS)


def planner_spec(name: str) -> PlannerSpec:
    """The registered planner `name`; ValueError lists the known ones."""
    try:
        return PLANNERS[name]
    except KeyError:
        raise SettingError("planner", f"unknown planner {name!r}; choose one of "
                                      f"{', '.join(PLANNER_NAMES)}") from None


def make_planner(name: str, scene: Scene, options: PlannerOptions | None = None,
                 physics: Physics | None = None) -> Planner:
    """The planner called `name` on `scene` (`PlannerSpec.make`)."""
    return planner_spec(name).make(scene, options, physics)


def planner_settings() -> tuple[SettingSpec, ...]:
    """Every planner setting once (a name shared by several planners has one meaning and one
    default), the shared ones first, then each planner's own, then the pushing model's."""
    seen: dict[str, SettingSpec] = {}
    types: list[type[Settings]] = [PlannerOptions]
    types += [p.options_type for p in PLANNERS.values()] + [PhysicsOptions]
    for options_type in types:
        for setting in options_type.describe():
            seen.setdefault(setting.name, setting)
    return tuple(seen.values())
