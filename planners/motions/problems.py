"""HS-DDP motions beyond the bound: a pronk and gait transitions, as planning tasks.

HS-DDP plans any sequence of contact modes with impacts (Li & Wensing, RA-L 2020, Sec. IV); the paper's task is one
gait. Here the same problem, weights and solver (AL on the switching constraints, ReB on torque, normal force and
friction cone) plan four more motions:

* ``"pronk"``: both legs together, double stance / flight repeated
([`plan_pronk`][hsddp_gym.planners.motions.planning.plan_pronk]);
* ``"stand_to_bound"``: from standing at rest in double stance into a few bounding cycles;
* ``"bound_pronk_bound"``: bounding, a pronk, bounding again;
* ``"bound_to_stop"``: bounding, then a landing on both feet and a double stance that ends at rest
  (the three with [`plan_transition`][hsddp_gym.planners.motions.planning.plan_transition]).

Every motion is a list of [`MotionPhase`][MotionPhase] (mode, duration, end-of-phase reference ``x_f (14,)``,
ground-force reference ``(4,)``): [`motion_problem`][motion_problem] turns it into a
[`HybridProblem`][hsddp_gym.planners.optimizer.problem.HybridProblem] with the bound's weights per mode
([`bounding_phase_cost`][hsddp_gym.planners.optimizer.problem.bounding_phase_cost], paper eqs. 32-33, the running
reference equal to the phase's end reference). A flight that ends in double stance lands both feet together: the
switching constraint then has one row per landing foot (``HybridProblem.switch_foot``), both heights ``g = 0`` at the
end of the flight.

References (derived as [`end_of_mode_reference`][hsddp_gym.core.references.end_of_mode_reference] derives the bound's: a
posture that puts the relevant feet on the ground, at the desired speed):

* a pronk stance ends at lift-off with both feet ``v T_s / 2`` behind their hips, a pronk flight at touchdown with
  both feet ``v T_s / 2`` ahead (the neutral point of a stance of duration ``T_s`` at speed ``v``), trunk height
  [`PRONK_HEIGHT`][PRONK_HEIGHT], pitch 0; the vertical velocity of a ballistic flight of duration ``T_f`` between equal
  heights, ``+g T_f / 2`` at lift-off and ``-g T_f / 2`` at touchdown; pitch and joint rates 0;
* the ground-force reference of a pronk stance carries the weight of the whole cycle on the two feet,
  ``m g (T_s + T_f) / (2 T_s)`` per foot; of a double stance at rest ``m g / 2`` per foot;
* bound phases use the bound's references ([`end_of_mode_reference`][hsddp_gym.core.references.end_of_mode_reference])
at the speed of their cycle; the joint angles of every double-stance posture come from inverse kinematics
  ([`leg_posture`][leg_posture]).

The warm start ([`motion_warm_start`][motion_warm_start]) rolls out a heuristic controller through the schedule: bound
phases use the paper's heuristic bounding controller
([`HeuristicBoundingController`][hsddp_gym.planners.policies.heuristic.HeuristicBoundingController]) at their cycle's
speed; a double stance sets ground forces on both feet that carry the weight of its gait's cycle, hold the trunk height,
track its reference speed and pitch (the vertical forces split to make the pitch moment), clipped to the friction cone
(``u = -J^T f``); a flight that lands both feet tracks its touchdown posture with a joint PD and the heuristic's
Raibert-style hip shift.

The double stance that ends the stop weights every velocity in its terminal cost
([`STOP_TERMINAL_WEIGHTS`][STOP_TERMINAL_WEIGHTS]), so the motion ends at rest.

The backflip ([`plan_backflip`][hsddp_gym.planners.motions.planning.plan_backflip]) has its own warm start
(``_FlipWarmStart``: ground forces in the friction cone that build up the take-off's angular momentum, tucked legs in
flight) and keeps, in its running cost, its joints in [`JOINT_LIMITS`][JOINT_LIMITS], its knees and lifted feet off the
ground (``ConstraintSpec.joint_limits``, ``knee_clearance``, ``swing_foot_clearance``; the other motions have none of
these terms).

Joint ranges: the model defines none (``RobotParams`` has no joint limits and the authors' code switches its own
off, original_code_facts §2), so [`JOINT_LIMITS`][JOINT_LIMITS] states the ranges used here; they are checked on every
plan ([`motion_limits`][hsddp_gym.planners.motions.planning.motion_limits]), not enforced by a barrier.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hsddp_gym.core.conventions import BACK, FOOT_JOINTS, FRONT, IPITCH, IVX, IVZ, IZ, NGRF, NQ, NU, NX, Mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.params import RobotParams
from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.core.rollout import Trajectory, rollout
from hsddp_gym.core.schedule import BOUNDING_CYCLE, PAPER_BOUNDING_DURATIONS, ModeSchedule
from hsddp_gym.core.task_constants import (
    BOX_HEIGHT,
    GAP_WIDTH,
    JUMPS,
    PRONK_DURATIONS,
    PRONK_HEIGHT,
    SPEED_RANGE,
    STAND_DURATION,
    STAND_HEIGHT,
    STOP_DURATION,
    TRANSITIONS,
    check_speed,
    jump_terrain,
)
from hsddp_gym.core.terrain import Terrain, check_terrain
from hsddp_gym.planners.optimizer.problem import ConstraintSpec, HybridProblem, bounding_phase_cost
from hsddp_gym.planners.optimizer.solution import SolverOptions
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController, HeuristicGains
from hsddp_gym.planners.tasks import check_warm_start
from hsddp_gym.util.validation import check_array, check_int

MOTIONS = ("pronk", *TRANSITIONS, *JUMPS, "backflip")
"""The motions of this module (``experiments/motions.py --motion``)."""

STOP_TERMINAL_WEIGHTS = 100.0 * np.array([0, 20, 8, 3, 3, 3, 3, 10, 10, 10, 5, 5, 5, 5], dtype=float)
"""``Q_f (14,)`` of the double stance that ends the stop: the bound's position and posture weights, and every velocity
weighted as the bound weights the forward speed (trunk) and a swing leg's joint rates (joints), so it ends at rest."""

