"""Quasistatic planar pushing of ONE object: limit surface, motion cone, multi-contact LCP.

This is the physics of King et al. (PC-RRT), §III-A, as specified in docs/design.md Objects move
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

3b. Several objects pushing each other (`build_multibody_lcp_kernel`)
   When a pushed object meets another, it pushes it in turn: one LCP over every object of the
   group (the quasistatic multi-body problem of Pang & Tedrake's quasistatic simulator and
   Haustein et al.'s Box2D model; King et al. 2015 do not model it). Each object's limit
   surface maps the wrench on it to its twist, scaled by its support load f_max = mu_s m g so
   that the objects share the motion by how hard each is to slide (for one object the scale
   cancels: §3 exactly); object-object contacts carry equal and opposite forces and a gap
   (speculative contacts: a gap may close within the step, a penetration is pushed out).

`object_twist` dispatches: no pushing contact -> no motion; one contact -> closed form; several
contacts -> the LCP (after a cheap exact shortcut when only one contact pushes and the closed
form motion does not run into the others).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit

from rearrangement_planner.model.errors import RearrangementError

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

    Uniform pressure over the support footprint (Lynch, Maekawa & Tanie 1992; docs/design.md):
    - 'disk' / 'cylinder': `size` is the radius R (or a sequence starting with it); c = 2R/3.
    - 'box' / 'rectangle': `size` is the FULL side lengths (x, y) or (x, y, z) as in the scene
      file; c = `rectangle_mean_distance(x/2, y/2)`.
    """
    dims = np.atleast_1d(np.asarray(size, dtype=float))
    if shape in _DISK_SHAPES:
        if dims.size < 1 or not (np.isfinite(dims[0]) and dims[0] > 0):
            raise PushingError(f"limit_surface_c('{shape}', {size!r}): size must be a positive "
                               "finite radius in metres")
        return 2.0 / 3.0 * float(dims[0])
    if shape in _RECTANGLE_SHAPES:
        if dims.size not in (2, 3) or not (np.isfinite(dims[:2]).all() and dims[:2].min() > 0):
            raise PushingError(f"limit_surface_c('{shape}', {size!r}): size must be the positive "
                               "full side lengths (x, y) or (x, y, z) in metres")
        a, b = 0.5 * float(dims[0]), 0.5 * float(dims[1])
        return rectangle_mean_distance(a, b)
    raise PushingError(f"limit_surface_c: unknown shape '{shape}'; expected one of "
                       f"{_DISK_SHAPES + _RECTANGLE_SHAPES}")


# --------------------------------------------------------------------------------------------
# 2. One contact: the motion cone
# --------------------------------------------------------------------------------------------

# Mode codes of the compiled kernels (`MODES[code]` is the name used in PushResult).
SEPARATING, STICKING, SLIDING, MOVING, JAMMED = 0, 1, 2, 3, 4
MODES: tuple[PushMode, ...] = ("separating", "sticking", "sliding", "moving", "jammed")
# Lemke status codes.
SOLVED, RAY_TERMINATION, ITERATION_LIMIT = 0, 1, 2
_STATUS: tuple[LCPStatus, ...] = ("solved", "ray_termination", "iteration_limit")


def _check_c_mu(c: float, mu: float) -> None:
    if not c > 0.0 or not math.isfinite(c):
        raise PushingError(f"limit-surface length c must be positive and finite, got {c!r} "
                           "(c = m_max/f_max in metres, see limit_surface_c)")
    if not mu >= 0.0 or not math.isfinite(mu):
        raise PushingError(f"pusher friction coefficient must be finite and >= 0, got {mu!r}")


@njit(cache=True)
def single_contact_kernel(c: float, x: float, y: float, nx: float, ny: float, vpx: float,
                          vpy: float, mu: float) -> tuple[float, float, float, int]:
    """The motion-cone model (module docstring, §2), compiled: (dx, dy, dtheta, mode code) for
    one contact at (x, y) with the UNIT inward normal (nx, ny) and pusher displacement
    (vpx, vpy), all in the object frame. Inputs are trusted (`single_contact_twist` checks
    them)."""
    vp_n = vpx * nx + vpy * ny
    if not vp_n > 0.0:  # separating (or tangential) pusher: no load, no motion
        return 0.0, 0.0, 0.0, SEPARATING
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
    if s_r <= s_p <= s_l:               # inside the motion cone: the contact sticks
        mode, vcx, vcy = STICKING, vpx, vpy
    elif s_p > s_l:                     # pusher slides towards +t: force on the edge n + mu t
        k = vp_n / vl_n
        mode, vcx, vcy = SLIDING, k * vl_x, k * vl_y
    else:                               # pusher slides towards -t: force on the edge n - mu t
        k = vp_n / vr_n
        mode, vcx, vcy = SLIDING, k * vr_x, k * vr_y
    # (STICK): the twist whose velocity at the contact is (vcx, vcy), the wrench a pure force
    # there (Lynch, Maekawa & Tanie 1992).
    den = c2 + x * x + y * y
    vx = ((c2 + x * x) * vcx + x * y * vcy) / den
    vy = (x * y * vcx + (c2 + y * y) * vcy) / den
    return vx, vy, (x * vy - y * vx) / c2, mode


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
    nx, ny = float(normal[0]), float(normal[1])
    nn = math.hypot(nx, ny)
    if not nn > 1e-12 or not math.isfinite(nn):
        raise PushingError(f"contact normal must be a non-zero finite vector, got {normal!r}")
    nx, ny = nx / nn, ny / nn
    vx, vy, w, code = single_contact_kernel(c, float(point[0]), float(point[1]), nx, ny,
                                            float(pusher_disp[0]), float(pusher_disp[1]), mu)
    mode = MODES[code]
    if code == SEPARATING:
        return PushResult(np.zeros(3), "separating", np.zeros(1), np.zeros(1), ("separating",))
    # With V = A F the contact force is the translational part of the twist (LCP units).
    return PushResult(np.array([vx, vy, w]), mode, np.array([vx * nx + vy * ny]),
                      np.array([-vx * ny + vy * nx]), (mode,))  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------
