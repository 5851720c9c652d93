"""The contact simulation of :mod:`hsddp_gym.core.contact` for ``N`` robots in one compiled (numba) call.

:class:`~hsddp_gym.core.contact.ContactSimulator` steps one robot with Pinocchio calls from Python; this
module is the same scheme -- semi-implicit Euler velocity step, the exact planar Coulomb LCP by
enumeration of foot states (the previous states first, then the same fixed order), the mass-metric
position projection (Newton to :data:`~hsddp_gym.core.contact.POSITION_TOLERANCE`; contact feet and every
foot that ended below the ground), the energy projection (flight: the centroidal momentum of the step's start
plus gravity's impulse and the energy of the torques' second-order work; contacts: scale ``v``) and the motor
torque-speed law -- written
out in closed form for the planar tree ``x -> z -> pitch -> {front, back} hip -> knee -> foot`` and
compiled with numba (``cache=True``), one loop over the robots.

The model is still Pinocchio's: :func:`kernel_params` reads every number from the
:class:`~hsddp_gym.core.model.CheetahModel` (its :class:`~hsddp_gym.core.params.RobotParams`), and
``tests/test_vector_env.py`` checks the closed-form mass matrix, bias, foot positions and Jacobians,
centroidal momentum map and energies against ``pin.crba``, ``pin.nonLinearEffects``, frame Jacobians,
``pin.computeCentroidalMap`` and ``pin.computeMechanicalEnergy`` to 1e-12 at random states, and whole
steps against ``ContactSimulator`` in every contact combination (flight, front, back, double stance;
stick and slide): the same foot states and contact flags, states within 1e-11 relative to their size (median
3e-16; 99.7 % within 1e-12). The LCP's linear solves, the small Cholesky factorizations and the order of the
projections are contact.py's, written out; Pinocchio's ABA and ``computeMinverse`` are replaced by one sparse
``L^T D L`` factorization of ``M`` along the kinematic tree per step (:func:`tree_factor7`), which is where the
round-off differences come from (at cond(M) ~ 2e4, ``computeMinverse`` and ``inv(crba)`` differ by ~8e-12
themselves).

Speed notes: numba passes a tuple of arrays (:class:`Scratch`) to a compiled call at about a microsecond (one
reference count per array), more than a whole flight step costs, so :func:`step_batch` is one function that
unpacks it once per batch and has the simulator's step written out in line. About 88 % of the 1 ms steps of a
random-action episode are in flight (no foot within reach), so the flight step is what costs: the kinematics
(:func:`sincos` inline instead of libm's call), :func:`mass_matrix` and :func:`bias` from per-leg lever arms,
the tree factorization (no fill, no square roots), the energy check over ``M``'s nonzeros; a robot's model
cache (:func:`model_cache`) spares the recomputation of the points and ``M`` a call starts from. No fast-math
flag, not even fused multiply-adds: the same seed gives the same episode on CPUs with and without FMA.

Closed form (world frame, ``R(t) (a, c) = (cos t a + sin t c, -sin t a + cos t c)`` the rotation about
+y): each body's centre of mass ``p`` has the Jacobian columns ``[1, 0]`` (x), ``[0, 1]`` (z) and, for each
revolute joint of its chain with pivot ``o``, ``[p_z - o_z, -(p_x - o_x)]``; its angular Jacobian is 1 on
its chain's revolute joints. ``M = sum m J_p^T J_p + I J_w^T J_w``; the bias is
``b = sum m J_p^T (a_p + [0, g])`` with ``a_p = -sum_k w_k^2 s_k`` (``s_k`` the chain segments, ``w_k``
their absolute rates: the planar Coriolis/centrifugal acceleration at zero joint accelerations).

Terrain: :func:`step_batch_terrain` is the same step on a terrain's piecewise-linear surface (contacts at the
closest point of the surface, along its normal, the friction cone in the local frame); :func:`step_batch` is the
flat ground's, unchanged. :class:`CompiledContactSimulator` calls the one its terrain needs; the vector env is flat.

Arrays: ``x (N, 14)`` states, ``u (N, 4)`` joint torques, ``states (N, 2)`` int64 foot states
(``SEPARATE`` ... ``SLIDE_NEG``), ``contact (N, 2)`` bool, ``impulse (N, 4)`` summed ground impulses (grf
layout), ``time (N,)`` simulated time, ``heights (N, 2)`` foot heights after the step, ``counters (N, 4)``
int64 ``[lcp_fallbacks, energy_projections, momentum_fallbacks, energy_deficits]``.
"""

from __future__ import annotations

import collections
import math
import sys
import time as _time

import numba
import numpy as np

from hsddp_gym.core.contact import (
    CONTACT_MARGIN,
    POSITION_TOLERANCE,
    SEPARATE,
    SLIDE_NEG,
    SLIDE_POS,
    STICK,
    ContactSimulator,
)
from hsddp_gym.core.conventions import FOOT_SIGN, NQ, NX
from hsddp_gym.core.terrain import check_terrain

_jit = numba.njit(cache=True, error_model="numpy")
"""numba's compile options for every kernel function: cached on disk; numpy's error model (no Python exception
checks on each division: every divisor is checked before, as in :mod:`hsddp_gym.core.contact`); no fast-math flag
(fused multiply-adds would make the round-off, and so whole episodes, depend on the CPU)."""

# ------------------------------------------------------------------------------ parameter vector layout
P_MASS = 0  # 3 entries: trunk, thigh, shank [kg]
P_COMZ = 3  # 3 entries: CoM offset along each link's local z [m]
P_INERTIA = 6  # 3 entries: I_yy about the CoM [kg m^2]
P_THIGH_LENGTH = 9
P_SHANK_LENGTH = 10
P_HIP_X = 11  # 2 entries: hip x in the trunk frame, front (+) and back (-) [m]
P_GRAVITY = 13
P_MU = 14
P_DT = 15
P_TORQUE_LIMIT = 16
P_W_FULL = 17
P_W_ZERO = 18
P_MOTOR = 19  # 1.0: motor torque-speed law on, 0.0: ideal torque sources
P_FAR = 20  # a foot higher than this [m] cannot reach the ground within one step (ContactSimulator._far)
P_TERRAIN_N = 21  # number K of vertices of the terrain's surface; 0: the flat ground z = 0
N_PARAMS = 22
"""Length of the parameter vector on flat ground; a terrain appends its surface's vertices: ``xs`` (K,) at
``p[N_PARAMS:N_PARAMS + K]``, ``zs`` (K,) after them (:func:`kernel_params`, :func:`terrain_piece`)."""

# points (rows of the (12, 2) point array): 0 trunk origin, 1 trunk CoM, then per leg hip, thigh CoM, knee,
# shank CoM, foot (front: 2..6, back: 7..11)
_FOOT_POINT = np.array([6, 11])
# chains: bodies 0..4 (trunk, thigh_f, shank_f, thigh_b, shank_b), then the feet 5, 6
_CHAIN_POINT = np.array([1, 3, 5, 8, 10, 6, 11])
_CHAIN_LEN = np.array([1, 2, 3, 2, 3, 3, 3])
_CHAIN_PIVOT = np.array([[0, 0, 0], [0, 2, 0], [0, 2, 4], [0, 7, 0], [0, 7, 9], [0, 2, 4], [0, 7, 9]])
_CHAIN_DOF = np.array([[2, 0, 0], [2, 3, 0], [2, 3, 4], [2, 5, 0], [2, 5, 6], [2, 3, 4], [2, 5, 6]])
_TOL_V = 1e-9
_TOL_L = 1e-12
_MAX_PROJECTION_ITERATIONS = 6
# the LCP's fixed order (contact._BASE_ORDER and its product for two feet)
_BASE_ORDER = np.array([STICK, SLIDE_POS, SLIDE_NEG, SEPARATE])

COUNTER_NAMES = ("lcp_fallbacks", "energy_projections", "momentum_fallbacks", "energy_deficits")
# a robot's model cache (row of the (N, MODEL_CACHE_SIZE) array of step_batch): the configuration q, its 12
# points and its mass matrix, as the robot's last step left them
_CACHE_Q = 0
_CACHE_PTS = NQ
_CACHE_M = NQ + 24
MODEL_CACHE_SIZE = NQ + 24 + 49


def model_cache(n: int) -> np.ndarray:
    """An empty model cache for ``n`` robots (n, MODEL_CACHE_SIZE): NaN configurations, which match no state."""
    return np.full((n, MODEL_CACHE_SIZE), np.nan)


def kernel_params(sim: ContactSimulator) -> np.ndarray:
    """The parameter vector (N_PARAMS,) of a simulator: its robot's :class:`RobotParams`, friction, gravity,
    step, torque limit and motor law; with a terrain (``sim.terrain``, a :class:`~hsddp_gym.core.terrain.Terrain`
    that is not None), followed by its surface's vertices (:meth:`~hsddp_gym.core.terrain.Terrain.surface_vertices`).
    Only the energy-consistent scheme is compiled (ValueError otherwise)."""
    if not isinstance(sim, ContactSimulator):
        raise TypeError(f"sim must be a ContactSimulator, got {type(sim).__name__}")
    if not sim.energy_consistent:
        raise ValueError("the batched kernel implements only the energy-consistent scheme (energy_consistent=True)")
    prm = sim.robot.params
    p = np.zeros(N_PARAMS)
    for i, link in enumerate((prm.trunk, prm.thigh, prm.shank)):
        p[P_MASS + i] = link.mass
        p[P_COMZ + i] = link.com_z
        p[P_INERTIA + i] = link.inertia_yy
    p[P_THIGH_LENGTH] = prm.thigh.length
    p[P_SHANK_LENGTH] = prm.shank.length
    p[P_HIP_X] = FOOT_SIGN[0] * prm.hip_offset
    p[P_HIP_X + 1] = FOOT_SIGN[1] * prm.hip_offset
    p[P_GRAVITY] = sim.gravity
    p[P_MU] = sim.mu
    p[P_DT] = sim.dt
    p[P_TORQUE_LIMIT] = sim.torque_limit
    if sim.motor_speed_limits is not None:
        p[P_W_FULL], p[P_W_ZERO] = sim.motor_speed_limits
        p[P_MOTOR] = 1.0
    p[P_FAR] = sim._far
    terrain = getattr(sim, "terrain", None)
    if terrain is not None:
        xs, zs = terrain.surface_vertices()
        p[P_TERRAIN_N] = len(xs)
        p = np.concatenate([p, xs, zs])
    return p


# sincos: fdlibm's polynomial kernels of sin and cos on |r| <= pi/4 (k_sin.c, k_cos.c) after a Cody-Waite
# reduction by pi/2 (pi/2 = _PIO2_1 + _PIO2_1T, _PIO2_1 with 33 significant bits: k * _PIO2_1 is exact)
_TWO_OVER_PI = 6.36619772367581382433e-01
_PIO2_1 = 1.57079632673412561417e+00
_PIO2_1T = 6.07710050650619224932e-11
_SINCOS_MAX = 1e5  # beyond (and for inf, nan): libm
_S1, _S2, _S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_S4, _S5, _S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_C1, _C2, _C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_C4, _C5, _C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@_jit
def sincos(a):
    """``(sin a, cos a)`` inline (the kernel's angles: about half the cost of libm's ``sincos`` call), accurate to
    about an ulp for ``|a| < 1e5`` (libm's ``sin``, ``cos`` beyond)."""
    if not abs(a) < _SINCOS_MAX:
        return math.sin(a), math.cos(a)
    k = math.floor(a * _TWO_OVER_PI + 0.5)  # the nearest multiple of pi/2
    r = (a - k * _PIO2_1) - k * _PIO2_1T
    z = r * r
    sr = r + (z * r) * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    cr = 1.0 - (0.5 * z - (z * z) * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6))))))
    quadrant = int(k) & 3
    if quadrant == 0:
        return sr, cr
    if quadrant == 1:
        return cr, -sr
    if quadrant == 2:
        return -sr, -cr
    return -cr, sr