JOINT_LIMITS = ((-0.6, 2.0), (-2.7, -0.3))
"""``((hip_min, hip_max), (knee_min, knee_max))`` [rad], both legs, in the conventions' signs (positive hip swings
the thigh backward, knees negative: they point backward). Chosen here, the model has none: the knee never straight or
bent forward (<= -0.3 rad, 17 deg short of straight) nor folded onto the thigh (>= -2.7 rad, 25 deg from it); the
thigh between 34 deg forward and 115 deg backward of the trunk's vertical. The bound's reference postures
(0.63-1.10 rad hips, -2.36 to -1.51 rad knees) and the paper's initial state (knee -2.20 rad) lie inside."""

JUMP_FLIGHT = 0.25
"""The jump: the flight after the take-off back stance [s] (the bound's: 0.072 s)."""
JUMP_SPEED_FACTOR = 1.3
"""The jump's cycle (take-off back stance, jump flight, front stance, flight) has the references of a bound this many
times faster (a longer jump)."""
LANDING_MARGIN = 0.05
"""Foot placement references around a jump's edges [m]: the last landings before it ``margin`` (front foot) and
``2 margin`` (back foot) short of the near edge, the first after it ``2 margin`` (front) and ``margin`` (back)
beyond the far edge."""
PLACEMENT_WEIGHT = 2.0e4
"""``Q_f`` weight on the trunk's x of a foot placement reference [1/m^2] (the bound's weight on the height)."""

BACKFLIP_DURATIONS = (0.25, 0.10, 0.40, 0.30)
"""The backflip's push (double stance), take-off (back stance), flight and landing (double stance) [s]."""
BACKFLIP_PITCH = (-0.7, -1.5)
"""The backflip's pitch references at the end of the push and at take-off [rad] (negative: nose-up)."""
BACKFLIP_PITCH_RATE = (-8.0, -12.0)
"""The backflip's pitch-rate references at the end of the push and at take-off [rad/s]."""
BACKFLIP_MOMENTUM = (-1.2, -3.0)
"""The backflip's warm start: the angular momentum about the centre of mass it builds up by the end of the push and
at take-off [N m s] (negative: nose-up; 3 N m s turns the tucked robot, about 0.24 kg m^2, at about 12 rad/s)."""
BACKFLIP_PUSH_VZ = 0.3
"""The backflip's warm start: the vertical speed of the centre of mass it reaches by the end of the push [m/s] (at
take-off: ``g T_f / 2``)."""
BACKFLIP_TUCK = (0.3 * math.pi, -2.5)
"""The backflip's warm start: the tucked leg ``(hip, knee)`` [rad] of the lifted front leg and of both legs over the
first 60 % of the flight."""
BACKFLIP_KNEE_CLEARANCE = 0.04
"""The backflip keeps its knees this high above the ground [m] (``ConstraintSpec.knee_clearance``: the trunk pitched
nose-up puts the back hip low, and a knee is no foot); its limits check the knees above the ground
([`motion_limits`][hsddp_gym.planners.motions.planning.motion_limits])."""
BACKFLIP_FOOT_CLEARANCE = 0.01
"""The backflip keeps the feet of its lifted legs this high above the ground [m] (``swing_foot_clearance``: the back
foot swings down as the trunk turns after take-off); its limits check them above ``-sqrt(SWITCHING_TOLERANCE)``
([`motion_limits`][hsddp_gym.planners.motions.planning.motion_limits], the landings' tolerance)."""
BACKFLIP_OPTIONS = SolverOptions(max_al_iterations=8, max_ddp_iterations=30)
"""The backflip's solver options: AL + ReB, up to 30 DDP iterations per AL iteration (the default 10 stop short of
the turn-over, the plan then ends at about -4 rad)."""

SWITCHING_TOLERANCE = 1e-4
"""The paper's stop rule on the switching constraints, ``sum g^2 <= 1e-4`` [m^2] (``SolverOptions.al_tolerance``)."""

_FLIGHT_KP = np.array([40.0, 20.0, 60.0, 50.0])
_FLIGHT_KD = np.ones(NU)
_RAIBERT = 0.2
_KZ, _DZ = 3000.0, 60.0  # the warm start's double stance: trunk height spring [N/m] and damper [N s/m]
_KV = 5.0  # speed feedback [1/s]
_KPITCH, _DPITCH = 400.0, 40.0  # pitch PD [1/s^2], [1/s]
_FLIP_KL, _FLIP_KV = 30.0, 15.0  # the flip's push: angular momentum [1/s] and vertical / forward speed [1/s] feedback
_FLIP_KP, _FLIP_KD = 60.0, 2.0  # the flip's leg PD [N m/rad], [N m s/rad]
_FLIP_WEIGHTS = (0.1, 1.0, 10.0)  # the flip's push: weights of the (f_x, f_z, moment) rows, single stance
_FLIP_TUCK_FRACTION = 0.6  # the flip's flight: tucked legs over this fraction, then the touchdown posture


