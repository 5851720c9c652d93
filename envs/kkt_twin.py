"""The planner's own model as an env: ``hsddp_gym/BoundingKKT-v0``, the task of ``hsddp_gym/Bounding-v0`` simulated
by the hybrid rigid-contact model the HS-DDP planner and the MPC predict with
([`hsddp_gym.core.dynamics`][hsddp_gym.core.dynamics]), with the contact mode decided by the state instead of a
schedule.

Model ([`KKTSimulator`][KKTSimulator]), one step of ``h`` (1 ms) in contact mode ``m`` (the set of pinned feet)
------------------------------------------------------------------------------------------------------------
1. *Touchdown at the start*: a free foot at or below the ground (``phi <= 0``) that does not move up joins ``m``
   through the touchdown reset map (paper eqs. 12-13, restitution 0: its velocity becomes 0;
   ``HybridDynamics.reset_map``).
2. *KKT dynamics* (paper eq. 11, Pinocchio ``constraintDynamics``; ABA in flight): ``M a + b = S^T u + J_m^T
   lam``, ``J_m a + dJ_m v = 0``. *Lift-off*: while a pinned foot's normal force ``lam_z`` is negative (the
   ground would have to pull), the most negative one is released and the dynamics are solved again without it.
3. *Semi-implicit Euler* (the MPC's integrator, ``HybridDynamics(integrator="semi_implicit")``):
   ``v+ = v + h a``, ``q+ = q + h v+``.
4. *Touchdown within the step*: a free foot that ends the step below the ground moving down touched it at the
   fraction ``s = phi(t) / (phi(t) - phi(t+h))`` of the straight-line position update; the state there goes
   through the reset map into ``m`` plus that foot, and the rest of the step, ``(1 - s) h``, moves the positions
   with the post-impact velocity. So a landing foot stops on the ground (up to the O(h^2) curvature of its path).
   A foot released in step 2 whose free motion still points into the ground (the pin also held it
   tangentially, so a negative normal force does not imply an upward free acceleration) is caught again here.
5. *Stabilization* (``stabilize=True``, the default; not part of the planner's model): the acceleration-level
   constraint ``J a + dJ v = 0`` integrated by semi-implicit Euler lets a pinned foot creep by about
   ``h^2 |dJ v|`` per step (~1e-6 m at 1 kHz; 0.05 mm in the first 50 ms of a landing), accumulating over a
   stance. So after every step the positions are moved in the mass metric to put each pinned foot back at
   its anchor (its touchdown x, z = 0; one Newton step, `KKTSimulator.pin_correction` is the largest
   correction so far) and the velocities go through the reset map of the current mode (the identity on exact
   stance motion). Both are zero on the planner's continuous-time stance trajectories; ``stabilize=False``
   gives the bare discrete model.

What the planner's model does not have, and what it therefore allows: the ground never makes a pinned foot slip
(no friction cone; `KKTSimulator.friction_ratio` and ``info["friction_ratio"]`` report the largest
``|f_x| / f_z`` of the pinned feet in the last control step, against ``mu = 0.6`` of the other two simulators,
and `KKTSimulator.cone_violations` counts the 1-ms steps above ``mu``); the acceleration-level constraint
``J a + dJ v = 0`` keeps the foot velocity at 0 to O(h) per step but does not correct position drift (a pinned
foot creeps unless stabilized, step 5); impacts are inelastic and instantaneous. The
motors' torque-speed limit of the env is applied first (the same
[`motor_torques`][hsddp_gym.core.contact.motor_torques]). """

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hsddp_gym.core.contact import SimulatorQueries, motor_torques
from hsddp_gym.core.contact_lcp import SEPARATE, STICK
from hsddp_gym.core.conventions import FEET, NGRF, NQ, NX, Mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.util.validation import check_vector

_LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class KKTSimulator(SimulatorQueries):
    """The planner's hybrid model ([`hsddp_gym.core.dynamics`][hsddp_gym.core.dynamics]) with state-based mode
    switching, behind the interface [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] uses of its simulator
    (``x``/``q``/``v`` views, ``set_state``, ``run``, ``contact``, ``impulse``, ``foot_heights_fast``, ``energy``, ...).
    See the module docstring for the step.

    Args:
        robot: the model (default: the paper's robot). timestep: ``h`` [s] (default 1e-3).
        friction: Coulomb ``mu`` used only to count friction-cone violations (the model pins its feet).
        gravity: [m/s^2] >= 0 (default ``robot.params.gravity``).
        motor_speed_limits: with ``torque_limit``, the env's torque-speed limit (as ContactSimulator).
        torque_limit: see ``motor_speed_limits``.
        stabilize: put pinned feet back on their anchors and zero their velocities after every step (step 5 of
            the module docstring; default True); False: the bare discrete planner's model.

    Attributes (read-only between calls): x (14,), q, v (7,) views; time [s]; mode (``Mode``, the pinned feet);
    impulse: ground impulses of the last 1-ms step (grf layout (4,)) [N s]; contact (2,) bool: the foot was
    pinned with a positive normal force (or touched down) in the last step; states (2,): ``STICK`` for a
    pinned foot, else ``SEPARATE``; friction_ratio: the largest ``|f_x| / f_z`` of a pinned foot over the last
    [`run`][run]; cone_violations: 1-ms steps since [`set_state`][set_state] in which a pinned foot had
    ``|f_x| > mu f_z``; touchdowns, liftoffs: counts since [`set_state`][set_state]; pin_correction: the largest
    position correction of the stabilization since [`set_state`][set_state] [m].
    """

    def __init__(self, robot: CheetahModel | None = None, timestep: float = 1e-3, friction: float | None = None,
                 gravity: float | None = None, motor_speed_limits=None, torque_limit: float | None = None,
                 stabilize: bool = True) -> None:
        if not isinstance(stabilize, (bool, np.bool_)):
            raise TypeError(f"stabilize must be a bool, got {type(stabilize).__name__}")
        self.stabilize = bool(stabilize)
        robot = self._set_common(robot, timestep, friction, gravity, torque_limit, motor_speed_limits)
        params = robot.params
        if self.gravity != params.gravity:  # a private copy of the model in this world's gravity
            robot = CheetahModel(params)
            robot.model.gravity = pin.Motion(np.array([0.0, 0.0, -self.gravity]), np.zeros(3))
        self.robot = robot
        self.dynamics = HybridDynamics(robot, dt=self.dt, integrator="semi_implicit")
        self._model = robot.model
        self._data = robot.model.createData()
        self._fids = tuple(robot.foot_frame_ids)
        self.x = np.zeros(NX)
        self.q = self.x[:NQ]
        self.v = self.x[NQ:]
        self.time = 0.0
        self.mode = Mode.FLIGHT
        self.impulse = np.zeros(NGRF)
        self.contact = np.zeros(2, dtype=bool)
        self.states = [SEPARATE, SEPARATE]
        self.lcp_fallbacks = 0  # interface compatibility: there is no LCP
        self.friction_ratio = 0.0
        self.cone_violations = 0
        self.touchdowns = 0
        self.liftoffs = 0
        self.pin_correction = 0.0
        self._next = np.zeros(NX)
        self._grf = np.zeros(NGRF)
        self._imp_sum = [0.0, 0.0, 0.0, 0.0]
        self._anchor = [0.0, 0.0]  # x [m] where each pinned foot touched down (its z anchor is the ground, 0)

    # ------------------------------------------------------------------ state
    def set_state(self, x: np.ndarray) -> None:
        """Set the state ``x`` (14,); every foot starts free (step 1 pins a foot on or below the ground)."""
        self.x[:] = check_vector(x, NX, "x")
        self.time = 0.0
        self.mode = Mode.FLIGHT
        self.impulse[:] = 0.0
        self.contact[:] = False
        self.states = [SEPARATE, SEPARATE]
        self.friction_ratio = 0.0
        self.cone_violations = self.touchdowns = self.liftoffs = 0
        self.pin_correction = 0.0

    def _feet(self, x: np.ndarray) -> list:
        """``[(height, vertical velocity)]`` of both feet at state ``x`` (14,)."""
        model, data = self._model, self._data
        pin.forwardKinematics(model, data, x[:NQ], x[NQ:])
        out = []
        for fid in self._fids:
            z = pin.updateFramePlacement(model, data, fid).translation[2]
            vz = pin.getFrameVelocity(model, data, fid, _LWA).linear[2]
            out.append((float(z), float(vz)))
        return out

    def energy(self) -> float:
        """Mechanical energy [J] of the current state (this world's gravity)."""
        pin.computeMechanicalEnergy(self._model, self._data, self.q, self.v)
        return float(self._data.kinetic_energy + self._data.potential_energy)

    # ------------------------------------------------------------------ stepping
    def run(self, u: np.ndarray, n: int) -> list:
        """``n`` steps with constant commanded joint torques ``u`` (4,) (unchecked: the env validates).

        Returns:
            The summed ground impulses over the ``n`` steps, grf layout (list of 4 floats) [N s].
        """
        total = self._imp_sum
        total[0] = total[1] = total[2] = total[3] = 0.0
        u = np.asarray(u, dtype=np.float64)
        self.friction_ratio = 0.0
        for _ in range(n):
            tau = u if self.motor_speed_limits is None else motor_torques(u, self.v[3:], self.motor_speed_limits,
                                                                          self.torque_limit)
            self._step(tau, total)
        return total

    def _touchdown(self, x: np.ndarray, mode: int, impulse: np.ndarray, count: bool = True) -> np.ndarray:
        """The reset map of ``x`` (14,) into ``mode`` (restitution 0); adds the impulse to ``impulse`` (4,)."""
        x_plus, imp = self.dynamics.reset_map(x, Mode(mode), restitution=0.0)
        impulse += imp
        self.touchdowns += count
        return x_plus

    def _set_anchors(self, x: np.ndarray, feet: int) -> None:
        """Anchor the feet of the bit mask ``feet`` where they are at state ``x`` (14,) (x only; z is 0)."""
        model, data = self._model, self._data
        pin.forwardKinematics(model, data, x[:NQ])
        for foot in FEET:
            if feet & (1 << foot):
                self._anchor[foot] = float(pin.updateFramePlacement(model, data, self._fids[foot]).translation[0])

    def _pin_feet(self, x: np.ndarray, mode: int) -> None:
        """Stabilization (``stabilize``): move the positions of ``x`` (14,) in the mass metric,
        ``dq = M^-1 J^T (J M^-1 J^T)^-1 r``, so that every pinned foot is back at its anchor ``(x_anchor, 0)``
        (one Newton step on corrections of O(h^2): the residual is O(h^4))."""
        model, data = self._model, self._data
        q = x[:NQ]
        pin.computeJointJacobians(model, data, q)
        rows, r = [], []
        for foot in FEET:
            if mode & (1 << foot):
                J = pin.getFrameJacobian(model, data, self._fids[foot], _LWA)
                p = pin.updateFramePlacement(model, data, self._fids[foot]).translation
                rows += [J[0], J[2]]
                r += [self._anchor[foot] - float(p[0]), -float(p[2])]
        J = np.array(rows)
        B = pin.computeMinverse(model, data, q) @ J.T
        q += B @ np.linalg.solve(J @ B, np.array(r))
        self.pin_correction = max(self.pin_correction, max(map(abs, r)))

    def _step(self, tau: np.ndarray, total: list) -> None:
        x, h = self.x, self.dt
        impulse = self.impulse
        impulse[:] = 0.0
        mode = int(self.mode)
        if not np.all(np.isfinite(x)):  # a blown-up state stays blown up (the env reports it)
            x[:] = np.nan
            self.time += h
            return
        feet = self._feet(x)
        landing = 0
        for foot in FEET:
            z, vz = feet[foot]
            if not mode & (1 << foot) and z <= 0.0 and vz <= 0.0:
                landing |= 1 << foot
        if landing:
            mode |= landing
            self._set_anchors(x, landing)
            x[:] = self._touchdown(x, mode, impulse)
        grf, nxt = self._grf, self._next
        while True:
            self.dynamics.simulate_step(x, tau, mode, nxt, grf)
            pulled = [(grf[2 * f + 1], f) for f in FEET if mode & (1 << f) and grf[2 * f + 1] < 0.0]
            if not pulled:
                break
            mode &= ~(1 << min(pulled)[1])  # release the foot the ground would pull hardest
            self.liftoffs += 1
        impulse += h * grf
        ratio = 0.0
        for f in FEET:
            if mode & (1 << f) and grf[2 * f + 1] > 0.0:
                ratio = max(ratio, abs(grf[2 * f]) / grf[2 * f + 1])
        if ratio > self.mu:
            self.cone_violations += 1
        self.friction_ratio = max(self.friction_ratio, ratio)
        # touchdown within the step: the first free foot to cross the ground, moving down
        if np.all(np.isfinite(nxt)):
            after = self._feet(nxt)
            s, landing = 1.0, 0
            for foot in FEET:
                z1, vz1 = after[foot]
                if not mode & (1 << foot) and z1 < 0.0 and vz1 < 0.0:
                    z0 = max(feet[foot][0], 0.0)
                    sf = z0 / (z0 - z1)
                    if sf < s - 1e-12:
                        s, landing = sf, 1 << foot
                    elif abs(sf - s) <= 1e-12:
                        landing |= 1 << foot
            if landing:
                mode |= landing
                crossing = nxt.copy()
                crossing[:NQ] = x[:NQ] + s * (nxt[:NQ] - x[:NQ])  # positions move linearly within the step
                self._set_anchors(crossing, landing)
                post = self._touchdown(crossing, mode, impulse)
                nxt[NQ:] = post[NQ:]
                nxt[:NQ] = crossing[:NQ] + (1.0 - s) * h * post[NQ:]
        if mode and self.stabilize:
            self._pin_feet(nxt, mode)
            nxt[:] = self._touchdown(nxt, mode, impulse, count=False)
        x[:] = nxt
        self.mode = Mode(mode)
        for f in FEET:
            pinned = bool(mode & (1 << f))
            self.states[f] = STICK if pinned else SEPARATE
            self.contact[f] = pinned and impulse[2 * f + 1] > 0.0
        for k in range(NGRF):
            total[k] += float(impulse[k])
        self.time += h


