"""The top-view PNG of a plan (docs/design.md, ``rearrangement-plan --plot OUT.png``).

Frame and units: the robot base frame seen from above, x to the right and y up, equal aspect,
metres. The picture shows the table rectangle, the robot base at the origin, the static
obstacles, every movable object at its start pose (dashed outline) and end pose (filled; the
goal object in its own colour), the path of every object's centre, the end-effector path and the
goal region.

Only the CLI imports this module: the planner core never draws. It uses matplotlib's
object-oriented API with an explicit Agg canvas, so importing it neither selects a backend nor
touches pyplot's global state.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Polygon, Rectangle

from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.scene import MovableObject, Obstacle, Scene

FIGURE_SIZE = (7.0, 6.0)   # inches
DPI = 120                  # dots per inch: the PNG is 840 x 720 pixels
CIRCLE_VERTICES = 64       # vertices of a cylinder's outline polygon
MARGIN = 0.05              # m of free space around everything drawn

GOAL_COLOUR = "#d62728"    # the goal object and its goal region
GOAL_REGION_FILL = to_rgba(GOAL_COLOUR, alpha=0.15)   # translucent, edge stays opaque
# Muted colours for the other movable objects (matplotlib's "Set2" palette), cycled.
OBJECT_COLOURS = ("#66c2a5", "#8da0cb", "#e5c494", "#a6d854", "#e78ac3", "#fc8d62", "#b3b3b3")
OBSTACLE_COLOUR = "0.45"
TABLE_COLOUR = "#f3ecdc"
EE_COLOUR = "#1f3b73"


class PlotError(RearrangementError, ValueError):
    """The arrays given to `plot_top_view` do not fit the scene (wrong shape or non-finite)."""


def object_outline(obj: MovableObject | Obstacle, pose: np.ndarray,
                   vertices: int = CIRCLE_VERTICES) -> np.ndarray:
    """The footprint of `obj` at planar `pose` (x, y, yaw) (m, rad) as a closed polygon
    (K, 2) in the base frame, counter-clockwise, without repeating the first vertex.

    A box gives its K = 4 corners: the corners (+-sx/2, +-sy/2) of the object frame mapped by
    p_base = R(yaw) p_obj + (x, y). A cylinder gives K = `vertices` points on its circle of
    radius r about (x, y) (its yaw does not change the footprint).
    """
    x, y, yaw = (float(v) for v in np.asarray(pose, dtype=float).reshape(3))
    centre = np.array([x, y])
    if obj.shape == "cylinder":
        r = 0.5 * float(obj.size[0])
        t = np.linspace(0.0, 2.0 * math.pi, vertices, endpoint=False)
        return centre + r * np.column_stack([np.cos(t), np.sin(t)])
    hx, hy = 0.5 * float(obj.size[0]), 0.5 * float(obj.size[1])
    local = np.array([[hx, hy], [-hx, hy], [-hx, -hy], [hx, -hy]])
    c, s = math.cos(yaw), math.sin(yaw)
    rotation = np.array([[c, -s], [s, c]])
    return local @ rotation.T + centre


def plot_top_view(scene: Scene, object_paths: np.ndarray, ee_path: np.ndarray,
                  out_path: str | Path, title: str = "",
                  start_states_only: bool = False,
                  executed_paths: np.ndarray | None = None) -> Path:
    """Draw the top view of a plan in `scene` (docs/design.md) and write it to `out_path` as a PNG
    of 840 x 720 pixels (7 x 6 in at 120 dpi); return the path written.

    `object_paths` (T, M, 3) holds the poses (x, y, yaw) (m, rad) of the scene's M objects, in
    scene order, at T >= 1 instants along the plan: the first row is the start, the last the
    end. `ee_path` (N, 2) is the end-effector (x, y) (m) along the plan; N = 0 draws none.
    With `start_states_only` only the start is drawn (objects filled at ``object_paths[0]``,
    the end-effector's first point), as for a scene preview or an unsolved problem. `title`
    defaults to the scene's name. `executed_paths` (T', M, 3), the object poses when the plan
    was executed in another engine (`world3d.execution`), are drawn beside the plan's:
    dotted centre paths and dotted outlines at their end. The PNG format is used whatever the
    suffix; the folder of
    `out_path` must exist. Raises `PlotError` (a `ValueError`) naming the argument whose shape
    or values are wrong, before anything is written.
    """
    paths = _checked_object_paths(scene, object_paths)
    ee = _checked_ee_path(ee_path)
    out_path = Path(out_path)

    fig = Figure(figsize=FIGURE_SIZE, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    handles = _draw_scene(ax, scene, paths, ee, start_states_only)
    if executed_paths is not None and not start_states_only:
        handles += _draw_executed(ax, scene, _checked_object_paths(scene, executed_paths))

    ax.set_xlim(*_limits(scene, paths, ee, axis=0))
    ax.set_ylim(*_limits(scene, paths, ee, axis=1))
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("x (m), robot base frame")
    ax.set_ylabel("y (m), robot base frame")
    ax.set_title(title or f"{Path(scene.source).stem}: top view")
    ax.grid(True, color="0.85", linewidth=0.5, zorder=0)
    # Outside the axes, so that it never covers the scene.
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8,
              frameon=False, borderaxespad=0.0)
    fig.savefig(out_path, format="png", dpi=DPI)
    return out_path


# --------------------------------------------------------------------------------------------
# Drawing
# --------------------------------------------------------------------------------------------


def _object_colour(scene: Scene, index: int) -> str:
    if index == scene.goal_index:
        return GOAL_COLOUR
    others = index - (index > scene.goal_index)
    return OBJECT_COLOURS[others % len(OBJECT_COLOURS)]


def _draw_scene(ax: Axes, scene: Scene, paths: np.ndarray, ee: np.ndarray,
                start_only: bool) -> list[Artist]:
    """Draw everything on `ax`; return the legend handles, objects first."""
    _draw_static(ax, scene)
    object_handles = _draw_objects(ax, scene, paths, start_only)
    _draw_tool(ax, ee, start_only)
    return object_handles + _style_handles(scene, len(ee) > 0, start_only)


def _draw_static(ax: Axes, scene: Scene) -> None:
    """Table, goal region, robot base and obstacles."""
    table = scene.table
    ax.add_patch(Rectangle(tuple(table.lower), *table.size, facecolor=TABLE_COLOUR,
                           edgecolor="0.55", linewidth=1.0, zorder=1))
    goal = scene.goal
    ax.add_patch(Circle(tuple(goal.position), goal.radius, facecolor=GOAL_REGION_FILL,
                        edgecolor=GOAL_COLOUR, linestyle=":", linewidth=1.0, zorder=2))
    ax.plot([0.0], [0.0], marker="P", markersize=10, color="black", linestyle="none", zorder=6)
    for obstacle in scene.obstacles:
        ax.add_patch(Polygon(object_outline(obstacle, obstacle.pose), closed=True,
                             facecolor=OBSTACLE_COLOUR, edgecolor="0.25", zorder=3))


def _draw_objects(ax: Axes, scene: Scene, paths: np.ndarray, start_only: bool) -> list[Artist]:
    """Objects at start (and end, with their centre paths); their legend handles."""
    object_handles: list[Artist] = []
    for i, obj in enumerate(scene.objects):
        colour = _object_colour(scene, i)
        start, end = paths[0, i], paths[-1, i]
        label = f"{obj.name} (goal object)" if i == scene.goal_index else obj.name
        object_handles.append(Patch(facecolor=colour, edgecolor="0.2", label=label))
        if start_only:
            _fill(ax, obj, start, colour)
            _label(ax, obj.name, start)
            continue
        ax.add_patch(Polygon(object_outline(obj, start), closed=True, fill=False,
                             edgecolor=colour, linestyle="--", linewidth=1.3, zorder=4))
        ax.plot(paths[:, i, 0], paths[:, i, 1], color=colour, linewidth=0.9, zorder=4)
        _fill(ax, obj, end, colour)
        _label(ax, obj.name, end)
    return object_handles


def _draw_tool(ax: Axes, ee: np.ndarray, start_only: bool) -> None:
    """The end effector at start (and its path and end)."""
    if len(ee):
        if start_only:
            ax.plot(ee[0, 0], ee[0, 1], marker="o", color=EE_COLOUR, linestyle="none", zorder=7)
        else:
            ax.plot(ee[:, 0], ee[:, 1], color=EE_COLOUR, linewidth=1.2, alpha=0.85, zorder=6)
            ax.plot(ee[0, 0], ee[0, 1], marker="o", color=EE_COLOUR, linestyle="none",
                    zorder=7)
            ax.plot(ee[-1, 0], ee[-1, 1], marker="s", markerfacecolor="white",
                    markeredgecolor=EE_COLOUR, markeredgewidth=1.5, linestyle="none", zorder=7)


def _style_handles(scene: Scene, has_tool: bool, start_only: bool) -> list[Artist]:
    """Legend entries for what is not an object."""
    goal = scene.goal
    style_handles: list[Artist] = [
        Patch(facecolor=TABLE_COLOUR, edgecolor="0.55", label="table"),
        Line2D([], [], marker="P", markersize=9, color="black", linestyle="none",
               label="robot base"),
        Patch(facecolor=GOAL_REGION_FILL, edgecolor=GOAL_COLOUR, linestyle=":",
              label=f"goal region (r = {goal.radius:.2f} m)"),
    ]
    if scene.obstacles:
        style_handles.append(Patch(facecolor=OBSTACLE_COLOUR, edgecolor="0.25",
                                   label="obstacle"))
    if start_only:
        style_handles.append(Patch(facecolor="0.6", edgecolor="0.2", label="object at start"))
        if has_tool:
            style_handles.append(Line2D([], [], marker="o", color=EE_COLOUR, linestyle="none",
                                        label="end effector at start"))
        return style_handles
    style_handles += [
        Patch(fill=False, edgecolor="0.3", linestyle="--", label="object at start"),
        Patch(facecolor="0.6", edgecolor="0.2", label="object at end"),
        Line2D([], [], color="0.3", linewidth=0.9, label="object centre path"),
    ]
    if has_tool:
        style_handles += [
            Line2D([], [], color=EE_COLOUR, linewidth=1.2, label="end-effector path"),
            Line2D([], [], marker="o", color=EE_COLOUR, linestyle="none",
                   label="end effector start"),
            Line2D([], [], marker="s", markerfacecolor="white", markeredgecolor=EE_COLOUR,
                   markeredgewidth=1.5, linestyle="none", label="end effector end"),
        ]
    return style_handles


def _draw_executed(ax: Axes, scene: Scene, executed: np.ndarray) -> list[Artist]:
    """The executed object paths and end poses, dotted, in the objects' colours."""
    for i, obj in enumerate(scene.objects):
        colour = _object_colour(scene, i)
        ax.plot(executed[:, i, 0], executed[:, i, 1], color=colour, linestyle=":",
                linewidth=1.4, zorder=6)
        ax.add_patch(Polygon(object_outline(obj, executed[-1, i]), closed=True, fill=False,
                             edgecolor=colour, linestyle=":", linewidth=1.6, zorder=6))
    return [Line2D([], [], color="0.3", linestyle=":", linewidth=1.4,
                   label="executed (MuJoCo): path, end")]