@dataclasses.dataclass(frozen=True)
class MotionPhase:
    """One phase of a motion.

    Attributes:
        mode: its contact mode.
        duration: [s].
        x_final: ``(14,)`` the reference state at its end (also its running reference).
        grf_ref: ``(4,)`` the ground-force reference during it [N] (``[f_front_x, f_front_z, f_back_x, f_back_z]``).
        support: the factor on the weight the stance legs carry on average, ``T_cycle / T_stance`` of its gait
            (the warm start's feed-forward; 1 for a double stance at rest).
        gait: ``"bound"``, ``"pronk"`` or ``"stand"`` (what the phase belongs to, for reports).
        qf: ``(14,)`` terminal weights replacing the mode's (None: the bound's ``Q_f`` of the mode).
    """

    mode: Mode
    duration: float
    x_final: np.ndarray
    grf_ref: np.ndarray
    support: float
    gait: str
    qf: np.ndarray | None = None


# --------------------------------------------------------------------------------------------------- postures
def leg_posture(height: float, pitch: float, foot_dx, params: RobotParams | None = None) -> np.ndarray:
    """The configuration ``q (7,)`` with the trunk at ``height`` [m] and ``pitch`` [rad], both feet on the ground
    ``foot_dx = (front, back)`` [m] ahead of their hips (negative: behind), knees bent backward, ``x = 0``.

    The joint angles by Newton's method on the feet's positions from a bound posture (hips 0.3 pi, knees -0.6 pi).

    Raises:
        ValueError: a foot out of the leg's reach.
    """
    params = params if params is not None else RobotParams()
    robot = _robot(params)
    dx = check_array(foot_dx, (2,), "foot_dx")
    q = np.array([0.0, float(height), float(pitch), 0.3 * math.pi, -0.6 * math.pi, 0.3 * math.pi, -0.6 * math.pi])
    hips = robot.hip_positions(q)
    target = np.array([[hips[f][0] + dx[f], 0.0] for f in (FRONT, BACK)])
    try:
        q = robot.place_feet(q, target)
    except (ValueError, np.linalg.LinAlgError):
        raise ValueError(f"no posture with the trunk at height={height!r} m, pitch={pitch!r} rad and the feet "
                         f"foot_dx={dx.tolist()} m from the hips: out of the legs' reach") from None
    if not np.all(np.isfinite(q)) or np.max(np.abs(target - robot.foot_positions(q))) > 1e-9:
        raise ValueError(f"no posture with the trunk at height={height!r} m and the feet foot_dx={dx.tolist()} m")
    return q


_ROBOTS: dict = {}


def _robot(params: RobotParams):
    from hsddp_gym.core.model import CheetahModel

    if params not in _ROBOTS:
        _ROBOTS[params] = CheetahModel(params)
    return _ROBOTS[params]


def double_stance_state(q: np.ndarray, speed: float = 0.0, params: RobotParams | None = None) -> np.ndarray:
    """A consistent double-stance state ``x (14,)``: configuration ``q (7,)`` (both feet on the ground), the trunk
    moving forward at ``speed`` [m/s] without vertical or pitch motion, and the joint rates that keep both feet at
    rest (``J_c v = 0``)."""
    robot = _robot(params if params is not None else RobotParams())
    q = check_array(q, (NQ,), "q")
    v = np.zeros(NQ)
    v[0] = float(speed)
    J = np.vstack([robot.foot_jacobian(q, f) for f in (FRONT, BACK)])  # (4, 7)
    v[3:] = np.linalg.solve(J[:, 3:], -J[:, :3] @ v[:3])
    return np.concatenate([q, v])


def pronk_reference(event: str, speed: float, durations=PRONK_DURATIONS, height: float = PRONK_HEIGHT,
                    params: RobotParams | None = None) -> np.ndarray:
    """The pronk's reference state ``x (14,)`` at ``event`` ``"liftoff"`` (end of a double stance) or
    ``"touchdown"`` (end of a flight), see the module docstring.

    Args:
        speed: forward speed [m/s]. durations: ``(T_s, T_f)`` stance and flight [s]. height: trunk height [m].
    """
    params = params if params is not None else RobotParams()
    if event not in ("liftoff", "touchdown"):
        raise ValueError(f"event must be 'liftoff' or 'touchdown', got {event!r}")
    t_s, t_f = _durations(durations)
    d = speed * t_s / 2.0
    sign = -1.0 if event == "liftoff" else 1.0
    x = np.zeros(NX)
    x[:NQ] = leg_posture(height, 0.0, (sign * d, sign * d), params)
    x[IVX] = speed
    x[IVZ] = -sign * params.gravity * t_f / 2.0
    return x


def stand_reference(params: RobotParams | None = None, height: float = STAND_HEIGHT) -> np.ndarray:
    """Standing at rest ``x (14,)``: feet under the hips, pitch 0, every velocity 0."""
    x = np.zeros(NX)
    x[:NQ] = leg_posture(height, 0.0, (0.0, 0.0), params)
    return x


def _durations(durations) -> tuple[float, float]:
    try:
        d = np.asarray(durations, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"durations must be two numbers (double stance, flight) [s], got {durations!r}") from None
    if d.shape != (2,) or not np.all(np.isfinite(d)) or np.any(d < 0.02) or np.any(d > 0.5):
        raise ValueError(f"durations must be two numbers (double stance, flight) in [0.02, 0.5] s, got {durations!r}")
    return float(d[0]), float(d[1])


# --------------------------------------------------------------------------------------------------- phases
def _weight(params: RobotParams) -> float:
    return params.total_mass * params.gravity


