"""The planar Mini Cheetah's rigid-body terms in closed form, compiled with numba: the contact kernel's model
([`hsddp_gym.core.batch_contact`][hsddp_gym.core.batch_contact]).

The model is still Pinocchio's: [`kernel_params`][kernel_params] reads every number from the
[`CheetahModel`][hsddp_gym.core.model.CheetahModel] (its [`RobotParams`][hsddp_gym.core.params.RobotParams]) into the
parameter vector ``p`` (the ``P_*`` slots), and ``tests/test_vector_env.py`` checks the closed-form mass matrix, bias,
foot positions and Jacobians, centroidal momentum map and energies against ``pin.crba``, ``pin.nonLinearEffects``, frame
Jacobians, ``pin.computeCentroidalMap`` and ``pin.computeMechanicalEnergy`` to 1e-12 at random states. Pinocchio's
ABA and ``computeMinverse`` are replaced by one sparse ``L^T D L`` factorization of ``M`` along the kinematic tree
([`tree_factor7`][tree_factor7]), which is where the kernel's round-off differences to
[`ContactSimulator`][hsddp_gym.core.contact.ContactSimulator] come from (at cond(M) ~ 2e4, ``computeMinverse`` and
``inv(crba)`` differ by ~8e-12 themselves).

Closed form (world frame, ``R(t) (a, c) = (cos t a + sin t c, -sin t a + cos t c)`` the rotation about
+y) for the planar tree ``x -> z -> pitch -> {front, back} hip -> knee -> foot``: each body's centre of mass ``p``
has the Jacobian columns ``[1, 0]`` (x), ``[0, 1]`` (z) and, for each revolute joint of its chain with pivot ``o``,
``[p_z - o_z, -(p_x - o_x)]``; its angular Jacobian is 1 on its chain's revolute joints.
``M = sum m J_p^T J_p + I J_w^T J_w``; the bias is ``b = sum m J_p^T (a_p + [0, g])`` with
``a_p = -sum_k w_k^2 s_k`` (``s_k`` the chain segments, ``w_k`` their absolute rates: the planar
Coriolis/centrifugal acceleration at zero joint accelerations).

Speed: the kinematics use [`sincos`][sincos] inline instead of libm's call, [`mass_matrix`][mass_matrix] and
[`bias`][bias] work from per-leg lever arms, the tree factorization has no fill and no square roots,
[`kinetic_energy`][kinetic_energy] sums over ``M``'s nonzeros; a robot's model cache ([`model_cache`][model_cache])
spares the recomputation of the points and ``M`` a call starts from. No fast-math flag ([`kernel_jit`][kernel_jit]).

Arrays: ``q (7,)`` a configuration, ``pts (12, 2)`` the world ``(x, z)`` of the points ([`FOOT_POINT`][FOOT_POINT]),
``M (7, 7)`` the joint-space inertia, ``p`` the parameter vector ([`N_PARAMS`][N_PARAMS], plus a terrain's vertices).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from hsddp_gym.core.contact import ContactSimulator
from hsddp_gym.core.conventions import FOOT_SIGN, NQ

kernel_jit = numba.njit(error_model="numpy")
"""numba's compile options for the kernel's functions: numpy's error model (no Python exception checks on each
division: every divisor is checked before, as in [`hsddp_gym.core.contact`][hsddp_gym.core.contact]); no fast-math flag
(fused multiply-adds would make the round-off, and so whole episodes, depend on the CPU). Not cached on their own: numba
compiles them into the step that calls them ([`hsddp_gym.core.batch_contact`][hsddp_gym.core.batch_contact]), whose
cache entry holds them and is keyed by their sources (a function called from Python, as the tests do, is compiled in
that process)."""

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
``p[N_PARAMS:N_PARAMS + K]``, ``zs`` (K,) after them ([`kernel_params`][kernel_params],
[`terrain_piece`][hsddp_gym.core.batch_terrain.terrain_piece])."""

# points (rows of the (12, 2) point array): 0 trunk origin, 1 trunk CoM, then per leg hip, thigh CoM, knee,
# shank CoM, foot (front: 2..6, back: 7..11)
FOOT_POINT = np.array([6, 11])
"""The rows of the front and back feet in the point array."""
# chains: bodies 0..4 (trunk, thigh_f, shank_f, thigh_b, shank_b), then the feet 5, 6
_CHAIN_POINT = np.array([1, 3, 5, 8, 10, 6, 11])
_CHAIN_LEN = np.array([1, 2, 3, 2, 3, 3, 3])
_CHAIN_PIVOT = np.array([[0, 0, 0], [0, 2, 0], [0, 2, 4], [0, 7, 0], [0, 7, 9], [0, 2, 4], [0, 7, 9]])
_CHAIN_DOF = np.array([[2, 0, 0], [2, 3, 0], [2, 3, 4], [2, 5, 0], [2, 5, 6], [2, 3, 4], [2, 5, 6]])

# a robot's model cache (row of the (N, MODEL_CACHE_SIZE) array of the batch step): the configuration q, its 12
# points and its mass matrix, as the robot's last step left them
_CACHE_Q = 0
_CACHE_PTS = NQ
_CACHE_M = NQ + 24
MODEL_CACHE_SIZE = NQ + 24 + 49


