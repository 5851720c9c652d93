"""State-based contact simulation of the planar Mini Cheetah: a velocity-level time-stepping scheme with an
exact planar Coulomb-friction LCP.

Scheme (Stewart & Trinkle 1996; Anitescu & Potra 1997), one step of length ``h`` (1 ms by default)
------------------------------------------------------------------------------------------------------
With ``M(q)`` the joint-space inertia, ``b(q, v)`` the bias (Coriolis, centrifugal and gravity terms) and
``tau = [0, 0, 0, u]`` the actuation (the base is unactuated)::

    v_free = v + h M^-1 (tau - b)                        (Pinocchio ABA: one call)
    v+     = v_free + M^-1 J_c^T lam                     (lam: ground impulses [N s] on the robot)
    q+     = q + h v+                                    (semi-implicit Euler)

For each foot ``i`` let ``phi_i`` be its height above the ground (``z = 0``), ``J_n,i`` / ``J_t,i`` the
z / x rows of its LOCAL_WORLD_ALIGNED frame Jacobian (``(1, 7)`` each), ``lam = [lam_n, lam_t]`` its
normal / tangential impulse and ``w = [w_n, w_t] = J v+`` its velocity after the step. A foot is a
*candidate* contact when it is within [`CONTACT_MARGIN`][CONTACT_MARGIN] (1 mm) of the ground or would reach it during
this step without contact forces (``phi + h J_n v_free <= 0``); the margin matters because the impulse at
one foot changes the velocity of the other, so a resting foot whose free motion points up may still be
pressed down by the coupling. Every candidate obeys the complementarity conditions

* non-penetration:  ``0 <= lam_n  _|_  w_n + phi_eff / h >= 0``, with ``phi_eff = phi`` above the ground
  (the foot may travel exactly down to the ground in this step, no earlier force) and ``phi_eff = 0`` on
  or below it;
* Coulomb friction with the planar cone, which has exactly two edges ``lam_t = +-mu lam_n`` (so the
  linearised cone of Stewart-Trinkle is *exact* in 2D): with edge impulses ``beta+-`` and slip speed
  ``gamma``: ``0 <= beta+ _|_ gamma + w_t >= 0``, ``0 <= beta- _|_ gamma - w_t >= 0``,
  ``0 <= gamma _|_ mu lam_n - beta+ - beta- >= 0``, ``lam_t = beta+ - beta-``.

Energy-consistent stepping (the default, ``energy_consistent=True``)
--------------------------------------------------------------------
The velocity-level step above is the legacy scheme; on its own it creates energy (the explicit Coriolis terms
of the semi-implicit step at high joint rates, and the O(h^2) curvature of a foot's path, which makes a
sticking foot creep and a landing foot penetrate), lets a fast foot cross the ground between two steps and
does not keep momentum in flight. Two projections after ``q+ = q + h v+`` close it:

1. *Position projection* (mass metric): every candidate foot in contact is moved back to height 0, every
   sticking foot back to its position at the start of the step, and **every other foot that ended below the
   ground onto it** (a candidate that separates, or a foot too fast for the candidate test's linear
   prediction: at hundreds of rad/s a foot's path curves within one step): ``q+ += M^-1 J^T mu`` with ``J``
   the rows of those constraints, Newton iterations on the exact kinematics until the residual is below
   [`POSITION_TOLERANCE`][POSITION_TOLERANCE] (1e-9 m); the first uses the exact Jacobians at ``q+`` and the step's
   ``M^-1``. So a sticking foot does not move (<= 1e-9 m per step), a contact foot ends each step on the ground, and no
   foot ends a step below it, at any joint rate (no tunnelling).
2. *Energy and momentum projection*, with ``E = 1/2 v^T M v + V``:

   * with contacts (or after a position correction), the work ``W = tau . (q+ - q)`` (tau constant over the
     step): if ``E(q+, v+) > E(q, v) + W``, ``v+`` is scaled to exactly that energy, which keeps every contact
     velocity condition (``J v+ = 0`` when sticking); a step that loses energy is left alone (contacts only
     dissipate);
   * in free flight, ``v+`` is moved to the nearest point (mass metric) with the centroidal momentum
     (linear x, z and angular y about the centre of mass) ``P(q) v + (0, -m g h, 0)`` (what gravity's impulse
     leaves of the step's start) and with energy exactly ``E(q, v) + W``, where ``W`` is the torques' work to
     second order, ``h/2 tau . (v + v+)``, capped by ``tau . h v+`` (semi-implicit Euler's ``tau . h v+``
     counts the torques' own acceleration twice and would pump energy into a leg driven bang-bang).

   Counted in `ContactSimulator.energy_projections` (steps whose energy had to come down).

Hence ``E(t+h) - E(t) <= tau . dq`` for every step, impacts and position corrections included (tested to
1e-9 J from random states in every contact combination, any gravity), and velocities stay bounded by the
energy (no blow-up). In flight the momentum is exact (to round-off: 1e-13 relative over 10 s) and, with zero
torque, so is the energy (a relative 1e-13 margin per step against round-off: 1e-9 over 10 s), at any joint
rate; the scheme it had before lost 49 % of a 100 rad/s leg's energy in 0.5 s and drifted 1 kg m/s in
momentum over 10 s. **Order**: the step stays first order in ``h`` (semi-implicit Euler, then projections onto
the constraint and invariant manifolds, which keep its order): trajectories converge linearly in the step, while
the invariants are kept exactly rather than to O(h). The legacy scheme (``energy_consistent=False``) corrects
penetration before the step (``q += M^-1 J_n^T mu`` lifting each penetrating contact foot by ``erp * (-phi)``,
slop 1 um) and does neither projection.

The restitution is zero (the constraint is on ``v+``: a landing foot stops in one step, an inelastic
impact), the ground only pushes (``lam_n >= 0``), a foot lifts off exactly when keeping it on the ground
would need ``lam_n < 0``, and sticking / sliding follow Coulomb's law. Every solution of this LCP puts each
candidate foot in one of four *states* -- ``SEPARATE`` (``lam = 0``, ``w_n + phi_eff/h >= 0``), ``STICK``
(``w = 0`` up to the correction, ``|lam_t| <= mu lam_n``), ``SLIDE_POS`` / ``SLIDE_NEG`` (``w_n`` at its
bound, ``lam_t = -/+ mu lam_n``, sliding toward +x / -x) -- so with at most two feet the LCP is solved
*exactly* by enumerating the at most ``4^2 = 16`` state combinations: each one is a linear system of size
<= 4 in the Delassus matrix ``G = J_c M^-1 J_c^T`` followed by sign checks. The previous step's states are
tried first (one linear solve per step in steady phases), then a fixed order, so the result is
deterministic. Existence of a solution is guaranteed for this LCP (Anitescu & Potra 1997); if round-off
makes every combination fail the checks, the least-violating one is used and counted in
`ContactSimulator.lcp_fallbacks`.

Relation to the planner's model: a sticking stance foot gives ``J_c(q_k) v_k+1 = 0``, whereas the KKT
model of [`hsddp_gym.core.dynamics`][hsddp_gym.core.dynamics] imposes ``J_c a + dJ_c v = 0``. Since ``v_k`` satisfies
the constraint with the previous Jacobian, ``J_c(q_k) v_k = h dJ_c v + O(h^2)`` and the implied acceleration is the KKT
one: sticking stance trajectories of the two agree to O(h) (tested: halving ``h`` halves the gap).

Motors (optional, ``motor_speed_limits``): a torque that drives its joint in the direction it moves is
capped at ``torque_limit`` up to ``w_full`` and linearly down to zero at ``w_zero`` (evaluated every step).

Cost per 1 ms step: one ABA, joint Jacobians and two frame Jacobians; with contacts also ``M^-1`` and three small
products; the LCP is pure Python (an unrolled 4x4 Cholesky for two sticking feet). The energy-consistent scheme adds
one energy evaluation per step (one ``computeMechanicalEnergy``: kinematics, kinetic and potential energy), with
contacts the position projection: joint and frame Jacobians at ``q+`` (which also give the foot positions), one
Newton correction (two small products, an unrolled Cholesky, one product) whose energy evaluation doubles as the
kinematics of the result, and an exact bound on the Newton remainder
(`ContactSimulator._newton_remainder_bound`) that makes the final placement check unnecessary (in 90 % of the
double-stick steps of a collapsing stance); two sticking feet take a straight-line version of the first Newton step.
Every flight step adds the centroidal map twice (the momentum target at the step's start, its projection at the end;
``M^-1 P^T`` is read off ``P`` without a solve). ``experiments/bench_env.py`` times both schemes, interleaved: on a
loaded 2-core machine (load average 5-5.7) the default made 0.65-0.76x the legacy env steps/s under random actions
(0.70x both with and without these shortcuts in the one run that timed both) and 0.54-0.56x in a collapsing double
stance (0.50x before), short of the 0.8x goal: the remaining gap is the Python and NumPy call overhead of the
projection (about 40 % glue, 27 % the 4x4 solve with its list conversion, 20 % the small NumPy products, 15 % the
Pinocchio calls of a double-stance step, line_profiler).

Everything lives in the world frame, SI units; ground forces follow
[`hsddp_gym.core.conventions`][hsddp_gym.core.conventions] (``grf (4,) = [f_front_x, f_front_z, f_back_x, f_back_z]``,
the force of the ground on the robot). """

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hsddp_gym.core.contact_lcp import SEPARATE, STICK, solve_contact_lcp_lists, solve_spd
from hsddp_gym.core.conventions import FEET, FOOT_JOINTS, IPITCH, NQ, NU, NV, NX
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.util.validation import check_in_range, check_positive, check_vector