def _double_grf(params: RobotParams, support: float) -> np.ndarray:
    y = np.zeros(NGRF)
    y[[1, 3]] = _weight(params) * support / 2.0
    return y


def pronk_phases(cycles: int, speed: float, durations=PRONK_DURATIONS, params: RobotParams | None = None,
                 first_stance: float | None = None) -> list[MotionPhase]:
    """``cycles`` pronk cycles (double stance, flight); the first stance lasts ``first_stance`` [s] (default
    ``T_s``)."""
    params = params if params is not None else RobotParams()
    t_s, t_f = _durations(durations)
    support = (t_s + t_f) / t_s
    lift = pronk_reference("liftoff", speed, (t_s, t_f), params=params)
    land = pronk_reference("touchdown", speed, (t_s, t_f), params=params)
    phases = []
    for c in range(cycles):
        ts = t_s if (c > 0 or first_stance is None) else first_stance
        phases.append(MotionPhase(Mode.DOUBLE_STANCE, ts, lift, _double_grf(params, support), support, "pronk"))
        phases.append(MotionPhase(Mode.FLIGHT, t_f, land, np.zeros(NGRF), support, "pronk"))
    return phases


def bound_phases(speeds, params: RobotParams | None = None, durations=PAPER_BOUNDING_DURATIONS,
                 last_lands_both: bool = False) -> list[MotionPhase]:
    """Bounding cycles (back stance, flight, front stance, flight), one per entry of ``speeds`` [m/s], with the
    bound's references ([`end_of_mode_reference`][hsddp_gym.core.references.end_of_mode_reference]) and ground-force
    references; with ``last_lands_both`` the last flight lands both feet (its reference: the pronk's touchdown
    posture)."""
    params = params if params is not None else RobotParams()
    d = tuple(float(t) for t in durations)
    support = sum(d) / (d[0] + d[2])
    phases = []
    for c, v in enumerate(speeds):
        for j, (mode, foot) in enumerate(zip(BOUNDING_CYCLE, (None, FRONT, None, BACK))):
            cost = bounding_phase_cost(mode, foot, v, params)
            x_f = cost.x_final
            if last_lands_both and c == len(speeds) - 1 and j == 3:
                x_f = pronk_reference("touchdown", v, (PRONK_DURATIONS[0], d[3]), params=params)
            phases.append(MotionPhase(mode, d[j], x_f, cost.grf_ref, support, "bound"))
    return phases


def motion_problem(phases: list[MotionPhase], x0: np.ndarray, final_mode: Mode,
                   dynamics: HybridDynamics | None = None, terrain: Terrain | None = None,
                   joint_limits=None, knee_clearance: float | None = None,
                   swing_foot_clearance: float | None = None) -> HybridProblem:
    """The hybrid problem of a motion: one phase per [`MotionPhase`][MotionPhase], the bound's weights per mode
    ([`bounding_phase_cost`][hsddp_gym.planners.optimizer.problem.bounding_phase_cost]: ``Q``, ``R``, ``S``, ``Q_f``)
    with the phase's references (running = end reference), the robot's torque limit and friction, ``x0 (14,)``,
    ``final_mode`` the mode entered after the last phase (a touchdown there keeps its switching constraint); ``terrain``
    the ground under the feet ([`Terrain`][hsddp_gym.core.terrain.Terrain], None: flat), whose height under a landing
    foot its switching constraint measures from (``g = foot_z - h(foot_x)``); ``joint_limits`` None (no joint-range
    term, the bound's problem) or the ranges of ``ConstraintSpec.joint_limits`` (e.g. [`JOINT_LIMITS`][JOINT_LIMITS]),
    penalized in the running cost; ``knee_clearance`` and ``swing_foot_clearance`` None (unconstrained) or the heights
    [m] the knees and the feet of the legs not in stance are kept above (``ConstraintSpec``, penalized in the running
    cost)."""
    dynamics = dynamics if dynamics is not None else HybridDynamics()
    params = dynamics.robot.params
    schedule = ModeSchedule([p.mode for p in phases], [p.duration for p in phases], final_mode=final_mode)
    costs = []
    for p in phases:
        foot = FRONT if p.mode in (Mode.FLIGHT, Mode.DOUBLE_STANCE) else None  # weights only; references below
        base = bounding_phase_cost(p.mode, foot, float(p.x_final[IVX]), params)
        qf = base.qf if p.qf is None else check_array(p.qf, (NX,), "MotionPhase.qf").copy()
        costs.append(dataclasses.replace(base, x_ref=p.x_final.copy(), x_final=p.x_final.copy(),
                                         grf_ref=np.asarray(p.grf_ref, dtype=np.float64).copy(), qf=qf))
    constraints = ConstraintSpec(torque_limit=params.torque_limit, friction=params.friction, joint_limits=joint_limits,
                                 knee_clearance=knee_clearance, swing_foot_clearance=swing_foot_clearance)
    return HybridProblem(dynamics, schedule, costs, x0, constraints, terrain=check_terrain(terrain))


# --------------------------------------------------------------------------------------------------- problems
def pronk_problem(cycles: int = 4, speed: float = 1.0, durations=PRONK_DURATIONS,
                  dynamics: HybridDynamics | None = None) -> tuple[HybridProblem, list[MotionPhase]]:
    """The pronk: ``cycles`` cycles of double stance and flight at ``speed`` [m/s], from mid stance (feet under the
    hips, moving at ``speed``; the first stance lasts ``T_s / 2``), ending with the last flight's touchdown on both
    feet. Returns the problem and its phases."""
    cycles = check_int(cycles, "cycles", minimum=1)
    speed = check_speed(speed)
    t_s, t_f = _durations(durations)
    dynamics = dynamics if dynamics is not None else HybridDynamics()
    params = dynamics.robot.params
    phases = pronk_phases(cycles, speed, (t_s, t_f), params, first_stance=t_s / 2.0)
    x0 = double_stance_state(leg_posture(PRONK_HEIGHT, 0.0, (0.0, 0.0), params), speed, params)
    return motion_problem(phases, x0, Mode.DOUBLE_STANCE, dynamics), phases


