"""`rearrangement-robot fit`: robot configs from URDFs alone (tools/robot_fit.py), on the Panda
(against the shipped, hand-checked config), the xArm7 and the Kinova arm of example-robot-data."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from rearrangement_planner.model.files import resolve_uri
from rearrangement_planner.model.robot import RobotConfig, RobotModel
from rearrangement_planner.tools import robot_fit
from rearrangement_planner.tools.robot_fit import (
    COVER_TOLERANCE,
    Capsule,
    FitError,
    capsules_per_link,
    config_dict,
    fit_capsule,
    read_arm,
    volume_inside,
)

PANDA = "package://example-robot-data/robots/panda_description/urdf/panda.urdf"
XARM = "package://example-robot-data/robots/xarm_description/urdf/xarm7.urdf"
KINOVA = "package://example-robot-data/robots/kinova_description/robots/kinova.urdf"


def _capsules(config: dict, link: str) -> list[Capsule]:
    return [Capsule(np.array(s["points"][0], float), np.array(s["points"][1], float),
                    float(s["radius"])) for s in config["contact_shapes"] if s["link"] == link]


def _outside(capsules: list[Capsule], points: np.ndarray) -> float:
    return float(np.min(np.stack([c.distance(points) for c in capsules]), axis=0).max())


def test_a_capsule_covers_its_points_and_fits_a_cylinder_tightly():
    rng = np.random.default_rng(0)
    # points of a cylinder of radius 0.05, from z = -0.1 to 0.1, turned and moved
    angle = rng.uniform(0, 2 * np.pi, 2000)
    z = rng.uniform(-0.1, 0.1, 2000)
    points = np.stack([0.05 * np.cos(angle), 0.05 * np.sin(angle), z], axis=1)
    turn = np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]], float)
    points = points @ turn.T + [0.3, -0.2, 0.1]
    capsule = fit_capsule(points)
    assert _outside([capsule], points) <= COVER_TOLERANCE
    # no larger than the obvious cover: radius 0.05 along the axis from end to end
    obvious = Capsule(np.array([0.2, -0.2, 0.1]), np.array([0.4, -0.2, 0.1]), 0.05)
    assert 0.05 <= capsule.radius <= 0.06 and capsule.volume <= obvious.volume * 1.001
    axis = (capsule.b - capsule.a) / np.linalg.norm(capsule.b - capsule.a)
    assert abs(axis @ [1, 0, 0]) > 0.999                           # along the cylinder


def test_an_l_shaped_link_gets_two_capsules_that_cover_it():
    rng = np.random.default_rng(1)
    arm_a = np.stack([rng.uniform(0, 0.3, 500), rng.normal(0, 0.01, 500),
                      rng.normal(0, 0.01, 500)], axis=1)
    arm_b = np.stack([rng.normal(0.3, 0.01, 500), rng.uniform(0, 0.3, 500),
                      rng.normal(0, 0.01, 500)], axis=1)
    points = np.concatenate([arm_a, arm_b])
    one = robot_fit.fit_capsules(points, 1)
    two = robot_fit.fit_capsules(points, 3)
    assert len(two) >= 2 and sum(c.volume for c in two) < 0.5 * one[0].volume
    assert _outside(two, points) <= COVER_TOLERANCE


@pytest.fixture(scope="module")
def panda_fit():
    arm = read_arm(resolve_uri(PANDA))
    return arm, config_dict(arm, PANDA, capsules_per_link(arm, 3))


def test_the_panda_refit_finds_its_chain_frames_and_covers_every_vertex(panda_fit):
    arm, config = panda_fit
    assert arm.joints == tuple(f"panda_joint{i}" for i in range(1, 8))
    assert (arm.base_frame, arm.tool_frame) == ("panda_link0", "panda_hand_tcp")
    # the fingers (prismatic joints) are fitted, closed, to the hand that carries them
    assert "panda_leftfinger" not in arm.points and any("panda_leftfinger" in n
                                                        for n in arm.notes)
    for link, points in arm.points.items():
        assert _outside(_capsules(config, link), points) <= COVER_TOLERANCE, link
    RobotModel(RobotConfig.from_dict(config))                     # a config the planner loads


def test_the_panda_refit_is_close_to_the_shipped_config_on_the_arm_links(panda_fit):
    """On links 1-5, which the shipped capsules cover within 1.5 mm too, most of the fitted
    volume lies inside the shipped capsules: the fit is the tighter cover. (The shipped config
    leaves the wrist's and hand's corners out on purpose, so those differ more.)"""
    _, config = panda_fit
    shipped = yaml.safe_load((resolve_uri("config/robots/panda.yaml")).read_text())
    for i in range(1, 6):
        link = f"panda_link{i}"
        share = volume_inside(_capsules(config, link), _capsules(shipped, link), 40_000)
        assert share > 0.7, (link, share)


def test_the_xarm7_fits_and_its_posture_search_reaches_the_workspace():
    arm = read_arm(resolve_uri(XARM), name="xarm7")
    assert arm.joints == tuple(f"joint{i}" for i in range(1, 8))
    assert arm.tool_frame == "link_eef"
    capsules = capsules_per_link(arm, 3)
    for link, points in arm.points.items():
        assert _outside(capsules[link], points) <= COVER_TOLERANCE, link
    config = config_dict(arm, XARM, capsules)
    # a corner of the search's grid (the whole grid, 40 postures, takes 20 s): the shipped
    # config's posture, 7 cm with roll pi/2, reaches every target, and 3 cm is too low
    heights, rolls = (0.03, 0.07), (0.0, math.pi / 2)
    (height, roll, pitch), share = robot_fit.search_posture(config, resolve_uri(XARM).parent,
                                                            heights, rolls)
    assert (height, roll, pitch, share) == (0.07, pytest.approx(math.pi / 2),
                                            pytest.approx(math.pi / 2), 1.0)
    shipped = RobotConfig.from_yaml(resolve_uri("config/robots/xarm7.yaml")).push_posture
    assert (shipped.height, shipped.roll) == (0.07, pytest.approx(math.pi / 2))


@pytest.mark.parametrize("urdf, link, plain_past", [(XARM, "link7", 0.02),
                                                     (PANDA, "panda_hand", 0.005)])
def test_the_tools_face_is_kept_flat(urdf, link, plain_past):
    """The capsules of the link that pushes reach at most FACE_TOLERANCE past its real front
    face along the tool axis (a plain fit's round caps reached 2.6 cm past the xArm's flange,
    and its pushes fell short in MuJoCo), and still cover every vertex."""
    arm = read_arm(resolve_uri(urdf))
    assert set(arm.tool_in_link) == {link}
    tool = arm.tool_in_link[link]
    capsules, past = robot_fit.fit_tool_link(arm.points[link], tool, 3)
    assert past <= robot_fit.FACE_TOLERANCE
    front = float(((arm.points[link] - tool[:3, 3]) @ tool[:3, :3])[:, 2].max())
    plain = robot_fit.fit_capsules(arm.points[link], 3)
    assert robot_fit._front(plain, tool[:3, :3], tool[:3, 3]) - front > max(plain_past, past)
    assert _outside(capsules, arm.points[link]) <= COVER_TOLERANCE


def test_what_the_urdf_leaves_undecided_is_a_clear_error():
    with pytest.raises(FitError, match=r"--joints: .*continuous joints"):
        read_arm(resolve_uri(KINOVA))                             # a 6-DOF Jaco2
    with pytest.raises(FitError, match=r"--joints: no joint 'elbow'"):
        read_arm(resolve_uri(XARM), joints=["joint1", "joint2", "joint3", "elbow", "joint5",
                                            "joint6", "joint7"])
    with pytest.raises(FitError, match=r"--joints: joint2 does not follow joint3"):
        read_arm(resolve_uri(XARM), joints=["joint1", "joint3", "joint2", "joint4", "joint5",
                                            "joint6", "joint7"])
    with pytest.raises(FitError, match="--tool-frame: no frame 'flange'"):
        read_arm(resolve_uri(XARM), tool_frame="flange")


def test_the_command_writes_a_config_that_loads(tmp_path, capsys):
    out = tmp_path / "xarm7.yaml"
    assert robot_fit.main(["fit", XARM, "--name", "xarm7", "--no-posture-search",
                           "--max-capsules", "1", "--out", str(out)]) == 0
    config = RobotConfig.from_yaml(out)
    assert config.urdf_path == resolve_uri(XARM) and config.name == "xarm7"
    assert "tool frame link_eef" in capsys.readouterr().err
    assert robot_fit.main(["fit", str(tmp_path / "none.urdf")]) == 2
    assert "rearrangement-robot: URDF: " in capsys.readouterr().err


def test_the_enclosing_circle_looks_at_the_hull_corners_only():
    """The iteration steps towards the farthest point, always a corner of the convex hull: the
    same centre as over every point, and collinear or repeated points (no hull) still work."""
    def over_all(xy, iterations=400):
        centre = xy.mean(axis=0)
        for i in range(iterations):
            far = xy[np.argmax(np.sum((xy - centre) ** 2, axis=1))]
            centre = centre + (far - centre) / (i + 2)
        return centre

    rng = np.random.default_rng(4)
    cloud = rng.normal(size=(500, 2)) * (0.03, 0.01)
    np.testing.assert_allclose(robot_fit._enclosing_circle(cloud), over_all(cloud), atol=1e-15)
    line = np.outer(np.linspace(0.0, 0.1, 50), (1.0, 2.0))
    np.testing.assert_allclose(robot_fit._enclosing_circle(line), (0.05, 0.1), atol=1e-3)
    np.testing.assert_allclose(robot_fit._enclosing_circle(np.zeros((6, 2))), (0.0, 0.0))
