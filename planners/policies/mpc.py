"""HS-DDP model-predictive control: re-plan from the observed state, act with the plan's feedback law.

As in MuJoCo MPC, the planner optimizes and the policy is queried at the control rate from the latest
plan. At each re-plan (every ``replan_period`` seconds of env time):

1. the observation gives the state, the contact mode and (from the policy's memory) the time already spent
   in that mode and the last stance foot;
2. a bounding :class:`~hsddp_gym.core.schedule.ModeSchedule` starts with the current mode for the rest of its
   nominal duration (at least ``min_phase`` seconds; a flight at least until its landing foot's hip, flying
   ballistically, is within reach of the ground: ``flight_reach``) and continues the bounding cycle to cover at least
   ``horizon`` seconds (default one gait cycle); the plan's speed reference is the target speed moved at
   most ``speed_ramp`` from the measured speed (a reference governor for pushes), a stance whose foot
   has left the ground is replaced at once by the flight that lands it again (:class:`GaitClock`), and
   a touchdown that finds the other foot on the ground starts a planned double stance (``double_stance``), a
   flight whose landing hip a pitch kick takes out of reach is planned as a re-step of the other foot, and a foot
   that lands again in the flight after its stance starts that stance again (``restep``), a flight
   past its nominal end whose landing foot the state puts at the ground ends, whatever that foot's contact flag
   says (``touchdown_height``, :func:`late_landing`); the plans and that rule put the ground where the feet on it
   put it (``bias_memory``), and a late flight before they have put it anywhere plans its touchdown below the
   measured ground (``ground_search_speed``);
3. the previous plan, aligned by phase with the contact events
   (:class:`~hsddp_gym.planners.policies.tracking.PlanTracker`),
   is shifted onto the new schedule as the warm start (controls, states and gains for a feedback first
   rollout, AL multipliers phase by phase, the outer-loop penalty and barrier state); phases beyond the
   previous plan copy the same mode one cycle earlier;
4. HS-DDP runs at most ``max_iterations`` DDP iterations (and ``time_budget`` seconds); a plan that ends far above the
   previous plan's objective is solved again from scratch (``restart_ratio``), and the augmented Lagrangian's
   multipliers and penalty passed on to the next re-plan are the warm start's (no outer-loop update is carried
   from one re-plan to the next, not even a feedback re-plan's; a plan from scratch, and a restart kept by a
   periodic re-plan, pass on their own);
5. the new plan replaces the old one ``latency_steps`` control steps later (simulated solver latency);
   between re-plans the policy applies ``u = U_k + K_k (x - X_k)`` at the plan's cursor, projected onto the
   torques with which every planned stance foot pushes on the ground inside the friction cone
   (``min_stance_force``, :class:`~hsddp_gym.planners.policies.contact_consistency.PushingTorques`); when the
   feedback term ``K_k (x - X_k)`` alone would reach ``replan_feedback`` of the torque limit, the state is too far
   from the plan for its linearization and the MPC re-plans from it at once, solving that plan further than a
   periodic one (``feedback_iterations`` DDP iterations in each of ``feedback_al_iterations`` outer iterations, the
   multipliers and penalty updated between them and not carried on).

Before step 1 the observation goes through the model-based state filter (``state_filter``) and, when the env
executes actions late (``EnvInterface.action_delay_steps``), is predicted over the delay with the model under the
actions already sent (``latency_compensation``): the plan and its feedback law are for the state at which the
action will act (:mod:`hsddp_gym.planners.policies.estimation`). Once the feet on the ground have put the ground in the
measurement's frame (``bias_memory``), that model stands on it too: the filter, the prediction over the delay and the
delay's estimate see the ground where the plans see it. The plans' speed reference also moves from the
start speed toward the target at a bounded rate (``speed_acceleration``).

Given the ground (``MPCPolicy(..., terrain=...)``, privileged information), the MPC works in the world frame: its
plans' switching constraints put a landing foot on the terrain under it, the reference heights follow the ground, and
the late-landing rule, the state filter, the bias estimate and the flight reach measure the feet from the terrain.

A failed re-plan (exception, non-finite rollout, no decrease) never ends the episode: the previous plan's
feedback law keeps acting and the failure is counted in :attr:`MPCPolicy.stats`. Only while no plan exists yet
(the episode's first re-plan failed) does the schedule-driven heuristic act instead (a start-up controller).
"""

from __future__ import annotations

import collections
import dataclasses
import functools
import math
import time
import warnings

import numpy as np

from hsddp_gym.core.conventions import BACK, FRONT, IPITCH, IZ, NQ, NU, NX, Mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.references import check_height_offset
from hsddp_gym.core.schedule import PAPER_BOUNDING_DURATIONS, ModeSchedule
from hsddp_gym.core.terrain import Terrain, check_terrain
from hsddp_gym.planners.optimizer.hsddp import HSDDP
from hsddp_gym.planners.optimizer.objective import ConstraintState
from hsddp_gym.planners.optimizer.problem import BOUNDING_WEIGHTS, ConstraintSpec, HybridProblem
from hsddp_gym.planners.optimizer.solution import SolverOptions
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.planners.policies.contact_consistency import PushingTorques
from hsddp_gym.planners.policies.estimation import (
    ContactModelPredictor,
    MeasurementBias,
    StateFilter,
    terrain_clearance,
)
from hsddp_gym.planners.policies.heuristic import HeuristicBoundingController, HeuristicGains
from hsddp_gym.planners.policies.latency import DelayEstimator
from hsddp_gym.planners.policies.tracking import PlanTracker
from hsddp_gym.util.validation import check_in_range, check_int, check_positive, check_vector

_CYCLE = (Mode.BACK_STANCE, Mode.FLIGHT, Mode.FRONT_STANCE, Mode.FLIGHT)
DOUBLE_STANCE_PHASE = 4
""":attr:`GaitClock.phase` of a double stance (outside the bounding cycle's phases 0-3)."""
FAST_BOUNDING_DURATIONS = (0.080, 0.100, 0.080, 0.100)
"""The authors' 1.5 m/s bounding durations (original_code_facts §3.2, MH HEAD); ``MPCOptions(durations=...)``."""