CONTACT_MARGIN = 1e-3
"""A foot at most this high [m] is always a candidate contact (its LCP may still choose ``SEPARATE``)."""
PENETRATION_SLOP = 1e-6
"""Penetrations up to this depth [m] are left alone by the position correction."""
_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
POSITION_TOLERANCE = 1e-9
"""The position projection iterates until every contact foot is this close [m] to its target."""
MAX_PROJECTION_ITERATIONS = 6
"""Newton iterations of the position projection at most (one in practice)."""
_MOMENTUM_ROWS = [0, 2, 4]  # centroidal momentum rows: linear x, linear z, angular y


# ------------------------------------------------------------------------------------------ the simulator
def motor_torques(u: np.ndarray, w: np.ndarray, motor_speed_limits, torque_limit: float) -> np.ndarray:
    """The torques (4,) the motors apply for commanded ``u`` (4,) at joint rates ``w`` (4,): a torque that drives
    its joint in the direction it moves is capped at ``torque_limit`` up to ``w_full`` and linearly down to 0 at
    ``w_zero`` (``motor_speed_limits = (w_full, w_zero)``; None: ideal torque sources, ``u`` unchanged)."""
    u = np.array(u, dtype=np.float64)
    if motor_speed_limits is None:
        return u
    w_full, w_zero = motor_speed_limits
    cap = np.clip((w_zero - np.abs(w)) * torque_limit / (w_zero - w_full), 0.0, None)
    limited = (u * w > 0.0) & (np.abs(w) > w_full) & (np.abs(u) > cap)
    u[limited] = np.sign(u[limited]) * cap[limited]
    return u


