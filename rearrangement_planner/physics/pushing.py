"""Quasistatic planar pushing of ONE object: limit surface, motion cone, multi-contact LCP.

This is the physics of King et al. (PC-RRT), §III-A, as specified in DESIGN §5. Objects move
only while pushed and stop at once (quasistatic, Coulomb friction; Lynch & Mason 1995 [23]).
Everything here is a pure function of plain numbers: no robot, no scene, no collision library.

Frames and units
----------------
All inputs and outputs are in the OBJECT frame: origin at the centre of the object's support
footprint, x/y along the object's axes. Lengths in metres, angles in radians. Motion is given
as DISPLACEMENTS over one propagation step, not velocities: in the quasistatic model the
object's motion is homogeneous of degree one in the pusher motion, so a "twist" here is the
object displacement (dx, dy, dtheta) produced by the given pusher displacements (and
`apply_twist` integrates it over the unit step with the exact SE(2) exponential).
`points_to_object_frame` / `vectors_to_object_frame` convert world-frame contact data.

1. Limit surface (Goyal, Ruina & Papadopoulos 1991 [15]; ellipsoidal approximation of
   Lee & Cutkosky 1991 / Howe & Cutkosky 1996 [18], as used by Lynch, Maekawa & Tanie 1992)
   With uniform support pressure, f_max = mu_s m g and m_max = mu_s m g rbar, where rbar is
   the mean distance of the support area from its centre. The ellipsoid
   H(F) = (f_x^2 + f_y^2)/f_max^2 + m^2/m_max^2 has normal grad H ∝ A F with

       A = diag(1, 1, 1/c^2),   c = m_max / f_max = rbar   (a LENGTH)          (LS)

   and the object twist is V = k A F for some k > 0 (F = (f_x, f_y, m) the total wrench on the
   object at its origin). Since only the direction of F matters, all forces below are in
   "LCP units" with k = 1, i.e. V = A F exactly (forces measured in metres of displacement).
   To get newtons, scale every force by f_max / sqrt(V_x^2 + V_y^2 + (c * omega)^2).

2. One contact: the motion cone (Mason 1986; Lynch, Maekawa & Tanie 1992)
   A force f applied at contact point p = (x, y) produces the wrench (f, x f_y - y f_x); through
   (LS) the object's velocity at p is v(p) = B f with the symmetric positive-definite

       B = I + r r^T / c^2,  r = (-y, x),  B^-1 = [[c^2+x^2, xy], [xy, c^2+y^2]] / (c^2+x^2+y^2).

   With inward unit normal n and tangent t = R(+90°) n, the friction cone edges
   f_l = n + mu t, f_r = n - mu t map to the motion-cone edges v_l = B f_l, v_r = B f_r.
   - separating:  v_p·n <= 0  ->  the object does not move.
   - sticking:    v_p inside the motion cone  ->  v(p) = v_p and (V = A F, F = (B^-1 v_p, ·))

       v_x = ((c^2+x^2) v_px + x y v_py) / (c^2+x^2+y^2)
       v_y = (x y v_px + (c^2+y^2) v_py) / (c^2+x^2+y^2)                         (STICK)
       omega = (x v_y - y v_x) / c^2

   - sliding:     otherwise; the contact force lies on the cone edge on v_p's side, the
     contact point moves along that motion-cone edge, v(p) = v_b (v_p·n)/(v_b·n) (normal
     velocities match), and (STICK) is applied to that v(p) instead of v_p.
   Well-posedness: the model assumes both cone edges point into the object, v_e·n > 0, i.e.
   c^2 + a^2 > mu |a| |p·n| with lever arm a = p x n. Violating it needs mu |p·n| > 2c, which
   cannot happen for mu <= 1 on a box or disk footprint (there |p·n| <= 2c, as c >= half the
   larger half-side, resp. c = 2R/3). Beyond it the rigid problem has several solutions (e.g.
   a receding pusher dragging the object by friction); the closed form then returns the
   'separating' one and the LCP may return another.

3. Several contacts: a linear complementarity problem (LCP)
   The quasistatic analogue of Stewart & Trinkle (1996)'s time-stepping LCP, with the inverse
   mass matrix replaced by the limit-surface map A (quasistatic multi-contact pushing as in
   Lynch & Mason 1996 and Chavan-Dafle, Holladay & Rodriguez 2018). Per contact i (point p_i,
   inward normal n_i, tangent t_i, pusher displacement v_i, friction mu_i):
   contact Jacobian J_i: V -> object velocity at p_i, J_i = [[1, 0, -y_i], [0, 1, x_i]];
   normal force f_n,i >= 0; pyramid friction components beta_i = (f_t+, f_t-) >= 0 along
   D_i = [t_i, -t_i] (exact in the plane); slack lambda_i >= 0 (the sliding speed).
   With G the 3K x 3 matrix of rows n_i^T J_i (normal) and ±t_i^T J_i (friction),

       V = A G^T (f_n, beta)                                   (wrench -> twist, (LS))
       u_i = J_i V - v_i                                       (object velocity rel. pusher)
       0 <= n_i·u_i                     ⊥ f_n,i  >= 0          (no penetration; may separate)
       0 <= lambda_i e + D_i^T u_i      ⊥ beta_i >= 0          (max. dissipation)
       0 <= mu_i f_n,i - e^T beta_i     ⊥ lambda_i >= 0        (Coulomb cone)

   i.e. w = M z + q, w >= 0, z >= 0, w^T z = 0 with z = (f_n, beta, lambda),

       M = [[N A N^T, N A D^T, 0], [D A N^T, D A D^T, E], [U, -E^T, 0]],
       q = (-n_i·v_i, -D_i^T v_i, 0),   U = diag(mu_i),  E = blockdiag(e),

   (`build_contact_lcp`). The pusher displacements enter only q. M is not symmetric and only
   copositive: z^T M z = |G^T (f_n, beta)|_A^2 + sum_i mu_i lambda_i f_n,i >= 0. It is solved
   exactly by Lemke's complementary pivoting (`lemke`; Lemke 1965; Cottle, Pang & Stone 1992,
   §4.4) with a lexicographic ratio test so that degenerate pivots cannot cycle.
   Jamming. For copositive M a secondary ray of Lemke's method yields z_h >= 0 with
   M z_h >= 0, z_h^T M z_h = 0 and q^T z_h < 0 (Cottle, Pang & Stone 1992, §4.4; the argument
   Stewart & Trinkle 1996 use for their LCP). Here such a z_h is a set of friction-cone contact
   forces with zero net wrench (G^T f = 0) doing positive work on the pusher displacements:
   the pushers SQUEEZE the object. Ray termination (and the iteration cap) is reported as
   JAMMED (`multi_contact_twist`), which the planner treats as an invalid step.
   - Frictionless (mu = 0): jammed <=> the no-penetration constraints n_i·(J_i V - v_i) >= 0
     have no common V (Farkas), e.g. two pushers closing in on opposite faces.
   - With friction the certificate can coexist with a solution (the rigid-body frictional
     indeterminacy); Lemke may then report jammed, which errs on the safe side. So does a
     numerically near-singular contact set (e.g. opposing contacts a fraction of a millimetre
     off one line, whose only "solution" is an absurd spin): pivots on entries below 1e-9 of
     their column are treated as zeros.

`object_twist` dispatches: no pushing contact -> no motion; one contact -> closed form; several
contacts -> the LCP (after a cheap exact shortcut when only one contact pushes and the closed
form motion does not run into the others).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from rearrangement_planner.model.errors import RearrangementError
from rearrangement_planner.model.state import wrap_angle

PushMode = Literal["separating", "sticking", "sliding", "moving", "jammed"]
ContactMode = Literal["separating", "sticking", "sliding", "jammed"]
LCPStatus = Literal["solved", "ray_termination", "iteration_limit"]

_DISK_SHAPES = ("disk", "cylinder", "circle")
_RECTANGLE_SHAPES = ("box", "rectangle")


class PushingError(RearrangementError, ValueError):
    """Inputs to the pushing model are malformed (shapes, non-positive sizes, zero normals)."""


# --------------------------------------------------------------------------------------------
# Value types
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class PushResult:
    """The object's response to one step of pusher displacements (object frame).

    `mode`: for one contact 'separating' | 'sticking' | 'sliding'; for several contacts
    'separating' (nothing loaded) | 'moving' | 'jammed'. `contact_modes[i]` is the mode of
    contact i ('separating' means it carries no load). Forces are in LCP units (V = A F, see
    the module docstring): `normal_forces[i]` = f_n,i >= 0 and `tangential_forces[i]` = the
    friction component along t_i = R(+90°) n_i. A jammed result has a zero twist and NaN forces.
    """

    twist: np.ndarray              # (3,) object displacement (dx m, dy m, dtheta rad), object frame
    mode: PushMode
    normal_forces: np.ndarray      # (K,) LCP units
    tangential_forces: np.ndarray  # (K,) LCP units, along t_i
    contact_modes: tuple[ContactMode, ...]

    def __post_init__(self) -> None:
        self.twist.setflags(write=False)
        self.normal_forces.setflags(write=False)
        self.tangential_forces.setflags(write=False)

    @property
    def jammed(self) -> bool:
        return self.mode == "jammed"


@dataclass(frozen=True, slots=True, eq=False)
class LCPSolution:
    """Result of `lemke`: w = M z + q with z, w >= 0 and w^T z = 0 when `status` == 'solved';
    z and w are NaN otherwise (ray termination: no solution was found; iteration limit)."""

    z: np.ndarray
    w: np.ndarray
    status: LCPStatus
    iterations: int

    def __post_init__(self) -> None:
        self.z.setflags(write=False)
        self.w.setflags(write=False)

    @property
    def solved(self) -> bool:
        return self.status == "solved"


@dataclass(frozen=True, slots=True, eq=False)
class ContactLCP:
    """The multi-contact LCP of the module docstring, §3, for K contacts.

    Unknowns z = (f_n (K), beta (2K: f_t+,1, f_t-,1, f_t+,2, ...), lambda (K)); n = 4K.
    `twist_map` (3, 3K) is A G^T: the object twist is twist_map @ z[:3K].
    """

    M: np.ndarray          # (4K, 4K)
    q: np.ndarray          # (4K,)
    twist_map: np.ndarray  # (3, 3K)
    num_contacts: int

    def __post_init__(self) -> None:
        self.M.setflags(write=False)
        self.q.setflags(write=False)
        self.twist_map.setflags(write=False)


# --------------------------------------------------------------------------------------------
# 1. Limit surface
# --------------------------------------------------------------------------------------------


def rectangle_mean_distance(half_x: float, half_y: float) -> float:
    """Mean distance from the centre over a rectangle with half-sides (a, b), in metres.

    rbar = 1/(4ab) ∫_{-a}^{a} ∫_{-b}^{b} sqrt(x^2+y^2) dy dx
         = d/3 + a^2/(6b) asinh(b/a) + b^2/(6a) asinh(a/b),   d = sqrt(a^2+b^2).
    (Integrate in polar coordinates over the two triangles of the quarter rectangle split by its
    diagonal: ∫_0^{atan(b/a)} (a/cos φ)^3/3 dφ = a^3/6 (d b/a^2 + asinh(b/a)), and
    symmetrically; divide by the area ab.) A square of side s gives s (√2 + asinh 1)/6.
    """
    a, b = float(half_x), float(half_y)
    d = math.hypot(a, b)
    return d / 3.0 + a * a / (6.0 * b) * math.asinh(b / a) + b * b / (6.0 * a) * math.asinh(a / b)


def limit_surface_c(shape: str, size: float | Sequence[float] | np.ndarray) -> float:
    """c = m_max / f_max = rbar of the ellipsoidal limit surface (LS), a length in metres.

    Uniform pressure over the support footprint (Lynch, Maekawa & Tanie 1992; DESIGN §5):
    - 'disk' / 'cylinder': `size` is the radius R (or a sequence starting with it); c = 2R/3.
    - 'box' / 'rectangle': `size` is the FULL side lengths (x, y) or (x, y, z) as in the scene
      file; c = `rectangle_mean_distance(x/2, y/2)`.
    """
    dims = np.atleast_1d(np.asarray(size, dtype=float))
    if shape in _DISK_SHAPES:
        if dims.size < 1 or not (np.isfinite(dims[0]) and dims[0] > 0):
            raise PushingError(f"limit_surface_c('{shape}', {size!r}): size must be a positive "
                               "finite radius in metres")
        return 2.0 * float(dims[0]) / 3.0
    if shape in _RECTANGLE_SHAPES:
        if dims.size not in (2, 3) or not (np.isfinite(dims[:2]).all() and dims[:2].min() > 0):
            raise PushingError(f"limit_surface_c('{shape}', {size!r}): size must be the positive "
                               "full side lengths (x, y) or (x, y, z) in metres")
        return rectangle_mean_distance(0.5 * float(dims[0]), 0.5 * float(dims[1]))
    raise PushingError(f"limit_surface_c: unknown shape '{shape}'; expected one of "
                       f"{_DISK_SHAPES + _RECTANGLE_SHAPES}")


# --------------------------------------------------------------------------------------------
# 2. One contact: the motion cone
# --------------------------------------------------------------------------------------------


def _check_c_mu(c: float, mu: float) -> None:
    if not c > 0.0 or not math.isfinite(c):
        raise PushingError(f"limit-surface length c must be positive and finite, got {c!r} "
                           "(c = m_max/f_max in metres, see limit_surface_c)")
    if not mu >= 0.0 or not math.isfinite(mu):
        raise PushingError(f"pusher friction coefficient must be finite and >= 0, got {mu!r}")


def _twist_from_contact_velocity(c2: float, x: float, y: float,
                                 vcx: float, vcy: float) -> tuple[float, float, float]:
    """(STICK): the object twist whose velocity at contact point (x, y) is (vcx, vcy), given that
    the wrench is a pure force at (x, y) (Lynch, Maekawa & Tanie 1992). Object frame."""
    den = c2 + x * x + y * y
    vx = ((c2 + x * x) * vcx + x * y * vcy) / den
    vy = (x * y * vcx + (c2 + y * y) * vcy) / den
    return vx, vy, (x * vy - y * vx) / c2


def single_contact_twist(c: float, point: Sequence[float] | np.ndarray,
                         normal: Sequence[float] | np.ndarray,
                         pusher_disp: Sequence[float] | np.ndarray, mu: float) -> PushResult:
    """Object twist for one point contact by the motion-cone model (module docstring, §2).

    c: limit-surface length (m); point: contact point (x, y) in the object frame (m); normal:
    inward contact normal (the direction the pusher pushes; normalised here); pusher_disp:
    pusher displacement at the contact point in the object frame (m); mu: pusher-object
    friction coefficient. Returns the twist (dx, dy, dtheta) and 'separating' | 'sticking' |
    'sliding'.
    """
    c = float(c)
    mu = float(mu)
    _check_c_mu(c, mu)
    x, y = float(point[0]), float(point[1])
    nx, ny = float(normal[0]), float(normal[1])
    nn = math.hypot(nx, ny)
    if not nn > 1e-12 or not math.isfinite(nn):
        raise PushingError(f"contact normal must be a non-zero finite vector, got {normal!r}")
    nx, ny = nx / nn, ny / nn
    vpx, vpy = float(pusher_disp[0]), float(pusher_disp[1])

    vp_n = vpx * nx + vpy * ny
    if not vp_n > 0.0:  # separating (or tangential) pusher: no load, no motion
        return PushResult(np.zeros(3), "separating", np.zeros(1), np.zeros(1), ("separating",))

    tx, ty = -ny, nx                    # tangent t = R(+90°) n
    c2 = c * c
    # Motion-cone edges v_e = B f_e, B = I + r r^T / c^2, r = (-y, x)  (module docstring, §2).
    fl_x, fl_y = nx + mu * tx, ny + mu * ty
    fr_x, fr_y = nx - mu * tx, ny - mu * ty
    ml = (x * fl_y - y * fl_x) / c2
    mr = (x * fr_y - y * fr_x) / c2
    vl_x, vl_y = fl_x - y * ml, fl_y + x * ml
    vr_x, vr_y = fr_x - y * mr, fr_y + x * mr
    # Compare directions in the half-plane v·n > 0 by their slope s(v) = (v·t)/(v·n), which
    # increases counter-clockwise. B preserves orientation, so v_r is clockwise of v_l; an edge
    # with v_e·n <= 0 leaves that whole side of the half-plane inside the cone.
    vl_n = vl_x * nx + vl_y * ny
    vr_n = vr_x * nx + vr_y * ny
    s_p = (vpx * tx + vpy * ty) / vp_n
    s_l = (vl_x * tx + vl_y * ty) / vl_n if vl_n > 0.0 else math.inf
    s_r = (vr_x * tx + vr_y * ty) / vr_n if vr_n > 0.0 else -math.inf

    mode: ContactMode
    if s_r <= s_p <= s_l:               # inside the motion cone: the contact sticks
        mode, vcx, vcy = "sticking", vpx, vpy
    elif s_p > s_l:                     # pusher slides towards +t: force on the edge n + mu t
        k = vp_n / vl_n
        mode, vcx, vcy = "sliding", k * vl_x, k * vl_y
    else:                               # pusher slides towards -t: force on the edge n - mu t
        k = vp_n / vr_n
        mode, vcx, vcy = "sliding", k * vr_x, k * vr_y
    vx, vy, w = _twist_from_contact_velocity(c2, x, y, vcx, vcy)
    # With V = A F the contact force is the translational part of the twist (LCP units).
    return PushResult(np.array([vx, vy, w]), mode, np.array([vx * nx + vy * ny]),
                      np.array([vx * tx + vy * ty]), (mode,))


# --------------------------------------------------------------------------------------------
# 3. Several contacts: build the LCP, solve it with Lemke's algorithm
# --------------------------------------------------------------------------------------------


def _as_contacts(points: np.ndarray | Sequence[Sequence[float]],
                 normals: np.ndarray | Sequence[Sequence[float]],
                 pusher_disps: np.ndarray | Sequence[Sequence[float]],
                 mu: float | Sequence[float] | np.ndarray,
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validate K contacts: (K, 2) points, unit inward normals, displacements; (K,) mu."""
    P = np.asarray(points, dtype=float).reshape(-1, 2)
    K = P.shape[0]
    N = np.asarray(normals, dtype=float).reshape(-1, 2)
    V = np.asarray(pusher_disps, dtype=float).reshape(-1, 2)
    if N.shape[0] != K or V.shape[0] != K:
        raise PushingError(f"points, normals and pusher_disps must all be (K, 2); got "
                           f"{P.shape}, {N.shape}, {V.shape}")
    norms = np.hypot(N[:, 0], N[:, 1])
    if K and not (norms.min() > 1e-12 and math.isfinite(norms.sum())):
        raise PushingError("every contact normal must be a non-zero finite vector; got "
                           f"norms {norms.tolist()}")
    mus = np.asarray(mu, dtype=float)
    if mus.ndim == 0:
        mus = np.full(K, float(mus))
    elif mus.shape != (K,):
        raise PushingError(f"mu must be one friction coefficient or one per contact ({K}), "
                           f"got shape {mus.shape}")
    if K and not (mus.min() >= 0.0 and math.isfinite(mus.sum())):
        raise PushingError(f"pusher friction coefficients must be finite and >= 0, got {mu!r}")
    return P, N / norms[:, None], V, mus


