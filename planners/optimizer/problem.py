"""The hybrid optimal control problem (paper eq. 17): phases from a mode schedule, each with its
discrete dynamics, quadratic running and terminal costs (eqs. 32-33), a switching constraint at every
touchdown (eq. 17d) and inequality constraints (17e-17g).

Running cost of knot k in phase i (``h`` the step; the authors' code adds the ground-force term)::

    L = h [ (x - xr_i)^T Q_i (x - xr_i) + u^T R_i u + (grf - grf_ref_i)^T S_i (grf - grf_ref_i) ]

Terminal cost at the end of phase i (the authors' code has the 1/2; the paper's eq. 33 has none, which
``terminal_half=False`` of [`bounding_phase_cost`][bounding_phase_cost] gives by doubling ``Qf_i``)::

    Phi_i = 1/2 (x^- - xf_i)^T Qf_i (x^- - xf_i)

All weight matrices are diagonal and stored as vectors.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from hsddp_gym.core.conventions import IZ, NGRF, NU, NX, Mode, grf_slice
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.params import RobotParams
from hsddp_gym.core.references import end_of_mode_reference
from hsddp_gym.core.schedule import BOUNDING_CYCLE, ModeSchedule
from hsddp_gym.core.terrain import Terrain, check_terrain
from hsddp_gym.util.validation import check_array, check_int, check_positive

# Weights of the authors' code closest to the paper (original_code_facts §3.5, MH@0b6ca76), state order
# [x, z, pitch, hf, kf, hb, kb, dx, dz, dpitch, dhf, dkf, dhb, dkb].
_Q = 0.01 * np.array([0, 10, 5, 2, 2, 2, 2, 8, 1, 0.01, 5, 5, 5, 5], dtype=float)
_QF_BASE = 100.0 * np.array([0, 20, 8, 3, 3, 3, 3, 10, 2, 0.01], dtype=float)
_QF_RATES = {Mode.BACK_STANCE: (500, 500, 1, 1), Mode.FLIGHT: (500, 500, 500, 500), Mode.FRONT_STANCE: (1, 1, 500, 500),
             Mode.DOUBLE_STANCE: (1, 1, 1, 1)}
_R = {Mode.BACK_STANCE: (5, 5, 1, 1), Mode.FLIGHT: (1, 1, 1, 1), Mode.FRONT_STANCE: (1, 1, 5, 5),
      Mode.DOUBLE_STANCE: (1, 1, 1, 1)}
_S = {Mode.BACK_STANCE: 0.3, Mode.FRONT_STANCE: 0.15, Mode.FLIGHT: 0.0, Mode.DOUBLE_STANCE: 0.15}
# Double stance is not in the authors' gait (the MPC plans one when a swing foot lands before the stance foot
# has lifted off): the stance-leg weights on both legs, the weight shared by the two feet.
# The authors' later weights (original_code_facts §3.5 "later version": MH HEAD / HM, used there with their
# 1.5 m/s gait): Q with more weight on the joints and less on the forward speed, R halved, Q_f with less weight
# on the forward speed (x weight 0 as in HM).
_Q_LATER = 0.01 * np.array([0, 10, 5, 4, 4, 4, 4, 2, 1, 0.01, 6, 6, 6, 6], dtype=float)
_QF_BASE_LATER = 100.0 * np.array([0, 20, 8, 3, 3, 3, 3, 3, 2, 0.01], dtype=float)
PERIODIC_BOUNDING_DURATIONS = (0.080, 0.072, 0.072, 0.072, 0.040)
"""Initial durations of [`HybridProblem.bounding_periodic`][HybridProblem.bounding_periodic] (BS, FL, FS, FL, BS)
[s]."""
BOUNDING_WEIGHTS = ("paper", "later")
"""``"paper"``: the authors' code closest to the paper (MH@0b6ca76), the default; ``"later"``: their later code."""