# 3. Several contacts: build the LCP, solve it with Lemke's algorithm
# --------------------------------------------------------------------------------------------


def _as_contacts(points: np.ndarray | Sequence[Sequence[float]],
                 normals: np.ndarray | Sequence[Sequence[float]],
                 pusher_disps: np.ndarray | Sequence[Sequence[float]],
                 mu: float | Sequence[float] | np.ndarray,
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Validate K contacts: (K, 2) points, unit inward normals, displacements; (K,) mu."""
    P = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 2))
    K = P.shape[0]
    N = np.asarray(normals, dtype=float).reshape(-1, 2)
    V = np.ascontiguousarray(np.asarray(pusher_disps, dtype=float).reshape(-1, 2))
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
    return P, N / norms[:, None], V, np.ascontiguousarray(mus)


LCP_CONTACTS = 64
"""The most contacts one contact problem of a physics step may have (an object's push, or a
group of objects in contact): the step's buffers hold that many (`lcp_scratch`, sized by its
square, whatever the number of objects), and a problem with more is refused as a jam. The
searches of eight varied scenes are the same with this bound as with none
(docs/benchmark.md)."""


@njit(cache=True)
def lcp_scratch(contacts: int, bodies: int) -> tuple[np.ndarray, np.ndarray]:
    """Buffers for the LCP of up to `contacts` contacts on up to `bodies` objects (floats,
    integers): what `object_twist_kernel` and `multibody_twists_kernel` carve their matrices
    and Lemke's tableau from (`_lcp_views`, `_lemke_views`), so that they allocate nothing
    and a physics step compiles without Numba's reference counting (`kernels.njit_bare`)."""
    n, r, cb = 4 * contacts, 3 * contacts, 3 * bodies
    floats = 2 * r * cb + n * n + n + cb * r + n * (2 * n + 2) + (2 * n + 2) + n \
        + (2 * n + 1) + 2 * n + cb
    return np.empty(floats), np.empty(2 * n, dtype=np.int64)


@njit(cache=True, inline="always")
def _lcp_views(floats: np.ndarray, K: int, B: int) -> tuple:
    """(G (3K, 3B), GA (3K, 3B), M (4K, 4K), q (4K,), twist_map (3B, 3K), the offset where
    Lemke's views begin) in `floats` (`lcp_scratch`). Inlined: kernels with and without
    reference counting call it, and a function that returns views must count them as its
    caller does (`kernels.njit_bare`)."""
    n, r, cb = 4 * K, 3 * K, 3 * B
    G = floats[:r * cb].reshape((r, cb))
    o = r * cb
    GA = floats[o:o + r * cb].reshape((r, cb))
    o += r * cb
    M = floats[o:o + n * n].reshape((n, n))
    o += n * n
    q = floats[o:o + n]
    o += n
    twist_map = floats[o:o + cb * r].reshape((cb, r))
    return G, GA, M, q, twist_map, o + cb * r


@njit(cache=True, inline="always")
def _lemke_views(floats: np.ndarray, integers: np.ndarray, o: int, n: int) -> tuple:
    """(T (n, 2n+2), row, col, x, z, w, basis, cand, the offset after them) of `lemke_into`
    for an LCP of size n, from offset `o` of `floats` (`lcp_scratch`). Inlined, as
    `_lcp_views`."""
    T = floats[o:o + n * (2 * n + 2)].reshape((n, 2 * n + 2))
    o += n * (2 * n + 2)
    row = floats[o:o + 2 * n + 2]
    o += 2 * n + 2
    col = floats[o:o + n]
    o += n
    x = floats[o:o + 2 * n + 1]
    o += 2 * n + 1
    z = floats[o:o + n]
    o += n
    w = floats[o:o + n]
    return T, row, col, x, z, w, integers[:n], integers[n:2 * n], o + n


@njit(cache=True, inline="always")
def _abs_max(a: np.ndarray) -> float:
    """max |a_i| of a 1-D array (0 when empty), without the temporary of np.abs(a).max()."""
    best = 0.0
    for i in range(a.shape[0]):
        best = max(best, abs(a[i]))
    return best


@njit(cache=True)
def _product_transposed(A: np.ndarray, B: np.ndarray, out: np.ndarray, rows: int) -> None:
    """out[:rows, :rows] = A @ B.T for A, B (rows, k), written out (no temporary)."""
    for i in range(rows):
        for j in range(rows):
            s = 0.0
            for k in range(A.shape[1]):
                s += A[i, k] * B[j, k]
            out[i, j] = s