def _ramp(start: float, stop: float, n: int) -> list[float]:
    return [float(v) for v in np.linspace(start, stop, n + 1)[1:]] if n > 0 else []


def transition_problem(motion: str, speed: float = 1.0, cycles: int = 2, dynamics: HybridDynamics | None = None
                       ) -> tuple[HybridProblem, list[MotionPhase]]:
    """The problem of a gait transition (see [`plan_transition`][hsddp_gym.planners.motions.planning.plan_transition]
    for the schedules). Returns the problem and its phases."""
    if motion not in TRANSITIONS:
        raise ValueError(f"motion must be one of {TRANSITIONS}, got {motion!r}")
    speed = check_speed(speed)
    cycles = check_int(cycles, "cycles", minimum=1)
    dynamics = dynamics if dynamics is not None else HybridDynamics()
    params = dynamics.robot.params
    if motion == "stand_to_bound":
        # from rest: a double stance that accelerates and pitches nose-up, the front foot lifts off into back stance
        v0 = 0.4 * speed
        q_end = leg_posture(STAND_HEIGHT, -math.pi / 25, (-0.03, 0.03), params)
        x_end = double_stance_state(q_end, v0, params)
        phases = [MotionPhase(Mode.DOUBLE_STANCE, STAND_DURATION, x_end, _double_grf(params, 1.0), 1.0, "stand")]
        phases += bound_phases(_ramp(v0, speed, min(cycles, 2)) + [speed] * max(cycles - 2, 0), params)
        return motion_problem(phases, stand_reference(params), Mode.BACK_STANCE, dynamics), phases
    if motion == "bound_pronk_bound":
        t_s, t_f = PRONK_DURATIONS
        phases = bound_phases([speed] * cycles, params, last_lands_both=True)
        phases += pronk_phases(cycles, speed, params=params)
        # the last pronk flight lands both feet; half a pronk stance, then the front foot lifts off into back stance
        lift = pronk_reference("liftoff", speed, params=params)
        q = leg_posture(PRONK_HEIGHT, -math.pi / 25, (-speed * t_s / 2.0, 0.0), params)
        x_lift = lift.copy()
        x_lift[:NQ] = q
        x_lift[IVZ] = 0.0
        phases.append(MotionPhase(Mode.DOUBLE_STANCE, t_s / 2.0, x_lift, _double_grf(params, (t_s + t_f) / t_s),
                                  (t_s + t_f) / t_s, "pronk"))
        phases += bound_phases([speed] * cycles, params)
        return motion_problem(phases, paper_initial_state(params), Mode.BACK_STANCE, dynamics), phases
    # bound_to_stop: slow down over the cycles, land both feet, come to rest in double stance
    speeds = [speed] + _ramp(speed, 0.4 * speed, cycles - 1) if cycles > 1 else [0.7 * speed]
    phases = bound_phases(speeds, params, last_lands_both=True)
    rest = stand_reference(params)
    phases.append(MotionPhase(Mode.DOUBLE_STANCE, STOP_DURATION, rest, _double_grf(params, 1.0), 1.0, "stand",
                              qf=STOP_TERMINAL_WEIGHTS))
    return motion_problem(phases, paper_initial_state(params), Mode.DOUBLE_STANCE, dynamics), phases


# --------------------------------------------------------------------------------------------------- jumps
def _foot_offset(x_ref: np.ndarray, foot: int, params: RobotParams) -> float:
    """World x of ``foot`` relative to the trunk origin in the reference posture ``x_ref (14,)`` [m]."""
    q = np.array(x_ref[:NQ], dtype=float)
    q[0] = 0.0
    return float(_robot(params).foot_positions(q)[foot, 0])


def _placed(phase: MotionPhase, foot: int, foot_x: float, params: RobotParams, dz: float = 0.0) -> MotionPhase:
    """``phase`` whose end reference puts ``foot`` (the one landing at its end) at world ``foot_x`` [m] (the trunk's
    x reference, weighted [`PLACEMENT_WEIGHT`][PLACEMENT_WEIGHT] in ``Q_f``) and the trunk ``dz`` [m] higher."""
    x_f = phase.x_final.copy()
    x_f[0] = foot_x - _foot_offset(x_f, foot, params)
    x_f[IZ] += dz
    base = bounding_phase_cost(phase.mode, foot, 1.0, params).qf if phase.qf is None else phase.qf
    qf = np.array(base, dtype=float)
    qf[0] = PLACEMENT_WEIGHT
    return dataclasses.replace(phase, x_final=x_f, qf=qf)


def _raised(phase: MotionPhase, dz: float) -> MotionPhase:
    x_f = phase.x_final.copy()
    x_f[IZ] += dz
    return dataclasses.replace(phase, x_final=x_f)