@functools.lru_cache(maxsize=16)
def _lcp_pattern(K: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The constant part of M for K contacts (E and -E^T), and the row maps of G: row k of G
    belongs to contact `contact_of_row[k]` with direction sign `sign_of_row[k]` (+n, +t, -t)."""
    n = 4 * K
    M0 = np.zeros((n, n))
    for i in range(K):
        M0[K + 2 * i, 3 * K + i] = M0[K + 2 * i + 1, 3 * K + i] = 1.0     # E
        M0[3 * K + i, K + 2 * i] = M0[3 * K + i, K + 2 * i + 1] = -1.0    # -E^T
    M0.setflags(write=False)
    contact_of_row = np.concatenate([np.arange(K), np.repeat(np.arange(K), 2)])
    sign_of_row = np.concatenate([np.ones(K), np.tile([1.0, -1.0], K)])
    return M0, contact_of_row, sign_of_row


def build_contact_lcp(c: float, points: np.ndarray | Sequence[Sequence[float]],
                      normals: np.ndarray | Sequence[Sequence[float]],
                      pusher_disps: np.ndarray | Sequence[Sequence[float]],
                      mu: float | Sequence[float] | np.ndarray) -> ContactLCP:
    """Assemble the quasistatic contact LCP (module docstring, §3) for K contacts.

    All arrays are (K, 2) in the object frame (m); normals are inward (normalised here); `mu`
    is one pusher-object friction coefficient or one per contact.
    """
    c = float(c)
    _check_c_mu(c, 0.0)
    P, Nrm, Vp, mus = _as_contacts(points, normals, pusher_disps, mu)
    K = P.shape[0]
    M0, contact_of_row, sign_of_row = _lcp_pattern(K)
    Tng = np.column_stack([-Nrm[:, 1], Nrm[:, 0]])          # t_i = R(+90°) n_i
    # Directions of the 3K rows of G: n_i (normal), then +t_i, -t_i (D_i = [t_i, -t_i]).
    dirs = np.concatenate([Nrm, Tng[contact_of_row[K:]]]) * sign_of_row[:, None]
    pts = P[contact_of_row]
    # Row d^T J_i with J_i = [[1, 0, -y_i], [0, 1, x_i]]: (d_x, d_y, x_i d_y - y_i d_x).
    G = np.empty((3 * K, 3))
    G[:, :2] = dirs
    G[:, 2] = pts[:, 0] * dirs[:, 1] - pts[:, 1] * dirs[:, 0]
    GA = G * np.array([1.0, 1.0, 1.0 / (c * c)])             # G A, A = diag(1, 1, 1/c^2) (LS)

    M = M0.copy()
    M[:3 * K, :3 * K] = GA @ G.T                             # [N; D] A [N; D]^T
    M[3 * K:, :K] = np.diag(mus)                             # U = diag(mu_i)
    q = np.zeros(4 * K)
    q[:3 * K] = -(dirs * Vp[contact_of_row]).sum(axis=1)     # -(n_i . v_i), -D_i^T v_i
    return ContactLCP(M, q, GA.T.copy(), K)


def _lexmin_row(rows: list[list[float]], tol: float = 1e-12) -> int:
    """Index of the lexicographically smallest row (entries equal within `tol`)."""
    best = 0
    for j in range(1, len(rows)):
        for a, b in zip(rows[j], rows[best], strict=True):
            if a < b - tol:
                best = j
                break
            if a > b + tol:
                break
    return best


def lemke(M: np.ndarray, q: np.ndarray, *, max_iterations: int | None = None,
          pivot_tol: float = 1e-9) -> LCPSolution:
    """Solve w = M z + q, w >= 0, z >= 0, w^T z = 0 by Lemke's complementary pivoting.

    Lemke (1965); Cottle, Pang & Stone (1992), §4.4, with the covering vector d = (1, ..., 1)
    with the lexicographic minimum-ratio rule (ties broken by the rows of the basis inverse)
    so that degenerate problems cannot cycle; the artificial variable z0 leaves as soon as it
    ties. M and q are first scaled to unit max-norm (z scales with q/M, w with q, the
    complementary bases do not change).

    Returns status 'solved', 'ray_termination' (the entering column has no positive entry: no
    solution found; for copositive M this certifies that the condition "z >= 0, Mz >= 0,
    z^T M z = 0 => z^T q >= 0" fails, see the module docstring) or 'iteration_limit' (default
    cap max(100, 20 n) pivots).
    """
    M = np.asarray(M, dtype=float)
    q = np.asarray(q, dtype=float).ravel()
    n = q.shape[0]
    if M.shape != (n, n):
        raise PushingError(f"lemke: M must be ({n}, {n}) to match q, got {M.shape}")
    if n == 0 or q.min() >= 0.0:                         # z = 0 is a solution
        return LCPSolution(np.zeros(n), q.copy(), "solved", 0)
    cap = max(100, 20 * n) if max_iterations is None else int(max_iterations)
    tableau = _LemkeTableau(M, q)
    # First pivot: z0 enters at max(-q_i); among ties the largest row index leaves (the
    # lexicographic rule for the perturbation q + (eps, eps^2, ...)).
    rhs = tableau.T[:, -1]
    ties = np.flatnonzero(rhs <= rhs.min() + 1e-14)
    leaving = tableau.pivot(int(ties[-1]), tableau.z0)
    entering = leaving + n                               # complement of the w that left
    for it in range(1, cap + 1):
        r = tableau.leaving_row(entering, pivot_tol)
        if r is None:
            return tableau.no_solution("ray_termination", it)
        leaving = tableau.pivot(r, entering)
        if leaving == tableau.z0:
            return tableau.solution(it)
        entering = leaving + n if leaving < n else leaving - n
    return tableau.no_solution("iteration_limit", cap)


class _LemkeTableau:
    """The tableau [I | -M | -d | q] of `lemke` over the variables (w_1..w_n, z_1..z_n, z0),
    scaled to unit max-norm; row r holds the basic variable basis[r], and columns 0..n-1 hold
    the basis inverse B^-1 (the initial basis is I)."""

    def __init__(self, M: np.ndarray, q: np.ndarray):
        n = q.shape[0]
        self.n, self.M, self.q = n, M, q
        self.q_scale = float(np.abs(q).max())
        self.m_scale = float(np.abs(M).max()) or 1.0
        self.z0 = 2 * n
        T = np.zeros((n, 2 * n + 2))
        T[:, :n] = np.eye(n)
        T[:, n:self.z0] = M * (-1.0 / self.m_scale)
        T[:, self.z0] = -1.0
        T[:, -1] = q * (1.0 / self.q_scale)
        self.T = T
        self.basis = list(range(n))

    def pivot(self, r: int, e: int) -> int:
        """Variable e enters the basis in row r; returns the variable that leaves."""
        T = self.T
        row = T[r] / T[r, e]
        T[:] -= T[:, e, None] * row
        T[r] = row
        leaving, self.basis[r] = self.basis[r], e
        return leaving

    def leaving_row(self, entering: int, pivot_tol: float) -> int | None:
        """The minimum-ratio test over the rows with a positive entry in the entering column
        (plain floats: n is small and this beats a dozen tiny numpy calls); ties go to z0's
        row (z0 leaves: solved), else to the lexicographic rule on the rows of B^-1. None: no
        positive entry (ray termination)."""
        T, n = self.T, self.n
        col = T[:, entering].tolist()
        rhs_list = T[:, -1].tolist()
        # Entries below pivot_tol relative to the column are rounding noise of exact zeros.
        threshold = pivot_tol * max(1.0, max(col), -min(col))
        best, cand = math.inf, []
        for i in range(n):
            if col[i] > threshold:
                ratio = rhs_list[i] / col[i]
                if ratio < best * (1.0 - 1e-10) - 1e-12:
                    best, cand = ratio, [i]
                elif ratio <= best * (1.0 + 1e-10) + 1e-12:
                    cand.append(i)
        if not cand:
            return None
        if len(cand) == 1:
            return cand[0]
        z0_rows = [k for k in cand if self.basis[k] == self.z0]
        if z0_rows:
            return z0_rows[0]
        return cand[_lexmin_row([[v / col[k] for v in T[k, :n].tolist()] for k in cand])]

    def solution(self, it: int) -> LCPSolution:
        n = self.n
        x = np.zeros(2 * n + 1)
        x[self.basis] = self.T[:, -1]
        z = np.maximum(x[n:self.z0], 0.0) * (self.q_scale / self.m_scale)
        return LCPSolution(z, self.M @ z + self.q, "solved", it)

    def no_solution(self, status: LCPStatus, it: int) -> LCPSolution:
        # Degenerate end: z0 is still basic but already ~0 (rounding kept it from leaving on a
        # tie), so the current almost-complementary point is complementary.
        if self.z0 in self.basis and self.T[self.basis.index(self.z0), -1] <= 1e-12:
            candidate = self.solution(it)
            if candidate.w.min() >= -1e-9 * self.q_scale:    # verified: w = M z + q >= 0
                return candidate
        nan = np.full(self.n, np.nan)
        return LCPSolution(nan, nan.copy(), status, it)


def multi_contact_twist(c: float, points: np.ndarray | Sequence[Sequence[float]],
                        normals: np.ndarray | Sequence[Sequence[float]],
                        pusher_disps: np.ndarray | Sequence[Sequence[float]],
                        mu: float | Sequence[float] | np.ndarray, *,
                        max_iterations: int | None = None) -> PushResult:
    """Object twist for K point contacts from the quasistatic LCP (module docstring, §3).

    Inputs as in `build_contact_lcp`. Mode 'moving' when some contact is loaded, 'separating'
    when none is (the object stays), 'jammed' when Lemke's algorithm finds no solution.
    """
    problem = build_contact_lcp(c, points, normals, pusher_disps, mu)
    return twist_from_lcp(problem, lemke(problem.M, problem.q, max_iterations=max_iterations))


def twist_from_lcp(problem: ContactLCP, solution: LCPSolution) -> PushResult:
    """Read the object twist V = A G^T (f_n, beta), the forces and the contact modes off an LCP
    solution (module docstring, §3)."""
    K = problem.num_contacts
    if not solution.solved:
        nan = np.full(K, np.nan)
        jammed: list[ContactMode] = ["jammed"] * K
        return PushResult(np.zeros(3), "jammed", nan, nan.copy(), tuple(jammed))
    z = solution.z
    twist = problem.twist_map @ z[:3 * K]
    f_n = z[:K].copy()
    f_t = z[K:3 * K:2] - z[K + 1:3 * K:2]
    lam = z[3 * K:]
    tol = 1e-9 * max(float(np.abs(problem.q).max()), 1e-300)
    modes: tuple[ContactMode, ...] = tuple(
        "separating" if f_n[i] <= tol else ("sliding" if lam[i] > tol else "sticking")
        for i in range(K))
    mode: PushMode = "moving" if np.any(f_n > tol) else "separating"
    if mode == "separating":
        twist = np.zeros(3)
    return PushResult(twist, mode, f_n, f_t, modes)


def object_twist(c: float, points: np.ndarray | Sequence[Sequence[float]],
                 normals: np.ndarray | Sequence[Sequence[float]],
                 pusher_disps: np.ndarray | Sequence[Sequence[float]],
                 mu: float | Sequence[float] | np.ndarray) -> PushResult:
    """Object twist for any number of contacts, by the cheapest exact route.

    - no contact, or no pusher moving into the object (all v_i·n_i <= 0): no motion;
    - one contact: the closed form (`single_contact_twist`);
    - several contacts: the LCP (`multi_contact_twist`). A contact whose pusher recedes is NOT
      dropped: another pusher may drive the object into it (then it blocks or jams). Shortcut:
      when exactly one contact pushes, its closed-form motion is returned if it penetrates no
      other contact — that is then an LCP solution (the other contacts unloaded, sliding slack
      lambda_j = |t_j·u_j|), so the answer is the same — except in the rare frictional
      indeterminate case (module docstring, §3), where `multi_contact_twist` may report
      'jammed' although this solution exists.
    Mode vocabulary: as `single_contact_twist` for one contact, as `multi_contact_twist` for
    several.
    """
    P, Nrm, Vp, mus = _as_contacts(points, normals, pusher_disps, mu)
    K = P.shape[0]
    if K == 1:
        return single_contact_twist(c, P[0], Nrm[0], Vp[0], float(mus[0]))
    pushing = np.flatnonzero(np.einsum("ij,ij->i", Nrm, Vp) > 0.0)
    if pushing.size == 0:
        _check_c_mu(float(c), 0.0)
        return PushResult(np.zeros(3), "separating", np.zeros(K), np.zeros(K),
                          ("separating",) * K)
    if pushing.size == 1:
        i = int(pushing[0])
        one = single_contact_twist(c, P[i], Nrm[i], Vp[i], float(mus[i]))
        vx, vy, w = one.twist
        # n_j . (J_j V - v_j) >= 0 for every other contact j (no penetration).
        v_at = np.column_stack([vx - w * P[:, 1], vy + w * P[:, 0]])
        gap_rate = np.einsum("ij,ij->i", Nrm, v_at - Vp)
        gap_rate[i] = 0.0
        if np.all(gap_rate >= -1e-12 * max(float(np.abs(Vp).max()), 1e-300)):
            f_n = np.zeros(K)
            f_t = np.zeros(K)
            f_n[i] = one.normal_forces[0]
            f_t[i] = one.tangential_forces[0]
            modes: list[ContactMode] = ["separating"] * K
            modes[i] = one.contact_modes[0]
            return PushResult(one.twist.copy(), "moving", f_n, f_t, tuple(modes))
    return multi_contact_twist(c, P, Nrm, Vp, mus)


# --------------------------------------------------------------------------------------------
# 4. SE(2): applying a twist, changing frames
# --------------------------------------------------------------------------------------------


def apply_twist(pose: Sequence[float] | np.ndarray,
                twist: Sequence[float] | np.ndarray) -> np.ndarray:
    """New world pose (x, y, yaw) after the object-frame twist (dx, dy, dtheta) over one step.

    pose ∘ exp(twist) with the exact SE(2) exponential (e.g. Lynch & Park 2017, Modern
    Robotics, Ch. 3; Solà et al. 2018, "A micro Lie theory", the SE(2) example): the body-frame
    translation is V(θ) (dx, dy) with V(θ) = [[sin θ, -(1 - cos θ)], [1 - cos θ, sin θ]] / θ,
    rotated into the world by the current yaw. Yaw is wrapped to [-pi, pi).
    """
    x, y, yaw = float(pose[0]), float(pose[1]), float(pose[2])
    dx, dy, th = float(twist[0]), float(twist[1]), float(twist[2])
    if abs(th) < 1e-6:                                   # series: sin θ/θ, (1 - cos θ)/θ
        th2 = th * th
        s, k = 1.0 - th2 / 6.0, th / 2.0 - th * th2 / 24.0
    else:
        s, k = math.sin(th) / th, (1.0 - math.cos(th)) / th
    bx, by = s * dx - k * dy, k * dx + s * dy              # body-frame translation V(θ) (dx, dy)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array([x + cy * bx - sy * by, y + sy * bx + cy * by, float(wrap_angle(yaw + th))])


def points_to_object_frame(pose: Sequence[float] | np.ndarray,
                           points: np.ndarray | Sequence[Sequence[float]]) -> np.ndarray:
    """World points (K, 2) -> object frame: R(yaw)^T (p - (x, y))."""
    x, y, yaw = float(pose[0]), float(pose[1]), float(pose[2])
    c, s = math.cos(yaw), math.sin(yaw)
    P = np.asarray(points, dtype=float).reshape(-1, 2)
    dx, dy = P[:, 0] - x, P[:, 1] - y
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy])


def vectors_to_object_frame(pose: Sequence[float] | np.ndarray,
                            vectors: np.ndarray | Sequence[Sequence[float]]) -> np.ndarray:
    """World free vectors (K, 2) — normals, pusher displacements — to the object frame:
    R(yaw)^T v."""
    yaw = float(pose[2])
    c, s = math.cos(yaw), math.sin(yaw)
    V = np.asarray(vectors, dtype=float).reshape(-1, 2)
    return np.column_stack([c * V[:, 0] + s * V[:, 1], -s * V[:, 0] + c * V[:, 1]])

