"""The contact simulation of [`hsddp_gym.core.contact`][hsddp_gym.core.contact] for ``N`` robots in one compiled (numba)
call: [`step_batch`][step_batch] on the flat ground, [`step_batch_terrain`][step_batch_terrain] on a terrain's surface.

[`ContactSimulator`][hsddp_gym.core.contact.ContactSimulator] steps one robot with Pinocchio calls from Python; this
module is the same scheme -- semi-implicit Euler velocity step, the exact planar Coulomb LCP by
enumeration of foot states (the previous states first, then the same fixed order;
[`hsddp_gym.core.batch_lcp`][hsddp_gym.core.batch_lcp]), the mass-metric position projection (Newton to
[`POSITION_TOLERANCE`][hsddp_gym.core.contact.POSITION_TOLERANCE]; contact feet and every foot that ended below the
ground), the energy projection (flight: the centroidal momentum of the step's start plus gravity's impulse and the
energy of the torques' second-order work, [`hsddp_gym.core.batch_projection`][hsddp_gym.core.batch_projection];
contacts: scale ``v``) and the motor torque-speed law -- written out on the closed-form model of
[`hsddp_gym.core.batch_model`][hsddp_gym.core.batch_model] and compiled with numba (cached on disk), one loop over the
robots.

``tests/test_vector_env.py`` checks whole steps against ``ContactSimulator`` in every contact combination (flight,
front, back, double stance; stick and slide): the same foot states and contact flags, states within 1e-11 relative
to their size (median 3e-16; 99.7 % within 1e-12). The LCP's linear solves, the small Cholesky factorizations and
the order of the projections are contact.py's, written out; the round-off differences come from the model's tree
factorization ([`tree_factor7`][hsddp_gym.core.batch_model.tree_factor7]).

One source, two compiled functions: [`compile_step`][compile_step] writes the step once, with the terrain's code paths
behind a constant of the closure (``on_terrain``) that numba resolves when it compiles (dead-branch pruning), so
[`step_batch`][step_batch] holds the flat ground's code alone (its numbers and its speed are those of a kernel written
for the flat ground) and [`step_batch_terrain`][step_batch_terrain] the terrain's
([`hsddp_gym.core.batch_terrain`][hsddp_gym.core.batch_terrain]: contacts at the closest point of the surface, along its
normal, the friction cone in the local frame).
[`CompiledContactSimulator`][hsddp_gym.core.compiled_contact.CompiledContactSimulator] calls the one its terrain needs;
the vector env is flat.

Speed notes: numba passes a tuple of arrays ([`Scratch`][Scratch]) to a compiled call at about a microsecond (one
reference count per array), more than a whole flight step costs, so the step is one function that unpacks it once
per batch and has the simulator's step written out in line. About 88 % of the 1 ms steps of a random-action episode
are in flight (no foot within reach), so the flight step is what costs (see
[`hsddp_gym.core.batch_model`][hsddp_gym.core.batch_model]). No fast-math flag, not even fused multiply-adds: the same
seed gives the same episode on CPUs with and without FMA.

numba's cache: the kernel's functions in the other modules are not cached on their own
([`kernel_jit`][hsddp_gym.core.batch_model.kernel_jit]); they are compiled into the step that calls them, whose cache
entry's key holds a digest of every source the step is compiled from ([`KERNEL_SOURCES`][KERNEL_SOURCES]), so an edit of
any of them recompiles it (numba itself checks only the step's own file).

Arrays: ``x (N, 14)`` states, ``u (N, 4)`` joint torques, ``states (N, 2)`` int64 foot states
(``SEPARATE`` ... ``SLIDE_NEG``), ``contact (N, 2)`` bool, ``impulse (N, 4)`` summed ground impulses (grf
layout), ``time (N,)`` simulated time, ``heights (N, 2)`` foot heights after the step, ``counters (N, 4)``
int64 ``[lcp_fallbacks, energy_projections, momentum_fallbacks, energy_deficits]``.
"""