def jump_problem(motion: str, speed: float = 1.0, cycles: int = 2, dynamics: HybridDynamics | None = None
                 ) -> tuple[HybridProblem, list[MotionPhase]]:
    """The problem of a jump (see [`plan_jump`][hsddp_gym.planners.motions.planning.plan_jump] for the schedules,
    references and terrain). Returns the problem and its phases; the terrain is ``problem.terrain``."""
    if motion not in JUMPS:
        raise ValueError(f"motion must be one of {JUMPS}, got {motion!r}")
    speed = check_speed(speed)
    cycles = check_int(cycles, "cycles", minimum=1)
    dynamics = dynamics if dynamics is not None else HybridDynamics()
    params = dynamics.robot.params
    terrain = jump_terrain(motion, speed, cycles)
    d = PAPER_BOUNDING_DURATIONS
    before = bound_phases([speed] * cycles, params)
    jump = bound_phases([JUMP_SPEED_FACTOR * speed], params, durations=(d[0], JUMP_FLIGHT, d[2], d[3]))
    after = bound_phases([speed] * cycles, params)
    if motion == "gap_jump":
        near, far = terrain.edges
        dz = 0.0
    else:
        near = far = terrain.edges[0]
        dz = BOX_HEIGHT
    m = LANDING_MARGIN
    # the last landings before the jump short of the near edge, the first after it beyond the far edge
    before[-3] = _placed(before[-3], FRONT, near - m, params)
    before[-1] = _placed(before[-1], BACK, near - 2 * m, params)
    jump[1] = _placed(jump[1], FRONT, far + 2 * m, params, dz)
    jump[2] = _raised(jump[2], dz)
    jump[3] = _placed(jump[3], BACK, far + m, params, dz)
    after = [_raised(p, dz) for p in after]
    phases = before + jump + after
    return motion_problem(phases, paper_initial_state(params), Mode.BACK_STANCE, dynamics, terrain), phases


def _back_stance_posture(height: float, pitch: float, params: RobotParams) -> np.ndarray:
    """``q (7,)``: the trunk at ``height`` [m] and ``pitch`` [rad], the back foot on the ground under its hip (Newton
    on the back leg), the front leg at the bound's angles relative to the world vertical (folded)."""
    robot = _robot(params)
    q = np.array([0.0, float(height), float(pitch), 0.3 * math.pi - pitch, -0.6 * math.pi, 0.3 * math.pi - pitch,
                  -0.6 * math.pi])
    joints = list(FOOT_JOINTS[BACK])
    for _ in range(50):
        err = np.array([robot.hip_positions(q)[BACK][0], 0.0]) - robot.foot_positions(q)[BACK]
        if np.max(np.abs(err)) < 1e-12:
            break
        q[joints] += np.linalg.solve(robot.foot_jacobian(q, BACK)[:, joints], err)
    return q


def backflip_problem(dynamics: HybridDynamics | None = None) -> tuple[HybridProblem, list[MotionPhase]]:
    """The backflip's problem (see [`plan_backflip`][hsddp_gym.planners.motions.planning.plan_backflip]). Returns the
    problem and its phases."""
    dynamics = dynamics if dynamics is not None else HybridDynamics()
    params = dynamics.robot.params
    t_ds, t_bs, t_fl, t_land = BACKFLIP_DURATIONS
    x_push = double_stance_state(leg_posture(0.22, BACKFLIP_PITCH[0], (0.0, 0.0), params), 0.0, params)
    x_push[IVZ], x_push[NQ + IPITCH] = 0.5, BACKFLIP_PITCH_RATE[0]
    x_off = np.zeros(NX)
    x_off[:NQ] = _back_stance_posture(0.33, BACKFLIP_PITCH[1], params)
    x_off[IVZ], x_off[NQ + IPITCH] = params.gravity * t_fl / 2.0, BACKFLIP_PITCH_RATE[1]
    x_land = double_stance_state(leg_posture(STAND_HEIGHT, 0.0, (0.0, 0.0), params), 0.0, params)
    x_land[IPITCH] -= 2.0 * math.pi
    x_land[IVZ] = -params.gravity * t_fl / 2.0
    x_rest = stand_reference(params)
    x_rest[IPITCH] -= 2.0 * math.pi
    grf_off = np.zeros(NGRF)
    grf_off[3] = _weight(params) * (t_bs + t_fl) / t_bs
    phases = [MotionPhase(Mode.DOUBLE_STANCE, t_ds, x_push, _double_grf(params, 1.5), 1.5, "flip"),
              MotionPhase(Mode.BACK_STANCE, t_bs, x_off, grf_off, (t_bs + t_fl) / t_bs, "flip"),
              MotionPhase(Mode.FLIGHT, t_fl, x_land, np.zeros(NGRF), 1.0, "flip"),
              MotionPhase(Mode.DOUBLE_STANCE, t_land, x_rest, _double_grf(params, 1.0), 1.0, "stand",
                          qf=STOP_TERMINAL_WEIGHTS)]
    return motion_problem(phases, stand_reference(params), Mode.DOUBLE_STANCE, dynamics,
                          joint_limits=JOINT_LIMITS, knee_clearance=BACKFLIP_KNEE_CLEARANCE,
                          swing_foot_clearance=BACKFLIP_FOOT_CLEARANCE), phases