@dataclasses.dataclass(frozen=True)
class PhaseCost:
    """Cost of one phase. Shapes: ``x_ref, q, x_final, qf (14,)``, ``r (4,)``, ``grf_ref, s (4,)``."""

    x_ref: np.ndarray
    q: np.ndarray
    r: np.ndarray
    grf_ref: np.ndarray
    s: np.ndarray
    x_final: np.ndarray
    qf: np.ndarray

    def __post_init__(self) -> None:
        for name, size in (("x_ref", NX), ("q", NX), ("r", NU), ("grf_ref", NGRF), ("s", NGRF), ("x_final", NX),
                           ("qf", NX)):
            arr = check_array(getattr(self, name), (size,), f"PhaseCost.{name}")
            if name in ("q", "r", "s", "qf") and np.any(arr < 0):
                raise ValueError(f"PhaseCost.{name} must be >= 0 (diagonal weights), got {arr}")
            object.__setattr__(self, name, arr)

    @classmethod
    def _checked_by_caller(cls, **arrays: np.ndarray) -> PhaseCost:
        """A PhaseCost of the arrays as given, without [`__post_init__`][__post_init__]'s checks: for arrays the caller
        built to pass them (finite float64 of the right shapes, weights >= 0;
        [`bounding_phase_cost`][bounding_phase_cost], once per phase of every MPC re-plan)."""
        cost = object.__new__(cls)
        for name, arr in arrays.items():
            object.__setattr__(cost, name, arr)
        return cost


def bounding_phase_cost(mode: Mode, touchdown_foot: int | None, speed: float = 1.0, params: RobotParams | None = None,
                        running_reference: str = "terminal", grf_tracking: bool = True, z_velocity: str = "paper",
                        weights: str = "paper", terminal_half: bool = True, height_offset: float = 0.0) -> PhaseCost:
    """The bounding cost of one phase (original_code_facts §3.4-§3.5).

    Args:
        mode: phase mode (BACK_STANCE, FLIGHT, FRONT_STANCE or DOUBLE_STANCE).
        touchdown_foot: the foot landing at the end of a flight phase; for DOUBLE_STANCE the foot that stays on
            the ground after it (see
            [`hsddp_gym.core.references.end_of_mode_reference`][hsddp_gym.core.references.end_of_mode_reference]).
        speed: desired forward speed [m/s].
        running_reference: ``"terminal"`` (paper eq. 32-33: the running cost tracks the mode's reference
            posture) or ``"code"`` (the authors' early code: a neutral posture, z = 0.254 m, legs straight).
        grf_tracking: include the authors' ground-force tracking term (full weight on the stance foot).
        z_velocity: terminal vertical-velocity reference, ``"code"`` (+-1 m/s) or ``"paper"`` (0).
        weights: ``"paper"`` (the authors' code closest to the paper, §3.5) or ``"later"`` (their later code,
            which they ran at 1.5 m/s), see [`BOUNDING_WEIGHTS`][BOUNDING_WEIGHTS].
        terminal_half: True (default, the authors' code): ``Phi = 1/2 dx' Qf dx``; False: the paper's eq. 33,
            ``Phi = dx' Qf dx`` (stored as a doubled ``qf``, since the objective always has the 1/2).
        height_offset: reference postures with the trunk this much higher [m], the feet where the authors' postures
            have them ([`end_of_mode_reference`][hsddp_gym.core.references.end_of_mode_reference]; 0: the authors').
    """
    params = params if params is not None else RobotParams()
    for name, flag in (("grf_tracking", grf_tracking), ("terminal_half", terminal_half)):
        if not isinstance(flag, (bool, np.bool_)):
            raise TypeError(f"{name} must be a bool, got {flag!r} ({type(flag).__name__})")
    if weights not in BOUNDING_WEIGHTS:
        raise ValueError(f"weights must be one of {BOUNDING_WEIGHTS}, got {weights!r}")
    mode = Mode(mode)
    if mode not in _R:
        raise ValueError(f"bounding costs exist for BACK_STANCE, FLIGHT, FRONT_STANCE and DOUBLE_STANCE, got {mode!r}")
    if running_reference not in ("terminal", "code"):
        raise ValueError(f"running_reference must be 'terminal' or 'code', got {running_reference!r}")
    x_final = end_of_mode_reference(mode, touchdown_foot, speed, z_velocity=z_velocity, params=params,
                                    height_offset=height_offset)
    if running_reference == "terminal":
        x_ref = x_final.copy()
    else:
        x_ref = np.zeros(NX)
        x_ref[1] = -0.15 + params.leg_length
        x_ref[7] = speed
    weight = params.total_mass * params.gravity
    grf_ref = np.zeros(NGRF)
    s = np.zeros(NGRF)
    if grf_tracking:
        for foot in mode.feet:
            sl = grf_slice(foot)
            grf_ref[sl] = (0.0, weight / len(mode.feet))
            s[sl] = _S[mode]
    later = weights == "later"
    qf = np.concatenate([_QF_BASE_LATER if later else _QF_BASE, _QF_RATES[mode]]) * (1.0 if terminal_half else 2.0)
    r = np.array(_R[mode], dtype=float) * (0.5 if later else 1.0)
    # float64 arrays of the right shapes by construction, finite (end_of_mode_reference checks the speed and the
    # parameters are finite), weights >= 0 (the constants above)
    return PhaseCost._checked_by_caller(x_ref=x_ref, q=(_Q_LATER if later else _Q).copy(), r=r, grf_ref=grf_ref,
                                        s=s, x_final=x_final, qf=qf)