@njit(cache=True)
def _build_lcp_into(c: float, P: np.ndarray, N: np.ndarray, V: np.ndarray, mus: np.ndarray,
                    G: np.ndarray, GA: np.ndarray, M: np.ndarray, q: np.ndarray,
                    twist_map: np.ndarray) -> None:
    """(M, q, twist_map) of the contact LCP (module docstring, §3) for K contacts with unit
    normals, written into the views of `_lcp_views` (B = 1), G and GA its scratch."""
    K = P.shape[0]
    for i in range(K):
        nx, ny = N[i, 0], N[i, 1]
        tx, ty = -ny, nx                                    # t_i = R(+90°) n_i
        # Rows of G: n_i (normal), then +t_i, -t_i (D_i = [t_i, -t_i]); row d^T J_i with
        # J_i = [[1, 0, -y_i], [0, 1, x_i]] is (d_x, d_y, x_i d_y - y_i d_x).
        for row, dx, dy in ((i, nx, ny), (K + 2 * i, tx, ty), (K + 2 * i + 1, -tx, -ty)):
            G[row, 0], G[row, 1] = dx, dy
            G[row, 2] = P[i, 0] * dy - P[i, 1] * dx
            q[row] = -(dx * V[i, 0] + dy * V[i, 1])         # -(n_i.v_i), -D_i^T v_i
    inv_c2 = 1.0 / (c * c)
    for row in range(3 * K):                                # G A, A = diag(1, 1, 1/c^2) (LS)
        GA[row, 0], GA[row, 1], GA[row, 2] = G[row, 0], G[row, 1], G[row, 2] * inv_c2
    n = 4 * K
    _fill(M, 0.0)
    _product_transposed(GA, G, M, 3 * K)                    # [N; D] A [N; D]^T
    for i in range(K):
        M[K + 2 * i, 3 * K + i] = M[K + 2 * i + 1, 3 * K + i] = 1.0     # E
        M[3 * K + i, K + 2 * i] = M[3 * K + i, K + 2 * i + 1] = -1.0    # -E^T
        M[3 * K + i, i] = mus[i]                                        # U = diag(mu_i)
    for row in range(3 * K, n):
        q[row] = 0.0
    _transpose_into(GA, twist_map)


@njit(cache=True)
def _fill(a: np.ndarray, value: float) -> None:
    """Every entry of the 2-D array a set to `value`."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            a[i, j] = value


@njit(cache=True)
def _transpose_into(a: np.ndarray, out: np.ndarray) -> None:
    """out = a.T, written out."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            out[j, i] = a[i, j]


@njit(cache=True)
def build_lcp_kernel(c: float, P: np.ndarray, N: np.ndarray, V: np.ndarray,
                     mus: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, q, twist_map) of the contact LCP (module docstring, §3) for K contacts with unit
    normals, compiled, in arrays of their own; `build_contact_lcp` checks the inputs."""
    K = P.shape[0]
    floats, _ = lcp_scratch(K, 1)
    G, GA, M, q, twist_map, _ = _lcp_views(floats, K, 1)
    _build_lcp_into(c, P, N, V, mus, G, GA, M, q, twist_map)
    return M.copy(), q.copy(), twist_map.copy()


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
    M, q, twist_map = build_lcp_kernel(c, P, np.ascontiguousarray(Nrm), Vp, mus)
    return ContactLCP(M, q, twist_map, P.shape[0])


@njit(cache=True)
def _pivot(T: np.ndarray, basis: np.ndarray, r: int, e: int, row: np.ndarray,
           col: np.ndarray) -> int:
    """Variable e enters the basis in row r of the tableau; returns the variable that leaves.
    `row` and `col` are scratch (2n + 2 and n)."""
    pivot = T[r, e]
    for j in range(T.shape[1]):
        row[j] = T[r, j] / pivot
    for i in range(T.shape[0]):
        col[i] = T[i, e]
    for i in range(T.shape[0]):
        for j in range(T.shape[1]):
            T[i, j] -= col[i] * row[j]
    for j in range(T.shape[1]):
        T[r, j] = row[j]
    leaving = basis[r]
    basis[r] = e
    return leaving


@njit(cache=True)
def _leaving_row(T: np.ndarray, basis: np.ndarray, n: int, entering: int,
                 pivot_tol: float, cand: np.ndarray) -> int:
    """The minimum-ratio test over the rows with a positive entry in the entering column; ties
    go to z0's row (z0 leaves: solved), else to the lexicographic rule on the rows of B^-1
    (tolerance 1e-12). -1: no positive entry (ray termination). `cand` is scratch (n)."""
    col = T[:, entering]
    # Entries below pivot_tol relative to the column are rounding noise of exact zeros.
    largest = -math.inf
    smallest = math.inf
    for i in range(col.shape[0]):
        largest = max(largest, col[i])
        smallest = min(smallest, col[i])
    threshold = pivot_tol * max(1.0, max(largest, -smallest))
    best = math.inf
    count = 0
    for i in range(n):
        if col[i] > threshold:
            ratio = T[i, -1] / col[i]
            if ratio < best * (1.0 - 1e-10) - 1e-12:
                best = ratio
                cand[0] = i
                count = 1
            elif ratio <= best * (1.0 + 1e-10) + 1e-12:
                cand[count] = i
                count += 1
    if count == 0:
        return -1
    if count == 1:
        return cand[0]
    z0 = 2 * n
    for k in range(count):
        if basis[cand[k]] == z0:
            return cand[k]
    best_k = 0
    for j in range(1, count):
        kj, kb = cand[j], cand[best_k]
        for m in range(n):
            a, b = T[kj, m] / col[kj], T[kb, m] / col[kb]
            if a < b - 1e-12:
                best_k = j
                break
            if a > b + 1e-12:
                break
    return cand[best_k]


@njit(cache=True)
def _lemke_solution(M: np.ndarray, q: np.ndarray, T: np.ndarray, basis: np.ndarray,
                    scale: float, x: np.ndarray, z: np.ndarray, w: np.ndarray) -> None:
    """The tableau's basic solution: z (unscaled) and w = M z + q, with the scratch x."""
    n = q.shape[0]
    for i in range(2 * n + 1):
        x[i] = 0.0
    for r in range(n):
        x[basis[r]] = T[r, -1]
    for i in range(n):
        z[i] = max(x[n + i], 0.0) * scale
    for i in range(n):
        s = 0.0
        for j in range(n):
            s += M[i, j] * z[j]
        w[i] = s + q[i]