# ------------------------------------------------------------------------------ terrain
@_jit
def terrain_piece(p, px):
    """The piece of the terrain's surface (the vertices in ``p``, :func:`kernel_params`) under ``px`` [m]:
    ``(h, s, x_j, z_j)`` its height at ``px``, its slope and its left vertex (a point on its line); level beyond
    the outermost vertices (slope 0, the end vertex). Binary search: a vertex belongs to the piece on its right."""
    k = int(p[P_TERRAIN_N])
    b = N_PARAMS
    if px < p[b]:
        return p[b + k], 0.0, p[b], p[b + k]
    if px >= p[b + k - 1]:
        return p[b + 2 * k - 1], 0.0, p[b + k - 1], p[b + 2 * k - 1]
    lo = 0
    hi = k - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if p[b + mid] <= px:
            lo = mid
        else:
            hi = mid
    x0, z0 = p[b + lo], p[b + k + lo]
    s = (p[b + k + lo + 1] - z0) / (p[b + lo + 1] - x0)
    return z0 + s * (px - x0), s, x0, z0


@_jit
def _piece_index(p, px):
    """The index j (0..K-2) of the piece ``[x_j, x_j+1)`` of the surface under ``px``, clamped to the first / last."""
    k = int(p[P_TERRAIN_N])
    b = N_PARAMS
    lo = 0
    hi = k - 1
    if px < p[b]:
        return 0
    if px >= p[b + k - 1]:
        return k - 2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if p[b + mid] <= px:
            lo = mid
        else:
            hi = mid
    return lo


@_jit
def terrain_contact(p, fx, fz, reach):
    """The point of the terrain's surface closest to the foot ``(fx, fz)`` [m], searched over the pieces within
    ``min(reach, vertical distance)`` of ``fx`` (the vertical distance bounds the closest one's): returns ``(phi, n_x,
    n_z, c_x, c_z)``, ``phi`` the signed distance (< 0 below the surface), ``n`` the unit outward normal there (the
    piece's, or from a corner vertex toward the outside) and ``c`` the closest point. So a foot beside a riser sees
    the riser, and one above a step's edge sees the edge (a corner: the normal points from it to the foot), not
    the riser's infinite line."""
    k = int(p[P_TERRAIN_N])
    b = N_PARAMS
    h, _, _, _ = terrain_piece(p, fx)
    above = fz >= h
    r = min(reach, abs(fz - h))
    jlo = _piece_index(p, fx - r)
    jhi = _piece_index(p, fx + r)
    best = np.inf
    bcx, bcz, bex, bez, inner = fx, h, 1.0, 0.0, True
    for j in range(jlo, jhi + 1):
        ax, az = p[b + j], p[b + k + j]
        ex, ez = p[b + j + 1] - ax, p[b + k + j + 1] - az
        u = ((fx - ax) * ex + (fz - az) * ez) / (ex * ex + ez * ez)
        inside = True
        if u <= 0.0:
            u = 0.0
            inside = False
        elif u >= 1.0:
            u = 1.0
            inside = False
        cx, cz = ax + u * ex, az + u * ez
        d2 = (fx - cx) * (fx - cx) + (fz - cz) * (fz - cz)
        if d2 < best:
            best = d2
            bcx, bcz, bex, bez, inner = cx, cz, ex, ez, inside
    dist = math.sqrt(best)
    if inner or dist < 1e-12:
        length = math.sqrt(bex * bex + bez * bez)
        nx, nz = -bez / length, bex / length
    elif above:
        nx, nz = (fx - bcx) / dist, (fz - bcz) / dist
    else:
        nx, nz = (bcx - fx) / dist, (bcz - fz) / dist
    return (dist if above else -dist), nx, nz, bcx, bcz


@_jit
def _terrain_candidate(p, pts, foot, fjx_all, fjz_all, fn, fpos, fa):
    """A foot's contact with the terrain at the step's start (step_batch's candidate test): ``phi`` its distance to the
    closest point ``c`` of the surface (:func:`terrain_contact`; returned), ``fn[foot]`` the outward normal ``n`` there,
    ``fa[foot] = n . c``, ``fpos[foot]`` the foot's position; ``fjz_all[foot]``, ``fjx_all[foot]`` the rows of the LCP,
    the foot's velocity along ``n`` and along the tangent ``t = (n_z, -n_x)``. Nothing is written when ``phi`` is
    beyond the reach ``p[P_FAR]``."""
    fx, fz = pts[_FOOT_POINT[foot], 0], pts[_FOOT_POINT[foot], 1]
    phi, nx, nz, cx, cz = terrain_contact(p, fx, fz, p[P_FAR])
    if phi > p[P_FAR]:
        return phi
    fn[foot, 0] = nx
    fn[foot, 1] = nz
    fa[foot] = nx * cx + nz * cz
    fpos[foot, 0] = fx
    fpos[foot, 1] = fz
    fjz = fjz_all[foot]
    fjx = fjx_all[foot]
    point_jacobian(pts, 5 + foot, fjx, fjz)
    for j in range(7):
        jxj, jzj = fjx[j], fjz[j]
        fjz[j] = nx * jxj + nz * jzj
        fjx[j] = nz * jxj - nx * jzj
    return phi


@_jit
def _terrain_rows(p, pts, ncand, cfoot, states, fn, fpos, fa, tfoot, taxis, tdir, tval):
    """The position projection's rows on a terrain (``pts`` the kinematics after ``q += h v``); returns their number.
    Each row is ``d . foot = target`` with a unit direction ``d`` (``taxis`` 2): a sticking foot keeps its position
    along the tangent of the step's start and a contact foot ends on the tangent line of its contact point (both the
    LCP's frame); a foot that ends below the surface (a sliding one too, when that is not the same line: a concave
    corner) is put back onto it at its closest point. When that point's piece is parallel to the foot's contact row
    and above it (the foot slid past a riser lower than the step's travel), the contact row moves onto it."""
    nt = 0
    held0 = False
    held1 = False
    stick0 = False
    stick1 = False
    row0 = -1
    row1 = -1
    for i in range(ncand):
        foot = cfoot[i]
        st = states[foot]
        nx, nz = fn[foot, 0], fn[foot, 1]
        if st == STICK:
            tfoot[nt] = foot
            taxis[nt] = 2
            tdir[nt, 0] = nz
            tdir[nt, 1] = -nx
            tval[nt] = nz * fpos[foot, 0] - nx * fpos[foot, 1]
            nt += 1
            if foot == 0:
                stick0 = True
            else:
                stick1 = True
        if st != SEPARATE:
            tfoot[nt] = foot
            taxis[nt] = 2
            tdir[nt, 0] = nx
            tdir[nt, 1] = nz
            tval[nt] = fa[foot]
            if foot == 0:
                held0 = True
                row0 = nt
            else:
                held1 = True
                row1 = nt
            nt += 1
    for foot in range(2):
        if (stick0 if foot == 0 else stick1):
            continue  # pinned to its start, on the surface
        fx, fz = pts[_FOOT_POINT[foot], 0], pts[_FOOT_POINT[foot], 1]
        th, _, _, _ = terrain_piece(p, fx)
        if fz < th:
            phi, nx, nz, cx, cz = terrain_contact(p, fx, fz, np.inf)
            if (held0 if foot == 0 else held1) and nx * fn[foot, 0] + nz * fn[foot, 1] > 1.0 - 1e-6:
                # the contact row's direction: the same line, or a parallel one above it (a foot slid past a low
                # riser onto the next level) that its row is moved to
                row = row0 if foot == 0 else row1
                target = nx * cx + nz * cz
                if target > tval[row] + POSITION_TOLERANCE:
                    tval[row] = target
                continue
            tfoot[nt] = foot
            taxis[nt] = 2
            tdir[nt, 0] = nx
            tdir[nt, 1] = nz
            tval[nt] = nx * cx + nz * cz
            nt += 1
    return nt


@_jit
def _terrain_corner_rows(p, pts, nt, tfoot, taxis, tdir, tval, res, residual):
    """During the projection on a terrain: a foot that the projection moved below another piece (a concave corner:
    a gap's floor and its wall) gets that piece's row too (its residual in ``res``), at most two rows a foot and four
    in all. Returns the number of rows and the largest residual."""
    for foot in range(2):
        if nt >= 4:
            break
        fp = _FOOT_POINT[foot]
        fx, fz = pts[fp, 0], pts[fp, 1]
        th, _, _, _ = terrain_piece(p, fx)
        if not fz < th - POSITION_TOLERANCE:
            continue
        phi, nx, nz, cx, cz = terrain_contact(p, fx, fz, np.inf)
        rows_f = 0
        same = False
        target = nx * cx + nz * cz
        for a in range(nt):
            if tfoot[a] == foot:
                rows_f += 1
                if tdir[a, 0] * nx + tdir[a, 1] * nz > 1.0 - 1e-6:
                    same = True
                    if target > tval[a] + POSITION_TOLERANCE:  # a parallel line above the row's: it moves there
                        res[a] += target - tval[a]
                        tval[a] = target
                        residual = max(residual, abs(res[a]))
        if rows_f >= 2 or same:
            continue
        tfoot[nt] = foot
        taxis[nt] = 2
        tdir[nt, 0] = nx
        tdir[nt, 1] = nz
        tval[nt] = nx * cx + nz * cz
        res[nt] = -phi
        residual = max(residual, -phi)
        nt += 1
    return nt, residual


# ------------------------------------------------------------------------------ kinematics and dynamics
@_jit
def kinematics(p, q, pts):
    """World (x, z) of the 12 points (12, 2) for configuration ``q`` (7,)."""
    x, z, th0 = q[0], q[1], q[2]
    s0, c0 = sincos(th0)
    pts[0, 0] = x
    pts[0, 1] = z
    cz = p[P_COMZ]
    pts[1, 0] = x + s0 * cz
    pts[1, 1] = z + c0 * cz
    for leg in range(2):
        base = 2 + 5 * leg
        hx = p[P_HIP_X + leg]
        hipx = x + c0 * hx
        hipz = z - s0 * hx
        pts[base, 0] = hipx
        pts[base, 1] = hipz
        th1 = th0 + q[3 + 2 * leg]
        s1, c1 = sincos(th1)
        pts[base + 1, 0] = hipx + s1 * p[P_COMZ + 1]
        pts[base + 1, 1] = hipz + c1 * p[P_COMZ + 1]
        lt = -p[P_THIGH_LENGTH]
        kx = hipx + s1 * lt
        kz = hipz + c1 * lt
        pts[base + 2, 0] = kx
        pts[base + 2, 1] = kz
        th2 = th1 + q[4 + 2 * leg]
        s2, c2 = sincos(th2)
        pts[base + 3, 0] = kx + s2 * p[P_COMZ + 2]
        pts[base + 3, 1] = kz + c2 * p[P_COMZ + 2]
        ls = -p[P_SHANK_LENGTH]
        pts[base + 4, 0] = kx + s2 * ls
        pts[base + 4, 1] = kz + c2 * ls