@dataclasses.dataclass(frozen=True)
class ConstraintSpec:
    """Which constraints the problem has (the solver's options decide how they are handled).

    Attributes:
        torque_limit: |u_j| <= torque_limit (eq. 17e) [N m].
        friction: mu of the friction cone |f_x| <= mu f_z (eq. 17g); f_z >= 0 (eq. 17f) for stance feet.
        switching: enforce g_c(x^-) = 0 at every touchdown (eq. 17d).
        joint_limits: None (default: no joint ranges, the paper's problem) or ``((hip_min, hip_max), (knee_min,
            knee_max))`` [rad], both legs: the running cost then adds ``joint_limit_weight * d^2`` per joint, ``d``
            [rad] how far the joint is beyond its range shrunk by ``joint_limit_margin`` (a one-sided quadratic
            penalty, zero inside).
        joint_limit_weight: [1/(rad^2 s)]. joint_limit_margin: [rad].
        knee_clearance: None (default: knees unconstrained, the paper's problem) or a height [m]: the running cost
            then adds ``clearance_weight * d^2`` per knee, ``d`` [m] how far the knee is below that height above the
            flat ground (a one-sided quadratic penalty; a knee is no foot, the ground does not hold it).
        swing_foot_clearance: None (default) or a height [m]: the same penalty on the feet of the legs not in stance
            (0 keeps them out of the ground and lets a landing foot reach it).
        clearance_weight: [1/(m^2 s)].

    The penalties are part of the objective's value and derivatives (``Objective.evaluate``, ``derivatives``), not
    of the running-cost rates the switching-time optimization uses (``Objective.running_rates``).
    """

    torque_limit: float = 33.0
    friction: float = 0.6
    switching: bool = True
    joint_limits: tuple | None = None
    joint_limit_weight: float = 1.0e6
    joint_limit_margin: float = 0.1
    knee_clearance: float | None = None
    swing_foot_clearance: float | None = None
    clearance_weight: float = 1.0e6

    def __post_init__(self) -> None:
        check_positive(self.torque_limit, "torque_limit")
        check_positive(self.friction, "friction")
        check_positive(self.joint_limit_weight, "joint_limit_weight")
        check_positive(self.clearance_weight, "clearance_weight")
        for name in ("knee_clearance", "swing_foot_clearance"):
            value = getattr(self, name)
            if value is not None and not np.isfinite(value):
                raise ValueError(f"{name} must be None or finite, got {value!r}")
        if not (np.isfinite(self.joint_limit_margin) and self.joint_limit_margin >= 0):
            raise ValueError(f"joint_limit_margin must be finite and >= 0, got {self.joint_limit_margin!r}")
        if self.joint_limits is not None:
            lim = np.asarray(self.joint_limits, dtype=np.float64)
            if lim.shape != (2, 2) or not np.all(np.isfinite(lim)) or np.any(
                    lim[:, 1] - lim[:, 0] <= 2 * self.joint_limit_margin):
                raise ValueError("joint_limits must be ((hip_min, hip_max), (knee_min, knee_max)) [rad], finite, each "
                                 f"range wider than 2 joint_limit_margin, got {self.joint_limits!r}")
            object.__setattr__(self, "joint_limits", tuple(tuple(float(v) for v in row) for row in lim))

    def joint_bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """``(lo (4,), hi (4,))`` the penalty's bounds of the joints ``q[3:7]`` (the ranges shrunk by the margin),
        or None without ``joint_limits``."""
        if self.joint_limits is None:
            return None
        (h_lo, h_hi), (k_lo, k_hi) = self.joint_limits
        m = self.joint_limit_margin
        return np.array([h_lo, k_lo, h_lo, k_lo]) + m, np.array([h_hi, k_hi, h_hi, k_hi]) - m