def _fill(ax: Axes, obj: MovableObject, pose: np.ndarray, colour: str) -> None:
    ax.add_patch(Polygon(object_outline(obj, pose), closed=True, facecolor=colour,
                         edgecolor="0.2", linewidth=0.8, alpha=0.9, zorder=5))


def _label(ax: Axes, name: str, pose: np.ndarray) -> None:
    ax.annotate(name, (pose[0], pose[1]), xytext=(6, 6), textcoords="offset points",
                fontsize=7, color="0.15", zorder=8)


def _limits(scene: Scene, paths: np.ndarray, ee: np.ndarray, axis: int) -> tuple[float, float]:
    """The range (m) along `axis` (0 = x, 1 = y) that holds the table, the robot base, the
    goal region, every object's footprint along its path and the end-effector path."""
    reach = max([o.footprint_radius for o in scene.objects], default=0.0)
    values = [scene.table.lower[axis], scene.table.upper[axis], 0.0,
              scene.goal.position[axis] - scene.goal.radius,
              scene.goal.position[axis] + scene.goal.radius,
              paths[..., axis].min() - reach, paths[..., axis].max() + reach]
    for obstacle in scene.obstacles:
        values += [obstacle.pose[axis] - obstacle.footprint_radius,
                   obstacle.pose[axis] + obstacle.footprint_radius]
    if len(ee):
        values += [ee[:, axis].min(), ee[:, axis].max()]
    return float(min(values)) - MARGIN, float(max(values)) + MARGIN