@dataclasses.dataclass(frozen=True)
class MPCOptions:
    """Settings of :class:`MPCPolicy`, grouped by purpose.

    The defaults are the configuration evaluated in the results pages; every field can be given by name
    (``MPCOptions(replan_period=0.01)``), and the experiment scripts accept any of them as JSON
    (``--mpc-options '{"planner_dt": 0.005}'``). The groups: **Timing** (the plan's horizon and grid, when re-plans
    happen and how the gait clock reads contacts), **Solver** (the HS-DDP run of each re-plan), **References** (the
    gait and the speed the plans aim at), **Perception** (the state estimate the plans start from) and **Recovery**
    (how the gait clock and the schedule follow a robot that leaves the nominal gait, e.g. after a push).

    Attributes: Timing
        horizon: the least planned time [s] (None: one gait cycle of ``durations``, 0.296 s for the paper's gait).
            The schedule continues the bounding cycle until it covers the horizon and ends after a stance. Change
            this to look further ahead, at the cost of a longer re-plan.
        planner_dt: the planner's knot spacing [s]; it may be coarser than the simulator's 1 ms step. Change this to
            trade re-plan time (coarser) against the accuracy of the planned contact timing (finer).
        fine_dt: knot spacing [s] of the plan's first ``fine_phases`` phases (None: ``planner_dt`` everywhere): a
            multi-rate grid, fine where the plan is acted on, coarse beyond. Must be ``planner_dt`` divided by a
            whole number; every phase duration stays on the ``planner_dt`` grid, so a phase keeps its duration when
            it moves onto the fine grid. Change this to make re-plans cheaper with a coarse ``planner_dt``.
        fine_phases: number of leading plan phases on the ``fine_dt`` grid (>= 1).
        replan_period: env time between re-plans [s]. Shorter re-plans react sooner and cost more computation per
            second of env time.
        latency_steps: control steps between the start of a re-plan and the moment its plan replaces the previous
            one (a simulated solver latency; 0: at once). Change this to emulate a deployment where solving takes
            time.
        time_budget: wall-clock limit of one re-plan [s] (None: no limit). A re-plan stopped by it keeps its best
            iterate (counted in ``stats["time_budget_stops"]``). Change this for real-time operation.
        min_phase: the shortest remaining duration [s] a plan gives the current phase, so that a phase that
            outlasts its nominal duration still gets a few knots.
        debounce_steps: control steps the landing foot must be in contact before a flight ends ahead of its
            nominal end (from the nominal end on, one contact step ends it). Raise it for noisier contact flags.
        min_flight: a fraction of the nominal flight: a touchdown before it is taken for a graze, and a foot must
            have been in the air at least that long for its contact to count as a landing (double stance,
            ``restep``).
        touchdown_height: from a flight's nominal end on, its landing foot counts as touched down when the
            (estimated) state puts it within this height [m] of the ground, whatever the contact flag says (None:
            the flags alone; :func:`late_landing`). A flag samples the contact at the end of a control step; on a
            stiff contact a landing foot can bounce at the control rate and be in the air at the end of every step,
            and a clock that waits for the flag keeps the plan in the flight while the trunk sinks. Raise it for a
            noisy state estimate of the feet; None for an env whose flags never miss a touchdown.
        ground_search_speed: the rate [m/s] at which a late flight's plans lower the ground its landing foot
            is to meet, until a stance has calibrated where the measurement puts the ground (``bias_memory``; None:
            the plans put it at the measured ground until then). Before that calibration nothing says where the
            ground is: a biased height sensor puts it centimetres above or below the measured ``z = 0``. A plan
            whose switching constraint holds the landing foot at ``z = 0`` stops it there, above a ground that is
            lower, and the foot hovers while the trunk sinks (the episode's first landing under a height bias). From
            the flight's nominal end on, the plans put the ground this rate times the lateness below the measured
            one, at most the bias estimate's height bound (:class:`~hsddp_gym.planners.policies.estimation.
            MeasurementBias`, 10 cm): the foot keeps reaching down until its contact flag reports the ground.

    Attributes: Solver
        method: HS-DDP constraint handling: ``"al-reb"`` (augmented Lagrangian on the switching constraints and
            relaxed barriers on torques, normal forces and friction), ``"al"`` (switching constraints only) or
            ``"ddp"`` (neither).
        max_iterations: DDP iterations of a warm-started re-plan. One iteration is a real-time iteration scheme:
            each re-plan takes one Newton-type step from the previous plan shifted to the new state, and the plans
            converge as the horizon moves. More iterations cost proportionally more time per re-plan.
        warmup_iterations: DDP iterations of a plan from scratch: the episode's first, one the previous plan cannot
            warm-start (its phases do not cover the new schedule, e.g. after a lost stance) and a restart
            (``restart_ratio``).
        sigma_max: cap of the augmented-Lagrangian penalty a warm-started re-plan starts with. Each re-plan keeps
            the multipliers and penalty it is warm-started with (the first plan's, shifted phase by phase, or a
            restart's): one DDP iteration does not solve its inner problem, so no outer-loop update is made
            between re-plans.
        reb_delta: the relaxed barriers' relaxation, the same in every re-plan (the one-shot solve's shrinking
            ``delta`` would make warm-started re-plans needlessly stiff).
        reb_eps: the relaxed barriers' weight, the same in every re-plan.
        integrator: the planner's integrator, ``"semi_implicit"`` or ``"euler"``. Semi-implicit Euler keeps the
            light shanks' closed loops stable at a coarse ``planner_dt``.
        refresh_gains: the solver's :attr:`SolverOptions.refresh_gains`. True: each plan's feedback gains come from
            one more linearization and backward pass at the plan's final trajectory. False: the gains of the backward
            pass that made the plan's last DDP step (``u = U + K (x - X)`` is then exactly that step's forward-pass
            law), which saves a linearization and a backward pass, about a third of a one-iteration re-plan. Change
            this when re-plan time matters more than the gains' consistency with the final trajectory.
        restart_ratio: a warm-started re-plan whose objective ends above this many times the previous plan's is
            solved again from scratch (``warmup_iterations``) and the better of the two plans is kept (None: never;
            must be > 1). After a push or a late touchdown the shifted previous plan's feedback rollout can leave
            the later phases far off, and one iteration from there does not recover. Counted in
            ``stats["restarts"]`` and ``stats["restarts_kept"]``.
        warm_start_kd: joint damping [N m s/rad] of the heuristic controller whose rollout warm-starts a plan from
            scratch (the heuristic's default 1 N m s/rad is unstable for explicit integration at steps above about
            1.5 ms).

    Attributes: References
        durations: nominal (back stance, flight, front stance, flight) durations [s] (None: the paper's
            80/72/72/72 ms at every target speed). :data:`FAST_BOUNDING_DURATIONS` are the authors' 1.5 m/s gait.
            The speed comes from the stride (see ``speed_integral_gain``), not from the durations.
        weights: cost weights, ``"later"`` (the authors' later code: more weight on the joints and their rates,
            less on the forward speed, half the torque weights) or ``"paper"`` (their code closest to the paper)
            (:func:`hsddp_gym.planners.optimizer.problem.bounding_phase_cost`). ``"later"`` trades a little
            forward speed for holding the posture after pushes (the MPC page has the numbers).
        z_velocity: vertical-velocity references at the phase ends
            (:func:`hsddp_gym.planners.optimizer.problem.bounding_phase_cost`): ``"code"`` (the authors' +-1 m/s:
            real flights with clearance) or ``"paper"`` (0: the swing feet barely leave the ground and graze it).
        height_offset: the plans' reference postures with the trunk this much higher [m] than the authors', the
            feet where the authors' postures have them and the joints by inverse kinematics
            (:func:`~hsddp_gym.core.references.end_of_mode_reference`; in [-0.1, 0.1]; 0: the authors' postures).
            A higher trunk leaves more room above the env's fall height (0.12 m) for a push.
        plan_friction: friction coefficient of the plans' friction cones (None: the model's 0.6). Below the
            model's, it is a friction margin: the ground forces are planned inside a narrower cone. Change this
            when the ground's friction differs (``gym.make("hsddp_gym/Bounding-v0", friction=...)``).
        speed_ramp: the largest difference [m/s] between a plan's forward-speed reference and the measured forward
            speed (:meth:`MPCPolicy.plan_speed`; None: always the reference speed). A reference governor: after a
            push that changes the speed by more than this, a plan does not demand the whole change within one gait
            cycle (the phase-end costs would ask for saturating torques and feet swung high).
        speed_acceleration: the largest rate [m/s^2] at which the plans' speed reference moves from the speed
            measured at the episode's first observation toward the target (None: no limit): a start-up that does
            not ask a robot at rest for the full speed within one gait cycle.
        speed_integral_gain: integral action on the plans' speed reference [1/s] (None: off). At every re-plan, once
            a whole gait cycle has been observed, :attr:`MPCPolicy.speed_bias` moves by ``gain * (time since the
            last re-plan) * (mean reference - mean estimated speed over the last cycle)`` and is added to the
            reference: offset-free speed tracking, which the cost's trade-offs and model error otherwise prevent at
            high speed. Cycle means on both sides, so the within-cycle speed swing and a ramping reference
            (``speed_acceleration``) do not wind it up.
        speed_bias_limit: the largest ``|speed_bias|`` [m/s].

    Attributes: Perception
        state_filter: estimate the state from the observations with the model
            (:class:`~hsddp_gym.planners.policies.estimation.StateFilter`, a Kalman filter: each observation
            corrects the previous estimate propagated with the executed torques; an innovation far beyond the noise
            model restarts it from the observation). With exact observations of the nominal robot the estimate is
            the observation to round-off. False: the observation is the state.
        filter_position_noise: the observed positions' noise the filter assumes, a standard deviation [m, rad]
            (the default is the robustness suite's ``obs_noise``). Change the ``filter_*`` fields to the sensor
            noise of the env the MPC runs in.
        filter_velocity_noise: the observed velocities' noise the filter assumes, a standard deviation
            [m/s, rad/s].
        filter_acceleration_noise: standard deviation of the accelerations the model misses [m/s^2, rad/s^2];
            larger: the estimate follows the observations more closely.
        filter_innovation_gate: threshold of the filter's innovation test (the normalized innovation squared over
            the 13 observed coordinates; 35 is exceeded by chance about once in 1000 observations).
        filter_restart_steps: consecutive observations beyond ``filter_innovation_gate`` that restart the estimate
            from the observation (1: the first). A single step beyond the gate is corrected by the filter's gain as
            any other: on a contact the filter's rigid model does not have (a soft contact whose feet sink and
            spring back, a stiff one whose impacts bounce) nearly every impact is beyond the gate, and restarting on
            each handed the measured velocities of the contact's vibration to the feedback law. A push keeps the
            innovation beyond the gate for the next observation as well and restarts the estimate one control step
            later. 1 for sensors with no single-step outliers and a model that matches the contact.
        bias_memory: time constant [s] of the estimate of a constant bias of the measured trunk height and pitch
            (None: none). A foot the contact flags put on the ground is at the ground, so the height at which the
            measurement puts it is the measurement's error seen at the foot; the two feet of a gait cycle give the
            height and the pitch bias, estimated by least squares over the observations with this forgetting
            (:class:`~hsddp_gym.planners.policies.estimation.MeasurementBias`). Once a stance has calibrated it, the
            plans land the feet on the ground where the measurement puts it and hold the trunk above it, and the
            late-landing rule (``touchdown_height``) measures a landing foot from there, and the model of the state
            filter, of the latency compensation and of the delay's estimate stands on that ground (its stance feet are
            held there, its touchdowns happen there); before, the plans search for the ground
            (``ground_search_speed``), the rule waits and the model stands on ``z = 0``. The estimate is not
            subtracted from the state: a foot that sinks into a soft contact reads as a bias too, right for where a
            landing foot stops, wrong for the trunk in a flight.
        action_delay: control steps between an action's return and its execution (None: the env's,
            ``EnvInterface.action_delay_steps``, e.g. behind :class:`hsddp_gym.envs.perturbations.ActionDelay`).
        latency_compensation: with an action delay ``d > 0``, plan and act for the state ``d`` control steps ahead,
            predicted with the model
            (:class:`~hsddp_gym.planners.policies.estimation.ContactModelPredictor`: contact dynamics, impacts,
            lift-offs, motor speed limits) from the estimated state under the ``d`` actions already sent; the gait
            clock is advanced over the prediction with the predicted contacts. False: act on the estimated state as
            if there were no delay.
        delay_search: how far the executed delay may differ from the announced one [control steps] (0: the
            announced delay is trusted). The delay ``d`` that the state filter and the latency compensation use is
            then estimated online from the robot's response to the MPC's own actions
            (:class:`~hsddp_gym.planners.policies.latency.DelayEstimator`: every control step the model predicts the
            measured velocities once per candidate ``announced - delay_search .. announced + delay_search``, each
            holding the torque that delay would have executed, and the estimate moves to the candidate that
            predicts them best by a margin): a latency announced one step wrong is found within a few control
            steps, and a rightly announced one is kept. Raise it when the latency is known only roughly; each
            candidate costs one model step (about 25 us) per control step.

    Attributes: Recovery
        lost_stance_steps: control steps a stance foot that has touched must be off the ground before the gait
            clock takes the stance as lost (0: never; see :class:`GaitClock`). Early in the stance the clock goes
            back to the flight that lands the foot and the MPC re-plans at once. With 1 no plan ever holds a foot
            that the last observation reports in the air on the ground.
        double_stance: duration [s] of a planned double stance (None: never; the authors' bounding gait has none).
            When a touchdown finds the other foot still on the ground, the gait clock enters a double stance, the
            MPC re-plans at once and its plans start with the double stance, then the stance of the foot that
            landed (:meth:`MPCPolicy._schedule`). Unperturbed bounding rarely enters one; it serves landings after
            pushes.
        flight_reach: a flight is planned to last at least until the hip of the foot that lands at its end is
            within ``flight_reach`` leg lengths of the ground (in (0, 1]; 0.85 is 0.343 m of the 0.404 m leg; None:
            the rest of the flight's nominal duration, at least ``min_phase``), the trunk flying ballistically from
            the re-plan's state (:meth:`MPCPolicy._reach_time`). After an upward push the flight outlasts its
            nominal duration; without this rule each plan would put the touchdown ``min_phase`` ahead while the
            foot is still far above the ground. At bounding height the hips are within reach, so unperturbed
            bounding is planned the same.
        restep: a *re-step*, the stance of the foot that has just lifted off once more, then the flight again
            (False: the plans and the clock wait for the landing foot, whatever the other foot does). The plans
            make one in a flight whose landing hip the ballistic flight (as for ``flight_reach``) puts out of reach
            at the flight's nominal end while the other hip (the foot of the stance before the flight) is within
            reach sooner: the rest of the flight, that foot's stance, this flight, the landing foot's stance. A
            pitch-rate kick in a flight (5-7 rad/s) lifts the landing hip while it lowers the other one; waiting for
            the landing foot lets the trunk rotate until it falls, a second stance of the other foot stops the
            rotation. The gait clock makes one when that foot lands again in the flight (after a real swing,
            debounced; at its first contact when planned, :attr:`GaitClock.restep_foot`): the clock goes on from
            its stance, which gets its nominal duration. Unperturbed bounding makes none (seeds 0-9 of the default env:
            the landing hip is within reach at every flight's end, and the foot that lifted off stays up).
        min_stance_force: the least normal force [N] every foot the plan has on the ground must be able to push
            with: the torques sent are the nearest (Euclidean) to the plan's feedback law for which the contact
            pushes with at least this force inside the plan's friction cone (``plan_friction``), within the torque
            limit (:class:`~hsddp_gym.planners.policies.contact_consistency.PushingTorques`; with a terrain, the cone
            along the surface's normal under each foot; None: the feedback law's torques as they are). Far from the
            plan (a touchdown earlier or later than planned, a push) the linear feedback law can ask a stance leg for
            torques that pull its foot off the ground or slide it; the light leg then whips away, the stance is
            lost and found again at every control step. Unperturbed bounding does not need the projection (none of
            the 10,000 control steps of seeds 0-9 of the default env; 3 with ``weights="paper"``); each control step
            in a stance costs one evaluation of the constrained dynamics (about 20 us), a projection about 0.25 ms
            (five more and Dykstra's sweeps).
        replan_feedback: re-plan at once, whatever ``replan_period`` says, when the plan's feedback term
            ``K_k (x - X_k)`` asks any motor for more than this fraction of the torque limit (> 0; None:
            re-plan every ``replan_period`` only). The feedback law is the plan's linearization; after a push, a
            touchdown the plan did not expect or a stance that ends early, the state is far from the plan, the law
            saturates the motors, the light legs whip at 50-170 rad/s, and the next periodic re-plan (up to 20 ms
            later) starts from a state that is already lost. A plan made from the present state has no feedback term
            at its first knot. Unperturbed bounding never triggers it in the 10,000 control steps of seeds 0-9 of the
            default env (4 times with ``weights="paper"``). A re-plan that fails (``stats["planner_failures"]``)
            leaves the previous plan acting and is tried again at the next control step while the feedback term stays
            that large.
        feedback_iterations: DDP iterations in each outer (augmented-Lagrangian) iteration of a warm-started
            feedback re-plan (``replan_feedback``; None: solved as a periodic re-plan, ``max_iterations`` and no
            outer-loop update). A periodic re-plan's single iteration only nudges the plan it shifts; after a push
            that plan is far off, and the switching constraints' soft penalty lets its touchdowns miss the ground
            by centimetres. The feedback re-plan, rare and made at the moment the robot is furthest from any plan,
            is solved onto them: ``feedback_iterations`` DDP iterations, then the multipliers and the penalty are
            updated (Algorithm 1) and the next outer iteration starts, ``feedback_al_iterations`` times, so at most
            ``feedback_iterations * feedback_al_iterations`` iterations (and ``time_budget``). The plan it makes is
            kept; its updated multipliers and penalty are not: the re-plans that follow start from the ones it was
            warm-started with. Its updates pull toward touchdowns that the state it was made from calls for;
            carried from one feedback re-plan to the next, they wound up (to thousands) where a touchdown could not
            be met, as for the MPC blind to the terrain of Terrain-v0. The MPC page has the measurements; a
            feedback re-plan takes about 11 ms (median) where a periodic one takes 3.5 ms.
        feedback_al_iterations: outer iterations of a feedback re-plan (>= 1; with 1 only ``feedback_iterations``
            DDP iterations and no update).
    """

    # Timing
    horizon: float | None = None
    planner_dt: float = 0.0025
    fine_dt: float | None = None
    fine_phases: int = 2
    replan_period: float = 0.02
    latency_steps: int = 0
    time_budget: float | None = None
    min_phase: float = 0.01
    debounce_steps: int = 2
    min_flight: float = 0.3
    touchdown_height: float | None = 0.01
    ground_search_speed: float | None = 0.5
    # Solver
    method: str = "al-reb"
    max_iterations: int = 1
    warmup_iterations: int = 30
    sigma_max: float = 500.0
    reb_delta: float = 0.2
    reb_eps: float = 1e-4
    integrator: str = "semi_implicit"
    refresh_gains: bool = True
    restart_ratio: float | None = 10.0
    warm_start_kd: float = 0.1
    # References
    durations: tuple | None = None
    weights: str = "later"
    z_velocity: str = "code"
    height_offset: float = 0.04
    plan_friction: float | None = 0.45
    speed_ramp: float | None = 0.5
    speed_acceleration: float | None = 1.0
    speed_integral_gain: float | None = 1.5
    speed_bias_limit: float = 0.5
    # Perception
    state_filter: bool = True
    filter_position_noise: float = 0.01
    filter_velocity_noise: float = 0.1
    filter_acceleration_noise: float = 3.0
    filter_innovation_gate: float = 35.0
    filter_restart_steps: int = 2
    bias_memory: float | None = 1.0
    action_delay: int | None = None
    latency_compensation: bool = True
    delay_search: int = 1
    # Recovery
    lost_stance_steps: int = 1
    double_stance: float | None = 0.04
    flight_reach: float | None = 0.85
    restep: bool = True
    min_stance_force: float | None = 0.0
    replan_feedback: float | None = 0.5
    feedback_iterations: int | None = 3
    feedback_al_iterations: int = 3

    @classmethod
    def from_record(cls, options: dict) -> MPCOptions:
        """The options stored in a record (``dataclasses.asdict`` of an ``MPCOptions`` as JSON: a dataset's
        ``metadata.json`` policy options, a workflow's summary) back as ``MPCOptions``. Records of earlier versions
        load too: ``weights`` None (the paper's weights, the default then) becomes ``"paper"``, and fields this
        version no longer has are left out with a ``UserWarning`` naming them."""
        if not isinstance(options, dict):
            raise TypeError(f"options must be a dict of MPCOptions fields, got {type(options).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        dropped = sorted(set(options) - known)
        if dropped:
            warnings.warn(f"MPCOptions.from_record: left out fields this version does not have: {dropped}",
                          UserWarning, stacklevel=2)
        opts = {k: v for k, v in options.items() if k in known}
        if "weights" in opts and opts["weights"] is None:
            opts["weights"] = "paper"
        if opts.get("durations") is not None:
            opts["durations"] = tuple(opts["durations"])
        return cls(**opts)

    def __post_init__(self) -> None:
        if self.horizon is not None:
            check_positive(self.horizon, "horizon")
        for name in ("planner_dt", "replan_period", "min_phase", "sigma_max"):
            check_positive(getattr(self, name), name)
        if self.fine_dt is not None:
            check_positive(self.fine_dt, "fine_dt")
            ratio = self.planner_dt / self.fine_dt
            if self.fine_dt > self.planner_dt or abs(ratio - round(ratio)) > 1e-9:
                raise ValueError(f"fine_dt must be None or planner_dt ({self.planner_dt}) divided by a whole number, "
                                 f"got {self.fine_dt!r}")
        check_int(self.fine_phases, "fine_phases", minimum=1)
        check_int(self.max_iterations, "max_iterations", minimum=1)
        check_int(self.warmup_iterations, "warmup_iterations", minimum=1)
        check_int(self.latency_steps, "latency_steps", minimum=0)
        check_int(self.debounce_steps, "debounce_steps", minimum=1)
        check_int(self.filter_restart_steps, "filter_restart_steps", minimum=1)
        if self.bias_memory is not None:
            check_positive(self.bias_memory, "bias_memory")
        check_int(self.lost_stance_steps, "lost_stance_steps", minimum=0)
        if self.double_stance is not None:
            check_positive(self.double_stance, "double_stance")
        if self.touchdown_height is not None:
            check_positive(self.touchdown_height, "touchdown_height")
        if self.ground_search_speed is not None:
            check_positive(self.ground_search_speed, "ground_search_speed")
        if not isinstance(self.restep, (bool, np.bool_)):
            raise TypeError(f"restep must be a bool, got {self.restep!r}")
        if self.min_stance_force is not None:
            check_positive(self.min_stance_force, "min_stance_force", allow_zero=True)
        if self.replan_feedback is not None:
            check_positive(self.replan_feedback, "replan_feedback")
        if self.feedback_iterations is not None:
            check_int(self.feedback_iterations, "feedback_iterations", minimum=1)
        check_int(self.feedback_al_iterations, "feedback_al_iterations", minimum=1)
        if self.flight_reach is not None:
            if check_in_range(self.flight_reach, 0.0, 1.0, "flight_reach") == 0.0:
                raise ValueError("flight_reach must be in (0, 1] (a fraction of the leg length) or None, got 0.0")
        if not (0.0 <= self.min_flight <= 1.0):
            raise ValueError(f"min_flight must be in [0, 1], got {self.min_flight!r}")
        check_positive(self.reb_delta, "reb_delta")
        check_positive(self.reb_eps, "reb_eps")
        if self.time_budget is not None:
            check_positive(self.time_budget, "time_budget")
        if self.speed_ramp is not None:
            check_positive(self.speed_ramp, "speed_ramp")
        if self.durations is not None and (len(self.durations) != 4 or any(not (d > 0) for d in self.durations)):
            raise ValueError(f"durations must be 4 positive numbers [s], got {self.durations!r}")
        if self.weights not in BOUNDING_WEIGHTS:
            raise ValueError(f"weights must be one of {BOUNDING_WEIGHTS}, got {self.weights!r}")
        if self.action_delay is not None:
            check_int(self.action_delay, "action_delay", minimum=0)
        check_int(self.delay_search, "delay_search", minimum=0)
        if self.speed_acceleration is not None:
            check_positive(self.speed_acceleration, "speed_acceleration")
        if self.plan_friction is not None:
            check_positive(self.plan_friction, "plan_friction")
        for name in ("filter_position_noise", "filter_velocity_noise", "filter_acceleration_noise",
                     "filter_innovation_gate"):
            check_positive(getattr(self, name), name)
        if self.speed_integral_gain is not None:
            check_positive(self.speed_integral_gain, "speed_integral_gain")
        check_positive(self.speed_bias_limit, "speed_bias_limit", allow_zero=True)
        for name in ("latency_compensation", "state_filter"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise TypeError(f"{name} must be a bool, got {getattr(self, name)!r}")
        check_height_offset(self.height_offset)
        if self.restart_ratio is not None and not (check_positive(self.restart_ratio, "restart_ratio") > 1.0):
            raise ValueError(f"restart_ratio must be None or > 1, got {self.restart_ratio!r}")
        if not isinstance(self.refresh_gains, (bool, np.bool_)):
            raise TypeError(f"refresh_gains must be a bool, got {self.refresh_gains!r}")
        if self.method not in ("ddp", "al", "al-reb"):
            raise ValueError(f"method must be 'ddp', 'al' or 'al-reb', got {self.method!r}")

class GaitClock:
    """The MPC's gait clock: the bounding phase ``phase`` (index into (back stance, flight, front stance,
    flight)) and the time ``tau`` spent in it, a deterministic function of the observation history.

    The plan's phase follows the contacts: a stance ends on time, a flight ends when its landing foot has touched
    for ``debounce_steps`` control steps (early, once ``min_flight`` of it has passed), or, from its nominal end on,
    at the landing foot's first contact step, however late (the clock never assumes a touchdown that has not
    happened); grazes of the other foot are ignored. A stance is *lost* when its
    foot, having touched, is off the ground for ``lost_stance_steps`` control steps (0: never): in the second
    half of the stance the stance ends; in the first half the clock goes back to the flight that lands that
    foot, with half of its nominal duration to go, and :attr:`resynced` is set for that update (the MPC then
    re-plans at once). With ``double_stance > 0``, a *double stance* (``phase`` = :data:`DOUBLE_STANCE_PHASE`)
    starts at a touchdown that finds the other foot on the ground: both feet touch and the one that touched down
    in the current phase, after a swing of at least ``min_flight`` of the flight that lands it, has touched for
    ``debounce_steps`` (in a flight, once ``min_flight`` of it has passed).
    It lasts ``double_stance`` seconds or until the other foot has lifted off for ``debounce_steps``, then the
    stance of the foot that landed follows (:attr:`resynced` is set when it starts); a foot still down when that
    stance starts does not start another double stance until it has lifted off and touched down again. With
    ``restep``, a *re-step*: in a flight, the foot of the stance before it that lands again (after a swing of at
    least ``min_flight`` of its flight, for ``debounce_steps``; at its first contact step when the planner has planned
    it, :attr:`restep_foot`) starts its stance again, :attr:`resynced` set, and the cycle goes on from there (without
    ``restep`` the clock waits for the landing foot whatever the other foot does). The first
    observation picks the phase from the contacts (and, in flight, the sign of the pitch rate).

    Because late touchdowns stretch the cycle, this clock drifts from the env's observation clock
    (``2 pi t / gait_period``): on seed 0 of the default env the MPC's phase slips by about 0.2 cycles per
    second, i.e. through a whole cycle in a 5 s episode. A learner that imitates the MPC needs this clock
    (:meth:`features`), which it can rebuild from the observations alone (:func:`gait_clock_features`).

    Args:
        durations: nominal (back stance, flight, front stance, flight) durations [s].
        dt: control period [s] (``tau`` advances by ``dt`` at every :meth:`tick`).
        debounce_steps: control steps the landing foot must touch before a flight ends (:class:`MPCOptions`).
        min_flight: fraction of the nominal flight before which a touchdown is taken for a graze.
        lost_stance_steps: control steps a stance foot must be off the ground before its stance is lost (0: never).
        double_stance: duration [s] of a double stance (0: the clock never enters one; the MPC's clock has
            ``MPCOptions.double_stance``).
        restep: whether a foot that lands again in the flight after its stance starts that stance again (the MPC's
            clock has ``MPCOptions.restep``; learners that rebuild the clock from observations use False).
    """

    def __init__(self, durations, dt: float, debounce_steps: int = 2, min_flight: float = 0.3,
                 lost_stance_steps: int = 0, double_stance: float = 0.0, restep: bool = False) -> None:
        if len(durations) != 4 or any(not (float(d) > 0) for d in durations):
            raise ValueError(f"durations must be 4 positive numbers [s], got {durations!r}")
        self.durations = tuple(float(d) for d in durations)
        self.dt = check_positive(dt, "dt")
        self.debounce_steps = check_int(debounce_steps, "debounce_steps", minimum=1)
        self.min_flight = float(min_flight)
        self.lost_stance_steps = check_int(lost_stance_steps, "lost_stance_steps", minimum=0)
        self.double_stance = check_positive(double_stance, "double_stance", allow_zero=True)
        """Duration [s] of a double stance entered now (0: the clock never enters one)."""
        if not isinstance(restep, (bool, np.bool_)):
            raise TypeError(f"restep must be a bool, got {restep!r}")
        self.restep = bool(restep)
        self.reset()

    def reset(self) -> None:
        self.phase: int | None = None
        self.tau = 0.0
        self._contact_steps = [0, 0]
        self._air_steps = [0, 0]
        self._phase_updates = 0
        """Observations since the current phase began (0 at the observation that began it)."""
        self._swing_steps = [0, 0]
        """Per foot, the observations it was in the air before its current (or last) contact began."""
        self._stance_touched = False
        self.after_double: int | None = None
        """In a double stance, the phase (0 or 2) of the single stance that follows it."""
        self.double_duration = 0.0
        """The duration [s] of the current double stance (``double_stance`` when it started)."""
        self.resynced = False
        """True when the last :meth:`update` moved the phase against the cycle (a lost stance)."""
        self.restep_foot: int | None = None
        """Set by the planner in a flight: the foot of the stance before it, when the plans put it on the ground
        again (a planned re-step, ``MPCOptions.restep``): with ``restep``, its first contact step then starts its
        stance. Cleared at every phase change."""

    def copy(self) -> GaitClock:
        twin = GaitClock(self.durations, self.dt, self.debounce_steps, self.min_flight, self.lost_stance_steps,
                         self.double_stance, self.restep)
        twin.after_double, twin.double_duration = self.after_double, self.double_duration
        twin.phase, twin.tau, twin._contact_steps = self.phase, self.tau, list(self._contact_steps)
        twin._air_steps, twin.resynced, twin._stance_touched = list(self._air_steps), self.resynced, \
            self._stance_touched
        twin._phase_updates, twin._swing_steps = self._phase_updates, list(self._swing_steps)
        twin.restep_foot = self.restep_foot
        return twin

    def update(self, mode: Mode, pitch_rate: float, elapsed=None) -> Mode:
        """Advance by the observed contact ``mode``; return the mode of the current gait phase.

        ``elapsed``: on the first observation, a function ``elapsed(phase, duration) -> float`` giving the time [s]
        already spent in the phase the observation starts (e.g. :func:`stance_elapsed` of the state); None: 0 (the
        phase has just begun). Ignored afterwards."""
        before = self.phase
        self._phase_updates += 1
        mode = self._update(mode, pitch_rate, elapsed)
        if self.phase != before:
            self._phase_updates = 0
            self.restep_foot = None
        return mode

    def _update(self, mode: Mode, pitch_rate: float, elapsed) -> Mode:
        self.resynced = False
        for foot in (FRONT, BACK):
            if mode.in_contact(foot) and not self._contact_steps[foot]:
                self._swing_steps[foot] = self._air_steps[foot]
            self._contact_steps[foot] = self._contact_steps[foot] + 1 if mode.in_contact(foot) else 0
            self._air_steps[foot] = 0 if mode.in_contact(foot) else self._air_steps[foot] + 1
        if self.phase is None:
            if mode == Mode.FLIGHT:
                self.phase = 1 if pitch_rate > 0 else 3
            else:
                self.phase = 0 if mode.in_contact(BACK) and not mode.in_contact(FRONT) else (
                    2 if not mode.in_contact(BACK) else 0)
            self.tau = 0.0
            if elapsed is not None and mode != Mode.DOUBLE_STANCE:
                duration = self.durations[self.phase]
                tau = float(elapsed(self.phase, duration))
                if not (0.0 <= tau <= duration):
                    raise ValueError(f"elapsed must give a time in [0, {duration}] s for phase {self.phase}, "
                                     f"got {tau!r}")
                self.tau = tau
            return _CYCLE[self.phase]
        j = self.phase
        if j == DOUBLE_STANCE_PHASE:
            # ends when the foot that does not stay has lifted off, or after its duration
            leaving = BACK if self.after_double == 2 else FRONT
            if self._air_steps[leaving] >= self.debounce_steps or self.tau >= self.double_duration - 1e-9:
                self.phase, self.tau, self.after_double = self.after_double, 0.0, None
                self._stance_touched = True
            return self.mode
        nominal = self.durations[j]
        if self.double_stance and self._double_starts(j, mode):
            # a swing foot landed while the stance foot is down (a stance, or a flight whose lift-off is late)
            self.after_double = 2 if _CYCLE[j] == Mode.BACK_STANCE or j == 1 else 0
            self.double_duration = self.double_stance
            self.phase, self.tau, self.resynced = DOUBLE_STANCE_PHASE, 0.0, True
            return self.mode
        touched = False
        if _CYCLE[j] == Mode.FLIGHT:
            landing = FRONT if j == 1 else BACK
            other = 1 - landing
            if self.restep and ((self.restep_foot == other and self._contact_steps[other]) or self._landed(other)):
                # a re-step: the foot of the stance before this flight is down again, its stance starts again
                self.phase, self.tau, self.resynced, self._stance_touched = (j - 1) % 4, 0.0, True, True
                return _CYCLE[self.phase]
            # debounced early in the flight (a graze is not a touchdown); from its nominal end on, any contact is
            touched = self._contact_steps[landing] >= (self.debounce_steps if self.tau < nominal - 1e-9 else 1)
            advance = touched and self.tau >= self.min_flight * self.durations[j]
        else:
            stance_foot = BACK if j == 0 else FRONT
            advance = self.tau >= nominal - 1e-9
            self._stance_touched |= mode.in_contact(stance_foot)
            if (not advance and self.lost_stance_steps and self._stance_touched
                    and self._air_steps[stance_foot] >= self.lost_stance_steps):
                # the stance foot left the ground (a push, a slip): late in the stance, the stance is over;
                # early in it, the foot has to land again, so the clock goes back to the flight that lands
                # it, with half of that flight still to come
                if self.tau >= 0.5 * nominal:
                    advance = True
                else:
                    self.phase = (j - 1) % 4
                    self.tau = 0.5 * self.durations[self.phase]
                    self._stance_touched = False
                    self.resynced = True
        if advance:
            self.phase = (j + 1) % 4
            self.tau = 0.0
            # a stance that starts at its foot's touchdown has touched: if the foot bounces off, it is lost
            self._stance_touched = touched
        return _CYCLE[self.phase]

    def _landed(self, foot: int) -> bool:
        """Whether ``foot`` has landed in the current phase: its contact began in this phase, after a swing of at
        least ``min_flight`` of the flight that lands it, and has lasted ``debounce_steps`` (a scuff, or a foot that
        stayed down from an earlier phase, has not)."""
        landing_flight = 1 if foot == FRONT else 3
        swung = self._swing_steps[foot] * self.dt >= self.min_flight * self.durations[landing_flight] - 1e-9
        return swung and self.debounce_steps <= self._contact_steps[foot] <= self._phase_updates

    @property
    def mode(self) -> Mode:
        """The contact mode of the current phase."""
        return Mode.DOUBLE_STANCE if self.phase == DOUBLE_STANCE_PHASE else _CYCLE[self.phase]

    def _double_starts(self, j: int, mode: Mode) -> bool:
        """Whether the observation starts a double stance in phase ``j``: a touchdown in this phase finds the other
        foot on the ground. In a stance, the swing foot has touched for ``debounce_steps`` while the stance foot
        touches; in a flight (once ``min_flight`` of it has passed), the landing foot has while the foot of the
        stance before it still touches. A touchdown is a landing, as for a flight's end: the touching foot's contact
        must have begun in this phase, after a swing of at least ``min_flight`` of the flight that lands it. A foot
        that has stayed down since a double stance ended on its duration is not a new touchdown (the stance that
        follows plans its lift-off instead of one double stance after another), nor is a scuff of the foot that
        has just lifted off (it would swap the gait's order: the clock would skip the stance and flight ahead)."""
        if mode != Mode.DOUBLE_STANCE:
            return False
        if _CYCLE[j] == Mode.FLIGHT:
            foot = FRONT if j == 1 else BACK
            if self.tau < self.min_flight * self.durations[j]:
                return False
        else:
            foot = FRONT if j == 0 else BACK
        return self._landed(foot)

    def tick(self) -> None:
        """One control period has passed."""
        self.tau += self.dt

    N_FEATURES = 7

    def features(self) -> np.ndarray:
        """(7,): one-hot of the phase (4), ``tau / nominal duration`` (clipped to [0, 2]) and sin, cos of the
        cycle fraction ``(start of the phase + tau) / cycle duration``; zeros before the first update."""
        f = np.zeros(self.N_FEATURES)
        if self.phase is None:
            return f
        j = self.phase
        tau = self.tau
        if j == DOUBLE_STANCE_PHASE:  # read as the start of the stance that follows
            j, tau = self.after_double, 0.0
        f[j] = 1.0
        f[4] = min(tau / self.durations[j], 2.0)
        frac = (sum(self.durations[:j]) + min(tau, self.durations[j])) / sum(self.durations)
        f[5], f[6] = math.sin(2 * math.pi * frac), math.cos(2 * math.pi * frac)
        return f


def stance_elapsed(robot, x: np.ndarray, phase: int, duration: float, min_speed: float = 0.25) -> float:
    """The time [s] already spent in bounding ``phase`` (0 back stance, 2 front stance; 0 for a flight) of nominal
    ``duration`` [s] at state ``x`` (14,), from where the stance foot is relative to its hip: a bounding stance sweeps
    its foot backward under the hip at the forward speed, symmetric about it (Raibert's neutral point), so
    ``duration / 2 - (x_foot - x_hip) / vx`` (``vx`` at least ``min_speed``), clipped to ``[0, 0.9 duration]``.
    The gait clock's start from a stance: the paper's initial state is mid back stance, not its start."""
    if _CYCLE[phase] == Mode.FLIGHT:
        return 0.0
    foot = BACK if phase == 0 else FRONT
    q = x[:NQ]
    offset = float(robot.foot_positions(q)[foot, 0] - robot.hip_positions(q)[foot, 0])
    tau = 0.5 * duration - offset / max(float(x[NQ]), min_speed)
    return float(min(max(tau, 0.0), 0.9 * duration))


def late_landing(clock: GaitClock, mode: Mode, x: np.ndarray, robot, touchdown_height: float | None,
                 terrain: Terrain | None = None, ground_offset=None) -> Mode:
    """``mode`` with the landing foot of a late flight added when the state ``x`` (14,) puts it within
    ``touchdown_height`` [m] of the ground (None: ``mode`` as it is): the plane ``z = 0``, or with a ``terrain``
    (:class:`~hsddp_gym.core.terrain.Terrain`, the state in the world frame) its surface under the foot, raised by
    ``ground_offset(q, foot)`` [m] (where the measurement puts a foot on the ground,
    :meth:`~hsddp_gym.planners.policies.estimation.MeasurementBias.ground_offset`; None: 0), evaluated only for a
    late flight's landing foot.

    A contact flag is a sample: it says whether the foot pushed on the ground at the end of the control step. On a
    stiff contact a landing foot can touch and leave within every step (it bounces at the control rate), so no
    flag ever reports the touchdown, the clock waits in the flight, and the plans keep the leg in its touchdown
    posture while the trunk sinks. From the flight's nominal end on, a landing foot at the ground is taken for
    the touchdown the flags missed. Before the nominal end the flags alone decide (a foot swung low is not a
    landing)."""
    if touchdown_height is None or clock.phase not in (1, 3):
        return mode
    if clock.tau < clock.durations[clock.phase] - 1e-9:
        return mode
    landing = FRONT if clock.phase == 1 else BACK
    if mode.in_contact(landing):
        return mode
    if robot is None:
        robot = _nominal_robot()
    offset = 0.0 if ground_offset is None else float(ground_offset(x[:NQ], landing))
    if terrain_clearance(robot, x[:NQ], landing, terrain) - offset < touchdown_height:
        return Mode(int(mode) | (1 << landing))
    return mode


def update_gait_clock(clock: GaitClock, mode: Mode, x: np.ndarray, robot=None,
                      touchdown_height: float | None = None, terrain: Terrain | None = None,
                      ground_offset=None) -> Mode:
    """Advance ``clock`` by one observation: contact ``mode`` and state ``x`` (14,) (its pitch rate; on the first
    observation the stance already elapsed, :func:`stance_elapsed` with ``robot``, default the nominal one). The one
    update rule of the MPC and of the learners that rebuild its clock from observations. ``touchdown_height``: a
    late flight's landing foot that ``x`` puts within this height [m] of the ground counts as in contact
    (:func:`late_landing`; None: the flags alone, as the learners' features use it), measured from ``terrain``'s
    surface when one is given (None: from ``z = 0``) raised by ``ground_offset(q, foot)`` (None: 0)."""
    x = check_vector(x, NX, "x")
    if clock.phase is None and robot is None:
        robot = _nominal_robot()
    mode = late_landing(clock, Mode(mode), x, robot, touchdown_height, terrain, ground_offset)
    return clock.update(mode, float(x[NQ + IPITCH]),
                        elapsed=None if clock.phase is not None else
                        (lambda phase, duration: stance_elapsed(robot, x, phase, duration)))


def env_terrain(env):
    """A function of no argument returning the terrain of ``env``'s current episode (its unwrapped env's
    ``terrain`` attribute: a :class:`~hsddp_gym.core.terrain.Terrain`, or None on flat ground), for
    ``MPCPolicy(..., terrain=env_terrain(env))``: a random terrain (``hsddp_gym/Terrain-v0``) is drawn at every
    reset of the env, and the MPC reads it at its own reset."""
    unwrapped = env.unwrapped

    def terrain():
        return getattr(unwrapped, "terrain", None)

    return terrain


@functools.lru_cache(maxsize=1)
def _nominal_robot():
    """The nominal robot model (built once per process)."""
    from hsddp_gym.core.model import CheetahModel

    return CheetahModel()


class MPCPolicy(Policy):
    """HS-DDP MPC acting from observations (see the module docstring).

    Args:
        interface: the env's public settings (``MPCPolicy.from_env(env)``).
        options: :class:`MPCOptions`.
        terrain: the ground, given to the MPC as privileged information (None, the default: the MPC plans for flat
            ground, and the feet on the ground set the height it plans from, ``bias_memory``): a
            :class:`~hsddp_gym.core.terrain.Terrain`, or a function of no argument returning the current episode's
            (a Terrain or None; called at every :meth:`reset`, e.g. :func:`env_terrain` of an env whose terrain is
            drawn at its reset: reset the env first). A flat Terrain is None. With a terrain the MPC works in the
            world frame (:attr:`terrain`, see the docs' "Terrain" section): its plans' switching constraints put a
            landing foot on the terrain under it, the reference heights follow the ground, the late-landing rule,
            the state filter's contact model and the bias estimate measure the feet from the terrain's surface,
            the stance torques keep the friction cone along its normal (``min_stance_force``), and without the
            trunk x in the observation the MPC integrates the measured forward speed for it.

    Attributes:
        terrain: the terrain of the current episode (None: flat ground).
        stats: ``replans``, ``planner_failures``, ``solve_ms`` (list), ``iterations`` (list),
            ``time_budget_stops`` (re-plans stopped by ``time_budget``: their best iterate is used, as any-time
            MPC does, and counted here rather than as failures), ``restarts`` and ``restarts_kept``
            (``MPCOptions.restart_ratio``), ``delay_changes`` (``MPCOptions.delay_search``) and
            ``feedback_replans`` (re-plans made at once by ``MPCOptions.replan_feedback``, also counted in
            ``replans`` when they succeed).
        last_solution: the latest plan (a :class:`~hsddp_gym.planners.optimizer.solution.Solution`).
        restep_foot: the foot (``FRONT`` or ``BACK``) the latest schedule plans a re-step with (None: none;
            ``MPCOptions.restep``).
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), options: MPCOptions = MPCOptions(),
                 terrain=None) -> None:
        super().__init__(interface)
        if not isinstance(options, MPCOptions):
            raise TypeError(f"options must be an MPCOptions, got {type(options).__name__}")
        if terrain is not None and not isinstance(terrain, Terrain) and not callable(terrain):
            raise TypeError(f"terrain must be None, a Terrain or a function returning the episode's Terrain "
                            f"(e.g. env_terrain(env)), got {type(terrain).__name__}")
        self.terrain_source = terrain
        """The ``terrain`` argument (None, a Terrain or a function returning one)."""
        self.terrain: Terrain | None = None
        self.options = options
        if options.durations is not None:
            self.durations = tuple(float(d) for d in options.durations)
        else:
            self.durations = PAPER_BOUNDING_DURATIONS
        self.weights = options.weights
        self.horizon = options.horizon if options.horizon is not None else float(sum(self.durations))
        # times [s] at which _reach_time looks for the landing hip's reach: the plan's knots over its horizon
        self._reach_grid = np.arange(0.0, self.horizon + 0.5 * options.planner_dt, options.planner_dt)
        self.dynamics = HybridDynamics(dt=options.planner_dt, integrator=options.integrator)
        self.announced_delay = (options.action_delay if options.action_delay is not None
                                else interface.action_delay_steps)
        """The action delay the MPC is told [control steps] (``MPCOptions.action_delay`` or the env's)."""
        self.action_delay = self.announced_delay
        """Control steps between an action's return and its execution, the latency compensated for: the announced
        delay, or its online estimate (``MPCOptions.delay_search``), updated every control step."""
        self._delay_estimator = DelayEstimator(self._make_predictor(), self.announced_delay, options.delay_search) \
            if options.delay_search > 0 else None
        self._predictor = self._make_predictor()
        self._filter = self._make_filter()
        self._bias = None if options.bias_memory is None else \
            MeasurementBias(self.dynamics.robot, interface.control_dt, options.bias_memory)
        params = self.dynamics.robot.params
        self._constraints = None if options.plan_friction is None else ConstraintSpec(
            torque_limit=params.torque_limit, friction=options.plan_friction)
        self._pushing = self._make_pushing()
        self._startup_controller = HeuristicBoundingController(gains=HeuristicGains(speed=interface.target_speed),
                                                               height_offset=options.height_offset)
        """Acts while no plan exists yet (the episode's first re-plan failed): the schedule-driven heuristic
        (stateless, ``torque(x, mode)``), fed the gait clock's mode."""
        self._warm_controller = HeuristicBoundingController(
            gains=HeuristicGains(speed=interface.target_speed, kd=(options.warm_start_kd,) * 4),
            height_offset=options.height_offset)
        self.reset()

    def _make_predictor(self) -> ContactModelPredictor:
        i = self.interface
        return ContactModelPredictor(i.control_dt, motor_speed_limits=i.motor_speed_limits,
                                     torque_limit=i.torque_limit)

    def _make_filter(self) -> StateFilter:
        o = self.options
        return StateFilter(ContactModelPredictor(self.interface.control_dt,
                                                 motor_speed_limits=self.interface.motor_speed_limits,
                                                 torque_limit=self.interface.torque_limit),
                           o.filter_position_noise, o.filter_velocity_noise, o.filter_acceleration_noise,
                           o.filter_innovation_gate, o.filter_restart_steps)

    def _make_pushing(self) -> PushingTorques | None:
        """The projection of the feedback law's torques (``min_stance_force``; its own constrained dynamics)."""
        o = self.options
        if o.min_stance_force is None:
            return None
        friction = o.plan_friction if o.plan_friction is not None else self.dynamics.robot.params.friction
        return PushingTorques(self.interface.torque_limit, o.min_stance_force, friction)

    def _reset_copy_state(self) -> None:
        self.dynamics = HybridDynamics(dt=self.options.planner_dt, integrator=self.options.integrator)
        self._predictor = self._make_predictor()
        self._filter = self._make_filter()
        self._pushing = self._make_pushing()
        if self._bias is not None:
            self._bias = MeasurementBias(self.dynamics.robot, self.interface.control_dt, self.options.bias_memory)

    def reset(self) -> None:
        self._solver = HSDDP(SolverOptions(method=self.options.method))
        self._restart_solver = HSDDP(SolverOptions(method=self.options.method))
        """Solves the restarts (``restart_ratio``); swapped with :attr:`_solver` when its plan is kept, so that
        :attr:`_solver` always holds the kept plan's backward pass and outer-loop state."""
        self.tracker: PlanTracker | None = None
        self._pending: tuple | None = None
        self.last_solution = None
        self._problem = None
        self._cs: ConstraintState | None = None
        o = self.options
        self.clock = GaitClock(self.durations, self.interface.control_dt, o.debounce_steps, o.min_flight,
                               o.lost_stance_steps, o.double_stance or 0.0, o.restep)
        self._plan_clock = self.clock
        # the last actions returned (oldest first), as many as the largest delay considered + 1: with a delay d,
        # _sent[-1 - d] was executed over the last control period and the d after it are still to be executed
        # (zeros before the first ones, as the env's delay queue)
        self.action_delay = self.announced_delay
        history = self._delay_estimator.history if self._delay_estimator is not None else self.announced_delay + 1
        if self._delay_estimator is not None:
            self._delay_estimator.reset()
        self._sent = collections.deque((np.zeros(NU, dtype=np.float32) for _ in range(history)), maxlen=history)
        self._last_observed: np.ndarray | None = None  # the previous observation's state, for the delay estimate
        self._filter.reset()
        if self._bias is not None:
            self._bias.reset()
        self._set_terrain()
        self._odometry: tuple[float, float] | None = None  # (trunk x [m], forward speed [m/s]) at the last obs
        self._first_obs = True
        self.restep_foot: int | None = None
        self._start_speed: float | None = None
        self.last_estimate: np.ndarray | None = None
        self.last_prediction: np.ndarray | None = None
        """The state (14,) the last action was computed for: the observed state, or with latency compensation
        the state predicted ``action_delay`` steps ahead."""
        self._since_replan = np.inf
        self.stats = {"replans": 0, "restarts": 0, "restarts_kept": 0, "planner_failures": 0, "solve_ms": [],
                      "iterations": [], "time_budget_stops": 0, "delay_changes": 0, "feedback_replans": 0}
        self._time = 0.0  # env time since reset [s]
        self.speed_bias = 0.0
        """The integral action on the plans' speed reference [m/s] (``MPCOptions.speed_integral_gain``)."""
        n_cycle = max(1, round(sum(self.durations) / self.interface.control_dt))
        self._vx_window = collections.deque(maxlen=n_cycle)  # estimated forward speeds of the last gait cycle
        self._ref_window = collections.deque(maxlen=n_cycle)  # the speed references at the same steps
        self._bias_time = 0.0

    def _set_terrain(self) -> None:
        """Read the episode's terrain (``terrain``) and give it to the models that see the ground."""
        source = self.terrain_source
        if source is None:
            return
        name = "terrain"
        if not isinstance(source, Terrain):
            source, name = source(), "terrain()"
        terrain = check_terrain(source, name)
        self.terrain = None if terrain is None or terrain.is_flat else terrain
        for predictor in (self._predictor, self._filter.predictor,
                          None if self._delay_estimator is None else self._delay_estimator.predictor):
            if predictor is not None:
                predictor.set_terrain(self.terrain)
        if self._bias is not None:
            self._bias.terrain = self.terrain

    def _trunk_x(self, x_obs: np.ndarray) -> np.ndarray:
        """On a terrain, without the trunk x in the observation: ``x_obs`` (14,) with its x set to the trapezoidal
        integral of the measured forward speed since the first observation (at x = 0, the env's start up to its reset
        noise). The MPC needs to know where it is on the terrain."""
        if self.terrain is None or not self.interface.layout.exclude_current_positions:
            return x_obs
        vx = float(x_obs[NQ])
        if self._odometry is None:
            self._odometry = (0.0, vx)
        else:
            x0, v0 = self._odometry
            self._odometry = (x0 + 0.5 * (v0 + vx) * self.interface.control_dt, vx)
        x_obs = x_obs.copy()
        x_obs[0] = self._odometry[0]
        return x_obs

    def _ground(self, xs) -> np.ndarray:
        """The ground [m] under the trunk x ``xs`` (any shape) [m]: the mean of the terrain under its two hips (the
        trunk level), 0 without a terrain."""
        xs = np.asarray(xs, dtype=np.float64)
        if self.terrain is None:
            return np.zeros_like(xs)
        hip = self.dynamics.robot.params.hip_offset
        return 0.5 * (self.terrain.support_heights(xs - hip) + self.terrain.support_heights(xs + hip))

    def _level(self, x: np.ndarray) -> np.ndarray:
        """``x`` (14,) with its height measured from :meth:`_ground` (``x`` itself without a terrain): for the
        heuristic controllers, which hold a trunk height above flat ground."""
        if self.terrain is None:
            return x
        x = np.array(x, dtype=np.float64)
        x[IZ] -= float(self._ground(x[0]))
        return x

    # ------------------------------------------------------------------ gait clock
    @property
    def _phase_j(self) -> int | None:
        return self._plan_clock.phase

    @property
    def _tau(self) -> float:
        return self._plan_clock.tau

    def _update_clock(self, mode: Mode, x: np.ndarray) -> Mode:
        """Advance the gait clock (:class:`GaitClock`) by the observed contacts; return the current phase's mode."""
        # the state says where a foot is relative to the ground once the feet on it have calibrated the measured
        # height (MeasurementBias; before the first stance of an episode, the flags alone)
        height = self.options.touchdown_height if self._bias is None or self._bias.calibrated else None
        offset = None if self._bias is None else self._bias.ground_offset
        return update_gait_clock(self.clock, mode, x, self.dynamics.robot, height, self.terrain, offset)

    def _schedule(self, x: np.ndarray | None = None) -> ModeSchedule:
        """Schedule from the gait clock: the current phase for the rest of its nominal duration (at least
        ``min_phase``; a double stance for the rest of its duration, then the stance that follows it; a flight at
        least until the landing hip can reach the ground from ``x``, and planned as the other foot's stance when that
        foot is back on the ground), then the bounding cycle until ``horizon`` is covered, ending after a stance.

        Args:
            x: the re-plan's state (14,), for ``flight_reach`` (None: the flight's nominal duration)."""
        o = self.options
        j = self._phase_j
        self.restep_foot = None
        if j == DOUBLE_STANCE_PHASE:  # the double stance, then the cycle from the stance that follows it
            j = self._plan_clock.after_double
            modes = [Mode.DOUBLE_STANCE, _CYCLE[j]]
            durs = [max(self._plan_clock.double_duration - self._tau, o.min_phase), self.durations[j]]
        else:
            modes, durs = [_CYCLE[j]], [max(self.durations[j] - self._tau, o.min_phase)]
            restep = False
            if _CYCLE[j] == Mode.FLIGHT and o.flight_reach is not None and x is not None:
                # a flight lasts at least until the landing foot can reach the ground
                if o.restep:
                    end = self._reach_time(x, _CYCLE[(j + 1) % 4], durs[0])
                    restep = end > self._reach_time(x, _CYCLE[(j - 1) % 4], durs[0])
                if not restep:
                    durs[0] = max(durs[0], self._reach_time(x, _CYCLE[(j + 1) % 4]))
            self.restep_foot = (BACK if j == 1 else FRONT) if restep else None
            if restep:
                # the landing hip is out of reach at the flight's end and the other one is within it: step again
                # with the other foot (the stance before this flight, then this flight again)
                j = (j - 1) % 4
                modes, durs = [Mode.FLIGHT, _CYCLE[j]], [durs[0], self.durations[j]]
        while sum(durs) < self.horizon - 1e-9 or _CYCLE[j] == Mode.FLIGHT:
            j = (j + 1) % 4
            modes.append(_CYCLE[j])
            durs.append(self.durations[j])
        # every duration on the coarse grid, so that a phase keeps its duration when it moves onto the fine grid of
        # the first phases at a later re-plan (fine_dt divides planner_dt)
        h = o.planner_dt
        durs = [max(1, round(d / h)) * h for d in durs]
        return ModeSchedule(modes, durs, final_mode=_CYCLE[(j + 1) % 4])

    def _reach_time(self, x: np.ndarray, stance: Mode, after: float = 0.0) -> float:
        """``flight_reach``: the time [s] from state ``x`` (14,) until the hip of the foot that lands in ``stance``
        is within ``flight_reach`` x the leg length of the ground, the trunk flying ballistically (its velocity,
        gravity, its pitch rate held); 0 when it already is, the plan's horizon when it is not within it. With
        ``after`` [s], the first such time at or after it (``after`` itself when the hip is within reach then)."""
        params = self.dynamics.robot.params
        side = 1.0 if stance == Mode.FRONT_STANCE else -1.0  # the front hip is at +hip_offset along the trunk
        reach = self.options.flight_reach * params.leg_length
        t = self._reach_grid
        if after > 0.0:
            t = t[t >= after - 1e-9]
            if not t.size:
                return float(self._reach_grid[-1])
        z = x[IZ] + x[NQ + IZ] * t - 0.5 * params.gravity * t * t - side * params.hip_offset * np.sin(
            x[IPITCH] + x[NQ + IPITCH] * t)
        if self.terrain is not None:  # the hip's height above the terrain under it
            z = z - self.terrain.support_heights(x[0] + x[NQ] * t + side * params.hip_offset * np.cos(
                x[IPITCH] + x[NQ + IPITCH] * t))
        below = np.flatnonzero(z <= reach)
        return float(t[below[0]]) if below.size else float(t[-1])

    def _phase_steps(self, n: int) -> list[float]:
        """The knot spacing [s] of each of ``n`` plan phases: ``fine_dt`` for the first ``fine_phases``, then
        ``planner_dt``."""
        o = self.options
        fine = o.planner_dt if o.fine_dt is None else o.fine_dt
        return [fine if i < o.fine_phases else o.planner_dt for i in range(n)]

    # ------------------------------------------------------------------ warm start
    def _warm_start(self, problem: HybridProblem, x: np.ndarray):
        """Shift the previous plan onto ``problem`` phase by phase: ``(U, X, K, lam)`` or None."""
        tr, prev = self.tracker, self.last_solution
        if tr is None or prev is None:
            return None
        N = problem.n_knots
        U = np.zeros((N, NU))
        X = np.zeros((N + 1, NX))
        K = np.zeros((N, NU, NX))
        lam = np.zeros(problem.n_phases)
        have = np.zeros(N, dtype=bool)
        prev_len = np.diff(prev.phase_start)
        # the previous plan's phase that matches the current one: the cursor's, the one before it (the
        # contact switch is late) or the one after it
        first = problem.schedule.modes[0]
        if tr.modes[tr.phase] == first:
            p0, offset0 = tr.phase, tr.local_time
        elif tr.phase > 0 and tr.modes[tr.phase - 1] == first:
            p0 = tr.phase - 1
            offset0 = (prev_len[p0] - 1) * tr.phase_dt[p0]
        elif tr.phase + 1 < tr.n_phases and tr.modes[tr.phase + 1] == first:
            p0, offset0 = tr.phase + 1, 0.0
        else:
            return None
        for j in range(problem.n_phases):
            a, b = problem.phase_start[j], problem.phase_start[j + 1]
            p = p0 + j
            local = np.arange(b - a)  # knot index within the phase
            if p < tr.n_phases and tr.modes[p] == problem.schedule.modes[j]:
                lam[j] = self._prev_lam[p] if self._prev_lam is not None else 0.0
                offset = offset0 if j == 0 else 0.0
                t_local = offset + local * problem.phase_dt[j]
                kp = prev.phase_start[p] + np.minimum((t_local / tr.phase_dt[p] + 1e-9).astype(np.int64),
                                                      prev_len[p] - 1)
                U[a:b], X[a:b], K[a:b] = prev.U[kp], prev.X[kp], prev.K[kp]
                have[a:b] = True
            elif j >= 4:
                lam[j] = lam[j - 4]
                src = problem.phase_start[j - 4]
                ks = src + np.minimum(local, problem.phase_start[j - 3] - src - 1)  # all before a
                U[a:b], X[a:b], K[a:b] = U[ks], X[ks], K[ks]
                have[a:b] = have[ks]
        if not have.all():
            return None
        X[N] = X[N - 1]
        X[:, 0] += x[0] - X[0, 0]
        return U, X, K, lam

    def _heuristic_controls(self, problem: HybridProblem) -> np.ndarray:
        from hsddp_gym.core.rollout import rollout

        ctrl = self._warm_controller.as_schedule_controller(problem.schedule)
        # the planner's dynamics do not depend on the ground's height: the heuristic acts from its level
        traj = rollout(problem.dynamics, problem.schedule, self._level(problem.x0), controller=ctrl)
        if not traj.is_finite:
            raise RuntimeError("heuristic warm start diverged")
        if traj.U.shape[0] == problem.n_knots:
            return traj.U
        # a multi-rate plan: sample the uniform-grid rollout at the times of the plan's knots, phase by phase
        src = np.concatenate([[0], np.cumsum(problem.schedule.knots(problem.dt))])
        U = np.empty((problem.n_knots, NU))
        for j in range(problem.n_phases):
            a, b = problem.phase_start[j], problem.phase_start[j + 1]
            n_src = src[j + 1] - src[j]
            for k in range(a, b):
                U[k] = traj.U[src[j] + min(int((k - a) * problem.phase_dt[j] / problem.dt + 1e-9), n_src - 1)]
        return U

    # ------------------------------------------------------------------ re-plan
    def reference_speed(self) -> float:
        """The forward speed [m/s] the robot should have now: the target, reached from the episode's start speed
        at ``speed_acceleration`` at most."""
        target = self.interface.target_speed
        acc = self.options.speed_acceleration
        if acc is not None and self._start_speed is not None:
            reach = acc * self._time
            target = min(max(target, self._start_speed - reach), self._start_speed + reach)
        return float(target)

    def _update_speed_bias(self) -> None:
        """Integral action (``speed_integral_gain``): once a whole gait cycle has been observed, move
        :attr:`speed_bias` by ``gain * elapsed * (mean reference - mean estimated speed)`` over the last cycle
        (both means over the same steps, so a ramping reference does not wind it up), clipped to
        ``speed_bias_limit``. Offset-free tracking of the speed whatever makes the closed loop lag its plans
        (the cost's trade-offs at high speed, model error)."""
        gain = self.options.speed_integral_gain
        elapsed, self._bias_time = self._time - self._bias_time, self._time
        if gain is None or len(self._vx_window) < self._vx_window.maxlen:
            return
        err = (sum(self._ref_window) - sum(self._vx_window)) / len(self._vx_window)
        lim = self.options.speed_bias_limit
        self.speed_bias = float(min(max(self.speed_bias + gain * elapsed * err, -lim), lim))

    def plan_speed(self, x: np.ndarray) -> float:
        """The forward-speed reference [m/s] of a plan from state ``x`` (14,): :meth:`reference_speed` plus
        :attr:`speed_bias`, moved at most ``speed_ramp`` from the measured speed (None: not moved)."""
        target = self.reference_speed() + self.speed_bias
        ramp = self.options.speed_ramp
        if ramp is None:
            return float(target)
        vx = float(x[NQ])
        return float(min(max(target, vx - ramp), vx + ramp))

    def replan(self, x: np.ndarray, mode: Mode, feedback: bool = False) -> bool:
        """Plan from state ``x`` (14,) in (effective) contact ``mode``; returns True on success. ``feedback``: a
        re-plan made at once because the feedback law would saturate (``replan_feedback``), solved with
        ``feedback_iterations`` and ``feedback_al_iterations`` when it is warm-started."""
        o = self.options
        t0 = time.perf_counter()
        schedule = self._schedule(x)
        self.clock.restep_foot = self.restep_foot
        knots = [max(1, round(d / h)) for d, h in zip(schedule.durations, self._phase_steps(len(schedule)))]
        speed = self.plan_speed(x)
        ground, terrain = self._plan_terrain(schedule, float(x[0]), speed)
        problem = HybridProblem.bounding(schedule=schedule, x0=x, speed=speed,
                                         dynamics=self.dynamics, constraints=self._constraints,
                                         z_velocity=o.z_velocity, weights=self.weights,
                                         knots=np.array(knots, dtype=np.int64), height_offset=o.height_offset,
                                         ground=ground, terrain=terrain)
        try:
            ws = None if self.last_solution is None else self._warm_start(problem, x)
        except ValueError:
            ws = None
        # a plan from scratch (the episode's first, or the previous plan does not cover this schedule's phases, e.g.
        # after a lost stance at start-up) gets the first plan's iterations; a shifted plan, max_iterations
        cold = ws is None
        iters = o.warmup_iterations if cold else o.max_iterations
        outer, total = (4 if cold else 2), iters
        further = feedback and not cold and o.feedback_iterations is not None
        if further:
            # far from the plan: solve further, onto the switching constraints (outer-loop updates in between)
            iters, outer = o.feedback_iterations, o.feedback_al_iterations
            total = iters * outer
        self._solver.options = SolverOptions(method=o.method, max_ddp_iterations=iters,
                                             max_total_ddp_iterations=total, time_limit=o.time_budget,
                                             max_al_iterations=outer, refresh_gains=o.refresh_gains)
        try:
            sol = None
            if ws is not None:
                U, X, K, lam = ws
                cs = self._cs.copy() if self._cs is not None else None
                if cs is not None:
                    cs.lam = lam
                    cs.sigma = min(cs.sigma, o.sigma_max)
                    cs.delta_torque = cs.delta_grf = o.reb_delta
                    cs.eps_torque = cs.eps_grf = o.reb_eps
                U = np.clip(U, -self.interface.torque_limit, self.interface.torque_limit)
                # warm starts, most informed first: shifted plan with its feedback law, then open loop
                for X_init, K_init in ((X, K), (None, None)):
                    try:
                        sol = self._solver.solve(problem, U, X_init=X_init, K_init=K_init, constraint_state=cs)
                    except ValueError:
                        sol = None
                    if sol is not None:
                        break
            if sol is None:
                sol = self._solver.solve(problem, self._cold_controls(problem))
            if (o.restart_ratio is not None and not cold
                    and not (sol.objective <= o.restart_ratio * max(self.last_solution.objective, 1.0))):
                sol = self._restart(problem, sol)
            if not (np.all(np.isfinite(sol.X)) and np.all(np.isfinite(sol.K))) or sol.status == "diverged":
                raise RuntimeError(f"planner status {sol.status}")
        except (RuntimeError, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            self.last_failure = f"{type(exc).__name__}: {exc}"
            self.stats["planner_failures"] += 1
            self.stats["solve_ms"].append(1e3 * (time.perf_counter() - t0))
            return False
        cs = self._solver.last_constraint_state
        if further and cs is not None and self._cs is not None:
            # keep the plan, not its outer-loop updates: the next re-plans start from this one's warm start (also
            # when a restart from scratch was kept: its multipliers are this state's updates too)
            cs = cs.copy()
            cs.lam = ws[3].copy()
            cs.sigma = min(self._cs.sigma, o.sigma_max)
        self._cs = cs
        self.stats["replans"] += 1
        self.stats["time_budget_stops"] += int(sol.status == "time_limit")
        self.stats["solve_ms"].append(1e3 * (time.perf_counter() - t0))
        self.stats["iterations"].append(sol.ddp_iterations)
        new_tracker = PlanTracker.from_solution(sol, problem)
        self._pending = (new_tracker, sol, problem, cs.lam.copy() if cs is not None else None, o.latency_steps)
        return True

    def _plan_ground(self) -> float:
        """The height [m] at which a plan made now puts the ground in the measurement's frame, above the flat ground
        (or :attr:`terrain`): with a calibrated bias estimate, its height bias (where the measurement puts a foot that
        stands on the ground, :class:`~hsddp_gym.planners.policies.estimation.MeasurementBias`); before the
        calibration, 0, lowered in a flight past its nominal end by ``ground_search_speed`` times the lateness, at
        most the estimate's height bound (the search for the ground); 0 without an estimate."""
        bias = self._bias
        if bias is None:
            return 0.0
        if bias.calibrated:
            return float(bias.bias[IZ])
        speed, clock = self.options.ground_search_speed, self.clock
        if speed is None or clock.phase not in (1, 3):
            return 0.0
        late = clock.tau - clock.durations[clock.phase]
        if late < -1e-9:
            return 0.0
        return -float(min(speed * max(late, 0.0), bias.limit[0]))

    def _model_ground(self) -> float:
        """The height [m] of the ground on which the state filter, the latency compensation and the delay's estimate
        put the model, in the measurement's frame: the calibrated height bias, as :meth:`_plan_ground`, and 0 before
        the calibration (no search: the model's ground moves only with what the feet have measured)."""
        bias = self._bias
        return float(bias.bias[IZ]) if bias is not None and bias.calibrated else 0.0

    def _plan_terrain(self, schedule: ModeSchedule, x: float, speed: float
                      ) -> tuple[np.ndarray | None, Terrain | None]:
        """The ground of a plan of ``schedule`` from trunk x ``x`` [m] at ``speed`` [m/s]: ``(ground, terrain)``,
        both None on the flat ground ``z = 0`` (no :attr:`terrain`, :meth:`_plan_ground` 0). Else ``ground (n,)``
        [m], each phase's reference trunk heights raised by the ground under the trunk where it is expected at the
        phase's end (:meth:`_ground`) plus :meth:`_plan_ground`, and ``terrain`` the ground of the switching
        constraints (a landing foot's height above it): :attr:`terrain` (None: flat) raised by
        :meth:`_plan_ground`."""
        level = self._plan_ground()
        if self.terrain is None and level == 0.0:
            return None, None
        ends = x + speed * np.cumsum(schedule.durations)
        terrain = self.terrain
        if level != 0.0:
            terrain = (Terrain.flat() if terrain is None else terrain).raised(level)
        return self._ground(ends) + level, terrain

    def _cold_controls(self, problem: HybridProblem) -> np.ndarray:
        """Controls ``(N, 4)`` to solve ``problem`` from scratch: the warm-start heuristic's rollout, or zero torques
        if that rollout diverges from this state."""
        try:
            return self._heuristic_controls(problem)
        except RuntimeError:
            return np.zeros((problem.n_knots, NU))

    def _restart(self, problem: HybridProblem, sol):
        """``restart_ratio``: solve ``problem`` again from scratch (``warmup_iterations``, the solver's own outer
        loop) after the warm-started ``sol`` ended far above the previous plan's objective; the plan with the lower
        objective is returned, and :attr:`_solver` is the solver that made it (its outer-loop state is carried). A
        restart whose warm start cannot be rolled out (ValueError) or that diverges keeps ``sol``: it counts in
        ``stats["restarts"]`` and not in ``stats["restarts_kept"]``."""
        o = self.options
        self.stats["restarts"] += 1
        solver = self._restart_solver
        solver.options = SolverOptions(method=o.method, max_ddp_iterations=o.warmup_iterations,
                                       max_total_ddp_iterations=o.warmup_iterations, time_limit=o.time_budget,
                                       max_al_iterations=4, refresh_gains=o.refresh_gains)
        try:
            fresh = solver.solve(problem, self._cold_controls(problem))
        except ValueError:
            return sol
        if (fresh.status != "diverged" and np.all(np.isfinite(fresh.X)) and np.all(np.isfinite(fresh.K))
                and fresh.objective < sol.objective):
            self.stats["restarts_kept"] += 1
            self._solver, self._restart_solver = solver, self._solver
            return fresh
        return sol

    def _activate_pending(self) -> None:
        tracker, sol, problem, lam, _ = self._pending
        if self.tracker is not None and self._pending[4] > 0:
            # the plan was computed latency steps ago: move its cursor to now
            tracker.advance(self._pending[4] * self.interface.control_dt)
        self.tracker, self.last_solution, self._problem, self._prev_lam = tracker, sol, problem, lam
        self._pending = None

    # ------------------------------------------------------------------ act
    def act(self, obs: np.ndarray) -> np.ndarray:
        """The plan's feedback law at the cursor, re-planning every ``replan_period`` (at once after a lost stance or
        a double stance's start); before the first plan exists, the start-up controller
        (:attr:`_startup_controller`)."""
        x_obs, mode, _ = self._parse(obs)
        x_obs = self._trunk_x(x_obs)
        o = self.options
        if self._bias is not None:
            self._bias.update(x_obs, mode)
        ground = self._model_ground()
        if self._delay_estimator is not None:
            if self._last_observed is not None:
                torques = np.array(self._sent, dtype=np.float64) * self.interface.torque_limit
                delay = self._delay_estimator.update(self._last_observed, x_obs, torques, ground)
                if delay != self.action_delay:
                    self.stats["delay_changes"] += 1
                    self.action_delay = delay
            self._last_observed = x_obs.copy()
        if o.state_filter:
            executed = None if self._first_obs else \
                self._sent[-1 - self.action_delay].astype(np.float64) * self.interface.torque_limit
            x_obs = self._filter.update(x_obs, mode, executed, ground)
        if self._first_obs:
            self._start_speed = float(x_obs[NQ])
        self._first_obs = False
        self.last_estimate = x_obs
        self._vx_window.append(float(x_obs[NQ]))
        self._ref_window.append(self.reference_speed())
        eff = self._update_clock(mode, x_obs)
        x, eff = self._predict_ahead(x_obs, mode, eff, ground)
        self.last_prediction = x.copy()
        if self.tracker is not None:
            self.tracker.sync(eff)
        if self.clock.resynced or self._plan_clock.resynced:
            self._since_replan = np.inf  # the schedule changed against the cycle: re-plan now
        if self._since_replan >= self.options.replan_period - 1e-9:
            self._since_replan = 0.0
            self._update_speed_bias()
            if self.replan(x, eff) and (self.tracker is None or self._pending[4] == 0):
                self._activate_pending()
        elif self._pending is not None:
            tracker, sol, problem, lam, steps = self._pending
            steps -= 1
            self._pending = (tracker, sol, problem, lam, steps)
            if steps <= 0:
                self._pending = (tracker, sol, problem, lam, self.options.latency_steps)
                self._activate_pending()
        if self.tracker is None:
            u = self._startup_controller.torque(self._level(x), eff)
        else:
            u = self.tracker.control(x)
            if (o.replan_feedback is not None and self._since_replan > 0.0
                    and np.abs(u - self.tracker.U[self.tracker.knot]).max()
                    > o.replan_feedback * self.interface.torque_limit):
                # far from the plan the feedback law alone would saturate the motors: plan again from here
                self.stats["feedback_replans"] += 1
                self._since_replan = 0.0
                if self.replan(x, eff, feedback=True) and self._pending[4] == 0:
                    self._activate_pending()
                    u = self.tracker.control(x)
            plan_mode = self.tracker.modes[self.tracker.phase]
            if self._pushing is not None and plan_mode != Mode.FLIGHT:
                normals = None if self.terrain is None else \
                    self.terrain.surface_normals(self.dynamics.robot.foot_positions(x[:NQ])[:, 0])
                u = self._pushing(x, u, plan_mode, normals)
            self.tracker.advance(self.interface.control_dt)
        self.clock.tick()
        self._since_replan += self.interface.control_dt
        self._time += self.interface.control_dt
        action = self.interface.action_from_torque(u)
        self._sent.append(action)
        return action

    def note_sent_action(self, action) -> None:
        """Tell the MPC that ``action`` (4,) (normalized, as :meth:`act` returns them) was sent to the env in place
        of the one it returned last (a learner's action in a DAgger rollout, the expert's action plus DART noise):
        its state filter and latency compensation then predict with the action the env executes."""
        a = np.asarray(action, dtype=np.float32)
        if a.shape != (NU,) or not np.all(np.isfinite(a)):
            raise ValueError(f"action must be a finite vector of shape ({NU},), got {a!r}")
        self._sent[-1] = a.copy()

    def _predict_ahead(self, x: np.ndarray, mode: Mode, eff: Mode, ground: float = 0.0) -> tuple[np.ndarray, Mode]:
        """Latency compensation (``MPCOptions.latency_compensation``): the state (14,) ``action_delay`` control
        steps after the observed ``x``, under the actions already sent, and the gait clock advanced over the
        prediction with the predicted contacts (in :attr:`_plan_clock`), on the model's ``ground`` [m]
        (:meth:`_model_ground`); returns ``(state, clock mode)``.
        Without a delay (or compensation) the observed state and clock."""
        self._plan_clock = self.clock
        if not self.action_delay or not self.options.latency_compensation:
            return x, eff
        clock = self.clock.copy()
        xp = x
        try:
            for a in list(self._sent)[len(self._sent) - self.action_delay:]:  # the actions still to be executed
                xp, mode = self._predictor.step(xp, a.astype(np.float64) * self.interface.torque_limit, mode, ground)
                clock.tick()
                eff = clock.update(mode, float(xp[NQ + IPITCH]))
        except (ArithmeticError, ValueError, RuntimeError, np.linalg.LinAlgError):
            return x, self.clock.mode
        self._plan_clock = clock
        return xp, eff

    _prev_lam = None