class KKTBoundingEnv(BoundingEnv):
    """``hsddp_gym/BoundingKKT-v0``: [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (same observation, action,
    reward, reset, termination and arguments) simulated by the planner's own hybrid model
    ([`KKTSimulator`][KKTSimulator]: pinned stance feet, KKT contact dynamics, touchdown reset maps, lift-off on a
    negative normal force) instead of the exact-LCP contact simulator. ``contact_erp`` and ``energy_consistent`` do not
    apply (accepted, ignored); ``friction`` only sets the cone against which violations are counted; extra argument
    ``stabilize`` (default True: the drift correction of the module docstring, step 5). ``info`` has the keys of
    Bounding-v0 plus ``friction_ratio``: the largest ``|f_x| / f_z`` of a pinned foot in the control step (0 in
    flight and at reset), which the model lets exceed ``mu``."""

    def __init__(self, *args, stabilize: bool = True, **kwargs) -> None:
        if not isinstance(stabilize, (bool, np.bool_)):
            raise TypeError(f"stabilize must be a bool, got {type(stabilize).__name__}")
        self._stabilize = bool(stabilize)
        super().__init__(*args, **kwargs)

    def _make_simulator(self, friction, gravity, contact_erp, motor_speed_limits, energy_consistent):
        return KKTSimulator(self.robot, timestep=self.sim_timestep, friction=friction, gravity=gravity,
                            motor_speed_limits=motor_speed_limits, torque_limit=self.torque_limit,
                            stabilize=self._stabilize)

    def _get_info(self) -> dict:
        info = super()._get_info()
        info["friction_ratio"] = float(self.sim.friction_ratio)
        return info
