"""The top-view PNG of docs/design.md (`--plot OUT.png`): it is written at the documented size, the
footprint polygons it draws are exact, and arrays of the wrong shape are rejected naming the
argument."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.image import imread

from rearrangement_planner.io.plot import (
    DPI,
    FIGURE_SIZE,
    GOAL_COLOUR,
    PlotError,
    object_outline,
    plot_top_view,
)
from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.scene import MovableObject, Obstacle

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
WIDTH_PX, HEIGHT_PX = round(FIGURE_SIZE[0] * DPI), round(FIGURE_SIZE[1] * DPI)


def straight_plan(scene, steps: int = 15) -> tuple[np.ndarray, np.ndarray]:
    """Object paths (T, M, 3) pushing the goal object straight to the goal point, the others
    standing still, and an end-effector path (N, 2) that follows behind it."""
    start = scene.object_poses
    end = start.copy()
    end[scene.goal_index, :2] = scene.goal.position
    t = np.linspace(0.0, 1.0, steps)[:, None, None]
    paths = start + t * (end - start)
    behind = paths[:, scene.goal_index, :2] + np.array([-0.05, 0.05])
    ee = np.vstack([[0.3, 0.3], behind])
    return paths, ee


def polygon_area(p: np.ndarray) -> float:
    """Signed area (shoelace formula); > 0 for a counter-clockwise polygon."""
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def assert_png(path, width: int, height: int) -> np.ndarray:
    assert path.is_file()
    data = path.read_bytes()
    assert len(data) > 1000
    assert data.startswith(PNG_SIGNATURE)
    image = imread(path)
    assert image.shape[:2] == (height, width)
    return image


# --------------------------------------------------------------------------------------------
# The PNG
# --------------------------------------------------------------------------------------------


def test_plot_writes_png_of_documented_size(default_scene, tmp_path):
    paths, ee = straight_plan(default_scene)
    out = plot_top_view(default_scene, paths, ee, tmp_path / "plan.png", title="straight push")
    assert out == tmp_path / "plan.png"
    image = assert_png(out, WIDTH_PX, HEIGHT_PX)
    # The goal object is drawn filled in its own colour (alpha 0.9 over the table).
    rgb = image[..., :3]
    goal = np.array(to_rgb(GOAL_COLOUR))
    assert np.count_nonzero(np.linalg.norm(rgb - goal, axis=-1) < 0.12) > 50


def test_plot_start_states_only_and_str_path(default_scene, tmp_path):
    paths, ee = straight_plan(default_scene)
    out = plot_top_view(default_scene, paths[:1], ee[:1], str(tmp_path / "start.png"),
                        start_states_only=True)
    assert_png(out, WIDTH_PX, HEIGHT_PX)


def test_plot_accepts_an_empty_ee_path(default_scene, tmp_path):
    paths, _ = straight_plan(default_scene)
    out = plot_top_view(default_scene, paths, np.empty((0, 2)), tmp_path / "no_ee.png")
    assert_png(out, WIDTH_PX, HEIGHT_PX)


def test_plotting_leaves_pyplot_unloaded(tmp_path):
    """No global matplotlib state changes: pyplot (and so its backend) is never loaded."""
    code = ("import sys; import numpy as np; "
            "from rearrangement_planner.physics.validation import load_scene; "
            "from rearrangement_planner.io.plot import plot_top_view; "
            "s = load_scene('easy_push'); "
            "plot_top_view(s, s.object_poses[None], np.zeros((1, 2)), sys.argv[1]); "
            "assert 'matplotlib.pyplot' not in sys.modules, 'pyplot was imported'")
    subprocess.run([sys.executable, "-c", code, str(tmp_path / "p.png")], check=True)


# --------------------------------------------------------------------------------------------
# Outlines
# --------------------------------------------------------------------------------------------


def test_box_outline_rotated_by_90_degrees_swaps_extents():
    box = MovableObject.box("b", [0.06, 0.08, 0.12], [0.0, 0.0, 0.0])
    outline = object_outline(box, np.array([0.5, -0.1, math.pi / 2]))
    assert outline.shape == (4, 2)
    np.testing.assert_allclose(outline.min(axis=0), [0.5 - 0.04, -0.1 - 0.03], atol=1e-12)
    np.testing.assert_allclose(outline.max(axis=0), [0.5 + 0.04, -0.1 + 0.03], atol=1e-12)


def test_box_outline_is_the_rotated_rectangle_for_random_poses():
    rng = np.random.default_rng(7)
    for _ in range(50):
        size = rng.uniform(0.02, 0.2, 3)
        pose = np.array([*rng.uniform(-1.0, 1.0, 2), rng.uniform(-math.pi, math.pi)])
        outline = object_outline(MovableObject.box("b", size, pose), pose)
        np.testing.assert_allclose(outline.mean(axis=0), pose[:2], atol=1e-12)
        sides = np.linalg.norm(np.roll(outline, -1, axis=0) - outline, axis=1)
        np.testing.assert_allclose(sides, [size[0], size[1], size[0], size[1]], atol=1e-12)
        assert polygon_area(outline) == pytest.approx(size[0] * size[1], rel=1e-9)
        # The first edge (corner +x+y to -x+y) runs along -x of the object frame.
        edge = outline[1] - outline[0]
        assert math.atan2(-edge[1], -edge[0]) == pytest.approx(pose[2], abs=1e-9)


def test_obstacle_outline_is_a_box():
    post = Obstacle("post", np.array([0.05, 0.10, 0.3]), np.array([0.8, 0.35, 0.0]))
    outline = object_outline(post, post.pose)
    np.testing.assert_allclose(outline.max(axis=0) - outline.min(axis=0), [0.05, 0.10])


@pytest.mark.parametrize("yaw", [0.0, 1.2, -2.5])
def test_cylinder_outline_is_a_circle_of_its_radius(yaw):
    can = MovableObject.cylinder("can", 0.035, 0.12, [0.0, 0.0, 0.0])
    outline = object_outline(can, np.array([0.62, 0.05, yaw]))
    assert outline.shape[0] >= 32
    np.testing.assert_allclose(np.linalg.norm(outline - [0.62, 0.05], axis=1), 0.035,
                               atol=1e-12)
    assert polygon_area(outline) > 0.0   # counter-clockwise
    assert polygon_area(outline) == pytest.approx(math.pi * 0.035 ** 2, rel=0.01)


# --------------------------------------------------------------------------------------------
# Input checks
# --------------------------------------------------------------------------------------------


def _bad_inputs(scene):
    paths, ee = straight_plan(scene)
    m = len(scene.objects)
    nan_paths = paths.copy()
    nan_paths[3, 0, 1] = np.nan
    return {
        "paths 2-D": (paths[0], ee, "object_paths", r"\(T, 3, 3\).*\(3, 3\)"),
        "paths missing object": (paths[:, : m - 1], ee, "object_paths", r"\(15, 2, 3\)"),
        "paths xy only": (paths[..., :2], ee, "object_paths", r"\(15, 3, 2\)"),
        "paths empty": (paths[:0], ee, "object_paths", r"\(0, 3, 3\)"),
        "paths NaN": (nan_paths, ee, "object_paths", "finite"),
        "ee xyz": (paths, np.zeros((4, 3)), "ee_path", r"\(N, 2\).*\(4, 3\)"),
        "ee 1-D": (paths, np.zeros(4), "ee_path", r"\(4,\)"),
        "ee inf": (paths, np.array([[0.1, np.inf]]), "ee_path", "finite"),
    }


@pytest.mark.parametrize("case", ["paths 2-D", "paths missing object", "paths xy only",
                                  "paths empty", "paths NaN", "ee xyz", "ee 1-D", "ee inf"])
def test_wrong_shapes_raise_naming_the_argument(default_scene, tmp_path, case):
    object_paths, ee_path, argument, detail = _bad_inputs(default_scene)[case]
    out = tmp_path / "bad.png"
    with pytest.raises(ValueError, match=rf"^{argument}: ") as info:
        plot_top_view(default_scene, object_paths, ee_path, out)
    assert isinstance(info.value, PlotError)
    assert isinstance(info.value, RearrangementError)
    assert info.match(detail)
    assert not out.exists()
