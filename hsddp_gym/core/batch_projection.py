"""The energy and momentum projection of a flight step in the contact kernel
([`hsddp_gym.core.batch_contact`][hsddp_gym.core.batch_contact]), compiled with numba: the free flight of
[`ContactSimulator`][hsddp_gym.core.contact.ContactSimulator]'s energy-consistent step (``_finish_consistent``,
``_project_flight``), written out.

In free flight the step's velocity ``v+`` is moved to the nearest point (mass metric) with the centroidal momentum
of the step's start plus gravity's impulse ([`momentum_target`][momentum_target], taken before the step) and with the
allowed kinetic energy ([`project_flight`][project_flight]). Both read the kernel's scratch (``sc``, a
[`Scratch`][hsddp_gym.core.batch_contact.Scratch]): ``sc.M`` (7, 7) the inertia of the configuration, ``sc.pt`` (3,) the
momentum target, and its small work arrays.
"""

from __future__ import annotations

import math

from hsddp_gym.core.batch_lcp import solve_spd
from hsddp_gym.core.batch_model import P_DT, P_GRAVITY, centroidal_rows, kernel_jit


@kernel_jit
def momentum_target(p, v, sc):
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


@kernel_jit
def project_flight(p, q, v, kinetic, target, sc, counters):
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
    ok = solve_spd(s_S, s_rhs, 3, s_zz, s_L)
    for a in range(3):
        yt[a] = s_zz[a]
        s_rhs[a] = pm[a]
    ok = solve_spd(s_S, s_rhs, 3, s_zz, s_L) and ok
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