from __future__ import annotations

import collections
import hashlib
import math
import sys
import time as _time

import numba
import numpy as np

from hsddp_gym.core import batch_lcp, batch_model, batch_projection, batch_terrain, contact, contact_lcp, conventions
from hsddp_gym.core.batch_lcp import solve_lcp, solve_spd
from hsddp_gym.core.batch_model import (
    FOOT_POINT,
    P_DT,
    P_FAR,
    P_MOTOR,
    P_MU,
    P_TORQUE_LIMIT,
    P_W_FULL,
    P_W_ZERO,
    bias,
    kernel_params,
    kinematics,
    kinetic_energy,
    load_model,
    mass_matrix,
    model_cache,
    point_jacobian,
    potential_energy,
    store_model,
    tree_factor7,
    tree_solve7,
    tree_solve_rows,
)
from hsddp_gym.core.batch_projection import momentum_target, project_flight
from hsddp_gym.core.batch_terrain import terrain_candidate, terrain_corner_rows, terrain_piece, terrain_rows
from hsddp_gym.core.contact import CONTACT_MARGIN, MAX_PROJECTION_ITERATIONS, POSITION_TOLERANCE, ContactSimulator
from hsddp_gym.core.contact_lcp import SEPARATE, STICK
from hsddp_gym.core.conventions import NQ, NX

COUNTER_NAMES = ("lcp_fallbacks", "energy_projections", "momentum_fallbacks", "energy_deficits")
"""The names of a robot's four counters (``counters (N, 4)``), [`ContactSimulator`][ContactSimulator]'s attributes."""

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
    """A fresh [`Scratch`][Scratch] (zeros)."""
    return Scratch(*[np.zeros(shape, dtype=np.int64 if name in _INT_FIELDS else np.float64)
                     for name, shape in _SCRATCH_FIELDS.items()])


# ------------------------------------------------------------------------------ the step
def _sources_digest(modules) -> str:
    """sha256 (hex) of the source files of ``modules`` (in this order)."""
    digest = hashlib.sha256()
    for module in modules:
        with open(module.__file__, "rb") as f:
            digest.update(f.read())
    return digest.hexdigest()


KERNEL_MODULES = (batch_model, batch_lcp, batch_projection, batch_terrain, contact_lcp, contact, conventions)
"""The modules the step is compiled from besides this one: the functions it calls, the constants it reads."""
KERNEL_SOURCES = _sources_digest(KERNEL_MODULES)
"""Digest of the sources of [`KERNEL_MODULES`][KERNEL_MODULES]: a constant of the compiled step, so part of its numba
cache key."""

_step_jit = numba.njit(cache=True, error_model="numpy")
"""The step's compile options: [`kernel_jit`][hsddp_gym.core.batch_model.kernel_jit]'s, cached on disk."""