# --------------------------------------------------------------------------------------------------- warm start
def motion_warm_start(problem: HybridProblem, phases: list[MotionPhase]) -> Trajectory:
    """Roll out the heuristic controller of the module docstring through ``problem``'s schedule (a flip's phases,
    ``MotionPhase.gait == "flip"``, and the landing after them: the flip's controller, ``_FlipWarmStart``).

    Returns:
        A [`Trajectory`][hsddp_gym.core.rollout.Trajectory] (``X (N+1, 14)``, ``U (N, 4)``, ...).
    Raises:
        WarmStartDivergedError: the rollout is not finite (naming the phase, knot and time).
    """
    robot = problem.dynamics.robot
    cache: dict = {}
    flip = _FlipWarmStart(problem, phases) if any(p.gait == "flip" for p in phases) else None

    def heuristic(p: MotionPhase) -> HeuristicBoundingController:
        speed = float(p.x_final[IVX])
        if speed not in cache:  # the paper's warm start (heuristic_warm_start) at this cycle's speed
            cache[speed] = HeuristicBoundingController(robot, HeuristicGains(speed=speed))
        return cache[speed]

    def controller(x, mode, phase, k):
        p = phases[phase]
        if flip is not None:
            return flip(x, mode, phase, k)
        if mode == Mode.DOUBLE_STANCE:
            return _double_stance_torque(robot, x, p)
        if mode == Mode.FLIGHT and len(problem.schedule.touchdown_feet(phase)) == 1:
            return heuristic(p).torque(x, mode, problem.schedule.touchdown_feet(phase)[0])
        if mode == Mode.FLIGHT:
            target = p.x_final[3:NQ].copy()
            shift = _RAIBERT * (x[IVX] - p.x_final[IVX])
            target[[0, 2]] -= shift
            return _FLIGHT_KP * (target - x[3:NQ]) - _FLIGHT_KD * x[NQ + 3:]
        return heuristic(p).torque(x, mode)

    traj = rollout(problem.dynamics, problem.schedule, problem.x0, controller=controller,
                   restitution=problem.restitution)
    return check_warm_start(problem, traj, "the motion's heuristic warm start")


def _double_stance_torque(robot, x: np.ndarray, p: MotionPhase) -> np.ndarray:
    """The warm start's double stance: the ground forces ``(f_x, f_z)`` of both feet that give the trunk a desired
    vertical force (weight support ``p.support`` and a height spring-damper), horizontal force (speed feedback to
    ``p``'s reference speed) and pitch moment (PD to its reference pitch), the horizontal force shared equally and the
    vertical forces splitting the moment; clipped to ``f_z >= 0`` and the friction cone; ``u = -J^T f`` per leg."""
    params = robot.params
    q = x[:NQ]
    m = params.total_mass
    inertia = params.trunk.inertia_yy + 2 * (params.thigh.mass + params.shank.mass) * params.hip_offset ** 2
    fz_total = m * params.gravity * p.support + _KZ * (float(p.x_final[IZ]) - q[IZ]) - _DZ * x[IVZ]
    fx_total = m * _KV * (float(p.x_final[IVX]) - x[IVX])
    pitch_ref = float(p.x_final[IPITCH])
    turns = round((q[IPITCH] - pitch_ref) / (2.0 * math.pi))
    if turns != 0:  # the reference posture a whole turn away (a flip's landing): the nearest one
        pitch_ref += 2.0 * math.pi * turns
    moment = inertia * (-_KPITCH * (q[IPITCH] - pitch_ref) - _DPITCH * x[NQ + IPITCH])
    r = robot.foot_positions(q) - q[[0, IZ]]  # (2, 2) feet relative to the trunk origin
    # sum fz = fz_total; sum (r_z f_x - r_x f_z) = moment (about +y, positive nose-down)
    A = np.array([[1.0, 1.0], [-r[FRONT, 0], -r[BACK, 0]]])
    b = np.array([fz_total, moment - (r[FRONT, 1] + r[BACK, 1]) * fx_total / 2.0])
    fz = np.linalg.solve(A, b) if abs(np.linalg.det(A)) > 1e-6 else np.full(2, fz_total / 2.0)
    u = np.zeros(NU)
    for foot in (FRONT, BACK):
        f_z = max(float(fz[foot]), 0.0)
        f_x = float(np.clip(fx_total / 2.0, -params.friction * f_z, params.friction * f_z))
        joints = list(FOOT_JOINTS[foot])
        J = robot.foot_jacobian(q, foot)[:, joints]
        u[[j - 3 for j in joints]] = -(J.T @ np.array([f_x, f_z]))
    return u


