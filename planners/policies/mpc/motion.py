"""HS-DDP MPC of a planned motion (the backflip, the jumps, the gait transitions): the motion re-planned online.

A motion is a fixed sequence of phases ([`hsddp_gym.planners.motions.problems`][hsddp_gym.planners.motions.problems]):
its problem on the MPC's knot grid and that problem's solution from the motion's start are the
[`MotionReference`][MotionReference]. [`MotionMPCPolicy`][MotionMPCPolicy] re-plans *what remains of it* from the
observed state (a shrinking horizon): the phases from the current one to the last, the current one shortened to what
remains of it ([`remaining_problem`][remaining_problem]). The parts are the bound's MPC's
([`hsddp_gym.planners.policies.mpc`][hsddp_gym.planners.policies.mpc]): the state estimator (filter, sensor bias,
latency compensation), the planner (warm starts from the previous plan shifted onto the new problem, restarts, feedback
re-plans), the feedback law between re-plans (projected onto pushing stance feet). What is the motion's own:

* **the phase**: the cursor of the plan acted on, moved over touchdowns by the motion's touchdown rule (feet seen clear
  of the ground before their flag counts, [`FootClearance`][hsddp_gym.planners.policies.touchdown.FootClearance]);
  lift-offs follow plan time. Every phase change re-plans at once.
* **the landing's timing** (``retime`` of the ``motion`` group of
  [`MPCOptions`][hsddp_gym.planners.policies.mpc.options.MPCOptions]): in a flight the time left is where the
  ballistic centre of mass reaches the height it has at the reference's touchdown
  ([`flight_time_to_go`][flight_time_to_go]): a push or a mistimed take-off moves the touchdown of the remaining flight
  with the state. Without it the flight keeps its nominal duration (fixed timing).
* **the ground**: where the sensor-bias estimate puts it (the calibrated height bias, as the bound's plans): a
  measurement that reads the trunk 2 cm low plans its landings 2 cm lower, not above the ground.
* **the end**: the last phase (a stance) is planned at least ``hold_horizon`` long, so after the motion the plans hold
  its final reference (a receding horizon on the last stance). A periodic gait (``loop_phase`` of its
  [`MotionReference`][MotionReference], the pronk) goes on at ``loop_phase`` at the touchdown that ends its last
  phase: its reference's cycles from there on are steady, and the plans cover what remains of them. A motion that
  ends in a bound (``hand_over`` of its [`MotionReference`][MotionReference]) is handed to the bounding MPC
  ([`MPCPolicy`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy], the same options) when its phase ``hand_over``
  begins: the bound's schedule estimator picks the gait up from the observed contacts, with the state estimator the
  motion used (its filter, bias and action history carry on).
* **starts and restarts**: the first plan of an episode is warm-started from the reference (its feedback law from its
  first knot); a plan from scratch starts from the reference at the motion's current phase and time.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin

from hsddp_gym.core.conventions import IZ, NQ, NX, Mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.schedule import ModeSchedule
from hsddp_gym.core.terrain import Terrain
from hsddp_gym.planners.optimizer.hold import held_feedforward, held_input_gains
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.optimizer.solution import Solution
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.planners.policies.estimation import terrain_clearance
from hsddp_gym.planners.policies.mpc.agent import MPCPolicy
from hsddp_gym.planners.policies.mpc.ground import GroundModel
from hsddp_gym.planners.policies.mpc.law import FeedbackLaw, feedback_torques
from hsddp_gym.planners.policies.mpc.options import MotionOptions, MPCOptions
from hsddp_gym.planners.policies.mpc.planner import MPCPlanner, Plan
from hsddp_gym.planners.policies.mpc.state import StateEstimator
from hsddp_gym.planners.policies.mpc.warm_start import shift_plan
from hsddp_gym.planners.policies.touchdown import FootClearance, plan_clearance
from hsddp_gym.planners.policies.tracking import PlanTracker
from hsddp_gym.util.validation import check_int, check_positive, check_vector

GRF_RELAXATION = 0.1
"""The least relaxation [N] of the ground forces' barriers in a re-plan. The re-plans keep the barriers the reference
converged with (relaxations and weights): the motion runs at the torque limits, and the bound's looser torque barrier
let the backflip's plans ask the motors for up to 36 N m where they give 33. On the ground forces the reference's
relaxation (about 0.003 N) is too tight for states that are observed: a state whose ground forces a noisy estimate puts
a hair outside the friction cone costs a re-plan millions, and its step goes astray."""


@dataclasses.dataclass
class MotionReference:
    """A motion on the MPC's knot grid.

    Attributes:
        name: the motion (e.g. ``"backflip"``).
        problem: its whole problem from its nominal start (``problem.x0``).
        solution: ``problem`` solved (the reference the first plan and every restart start from).
        multipliers: ``(m,)`` the solution's AL multipliers, one per switching-constraint row of ``problem``.
        constraint_state: the solver's outer-loop state at the solution (penalty, barrier settings).
        touchdown_com_height: ``(n,)`` per phase, the centre of mass's height [m] at the touchdown that ends it in the
            solution (NaN for a phase without one).
        law: the solution with the feedback law of a control held over ``hold`` knots (the first plan's law).
        hold: knots per control period.
        hand_over: the phase at whose start the bounding MPC takes over (None: the motion ends in its last stance,
            held): the first steady bounding cycle of a motion that ends in a bound.
        loop_phase: a periodic gait's (None: a motion that ends): the phase the gait goes on at after the touchdown
            that ends the last phase (its reference's cycles from there on are steady).
    """

    name: str
    problem: HybridProblem
    solution: Solution
    multipliers: np.ndarray
    constraint_state: object
    touchdown_com_height: np.ndarray
    law: Solution
    hold: int
    hand_over: int | None = None
    loop_phase: int | None = None

    def __post_init__(self) -> None:
        if self.loop_phase is not None:
            if self.hand_over is not None:
                raise ValueError("a motion has a hand_over or a loop_phase, not both")
            self.loop_phase = check_int(self.loop_phase, "loop_phase")
            modes = self.problem.schedule.modes
            if self.loop_phase >= self.problem.n_phases or modes[self.loop_phase] != self.problem.schedule.final_mode:
                raise ValueError(f"loop_phase must be a phase of the mode the last phase lands in "
                                 f"({Mode(self.problem.schedule.final_mode).name}), got {self.loop_phase}")
        if self.hand_over is not None:
            self.hand_over = check_int(self.hand_over, "hand_over", minimum=1)
            modes = self.problem.schedule.modes
            if self.hand_over >= self.problem.n_phases or modes[self.hand_over] != Mode.BACK_STANCE:
                raise ValueError(f"hand_over must be a back stance of the motion (a bounding cycle's first phase), got "
                                 f"{self.hand_over}")

    @property
    def n_phases(self) -> int:
        return self.problem.n_phases

    def tracker(self, phase: int, elapsed: float, touchdown=None, law: bool = False) -> PlanTracker:
        """A tracker of the solution (``law``: of its held law) with its cursor ``elapsed`` [s] into ``phase``."""
        tr = PlanTracker.from_solution(self.law if law else self.solution, self.problem, touchdown=touchdown)
        tr.phase, tr.local_time = int(phase), float(elapsed)
        return tr


def reference_from_solve(name: str, problem: HybridProblem, solver, solution: Solution, hold: int,
                         hand_over: int | None = None, loop_phase: int | None = None) -> MotionReference:
    """The [`MotionReference`][MotionReference] of motion ``name`` from ``solver``'s last solve of ``problem``, which
    gave ``solution`` (its multipliers and barrier settings; its law for a control held over ``hold`` knots, from the
    same backward pass), handed to the bounding MPC at phase ``hand_over`` (None: never), periodic from
    ``loop_phase`` (None: not periodic).

    Raises:
        ValueError: ``solver`` has not just solved ``problem``.
        RuntimeError: the solve did not converge (or its trajectory is not finite).
    """
    hold = check_int(hold, "hold", minimum=1)
    if solver.last_problem is not problem:
        raise ValueError("solver has not just solved problem: solve it first")
    if not (solution.converged and np.all(np.isfinite(solution.X))):
        raise RuntimeError(f"the {name} reference did not converge on a {problem.dt} s grid (status "
                           f"{solution.status})")
    cs = solver.last_constraint_state
    robot = problem.dynamics.robot
    data = robot.new_data()
    heights = np.full(problem.n_phases, np.nan)
    for i in range(problem.n_phases):
        if problem.touchdown[i] >= 0:
            heights[i] = com_state(robot, solution.X_pre[i], data)[0]
    law = dataclasses.replace(solution, K=held_input_gains(solver, problem, hold),
                              U=held_feedforward(solution.U, problem.phase_start, hold))
    return MotionReference(name, problem, solution, cs.lam.copy(), cs.copy(), heights, law, hold, hand_over,
                           loop_phase)


def held_knots(control_dt: float, planner_dt: float) -> int:
    """The plan knots of ``planner_dt`` [s] per control period ``control_dt`` [s] (a whole number).

    Raises:
        ValueError: ``planner_dt`` does not divide ``control_dt``.
    """
    hold = check_positive(control_dt, "control_dt") / check_positive(planner_dt, "planner_dt")
    if abs(hold - round(hold)) > 1e-6 or round(hold) < 1:
        raise ValueError(f"planner_dt ({planner_dt} s) must divide the control period ({control_dt} s): the plans' "
                         "laws hold their control over whole knots")
    return int(round(hold))


def com_state(robot, x: np.ndarray, data=None) -> tuple[float, float]:
    """The centre of mass's height [m] and vertical velocity [m/s] at the state ``x`` (14,) of ``robot``'s model
    (``data``: a ``pin.Data`` of it to compute in, None: a new one)."""
    x = check_vector(x, NX, "x")
    data = robot.new_data() if data is None else data
    pin.centerOfMass(robot.model, data, x[:NQ], x[NQ:])
    return float(data.com[0][2]), float(data.vcom[0][2])


def flight_time_to_go(z: float, vz: float, z_touchdown: float, gravity: float) -> float:
    """The time [s] until a ballistic centre of mass at height ``z`` [m] rising at ``vz`` [m/s] comes down to
    ``z_touchdown`` [m]: the later root of ``z + vz t - g t^2 / 2 = z_touchdown``; 0 when it is below that height
    and cannot rise to it.

    Raises:
        ValueError: a value that is not finite, or ``gravity`` not positive.
    """
    for name, value in (("z", z), ("vz", vz), ("z_touchdown", z_touchdown)):
        if not math.isfinite(value):
            raise ValueError(f"{name} must be finite, got {value!r}")
    gravity = check_positive(gravity, "gravity")
    disc = vz * vz + 2.0 * gravity * (z - z_touchdown)
    if disc < 0.0:
        return 0.0
    return max(0.0, (vz + math.sqrt(disc)) / gravity)


def remaining_problem(reference: MotionReference, phase: int, duration: float, x: np.ndarray,
                      last_duration: float | None = None, elapsed: float = 0.0, ground: float = 0.0,
                      dynamics: HybridDynamics | None = None) -> HybridProblem:
    """What remains of the motion from ``phase``, ``elapsed`` [s] into it: its phases ``phase .. n - 1`` from the state
    ``x`` (14,), the first ``duration`` [s] long (the others nominal; ``last_duration``: the last one's duration when
    it is not the first, None: nominal), on the ground (or the motion's terrain) raised by ``ground`` [m] (where the
    measurement puts it), with ``dynamics`` (None: the reference's; another robot on the same grid: a trunk of
    another mass). Knots: ``max(1, round(T / h))`` per phase (``h`` the reference's grid).

    The running references are the reference's trajectory (states and ground forces at the same point of the
    motion, [`reference_knots`][reference_knots]), not the phases' end references: a re-plan keeps to the motion the
    reference solved for where nothing forces it off."""
    full = reference.problem
    n = full.n_phases
    if not 0 <= phase < n:
        raise ValueError(f"phase must be in [0, {n - 1}], got {phase!r}")
    s = full.schedule
    durations = np.array(s.durations[phase:], dtype=np.float64)
    durations[0] = check_positive(duration, "duration")
    if last_duration is not None and len(durations) > 1:
        durations[-1] = check_positive(last_duration, "last_duration")
    knots = np.maximum(1, np.round(durations / full.dt)).astype(np.int64)
    schedule = ModeSchedule(s.modes[phase:], durations, final_mode=s.final_mode)
    ground = float(ground)
    if not math.isfinite(ground):
        raise ValueError(f"ground must be finite, got {ground!r}")
    terrain = full.terrain
    if ground != 0.0:
        terrain = (Terrain.flat() if terrain is None else terrain).raised(ground)
    if dynamics is None:
        dynamics = full.dynamics
    elif not isinstance(dynamics, HybridDynamics) or dynamics.dt != full.dynamics.dt:
        raise ValueError(f"dynamics must be a HybridDynamics on the reference's grid ({full.dynamics.dt} s), "
                         f"got {dynamics!r}")
    problem = HybridProblem(dynamics, schedule, full.costs[phase:], x, full.constraints, full.restitution,
                            knots=knots, terrain=terrain)
    idx = reference_knots(reference, phase, elapsed, problem)
    problem.XR = reference.solution.X[idx].copy()
    if full.terrain is None:  # on flat ground the motion is the same wherever it starts; on a terrain it is not
        problem.XR[:, 0] += x[0] - reference.solution.X[idx[0], 0]
    problem.XR[:, IZ] += ground
    problem.YR = reference.solution.GRF[idx].copy()
    return problem


def reference_knots(reference: MotionReference, phase: int, elapsed: float, problem: HybridProblem) -> np.ndarray:
    """``(N,)`` per knot of ``problem`` (what remains of the motion from ``phase``, ``elapsed`` [s] into it), the
    reference's knot at the same point of the motion: in a stance the same time since the phase began (the last knot
    of the phase beyond its nominal end); in a flight the same fraction of what remained of it (a retimed flight
    follows the reference's flight, faster or slower)."""
    ref = reference.problem
    out = np.empty(problem.n_knots, dtype=np.int64)
    for j in range(problem.n_phases):
        r = phase + j
        a, n_r = int(ref.phase_start[r]), int(ref.knots[r])
        lo, hi = int(problem.phase_start[j]), int(problem.phase_start[j + 1])
        i = np.arange(hi - lo)
        start = elapsed if j == 0 else 0.0
        if ref.schedule.modes[r] == Mode.FLIGHT:
            f0 = min(start / float(ref.schedule.durations[r]), 1.0)
            local = ((f0 + (1.0 - f0) * i / (hi - lo)) * n_r + 1e-9).astype(np.int64)
        else:
            local = ((start + i * problem.phase_dt[j]) / ref.phase_dt[r] + 1e-9).astype(np.int64)
        out[lo:hi] = a + np.minimum(local, n_r - 1)
    return out


class MotionMPCPolicy(Policy):
    """HS-DDP MPC of a planned motion, acting from observations (see the module docstring).

    Args:
        interface: the env's public settings.
        reference: the motion on the plans' grid ([`MotionReference`][MotionReference], e.g.
            [`motion_reference`][hsddp_gym.planners.motions.references.motion_reference]; the policy of a task's env:
            ``make_policy("mpc", env)``).
        options: [`MPCOptions`][hsddp_gym.planners.policies.mpc.options.MPCOptions]: the estimator, the plans' grid
            (``planner_dt`` must divide the control period), the re-plans, ``min_flight`` and the ``motion`` group
            ([`MotionOptions`][hsddp_gym.planners.policies.mpc.options.MotionOptions]); the speed reference's and the
            gait clock's other settings are the bound's and not used.

    Attributes:
        reference: the [`MotionReference`][MotionReference]. phase: the motion's current phase (index into its phases).
        stats: the planner's statistics (``replans``, ``planner_failures``, ``solve_ms``, ...), and ``phase_replans``
            (re-plans made at a phase change) and ``feedback_replans``; after a hand-over the bounding MPC's add to
            them (one dict per episode).
        gait: the bounding MPC the motion is handed to (None: a motion without ``hand_over``).
        handed_over: whether the bounding MPC acts (the motion reached its ``hand_over`` phase).
    """

    def __init__(self, interface: EnvInterface, reference: MotionReference, options: MPCOptions = MPCOptions()) -> None:
        super().__init__(interface)
        if not isinstance(options, MPCOptions):
            raise TypeError(f"options must be an MPCOptions, got {type(options).__name__}")
        if not isinstance(reference, MotionReference):
            raise TypeError(f"reference must be a MotionReference, got {type(reference).__name__}")
        self.hold = held_knots(interface.control_dt, options.plan.planner_dt)
        if abs(reference.problem.dt - options.plan.planner_dt) > 1e-12 or reference.hold != self.hold:
            raise ValueError(f"reference must be on the plans' grid ({options.plan.planner_dt} s, {self.hold} knots "
                             f"per control period), got {reference.problem.dt} s and {reference.hold}")
        self.motion = reference.name
        self.options = options
        self.motion_options: MotionOptions = options.motion
        self.reference = reference
        self._build()
        self.reset()

    def _build(self) -> None:
        o, i = self.options, self.interface
        self.planner = MPCPlanner(o.plan, o.replan, i.torque_limit, 0.0, None)
        robot = self.planner.dynamics.robot
        self.robot = robot
        self._com_data = robot.new_data()
        self.touchdown = FootClearance(plan_clearance(self.reference.solution, robot), robot)
        self.planner.touchdown = self.touchdown
        self.planner.hold = self.hold
        c = self.reference.constraint_state
        # the re-plans keep the relaxed barriers the reference converged with (GRF_RELAXATION)
        self.planner.barrier = (c.delta_torque, max(c.delta_grf, GRF_RELAXATION), c.eps_torque, c.eps_grf)
        self.planner.cold_start = self._cold_start
        mo = self.motion_options
        self.estimator = StateEstimator(i, o.estimator, robot, correct_bias=mo.bias_correction,
                                        estimate_mass=mo.mass_estimate)
        self._models: dict[float, HybridDynamics] = {}  # the plans' models by trunk mass scale (plan_dynamics)
        friction = self.reference.problem.constraints.friction
        terrain = self.reference.problem.terrain
        self.law = FeedbackLaw(i.torque_limit, o.min_stance_force, friction,
                               GroundModel(terrain, robot.params.hip_offset), robot)
        self.gait = None
        if self.reference.hand_over is not None:
            self.gait = MPCPolicy(i, o, terrain=terrain)
            self.gait.estimator = self.estimator  # one estimate of the state over the hand-over

    def _reset_copy_state(self) -> None:
        self._build()

    def reset(self) -> None:
        ref = self.reference
        self.planner.reset(ref.constraint_state)
        if self.gait is not None:
            self.gait.reset()
        self.estimator.reset(self.law.ground.reset())  # the motion's terrain (None: flat)
        self.law.plan = Plan(ref.tracker(0, 0.0, self.touchdown, law=True), ref.solution, ref.problem,
                             ref.multipliers.copy())
        self._plan_phase = 0
        """The motion's phase the plan acted on begins in."""
        self._tracker_phase = 0
        self.phase = 0
        self._phase_time = 0.0
        """Time [s] spent in the current phase (env time, by control periods)."""
        self._since_replan = np.inf
        self._airborne = False
        """Whether no foot touches (predicted over the action delay): a flight is retimed from its ballistic state only
        then (while the take-off foot still pushes, the centre of mass is still gaining speed)."""
        self.stats = self.planner.stats
        self.stats.update(phase_replans=0, feedback_replans=0)
        self.handed_over = False
        if self.gait is not None:
            self.stats.update(delay_changes=0)
            self.gait.stats = self.gait.planner.stats = self.stats
        self.last_estimate: np.ndarray | None = None
        self.last_prediction: np.ndarray | None = None
        self.flight_time_to_go: float | None = None
        """The last retimed flight's time left [s] (None: none yet)."""

    # ------------------------------------------------------------------ the plans
    @property
    def last_solution(self):
        return self.law.plan.solution

    def _remaining(self, x: np.ndarray) -> HybridProblem:
        """The problem of what remains of the motion from the current phase and the state ``x`` (14,)."""
        ref, mo = self.reference, self.motion_options
        k = self.phase
        nominal = float(ref.problem.schedule.durations[k])
        duration = nominal - self._phase_time
        last = ref.n_phases - 1
        if (ref.problem.schedule.modes[k] == Mode.FLIGHT and mo.retime and self._airborne
                and not np.isnan(ref.touchdown_com_height[k])):
            z, vz = com_state(self.robot, x, self._com_data)
            duration = min(flight_time_to_go(z, vz, float(ref.touchdown_com_height[k]), self.robot.params.gravity),
                           mo.max_flight_stretch * nominal)
            self.flight_time_to_go = duration
        duration = max(duration, self.options.plan.min_phase)
        ground = self.estimator.model_ground()
        dynamics = self.plan_dynamics()
        if k == last and ref.loop_phase is None:
            return remaining_problem(ref, k, max(duration, mo.hold_horizon), x, elapsed=self._phase_time,
                                     ground=ground, dynamics=dynamics)
        return remaining_problem(ref, k, duration, x, float(ref.problem.schedule.durations[last]),
                                 elapsed=self._phase_time, ground=ground, dynamics=dynamics)

    def plan_dynamics(self) -> HybridDynamics:
        """The plans' model: the reference's, its trunk's mass scaled by the estimate
        ([`MotionOptions.mass_estimate`][hsddp_gym.planners.policies.mpc.options.MotionOptions]) rounded to a
        multiple of ``mass_step`` (built once per multiple)."""
        nominal = self.reference.problem.dynamics
        mo = self.motion_options
        if self.estimator.mass is None:
            return nominal
        scale = round(round(self.estimator.mass.scale / mo.mass_step) * mo.mass_step, 6)
        if scale == 1.0:
            return nominal
        if scale not in self._models:
            robot = CheetahModel(nominal.robot.params.with_trunk_mass_scale(scale))
            self._models[scale] = HybridDynamics(robot, nominal.dt, nominal.integrator)
        return self._models[scale]

    def _cold_start(self, problem: HybridProblem) -> tuple:
        """The reference at the motion's current phase and time on ``problem``'s knots: ``(U, X, K)``, its controls,
        states and feedback law (its first rollout follows the reference's law from the state)."""
        ref = self.reference
        ws = shift_plan(problem, problem.x0, ref.tracker(self.phase, self._phase_time), ref.solution, None)
        if ws is None:
            return np.zeros((problem.n_knots, 4)), None, None
        return ws[0], ws[1], ws[2]

    def replan(self, x: np.ndarray, feedback: bool = False) -> bool:
        """Plan what remains of the motion from ``x`` (14,) and act on it; True on success."""
        old = self.law.plan
        problem = self._remaining(x)
        first = problem.schedule.modes[0]
        if first != Mode.FLIGHT:
            # the plan's stance feet are held from its first knot: their velocities go, as at a touchdown
            problem.x0 = problem.dynamics.reset_map(x, first)[0]
        plan = self.planner.solve(problem, problem.x0, old, feedback)
        if plan is None:
            return False
        plan.tracker.carry_evidence(old.tracker)
        self.law.plan = plan
        self._plan_phase = self.phase
        self._tracker_phase = 0
        return True

    # ------------------------------------------------------------------ the loop
    def act(self, obs: np.ndarray) -> np.ndarray:
        if self.handed_over:
            action = self.gait.act(obs)
            self.last_estimate, self.last_prediction = self.gait.last_estimate, self.gait.last_prediction
            return action
        x_obs, mode, _ = self._parse(obs)
        x_est = self.estimator.update(x_obs, mode)
        self.last_estimate = x_est
        steps = self.estimator.predict(x_est, mode)
        x, eff = (steps[-1][0], steps[-1][1]) if steps else (x_est, mode)
        self._airborne = eff == Mode.FLIGHT
        self.last_prediction = x.copy()
        tracker = self.law.plan.tracker
        if self._in_early_flight():
            eff = tracker.modes[tracker.phase]  # a contact this early in a flight is a scuff, not its landing
        self.touchdown.ground = self.estimator.model_ground()  # feet seen clear of the ground where it is measured
        if tracker.waiting:
            eff = self._late_landing(eff, x, tracker)
        tracker.sync(eff, x)
        self._follow(tracker)
        dt = self.interface.control_dt
        if self._since_replan >= self.options.replan.period - 1e-9:
            self._since_replan = 0.0
            self.replan(x)
        u, tried = feedback_torques(self.law, x, self.options.replan.feedback_threshold, self._feedback_replan())
        if tried:
            self._since_replan = 0.0
        tracker = self.law.plan.tracker
        tracker.advance(dt)
        self._phase_time += dt
        self._since_replan += dt
        self._follow(tracker)  # a lift-off on plan time
        if tracker.waiting:  # a late landing: re-plan it from each state, not hover at the plan's last flight knot
            self._since_replan = np.inf
        action = self.interface.action_from_torque(u)
        self.estimator.record_sent(action)
        return action

    _feedback_replan = MPCPolicy._feedback_replan

    def _late_landing(self, mode: Mode, x: np.ndarray, tracker: PlanTracker) -> Mode:
        """``mode`` with the landing feet of a late flight (the cursor waits at its end) added where the state ``x``
        (14,) puts them within ``ScheduleOptions.touchdown_height`` of the measured ground, as the bound's schedule
        estimator does ([`late_landing`][hsddp_gym.planners.policies.mpc.schedule.late_landing]): on a stiff contact a
        landing foot can touch and leave within every control step, so no flag reports the touchdown and the flight
        would wait while the trunk sinks."""
        height = self.options.schedule.touchdown_height
        if height is None:
            return mode
        i = tracker.phase
        ground = self.estimator.model_ground()
        terrain = self.reference.problem.terrain
        for foot in (0, 1):
            if (tracker.next_modes[i].in_contact(foot) and not tracker.modes[i].in_contact(foot)
                    and not mode.in_contact(foot)
                    and terrain_clearance(self.robot, x[:NQ], foot, terrain) - ground < height):
                mode = Mode(int(mode) | (1 << foot))
        return mode

    def _in_early_flight(self) -> bool:
        """Whether the motion is in a flight of which less than ``ScheduleOptions.min_flight`` of its nominal
        duration has passed (its landing cannot be yet)."""
        schedule = self.reference.problem.schedule
        return (schedule.modes[self.phase] == Mode.FLIGHT
                and self._phase_time < self.options.schedule.min_flight * float(schedule.durations[self.phase]))

    def _follow(self, tracker: PlanTracker) -> None:
        """Take the motion's phase from the plan's cursor; a new phase of the plan re-plans at once (a periodic gait:
        the touchdown that ends its last phase starts ``loop_phase``)."""
        loop = self.reference.loop_phase
        if loop is not None and tracker.finished and self.phase == self.reference.n_phases - 1:
            self.phase, self._phase_time, self._since_replan = loop, 0.0, np.inf
            self._tracker_phase = -1  # the plan acted on is over: the re-plan from loop_phase replaces it
            self.stats["phase_replans"] += 1
            return
        if tracker.phase == self._tracker_phase:
            return
        self._tracker_phase = tracker.phase
        self._since_replan = np.inf
        phase = min(self._plan_phase + tracker.phase, self.reference.n_phases - 1)
        if phase != self.phase:
            self.phase = phase
            self._phase_time = 0.0
            self.stats["phase_replans"] += 1
            self.handed_over = self.gait is not None and phase >= self.reference.hand_over

    def note_sent_action(self, action) -> None:
        """As [`MPCPolicy.note_sent_action`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy.note_sent_action]."""
        self.estimator.replace_sent(action)  # the estimator the bounding MPC shares after a hand-over