def compile_step(on_terrain: bool, name: str):
    """The batch step compiled for the flat ground (``on_terrain=False``) or a terrain's surface (True), named
    ``name`` (numba's cache files carry it): one source, the terrain's code paths pruned from the flat ground's
    function at compile time. See [`step_batch`][step_batch] and [`step_batch_terrain`][step_batch_terrain] for the
    arguments."""
    if not isinstance(on_terrain, bool):
        raise TypeError(f"on_terrain must be a bool, got {type(on_terrain).__name__}")
    if not (isinstance(name, str) and name.isidentifier()):
        raise ValueError(f"name must be a Python identifier, got {name!r}")
    sources = KERNEL_SOURCES

    def step(p, x_batch, u_batch, n, active, states_batch, contact_batch, impulse_batch, sim_time, heights,
             counters_batch, cache_batch, sc):
        _sources = sources  # the digest of the kernel's sources: a closure constant, part of the cache key
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
        if on_terrain:
            s_fn = sc.fn
            s_fpos = sc.fpos
            s_fa = sc.fa
            s_tdir = sc.tdir
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
                load_model(p, q, cache_batch[ir], s_pts, s_M)  # the energy at the start (mechanical_energy)
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
                        if not on_terrain:
                            phi = pts[FOOT_POINT[foot], 1]
                            if phi > p[P_FAR]:
                                continue
                            fjz = s_fjz[foot]
                            point_jacobian(pts, 5 + foot, s_fjx[foot], fjz)  # the foot's rows, kept for the LCP
                        else:  # the closest point of the surface, the LCP's rows along its normal and tangent
                            phi = terrain_candidate(p, pts, foot, s_fjx, s_fjz, s_fn, s_fpos, s_fa)
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
                        momentum_target(p, v, sc)  # s_M holds the inertia of the step's start
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
                        exact = solve_lcp(s_G, s_c, p[P_MU], ncand, g0, g1, s_lam, s_sol, s_best_lam, s_w, s_A, s_rhs,
                                          s_zz, s_L, s_cols_j, s_cols_c, s_cols_n, s_rows)
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
                            if not on_terrain:
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
                    tfoot, taxis, tval = s_tfoot, s_taxis, s_tval
                    nt = 0
                    held0 = False
                    held1 = False
                    if not on_terrain:
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
                            if not held and s_pts[FOOT_POINT[foot], 1] < 0.0:
                                tfoot[nt] = foot
                                taxis[nt] = 1
                                tval[nt] = 0.0
                                nt += 1
                    else:  # rows along directions (taxis 2)
                        kinematics(p, q, s_pts)
                        nt = terrain_rows(p, s_pts, ncand, cfoot, states, s_fn, s_fpos, s_fa, tfoot, taxis, s_tdir,
                                          tval)
                    constrained = ncand > 0 or nt > 0
                    if nt > 0:
                        res = s_rhs
                        for _ in range(MAX_PROJECTION_ITERATIONS):
                            residual = 0.0
                            for a in range(nt):
                                fp = FOOT_POINT[tfoot[a]]
                                if on_terrain and taxis[a] == 2:
                                    res[a] = tval[a] - (s_tdir[a, 0] * s_pts[fp, 0] + s_tdir[a, 1] * s_pts[fp, 1])
                                else:
                                    res[a] = tval[a] - s_pts[fp, taxis[a]]
                                residual = max(residual, abs(res[a]))
                            if on_terrain and nt < 4:  # a foot moved below another piece: its row too
                                nt, residual = terrain_corner_rows(p, s_pts, nt, tfoot, taxis, s_tdir, tval, res,
                                                                   residual)
                            if residual <= POSITION_TOLERANCE:
                                break
                            for a in range(nt):
                                point_jacobian(s_pts, 5 + tfoot[a], s_jx, s_jz)
                                if on_terrain and taxis[a] == 2:
                                    for j in range(7):
                                        s_Jr[a, j] = s_tdir[a, 0] * s_jx[j] + s_tdir[a, 1] * s_jz[j]
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
                            if not solve_spd(s_S, res, nt, s_zz, s_L):
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
                            kinetic = project_flight(p, q, v, kinetic, target, sc, counters)
                    energy = kinetic + potential

            for _ in range(n):
                sim_time[ir] += h
            if finite and n > 0:  # s_pts, s_M hold the kinematics and inertia of the last step's q
                store_model(x[:NQ], s_pts, s_M, cache_batch[ir])
            else:
                kinematics(p, x[:NQ], s_pts)
            if not on_terrain:
                heights[ir, 0] = s_pts[6, 1]
                heights[ir, 1] = s_pts[11, 1]
            else:  # terrain: the feet's heights above the surface under them
                for foot in range(2):
                    fx, fz = s_pts[FOOT_POINT[foot], 0], s_pts[FOOT_POINT[foot], 1]
                    th, _, _, _ = terrain_piece(p, fx)
                    heights[ir, foot] = fz - th

    step.__name__ = step.__qualname__ = name
    return _step_jit(step)