def check_motor_speed_limits(value, name: str = "motor_speed_limits") -> tuple[float, float] | None:
    """None, or a pair ``(w_full, w_zero)`` of finite speeds with ``0 < w_full < w_zero`` [rad/s]."""
    if value is None:
        return None
    if not isinstance(value, (tuple, list, np.ndarray)) or len(value) != 2:
        raise TypeError(f"{name} must be None or a pair (w_full, w_zero) in rad/s, got {value!r}")
    w_full = check_positive(value[0], f"{name}[0]")
    w_zero = check_positive(value[1], f"{name}[1]")
    if not w_full < w_zero:
        raise ValueError(f"{name} must satisfy w_full < w_zero, got {value!r}")
    return w_full, w_zero


class SimulatorQueries:
    """The state queries and the checked one-step call that every simulator of the task shares (the env reads
    them): [`ContactSimulator`][ContactSimulator], the MuJoCo twin's and the planner's-model twin's simulators. A
    subclass provides ``robot`` (a [`CheetahModel`][CheetahModel]), the state views ``x`` (14,), ``q`` (7,), ``v`` (7,),
    ``motor_speed_limits``, ``torque_limit`` and ``run(u, n)``."""

    def _set_common(self, robot, timestep, friction, gravity, torque_limit, motor_speed_limits) -> CheetahModel:
        """Check and store the settings every simulator takes: ``dt``, ``mu``, ``gravity``, ``torque_limit``,
        ``motor_speed_limits`` (defaults from the robot's parameters); returns the robot (default: the paper's),
        checked to be a [`CheetahModel`][CheetahModel] (errors name the argument)."""
        robot = robot if robot is not None else CheetahModel()
        if not isinstance(robot, CheetahModel):
            raise TypeError(f"robot must be a CheetahModel, got {type(robot).__name__}")
        params = robot.params
        self.dt = check_positive(timestep, "timestep")
        self.mu = check_positive(params.friction if friction is None else friction, "friction", allow_zero=True)
        self.gravity = check_positive(params.gravity if gravity is None else gravity, "gravity", allow_zero=True)
        self.torque_limit = check_positive(params.torque_limit if torque_limit is None else torque_limit,
                                           "torque_limit")
        self.motor_speed_limits = check_motor_speed_limits(motor_speed_limits)
        return robot

    def foot_positions(self) -> np.ndarray:
        """World ``(x, z)`` of both feet at the current state (2, 2) [m]."""
        return self.robot.foot_positions(self.q)

    terrain = None
    """The ground's profile (a [`Terrain`][hsddp_gym.core.terrain.Terrain]; None: the flat ground ``z = 0``). Only the
    compiled kernel ([`CompiledContactSimulator`][hsddp_gym.core.compiled_contact.CompiledContactSimulator]) and the
    MuJoCo twin simulate one; the foot heights below measure from its simulated surface."""

    def foot_heights(self) -> np.ndarray:
        """Heights of both feet above the ground at the current state (2,) [m] (with a [`terrain`][terrain]: above its
        simulated surface under each foot, [`surface_heights`][hsddp_gym.core.terrain.Terrain.surface_heights])."""
        if self.terrain is None:
            return self.robot.foot_heights(self.q)
        feet = self.robot.foot_positions(self.q)
        return feet[:, 1] - self.terrain.surface_heights(feet[:, 0])

    def foot_heights_fast(self) -> tuple[float, float]:
        """`foot_heights` as two floats ``(front, back)`` (the env's hot path)."""
        h = self.foot_heights()
        return float(h[0]), float(h[1])

    def foot_velocities(self) -> np.ndarray:
        """World ``(vx, vz)`` of both feet at the current state (2, 2) [m/s]."""
        return self.robot.foot_velocities(self.x)

    def applied_torque(self, u: np.ndarray) -> np.ndarray:
        """The torques (4,) the motors would apply for commanded ``u`` (4,) at the current joint rates."""
        return motor_torques(check_vector(u, NU, "u"), self.v[3:], self.motor_speed_limits, self.torque_limit)

    def step(self, u: np.ndarray) -> None:
        """One step of ``h`` with joint torques ``u`` (4,) [N m] (checked)."""
        self.run(check_vector(u, NU, "u"), 1)