@njit(cache=True)
def _lemke_tableau(M: np.ndarray, q: np.ndarray, T: np.ndarray,
                   basis: np.ndarray) -> tuple[float, float]:
    """Lemke's starting tableau [I | -M | -d | q] over (w_1..w_n, z_1..z_n, z0), scaled to
    unit max-norm, into T; row r holds the basic variable basis[r] (initially w_r), columns
    0..n-1 hold B^-1 (initially I). Returns the scales of q and M."""
    n = q.shape[0]
    q_scale = _abs_max(q)
    m_scale = 0.0
    for i in range(n):
        m_scale = max(m_scale, _abs_max(M[i]))
    if m_scale == 0.0:
        m_scale = 1.0
    _fill(T, 0.0)
    m_factor, q_factor = -1.0 / m_scale, 1.0 / q_scale
    for i in range(n):
        T[i, i] = 1.0
        for j in range(n):
            T[i, n + j] = M[i, j] * m_factor
        T[i, 2 * n] = -1.0
        T[i, 2 * n + 1] = q[i] * q_factor
        basis[i] = i
    return q_scale, m_scale


@njit(cache=True)
def lemke_into(M: np.ndarray, q: np.ndarray, cap: int, pivot_tol: float, T: np.ndarray,
               row: np.ndarray, col: np.ndarray, x: np.ndarray, z: np.ndarray, w: np.ndarray,
               basis: np.ndarray, cand: np.ndarray) -> tuple[int, int]:
    """Lemke's method as `lemke` describes it, compiled, in the scratch of `_lemke_views`:
    writes z and w, returns (status code, iterations)."""
    n = q.shape[0]
    q_min = math.inf
    for i in range(n):
        q_min = min(q_min, q[i])
    if n == 0 or q_min >= 0.0:                           # z = 0 is a solution
        for i in range(n):
            z[i], w[i] = 0.0, q[i]
        return SOLVED, 0
    q_scale, m_scale = _lemke_tableau(M, q, T, basis)
    z0 = 2 * n
    # First pivot: z0 enters at max(-q_i); among ties the largest row index leaves (the
    # lexicographic rule for the perturbation q + (eps, eps^2, ...)).
    rhs_min = math.inf
    for i in range(n):
        rhs_min = min(rhs_min, T[i, -1])
    first = 0
    for i in range(n):
        if T[i, -1] <= rhs_min + 1e-14:
            first = i
    leaving = _pivot(T, basis, first, z0, row, col)
    entering = leaving + n                               # complement of the w that left
    scale = q_scale / m_scale
    status, iterations = ITERATION_LIMIT, cap
    for it in range(1, cap + 1):
        r = _leaving_row(T, basis, n, entering, pivot_tol, cand)
        if r < 0:
            status, iterations = RAY_TERMINATION, it
            break
        leaving = _pivot(T, basis, r, entering, row, col)
        if leaving == z0:
            _lemke_solution(M, q, T, basis, scale, x, z, w)
            return SOLVED, it
        entering = leaving + n if leaving < n else leaving - n
    # Degenerate end: z0 is still basic but already ~0 (rounding kept it from leaving on a
    # tie), so the current almost-complementary point is complementary.
    for r in range(n):
        if basis[r] == z0 and T[r, -1] <= 1e-12:
            _lemke_solution(M, q, T, basis, scale, x, z, w)
            w_min = math.inf
            for i in range(n):
                w_min = min(w_min, w[i])
            if w_min >= -1e-9 * q_scale:                 # verified: w = M z + q >= 0
                return SOLVED, iterations
    for i in range(n):
        z[i] = w[i] = np.nan
    return status, iterations