@_jit
def point_jacobian(pts, chain, jx, jz):
    """Rows ``x`` and ``z`` (7,) each of the world Jacobian of chain ``chain``'s point (0..4: body CoMs,
    5, 6: front, back foot)."""
    for j in range(7):
        jx[j] = 0.0
        jz[j] = 0.0
    jx[0] = 1.0
    jz[1] = 1.0
    pt = _CHAIN_POINT[chain]
    px, pz = pts[pt, 0], pts[pt, 1]
    for k in range(_CHAIN_LEN[chain]):
        o = _CHAIN_PIVOT[chain, k]
        d = _CHAIN_DOF[chain, k]
        jx[d] = pz - pts[o, 1]
        jz[d] = -(px - pts[o, 0])


@_jit
def _leg_inertia(m1, m2, i1, i2, x0, z0, hx, hz, tx, tz, kx, kz, sx, sz):
    """One leg's terms of :func:`mass_matrix`, from the trunk origin ``(x0, z0)``, the hip ``(hx, hz)``, thigh
    CoM ``(tx, tz)``, knee ``(kx, kz)`` and shank CoM ``(sx, sz)`` (scalars, so that nothing is reloaded):
    ``(M[x, hip], M[z, hip], M[x, knee], M[z, knee], M[pitch, hip], M[pitch, knee], M[hip, hip], M[hip, knee],
    M[knee, knee], the leg's share of M[pitch, pitch], its first moments about the trunk origin (x, z))``."""
    thx, thz = tx - hx, tz - hz  # the lever arms: thigh CoM about the hip, shank CoM about hip and knee,
    shx, shz = sx - hx, sz - hz  # both CoMs about the trunk origin
    skx, skz = sx - kx, sz - kz
    tox, toz = tx - x0, tz - z0
    sox, soz = sx - x0, sz - z0
    return (m1 * thz + m2 * shz, -(m1 * thx + m2 * shx), m2 * skz, -(m2 * skx),
            m1 * (tox * thx + toz * thz) + i1 + m2 * (sox * shx + soz * shz) + i2,
            m2 * (sox * skx + soz * skz) + i2,
            m1 * (thx * thx + thz * thz) + i1 + m2 * (shx * shx + shz * shz) + i2,
            m2 * (shx * skx + shz * skz) + i2,
            m2 * (skx * skx + skz * skz) + i2,
            m1 * (tox * tox + toz * toz) + i1 + m2 * (sox * sox + soz * soz) + i2,
            m1 * tox + m2 * sox, m1 * toz + m2 * soz)


@_jit
def mass_matrix(p, pts, M):
    """Joint-space inertia ``M`` (7, 7) at the points ``pts`` of :func:`kinematics`, in closed form: with body
    CoM ``P``, mass ``m``, inertia ``I`` and joint pivots ``O``, ``M[x, j] = sum m (P_z - O_z)``,
    ``M[z, j] = -sum m (P_x - O_x)``, ``M[j, k] = sum m (P - O_j).(P - O_k) + I`` over the bodies moved by
    both joints (the front and back legs do not couple: those entries are 0)."""
    m0, m1, m2 = p[P_MASS], p[P_MASS + 1], p[P_MASS + 2]
    i0, i1, i2 = p[P_INERTIA], p[P_INERTIA + 1], p[P_INERTIA + 2]
    x0, z0 = pts[0, 0], pts[0, 1]
    cx, cz = pts[1, 0] - x0, pts[1, 1] - z0  # the trunk CoM about the trunk origin (the pitch pivot)
    front = _leg_inertia(m1, m2, i1, i2, x0, z0, pts[2, 0], pts[2, 1], pts[3, 0], pts[3, 1], pts[4, 0], pts[4, 1],
                         pts[5, 0], pts[5, 1])
    back = _leg_inertia(m1, m2, i1, i2, x0, z0, pts[7, 0], pts[7, 1], pts[8, 0], pts[8, 1], pts[9, 0], pts[9, 1],
                        pts[10, 0], pts[10, 1])
    for i in range(7):
        for j in range(7):
            M[i, j] = 0.0
    mtot = m0 + 2.0 * (m1 + m2)
    M[0, 0] = mtot
    M[1, 1] = mtot
    M[0, 2] = m0 * cz + front[11] + back[11]
    M[1, 2] = -(m0 * cx + front[10] + back[10])
    M[2, 2] = m0 * (cx * cx + cz * cz) + i0 + front[9] + back[9]
    for leg in range(2):
        e = front if leg == 0 else back
        jh, jk = 3 + 2 * leg, 4 + 2 * leg
        M[0, jh], M[1, jh], M[0, jk], M[1, jk] = e[0], e[1], e[2], e[3]
        M[2, jh], M[2, jk] = e[4], e[5]
        M[jh, jh], M[jh, jk], M[jk, jk] = e[6], e[7], e[8]
    for i in range(7):  # symmetric: the lower triangle is the mirror, exactly
        for j in range(i):
            M[i, j] = M[j, i]


@_jit
def _leg_bias(m1, m2, g, r0, x0, z0, w1, w2, hx, hz, tx, tz, kx, kz, sx, sz):
    """One leg's terms of :func:`bias` from scalars (the trunk origin, hip, thigh CoM, knee, shank CoM; ``r0``
    the trunk's squared rate, ``w1``, ``w2`` the thigh's and shank's absolute rates): ``(sum of its forces x,
    z, their moment about the trunk origin, b[hip], b[knee])``."""
    r1, r2 = w1 * w1, w2 * w2
    hax = -(r0 * (hx - x0))  # the hip's acceleration
    haz = -(r0 * (hz - z0))
    tfx = m1 * (hax - r1 * (tx - hx))  # the thigh's and the shank's m (a + [0, g])
    tfz = m1 * (haz - r1 * (tz - hz) + g)
    kax = hax - r1 * (kx - hx)
    kaz = haz - r1 * (kz - hz)
    sfx = m2 * (kax - r2 * (sx - kx))
    sfz = m2 * (kaz - r2 * (sz - kz) + g)
    moment0 = ((tz - z0) * tfx - (tx - x0) * tfz) + ((sz - z0) * sfx - (sx - x0) * sfz)
    hip = ((tz - hz) * tfx - (tx - hx) * tfz) + ((sz - hz) * sfx - (sx - hx) * sfz)
    knee = (sz - kz) * sfx - (sx - kx) * sfz
    return tfx + sfx, tfz + sfz, moment0, hip, knee


@_jit
def bias(p, pts, v, out):
    """``b(q, v)`` (7,): Coriolis, centrifugal and gravity terms (``M a + b = tau``), at the points ``pts``, in
    closed form: ``b = sum J_P^T m (a_P + [0, g])`` with ``a_P = -sum_k w_k^2 s_k`` the acceleration of each
    body CoM at zero joint accelerations (``s_k`` its chain's segments, ``w_k`` their absolute rates); a body's
    generalized force on a revolute joint with pivot ``O`` is the moment ``(P - O) x f``."""
    g = p[P_GRAVITY]
    m0, m1, m2 = p[P_MASS], p[P_MASS + 1], p[P_MASS + 2]
    x0, z0 = pts[0, 0], pts[0, 1]
    w0 = v[2]
    r0 = w0 * w0
    cx, cz = pts[1, 0] - x0, pts[1, 1] - z0  # the trunk CoM
    fx = m0 * -(r0 * cx)
    fz = m0 * (-(r0 * cz) + g)
    w1f = w0 + v[3]
    w1b = w0 + v[5]
    front = _leg_bias(m1, m2, g, r0, x0, z0, w1f, w1f + v[4], pts[2, 0], pts[2, 1], pts[3, 0], pts[3, 1],
                      pts[4, 0], pts[4, 1], pts[5, 0], pts[5, 1])
    back = _leg_bias(m1, m2, g, r0, x0, z0, w1b, w1b + v[6], pts[7, 0], pts[7, 1], pts[8, 0], pts[8, 1],
                     pts[9, 0], pts[9, 1], pts[10, 0], pts[10, 1])
    out[0] = fx + front[0] + back[0]
    out[1] = fz + front[1] + back[1]
    out[2] = (cz * fx - cx * fz) + front[2] + back[2]
    out[3] = front[3]
    out[4] = front[4]
    out[5] = back[3]
    out[6] = back[4]


@_jit
def potential_energy(p, pts):
    """``sum m g z_com`` [J] at the points ``pts`` (the trunk, thigh and shank CoMs, front then back)."""
    m0, m1, m2 = p[P_MASS], p[P_MASS + 1], p[P_MASS + 2]
    e = m0 * pts[1, 1] + m1 * pts[3, 1] + m2 * pts[5, 1] + m1 * pts[8, 1] + m2 * pts[10, 1]
    return e * p[P_GRAVITY]


@_jit
def kinetic_energy(M, v):
    """``1/2 v^T M v`` [J] over the nonzeros of :func:`mass_matrix` (``M[x, z]`` and the legs' cross terms are
    0): the diagonal plus twice the upper triangle."""
    d = 0.0
    for i in range(7):
        d += M[i, i] * v[i] * v[i]
    off = v[0] * (M[0, 2] * v[2] + M[0, 3] * v[3] + M[0, 4] * v[4] + M[0, 5] * v[5] + M[0, 6] * v[6])
    off += v[1] * (M[1, 2] * v[2] + M[1, 3] * v[3] + M[1, 4] * v[4] + M[1, 5] * v[5] + M[1, 6] * v[6])
    off += v[2] * (M[2, 3] * v[3] + M[2, 4] * v[4] + M[2, 5] * v[5] + M[2, 6] * v[6])
    off += v[3] * M[3, 4] * v[4] + v[5] * M[5, 6] * v[6]
    return 0.5 * d + off


@_jit
def centroidal_rows(M, P):
    """Rows linear x, linear z and angular y (about the centre of mass) of the centroidal momentum map (3, 7)
    (``pin.computeCentroidalMap`` rows 0, 2, 4), from the joint-space inertia ``M`` (7, 7) of the same
    configuration: the linear rows are ``M``'s x and z rows (the total mass times the CoM Jacobian); the pitch
    row is the angular momentum about the trunk origin, from which the moment of the linear momentum about the
    CoM offset ``c - o = (-M[1, 2], M[0, 2]) / M[0, 0]`` is taken."""
    rz = M[0, 2] / M[0, 0]
    rx = -M[1, 2] / M[0, 0]
    for j in range(7):
        P[0, j] = M[0, j]
        P[1, j] = M[1, j]
        P[2, j] = M[2, j] - rz * M[0, j] + rx * M[1, j]