step_batch = compile_step(False, "step_batch")
"""``step_batch(p, x_batch, u_batch, n, active, states_batch, contact_batch, impulse_batch, sim_time, heights,
counters_batch, cache_batch, sc)``: ``n`` simulation steps on the flat ground of every robot ``r`` with ``active[r]``
((N,) bool; the others are left untouched): ``x_batch (N, 14)`` in place, ``u_batch (N, 4)`` commanded joint torques
(ContactSimulator.run: the motor law every step, the energy taken at the start), ``states_batch (N, 2)``,
``contact_batch (N, 2)``, ``impulse_batch (N, 4)`` (summed over the ``n`` steps), ``sim_time (N,)`` (``+= h`` per
step, accumulated like ``ContactSimulator.time``), ``heights (N, 2)`` foot heights after the steps,
``counters_batch (N, 4)`` (see the module docstring), ``cache_batch (N, MODEL_CACHE_SIZE)`` each robot's model cache
([`model_cache`][hsddp_gym.core.batch_model.model_cache]: the points and mass matrix its last step ended with, reused
when the next call starts from the same configuration, as it does unless the caller moved the robot; the parameters
``p`` ([`kernel_params`][hsddp_gym.core.batch_model.kernel_params]) must stay the same), ``sc`` a [`Scratch`][Scratch].
Robots whose state is not finite are not stepped (NaN heights, no impulse); the caller ends their episodes.

One function for the whole batch (ContactSimulator._step, _finish_consistent and _project_positions written out in
line): numba passes a [`Scratch`][Scratch] to a call at a cost of about a microsecond (one reference count per array),
more than a whole flight step, so it is unpacked here once per batch."""

step_batch_terrain = compile_step(True, "step_batch_terrain")
"""[`step_batch`][step_batch] on a terrain: the same arguments, with ``p`` holding the terrain's surface
([`kernel_params`][hsddp_gym.core.batch_model.kernel_params] of a simulator with a terrain: ``p[P_TERRAIN_N] >= 2``
vertices) and ``heights`` the feet's heights above the surface under each. A foot's contact is with the closest point of
the
surface ([`terrain_contact`][hsddp_gym.core.batch_terrain.terrain_contact]): its gap is the distance to it, the LCP's
rows are its velocity along the outward normal there and along the tangent (the friction cone in the local frame), and
the impulses are turned back into the world frame; the position projection puts a contact foot on the tangent line of
its contact point, a sticking foot at its start, and a foot below the surface onto its closest point (two rows at a
concave corner; [`terrain_rows`][hsddp_gym.core.batch_terrain.terrain_rows],
[`terrain_corner_rows`][hsddp_gym.core.batch_terrain.terrain_corner_rows]). Compiled on first use."""


def run_one(p, x, u, n, states, contact, total, sc, counters) -> None:
    """``n`` steps of one robot (ContactSimulator.run): [`step_batch`][step_batch] on a batch of one. ``x`` (14,) in
    place, ``u`` (4,) commanded torques, ``states`` (2,) int64, ``contact`` (2,) bool, ``total`` (4,) the summed
    impulses, ``counters`` (4,) int64 (all updated in place)."""
    step_batch(p, x.reshape(1, NX), np.asarray(u, dtype=np.float64).reshape(1, 4), int(n), np.ones(1, dtype=np.bool_),
               states.reshape(1, 2), contact.reshape(1, 2), total.reshape(1, 4), np.zeros(1), np.zeros((1, 2)),
               counters.reshape(1, 4), model_cache(1), sc)


_READY = False
ANNOUNCE_AFTER_S = 5.0
"""With a cache index on disk, the warm-up still says that numba compiles when it takes longer than this."""


def _cache_index_exists() -> bool:
    """Whether numba's cache index of [`step_batch`][step_batch] is on disk (numba internals: False if they moved)."""
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