def _nonnegative_least_squares(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``argmin |A z - b|`` over ``z >= 0`` for a few columns (``A (m, n)``, n <= 4): the best of the least-squares
    solutions on every subset of the columns that is nonnegative (exact for so few unknowns)."""
    n = A.shape[1]
    best, z_best = np.inf, np.zeros(n)
    for mask in range(1, 2 ** n):
        cols = [i for i in range(n) if mask >> i & 1]
        sol = np.linalg.lstsq(A[:, cols], b, rcond=None)[0]
        if np.any(sol < 0.0):
            continue
        z = np.zeros(n)
        z[cols] = sol
        r = float(np.sum((A @ z - b) ** 2))
        if r < best:
            best, z_best = r, z
    return z_best


class _FlipWarmStart:
    """The warm start of a flip (``MotionPhase.gait == "flip"`` phases: a push in double stance, a take-off back
    stance, a flight; then the landing's double stance).

    * Push and take-off: the ground forces of the stance feet, nonnegative combinations of the friction cone's edges
      (``f_z >= 0``, ``|f_x| <= mu f_z`` by construction), that best give the centre of mass the vertical force of a
      vertical speed ramped from 0 to [`BACKFLIP_PUSH_VZ`][BACKFLIP_PUSH_VZ] over the push and on to ``g T_f / 2`` at
      take-off, no forward speed, and the moment about it of an angular momentum ramped (quadratically) to
      [`BACKFLIP_MOMENTUM`][BACKFLIP_MOMENTUM] ``[0]`` over the push and (linearly) to ``[1]`` at take-off, each with
      feed-forward and feedback; ``u = -J^T f`` per stance leg; the lifted front leg tucks
      ([`BACKFLIP_TUCK`][BACKFLIP_TUCK], joint PD).
    * Flight: both legs tucked, then (after ``_FLIP_TUCK_FRACTION`` of it) the touchdown posture (joint PD).
    * Landing: the double stance's ground-force controller ([`_double_stance_torque`][_double_stance_torque]), pitch to
    the nearest whole turn.

    Every torque clipped to the torque limit.
    """

    def __init__(self, problem: HybridProblem, phases: list[MotionPhase]) -> None:
        import pinocchio as pin

        self._pin = pin
        self.robot = problem.dynamics.robot
        self.params = self.robot.params
        self.data = self.robot.model.createData()
        self.phases = phases
        self.dt = problem.dt
        d = problem.schedule.durations
        self.start = np.concatenate([[0.0], np.cumsum(d)])
        flips = [i for i, p in enumerate(phases) if p.gait == "flip"]
        if len(flips) != 3 or [phases[i].mode for i in flips] != [Mode.DOUBLE_STANCE, Mode.BACK_STANCE, Mode.FLIGHT]:
            raise ValueError("a flip's phases must be a double stance, a back stance and a flight")
        self.push, self.takeoff, self.flight = flips
        self.vz_off = self.params.gravity * float(d[self.flight]) / 2.0

    def centroid(self, x: np.ndarray) -> tuple[np.ndarray, float, float, float]:
        """Centre of mass ``(x, z)`` [m], its velocity ``vx, vz`` [m/s] and the angular momentum about it [N m s]."""
        pin, model, data = self._pin, self.robot.model, self.data
        q, v = x[:NQ], x[NQ:]
        pin.ccrba(model, data, q, v)
        h = data.Ag @ v
        m = self.params.total_mass
        return pin.centerOfMass(model, data, q)[[0, 2]], h[0] / m, h[2] / m, h[4]

    def stance(self, x: np.ndarray, t: float, feet: tuple) -> np.ndarray:
        c, vx, vz, momentum = self.centroid(x)
        t0, t1, t2 = self.start[self.push], self.start[self.takeoff], self.start[self.takeoff + 1]
        (l1, l2), v1 = BACKFLIP_MOMENTUM, BACKFLIP_PUSH_VZ
        if t < t1:
            s = (t - t0) / (t1 - t0)
            vz_ref, az = v1 * s, v1 / (t1 - t0)
            l_ref, dl = l1 * s * s, 2.0 * l1 * s / (t1 - t0)
        else:
            s = min((t - t1) / (t2 - t1), 1.0)
            vz_ref, az = v1 + (self.vz_off - v1) * s, (self.vz_off - v1) / (t2 - t1)
            l_ref, dl = l1 + (l2 - l1) * s, (l2 - l1) / (t2 - t1)
        m, mu = self.params.total_mass, self.params.friction
        target = np.array([-m * _FLIP_KV * vx, m * (self.params.gravity + az + _FLIP_KV * (vz_ref - vz)),
                           dl + _FLIP_KL * (l_ref - momentum)])
        q = x[:NQ]
        feet_xz = self.robot.foot_positions(q)
        cols = []  # per foot, the cone's edges (mu, 1) and (-mu, 1): force and moment about the centre of mass
        for foot in feet:
            r = feet_xz[foot] - c
            cols += [[e, 1.0, r[1] * e - r[0]] for e in (mu, -mu)]
        w = np.array(_FLIP_WEIGHTS if len(feet) == 1 else (1.0,) + _FLIP_WEIGHTS[1:])
        z = _nonnegative_least_squares(w[:, None] * np.array(cols).T, w * target)
        u = np.zeros(NU)
        for i, foot in enumerate(feet):
            f = np.array([mu * (z[2 * i] - z[2 * i + 1]), z[2 * i] + z[2 * i + 1]])
            joints = list(FOOT_JOINTS[foot])
            u[[j - 3 for j in joints]] = -(self.robot.foot_jacobian(q, foot)[:, joints].T @ f)
        return u

    def __call__(self, x: np.ndarray, mode: Mode, phase: int, k: int) -> np.ndarray:
        t = k * self.dt
        tuck = np.array(BACKFLIP_TUCK)
        if phase in (self.push, self.takeoff):
            u = self.stance(x, t, (FRONT, BACK) if mode == Mode.DOUBLE_STANCE else (BACK,))
            if mode == Mode.BACK_STANCE:
                u[:2] = _FLIP_KP * (tuck - x[3:5]) - _FLIP_KD * x[NQ + 3:NQ + 5]
        elif phase == self.flight:
            tf = (t - self.start[phase]) / (self.start[phase + 1] - self.start[phase])
            target = np.tile(tuck, 2) if tf < _FLIP_TUCK_FRACTION else self.phases[phase].x_final[3:NQ]
            u = _FLIP_KP * (target - x[3:NQ]) - _FLIP_KD * x[NQ + 3:]
        else:
            u = _double_stance_torque(self.robot, x, self.phases[phase])
        return np.clip(u, -self.params.torque_limit, self.params.torque_limit)


__all__ = ["MOTIONS", "TRANSITIONS", "SPEED_RANGE", "PRONK_DURATIONS", "JOINT_LIMITS", "MotionPhase", "leg_posture",
           "double_stance_state", "pronk_reference", "stand_reference", "pronk_phases", "bound_phases",
           "motion_problem", "pronk_problem", "transition_problem", "motion_warm_start", "JUMPS", "GAP_WIDTH",
           "BOX_HEIGHT", "JUMP_FLIGHT", "jump_terrain", "jump_problem", "backflip_problem", "BACKFLIP_OPTIONS"]