class ContactSimulator(SimulatorQueries):
    """Time-stepping simulation of the planar Mini Cheetah with state-based point-foot contacts.

    See the module docstring for the scheme. The simulator owns its state and scratch buffers; call
    [`set_state`][set_state] then [`run`][run] (or `step`).

    Args:
        robot: the model (default: the paper's robot). The simulator copies its Pinocchio model, so a
            ``gravity`` override does not touch ``robot``.
        timestep: ``h`` [s] (default 1e-3).
        friction: Coulomb coefficient ``mu`` >= 0 (default: ``robot.params.friction`` = 0.6).
        gravity: gravitational acceleration [m/s^2] >= 0 (default: ``robot.params.gravity`` = 9.81);
            0 gives a gravity-free world (energy tests).
        erp: legacy scheme only: fraction of a contact foot's penetration removed per step by its position
            correction, in [0, 1] (default 1: back onto the ground).
        motor_speed_limits: ``(w_full, w_zero)`` [rad/s] with ``0 < w_full < w_zero``, or None (ideal torque
            sources, the planner's model; the default). When given, a joint torque that drives its joint in
            the direction it already moves is limited to ``torque_limit`` up to ``|qdot| = w_full`` and then
            linearly down to zero at ``w_zero`` (the back-EMF/voltage limit of an electric motor, as in the
            MIT Cheetah-Software simulator); braking torques are not limited. Evaluated every step.
        torque_limit: the actuator torque limit [N m] used by ``motor_speed_limits`` (default:
            ``robot.params.torque_limit`` = 33).
        energy_consistent: True (default): the position and energy projections of the module docstring; False:
            the legacy velocity-level scheme (creates energy, sticking feet creep; kept for comparisons).

    Attributes (read-only between calls):
        x: state (14,) ``[q, v]``. q, v: views (7,) of it. time: simulated time since [`set_state`][set_state] [s].
        impulse: ground impulses of the last step [N s], grf layout (4,).
        states: per-foot contact state of the last step (2,) (``SEPARATE`` ... ``SLIDE_NEG``).
        contact: per-foot flag (2,) bool: the ground pushed the foot (``lam_n > 0``) in the last step.
        lcp_fallbacks: number of steps whose LCP needed the least-violation fallback (0 in practice).
        energy_projections: steps whose energy projection removed energy; momentum_fallbacks: flight
            projections that had to scale all of ``v`` (0 in the tests); energy_deficits: steps whose positions
            alone exceeded the allowed energy, so ``v`` was zeroed (0 in the tests); projection_residual: the
            largest position-projection residual so far [m] (or, after a Newton step, its exact upper bound
            ``_newton_remainder_bound`` when that is below half the tolerance).
    """

    def __init__(self, robot: CheetahModel | None = None, timestep: float = 1e-3, friction: float | None = None,
                 gravity: float | None = None, erp: float = 1.0, motor_speed_limits=None,
                 torque_limit: float | None = None, energy_consistent: bool = True) -> None:
        self.robot = self._set_common(robot, timestep, friction, gravity, torque_limit, motor_speed_limits)
        self.erp = check_in_range(erp, 0.0, 1.0, "erp")
        if not isinstance(energy_consistent, (bool, np.bool_)):
            raise TypeError(f"energy_consistent must be a bool, got {type(energy_consistent).__name__}")
        self.energy_consistent = bool(energy_consistent)
        self.model = pin.Model(self.robot.model)
        self.model.gravity = pin.Motion(np.array([0.0, 0.0, -self.gravity]), np.zeros(3))
        self.data = self.model.createData()
        self._fids = tuple(self.robot.foot_frame_ids)
        self.x = np.zeros(NX)
        self.q = self.x[:NQ]
        self.v = self.x[NQ:]
        self.time = 0.0
        self.impulse = np.zeros(4)
        self.states = [SEPARATE, SEPARATE]
        self.contact = np.zeros(2, dtype=bool)
        self.lcp_fallbacks = 0
        self.energy_projections = 0
        self.momentum_fallbacks = 0
        self.energy_deficits = 0
        self.projection_residual = 0.0
        self._tau = np.zeros(NV)
        self._vf = np.zeros(NV)
        self._dq = np.zeros(NQ)
        # per number of candidate contacts k: J_c (2k, 7), A = J_c M^-1 (2k, 7), G (2k, 2k), J_c v_free (2k,)
        self._buffers = {k: (np.zeros((2 * k, NV)), np.zeros((2 * k, NV)), np.zeros((2 * k, 2 * k)),
                             np.zeros(2 * k)) for k in (1, 2)}
        self._lam = {k: np.zeros(2 * k) for k in (1, 2)}
        # position projection with m constraint rows: J (m, 7), J M^-1 (m, 7), J M^-1 J^T (m, m)
        self._proj_buffers = {m: (np.zeros((m, NV)), np.zeros((m, NV)), np.zeros((m, m))) for m in (1, 2, 3, 4)}
        self._had_contact = False
        self._minv = None
        self._q_old = np.zeros(NQ)
        self._energy = 0.0
        self._momentum_target = np.zeros(3)
        self._power_start = 0.0
        self._total_mass = float(self.robot.total_mass)
        self._imp_sum = [0.0, 0.0, 0.0, 0.0]
        p = self.robot.params
        self._link_lengths = (abs(p.hip_offset), abs(p.thigh.length), abs(p.shank.length))  # |c_0|, |c_1|, |c_2|
        # A foot farther than this above the ground cannot reach it within one step at < 50 m/s.
        self._far = 50.0 * self.dt

    # ------------------------------------------------------------------ state
    def set_state(self, x: np.ndarray) -> None:
        """Set the state ``x`` (14,), reset the clock, contact states and impulses."""
        self.x[:] = check_vector(x, NX, "x")
        self.time = 0.0
        self.impulse[:] = 0.0
        self.states = [SEPARATE, SEPARATE]
        self.contact[:] = False
        self._had_contact = False

    def foot_heights_fast(self) -> tuple[float, float]:
        """Unchecked `foot_heights` as two floats ``(front, back)`` (the env's hot path)."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, self.q)
        return (pin.updateFramePlacement(model, data, self._fids[0]).translation[2],
                pin.updateFramePlacement(model, data, self._fids[1]).translation[2])

    def energy(self) -> float:
        """Mechanical energy ``1/2 v^T M v + potential`` [J] at the current state (with this world's gravity)."""
        M = pin.crba(self.model, self.data, self.q)
        kinetic = 0.5 * float(self.v @ M @ self.v)
        return kinetic + float(pin.computePotentialEnergy(self.model, self.data, self.q))

    # ------------------------------------------------------------------ stepping
    def run(self, u: np.ndarray, n: int) -> list:
        """``n`` steps with constant joint torques ``u`` (4,) (unchecked: the env validates).

        Returns:
            The summed ground impulses over the ``n`` steps, grf layout (list of 4 floats) [N s].
        """
        total = self._imp_sum
        total[0] = total[1] = total[2] = total[3] = 0.0
        if self.energy_consistent and n > 0:
            model, data = self.model, self.data
            pin.computeMechanicalEnergy(model, data, self.q, self.v)
            self._energy = data.kinetic_energy + data.potential_energy
        if self.motor_speed_limits is None:
            self._tau[3:] = u
            for _ in range(n):
                self._step(total)
            return total
        u = [float(ui) for ui in u]
        w_full, w_zero = self.motor_speed_limits
        slope = self.torque_limit / (w_zero - w_full)
        tau, v = self._tau, self.v
        for _ in range(n):
            for j, (uj, wj) in enumerate(zip(u, v[3:].tolist())):
                if uj * wj > 0.0 and abs(wj) > w_full:
                    cap = max(0.0, (w_zero - abs(wj)) * slope)
                    if abs(uj) > cap:
                        uj = cap if uj > 0.0 else -cap
                tau[3 + j] = uj
            self._step(total)
        return total

    def _step(self, total: list) -> None:
        model, data, q, v, h = self.model, self.data, self.q, self.v, self.dt
        vf = self._vf
        np.multiply(pin.aba(model, data, q, v, self._tau), h, out=vf)
        vf += v
        pin.computeJointJacobians(model, data, q)
        z = float(q[1])
        cand = []
        for foot in FEET:
            J = pin.getFrameJacobian(model, data, self._fids[foot], _LWA)
            phi = z + float(J[0, 2])  # LWA Jacobian: linear x column of the pitch joint = p_z - z_trunk
            if phi > self._far:
                continue
            if phi <= CONTACT_MARGIN or phi + h * float(J[2].dot(vf)) <= 0.0:
                cand.append((foot, J, phi))
        states = self.states
        if not cand:
            if self.energy_consistent:  # the exact momentum after a free step: gravity's impulse only
                pm = self._momentum_target
                pm[:] = pin.computeCentroidalMap(model, data, q)[_MOMENTUM_ROWS] @ v
                pm[1] -= self._total_mass * self.gravity * h
                self._power_start = float(self._tau.dot(v))  # tau . v at the step's start (its work estimate)
            v[:] = vf
            if states[0] or states[1] or self._had_contact:
                states[0] = states[1] = SEPARATE
                self.impulse[:] = 0.0
                self.contact[:] = False
                self._had_contact = False
        else:
            k = len(cand)
            jc, A, G_array, c_array = self._buffers[k]
            for i, (_, J, _) in enumerate(cand):
                jc[2 * i:2 * i + 2] = J[2::-2]  # rows z (normal), x (tangent)
            minv = self._minv = pin.computeMinverse(model, data, q)
            np.dot(jc, minv, out=A)  # A = J M^-1 (2k, 7); M^-1 J^T = A^T
            np.dot(A, jc.T, out=G_array)
            np.dot(jc, vf, out=c_array)
            c = c_array.tolist()
            guess = []
            for i, (foot, _, phi) in enumerate(cand):
                if phi > 0.0:
                    c[2 * i] += phi / h
                guess.append(states[foot])
            G = G_array.tolist()
            lam, sol, exact = solve_contact_lcp_lists(G, c, self.mu, tuple(guess))
            if not exact:
                self.lcp_fallbacks += 1
            lam_buf = self._lam[k]
            lam_buf[:] = lam
            np.dot(lam_buf, A, out=v)
            v += vf
            imp, contact = self.impulse, self.contact
            imp[:] = 0.0
            contact[:] = False
            states[0] = states[1] = SEPARATE
            pen = None
            for i, (foot, _, phi) in enumerate(cand):
                ln, lt = lam[2 * i], lam[2 * i + 1]
                states[foot] = sol[i]
                imp[2 * foot] = lt
                imp[2 * foot + 1] = ln
                total[2 * foot] += lt
                total[2 * foot + 1] += ln
                contact[foot] = ln > 1e-9
                if phi < -PENETRATION_SLOP and sol[i] != SEPARATE:
                    pen = [(i, phi)] if pen is None else pen + [(i, phi)]
            self._had_contact = True
            if pen is not None and self.erp > 0.0 and not self.energy_consistent:
                self._correct_penetration(pen, G, A)
        if self.energy_consistent:
            self._finish_consistent(cand)
        else:
            np.multiply(v, h, out=self._dq)
            q += self._dq
        self.time += h

    def _finish_consistent(self, cand: list) -> None:
        """End of an energy-consistent step: ``q+ = q + h v+``, then the position projection of the contact feet
        and of every foot that ended below the ground, then the energy projection of ``v+``; see the module
        docstring (*Energy-consistent stepping*)."""
        model, data, q, v = self.model, self.data, self.q, self.v
        tau, dq = self._tau, self._dq
        np.multiply(v, self.dt, out=dq)
        # work of the joint torques over the step (tau is constant during it; its base entries are 0)
        q_old = self._q_old
        q_old[:] = q
        q += dq
        constrained = bool(cand)
        if not constrained:
            pin.forwardKinematics(model, data, q)
            fids = self._fids
            if (pin.updateFramePlacement(model, data, fids[0]).translation[2] < 0.0
                    or pin.updateFramePlacement(model, data, fids[1]).translation[2] < 0.0):
                # a foot crossed the ground within the step without being a candidate (a foot that moves faster
                # than the candidate test's linear prediction sees): back onto the ground, in the step's metric
                self._minv = pin.computeMinverse(model, data, q_old)
                constrained = True
        if constrained:
            self._project_positions(cand, q_old)  # leaves the mechanical energy of the result in data
            work = tau.dot(q) - tau.dot(q_old)
        else:
            pin.computeMechanicalEnergy(model, data, q, v)  # one call: kinematics, kinetic and potential energy
            # The work of the torques along the step, second order (trapezoidal in the velocity), capped by the
            # work along the scheme's displacement h v+ (which overestimates it by h^2 tau^T M^-1 tau / 2 when the
            # torques accelerate the joints): the flight's energy follows the torques' work, never more.
            work = min(tau.dot(dq), 0.5 * self.dt * (self._power_start + tau.dot(v)))
        kinetic, potential = data.kinetic_energy, data.potential_energy
        allowed = self._energy + work
        # with contacts a step that loses energy is left alone (contacts only dissipate); in free flight the step
        # always takes the momentum gravity leaves and exactly the allowed energy (no numerical damping)
        if not constrained or kinetic + potential > allowed:
            if kinetic + potential > allowed:
                self.energy_projections += 1
            target = allowed - potential
            target -= 1e-13 * (abs(allowed) + abs(potential))  # round-off margin
            if target <= 0.0:
                # the positions alone exceed the allowed energy (never seen; counted): stop the robot, the
                # least energy this step can leave
                self.energy_deficits += 1
                v[:] = 0.0
                kinetic = 0.0
            elif constrained:
                # contacts: scale v+, which keeps every contact velocity condition (J v+ = 0 when sticking)
                v *= (target / kinetic) ** 0.5
                kinetic = target
            else:
                kinetic = self._project_flight(kinetic, target)
        self._energy = kinetic + potential

    def _project_flight(self, kinetic: float, target: float) -> float:
        """Free flight: the point nearest to ``v+`` in the mass metric with kinetic energy ``target`` and the
        centroidal momentum (linear x, z and angular y about the centre of mass) of the step's start plus gravity's
        impulse (``_momentum_target``). With ``P`` (3, 7) those rows of the centroidal momentum matrix at ``q+``,
        ``B = M^-1 P^T``, ``S = P B`` and ``v_c(p) = B S^-1 p`` (the least-energy motion with momentum ``p``,
        M-orthogonal to every momentum-free motion), ``v = v_c(p_target) + s (v+ - v_c(P v+))`` with ``s`` giving
        the kinetic energy ``target``. Falls back to scaling ``v+`` (counted in
        [`momentum_fallbacks`][momentum_fallbacks]) when ``target`` is below the least energy of that momentum or ``v+``
        has no momentum-free part."""
        model, data, q, v = self.model, self.data, self.q, self.v
        P = pin.computeCentroidalMap(model, data, q)[_MOMENTUM_ROWS]
        # B = M^-1 P^T (7, 3) without a solve: the centroidal rows are P = T M[:3, :] with T the 3x3 shift of the
        # angular row from the trunk origin to the centre of mass, so M^-1 P^T = I[:, :3] T^T -- the rigid motions
        # of the locked robot (translations along x and z, the rotation about the centre of mass)
        # (the linear rows of P are M's x and z rows, so the CoM offset from the trunk origin reads off P)
        B = np.zeros((NV, 3))
        B[0, 0] = B[1, 1] = B[2, 2] = 1.0
        B[0, 2] = -P[0, 2] / P[0, 0]
        B[1, 2] = -P[1, 2] / P[0, 0]
        S = (P @ B).tolist()  # P M^-1 P^T (3, 3): symmetric positive definite
        p = (P @ v).tolist()
        pt = self._momentum_target.tolist()
        y = solve_spd(S, p)
        yt = solve_spd(S, pt)
        if y is None or yt is None:  # pragma: no cover - the momentum rows are independent for this robot
            y = yt = [0.0, 0.0, 0.0]
        k_c = 0.5 * (p[0] * y[0] + p[1] * y[1] + p[2] * y[2])
        k_t = 0.5 * (pt[0] * yt[0] + pt[1] * yt[1] + pt[2] * yt[2])
        free = kinetic - k_c  # kinetic energy of the momentum-free part of v+
        if target >= k_t and free > 1e-14 * kinetic:
            factor = ((target - k_t) / free) ** 0.5
            v -= B @ y
            v *= factor
            v += B @ yt
            return target
        self.momentum_fallbacks += 1
        v *= (target / kinetic) ** 0.5
        return target

    def _project_positions(self, cand: list, q_old: np.ndarray) -> None:
        """Move ``q+`` in the mass metric of the step (``dq = M^-1 J^T mu``) so that every candidate foot in
        contact (or ending below the ground) is at height 0 and every sticking foot at its position at the start
        of the step. Newton iterations with the exact Jacobians at the current ``q`` (quadratic: one iteration
        in practice) until the residual is below [`POSITION_TOLERANCE`][POSITION_TOLERANCE]. Leaves ``data`` with the
        kinematics (``q``, ``v``) of the result and its mechanical energy (``data.kinetic_energy``,
        ``data.potential_energy``).

        Hot path: the foot positions at ``q+`` come from the LWA frame Jacobians the first Newton step needs
        anyway (foot ``x = q_x - J[2, 2]``, ``z = q_z + J[0, 2]``); the check after a Newton step evaluates the
        kinematics with the velocities and the energy in one Pinocchio call, so a converged projection leaves
        the energy of the result at hand."""
        model, data, q, v = self.model, self.data, self.q, self.v
        fids = self._fids
        states = self.states
        iterations = MAX_PROJECTION_ITERATIONS
        if len(cand) == 2 and states[0] == STICK and states[1] == STICK:
            if self._project_double_stick(cand, q_old):
                return
            iterations -= 1  # one Newton step done; go on with the general iteration
        rows = []  # (foot, axis of the translation (0: x, 2: z), target)
        x_old = q_old.item(0)
        for foot, J, _ in cand:
            state = states[foot]
            if state == STICK:
                rows.append((foot, 0, x_old - J.item(2, 2)))  # LWA Jacobian: foot x = x - J[2, 2]
            if state != SEPARATE:
                rows.append((foot, 2, 0.0))
        pin.computeJointJacobians(model, data, q)
        held = {foot for foot, _, _ in cand if states[foot] != SEPARATE}
        for foot in FEET:  # any other foot that ends below the ground is lifted onto it
            if foot not in held and pin.updateFramePlacement(model, data, fids[foot]).translation[2] < 0.0:
                rows.append((foot, 2, 0.0))
        if not rows:
            pin.computeMechanicalEnergy(model, data, q, v)
            return
        m = len(rows)
        Jr, A, S = self._proj_buffers[m]
        feet = (rows[0][0],) if rows[-1][0] == rows[0][0] else (0, 1)
        fresh = True  # data holds the joint Jacobians of the current q
        residual = 0.0
        for _ in range(iterations):
            if fresh:  # positions from the Jacobians, which the Newton step needs
                jac = [None, None]
                for foot in feet:
                    jac[foot] = pin.getFrameJacobian(model, data, fids[foot], _LWA)
                qx, qz = q.item(0), q.item(1)
                r = [target - (qx - jac[foot].item(2, 2) if axis == 0 else qz + jac[foot].item(0, 2))
                     for foot, axis, target in rows]
            else:
                pos = [None, None]
                for foot in feet:
                    pos[foot] = pin.updateFramePlacement(model, data, fids[foot]).translation.tolist()
                r = [target - pos[foot][axis] for foot, axis, target in rows]
            residual = max(map(abs, r))
            if residual <= POSITION_TOLERANCE:
                break
            if not fresh:
                pin.computeJointJacobians(model, data, q)
                jac = [None, None]
                for foot in feet:
                    jac[foot] = pin.getFrameJacobian(model, data, fids[foot], _LWA)
            if m == 4 and rows[0][1] == 0 and rows[2][1] == 0:  # both feet sticking: rows x, z of each foot
                Jr[0:2] = jac[rows[0][0]][0:3:2]
                Jr[2:4] = jac[rows[2][0]][0:3:2]
            else:
                for i, (foot, axis, _) in enumerate(rows):
                    Jr[i] = jac[foot][axis]
            np.dot(Jr, self._minv, out=A)  # J M^-1 (m, 7)
            np.dot(A, Jr.T, out=S)  # J M^-1 J^T (m, m): symmetric positive definite
            mu = solve_spd(S.tolist(), r)
            if mu is None:  # pragma: no cover - the contact rows of this robot are never dependent
                break
            dq = np.dot(mu, A)
            q += dq
            pin.computeMechanicalEnergy(model, data, q, v)  # kinematics (q, v) and the energy of the new q
            fresh = False
            # Exact bound on the new residual (see _newton_remainder_bound): when it is far below the tolerance
            # the check would stop the iteration anyway, so the foot placements need not be evaluated.
            bound = self._newton_remainder_bound(dq.tolist(), feet)
            if bound <= 0.5 * POSITION_TOLERANCE:
                residual = bound
                break
        self.projection_residual = max(self.projection_residual, residual)
        if fresh:
            pin.computeMechanicalEnergy(model, data, q, v)

    def _project_double_stick(self, cand: list, q_old: np.ndarray) -> bool:
        """The first Newton step of [`_project_positions`][_project_positions] for its commonest case, both feet
        sticking (rows ``x, z`` of the front foot, then of the back foot), in straight-line code. Returns True when the
        projection is finished (residual or its exact bound below the tolerance; ``data`` then holds the
        kinematics and the energy of the result), False when the general iteration must go on from ``q``."""
        model, data, q = self.model, self.data, self.q
        fid0, fid1 = self._fids
        (_, Ja, _), (_, Jb, _) = cand  # the Jacobians at the start of the step (candidates in FEET order)
        x_old = q_old.item(0)
        pin.computeJointJacobians(model, data, q)
        J0 = pin.getFrameJacobian(model, data, fid0, _LWA)
        J1 = pin.getFrameJacobian(model, data, fid1, _LWA)
        qx, qz = q.item(0), q.item(1)
        r = [(x_old - Ja.item(2, 2)) - (qx - J0.item(2, 2)), 0.0 - (qz + J0.item(0, 2)),
             (x_old - Jb.item(2, 2)) - (qx - J1.item(2, 2)), 0.0 - (qz + J1.item(0, 2))]
        residual = max(abs(r[0]), abs(r[1]), abs(r[2]), abs(r[3]))
        if residual <= POSITION_TOLERANCE:
            pin.computeMechanicalEnergy(model, data, q, self.v)
            self.projection_residual = max(self.projection_residual, residual)
            return True
        Jr, A, S = self._proj_buffers[4]
        Jr[0:2] = J0[0:3:2]
        Jr[2:4] = J1[0:3:2]
        np.dot(Jr, self._minv, out=A)  # J M^-1 (4, 7)
        np.dot(A, Jr.T, out=S)  # J M^-1 J^T (4, 4)
        mu = solve_spd(S.tolist(), r)
        if mu is None:  # pragma: no cover - the contact rows of this robot are never dependent
            return False
        dq = np.dot(mu, A)
        q += dq
        pin.computeMechanicalEnergy(model, data, q, self.v)
        d = dq.tolist()
        c0, c1, c2 = self._link_lengths
        (hf, kf), (hb, kb) = FOOT_JOINTS
        d0 = d[IPITCH]
        a1 = d0 + d[hf]
        a2 = a1 + d[kf]
        b1 = d0 + d[hb]
        b2 = b1 + d[kb]
        t0 = c0 * d0 * d0
        bound = max(0.5 * (t0 + c1 * a1 * a1 + c2 * a2 * a2), 0.5 * (t0 + c1 * b1 * b1 + c2 * b2 * b2))
        if bound <= 0.5 * POSITION_TOLERANCE:
            self.projection_residual = max(self.projection_residual, bound)
            return True
        return False

    def _newton_remainder_bound(self, dq: list, feet: tuple) -> float:
        """An upper bound [m] on every foot coordinate's residual after a Newton step ``dq`` (7,) of the position
        projection. The step solves the linearised constraints (``J dq = r`` to round-off), so what remains is
        the Taylor remainder of the foot kinematics. A foot is ``(x, z) + sum_i R(phi_i) c_i`` with the trunk
        vector ``c_0`` (hip offset, angle ``phi_0`` = pitch), the thigh ``c_1`` (``phi_0 + hip``) and the shank
        ``c_2`` (``phi_0 + hip + knee``); along ``dq`` each term's second derivative has norm
        ``|c_i| dphi_i^2`` exactly, so the remainder of either coordinate is at most
        ``1/2 sum_i |c_i| dphi_i^2``."""
        c0, c1, c2 = self._link_lengths
        d0 = dq[IPITCH]
        worst = 0.0
        for foot in feet:
            hip, knee = FOOT_JOINTS[foot]
            d1 = d0 + dq[hip]
            d2 = d1 + dq[knee]
            worst = max(worst, 0.5 * (c0 * d0 * d0 + c1 * d1 * d1 + c2 * d2 * d2))
        return worst

    def _correct_penetration(self, pen: list, G: list, A: np.ndarray) -> None:
        """Split-impulse position correction: move ``q`` by ``M^-1 J_n^T mu`` (``A = J M^-1``) so that each
        penetrating contact foot rises by ``erp * (-phi)``; velocities (hence kinetic energy) are untouched."""
        erp = self.erp
        if len(pen) == 1:
            i, phi = pen[0]
            self.q += A[2 * i] * (erp * -phi / G[2 * i][2 * i])
            return
        (i, pi), (j, pj) = pen
        a, b, d = G[2 * i][2 * i], G[2 * i][2 * j], G[2 * j][2 * j]
        det = a * d - b * b
        if det <= 1e-12 * a * d:  # pragma: no cover - the two normals are never parallel for this robot
            return
        ri, rj = erp * -pi, erp * -pj
        self.q += A[2 * i] * ((d * ri - b * rj) / det) + A[2 * j] * ((a * rj - b * ri) / det)