def model_cache(n: int) -> np.ndarray:
    """An empty model cache for ``n`` robots (n, MODEL_CACHE_SIZE): NaN configurations, which match no state."""
    return np.full((n, MODEL_CACHE_SIZE), np.nan)


def kernel_params(sim: ContactSimulator) -> np.ndarray:
    """The parameter vector (N_PARAMS,) of a simulator: its robot's [`RobotParams`][hsddp_gym.core.params.RobotParams],
    friction, gravity, step, torque limit and motor law; with a terrain (``sim.terrain``, a
    [`Terrain`][hsddp_gym.core.terrain.Terrain] that is not None), followed by its surface's vertices
    ([`surface_vertices`][hsddp_gym.core.terrain.Terrain.surface_vertices]). Only the energy-consistent scheme is
    compiled (ValueError otherwise)."""
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


@kernel_jit
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


# ------------------------------------------------------------------------------ kinematics and dynamics
@kernel_jit
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


@kernel_jit
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


@kernel_jit
def _leg_inertia(m1, m2, i1, i2, x0, z0, hx, hz, tx, tz, kx, kz, sx, sz):
    """One leg's terms of [`mass_matrix`][mass_matrix], from the trunk origin ``(x0, z0)``, the hip ``(hx, hz)``, thigh
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


@kernel_jit
def mass_matrix(p, pts, M):
    """Joint-space inertia ``M`` (7, 7) at the points ``pts`` of [`kinematics`][kinematics], in closed form: with body
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


@kernel_jit
def _leg_bias(m1, m2, g, r0, x0, z0, w1, w2, hx, hz, tx, tz, kx, kz, sx, sz):
    """One leg's terms of [`bias`][bias] from scalars (the trunk origin, hip, thigh CoM, knee, shank CoM; ``r0``
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


@kernel_jit
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


@kernel_jit
def potential_energy(p, pts):
    """``sum m g z_com`` [J] at the points ``pts`` (the trunk, thigh and shank CoMs, front then back)."""
    m0, m1, m2 = p[P_MASS], p[P_MASS + 1], p[P_MASS + 2]
    e = m0 * pts[1, 1] + m1 * pts[3, 1] + m2 * pts[5, 1] + m1 * pts[8, 1] + m2 * pts[10, 1]
    return e * p[P_GRAVITY]


@kernel_jit
def kinetic_energy(M, v):
    """``1/2 v^T M v`` [J] over the nonzeros of [`mass_matrix`][mass_matrix] (``M[x, z]`` and the legs' cross terms are
    0): the diagonal plus twice the upper triangle."""
    d = 0.0
    for i in range(7):
        d += M[i, i] * v[i] * v[i]
    off = v[0] * (M[0, 2] * v[2] + M[0, 3] * v[3] + M[0, 4] * v[4] + M[0, 5] * v[5] + M[0, 6] * v[6])
    off += v[1] * (M[1, 2] * v[2] + M[1, 3] * v[3] + M[1, 4] * v[4] + M[1, 5] * v[5] + M[1, 6] * v[6])
    off += v[2] * (M[2, 3] * v[3] + M[2, 4] * v[4] + M[2, 5] * v[5] + M[2, 6] * v[6])
    off += v[3] * M[3, 4] * v[4] + v[5] * M[5, 6] * v[6]
    return 0.5 * d + off


@kernel_jit
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


@kernel_jit
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


@kernel_jit
def tree_solve7(L, dinv, b, out):
    """``out = M^-1 b`` (7,) from the factor of [`tree_factor7`][tree_factor7]: ``L^T y = b`` from the leaves up, then
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


@kernel_jit
def tree_solve_rows(L, dinv, R, m, out):
    """``out[r] = M^-1 R[r]`` for the rows ``r < m`` of ``R`` (m, 7) ([`tree_solve7`][tree_solve7] on each)."""
    for r in range(m):
        tree_solve7(L, dinv, R[r], out[r])

@kernel_jit
def mechanical_energy(p, x, sc):
    """``1/2 v^T M v + V`` [J] of one state (14,)."""
    s_M = sc.M
    s_pts = sc.pts
    kinematics(p, x[:NQ], s_pts)
    mass_matrix(p, s_pts, s_M)
    return kinetic_energy(s_M, x[NQ:]) + potential_energy(p, s_pts)


@kernel_jit
def load_model(p, q, cache, pts, M):
    """The points ``pts`` (12, 2) and mass matrix ``M`` (7, 7) of configuration ``q`` (7,): copied from the robot's
    ``cache`` (MODEL_CACHE_SIZE,) when it holds this very ``q`` (the state the robot's last step left, untouched
    since), else computed ([`kinematics`][kinematics], [`mass_matrix`][mass_matrix]; the same numbers either way)."""
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


@kernel_jit
def store_model(q, pts, M, cache):
    """Keep ``q`` (7,), its points ``pts`` (12, 2) and mass matrix ``M`` (7, 7) in the robot's ``cache``."""
    for i in range(NQ):
        cache[_CACHE_Q + i] = q[i]
    for i in range(12):
        cache[_CACHE_PTS + 2 * i] = pts[i, 0]
        cache[_CACHE_PTS + 2 * i + 1] = pts[i, 1]
    for i in range(7):
        for j in range(7):
            cache[_CACHE_M + 7 * i + j] = M[i, j]
