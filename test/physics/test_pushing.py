"""Tests for the quasistatic pushing model (rearrangement_planner/pushing.py; docs/design.md).

Property tests draw random contacts from one fixed-seed generator each and check the laws of
the model against closed forms recomputed here by a different route (wrench -> A -> twist).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate, linalg, optimize

from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.physics.pushing import (
    PushingError,
    apply_twist,
    build_contact_lcp,
    lemke,
    limit_surface_c,
    multi_contact_twist,
    object_twist,
    points_to_object_frame,
    rectangle_mean_distance,
    single_contact_twist,
    vectors_to_object_frame,
)

# ---------------------------------------------------------------------------------------------
# Reference model, written independently of the module: forces -> wrench -> A -> twist.
# ---------------------------------------------------------------------------------------------


def wrench_at(point: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Wrench (f_x, f_y, m) at the object origin of a force applied at `point`."""
    return np.array([force[0], force[1], point[0] * force[1] - point[1] * force[0]])


def twist_of_wrench(c: float, wrench: np.ndarray) -> np.ndarray:
    """Ellipsoidal limit surface: V = A F, A = diag(1, 1, 1/c^2)."""
    return np.diag([1.0, 1.0, 1.0 / c**2]) @ wrench


def velocity_at(point: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """Velocity of the object-frame `point` under `twist`: v + omega x p."""
    return np.array([twist[0] - twist[2] * point[1], twist[1] + twist[2] * point[0]])


def stick_formula(c: float, p: np.ndarray, v: np.ndarray) -> np.ndarray:
    """docs/design.md closed form (Lynch, Maekawa & Tanie 1992), typed in again."""
    x, y = p
    den = c**2 + x**2 + y**2
    vx = ((c**2 + x**2) * v[0] + x * y * v[1]) / den
    vy = (x * y * v[0] + (c**2 + y**2) * v[1]) / den
    return np.array([vx, vy, (x * vy - y * vx) / c**2])


def cone_edges(c: float, p: np.ndarray, n: np.ndarray, mu: float):
    """Friction-cone edge forces and the contact-point velocities they cause (motion cone)."""
    t = np.array([-n[1], n[0]])
    forces = {"left": n + mu * t, "right": n - mu * t}
    return {k: (f, velocity_at(p, twist_of_wrench(c, wrench_at(p, f)))) for k, f in forces.items()}


def lcp_residuals(c, points, normals, disps, mu, res):
    """Check the multi-contact solution's physics directly: no penetration, unloaded or
    touching, Coulomb, and the twist being A times the contact wrench."""
    wrench = np.zeros(3)
    for p, n, v, fn, ft in zip(points, normals, disps, res.normal_forces,
                               res.tangential_forces, strict=True):
        t = np.array([-n[1], n[0]])
        u = velocity_at(p, res.twist) - v
        assert u @ n >= -1e-9                                    # no penetration
        assert fn >= 0 and abs(fn * (u @ n)) < 1e-9              # loaded only if touching
        assert abs(ft) <= mu * fn + 1e-9                         # in the friction cone
        if abs(u @ t) > 1e-9:                                    # sliding: on the edge,
            assert ft == pytest.approx(-mu * fn * np.sign(u @ t), abs=1e-9)  # opposing slip
        wrench += wrench_at(p, fn * n + ft * t)
    np.testing.assert_allclose(res.twist, twist_of_wrench(c, wrench), atol=1e-9)


def random_contact(rng: np.random.Generator):
    c = rng.uniform(0.2, 2.0)
    p = rng.uniform(-1.5, 1.5, 2)
    a = rng.uniform(-np.pi, np.pi)
    n = np.array([math.cos(a), math.sin(a)])
    v = rng.uniform(-1.0, 1.0, 2)
    mu = rng.choice([0.0, rng.uniform(0.0, 1.5)])
    return c, p, n, v, float(mu)


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    return abs(math.atan2(a[0] * b[1] - a[1] * b[0], a @ b))


# ---------------------------------------------------------------------------------------------
# 1. Limit surface
# ---------------------------------------------------------------------------------------------


def test_disk_c_is_two_thirds_radius():
    for r in (0.01, 0.035, 1.0):
        assert limit_surface_c("disk", r) == pytest.approx(2 * r / 3, rel=1e-15)
        assert limit_surface_c("cylinder", [r, 0.12]) == pytest.approx(2 * r / 3, rel=1e-15)


def test_rectangle_c_matches_numerical_integration():
    for sx, sy in [(0.06, 0.08), (1.0, 1.0), (0.3, 0.02), (2.0, 0.5)]:
        a, b = sx / 2, sy / 2
        quarter, _ = integrate.dblquad(lambda y, x: math.hypot(x, y), 0, a, 0, b,
                                       epsabs=1e-14, epsrel=1e-11)
        numeric = quarter / (a * b)                  # by symmetry: (4 x quarter) / (4ab)
        assert limit_surface_c("box", (sx, sy, 0.1)) == pytest.approx(numeric, abs=1e-6 * sx)
        assert rectangle_mean_distance(a, b) == pytest.approx(numeric, rel=1e-9)


def test_square_c_known_value_and_linear_scaling():
    # mean distance from the centre of a unit square: (sqrt(2) + ln(1 + sqrt(2))) / 6 = 0.38259...
    assert limit_surface_c("box", (1.0, 1.0)) == pytest.approx(0.3825978582, abs=1e-10)
    base_box, base_disk = limit_surface_c("box", (0.06, 0.08)), limit_surface_c("disk", 0.035)
    for k in (0.5, 2.0, 10.0):
        assert limit_surface_c("box", (0.06 * k, 0.08 * k)) == pytest.approx(k * base_box)
        assert limit_surface_c("disk", 0.035 * k) == pytest.approx(k * base_disk)
    # c is a length of the order of the footprint (metres), not its inverse.
    assert 0.02 < base_box < 0.05


def test_limit_surface_rejects_bad_input():
    with pytest.raises(PushingError, match="unknown shape 'sphere'"):
        limit_surface_c("sphere", 0.1)
    with pytest.raises(RearrangementError, match="positive"):
        limit_surface_c("box", (0.1, -0.2))
    with pytest.raises(PushingError, match="radius"):
        limit_surface_c("disk", 0.0)


# ---------------------------------------------------------------------------------------------
# 2. One contact: motion cone
# ---------------------------------------------------------------------------------------------


def test_single_contact_matches_closed_forms_property():
    rng = np.random.default_rng(20240611)
    seen = {"separating": 0, "sticking": 0, "sliding": 0}
    for _ in range(400):
        c, p, n, v, mu = random_contact(rng)
        res = single_contact_twist(c, p, n, v, mu)
        seen[res.mode] += 1
        if v @ n <= 0:
            assert res.mode == "separating"
            np.testing.assert_array_equal(res.twist, 0.0)
            continue
        edges = cone_edges(c, p, n, mu)
        v_l, v_r = edges["left"][1], edges["right"][1]
        if mu > 0:                                   # v = alpha v_l + beta v_r, both >= 0
            alpha, beta = np.linalg.solve(np.column_stack([v_l, v_r]), v)
            inside = alpha >= -1e-12 and beta >= -1e-12
        else:                                        # degenerate cone: a ray, never hit here
            inside = False
        if inside:
            assert res.mode == "sticking"
            np.testing.assert_allclose(res.twist, stick_formula(c, p, v), atol=1e-9)
            np.testing.assert_allclose(velocity_at(p, res.twist), v, atol=1e-9)
        else:
            assert res.mode == "sliding"
            # The nearer motion-cone edge (by angle), among those pointing into the object.
            usable = {k: e for k, e in edges.items() if e[1] @ n > 0}
            name = min(usable, key=lambda k: angle_between(usable[k][1], v))
            f_e, v_e = usable[name]
            expected = twist_of_wrench(c, wrench_at(p, f_e)) * (v @ n) / (v_e @ n)
            np.testing.assert_allclose(res.twist, expected, atol=1e-9)
            # ... and the design's formula applied to the scaled edge velocity agrees.
            np.testing.assert_allclose(res.twist, stick_formula(c, p, v_e * (v @ n) / (v_e @ n)),
                                       atol=1e-9)
            # Coulomb + max dissipation: force on the cone edge, friction along the slip.
            t = np.array([-n[1], n[0]])
            f = res.twist[:2]
            slip = (v - velocity_at(p, res.twist)) @ t
            assert abs(abs(f @ t) - mu * (f @ n)) < 1e-9
            assert slip * (f @ t) > 0 or (mu == 0 and abs(f @ t) < 1e-12)
            assert velocity_at(p, res.twist) @ n == pytest.approx(v @ n, abs=1e-9)
        # Forces reported are the contact force in LCP units (V = A F).
        assert res.normal_forces[0] == pytest.approx(res.twist[:2] @ n, abs=1e-12)
        assert res.normal_forces[0] > 0
    assert min(seen.values()) > 25, seen


def test_push_through_centre_translates():
    c = limit_surface_c("box", (0.2, 0.1))
    for mu in (0.0, 0.3):
        res = single_contact_twist(c, (-0.1, 0.0), (1.0, 0.0), (0.01, 0.0), mu)
        assert res.mode == "sticking"
        np.testing.assert_allclose(res.twist, [0.01, 0.0, 0.0], atol=1e-15)
    # Along the normal through the centre of a disk, from any side.
    for a in np.linspace(-np.pi, np.pi, 7):
        n = np.array([math.cos(a), math.sin(a)])
        res = single_contact_twist(0.02, -0.03 * n, n, 0.005 * n, 0.2)
        np.testing.assert_allclose(res.twist, [*(0.005 * n), 0.0], atol=1e-15)


def test_off_centre_push_rotates_by_moment_arm():
    c = limit_surface_c("box", (0.2, 0.2))
    # Pushing +x on the -x face above the centre: moment x f_y - y f_x < 0 -> clockwise.
    above = single_contact_twist(c, (-0.1, 0.05), (1.0, 0.0), (0.01, 0.0), 0.5)
    below = single_contact_twist(c, (-0.1, -0.05), (1.0, 0.0), (0.01, 0.0), 0.5)
    assert above.twist[2] < 0 < below.twist[2]
    assert above.twist[2] == pytest.approx(-below.twist[2])
    # omega = m / c^2 for the force f = (v_x, v_y): the limit-surface ratio.
    w = wrench_at(np.array([-0.1, 0.05]), above.twist[:2])
    assert above.twist[2] == pytest.approx(w[2] / c**2, rel=1e-12)
    # A farther-off push turns the object faster and moves it less.
    farther = single_contact_twist(c, (-0.1, 0.09), (1.0, 0.0), (0.01, 0.0), 0.5)
    assert farther.twist[2] < above.twist[2] and farther.twist[0] < above.twist[0]


def test_push_outside_friction_cone_slides():
    c = limit_surface_c("box", (0.2, 0.2))
    p, n, v = np.array([-0.1, 0.0]), np.array([1.0, 0.0]), np.array([0.01, 0.01])  # 45 deg
    res = single_contact_twist(c, p, n, v, 0.2)
    assert res.mode == "sliding"
    v_obj = velocity_at(p, res.twist)
    assert v_obj[0] == pytest.approx(v[0], abs=1e-15)                 # normal components match
    assert abs(v_obj[1] - v[1]) > 1e-3                               # tangential ones do not
    assert res.tangential_forces[0] == pytest.approx(0.2 * res.normal_forces[0])
    # The same push with enough friction sticks.
    assert single_contact_twist(c, p, n, v, 2.0).mode == "sticking"


def test_separating_pusher_moves_nothing():
    for v in [(-0.01, 0.0), (-0.01, 0.02), (0.0, 0.01)]:
        res = single_contact_twist(0.05, (-0.1, 0.0), (1.0, 0.0), v, 0.5)
        assert res.mode == "separating" and res.contact_modes == ("separating",)
        np.testing.assert_array_equal(res.twist, 0.0)
        np.testing.assert_array_equal(res.normal_forces, 0.0)


def test_single_contact_rejects_bad_input():
    with pytest.raises(PushingError, match="c must be positive"):
        single_contact_twist(-0.1, (0, 0), (1, 0), (1, 0), 0.3)
    with pytest.raises(PushingError, match="normal"):
        single_contact_twist(0.1, (0, 0), (0, 0), (1, 0), 0.3)
    with pytest.raises(PushingError, match="friction"):
        single_contact_twist(0.1, (0, 0), (1, 0), (1, 0), -0.3)


def test_result_arrays_are_read_only():
    res = single_contact_twist(0.05, (-0.1, 0.0), (1.0, 0.0), (0.01, 0.0), 0.5)
    with pytest.raises(ValueError):
        res.twist[0] = 1.0
    with pytest.raises(AttributeError):
        res.mode = "sliding"  # type: ignore[misc]


# ---------------------------------------------------------------------------------------------
# 3. Several contacts: LCP
# ---------------------------------------------------------------------------------------------


def test_lcp_with_one_contact_equals_closed_form_property():
    rng = np.random.default_rng(7)
    modes = {"sticking": 0, "sliding": 0, "separating": 0}
    improper = 0
    for _ in range(400):
        c, p, n, v, mu = random_contact(rng)
        closed = single_contact_twist(c, p, n, v, mu)
        lcp = multi_contact_twist(c, p[None], n[None], v[None], mu)
        assert not lcp.jammed
        # Both answers are quasistatic equilibria of the contact (Coulomb, no penetration).
        lcp_residuals(c, p[None], n[None], v[None], mu, lcp)
        lcp_residuals(c, p[None], n[None], v[None], mu, closed)
        lever, dist = p[0] * n[1] - p[1] * n[0], p @ n
        if mu * abs(lever * dist) >= c**2 + lever**2:
            # The motion cone leaves the half-plane v.n > 0 (huge mu x lever arm, not met by
            # real contacts): the rigid problem has several solutions, e.g. a receding pusher
            # dragging the object by friction. Only the equilibrium checks above apply.
            improper += 1
            continue
        np.testing.assert_allclose(lcp.twist, closed.twist, atol=1e-9)
        np.testing.assert_allclose(lcp.normal_forces, closed.normal_forces, atol=1e-9)
        np.testing.assert_allclose(lcp.tangential_forces, closed.tangential_forces, atol=1e-9)
        assert lcp.contact_modes == closed.contact_modes
        modes[closed.mode] += 1
    assert min(modes.values()) > 20 and improper > 0, (modes, improper)


def test_two_opposing_pushers_jam():
    c = limit_surface_c("box", (0.2, 0.2))
    pts = [(-0.1, 0.0), (0.1, 0.0)]
    nrm = [(1.0, 0.0), (-1.0, 0.0)]
    for mu in (0.0, 0.5):
        res = multi_contact_twist(c, pts, nrm, [(0.01, 0.0), (-0.01, 0.0)], mu)
        assert res.jammed and res.mode == "jammed"
        np.testing.assert_array_equal(res.twist, 0.0)
        assert np.all(np.isnan(res.normal_forces))
        # Squeezing along one line off the centre, with tangential motion, jams too.
        res = multi_contact_twist(c, [(-0.1, 0.05), (0.1, 0.05)], nrm,
                                  [(0.01, 0.004), (-0.002, -0.003)], mu)
        assert res.jammed
    # Squeezing along two different lines without friction does not jam to first order: the
    # couple of the two normal forces turns the object out of the squeeze (clockwise here).
    pts_off = np.array([(-0.1, 0.05), (0.1, -0.03)])
    v_off = np.array([(0.01, 0.0), (-0.002, 0.0)])
    res = multi_contact_twist(c, pts_off, nrm, v_off, 0.0)
    assert res.mode == "moving" and res.twist[2] < 0
    lcp_residuals(c, pts_off, np.array(nrm), v_off, 0.0, res)
    # The second pusher recedes, but slower than the first one drives the object into it.
    res = object_twist(c, pts, nrm, [(0.01, 0.0), (0.005, 0.0)], 0.3)
    assert res.jammed
    # Both pushers move the same way at the same speed: a rigid translation, not a jam.
    res = multi_contact_twist(c, pts, nrm, [(0.01, 0.0), (0.01, 0.0)], 0.3)
    assert res.mode == "moving"
    np.testing.assert_allclose(res.twist, [0.01, 0.0, 0.0], atol=1e-12)


def test_two_pushers_on_one_face_push_consistently():
    c = limit_surface_c("box", (0.2, 0.1))
    n = np.array([[1.0, 0.0], [1.0, 0.0]])
    pts = np.array([[-0.1, 0.03], [-0.1, -0.03]])
    v = np.array([[0.01, 0.0], [0.01, 0.0]])
    res = multi_contact_twist(c, pts, n, v, 0.4)
    assert res.mode == "moving" and res.contact_modes == ("sticking", "sticking")
    np.testing.assert_allclose(res.twist, [0.01, 0.0, 0.0], atol=1e-12)   # symmetric: translate
    np.testing.assert_allclose(res.normal_forces, [0.005, 0.005], atol=1e-12)
    lcp_residuals(c, pts, n, v, 0.4, res)
    # Asymmetric placement and a slanted push: both contacts still move with the pushers.
    pts2 = np.array([[-0.1, 0.045], [-0.1, -0.01]])
    v2 = np.array([[0.01, 0.002], [0.01, 0.002]])
    res = multi_contact_twist(c, pts2, n, v2, 0.4)
    assert res.mode == "moving" and not res.jammed
    for p, vp, fn in zip(pts2, v2, res.normal_forces, strict=True):
        gap_rate = velocity_at(p, res.twist)[0] - vp[0]
        assert gap_rate >= -1e-12                    # never penetrates; touches where loaded
        assert fn == 0 or abs(gap_rate) < 1e-12
    lcp_residuals(c, pts2, n, v2, 0.4, res)
    # Contacts straddling the centre unevenly, pushed along the normal: still a translation.
    pts3 = np.array([[-0.1, 0.045], [-0.1, -0.01]])
    res = multi_contact_twist(c, pts3, n, v, 0.4)
    np.testing.assert_allclose(res.twist, [0.01, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(res.normal_forces, [0.01 * 0.01 / 0.055, 0.01 * 0.045 / 0.055],
                               atol=1e-12)
    for p in pts3:
        assert velocity_at(p, res.twist)[0] == pytest.approx(0.01, abs=1e-12)


def test_receding_contact_separates_while_other_pushes():
    c = limit_surface_c("box", (0.2, 0.2))
    pts = np.array([[-0.1, 0.02], [0.1, 0.05]])
    nrm = np.array([[1.0, 0.0], [-1.0, 0.0]])
    v = np.array([[0.01, 0.0], [0.02, 0.0]])             # pusher 2 moves away, faster
    res = multi_contact_twist(c, pts, nrm, v, 0.3)
    assert res.mode == "moving"
    assert res.contact_modes[1] == "separating" and res.normal_forces[1] == 0.0
    assert res.normal_forces[0] > 0
    alone = single_contact_twist(c, pts[0], nrm[0], v[0], 0.3)
    np.testing.assert_allclose(res.twist, alone.twist, atol=1e-12)
    lcp_residuals(c, pts, nrm, v, 0.3, res)
    # object_twist takes its shortcut here and agrees.
    fast = object_twist(c, pts, nrm, v, 0.3)
    np.testing.assert_allclose(fast.twist, res.twist, atol=1e-12)
    assert fast.contact_modes == res.contact_modes
    # Nobody pushes: nothing moves (LCP and dispatcher agree).
    still = np.array([[-0.01, 0.0], [0.01, 0.0]])
    assert multi_contact_twist(c, pts, nrm, still, 0.3).mode == "separating"
    assert object_twist(c, pts, nrm, still, 0.3).mode == "separating"


def random_box_contacts(rng: np.random.Generator, K: int, half: float = 0.06):
    """K contact points on the boundary of a 2half x 2half box, with inward normals."""
    pts, nrm = [], []
    for _ in range(K):
        s = rng.uniform(-half, half)
        p, n = [((-half, s), (1, 0)), ((half, s), (-1, 0)),
                ((s, -half), (0, 1)), ((s, half), (0, -1))][rng.integers(4)]
        pts.append(p)
        nrm.append(n)
    return np.array(pts, float), np.array(nrm, float)


def test_random_multi_contact_solutions_satisfy_the_physics_and_dispatch_agrees():
    rng = np.random.default_rng(11)
    c = 0.05
    counts = {"moving": 0, "jammed": 0, "separating": 0}
    indeterminate = 0
    for _ in range(150):
        K = int(rng.integers(2, 5))
        pts, nrm = random_box_contacts(rng, K)
        v = rng.uniform(-0.01, 0.01, (K, 2))
        mu = float(rng.uniform(0.0, 1.0))
        res = multi_contact_twist(c, pts, nrm, v, mu)
        counts[res.mode] += 1
        assert len(res.contact_modes) == K
        fast = object_twist(c, pts, nrm, v, mu)
        if not fast.jammed:
            lcp_residuals(c, pts, nrm, v, mu, fast)
        if res.jammed:
            # Frictional indeterminacy: Lemke found a squeezing certificate, yet the dispatcher's
            # one-pusher shortcut may hold a genuine solution (checked just above).
            indeterminate += not fast.jammed
            continue
        lcp_residuals(c, pts, nrm, v, mu, res)
        assert fast.mode == res.mode
        np.testing.assert_allclose(fast.twist, res.twist, atol=1e-9)
    assert min(counts.values()) > 5 and indeterminate <= 2, (counts, indeterminate)


def normal_constraints_feasible(points, normals, disps) -> bool:
    """Is there a twist V with n_i . (J_i V - v_i) >= 0 for all i? (an LP, by scipy)"""
    rows = np.column_stack([normals, points[:, 0] * normals[:, 1] - points[:, 1] * normals[:, 0]])
    b = np.einsum("ij,ij->i", normals, disps)
    return optimize.linprog(np.zeros(3), A_ub=-rows, b_ub=-b, bounds=[(None, None)] * 3).status == 0


def test_frictionless_jams_exactly_when_no_twist_avoids_penetration():
    # Without friction the LCP is solvable iff the no-penetration constraints are (Farkas), so
    # Lemke's ray termination must coincide with LP infeasibility.
    rng = np.random.default_rng(1996)
    jammed = 0
    for _ in range(120):
        K = int(rng.integers(2, 5))
        pts, nrm = random_box_contacts(rng, K)
        v = rng.uniform(-0.01, 0.01, (K, 2))
        res = multi_contact_twist(0.05, pts, nrm, v, 0.0)
        assert res.jammed == (not normal_constraints_feasible(pts, nrm, v))
        jammed += res.jammed
        if not res.jammed:
            lcp_residuals(0.05, pts, nrm, v, 0.0, res)
            np.testing.assert_allclose(res.tangential_forces, 0.0, atol=1e-12)
    assert 5 < jammed < 115
    # Regression: a degenerate path on which the artificial variable reaches 0 on a tie.
    pts = np.array([[-0.0409064727882845, 0.06], [0.0125331088054921, 0.06],
                    [-0.0447328189167759, -0.06]])
    nrm = np.array([[0.0, -1.0], [0.0, -1.0], [0.0, 1.0]])
    v = np.array([[-0.006460962735926898, -0.00430253453110913],
                  [0.00910706619522885, -0.0023839991822184655],
                  [0.00859931307028594, -0.0019153514883798635]])
    res = multi_contact_twist(0.05, pts, nrm, v, 0.0)
    assert not res.jammed
    lcp_residuals(0.05, pts, nrm, v, 0.0, res)


def test_object_twist_dispatch():
    c = 0.05
    empty = object_twist(c, np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2)), 0.3)
    assert empty.mode == "separating" and empty.normal_forces.shape == (0,)
    np.testing.assert_array_equal(empty.twist, 0.0)
    one = object_twist(c, [(-0.05, 0.01)], [(1, 0)], [(0.01, 0.003)], 0.3)
    ref = single_contact_twist(c, (-0.05, 0.01), (1, 0), (0.01, 0.003), 0.3)
    np.testing.assert_array_equal(one.twist, ref.twist)
    assert one.mode == ref.mode


def test_build_contact_lcp_structure():
    pts = np.array([[-0.05, 0.01], [0.02, 0.05]])
    nrm = np.array([[1.0, 0.0], [0.0, -1.0]])
    v = np.array([[0.01, 0.002], [0.0, -0.003]])
    lcp = build_contact_lcp(0.04, pts, nrm, v, [0.3, 0.6])
    K = 2
    assert lcp.M.shape == (4 * K, 4 * K) and lcp.q.shape == (4 * K,)
    np.testing.assert_allclose(lcp.q[:K], [-0.01, -0.003])           # -(n . v)
    np.testing.assert_array_equal(lcp.q[3 * K:], 0.0)
    np.testing.assert_allclose(lcp.M[3 * K:, :K], np.diag([0.3, 0.6]))
    top = lcp.M[:3 * K, :3 * K]
    np.testing.assert_allclose(top, top.T, atol=1e-15)                 # G A G^T symmetric PSD
    assert np.linalg.eigvalsh(top).min() > -1e-12
    z = np.random.default_rng(3).uniform(0, 1, (50, 4 * K))         # copositive on samples
    assert np.all(np.einsum("ij,jk,ik->i", z, lcp.M, z) >= -1e-12)
    with pytest.raises(PushingError, match=r"\(K, 2\)"):
        build_contact_lcp(0.04, pts, nrm[:1], v, 0.3)


# ---------------------------------------------------------------------------------------------
# Lemke's algorithm on small LCPs
# ---------------------------------------------------------------------------------------------


def test_lemke_known_solutions():
    sol = lemke(np.array([[2.0, 1.0], [1.0, 2.0]]), np.array([-5.0, -6.0]))
    assert sol.solved
    np.testing.assert_allclose(sol.z, [4 / 3, 7 / 3], atol=1e-14)
    np.testing.assert_allclose(sol.w, [0.0, 0.0], atol=1e-14)
    sol = lemke(np.eye(3), np.array([1.0, 2.0, 0.0]))                   # q >= 0: z = 0
    assert sol.solved and sol.iterations == 0
    np.testing.assert_array_equal(sol.z, 0.0)
    # Mixed: z_1 > 0 = w_1, z_2 = 0 < w_2.
    sol = lemke(np.array([[1.0, 0.0], [2.0, 1.0]]), np.array([-1.0, 1.0]))
    np.testing.assert_allclose(sol.z, [1.0, 0.0], atol=1e-14)
    np.testing.assert_allclose(sol.w, [0.0, 3.0], atol=1e-14)
    # Degenerate (ties in the ratio test, zero entries of q) with a PSD non-symmetric M.
    M = np.array([[1.0, -1.0, 0.0], [1.0, 1.0, 1.0], [0.0, -1.0, 0.0]])
    sol = lemke(M, np.array([-1.0, 0.0, 0.0]))
    assert sol.solved
    assert np.all(sol.z >= 0) and np.all(sol.w >= -1e-12) and abs(sol.z @ sol.w) < 1e-12


def test_lemke_ray_termination_without_solution():
    # w = -z - 1 < 0 for every z >= 0.
    sol = lemke(np.array([[-1.0]]), np.array([-1.0]))
    assert sol.status == "ray_termination" and not sol.solved and np.all(np.isnan(sol.z))
    # w_1 = z_2 - 1, w_2 = -z_1 - 1: w_2 < 0 always.
    sol = lemke(np.array([[0.0, 1.0], [-1.0, 0.0]]), np.array([-1.0, -1.0]))
    assert sol.status == "ray_termination"


def test_lemke_iteration_cap():
    M = np.array([[2.0, 1.0], [1.0, 2.0]])
    sol = lemke(M, np.array([-5.0, -6.0]), max_iterations=1)
    assert sol.status == "iteration_limit" and not sol.solved


def test_lemke_random_psd_property():
    rng = np.random.default_rng(1996)
    for _ in range(150):
        n = int(rng.integers(1, 9))
        B = rng.normal(size=(n, n))
        S = rng.normal(size=(n, n))
        M = B @ B.T + (S - S.T) + 1e-3 * np.eye(n)                    # positive definite
        q = rng.normal(size=n)
        q[rng.random(n) < 0.3] = 0.0                                   # degenerate entries
        sol = lemke(M, q)
        assert sol.solved
        assert np.all(sol.z >= 0)
        np.testing.assert_allclose(sol.w, M @ sol.z + q, atol=1e-12)
        assert np.all(sol.w >= -1e-10) and abs(sol.z @ sol.w) < 1e-9


# ---------------------------------------------------------------------------------------------
# 4. SE(2)
# ---------------------------------------------------------------------------------------------


def se2(pose) -> np.ndarray:
    x, y, a = pose
    return np.array([[math.cos(a), -math.sin(a), x], [math.sin(a), math.cos(a), y], [0, 0, 1]])


def hat(twist) -> np.ndarray:
    dx, dy, th = twist
    return np.array([[0.0, -th, dx], [th, 0.0, dy], [0.0, 0.0, 0.0]])


def test_apply_twist_translation_and_rotation():
    pose = np.array([0.5, -0.2, 0.3])
    moved = apply_twist(pose, (0.1, 0.0, 0.0))                         # along the object's x
    np.testing.assert_allclose(moved, [0.5 + 0.1 * math.cos(0.3), -0.2 + 0.1 * math.sin(0.3), 0.3],
                               atol=1e-15)
    turned = apply_twist(pose, (0.0, 0.0, 0.7))                        # about the centre
    np.testing.assert_allclose(turned, [0.5, -0.2, 1.0], atol=1e-15)
    wrapped = apply_twist((0.0, 0.0, 3.0), (0.0, 0.0, 0.5))
    assert wrapped[2] == pytest.approx(3.5 - 2 * math.pi)


def test_apply_twist_is_the_exponential_and_composes():
    rng = np.random.default_rng(42)
    for _ in range(50):
        pose = rng.uniform([-1, -1, -math.pi], [1, 1, math.pi])
        a = rng.uniform(-0.2, 0.2, 3) * rng.choice([1e-9, 1.0, 10.0])
        b = rng.uniform(-0.2, 0.2, 3)
        expected = se2(pose) @ linalg.expm(hat(a)) @ linalg.expm(hat(b))
        got = apply_twist(apply_twist(pose, a), b)
        np.testing.assert_allclose(se2(got), expected, atol=1e-12)
        # One-parameter subgroup: two half steps make one step.
        np.testing.assert_allclose(se2(apply_twist(apply_twist(pose, a / 2), a / 2)),
                                   se2(apply_twist(pose, a)), atol=1e-12)


def test_frame_helpers_round_trip_with_pushing():
    rng = np.random.default_rng(5)
    pose = np.array([0.4, 0.1, 0.9])
    p_obj = rng.uniform(-0.05, 0.05, (3, 2))
    T = se2(pose)
    p_world = (T[:2, :2] @ p_obj.T).T + pose[:2]
    np.testing.assert_allclose(points_to_object_frame(pose, p_world), p_obj, atol=1e-15)
    v_obj = rng.uniform(-1, 1, (3, 2))
    np.testing.assert_allclose(vectors_to_object_frame(pose, (T[:2, :2] @ v_obj.T).T), v_obj,
                               atol=1e-15)
    # A push through the centre along world +x of a rotated object moves it along world +x.
    c = limit_surface_c("disk", 0.03)
    contact_w = pose[:2] - np.array([0.03, 0.0])
    res = single_contact_twist(c, points_to_object_frame(pose, contact_w[None])[0],
                               vectors_to_object_frame(pose, [(1.0, 0.0)])[0],
                               vectors_to_object_frame(pose, [(0.01, 0.0)])[0], 0.3)
    np.testing.assert_allclose(apply_twist(pose, res.twist), pose + [0.01, 0.0, 0.0], atol=1e-15)


# ---------------------------------------------------------------------------------------------
# Support pressure: c and the centre of friction (what the model cannot know)
# ---------------------------------------------------------------------------------------------

SQUARE_C = limit_surface_c("box", (0.08, 0.08))


def test_a_centre_of_friction_shifts_the_limit_surface_and_a_zero_one_is_exact():
    """The twist about an offset centre of friction equals the twist of the same contacts
    taken relative to that centre, moved back to the origin (v_o = v_c + w x (o - c)); a zero
    centre is the uniform model bit for bit."""
    rng = np.random.default_rng(3)
    for _ in range(30):
        k = int(rng.integers(1, 3))
        P = rng.uniform(-0.04, 0.04, (k, 2))
        angles = rng.uniform(0, 2 * np.pi, k)
        N = np.column_stack([np.cos(angles), np.sin(angles)])
        V = N * rng.uniform(0.001, 0.004, (k, 1)) + rng.normal(0, 0.001, (k, 2))
        centre = rng.uniform(-0.01, 0.01, 2)
        plain = object_twist(SQUARE_C, P, N, V, 0.3)
        assert np.array_equal(object_twist(SQUARE_C, P, N, V, 0.3, (0.0, 0.0)).twist,
                              plain.twist)
        about = object_twist(SQUARE_C, P, N, V, 0.3, centre)
        shifted = object_twist(SQUARE_C, P - centre, N, V, 0.3)
        if about.jammed or shifted.jammed:
            assert about.jammed == shifted.jammed
            continue
        vx, vy, w = shifted.twist
        expected = (vx + w * centre[1], vy - w * centre[0], w)
        np.testing.assert_allclose(about.twist, expected, atol=1e-12)


def test_an_off_centre_point_push_turns_differently_across_the_pressure_range():
    """One finger 3 cm off the centre line of an 8 cm square pushes it 1 cm: how far the box
    turns depends on c (centre- to corner-loaded) and on where the centre of friction lies,
    which is why the rollouts draw them."""
    point, normal, push = [0.03, -0.04], [0.0, 1.0], [0.0, 0.01]
    turns = {scale: object_twist(scale * SQUARE_C, [point], [normal], [push], 0.3).twist[2]
             for scale in (0.8, 1.0, 1.8)}
    assert turns[0.8] > turns[1.0] > turns[1.8] > 0.0
    assert turns[0.8] > 1.5 * turns[1.8]
    toward = object_twist(SQUARE_C, [point], [normal], [push], 0.3, (0.015, 0.0)).twist[2]
    away = object_twist(SQUARE_C, [point], [normal], [push], 0.3, (-0.015, 0.0)).twist[2]
    assert away > turns[1.0] > toward         # a centre nearer the finger turns it less
    assert away > 1.5 * toward


def test_a_centred_face_push_with_two_contacts_barely_turns_across_the_range():
    """Two fingers 6 cm apart on the near face push straight: a stable push (Lynch & Mason
    1996). Whatever the pressure within the drawn range, the box goes straight."""
    points = [[-0.03, -0.04], [0.03, -0.04]]
    normals = [[0.0, 1.0]] * 2
    pushes = [[0.0, 0.01]] * 2
    rng = np.random.default_rng(0)
    for _ in range(20):
        scale = rng.uniform(0.8, 1.8)
        centre = rng.uniform(-0.25, 0.25, 2) * 0.04
        result = object_twist(scale * SQUARE_C, points, normals, pushes, 0.3, centre)
        assert not result.jammed
        assert abs(result.twist[2]) < 1e-9 and result.twist[1] == pytest.approx(0.01)


# ---------------------------------------------------------------------------------------------
# Several objects pushing each other (module docstring, §3b)
# ---------------------------------------------------------------------------------------------


def test_one_object_alone_in_the_multibody_problem_moves_as_in_the_single_object_model():
    """With one object and the arm's contacts only, the multi-body LCP is §3's problem (in the
    world frame, about the centre of friction, any support scale): the same twist."""
    from rearrangement_planner.physics.pushing import multibody_twists

    rng = np.random.default_rng(5)
    checked = 0
    for _ in range(40):
        k = int(rng.integers(1, 4))
        yaw, origin = rng.uniform(-np.pi, np.pi), rng.uniform(-0.5, 0.5, 2)
        centre = rng.uniform(-0.01, 0.01, 2)
        P = rng.uniform(-0.04, 0.04, (k, 2))
        angles = rng.uniform(0, 2 * np.pi, k)
        N = np.column_stack([np.cos(angles), np.sin(angles)])
        V = N * rng.uniform(0.001, 0.004, (k, 1)) + rng.normal(0, 0.001, (k, 2))
        local = object_twist(SQUARE_C, P, N, V, 0.3, centre)
        R = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        world_centre = origin + R @ centre
        mode, twists = multibody_twists(
            [world_centre], [SQUARE_C], [rng.uniform(0.2, 5.0)], origin + P @ R.T, N @ R.T,
            np.zeros(k), -np.ones(k), V @ R.T, np.zeros(k), np.full(k, 0.3))
        if local.jammed or mode == "jammed":
            continue
        checked += 1
        vx, vy, w = twists[0]
        # the twist of the object's origin, in its own frame
        v_origin = R.T @ (np.array([vx, vy]) + w * np.array([-(origin - world_centre)[1],
                                                             (origin - world_centre)[0]]))
        # the same up to the multi-body problem's compliance (MULTIBODY_COMPLIANCE)
        np.testing.assert_allclose([*v_origin, w], local.twist, rtol=1e-3, atol=1e-8)
    assert checked >= 30


def test_a_box_pushed_into_another_pushes_it_along_and_the_lighter_gives_way():
    """The arm pushes box a (2 contacts on its back face) against box b (face to face): both
    go straight at the arm's speed. Pushed into b from its side at a corner, b turns and the
    arm's box goes on."""
    from rearrangement_planner.physics.pushing import multibody_twists

    centres = [[0.0, 0.0], [0.065, 0.0]]
    arm = dict(P=[[-0.03, 0.01], [-0.03, -0.01]], V=[[0.001, 0.0]] * 2)
    faces = [[0.0325, 0.04], [0.0325, -0.04]]
    P = np.array(arm["P"] + faces)
    N = np.array([[1.0, 0.0]] * 4)
    mode, twists = multibody_twists(centres, [SQUARE_C] * 2, [1.0, 1.0], P, N, [0, 0, 1, 1],
                                    [-1, -1, 0, 0], arm["V"] + [[0, 0]] * 2, [0, 0, 0.0005,
                                                                              0.0005],
                                    [0.3] * 4)
    assert mode == "moving"
    np.testing.assert_allclose(twists[0], [0.001, 0, 0], atol=1e-8)
    # b closes the 0.5 mm gap first: it moves 0.5 mm less
    np.testing.assert_allclose(twists[1], [0.0005, 0, 0], atol=1e-8)
    corner = np.array(arm["P"] + [[0.0325, 0.04]])
    mode, twists = multibody_twists(centres[:1] + [[0.065, 0.07]], [SQUARE_C] * 2, [1.0, 1.0],
                                    corner, N[:3], [0, 0, 1], [-1, -1, 0],
                                    arm["V"] + [[0, 0]], [0, 0, 0.0], [0.3] * 3)
    assert mode == "moving" and twists[1, 2] > 0.0          # b turns about its far side
    assert twists[0, 0] == pytest.approx(0.001, abs=1e-8)   # the arm carries a on