@_jit
def tree_factor7(M, L, dinv):
    """The sparse factorization ``M = L^T D L`` (7, 7) of the joint-space inertia along the kinematic tree
    ``x -> z -> pitch -> {hip -> knee} x 2`` (Featherstone's LTDL, RBDA 6.5), eliminated from the leaves up:
    ``L`` unit lower triangular, row ``k`` nonzero on ``k``'s ancestors only (no fill: the legs do not couple;
    its diagonal is not stored), ``dinv`` (7,) ``1 / D``. Reads the lower triangle of ``M``; the entries of ``L``
    off the tree are not written. False if ``M`` is not positive definite."""
    b00, b10, b11, b20, b21, b22 = M[0, 0], M[1, 0], M[1, 1], M[2, 0], M[2, 1], M[2, 2]
    for leg in range(2):
        h, k = 3 + 2 * leg, 4 + 2 * leg
        d = M[k, k]
        if not d > 0.0:
            return False
        inv = 1.0 / d
        dinv[k] = inv
        ah, a2, a1, a0 = M[k, h], M[k, 2], M[k, 1], M[k, 0]
        lkh, lk2, lk1, lk0 = ah * inv, a2 * inv, a1 * inv, a0 * inv
        L[k, h], L[k, 2], L[k, 1], L[k, 0] = lkh, lk2, lk1, lk0
        d = M[h, h] - lkh * ah
        if not d > 0.0:
            return False
        inv = 1.0 / d
        dinv[h] = inv
        c2, c1, c0 = M[h, 2] - lkh * a2, M[h, 1] - lkh * a1, M[h, 0] - lkh * a0
        lh2, lh1, lh0 = c2 * inv, c1 * inv, c0 * inv
        L[h, 2], L[h, 1], L[h, 0] = lh2, lh1, lh0
        b22 -= lk2 * a2 + lh2 * c2
        b21 -= lk2 * a1 + lh2 * c1
        b20 -= lk2 * a0 + lh2 * c0
        b11 -= lk1 * a1 + lh1 * c1
        b10 -= lk1 * a0 + lh1 * c0
        b00 -= lk0 * a0 + lh0 * c0
    if not b22 > 0.0:
        return False
    inv = 1.0 / b22
    dinv[2] = inv
    l21, l20 = b21 * inv, b20 * inv
    L[2, 1], L[2, 0] = l21, l20
    b11 -= l21 * b21
    b10 -= l21 * b20
    b00 -= l20 * b20
    if not b11 > 0.0:
        return False
    inv = 1.0 / b11
    dinv[1] = inv
    l10 = b10 * inv
    L[1, 0] = l10
    b00 -= l10 * b10
    if not b00 > 0.0:
        return False
    dinv[0] = 1.0 / b00
    return True


@_jit
def tree_solve7(L, dinv, b, out):
    """``out = M^-1 b`` (7,) from the factor of :func:`tree_factor7`: ``L^T y = b`` from the leaves up, then
    ``L out = D^-1 y`` from the root down (``out`` may not be ``b``)."""
    c0, c1, c2 = b[0], b[1], b[2]
    for leg in range(2):
        h, k = 3 + 2 * leg, 4 + 2 * leg
        yk = b[k]
        yh = b[h] - L[k, h] * yk
        c2 -= L[k, 2] * yk + L[h, 2] * yh
        c1 -= L[k, 1] * yk + L[h, 1] * yh
        c0 -= L[k, 0] * yk + L[h, 0] * yh
        out[h], out[k] = yh * dinv[h], yk * dinv[k]
    c1 -= L[2, 1] * c2
    c0 -= L[2, 0] * c2
    c0 -= L[1, 0] * c1
    a0 = c0 * dinv[0]
    a1 = c1 * dinv[1] - L[1, 0] * a0
    a2 = c2 * dinv[2] - L[2, 1] * a1 - L[2, 0] * a0
    out[0], out[1], out[2] = a0, a1, a2
    for leg in range(2):
        h, k = 3 + 2 * leg, 4 + 2 * leg
        ah = out[h] - L[h, 2] * a2 - L[h, 1] * a1 - L[h, 0] * a0
        out[h] = ah
        out[k] = out[k] - L[k, h] * ah - L[k, 2] * a2 - L[k, 1] * a1 - L[k, 0] * a0


@_jit
def tree_solve_rows(L, dinv, R, m, out):
    """``out[r] = M^-1 R[r]`` for the rows ``r < m`` of ``R`` (m, 7) (:func:`tree_solve7` on each)."""
    for r in range(m):
        tree_solve7(L, dinv, R[r], out[r])


# ------------------------------------------------------------------------------ small solves (contact.py's)
@_jit
def _solve_linear(A, b, n, z):
    """``A z = b`` for the leading ``n x n`` block (n <= 4): contact._solve_linear (closed form for n <= 2,
    Gaussian elimination with partial pivoting otherwise); A, b are overwritten; False if singular."""
    if n == 1:
        a = A[0, 0]
        if abs(a) < 1e-300:
            return False
        z[0] = b[0] / a
        return True
    if n == 2:
        a, bb = A[0, 0], A[0, 1]
        c, d = A[1, 0], A[1, 1]
        det = a * d - bb * c
        scale = max(abs(a * d), abs(bb * c), 1e-300)
        if abs(det) <= 1e-13 * scale:
            return False
        z[0] = (b[0] * d - bb * b[1]) / det
        z[1] = (a * b[1] - c * b[0]) / det
        return True
    for col in range(n):
        piv = col
        best = abs(A[col, col])
        for r in range(col + 1, n):
            if abs(A[r, col]) > best:
                best = abs(A[r, col])
                piv = r
        if abs(A[piv, col]) < 1e-300:
            return False
        if piv != col:
            for j in range(n):
                t = A[col, j]
                A[col, j] = A[piv, j]
                A[piv, j] = t
            t = b[col]
            b[col] = b[piv]
            b[piv] = t
        pv = A[col, col]
        for r in range(col + 1, n):
            f = A[r, col] / pv
            if f != 0.0:
                for j in range(col, n):
                    A[r, j] -= f * A[col, j]
                b[r] -= f * b[col]
    for r in range(n - 1, -1, -1):
        s = b[r]
        for j in range(r + 1, n):
            s -= A[r, j] * z[j]
        z[r] = s / A[r, r]
    return True


@_jit
def _cholesky_small(S, r, n, z, L):
    """contact._solve_spd for n = 3, 4 (upper triangle of S read, as the unrolled version); False if not PD."""
    for i in range(n):
        for j in range(i + 1):
            if i == j:
                d = S[i, i]
                for k in range(i):
                    d -= L[i, k] * L[i, k]
                if i == 0:
                    if d <= 0.0:
                        return False
                elif d <= 1e-12 * S[i, i]:
                    return False
                L[i, i] = math.sqrt(d)
            else:
                s = S[j, i]
                for k in range(j):
                    s -= L[i, k] * L[j, k]
                L[i, j] = s / L[j, j]
    for i in range(n):
        s = r[i]
        for k in range(i):
            s -= L[i, k] * z[k]
        z[i] = s / L[i, i]
    for i in range(n - 1, -1, -1):
        s = z[i]
        for k in range(i + 1, n):
            s -= L[k, i] * z[k]
        z[i] = s / L[i, i]
    return True


@_jit
def _solve_spd(S, r, n, z, L):
    """contact._solve_spd: ``S z = r`` (n <= 4) for symmetric positive-definite ``S``; S, r may be overwritten."""
    if n <= 2:
        return _solve_linear(S, r, n, z)
    return _cholesky_small(S, r, n, z, L)


# ------------------------------------------------------------------------------ the LCP (contact.py's)
@_jit
def _try_states(G, c, mu, k, s0, s1, lam, w, A, rhs, zz, cols_j, cols_c, cols_n, rows):
    """contact._try_states for ``k`` candidate feet with states ``(s0, s1)``; returns the violation
    (inf if singular) and fills ``lam`` (2k,)."""
    m = 2 * k
    ncol = 0
    nrow = 0
    for i in range(k):
        s = s0 if i == 0 else s1
        n, t = 2 * i, 2 * i + 1
        if s == STICK:
            cols_n[ncol] = 1
            cols_j[ncol, 0] = n
            cols_c[ncol, 0] = 1.0
            ncol += 1
            cols_n[ncol] = 1
            cols_j[ncol, 0] = t
            cols_c[ncol, 0] = 1.0
            ncol += 1
            rows[nrow] = n
            rows[nrow + 1] = t
            nrow += 2
        elif s == SLIDE_POS or s == SLIDE_NEG:
            cols_n[ncol] = 2
            cols_j[ncol, 0] = n
            cols_c[ncol, 0] = 1.0
            cols_j[ncol, 1] = t
            cols_c[ncol, 1] = -mu if s == SLIDE_POS else mu
            ncol += 1
            rows[nrow] = n
            nrow += 1
    for j in range(m):
        lam[j] = 0.0
    if nrow > 0:
        for a in range(nrow):
            r = rows[a]
            for b in range(ncol):
                acc = 0.0
                for e in range(cols_n[b]):
                    acc += cols_c[b, e] * G[r, cols_j[b, e]]
                A[a, b] = acc
            rhs[a] = -c[r]
        if not _solve_linear(A, rhs, nrow, zz):
            return np.inf
        for b in range(ncol):
            for e in range(cols_n[b]):
                lam[cols_j[b, e]] += cols_c[b, e] * zz[b]
    for r in range(m):
        acc = 0.0
        for j in range(m):
            acc += G[r, j] * lam[j]
        w[r] = c[r] + acc
    viol = 0.0
    for i in range(k):
        s = s0 if i == 0 else s1
        n, t = 2 * i, 2 * i + 1
        if s == SEPARATE:
            viol = max(viol, (-w[n] - _TOL_V) / _TOL_V)
        else:
            viol = max(viol, (-lam[n] - _TOL_L) / _TOL_L)
            if s == STICK:
                viol = max(viol, (abs(lam[t]) - mu * lam[n] - _TOL_L) / _TOL_L)
            elif s == SLIDE_POS:
                viol = max(viol, (-w[t] - _TOL_V) / _TOL_V)
            else:
                viol = max(viol, (w[t] - _TOL_V) / _TOL_V)
    return viol


@_jit
def _try_double_stick(G, c, mu, lam, L, rhs, zz):
    """contact._try_double_stick: ``lam = -G^-1 c`` by Cholesky; returns the violation (inf if not PD)."""
    for i in range(4):
        rhs[i] = -c[i]
    if not _cholesky_small(G, rhs, 4, zz, L):
        return np.inf
    n0, t0, n1, t1 = zz[0], zz[1], zz[2], zz[3]
    lam[0] = n0
    lam[1] = t0
    lam[2] = n1
    lam[3] = t1
    return max(-n0 - _TOL_L, -n1 - _TOL_L, abs(t0) - mu * n0 - _TOL_L, abs(t1) - mu * n1 - _TOL_L) / _TOL_L


@_jit
def _try(G, c, mu, k, s0, s1, lam, w, A, rhs, zz, L, cols_j, cols_c, cols_n, rows):
    if k == 2 and s0 == STICK and s1 == STICK:
        return _try_double_stick(G, c, mu, lam, L, rhs, zz)
    return _try_states(G, c, mu, k, s0, s1, lam, w, A, rhs, zz, cols_j, cols_c, cols_n, rows)