# --------------------------------------------------------------------------------------------
# Input checks
# --------------------------------------------------------------------------------------------


def _checked_object_paths(scene: Scene, object_paths: np.ndarray) -> np.ndarray:
    m = len(scene.objects)
    expected = f"expected shape (T, {m}, 3): T >= 1 poses (x, y, yaw) of the scene's {m} " \
               f"objects {list(scene.object_names)}"
    try:
        paths = np.asarray(object_paths, dtype=float)
    except (TypeError, ValueError):
        raise PlotError(f"object_paths: {expected}; got a non-numeric array") from None
    if paths.ndim != 3 or paths.shape[0] < 1 or paths.shape[1:] != (m, 3):
        raise PlotError(f"object_paths: {expected}; got shape {paths.shape}")
    if not np.all(np.isfinite(paths)):
        raise PlotError("object_paths: every pose must be finite; got a NaN or infinite entry")
    return paths


def _checked_ee_path(ee_path: np.ndarray) -> np.ndarray:
    expected = "expected shape (N, 2): end-effector (x, y) in m along the plan"
    try:
        ee = np.asarray(ee_path, dtype=float)
    except (TypeError, ValueError):
        raise PlotError(f"ee_path: {expected}; got a non-numeric array") from None
    if ee.ndim != 2 or ee.shape[1] != 2:
        raise PlotError(f"ee_path: {expected}; got shape {ee.shape}")
    if not np.all(np.isfinite(ee)):
        raise PlotError("ee_path: every point must be finite; got a NaN or infinite entry")
    return ee