def _reference_foot(schedule: ModeSchedule, phase: int) -> int | None:
    """The ``touchdown_foot`` argument of [`bounding_phase_cost`][bounding_phase_cost] for ``phase``: the landing foot
    of a flight, the foot that stays on the ground after a double stance."""
    if schedule.modes[phase] == Mode.DOUBLE_STANCE:
        feet = schedule.next_mode(phase).feet
        if len(feet) != 1:
            raise ValueError(f"phase {phase}: a double stance must be followed by a single stance, got "
                             f"{schedule.next_mode(phase)!r}")
        return feet[0]
    return schedule.bounding_touchdown_foot(phase)


class HybridProblem:
    """A hybrid optimal control problem over a mode schedule.

    Args:
        dynamics: discrete hybrid dynamics (its ``dt`` is the knot spacing ``h``).
        schedule: modes and durations (phase i has ``round(T_i / h)`` knots).
        costs: one [`PhaseCost`][PhaseCost] per phase.
        x0: initial state (14,).
        constraints: a [`ConstraintSpec`][ConstraintSpec].
        restitution: of the touchdown reset maps (paper: 0).
        knots: steps per phase ``(n,)``; default ``round(T_i / dt)``. Given explicitly (time-scaled problems
            of the switching-time optimization, eq. 28), phase ``i`` steps with ``h_i = T_i / knots[i]``.
        terrain: the ground under the feet, a [`Terrain`][hsddp_gym.core.terrain.Terrain] (None: flat, ``z = 0``).
            The switching constraint of a landing foot is its height above the terrain under it,
            ``g = foot_z - terrain.height(foot_x)``
            ([`Objective.switching_values`][hsddp_gym.planners.optimizer.objective.Objective.switching_values]); on a
            level segment ``dg/dq = d foot_z / dq`` wherever the foot is not exactly on an edge, on a slope
            ``dg/dq = d foot_z / dq - dh/dx d foot_x / dq`` (the Hessian is foot_z's). None and a flat terrain give the
            same problem, bit for bit. The contact dynamics do not depend on the ground height (a stance foot is held
            where it landed).

    Per-knot arrays (N = total knots): ``modes (N,)``, ``phase_of_knot (N,)``, weights ``Qd (N, 14)``,
    ``Rd (N, 4)``, ``Sd (N, 4)``, references ``XR (N, 14)``, ``YR (N, 4)``; per phase ``QF (n, 14)``,
    ``XF (n, 14)``, ``touchdown (n,)`` (the first landing foot, or -1), ``next_modes (n,)``; per switching-constraint
    row ``switch_phase (m,)``, ``switch_foot (m,)``: one row per phase, plus one for the second foot of every
    simultaneous touchdown (flight -> double stance, e.g. a pronk), so ``m = n`` for the bound.
    """

    def __init__(self, dynamics: HybridDynamics, schedule: ModeSchedule, costs, x0: np.ndarray,
                 constraints: ConstraintSpec = ConstraintSpec(), restitution: float = 0.0, knots=None,
                 terrain: Terrain | None = None) -> None:
        if not isinstance(dynamics, HybridDynamics):
            raise TypeError(f"dynamics must be a HybridDynamics, got {type(dynamics).__name__}")
        if not isinstance(schedule, ModeSchedule):
            raise TypeError(f"schedule must be a ModeSchedule, got {type(schedule).__name__}")
        costs = list(costs)
        if len(costs) != len(schedule) or not all(isinstance(c, PhaseCost) for c in costs):
            raise ValueError(f"costs must be {len(schedule)} PhaseCost objects (one per phase), got {len(costs)}")
        if not isinstance(constraints, ConstraintSpec):
            raise TypeError(f"constraints must be a ConstraintSpec, got {type(constraints).__name__}")
        self.dynamics = dynamics
        self.schedule = schedule
        self.costs = tuple(costs)
        self.x0 = check_array(x0, (NX,), "x0").copy()
        self.constraints = constraints
        self.restitution = float(restitution)
        self.terrain = check_terrain(terrain)
        """The ground under the feet (None: flat)."""
        self.dt = dynamics.dt
        if knots is None:
            knots = schedule.knots(dynamics.dt)
        knots = np.asarray(knots)
        if knots.shape != (len(schedule),) or not np.issubdtype(knots.dtype, np.integer) or np.any(knots < 1):
            raise ValueError(f"knots must be {len(schedule)} positive integers, got {knots!r}")
        self.knots = knots.astype(np.int64)
        self.phase_start = np.concatenate([[0], np.cumsum(self.knots)]).astype(np.int64)
        self.phase_of_knot = np.repeat(np.arange(len(schedule)), self.knots)
        self.modes = np.array([int(m) for m in schedule.modes], dtype=np.int64)[self.phase_of_knot]
        self.n_knots = int(self.modes.shape[0])
        self.n_phases = len(schedule)
        self.phase_dt = schedule.durations / self.knots
        """Step of each phase ``h_i = T_i / N_i`` (n,)."""
        self.h = self.phase_dt[self.phase_of_knot]
        """Step of each knot (N,)."""
        p = self.phase_of_knot
        self.Qd = np.stack([c.q for c in costs])[p]
        self.Rd = np.stack([c.r for c in costs])[p]
        self.Sd = np.stack([c.s for c in costs])[p]
        self.XR = np.stack([c.x_ref for c in costs])[p]
        self.YR = np.stack([c.grf_ref for c in costs])[p]
        self.QF = np.stack([c.qf for c in costs])
        self.XF = np.stack([c.x_final for c in costs])
        self.next_modes = np.array([int(schedule.next_mode(i)) for i in range(self.n_phases)])
        # switching constraints, one row per landing foot: row i (< n) is phase i's first landing foot (-1: none);
        # a simultaneous touchdown (flight -> double stance) adds a row for its second foot after the n rows
        td, extra = [], []
        for i in range(self.n_phases):
            feet = schedule.touchdown_feet(i)
            td.append(feet[0] if feet else -1)
            extra += [(i, f) for f in feet[1:]]
        self.touchdown = np.array(td, dtype=np.int64)
        """The first landing foot at the end of each phase (n,), -1 where no foot lands."""
        self.switch_phase = np.concatenate([np.arange(self.n_phases), [i for i, _ in extra]]).astype(np.int64)
        """Phase of each switching-constraint row (m,), ``m = n + `` the second feet of simultaneous touchdowns."""
        self.switch_foot = np.concatenate([self.touchdown, [f for _, f in extra]]).astype(np.int64)
        """Landing foot of each switching-constraint row (m,), -1 for a phase without a touchdown."""
        self.n_switching = int(self.switch_phase.shape[0])
        """Rows ``m`` of the switching constraint g and of the AL multipliers (``n`` unless feet land together)."""
        # stance feet per knot (for friction-cone constraints): (N, 2) bool
        self.stance = np.array([[m.in_contact(f) for f in (0, 1)] for m in schedule.modes],
                               dtype=bool)[self.phase_of_knot]
        self.stance_any = self.stance.any(axis=1)

    @classmethod
    def bounding(cls, cycles: int = 5, durations=None, x0: np.ndarray | None = None, speed: float = 1.0,
                 dynamics: HybridDynamics | None = None, constraints: ConstraintSpec | None = None,
                 running_reference: str = "terminal", grf_tracking: bool = True, schedule: ModeSchedule | None = None,
                 z_velocity: str = "paper", weights: str = "paper", terminal_half: bool = True,
                 knots=None, height_offset: float = 0.0, ground=None, terrain: Terrain | None = None
                 ) -> HybridProblem:
        """The paper's bounding task: ``cycles`` gait cycles from back stance, 80/72/72/72 ms, h = 1 ms,
        v_d = 1 m/s, the paper's initial state (Sec. V-B); ``running_reference``, ``grf_tracking``,
        ``z_velocity``, ``weights``, ``terminal_half``, ``height_offset`` see
        [`bounding_phase_cost`][bounding_phase_cost]; ``knots`` (n,) the knots per phase (None:
        ``schedule.knots(dynamics.dt)``; a per-phase grid, e.g. finer first phases); ``ground`` (n,) a height [m] per
        phase added to its reference trunk heights (running and terminal; the ground under the trunk, e.g. at the
        phase's end; None: 0); ``terrain`` the ground of the switching constraints (see the class; None: flat)."""
        from hsddp_gym.core.references import paper_initial_state
        from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS

        dynamics = dynamics if dynamics is not None else HybridDynamics()
        if schedule is None:
            schedule = ModeSchedule.bounding(cycles, PAPER_BOUNDING_DURATIONS if durations is None else durations)
        params = dynamics.robot.params
        costs = [bounding_phase_cost(m, _reference_foot(schedule, i), speed, params, running_reference, grf_tracking,
                                     z_velocity, weights, terminal_half, height_offset)
                 for i, m in enumerate(schedule.modes)]
        if ground is not None:
            ground = check_array(ground, (len(costs),), "ground")
            for cost, z in zip(costs, ground):  # the costs' own arrays, built above
                cost.x_ref[IZ] += z
                cost.x_final[IZ] += z
        if constraints is None:
            constraints = ConstraintSpec(torque_limit=params.torque_limit, friction=params.friction)
        x0 = paper_initial_state(params) if x0 is None else x0
        return cls(dynamics, schedule, costs, x0, constraints, knots=knots, terrain=terrain)

    @classmethod
    def bounding_periodic(cls, durations=PERIODIC_BOUNDING_DURATIONS, periodic_weight: float = 1e5,
                          dynamics: HybridDynamics | None = None, **cost_options) -> HybridProblem:
        """One bounding cycle that must end in the state it started from, up to the forward position x.

        The paper's task starts mid back stance
        ([`hsddp_gym.core.references.paper_initial_state`][hsddp_gym.core.references.paper_initial_state]) and ends at
        the back foot's touchdown, so nothing makes its end state repeatable. Here the cycle is back stance, flight,
        front stance, flight, back stance again (the back foot lands, a switching constraint as every touchdown), and
        the last phase ends where the first began: its terminal cost is ``1/2 (x^- - x0)^T W (x^- - x0)`` with ``W =
        periodic_weight * [0, 1 (z, pitch, 4 joints), 0.1 (7 velocities)]`` (x excluded) in place of the back-stance
        reference. Since the dynamics do not depend on x, a trajectory that meets the condition can be repeated by
        applying the same controls again: its gait is the sequence of the five phases, the last and the first back
        stance forming one back stance of ``T_5 + T_1``. The condition is a stiff quadratic penalty, not an equality;
        its residual is reported by the task ([`hsddp_gym.planners.tasks.run_sto`][hsddp_gym.planners.tasks.run_sto]).

        Args:
            durations: 5 durations [s] (BS, FL, FS, FL, BS); default the paper's 80/72/72/72 ms and a second
                back stance of 40 ms.
            periodic_weight: ``W``'s scale (> 0).
            dynamics: default [`HybridDynamics`][HybridDynamics] (h = 1 ms).
            cost_options: ``speed``, ``running_reference``, ``grf_tracking``, ``z_velocity``, ``weights``,
                ``terminal_half`` of [`bounding`][bounding].
        """
        check_positive(periodic_weight, "periodic_weight")
        durations = np.asarray(durations, dtype=np.float64)
        if durations.shape != (5,):
            raise ValueError(f"durations must be 5 durations [s] (BS, FL, FS, FL, BS), got {durations.tolist()!r}")
        modes = tuple(BOUNDING_CYCLE) + (Mode.BACK_STANCE,)
        schedule = ModeSchedule(modes, durations, final_mode=Mode.BACK_STANCE)
        base = cls.bounding(1, dynamics=dynamics, schedule=schedule, **cost_options)
        x0 = base.x0
        last = base.costs[-1]
        w = np.concatenate([[0.0], np.ones(6), 0.1 * np.ones(7)]) * float(periodic_weight)
        x_final = x0.copy()
        x_final[0] = 0.0
        costs = list(base.costs[:-1]) + [dataclasses.replace(last, x_final=x_final, qf=w)]
        return cls(base.dynamics, schedule, costs, x0, base.constraints, base.restitution)

    def with_durations(self, durations) -> HybridProblem:
        """The time-scaled problem (eq. 28): the same knots per phase, new durations ``(n,)`` [s]."""
        return HybridProblem(self.dynamics, self.schedule.with_durations(durations), self.costs, self.x0,
                             self.constraints, self.restitution, knots=self.knots, terrain=self.terrain)

    def with_x0(self, x0: np.ndarray) -> HybridProblem:
        """The same problem from another initial state (14,)."""
        return HybridProblem(self.dynamics, self.schedule, self.costs, x0, self.constraints, self.restitution,
                             knots=self.knots, terrain=self.terrain)

    def with_constraints(self, constraints: ConstraintSpec) -> HybridProblem:
        """The same problem under other ``constraints`` (a [`ConstraintSpec`][ConstraintSpec], e.g. a friction
        margin)."""
        return HybridProblem(self.dynamics, self.schedule, self.costs, self.x0, constraints, self.restitution,
                             knots=self.knots, terrain=self.terrain)

    def sub_problem(self, start: int, stop: int, x0: np.ndarray | None = None) -> HybridProblem:
        """Phases ``start`` to ``stop - 1`` as a problem of their own: the same dynamics, costs, constraints and
        knots; the mode entered after phase ``stop - 1`` is its final mode, so a touchdown there keeps its switching
        constraint.

        Args:
            start: its first phase, ``0 <= start < stop``.
            stop: one past its last phase, ``stop <= n``.
            x0: its initial state (14,); default this problem's ``x0`` (only when ``start == 0``).
        """
        start = check_int(start, "start", minimum=0)
        stop = check_int(stop, "stop", minimum=1)
        if not start < stop <= self.n_phases:
            raise ValueError(f"start and stop must satisfy 0 <= start < stop <= {self.n_phases} (the phases), "
                             f"got start={start}, stop={stop}")
        if x0 is None:
            if start != 0:
                raise ValueError(f"x0 is required for a sub-problem that starts after phase 0 (start={start})")
            x0 = self.x0
        s = self.schedule
        schedule = ModeSchedule(s.modes[start:stop], s.durations[start:stop], final_mode=s.next_mode(stop - 1))
        return HybridProblem(self.dynamics, schedule, self.costs[start:stop], x0, self.constraints, self.restitution,
                             knots=self.knots[start:stop], terrain=self.terrain)

    @property
    def cycle_length(self) -> int | None:
        """Phases per gait cycle: 4 when the schedule repeats the bounding cycle (back stance, flight, front stance,
        flight, starting anywhere in it; a last cycle may be cut short), else None."""
        modes = self.schedule.modes
        first = tuple(modes[:len(BOUNDING_CYCLE)])
        n = len(BOUNDING_CYCLE)
        rotations = [tuple(BOUNDING_CYCLE[i:] + BOUNDING_CYCLE[:i])[:len(first)] for i in range(n)]
        if first not in rotations or any(m != first[i % n] for i, m in enumerate(modes)):
            return None
        return n

    def knot_time(self, k: int) -> float:
        """Time [s] of knot ``k`` (``0 <= k <= N``; ``k = N`` is the end of the horizon)."""
        k = check_int(k, "k", minimum=0)
        if k > self.n_knots:
            raise ValueError(f"k must be at most N = {self.n_knots}, got {k}")
        i = min(int(np.searchsorted(self.phase_start, k, side="right")) - 1, self.n_phases - 1)
        return float(np.sum(self.schedule.durations[:i]) + (k - self.phase_start[i]) * self.phase_dt[i])

    def describe_knot(self, k: int) -> str:
        """Where knot ``k`` (``0 <= k <= N``) lies, in words for an error message, counting phases and cycles
        from 1: ``"t = 2.722 s, cycle 10 of 10, phase 37 of 40 (back stance)"`` (no cycle when the schedule does
        not repeat the bounding cycle, see [`cycle_length`][cycle_length])."""
        t = self.knot_time(k)
        i = min(int(np.searchsorted(self.phase_start, k, side="right")) - 1, self.n_phases - 1)
        mode = self.schedule.modes[i].name.lower().replace("_", " ")
        parts = [f"t = {t:.3f} s"]
        n = self.cycle_length
        if n is not None:
            parts.append(f"cycle {i // n + 1} of {-(-self.n_phases // n)}")
        parts.append(f"phase {i + 1} of {self.n_phases} ({mode})")
        return ", ".join(parts)

    def cycle_of_knot(self, k: int) -> int | None:
        """The gait cycle (counted from 1) of knot ``k`` (``0 <= k <= N``), or None (see
        [`cycle_length`][cycle_length])."""
        n = self.cycle_length
        if n is None:
            return None
        k = check_int(k, "k", minimum=0)
        i = min(int(np.searchsorted(self.phase_start, k, side="right")) - 1, self.n_phases - 1)
        return i // n + 1


def first_non_finite_knot(X: np.ndarray, U: np.ndarray | None = None) -> int | None:
    """The first knot ``k`` whose state ``X[k]`` (or control ``U[k]``) holds a NaN or an infinity, or None.

    Args:
        X: ``(N+1, 14)`` states. U: optional ``(N, 4)`` controls.
    """
    bad = ~np.all(np.isfinite(np.asarray(X, dtype=np.float64)), axis=1)
    if U is not None:
        bad_u = ~np.all(np.isfinite(np.asarray(U, dtype=np.float64)), axis=1)
        bad[:bad_u.shape[0]] |= bad_u
    hits = np.flatnonzero(bad)
    return int(hits[0]) if hits.size else None
