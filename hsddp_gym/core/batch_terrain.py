"""The terrain's surface in the contact kernel ([`hsddp_gym.core.batch_contact`][hsddp_gym.core.batch_contact]),
compiled with numba.

A terrain enters the kernel as the vertices of its continuous piecewise-linear surface
([`surface_vertices`][hsddp_gym.core.terrain.Terrain.surface_vertices]), appended to the parameter vector
([`kernel_params`][hsddp_gym.core.batch_model.kernel_params]: ``K = p[P_TERRAIN_N]`` of them, ``xs`` (K,) from
``p[N_PARAMS]``, ``zs`` (K,) after them). A foot's contact is with the closest point of the surface
([`terrain_contact`][terrain_contact]): its gap is the distance to it, the LCP's rows are its velocity along the outward
normal there and along the tangent (the friction cone in the local frame, [`terrain_candidate`][terrain_candidate]); the
position projection puts a contact foot on the tangent line of its contact point, a sticking foot at its start, and a
foot below the surface onto its closest point (two rows at a concave corner; [`terrain_rows`][terrain_rows],
[`terrain_corner_rows`][terrain_corner_rows]). A projection row ``a`` on a terrain has the axis 2 (``taxis[a]``): its
unit direction ``tdir[a]`` (2,) dotted with the foot's position equals ``tval[a]``.
"""

from __future__ import annotations

import math

import numpy as np

from hsddp_gym.core.batch_model import FOOT_POINT, N_PARAMS, P_FAR, P_TERRAIN_N, kernel_jit, point_jacobian
from hsddp_gym.core.contact import POSITION_TOLERANCE
from hsddp_gym.core.contact_lcp import SEPARATE, STICK


@kernel_jit
def _piece_index(p, px):
    """The index j (0..K-2) of the piece ``[x_j, x_j+1)`` of the surface under ``px``, clamped to the first / last (a
    binary search)."""
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


@kernel_jit
def terrain_piece(p, px):
    """The piece of the terrain's surface (the vertices in ``p``,
    [`kernel_params`][hsddp_gym.core.batch_model.kernel_params]) under ``px`` [m]: ``(h, s, x_j, z_j)`` its height at
    ``px``, its slope and its left vertex (a point on its line); level beyond the outermost vertices (slope 0, the end
    vertex). A vertex belongs to the piece on its right."""
    k = int(p[P_TERRAIN_N])
    b = N_PARAMS
    if px < p[b]:
        return p[b + k], 0.0, p[b], p[b + k]
    if px >= p[b + k - 1]:
        return p[b + 2 * k - 1], 0.0, p[b + k - 1], p[b + 2 * k - 1]
    lo = _piece_index(p, px)
    x0, z0 = p[b + lo], p[b + k + lo]
    s = (p[b + k + lo + 1] - z0) / (p[b + lo + 1] - x0)
    return z0 + s * (px - x0), s, x0, z0


@kernel_jit
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


@kernel_jit
def terrain_candidate(p, pts, foot, fjx_all, fjz_all, fn, fpos, fa):
    """A foot's contact with the terrain at the step's start (the batch step's candidate test): ``phi`` its distance
    to the closest point ``c`` of the surface ([`terrain_contact`][terrain_contact]; returned), ``fn[foot]`` the outward
    normal ``n`` there, ``fa[foot] = n . c``, ``fpos[foot]`` the foot's position; ``fjz_all[foot]``, ``fjx_all[foot]``
    the rows of the LCP, the foot's velocity along ``n`` and along the tangent ``t = (n_z, -n_x)``. Nothing is written
    when ``phi`` is beyond the reach ``p[P_FAR]``."""
    fx, fz = pts[FOOT_POINT[foot], 0], pts[FOOT_POINT[foot], 1]
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


@kernel_jit
def _append_row(foot, nx, nz, cx, cz, nt, tfoot, taxis, tdir, tval):
    """Projection row ``nt`` (returns ``nt + 1``): foot ``foot`` onto the line through ``(cx, cz)`` with the unit normal
    ``(nx, nz)`` (axis 2: ``n . foot = n . c``)."""
    tfoot[nt] = foot
    taxis[nt] = 2
    tdir[nt, 0] = nx
    tdir[nt, 1] = nz
    tval[nt] = nx * cx + nz * cz
    return nt + 1


@kernel_jit
def terrain_rows(p, pts, ncand, cfoot, states, fn, fpos, fa, tfoot, taxis, tdir, tval):
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
        fx, fz = pts[FOOT_POINT[foot], 0], pts[FOOT_POINT[foot], 1]
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
            nt = _append_row(foot, nx, nz, cx, cz, nt, tfoot, taxis, tdir, tval)
    return nt


@kernel_jit
def terrain_corner_rows(p, pts, nt, tfoot, taxis, tdir, tval, res, residual):
    """During the projection on a terrain: a foot that the projection moved below another piece (a concave corner:
    a gap's floor and its wall) gets that piece's row too (its residual in ``res``), at most two rows a foot and four
    in all. Returns the number of rows and the largest residual."""
    for foot in range(2):
        if nt >= 4:
            break
        fp = FOOT_POINT[foot]
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
        res[nt] = -phi
        residual = max(residual, -phi)
        nt = _append_row(foot, nx, nz, cx, cz, nt, tfoot, taxis, tdir, tval)
    return nt, residual