@njit(cache=True)
def lemke_kernel(M: np.ndarray, q: np.ndarray, cap: int,
                 pivot_tol: float) -> tuple[np.ndarray, np.ndarray, int, int]:
    """`lemke_into` in arrays of its own: (z, w, status code, iterations)."""
    n = q.shape[0]
    floats, integers = lcp_scratch(n // 4 + 1, 1)
    T, row, col, x, z, w, basis, cand, _ = _lemke_views(floats, integers, 0, n)
    status, iterations = lemke_into(M, q, cap, pivot_tol, T, row, col, x, z, w, basis, cand)
    return z.copy(), w.copy(), status, iterations


def lemke(M: np.ndarray, q: np.ndarray, *, max_iterations: int | None = None,
          pivot_tol: float = 1e-9) -> LCPSolution:
    """Solve w = M z + q, w >= 0, z >= 0, w^T z = 0 by Lemke's complementary pivoting.

    Lemke (1965); Cottle, Pang & Stone (1992), §4.4, with the covering vector d = (1, ..., 1)
    with the lexicographic minimum-ratio rule (ties broken by the rows of the basis inverse)
    so that degenerate problems cannot cycle; the artificial variable z0 leaves as soon as it
    ties. M and q are first scaled to unit max-norm (z scales with q/M, w with q, the
    complementary bases do not change). Compiled (`lemke_kernel`).

    Returns status 'solved', 'ray_termination' (the entering column has no positive entry: no
    solution found; for copositive M this certifies that the condition "z >= 0, Mz >= 0,
    z^T M z = 0 => z^T q >= 0" fails, see the module docstring) or 'iteration_limit' (default
    cap max(100, 20 n) pivots).
    """
    M = np.ascontiguousarray(np.asarray(M, dtype=float))
    q = np.ascontiguousarray(np.asarray(q, dtype=float).ravel())
    n = q.shape[0]
    if M.shape != (n, n):
        raise PushingError(f"lemke: M must be ({n}, {n}) to match q, got {M.shape}")
    cap = max(100, 20 * n) if max_iterations is None else int(max_iterations)
    z, w, status, iterations = lemke_kernel(M, q, cap, float(pivot_tol))
    return LCPSolution(z, w, _STATUS[status], iterations)


@njit(cache=True)
def _forces_and_modes(twist_map: np.ndarray, q: np.ndarray, z: np.ndarray, K: int,
                      twist: np.ndarray, f_n: np.ndarray, f_t: np.ndarray,
                      modes: np.ndarray) -> int:
    """Read the object twist V = A G^T (f_n, beta), the forces and the contact modes off an
    LCP solution z (module docstring, §3) into the output arrays; returns the mode code."""
    tol = 1e-9 * max(_abs_max(q), 1e-300)
    loaded = False
    for i in range(K):
        f_n[i] = z[i]
        f_t[i] = z[K + 2 * i] - z[K + 2 * i + 1]
        if z[i] <= tol:
            modes[i] = SEPARATING
        else:
            loaded = True
            modes[i] = SLIDING if z[3 * K + i] > tol else STICKING
    if not loaded:
        twist[0] = twist[1] = twist[2] = 0.0
        return SEPARATING
    _map_into(twist_map, z, 3 * K, twist)
    return MOVING


@njit(cache=True)
def _map_into(twist_map: np.ndarray, z: np.ndarray, count: int, out: np.ndarray) -> None:
    """out = twist_map @ z[:count], written out."""
    for r in range(twist_map.shape[0]):
        s = 0.0
        for k in range(count):
            s += twist_map[r, k] * z[k]
        out[r] = s


@njit(cache=True)
def object_twist_kernel(c: float, P: np.ndarray, N: np.ndarray, V: np.ndarray, mus: np.ndarray,
                        cap: int, twist: np.ndarray, f_n: np.ndarray, f_t: np.ndarray,
                        modes: np.ndarray, floats: np.ndarray, integers: np.ndarray) -> int:
    """`object_twist` compiled (K >= 1 contacts with unit normals): writes the twist, the
    forces and the contact modes, returns the mode code (JAMMED: zero twist, NaN forces).
    `floats` and `integers`: the LCP's scratch (`lcp_scratch`, K contacts or more)."""
    K = P.shape[0]
    if K == 1:
        vx, vy, w, code = single_contact_kernel(c, P[0, 0], P[0, 1], N[0, 0], N[0, 1],
                                                V[0, 0], V[0, 1], mus[0])
        twist[0], twist[1], twist[2] = vx, vy, w
        f_n[0] = vx * N[0, 0] + vy * N[0, 1]
        f_t[0] = -vx * N[0, 1] + vy * N[0, 0]
        modes[0] = code
        return code
    pushing, pusher = 0, -1
    for i in range(K):
        if N[i, 0] * V[i, 0] + N[i, 1] * V[i, 1] > 0.0:
            pushing += 1
            pusher = i
    if pushing == 0:
        twist[0] = twist[1] = twist[2] = 0.0
        for i in range(K):
            f_n[i], f_t[i], modes[i] = 0.0, 0.0, SEPARATING
        return SEPARATING
    if pushing == 1:
        # The closed form of the one pushing contact is an LCP solution when it penetrates no
        # other contact: n_j . (J_j V - v_j) >= 0 for every other j.
        i = pusher
        vx, vy, w, code = single_contact_kernel(c, P[i, 0], P[i, 1], N[i, 0], N[i, 1],
                                                V[i, 0], V[i, 1], mus[i])
        vmax = 1e-300
        for j in range(K):
            vmax = max(vmax, abs(V[j, 0]), abs(V[j, 1]))
        clear = True
        for j in range(K):
            if j != i:
                ux = vx - w * P[j, 1] - V[j, 0]
                uy = vy + w * P[j, 0] - V[j, 1]
                if N[j, 0] * ux + N[j, 1] * uy < -1e-12 * vmax:
                    clear = False
                    break
        if clear:
            twist[0], twist[1], twist[2] = vx, vy, w
            for j in range(K):
                f_n[j], f_t[j], modes[j] = 0.0, 0.0, SEPARATING
            f_n[i] = vx * N[i, 0] + vy * N[i, 1]
            f_t[i] = -vx * N[i, 1] + vy * N[i, 0]
            modes[i] = code
            return MOVING
    G, GA, M, q, twist_map, o = _lcp_views(floats, K, 1)
    _build_lcp_into(c, P, N, V, mus, G, GA, M, q, twist_map)
    T, row, col, x, z, w, basis, cand, _ = _lemke_views(floats, integers, o, 4 * K)
    status, _ = lemke_into(M, q, cap, 1e-9, T, row, col, x, z, w, basis, cand)
    if status != SOLVED:
        twist[0] = twist[1] = twist[2] = 0.0
        for i in range(K):
            f_n[i], f_t[i], modes[i] = np.nan, np.nan, JAMMED
        return JAMMED
    return _forces_and_modes(twist_map, q, z, K, twist, f_n, f_t, modes)


@njit(cache=True)
def object_twist_about_kernel(c: float, cx: float, cy: float, P: np.ndarray, N: np.ndarray,
                              V: np.ndarray, mus: np.ndarray, cap: int, twist: np.ndarray,
                              f_n: np.ndarray, f_t: np.ndarray, modes: np.ndarray,
                              floats: np.ndarray, integers: np.ndarray) -> int:
    """`object_twist_kernel` for an object whose centre of friction is (cx, cy) in its frame
    (m; the support pressure's centre, `model.scene.SupportPressure`): the limit surface
    (LS) holds about that point, so the contacts are taken relative to it, and the twist it
    gives (the motion of the centre of friction) is moved back to the object's origin:
    v_o = v_c + omega x (o - c) = (v_cx + omega cy, v_cy - omega cx). With (cx, cy) = 0 it
    is `object_twist_kernel` exactly. P is shifted in place and restored."""
    if cx == 0.0 and cy == 0.0:
        return object_twist_kernel(c, P, N, V, mus, cap, twist, f_n, f_t, modes, floats,
                                   integers)
    for i in range(P.shape[0]):
        P[i, 0] -= cx
        P[i, 1] -= cy
    code = object_twist_kernel(c, P, N, V, mus, cap, twist, f_n, f_t, modes, floats,
                               integers)
    for i in range(P.shape[0]):
        P[i, 0] += cx
        P[i, 1] += cy
    twist[0] += twist[2] * cy
    twist[1] -= twist[2] * cx
    return code


# --------------------------------------------------------------------------------------------
# 3b. Several objects pushing each other: one LCP over all of them
# --------------------------------------------------------------------------------------------


@njit(cache=True)
def _multibody_rows(centres: np.ndarray, P: np.ndarray, N: np.ndarray, body: np.ndarray,
                    other: np.ndarray, V: np.ndarray, gaps: np.ndarray, G: np.ndarray,
                    q: np.ndarray) -> None:
    """G (3K x 3B) and q (4K,) of `build_multibody_lcp_kernel`, written: per contact k the
    rows d^T J for d = n_k, +t_k, -t_k (+J for body[k], -J for other[k]) and their q."""
    K = P.shape[0]
    _fill(G, 0.0)
    for r in range(4 * K):
        q[r] = 0.0
    for k in range(K):
        nx, ny = N[k, 0], N[k, 1]
        tx, ty = -ny, nx
        for row, dx, dy in ((k, nx, ny), (K + 2 * k, tx, ty), (K + 2 * k + 1, -tx, -ty)):
            a = body[k]
            G[row, 3 * a] = dx
            G[row, 3 * a + 1] = dy
            G[row, 3 * a + 2] = (P[k, 0] - centres[a, 0]) * dy - (P[k, 1] - centres[a, 1]) * dx
            b = other[k]
            if b >= 0:
                G[row, 3 * b] -= dx
                G[row, 3 * b + 1] -= dy
                G[row, 3 * b + 2] -= ((P[k, 0] - centres[b, 0]) * dy
                                      - (P[k, 1] - centres[b, 1]) * dx)
            else:
                q[row] = -(dx * V[k, 0] + dy * V[k, 1])
        q[k] += gaps[k]


@njit(cache=True)
def build_multibody_lcp_into(centres: np.ndarray, cs: np.ndarray, weights: np.ndarray,
                             P: np.ndarray, N: np.ndarray, body: np.ndarray,
                             other: np.ndarray, V: np.ndarray, gaps: np.ndarray,
                             mus: np.ndarray, G: np.ndarray, GA: np.ndarray, M: np.ndarray,
                             q: np.ndarray, twist_map: np.ndarray) -> None:
    """(M, q, twist_map) of the quasistatic LCP of module docstring §3 over B objects at once
    (module docstring, §3b), compiled. Everything is in the world frame (m):

    - object b has its limit surface about `centres[b]` (its centre of friction) with
      c = `cs[b]`, and the scale `weights[b]` = f_ref / f_max,b (f_max = mu_s m g): its twist
      about that point is V_b = weights[b] diag(1, 1, 1/c_b^2) F_b, F_b the wrench on it
      there. One object alone gives the twist of §3 (the scale cancels); between objects
      it shares the motion by their support loads, as a heavier or grippier object gives way
      less;
    - contact k at P[k] with unit normal N[k] pointing into object body[k] (the one it
      pushes); the force on it is f_n N[k] + f_t t_k, t_k = R(+90°) N[k]; on other[k] the
      opposite, or, when other[k] = -1, the pusher (the arm) moves by V[k] (its displacement
      over the step, m);
    - non-penetration with a gap: the normal velocity of body[k] relative to the other side
      at P[k] is at least -gaps[k] (an object-object contact gaps[k] apart may close by that
      much, one penetrating by -gaps[k] is pushed apart; an arm contact's gap is 0, its V[k]
      already undoes its penetration); Coulomb friction mus[k] with maximal dissipation, as
      in §3.

    The rows of G (3K x 3B) are d^T J for d = n_k, +t_k, -t_k, with J_b(p) V = (v_x - w
    (p_y - c_y), v_y + w (p_x - c_x)) for body[k] and -J for other[k]; M, E, U as in §3 with
    A the block-diagonal of the weighted limit surfaces; q = -(d . V[k]) + (gaps[k] on the
    normal row). The twists are twist_map @ z[:3K] (3B: v_x, v_y, omega per object, about its
    centre of friction, world frame). Written into the views of `_lcp_views`, G and GA its
    scratch."""
    K, B = P.shape[0], centres.shape[0]
    _multibody_rows(centres, P, N, body, other, V, gaps, G, q)
    for r in range(3 * K):
        for b in range(B):
            GA[r, 3 * b] = G[r, 3 * b] * weights[b]
            GA[r, 3 * b + 1] = G[r, 3 * b + 1] * weights[b]
            GA[r, 3 * b + 2] = G[r, 3 * b + 2] * (weights[b] / (cs[b] * cs[b]))
    _fill(M, 0.0)
    _product_transposed(GA, G, M, 3 * K)
    # A compliance of MULTIBODY_COMPLIANCE times the largest diagonal entry on the force
    # block: a group in contact has many redundant contacts (a face pushed flat against a
    # face), whose singular M stalls Lemke's method on its degenerate pivots; the regularised
    # M is strictly copositive on the forces; the twists move by a relative 1e-3 or less
    # (1e-8 leaves three of seven pushed rows of objects in test jammed).
    largest = 0.0
    for r in range(4 * K):
        largest = max(largest, abs(M[r, r]))
    eps = MULTIBODY_COMPLIANCE * max(largest, 1e-300)
    for r in range(3 * K):
        M[r, r] += eps
    for k in range(K):
        M[K + 2 * k, 3 * K + k] = M[K + 2 * k + 1, 3 * K + k] = 1.0     # E
        M[3 * K + k, K + 2 * k] = M[3 * K + k, K + 2 * k + 1] = -1.0    # -E^T
        M[3 * K + k, k] = mus[k]                                        # U
    _transpose_into(GA, twist_map)


@njit(cache=True)
def build_multibody_lcp_kernel(centres: np.ndarray, cs: np.ndarray, weights: np.ndarray,
                               P: np.ndarray, N: np.ndarray, body: np.ndarray,
                               other: np.ndarray, V: np.ndarray, gaps: np.ndarray,
                               mus: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(M, q, twist_map) of `build_multibody_lcp_into`, in arrays of their own."""
    K, B = P.shape[0], centres.shape[0]
    floats, _ = lcp_scratch(K, B)
    G, GA, M, q, twist_map, _ = _lcp_views(floats, K, B)
    build_multibody_lcp_into(centres, cs, weights, P, N, body, other, V, gaps, mus, G, GA, M,
                             q, twist_map)
    return M.copy(), q.copy(), twist_map.copy()


MULTIBODY_COMPLIANCE = 1e-6
"""Relative compliance added to the multi-body LCP's force block (`build_multibody_lcp_kernel`)."""


@njit(cache=True)
def multibody_twists_kernel(centres: np.ndarray, cs: np.ndarray, weights: np.ndarray,
                            P: np.ndarray, N: np.ndarray, body: np.ndarray, other: np.ndarray,
                            V: np.ndarray, gaps: np.ndarray, mus: np.ndarray, cap: int,
                            twists: np.ndarray, floats: np.ndarray,
                            integers: np.ndarray) -> int:
    """Solve the LCP of `build_multibody_lcp_kernel` (Lemke): writes each object's twist
    about its centre of friction (B, 3) (world frame) and returns MOVING, SEPARATING (no
    contact loaded: nothing moves) or JAMMED (no solution: the pushers squeeze the group;
    zero twists). `floats` and `integers` are its scratch (`lcp_scratch`, for K contacts
    and B objects or more): it allocates nothing."""
    K, B = P.shape[0], centres.shape[0]
    G, GA, M, q, twist_map, o = _lcp_views(floats, K, B)
    build_multibody_lcp_into(centres, cs, weights, P, N, body, other, V, gaps, mus, G, GA, M,
                             q, twist_map)
    T, row, col, x, z, w, basis, cand, o = _lemke_views(floats, integers, o, 4 * K)
    status, _ = lemke_into(M, q, cap, 1e-9, T, row, col, x, z, w, basis, cand)
    _fill(twists, 0.0)
    if status != SOLVED:
        return JAMMED
    loaded = -math.inf
    for k in range(K):
        loaded = max(loaded, z[k])
    if loaded <= 1e-9 * max(_abs_max(q), 1e-300):
        return SEPARATING
    flat = floats[o:o + 3 * B]
    _map_into(twist_map, z, 3 * K, flat)
    for b in range(B):
        twists[b, 0], twists[b, 1], twists[b, 2] = flat[3 * b], flat[3 * b + 1], flat[3 * b + 2]
    return MOVING


def multibody_twists(centres: np.ndarray, cs: np.ndarray, weights: np.ndarray,
                     points: np.ndarray, normals: np.ndarray, body: np.ndarray,
                     other: np.ndarray, pusher_disps: np.ndarray, gaps: np.ndarray,
                     mus: np.ndarray) -> tuple[str, np.ndarray]:
    """Objects pushing each other (module docstring, §3b; `build_multibody_lcp_kernel` says
    what each array is): the mode ('moving', 'separating' or 'jammed') and each object's
    twist (B, 3) about its centre of friction, world frame."""
    arrays = [np.ascontiguousarray(np.asarray(a, dtype=float)) for a in
              (centres, cs, weights, points, normals, pusher_disps, gaps, mus)]
    centres_, cs_, weights_, P, Nrm, Vp, gaps_, mus_ = arrays
    norms = np.hypot(Nrm[:, 0], Nrm[:, 1])
    if Nrm.shape[0] and not norms.min() > 1e-12:
        raise PushingError("every contact normal must be a non-zero vector")
    twists = np.zeros((centres_.shape[0], 3))
    floats, integers = lcp_scratch(P.reshape(-1, 2).shape[0], centres_.reshape(-1, 2).shape[0])
    code = multibody_twists_kernel(
        centres_.reshape(-1, 2), cs_, weights_, P.reshape(-1, 2), Nrm.reshape(-1, 2)
        / norms[:, None], np.asarray(body, dtype=np.int64), np.asarray(other, dtype=np.int64),
        Vp.reshape(-1, 2), gaps_, mus_, max(100, 80 * P.shape[0]), twists, floats, integers)
    return MODES[code], twists


def _push_result(code: int, twist: np.ndarray, f_n: np.ndarray, f_t: np.ndarray,
                 modes: np.ndarray) -> PushResult:
    contact_modes: tuple[ContactMode, ...] = tuple(
        MODES[m] for m in modes.tolist())  # type: ignore[misc]
    if code == SEPARATING:
        twist = np.zeros(3)
    return PushResult(twist, MODES[code], f_n, f_t, contact_modes)


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
    twist, f_n, f_t = np.empty(3), np.empty(K), np.empty(K)
    modes = np.empty(K, dtype=np.int64)
    code = _forces_and_modes(problem.twist_map, problem.q, np.ascontiguousarray(solution.z), K,
                             twist, f_n, f_t, modes)
    return _push_result(code, twist, f_n, f_t, modes)


def object_twist(c: float, points: np.ndarray | Sequence[Sequence[float]],
                 normals: np.ndarray | Sequence[Sequence[float]],
                 pusher_disps: np.ndarray | Sequence[Sequence[float]],
                 mu: float | Sequence[float] | np.ndarray,
                 centre: Sequence[float] = (0.0, 0.0)) -> PushResult:
    """Object twist for any number of contacts, by the cheapest exact route (compiled:
    `object_twist_about_kernel`, which `Physics.step` calls directly). `centre`: the centre
    of friction (m, object frame; the footprint's centre under uniform pressure), about which
    the limit surface holds; the twist is always that of the object's origin.

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
    cx, cy = float(centre[0]), float(centre[1])
    if not (math.isfinite(cx) and math.isfinite(cy)):
        raise PushingError(f"centre of friction must be finite, got {centre!r}")
    if K == 0:
        _check_c_mu(float(c), 0.0)
        return PushResult(np.zeros(3), "separating", np.zeros(0), np.zeros(0), ())
    _check_c_mu(float(c), float(mus.max()))
    if K == 1 and cx == 0.0 and cy == 0.0:
        return single_contact_twist(c, P[0], Nrm[0], Vp[0], float(mus[0]))
    twist, f_n, f_t = np.empty(3), np.empty(K), np.empty(K)
    modes = np.empty(K, dtype=np.int64)
    floats, integers = lcp_scratch(K, 1)
    code = object_twist_about_kernel(float(c), cx, cy, P.copy(), np.ascontiguousarray(Nrm),
                                     Vp, mus, 20 * 4 * K, twist, f_n, f_t, modes, floats,
                                     integers)
    return _push_result(code, twist, f_n, f_t, modes)


# --------------------------------------------------------------------------------------------
# 4. SE(2): applying a twist, changing frames
# --------------------------------------------------------------------------------------------


@njit(cache=True)
def apply_twist_kernel(x: float, y: float, yaw: float, dx: float, dy: float,
                       th: float) -> tuple[float, float, float]:
    """`apply_twist`, compiled."""
    if abs(th) < 1e-6:                                   # series: sin θ/θ, (1 - cos θ)/θ
        th2 = th * th
        s, k = 1.0 - th2 / 6.0, th / 2.0 - th * th2 / 24.0
    else:
        s, k = math.sin(th) / th, (1.0 - math.cos(th)) / th
    bx, by = s * dx - k * dy, k * dx + s * dy              # body-frame translation V(θ) (dx, dy)
    cy, sy = math.cos(yaw), math.sin(yaw)
    # Yaw wrapped to [-pi, pi) as `state.wrap_angle` does.
    new_yaw = (yaw + th + math.pi) % (2.0 * math.pi) - math.pi
    return x + cy * bx - sy * by, y + sy * bx + cy * by, new_yaw


def apply_twist(pose: Sequence[float] | np.ndarray,
                twist: Sequence[float] | np.ndarray) -> np.ndarray:
    """New world pose (x, y, yaw) after the object-frame twist (dx, dy, dtheta) over one step.

    pose ∘ exp(twist) with the exact SE(2) exponential (e.g. Lynch & Park 2017, Modern
    Robotics, Ch. 3; Solà et al. 2018, "A micro Lie theory", the SE(2) example): the body-frame
    translation is V(θ) (dx, dy) with V(θ) = [[sin θ, -(1 - cos θ)], [1 - cos θ, sin θ]] / θ,
    rotated into the world by the current yaw. Yaw is wrapped to [-pi, pi).
    """
    return np.array(apply_twist_kernel(float(pose[0]), float(pose[1]), float(pose[2]),
                                       float(twist[0]), float(twist[1]), float(twist[2])))


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

