"""The planner's contact shapes against the Panda's real collision geometry:
the capsules of config/robots/panda.yaml were fitted to the collision meshes and finger boxes of
example-robot-data (the ones the MuJoCo check executes with). These tests keep them fitted:
every link's mesh inside the shapes (clearance from the table and obstacles is real), the hand
and finger pads close to their real size (contact is planned with them), the pads reaching as
far as the real ones."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from rearrangement_planner.planning.machinery.manifold import ik_on_manifold, lowest_point
from rearrangement_planner.world3d.mujoco_model import arm_model

LINKS = [f"panda_link{i}" for i in range(1, 6)]
"""Covered within 1.5 mm. The wrist (link6, link7) is box- and disc-like: capsules that covered
its corners would sit 3 cm below its flat underside in the pushing posture, so its corners are
left out by up to 12 mm, like the hand's (`test_planned_pushing_postures_...` checks that
what faces the table is covered)."""
WRIST = ("panda_link6", "panda_link7")


@pytest.fixture(scope="module")
def real(panda):
    """The arm model and, per body, its collision geometry as points in the body frame:
    mesh vertices plus points spread over the mesh faces, box corners."""
    model = arm_model(panda)
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    rng = np.random.default_rng(0)
    points: dict[str, list[np.ndarray]] = {}
    for g in range(model.ngeom):
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
            mesh = model.geom_dataid[g]
            start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
            verts = model.mesh_vert[start:start + count]
            faces = model.mesh_face[model.mesh_faceadr[mesh]:
                                    model.mesh_faceadr[mesh] + model.mesh_facenum[mesh]]
            weights = rng.dirichlet([1.0, 1.0, 1.0], size=(len(faces), 4))
            local = np.vstack([verts, np.einsum("fkj,fjd->fkd", weights, verts[faces])
                               .reshape(-1, 3)])
        elif model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
            local = signs * model.geom_size[g]
        else:
            continue
        body = model.geom_bodyid[g]
        world = local @ data.geom_xmat[g].reshape(3, 3).T + data.geom_xpos[g]
        in_body = (world - data.xpos[body]) @ data.xmat[body].reshape(3, 3)
        points.setdefault(model.body(body).name, []).append(in_body)
    return model, {name: np.vstack(p) for name, p in points.items()}


def _outside(robot, q, link_points, link):
    """Signed distance (m) of each point, on `link` at q, outside the union of all shapes."""
    frame = robot.frame_pose(q, link)
    world = link_points @ frame[:3, :3].T + frame[:3, 3]
    best = np.full(len(world), np.inf)
    for shape, pose in zip(robot.contact_shapes, robot.shape_poses(q), strict=True):
        assert shape.kind == "capsule"
        radius, length = shape.dims
        a = pose[:3, 3] - 0.5 * length * pose[:3, 2]
        t = np.clip((world - a) @ pose[:3, 2], 0.0, length)
        gap = np.linalg.norm(world - (a + t[:, None] * pose[:3, 2]), axis=1) - radius
        best = np.minimum(best, gap)
    return best


def test_the_arm_links_are_inside_their_contact_shapes(panda, real):
    _, points = real
    rng = np.random.default_rng(1)
    for q in [panda.home] + [rng.uniform(panda.lower, panda.upper) for _ in range(10)]:
        for link in LINKS + list(WRIST):
            worst = _outside(panda, q, points[link], link).max()
            bound = 0.012 if link in WRIST else 0.0015
            assert worst < bound, f"{link} sticks out of the contact shapes by {worst:.4f} m"


def test_the_hand_and_finger_pads_are_shaped_like_the_real_ones(panda, real):
    model, points = real
    q = panda.home
    # Rounded capsule ends leave the box-like corners out by about a centimetre ...
    worst = _outside(panda, q, _hand_frame_points(model, points), "panda_hand").max()
    assert worst < 0.012, worst
    # ... and the finger pads reach as far past the tool point as the real ones (9.6 mm).
    assert panda.tool_reach == pytest.approx(0.1129 - 0.1034, abs=0.001)
    # Nor are they bigger: the hand's shapes span the real hand and pads' extent within 2 mm
    # on every side but the back (hand z < 0, inside the flange), 7 mm.
    hand = [i for i, c in enumerate(panda.contact_shapes) if c.link == "panda_hand"]
    to_hand = np.linalg.inv(panda.frame_pose(q, "panda_hand"))
    ends = []
    for i in hand:
        pose, (radius, length) = to_hand @ panda.shape_poses(q)[i], panda.contact_shapes[i].dims
        for sign in (-0.5, 0.5):
            ends.append(pose[:3, 3] + sign * length * pose[:3, 2] - radius)
            ends.append(pose[:3, 3] + sign * length * pose[:3, 2] + radius)
    model, _ = real
    real_hand = _hand_frame_points(model, points)
    low, high = np.min(ends, axis=0), np.max(ends, axis=0)
    assert np.all(high - real_hand.max(axis=0) < 0.002), high - real_hand.max(axis=0)
    assert np.all((real_hand.min(axis=0) - low) < [0.002, 0.002, 0.008])


def test_planned_pushing_postures_clear_the_table_as_the_real_arm_does(panda, real):
    """On the pushing manifold the shapes' lowest point is at most 1 cm below the real meshes'
    lowest point (the clearance the planner keeps is real, and not much more than real)."""
    model, _ = real
    data = mujoco.MjData(model)
    qadr = [model.joint(n).qposadr[0] for n in panda.joint_names]
    rng = np.random.default_rng(0)
    checked = 0
    for x, y, yaw in [(0.5, 0.0, 0.0), (0.4, 0.2, 1.0), (0.65, -0.2, -0.5), (0.45, 0.3, 1.57)]:
        q = ik_on_manifold(panda, x, y, yaw, 0.0, panda.home, rng=rng, restarts=5)
        assert q is not None
        data.qpos[qadr] = q
        mujoco.mj_kinematics(model, data)
        real_lowest = min(float(data.geom_xpos[g][2]) - _half_height(model, data, g)
                          for g in range(model.ngeom)
                          if model.body(model.geom_bodyid[g]).name not in ("world", "panda_link0"))
        planned = lowest_point(panda, q)[0]
        assert real_lowest - 0.01 <= planned <= real_lowest, (planned, real_lowest)
        checked += 1
    assert checked == 4


def _half_height(model, data, g) -> float:
    """How far geom g reaches below its centre (mesh: its vertices; box: its corners)."""
    rot = data.geom_xmat[g].reshape(3, 3)
    if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH:
        mesh = model.geom_dataid[g]
        verts = model.mesh_vert[model.mesh_vertadr[mesh]:
                                model.mesh_vertadr[mesh] + model.mesh_vertnum[mesh]]
        return float(-(verts @ rot.T)[:, 2].min())
    return float(np.abs(rot[2]) @ model.geom_size[g])


def _hand_frame_points(model, points):
    """The hand's and the closed fingers' points, in the hand frame (at q = 0: the fingers
    are rigidly closed on the hand in both models)."""
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    hand = model.body("panda_hand").id
    out = [points["panda_hand"]]
    for finger in ("panda_leftfinger", "panda_rightfinger"):
        b = model.body(finger).id
        world = points[finger] @ data.xmat[b].reshape(3, 3).T + data.xpos[b]
        out.append((world - data.xpos[hand]) @ data.xmat[hand].reshape(3, 3))
    return np.vstack(out)