@_jit
def solve_lcp(G, c, mu, k, g0, g1, lam, out_states, best_lam, w, A, rhs, zz, L, cols_j, cols_c, cols_n, rows):
    """contact.solve_contact_lcp_lists: the guess ``(g0, g1)`` first, then the fixed order; fills ``lam``
    (2k,) and ``out_states`` (k,); returns True when exact (False: the least-violating combination). The
    other arrays are scratch (the :class:`Scratch` fields of the same names; passed one by one, which is
    cheaper than passing the whole tuple)."""
    best_v = np.inf
    have = False
    b0 = SEPARATE
    b1 = SEPARATE
    viol = _try(G, c, mu, k, g0, g1, lam, w, A, rhs, zz, L, cols_j, cols_c, cols_n, rows)
    if viol <= 0.0:
        out_states[0] = g0
        out_states[1] = g1
        return True
    if viol < np.inf:
        best_v = viol
        have = True
        b0, b1 = g0, g1
        for j in range(2 * k):
            best_lam[j] = lam[j]
    n_combos = 4 if k == 1 else 16
    for idx in range(n_combos):
        if k == 1:
            s0 = _BASE_ORDER[idx]
            s1 = SEPARATE
        else:
            s0 = _BASE_ORDER[idx // 4]
            s1 = _BASE_ORDER[idx % 4]
        if s0 == g0 and (k == 1 or s1 == g1):
            continue
        viol = _try(G, c, mu, k, s0, s1, lam, w, A, rhs, zz, L, cols_j, cols_c, cols_n, rows)
        if viol <= 0.0:
            out_states[0] = s0
            out_states[1] = s1
            return True
        if viol < best_v:
            best_v = viol
            have = True
            b0, b1 = s0, s1
            for j in range(2 * k):
                best_lam[j] = lam[j]
    if not have:
        for j in range(2 * k):
            lam[j] = 0.0
        out_states[0] = SEPARATE
        out_states[1] = SEPARATE
        return False
    for j in range(2 * k):
        lam[j] = best_lam[j]
    out_states[0] = b0
    out_states[1] = b1
    return False


# ------------------------------------------------------------------------------ scratch space
_SCRATCH_FIELDS = {  # name: shape (int64 when the name is in _INT_FIELDS)
    "pts": (12, 2), "M": (7, 7), "Lm": (7, 7), "bvec": (7,), "tau": (7,),
    "acc": (7,), "rhs7": (7,), "vf": (7,), "q_old": (7,), "jx": (7,), "jz": (7,), "fjx": (2, 7), "fjz": (2, 7),
    "jc": (4, 7), "Ac": (4, 7), "G": (4, 4), "c": (4,), "lam": (4,), "best_lam": (4,), "w": (4,), "A": (4, 4),
    "rhs": (4,), "zz": (4,), "L": (4, 4), "cols_j": (4, 2), "cols_c": (4, 2), "cols_n": (4,), "rows": (4,),
    "sol": (2,), "cfoot": (2,), "cphi": (2,), "tfoot": (4,), "taxis": (4,), "tval": (4,),
    "fn": (2, 2), "fpos": (2, 2), "fa": (2,), "tdir": (4, 2),
    "B": (7, 4), "BT": (4, 7), "S": (4, 4), "Jr": (4, 7), "P": (3, 7), "dinv": (7,), "pt": (3,), "yt": (4,),
}
_INT_FIELDS = ("cols_j", "cols_n", "rows", "sol", "cfoot", "tfoot", "taxis")
Scratch = collections.namedtuple("Scratch", list(_SCRATCH_FIELDS))
"""Work arrays of the kernel (one set reused for every robot of a batch)."""


def kernel_scratch() -> Scratch:
    """A fresh :class:`Scratch` (zeros)."""
    return Scratch(*[np.zeros(shape, dtype=np.int64 if name in _INT_FIELDS else np.float64)
                     for name, shape in _SCRATCH_FIELDS.items()])


# ------------------------------------------------------------------------------ one step
@_jit
def _momentum_target(p, v, sc):
    """``sc.pt`` (3,): the centroidal momentum (linear x, z, angular y about the CoM) of ``v`` at the configuration
    whose inertia ``sc.M`` holds, plus gravity's impulse over one step (ContactSimulator._step, a free step)."""
    s_P = sc.P
    pt = sc.pt
    centroidal_rows(sc.M, s_P)
    for a in range(3):
        acc = 0.0
        for j in range(7):
            acc += s_P[a, j] * v[j]
        pt[a] = acc
    pt[1] -= sc.M[0, 0] * p[P_GRAVITY] * p[P_DT]


@_jit
def _project_flight(p, q, v, kinetic, target, sc, counters):
    """ContactSimulator._project_flight: the nearest ``v`` (mass metric) with kinetic energy ``target`` and the
    momentum ``sc.pt`` (``sc.pts``, ``sc.M`` at the current q)."""
    s_B = sc.B
    s_L = sc.L
    s_M = sc.M
    s_P = sc.P
    s_S = sc.S
    s_c = sc.c
    s_rhs = sc.rhs
    s_zz = sc.zz
    pt = sc.pt
    yt = sc.yt
    centroidal_rows(s_M, s_P)
    # B = M^-1 P^T without a solve: P = T M[:3, :] (centroidal_rows), so M^-1 P^T = I[:, :3] T^T, the rigid
    # motions of the locked robot: translations along x and z, and the rotation about the centre of mass
    rz = s_M[0, 2] / s_M[0, 0]
    rx = -s_M[1, 2] / s_M[0, 0]
    for j in range(7):
        s_B[j, 0] = 0.0
        s_B[j, 1] = 0.0
        s_B[j, 2] = 0.0
    s_B[0, 0] = 1.0
    s_B[1, 1] = 1.0
    s_B[0, 2] = -rz
    s_B[1, 2] = rx
    s_B[2, 2] = 1.0
    pm = s_c
    for a in range(3):
        acc = 0.0
        for j in range(7):
            acc += s_P[a, j] * v[j]
        pm[a] = acc
    for a in range(3):
        for b in range(3):
            acc = 0.0
            for j in range(3):  # B's rows past the base are zero
                acc += s_P[a, j] * s_B[j, b]
            s_S[a, b] = acc
    for a in range(3):
        s_rhs[a] = pt[a]
    ok = _solve_spd(s_S, s_rhs, 3, s_zz, s_L)
    for a in range(3):
        yt[a] = s_zz[a]
        s_rhs[a] = pm[a]
    ok = _solve_spd(s_S, s_rhs, 3, s_zz, s_L) and ok
    if not ok:
        for a in range(3):
            s_zz[a] = 0.0
            yt[a] = 0.0
    y = s_zz
    k_c = 0.5 * (pm[0] * y[0] + pm[1] * y[1] + pm[2] * y[2])
    k_t = 0.5 * (pt[0] * yt[0] + pt[1] * yt[1] + pt[2] * yt[2])
    free = kinetic - k_c
    if target >= k_t and free > 1e-14 * kinetic:
        factor = math.sqrt((target - k_t) / free)
        for j in range(3):
            vc = s_B[j, 0] * y[0] + s_B[j, 1] * y[1] + s_B[j, 2] * y[2]
            vt = s_B[j, 0] * yt[0] + s_B[j, 1] * yt[1] + s_B[j, 2] * yt[2]
            v[j] = (v[j] - vc) * factor + vt
        for j in range(3, 7):
            v[j] *= factor
        return target
    counters[2] += 1
    s = math.sqrt(target / kinetic)
    for j in range(7):
        v[j] *= s
    return target


@_jit
def mechanical_energy(p, x, sc):
    """``1/2 v^T M v + V`` [J] of one state (14,)."""
    s_M = sc.M
    s_pts = sc.pts
    kinematics(p, x[:NQ], s_pts)
    mass_matrix(p, s_pts, s_M)
    return kinetic_energy(s_M, x[NQ:]) + potential_energy(p, s_pts)


@_jit
def _load_model(p, q, cache, pts, M):
    """The points ``pts`` (12, 2) and mass matrix ``M`` (7, 7) of configuration ``q`` (7,): copied from the robot's
    ``cache`` (MODEL_CACHE_SIZE,) when it holds this very ``q`` (the state the robot's last step left, untouched
    since), else computed (:func:`kinematics`, :func:`mass_matrix`; the same numbers either way)."""
    for i in range(NQ):
        if not cache[_CACHE_Q + i] == q[i]:
            kinematics(p, q, pts)
            mass_matrix(p, pts, M)
            return
    for i in range(12):
        pts[i, 0] = cache[_CACHE_PTS + 2 * i]
        pts[i, 1] = cache[_CACHE_PTS + 2 * i + 1]
    for i in range(7):
        for j in range(7):
            M[i, j] = cache[_CACHE_M + 7 * i + j]


@_jit
def _store_model(q, pts, M, cache):
    """Keep ``q`` (7,), its points ``pts`` (12, 2) and mass matrix ``M`` (7, 7) in the robot's ``cache``."""
    for i in range(NQ):
        cache[_CACHE_Q + i] = q[i]
    for i in range(12):
        cache[_CACHE_PTS + 2 * i] = pts[i, 0]
        cache[_CACHE_PTS + 2 * i + 1] = pts[i, 1]
    for i in range(7):
        for j in range(7):
            cache[_CACHE_M + 7 * i + j] = M[i, j]


@_jit
def step_batch(p, x_batch, u_batch, n, active, states_batch, contact_batch, impulse_batch, sim_time, heights,
               counters_batch, cache_batch, sc):
    """``n`` simulation steps of every robot ``r`` with ``active[r]`` ((N,) bool; the others are left
    untouched): ``x_batch (N, 14)`` in place, ``u_batch (N, 4)`` commanded joint torques (ContactSimulator.run:
    the motor law every step, the energy taken at the start), ``states_batch (N, 2)``, ``contact_batch (N, 2)``,
    ``impulse_batch (N, 4)`` (summed over the ``n`` steps), ``sim_time (N,)`` (``+= h`` per step, accumulated
    like ``ContactSimulator.time``), ``heights (N, 2)`` foot heights after the steps, ``counters_batch (N, 4)``
    (see the module docstring), ``cache_batch (N, MODEL_CACHE_SIZE)`` each robot's model cache (:func:`model_cache`:
    the points and mass matrix its last step ended with, reused when the next call starts from the same
    configuration, as it does unless the caller moved the robot; the parameters ``p`` must stay the same),
    ``sc`` a :class:`Scratch`. Robots whose state is not finite are not stepped
    (NaN heights, no impulse); the caller ends their episodes.

    One function for the whole batch (ContactSimulator._step, _finish_consistent and _project_positions
    written out in line): numba passes a :class:`Scratch` to a call at a cost of about a microsecond (one
    reference count per array), more than a whole flight step, so it is unpacked here once per batch."""
    s_A = sc.A
    s_Ac = sc.Ac
    s_B = sc.B
    s_BT = sc.BT
    s_G = sc.G
    s_Jr = sc.Jr
    s_L = sc.L
    s_Lm = sc.Lm
    s_M = sc.M
    s_S = sc.S
    s_acc = sc.acc
    s_best_lam = sc.best_lam
    s_bvec = sc.bvec
    s_dinv = sc.dinv
    s_c = sc.c
    s_cfoot = sc.cfoot
    s_cols_c = sc.cols_c
    s_cols_j = sc.cols_j
    s_cols_n = sc.cols_n
    s_cphi = sc.cphi
    s_fjx = sc.fjx
    s_fjz = sc.fjz
    s_jc = sc.jc
    s_jx = sc.jx
    s_jz = sc.jz
    s_lam = sc.lam
    s_pts = sc.pts
    s_q_old = sc.q_old
    s_rhs = sc.rhs
    s_rhs7 = sc.rhs7
    s_rows = sc.rows
    s_sol = sc.sol
    s_tau = sc.tau
    s_taxis = sc.taxis
    s_tfoot = sc.tfoot
    s_tval = sc.tval
    s_vf = sc.vf
    s_w = sc.w
    s_zz = sc.zz
    h = p[P_DT]
    motor = p[P_MOTOR] != 0.0
    w_full, w_zero = p[P_W_FULL], p[P_W_ZERO]
    slope = p[P_TORQUE_LIMIT] / (w_zero - w_full) if motor else 0.0
    for i in range(3):
        s_tau[i] = 0.0
    for ir in range(x_batch.shape[0]):
        if not active[ir]:
            continue
        x = x_batch[ir]
        u = u_batch[ir]
        states = states_batch[ir]
        contact = contact_batch[ir]
        total = impulse_batch[ir]
        counters = counters_batch[ir]
        finite = True
        for i in range(NX):
            if not math.isfinite(x[i]):
                finite = False
        for i in range(4):
            total[i] = 0.0
        if finite and n > 0:
            q = x[:NQ]
            v = x[NQ:]
            pts = s_pts
            _load_model(p, q, cache_batch[ir], s_pts, s_M)  # the energy at the start (mechanical_energy)
            energy = kinetic_energy(s_M, v) + potential_energy(p, s_pts)
            for _ in range(n):
                for j in range(4):
                    uj = u[j]
                    if motor:
                        wj = x[NQ + 3 + j]
                        if uj * wj > 0.0 and abs(wj) > w_full:
                            cap = max(0.0, (w_zero - abs(wj)) * slope)
                            if abs(uj) > cap:
                                uj = cap if uj > 0.0 else -cap
                    s_tau[3 + j] = uj
                # ---- one step of h (ContactSimulator._step and _finish_consistent)
                # s_pts, s_M hold the kinematics and inertia of q (computed at the end of the last
                # step or for the energy at the start)
                bias(p, pts, v, s_bvec)
                for i in range(7):
                    s_rhs7[i] = s_tau[i] - s_bvec[i]
                tree_factor7(s_M, s_Lm, s_dinv)
                tree_solve7(s_Lm, s_dinv, s_rhs7, s_acc)
                vf = s_vf
                for i in range(7):
                    vf[i] = s_acc[i] * h + v[i]
                # candidate contacts
                cfoot, cphi = s_cfoot, s_cphi
                ncand = 0
                for foot in range(2):
                    phi = pts[_FOOT_POINT[foot], 1]
                    if phi > p[P_FAR]:
                        continue
                    fjz = s_fjz[foot]
                    point_jacobian(pts, 5 + foot, s_fjx[foot], fjz)  # the foot's rows, kept for the LCP
                    wn = 0.0
                    for j in range(7):
                        wn += fjz[j] * vf[j]
                    if phi <= CONTACT_MARGIN or phi + h * wn <= 0.0:
                        cfoot[ncand] = foot
                        cphi[ncand] = phi
                        ncand += 1
                power_start = 0.0
                if ncand == 0:
                    _momentum_target(p, v, sc)  # s_M holds the inertia of the step's start
                    for i in range(7):
                        power_start += s_tau[i] * v[i]
                    for i in range(7):
                        v[i] = vf[i]
                    states[0] = SEPARATE
                    states[1] = SEPARATE
                    contact[0] = False
                    contact[1] = False
                else:
                    m = 2 * ncand
                    for i in range(ncand):
                        foot = cfoot[i]
                        for j in range(7):
                            s_jc[2 * i, j] = s_fjz[foot, j]
                            s_jc[2 * i + 1, j] = s_fjx[foot, j]
                    tree_solve_rows(s_Lm, s_dinv, s_jc, m, s_Ac)  # A = J_c M^-1 (M symmetric: rows M^-1 J_c[r])
                    for r in range(m):
                        for s in range(m):
                            acc = 0.0
                            for k in range(7):
                                acc += s_Ac[r, k] * s_jc[s, k]
                            s_G[r, s] = acc
                        acc = 0.0
                        for k in range(7):
                            acc += s_jc[r, k] * vf[k]
                        s_c[r] = acc
                    for i in range(ncand):
                        if cphi[i] > 0.0:
                            s_c[2 * i] += cphi[i] / h
                    g0 = states[cfoot[0]]
                    g1 = states[cfoot[1]] if ncand == 2 else SEPARATE
                    exact = solve_lcp(s_G, s_c, p[P_MU], ncand, g0, g1, s_lam, s_sol, s_best_lam, s_w, s_A, s_rhs, s_zz,
                                      s_L, s_cols_j, s_cols_c, s_cols_n, s_rows)
                    if not exact:
                        counters[0] += 1
                    for j in range(7):
                        acc = 0.0
                        for r in range(m):
                            acc += s_lam[r] * s_Ac[r, j]
                        v[j] = acc + vf[j]
                    states[0] = SEPARATE
                    states[1] = SEPARATE
                    contact[0] = False
                    contact[1] = False
                    for i in range(ncand):
                        foot = cfoot[i]
                        ln, lt = s_lam[2 * i], s_lam[2 * i + 1]
                        states[foot] = s_sol[i]
                        total[2 * foot] += lt
                        total[2 * foot + 1] += ln
                        contact[foot] = ln > 1e-9
                # energy-consistent end of the step (ContactSimulator._finish_consistent)
                for i in range(7):
                    s_q_old[i] = q[i]
                for i in range(7):
                    q[i] += v[i] * h
                tfoot, taxis, tval = s_tfoot, s_taxis, s_tval
                nt = 0
                held0 = False
                held1 = False
                for i in range(ncand):
                    foot = cfoot[i]
                    st = states[foot]
                    if st == STICK:
                        jz_pitch = s_fjz[foot, 2]  # LWA z row, pitch column, at the step's start
                        tfoot[nt] = foot
                        taxis[nt] = 0
                        tval[nt] = s_q_old[0] - jz_pitch
                        nt += 1
                    if st != SEPARATE:
                        tfoot[nt] = foot
                        taxis[nt] = 1
                        tval[nt] = 0.0
                        nt += 1
                        if foot == 0:
                            held0 = True
                        else:
                            held1 = True
                kinematics(p, q, s_pts)
                for foot in range(2):  # any other foot that ends below the ground is lifted onto it
                    held = held0 if foot == 0 else held1
                    if not held and s_pts[_FOOT_POINT[foot], 1] < 0.0:
                        tfoot[nt] = foot
                        taxis[nt] = 1
                        tval[nt] = 0.0
                        nt += 1
                constrained = ncand > 0 or nt > 0
                if nt > 0:
                    res = s_rhs
                    for _ in range(_MAX_PROJECTION_ITERATIONS):
                        residual = 0.0
                        for a in range(nt):
                            res[a] = tval[a] - s_pts[_FOOT_POINT[tfoot[a]], taxis[a]]
                            residual = max(residual, abs(res[a]))
                        if residual <= POSITION_TOLERANCE:
                            break
                        for a in range(nt):
                            point_jacobian(s_pts, 5 + tfoot[a], s_jx, s_jz)
                            row = s_jx if taxis[a] == 0 else s_jz
                            for j in range(7):
                                s_Jr[a, j] = row[j]
                        tree_solve_rows(s_Lm, s_dinv, s_Jr, nt, s_BT)  # B = M^-1 Jr^T, the step's M (factor s_Lm)
                        for a in range(nt):
                            for j in range(7):
                                s_B[j, a] = s_BT[a, j]
                        for a in range(nt):
                            for b in range(nt):
                                acc = 0.0
                                for j in range(7):
                                    acc += s_Jr[a, j] * s_B[j, b]
                                s_S[a, b] = acc
                        if not _solve_spd(s_S, res, nt, s_zz, s_L):
                            break
                        for i in range(7):
                            acc = 0.0
                            for a in range(nt):
                                acc += s_B[i, a] * s_zz[a]
                            q[i] += acc
                        kinematics(p, q, s_pts)
                mass_matrix(p, s_pts, s_M)
                kinetic = kinetic_energy(s_M, v)
                potential = potential_energy(p, s_pts)
                tq = 0.0
                tq_old = 0.0
                for i in range(7):
                    tq += s_tau[i] * q[i]
                    tq_old += s_tau[i] * s_q_old[i]
                work = tq - tq_old
                if not constrained:  # flight: the second-order work, capped (ContactSimulator._finish_consistent)
                    power_end = 0.0
                    work = 0.0
                    for i in range(7):
                        power_end += s_tau[i] * v[i]
                        work += s_tau[i] * (v[i] * h)
                    work = min(work, 0.5 * h * (power_start + power_end))
                allowed = energy + work
                if kinetic + potential > allowed or not constrained:
                    # contacts: only an energy gain is removed; free flight: the allowed energy exactly
                    if kinetic + potential > allowed:
                        counters[1] += 1
                    target = allowed - potential
                    target -= 1e-13 * (abs(allowed) + abs(potential))
                    if target <= 0.0:
                        counters[3] += 1
                        for i in range(7):
                            v[i] = 0.0
                        kinetic = 0.0
                    elif constrained:
                        s = math.sqrt(target / kinetic)
                        for i in range(7):
                            v[i] *= s
                        kinetic = target
                    else:
                        kinetic = _project_flight(p, q, v, kinetic, target, sc, counters)
                energy = kinetic + potential

        for _ in range(n):
            sim_time[ir] += h
        if finite and n > 0:  # s_pts, s_M hold the kinematics and inertia of the last step's q
            _store_model(x[:NQ], s_pts, s_M, cache_batch[ir])
        else:
            kinematics(p, x[:NQ], s_pts)
        heights[ir, 0] = s_pts[6, 1]
        heights[ir, 1] = s_pts[11, 1]

@_jit
def step_batch_terrain(p, x_batch, u_batch, n, active, states_batch, contact_batch, impulse_batch, sim_time, heights,
               counters_batch, cache_batch, sc):
    """:func:`step_batch` on a terrain: the same arguments, with ``p`` holding the terrain's surface
    (:func:`kernel_params`; ``p[P_TERRAIN_N]`` vertices) and ``heights`` the feet's heights above the surface under
    each. A foot's contact is with the closest point of the surface (:func:`terrain_contact`): its gap is the distance
    to it, the LCP's rows are its velocity along the outward normal there and along the tangent (the friction cone in
    the local frame), and the impulses are turned back into the world frame; the position projection puts a contact
    foot on the tangent line of its contact point, a sticking foot at its start, and a foot below the surface onto its
    closest point (two rows at a concave corner; :func:`_terrain_rows`, :func:`_terrain_corner_rows`). A separate
    compiled function, so that the flat ground's :func:`step_batch` keeps its code (bit for bit) and its speed; with
    ``p[P_TERRAIN_N] = 0`` it steps the flat ground too."""
    s_A = sc.A
    s_Ac = sc.Ac
    s_B = sc.B
    s_BT = sc.BT
    s_G = sc.G
    s_Jr = sc.Jr
    s_L = sc.L
    s_Lm = sc.Lm
    s_M = sc.M
    s_S = sc.S
    s_acc = sc.acc
    s_best_lam = sc.best_lam
    s_bvec = sc.bvec
    s_dinv = sc.dinv
    s_c = sc.c
    s_cfoot = sc.cfoot
    s_cols_c = sc.cols_c
    s_cols_j = sc.cols_j
    s_cols_n = sc.cols_n
    s_cphi = sc.cphi
    s_fjx = sc.fjx
    s_fjz = sc.fjz
    s_jc = sc.jc
    s_jx = sc.jx
    s_jz = sc.jz
    s_lam = sc.lam
    s_pts = sc.pts
    s_q_old = sc.q_old
    s_rhs = sc.rhs
    s_rhs7 = sc.rhs7
    s_rows = sc.rows
    s_sol = sc.sol
    s_tau = sc.tau
    s_taxis = sc.taxis
    s_tfoot = sc.tfoot
    s_tval = sc.tval
    s_vf = sc.vf
    s_w = sc.w
    s_zz = sc.zz
    s_fn = sc.fn
    s_fpos = sc.fpos
    s_fa = sc.fa
    s_tdir = sc.tdir
    h = p[P_DT]
    nter = int(p[P_TERRAIN_N])  # 0: flat ground (the code paths below are the flat ground's, unchanged)
    motor = p[P_MOTOR] != 0.0
    w_full, w_zero = p[P_W_FULL], p[P_W_ZERO]
    slope = p[P_TORQUE_LIMIT] / (w_zero - w_full) if motor else 0.0
    for i in range(3):
        s_tau[i] = 0.0
    for ir in range(x_batch.shape[0]):
        if not active[ir]:
            continue
        x = x_batch[ir]
        u = u_batch[ir]
        states = states_batch[ir]
        contact = contact_batch[ir]
        total = impulse_batch[ir]
        counters = counters_batch[ir]
        finite = True
        for i in range(NX):
            if not math.isfinite(x[i]):
                finite = False
        for i in range(4):
            total[i] = 0.0
        if finite and n > 0:
            q = x[:NQ]
            v = x[NQ:]
            pts = s_pts
            _load_model(p, q, cache_batch[ir], s_pts, s_M)  # the energy at the start (mechanical_energy)
            energy = kinetic_energy(s_M, v) + potential_energy(p, s_pts)
            for _ in range(n):
                for j in range(4):
                    uj = u[j]
                    if motor:
                        wj = x[NQ + 3 + j]
                        if uj * wj > 0.0 and abs(wj) > w_full:
                            cap = max(0.0, (w_zero - abs(wj)) * slope)
                            if abs(uj) > cap:
                                uj = cap if uj > 0.0 else -cap
                    s_tau[3 + j] = uj
                # ---- one step of h (ContactSimulator._step and _finish_consistent)
                # s_pts, s_M hold the kinematics and inertia of q (computed at the end of the last
                # step or for the energy at the start)
                bias(p, pts, v, s_bvec)
                for i in range(7):
                    s_rhs7[i] = s_tau[i] - s_bvec[i]
                tree_factor7(s_M, s_Lm, s_dinv)
                tree_solve7(s_Lm, s_dinv, s_rhs7, s_acc)
                vf = s_vf
                for i in range(7):
                    vf[i] = s_acc[i] * h + v[i]
                # candidate contacts
                cfoot, cphi = s_cfoot, s_cphi
                ncand = 0
                for foot in range(2):
                    if nter == 0:
                        phi = pts[_FOOT_POINT[foot], 1]
                        if phi > p[P_FAR]:
                            continue
                        fjz = s_fjz[foot]
                        point_jacobian(pts, 5 + foot, s_fjx[foot], fjz)  # the foot's rows, kept for the LCP
                    else:  # terrain (_terrain_candidate: the closest point, the LCP's rows along n and t)
                        phi = _terrain_candidate(p, pts, foot, s_fjx, s_fjz, s_fn, s_fpos, s_fa)
                        if phi > p[P_FAR]:
                            continue
                        fjz = s_fjz[foot]
                    wn = 0.0
                    for j in range(7):
                        wn += fjz[j] * vf[j]
                    if phi <= CONTACT_MARGIN or phi + h * wn <= 0.0:
                        cfoot[ncand] = foot
                        cphi[ncand] = phi
                        ncand += 1
                power_start = 0.0
                if ncand == 0:
                    _momentum_target(p, v, sc)  # s_M holds the inertia of the step's start
                    for i in range(7):
                        power_start += s_tau[i] * v[i]
                    for i in range(7):
                        v[i] = vf[i]
                    states[0] = SEPARATE
                    states[1] = SEPARATE
                    contact[0] = False
                    contact[1] = False
                else:
                    m = 2 * ncand
                    for i in range(ncand):
                        foot = cfoot[i]
                        for j in range(7):
                            s_jc[2 * i, j] = s_fjz[foot, j]
                            s_jc[2 * i + 1, j] = s_fjx[foot, j]
                    tree_solve_rows(s_Lm, s_dinv, s_jc, m, s_Ac)  # A = J_c M^-1 (M symmetric: rows M^-1 J_c[r])
                    for r in range(m):
                        for s in range(m):
                            acc = 0.0
                            for k in range(7):
                                acc += s_Ac[r, k] * s_jc[s, k]
                            s_G[r, s] = acc
                        acc = 0.0
                        for k in range(7):
                            acc += s_jc[r, k] * vf[k]
                        s_c[r] = acc
                    for i in range(ncand):
                        if cphi[i] > 0.0:
                            s_c[2 * i] += cphi[i] / h
                    g0 = states[cfoot[0]]
                    g1 = states[cfoot[1]] if ncand == 2 else SEPARATE
                    exact = solve_lcp(s_G, s_c, p[P_MU], ncand, g0, g1, s_lam, s_sol, s_best_lam, s_w, s_A, s_rhs, s_zz,
                                      s_L, s_cols_j, s_cols_c, s_cols_n, s_rows)
                    if not exact:
                        counters[0] += 1
                    for j in range(7):
                        acc = 0.0
                        for r in range(m):
                            acc += s_lam[r] * s_Ac[r, j]
                        v[j] = acc + vf[j]
                    states[0] = SEPARATE
                    states[1] = SEPARATE
                    contact[0] = False
                    contact[1] = False
                    for i in range(ncand):
                        foot = cfoot[i]
                        ln, lt = s_lam[2 * i], s_lam[2 * i + 1]
                        states[foot] = s_sol[i]
                        if nter == 0:
                            total[2 * foot] += lt
                            total[2 * foot + 1] += ln
                        else:  # the impulse along (n, t) in the world frame
                            nx, nz = s_fn[foot, 0], s_fn[foot, 1]
                            total[2 * foot] += nz * lt + nx * ln
                            total[2 * foot + 1] += nz * ln - nx * lt
                        contact[foot] = ln > 1e-9
                # energy-consistent end of the step (ContactSimulator._finish_consistent)
                for i in range(7):
                    s_q_old[i] = q[i]
                for i in range(7):
                    q[i] += v[i] * h
                tfoot, taxis, tval, tdir = s_tfoot, s_taxis, s_tval, s_tdir
                nt = 0
                held0 = False
                held1 = False
                if nter == 0:
                    for i in range(ncand):
                        foot = cfoot[i]
                        st = states[foot]
                        if st == STICK:
                            jz_pitch = s_fjz[foot, 2]  # LWA z row, pitch column, at the step's start
                            tfoot[nt] = foot
                            taxis[nt] = 0
                            tval[nt] = s_q_old[0] - jz_pitch
                            nt += 1
                        if st != SEPARATE:
                            tfoot[nt] = foot
                            taxis[nt] = 1
                            tval[nt] = 0.0
                            nt += 1
                            if foot == 0:
                                held0 = True
                            else:
                                held1 = True
                    kinematics(p, q, s_pts)
                    for foot in range(2):  # any other foot that ends below the ground is lifted onto it
                        held = held0 if foot == 0 else held1
                        if not held and s_pts[_FOOT_POINT[foot], 1] < 0.0:
                            tfoot[nt] = foot
                            taxis[nt] = 1
                            tval[nt] = 0.0
                            nt += 1
                else:  # terrain: rows along directions (taxis 2), _terrain_rows
                    kinematics(p, q, s_pts)
                    nt = _terrain_rows(p, s_pts, ncand, cfoot, states, s_fn, s_fpos, s_fa, tfoot, taxis, tdir, tval)
                constrained = ncand > 0 or nt > 0
                if nt > 0:
                    res = s_rhs
                    for _ in range(_MAX_PROJECTION_ITERATIONS):
                        residual = 0.0
                        for a in range(nt):
                            fp = _FOOT_POINT[tfoot[a]]
                            if taxis[a] == 2:
                                res[a] = tval[a] - (tdir[a, 0] * s_pts[fp, 0] + tdir[a, 1] * s_pts[fp, 1])
                            else:
                                res[a] = tval[a] - s_pts[fp, taxis[a]]
                            residual = max(residual, abs(res[a]))
                        if nter > 0 and nt < 4:  # a foot moved below another piece: _terrain_corner_rows
                            nt, residual = _terrain_corner_rows(p, s_pts, nt, tfoot, taxis, tdir, tval, res, residual)
                        if residual <= POSITION_TOLERANCE:
                            break
                        for a in range(nt):
                            point_jacobian(s_pts, 5 + tfoot[a], s_jx, s_jz)
                            if taxis[a] == 2:
                                for j in range(7):
                                    s_Jr[a, j] = tdir[a, 0] * s_jx[j] + tdir[a, 1] * s_jz[j]
                            else:
                                row = s_jx if taxis[a] == 0 else s_jz
                                for j in range(7):
                                    s_Jr[a, j] = row[j]
                        tree_solve_rows(s_Lm, s_dinv, s_Jr, nt, s_BT)  # B = M^-1 Jr^T, the step's M (factor s_Lm)
                        for a in range(nt):
                            for j in range(7):
                                s_B[j, a] = s_BT[a, j]
                        for a in range(nt):
                            for b in range(nt):
                                acc = 0.0
                                for j in range(7):
                                    acc += s_Jr[a, j] * s_B[j, b]
                                s_S[a, b] = acc
                        if not _solve_spd(s_S, res, nt, s_zz, s_L):
                            break
                        for i in range(7):
                            acc = 0.0
                            for a in range(nt):
                                acc += s_B[i, a] * s_zz[a]
                            q[i] += acc
                        kinematics(p, q, s_pts)
                mass_matrix(p, s_pts, s_M)
                kinetic = kinetic_energy(s_M, v)
                potential = potential_energy(p, s_pts)
                tq = 0.0
                tq_old = 0.0
                for i in range(7):
                    tq += s_tau[i] * q[i]
                    tq_old += s_tau[i] * s_q_old[i]
                work = tq - tq_old
                if not constrained:  # flight: the second-order work, capped (ContactSimulator._finish_consistent)
                    power_end = 0.0
                    work = 0.0
                    for i in range(7):
                        power_end += s_tau[i] * v[i]
                        work += s_tau[i] * (v[i] * h)
                    work = min(work, 0.5 * h * (power_start + power_end))
                allowed = energy + work
                if kinetic + potential > allowed or not constrained:
                    # contacts: only an energy gain is removed; free flight: the allowed energy exactly
                    if kinetic + potential > allowed:
                        counters[1] += 1
                    target = allowed - potential
                    target -= 1e-13 * (abs(allowed) + abs(potential))
                    if target <= 0.0:
                        counters[3] += 1
                        for i in range(7):
                            v[i] = 0.0
                        kinetic = 0.0
                    elif constrained:
                        s = math.sqrt(target / kinetic)
                        for i in range(7):
                            v[i] *= s
                        kinetic = target
                    else:
                        kinetic = _project_flight(p, q, v, kinetic, target, sc, counters)
                energy = kinetic + potential

        for _ in range(n):
            sim_time[ir] += h
        if finite and n > 0:  # s_pts, s_M hold the kinematics and inertia of the last step's q
            _store_model(x[:NQ], s_pts, s_M, cache_batch[ir])
        else:
            kinematics(p, x[:NQ], s_pts)
        if nter == 0:
            heights[ir, 0] = s_pts[6, 1]
            heights[ir, 1] = s_pts[11, 1]
        else:  # terrain: the feet's heights above the surface under them
            for foot in range(2):
                fx, fz = s_pts[_FOOT_POINT[foot], 0], s_pts[_FOOT_POINT[foot], 1]
                th, _, _, _ = terrain_piece(p, fx)
                heights[ir, foot] = fz - th


def run_one(p, x, u, n, states, contact, total, sc, counters) -> None:
    """``n`` steps of one robot (ContactSimulator.run): :func:`step_batch` on a batch of one. ``x`` (14,) in
    place, ``u`` (4,) commanded torques, ``states`` (2,) int64, ``contact`` (2,) bool, ``total`` (4,) the summed
    impulses, ``counters`` (4,) int64 (all updated in place)."""
    step_batch(p, x.reshape(1, NX), np.asarray(u, dtype=np.float64).reshape(1, 4), int(n), np.ones(1, dtype=np.bool_),
               states.reshape(1, 2), contact.reshape(1, 2), total.reshape(1, 4), np.zeros(1), np.zeros((1, 2)),
               counters.reshape(1, 4), model_cache(1), sc)


_READY = False
ANNOUNCE_AFTER_S = 5.0
"""With a cache index on disk, the warm-up still says that numba compiles when it takes longer than this."""


def _cache_index_exists() -> bool:
    """Whether numba's cache index of :func:`step_batch` is on disk (numba internals: False if they moved)."""
    import os

    try:
        return os.path.exists(step_batch._cache._cache_file._index_path)
    except AttributeError:  # pragma: no cover (another numba version)
        return False


def warm_up(announce: bool = True) -> float:
    """Make the kernel ready before anything is timed: compile it (the first run on a machine, about a minute)
    or load numba's on-disk cache (``cache=True``; later runs, about a second), once per process. With
    ``announce``, a line on stderr says when a compile is under way and how long it took. Returns the seconds
    spent (0 when already done)."""
    global _READY
    if _READY:
        return 0.0
    import threading

    def say():
        print("numba: compiling the batched contact kernel, once (the first run on this machine takes about a "
              f"minute; later runs load it from the cache in {step_batch.stats.cache_path}) ...", file=sys.stderr,
              flush=True)

    if announce and not _cache_index_exists():
        say()
        announce_later = False
    else:
        announce_later = announce
    timer = threading.Timer(ANNOUNCE_AFTER_S, say) if announce_later else None
    if timer is not None:
        timer.daemon = True
        timer.start()
    start = _time.perf_counter()
    try:
        p = kernel_params(ContactSimulator())
        n = 1
        x = np.zeros((n, NX))
        x[:, 1] = 0.5
        step_batch(p, x, np.zeros((n, 4)), 1, np.ones(n, dtype=np.bool_), np.zeros((n, 2), dtype=np.int64),
                   np.zeros((n, 2), dtype=np.bool_), np.zeros((n, 4)), np.zeros(n), np.zeros((n, 2)),
                   np.zeros((n, 4), dtype=np.int64), model_cache(n), kernel_scratch())
    finally:
        if timer is not None:
            timer.cancel()
    elapsed = _time.perf_counter() - start
    if announce and sum(step_batch.stats.cache_misses.values()):
        print(f"numba: compiled in {elapsed:.1f} s; cached for later runs", file=sys.stderr, flush=True)
    _READY = True
    return elapsed


# ------------------------------------------------------------------------------ one robot through the kernel
def _counter_property(index: int, name: str) -> property:
    def get(self) -> int:
        return int(self._counters_b[0, index])

    def set_(self, value) -> None:
        self._counters_b[0, index] = value

    return property(get, set_, doc=f"``{name}`` of :class:`ContactSimulator`, counted by the kernel.")


class CompiledContactSimulator(ContactSimulator):
    """:class:`ContactSimulator`'s energy-consistent scheme stepped by the compiled kernel: :meth:`run` is one
    :func:`step_batch` call on a batch of one robot, the same compiled code the vector env
    (:mod:`hsddp_gym.envs.vector`) runs for N robots, so a single env and the vector env produce bit-identical
    states from the same inputs. ``hsddp_gym/Bounding-v0`` uses it for ``energy_consistent=True``;
    :class:`ContactSimulator` stays the readable reference (the MPC's predictor,
    :class:`~hsddp_gym.planners.policies.estimation.ContactModelPredictor`, uses this one); the two agree to
    round-off (``tests/test_vector_env.py``: 1e-11 relative, median 4e-16).

    Same arguments as :class:`ContactSimulator` without ``erp`` and ``energy_consistent`` (the legacy scheme is
    not compiled), and the same attributes, with these differences: ``x`` (with its views ``q``, ``v``),
    ``states`` (an int64 array (2,)), ``contact``, ``time`` and the counters live in the kernel's batch-of-one
    arrays (assigning to them writes into those); ``impulse`` holds the impulses summed over the last
    :meth:`run` call (the last step's for ``run(u, 1)``), which is also what :meth:`run` returns (an array, reused
    by the next call); ``projection_residual`` is not tracked (stays 0). :meth:`foot_heights_fast` returns the
    kernel's foot heights of the state the last :meth:`run` left (Pinocchio's after :meth:`set_state`; pushes
    change only ``v``). ``_tau`` holds the torques the motors applied in the last step, as in
    :class:`ContactSimulator`. :meth:`energy` and the other queries are Pinocchio's, as in :class:`ContactSimulator`.
    ``terrain`` (a :class:`~hsddp_gym.core.terrain.Terrain` or None, :meth:`set_terrain`): stepped by
    :func:`step_batch_terrain` (its own compiled function, compiled on first use), the feet's heights above its surface.
    The kernel is compiled once per machine (:func:`warm_up`, announced on stderr) when the first one is built.
    """

    lcp_fallbacks = _counter_property(0, "lcp_fallbacks")
    energy_projections = _counter_property(1, "energy_projections")
    momentum_fallbacks = _counter_property(2, "momentum_fallbacks")
    energy_deficits = _counter_property(3, "energy_deficits")

    def __init__(self, robot=None, timestep: float = 1e-3, friction: float | None = None,
                 gravity: float | None = None, motor_speed_limits=None, torque_limit: float | None = None,
                 terrain=None) -> None:
        # batch-of-one arrays the kernel works in (created before ContactSimulator.__init__ assigns through
        # the properties below)
        self._xb = np.zeros((1, NX))
        self._ub = np.zeros((1, 4))
        self._states_b = np.zeros((1, 2), dtype=np.int64)
        self._contact_b = np.zeros((1, 2), dtype=np.bool_)
        self._total_b = np.zeros((1, 4))
        self._time_b = np.zeros(1)
        self._heights_b = np.zeros((1, 2))
        self._counters_b = np.zeros((1, 4), dtype=np.int64)
        self._cache_b = model_cache(1)
        self._active = np.ones(1, dtype=np.bool_)
        self._heights_valid = False
        super().__init__(robot, timestep=timestep, friction=friction, gravity=gravity,
                         motor_speed_limits=motor_speed_limits, torque_limit=torque_limit, energy_consistent=True)
        self.terrain = check_terrain(terrain)
        self._p = kernel_params(self)
        self._sc = kernel_scratch()
        self._link_views()
        warm_up()

    def _link_views(self) -> None:
        """The attributes that are views of the batch-of-one arrays (again after a copy, which copies views
        as separate arrays)."""
        self.x = self._xb[0]
        self.q = self.x[:NQ]
        self.v = self.x[NQ:]
        self.contact = self._contact_b[0]
        self._total = self._total_b[0]
        self._u = self._ub[0]
        self._tau = self._sc.tau  # the applied torques of the last step (the kernel's), as ContactSimulator's

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._link_views()

    # state kept in the kernel's arrays
    @property
    def time(self) -> float:
        """Simulated time since :meth:`set_state` [s] (accumulated ``+= h`` per step by the kernel)."""
        return float(self._time_b[0])

    @time.setter
    def time(self, value: float) -> None:
        self._time_b[0] = value

    @property
    def states(self) -> np.ndarray:
        """Per-foot contact state of the last step, int64 (2,) (a view: writes set the LCP's first guess)."""
        return self._states_b[0]

    @states.setter
    def states(self, value) -> None:
        self._states_b[0] = value

    @property
    def impulse(self) -> np.ndarray:
        """Ground impulses summed over the last :meth:`run` call [N s], grf layout (4,)."""
        return self._total_b[0]

    @impulse.setter
    def impulse(self, value) -> None:
        self._total_b[0] = value

    def set_state(self, x: np.ndarray) -> None:
        """Set the state ``x`` (14,), reset the clock, contact states and impulses."""
        super().set_state(x)
        self._heights_valid = False

    def set_terrain(self, terrain) -> None:
        """Simulate on ``terrain`` (a :class:`~hsddp_gym.core.terrain.Terrain`, or None: the flat ground) from now
        on: the kernel's parameters get its surface (:func:`kernel_params`)."""
        self.terrain = check_terrain(terrain)
        self._p = kernel_params(self)
        self._heights_valid = False

    def foot_heights_fast(self) -> tuple[float, float]:
        """Foot heights ``(front, back)`` above the ground (with a terrain: above its surface under each foot): the
        kernel's after a :meth:`run`, Pinocchio's after :meth:`set_state`."""
        if self._heights_valid:
            h = self._heights_b[0]
            return float(h[0]), float(h[1])
        if self.terrain is not None:
            h = self.foot_heights()
            return float(h[0]), float(h[1])
        return super().foot_heights_fast()

    def run(self, u: np.ndarray, n: int) -> np.ndarray:
        """``n`` steps with constant commanded joint torques ``u`` (4,) (unchecked: the env validates), in one
        compiled call.

        Returns:
            The summed ground impulses over the ``n`` steps, grf layout (4,) [N s] (an array reused by the next
            call).
        """
        self._u[:] = u
        kernel = step_batch if self.terrain is None else step_batch_terrain
        kernel(self._p, self._xb, self._ub, n, self._active, self._states_b, self._contact_b, self._total_b,
               self._time_b, self._heights_b, self._counters_b, self._cache_b, self._sc)
        self._heights_valid = True
        return self._total
