"""The pushing model's options: the one place its settings live.

The planners that step the quasistatic physics (PC-RRT, the Static RRT) plan in a `Physics`
built from these options, and so do shortcutting and the robustness rollouts of their plans;
DARRT never steps the physics, so its requests refuse these settings (`planning.requests.registry`).
A simulator that executes a trajectory (world_sim, `execution.open_loop`) lets objects slide
however they are pushed: it uses `simulation_options`, with the planner's two validity rules,
tipping and the turn limit, off.
"""

from __future__ import annotations

from dataclasses import dataclass

from rearrangement_planner.model.settings import Settings, internal, setting


@dataclass(frozen=True)
class PhysicsOptions(Settings):
    """How the quasistatic pushing model moves objects, and which pushes it refuses."""

    tipping: bool = setting(True)
    """Refuse a push that would tip its object over (the quasistatic tipping condition,
    `physics.step.tips_over`: push height, support friction and the footprint along the push),
    so that plans slide objects instead of toppling them. Off: objects never tip, as in King
    et al. 2015 (§III-A). Results: docs/benchmark.md."""
    max_turn: float = setting(5.0, low=0.0, high=1000.0)
    """Refuse a push that turns a box by more than this many radians per metre its centre
    travels (1 rad over 20 cm at the default 5). How fast an off-centre push turns an object is
    what the quasistatic model predicts worst, and a box's mispredicted turn sends every later
    push elsewhere. A cylinder's turn leaves its footprint where it was, and the limit refused
    most pushes of one (a point push more than 12 degrees off the normal turns a cylinder of
    3 cm radius faster), so cylinders turn freely. 0 = no limit, as in King et al. 2015. Measured:
    docs/experiments.md."""
    object_contact: bool = setting(True)
    """Objects that meet push each other (one complementarity problem over every object in
    contact, `pushing.build_multibody_lcp_kernel`), as in Haustein et al.'s Box2D model and
    Pang & Tedrake's quasistatic simulator, so that a plan may push a row of objects and the
    model predicts what execution does when objects meet. Off: a state in which objects touch
    is invalid, as in King et al. 2015 (§III-A). Results: docs/experiments.md."""
    tip_judgement: bool = internal(False)
    """Judge rather than refuse a push that would tip its object: the step reports, per
    object, how far the pusher must carry it while it tips to topple it (`step._tip_travel`),
    and the robustness rollouts count a topple when a push goes on that far
    (`planning.requests.robustness`). With `tipping` on, such a push is refused whatever this
    says."""
    contact_tolerance: float = internal(0.002)
    """With object_contact: object-object penetration (m) still valid after a step (the
    contact problem is solved for the step's first-order motion; a rotation leaves a little
    second-order overlap, which the next step pushes out)."""
    max_substep: float = internal(0.004)
    """Largest displacement (m) of any point of any contact shape within one substep."""
    penetration_tolerance: float = internal(0.003)
    """Largest arm-object penetration (m) allowed after a step."""
    vertical_normal_limit: float = internal(0.7)
    """|n_z| of a contact normal above which the arm presses on an object from above (45 deg)."""
    overlap_tolerance: float = internal(1e-4)
    """Object-object and object-obstacle penetration (m) still counted as touching."""
    static_objects: frozenset[str] = internal(frozenset())
    """Names of movable objects treated as static obstacles: any arm contact with one is
    invalid (`Invalid.ARM_OBSTACLE`). The Static RRT baseline makes every object but the goal
    object static (King et al. 2015, §V-A)."""


def simulation_options(max_substep: float = PhysicsOptions.max_substep) -> PhysicsOptions:
    """The physics of a simulated world that executes trajectories (world_sim, open-loop
    execution): a pushed object slides whatever the push height or turn, because tipping and
    the turn limit are rules for choosing plans, not physics; objects that meet push each
    other."""
    return PhysicsOptions(tipping=False, max_turn=0.0, max_substep=max_substep,
                          object_contact=True)
