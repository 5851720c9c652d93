"""Torques that push on the ground: the feedback law's torques projected onto the contact-consistent set.

A plan's feedback law ``u = U + K (x - X)`` is linear in the state error, and far from the plan (a touchdown
earlier or later than planned, a push) it can ask a stance leg for torques that the contact cannot transmit: a
normal force that pulls on the ground, or a tangential force outside the friction cone. The foot then leaves or
slides, the light leg whips away from the ground, the stance is lost, and the plan that holds the trunk is gone.
The torques the MPC sends are therefore the nearest ones (Euclidean, in N m) for which every foot the plan has on
the ground pushes with at least ``min_force`` inside the friction cone ``|f_t| <= friction f_n``, within the torque
limit.

For a contact mode and a state the ground forces are affine in the torques, ``grf(u) = grf(0) + G u`` (the
constrained dynamics, paper eq. 11): five evaluations of the constrained dynamics give them exactly, and the
projection onto the intersection of the half-spaces and the torque box is computed with Dykstra's alternating
projections. Torques that the contact can transmit are returned unchanged (one evaluation). On a terrain the normal
and tangential forces are taken along the surface's normal under each foot (``normals``).
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NGRF, NU, NX, Mode, as_mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.util.validation import check_int, check_positive, check_vector


class PushingTorques:
    """The nearest torques within ``torque_limit`` for which every stance foot pushes on the ground with at least
    ``min_force`` and inside the friction cone.

    Args:
        torque_limit: the motors' torque limit [N m] (the box ``|u_i| <= torque_limit``).
        min_force: the least normal force [N] of a stance foot (>= 0).
        friction: the friction coefficient of the cone the forces must stay in (None: no cone, the normal forces
            only).
        iterations: the most Dykstra sweeps of a projection (it stops once a sweep moves the torques by less than
            1e-10 N m with the constraints holding to 1e-9 N).
        dynamics: the model whose constrained dynamics give the forces (None: the nominal robot). Give a
            [`HybridDynamics`][hsddp_gym.core.dynamics.HybridDynamics] of its own (its Pinocchio data is overwritten).

    Attributes:
        projections: how many calls changed the torques (beyond clipping them to the limit).
    """

    def __init__(self, torque_limit: float, min_force: float = 0.0, friction: float | None = None,
                 iterations: int = 500, dynamics: HybridDynamics | None = None) -> None:
        self.torque_limit = check_positive(torque_limit, "torque_limit")
        self.min_force = check_positive(min_force, "min_force", allow_zero=True)
        self.friction = None if friction is None else check_positive(friction, "friction")
        self.iterations = check_int(iterations, "iterations", minimum=1)
        if dynamics is not None and not isinstance(dynamics, HybridDynamics):
            raise TypeError(f"dynamics must be None or a HybridDynamics, got {type(dynamics).__name__}")
        self._dynamics = dynamics if dynamics is not None else HybridDynamics()
        self.projections = 0

    def _constraints(self, mode: Mode, normals) -> tuple[np.ndarray, np.ndarray]:
        """``(A (m, 4), c (m,))``: the contact's conditions on a ground-force vector ``A grf >= c`` for ``mode``
        (``normals``: None, or the surface's unit normals ``(2, 2)`` ``(n_x, n_z)`` under the front and back foot)."""
        rows, lows = [], []
        for foot in mode.feet:
            ix, iz = 2 * foot, 2 * foot + 1  # grf = [f_front_x, f_front_z, f_back_x, f_back_z]
            normal, tangent = np.zeros(NGRF), np.zeros(NGRF)
            if normals is None:  # flat ground: exactly z and x
                normal[iz], tangent[ix] = 1.0, 1.0
            else:
                nx, nz = normals[foot]
                normal[ix], normal[iz] = nx, nz
                tangent[ix], tangent[iz] = nz, -nx
            rows.append(normal)
            lows.append(self.min_force)
            if self.friction is not None:
                for sign in (1.0, -1.0):
                    rows.append(self.friction * normal - sign * tangent)
                    lows.append(0.0)
        return np.array(rows), np.array(lows)

    def forces(self, x: np.ndarray, u: np.ndarray, mode: Mode) -> tuple[np.ndarray, np.ndarray]:
        """``(grf (4,), G (4, 4))``: the ground forces [N] under torques ``u`` (4,) at state ``x`` (14,) in contact
        ``mode``, and their (constant) derivative with respect to the torques."""
        mode = as_mode(mode)
        grf = self._dynamics._accelerations(x, u, mode)[1]
        return grf, self._derivative(x, u, mode, grf)

    def _derivative(self, x: np.ndarray, u: np.ndarray, mode: Mode, grf: np.ndarray) -> np.ndarray:
        """``G (4, 4)``: the forces' derivative with respect to the torques, from the forces ``grf`` (4,) under
        ``u`` and four more evaluations of the constrained dynamics (the forces are affine in the torques)."""
        G = np.empty((NGRF, NU))
        for i in range(NU):
            du = u.copy()
            du[i] += 1.0
            G[:, i] = self._dynamics._accelerations(x, du, mode)[1] - grf
        return G

    def __call__(self, x: np.ndarray, u: np.ndarray, mode: Mode, normals=None) -> np.ndarray:
        """Torques (4,) [N m] for state ``x`` (14,) and the plan's contact ``mode``: ``u`` (4,) clipped to the limit
        in a flight or when the contact can transmit them, else their projection onto the set it can. ``normals``:
        the ground's unit normals ``(2, 2)`` ``(n_x, n_z)`` under the front and back foot (None: flat ground)."""
        x = check_vector(x, NX, "x")
        u = np.clip(check_vector(u, NU, "u"), -self.torque_limit, self.torque_limit)
        mode = as_mode(mode)
        if mode == Mode.FLIGHT:
            return u
        if normals is not None:
            normals = np.asarray(normals, dtype=np.float64)
            if normals.shape != (2, 2) or not np.all(np.isfinite(normals)) or not np.allclose(
                    np.linalg.norm(normals, axis=1), 1.0):
                raise ValueError(f"normals must be None or two unit vectors (2, 2), got {normals!r}")
        A, c = self._constraints(mode, normals)
        grf = self._dynamics._accelerations(x, u, mode)[1]
        if np.all(A @ grf >= c - 1e-9):
            return u
        G = self._derivative(x, u, mode, grf)  # the forces under u are already known
        M = A @ G  # half-spaces M v >= b over the torques v
        b = c - A @ (grf - G @ u)
        self.projections += 1
        return _dykstra(u, M, b, self.torque_limit, self.iterations)


def _dykstra(u0: np.ndarray, M: np.ndarray, b: np.ndarray, lim: float, iterations: int) -> np.ndarray:
    """The Euclidean projection of ``u0`` onto ``{v : M v >= b, |v_i| <= lim}`` (Dykstra's algorithm over the
    half-spaces and the box; it ends on a box projection, so the limit always holds). Where the set is empty (the
    contact cannot hold whatever the torques) the iterates approach the nearest compromise."""
    sets = len(b) + 1
    corrections = np.zeros((sets, NU))
    u = u0.copy()
    for _ in range(iterations):
        start = u
        for s in range(sets):
            y = u + corrections[s]
            if s < len(b):
                g = M[s]
                gg = g @ g
                gap = b[s] - g @ y
                p = y + (gap / gg) * g if gap > 0 and gg > 0 else y
            else:
                p = np.clip(y, -lim, lim)
            corrections[s] = y - p
            u = p
        if np.abs(u - start).max() < 1e-10 and np.all(M @ u >= b - 1e-9):
            break
    return u
