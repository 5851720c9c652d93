"""The MPC's settings: [`MPCOptions`][MPCOptions], five small groups and one field.

Every field has one line here; what each setting does, when to change it and what it was measured to do are on the
documentation site's MPC options page. ``MPCOptions()`` is the configuration evaluated in the results pages.

Flat names: the settings of earlier versions were one flat list (``replan_period``, ``touchdown_height``, ...).
[`FLAT_FIELDS`][FLAT_FIELDS] maps each flat name onto its group and field, so that
[`MPCOptions.from_record`][MPCOptions.from_record] loads a record written with flat options,
[`MPCOptions.replace`][MPCOptions.replace] takes either spelling, and the experiment scripts' ``--mpc-options
'{"touchdown_height": null}'`` keep working as recorded. Settings that earlier versions had and this one does not
([`FIXED_SETTINGS`][FIXED_SETTINGS]: rejected variants and constants) load when they hold the value this version always
uses, and are left out with a ``UserWarning`` naming them otherwise. """

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from hsddp_gym.core.references import check_height_offset
from hsddp_gym.util.validation import check_in_range, check_int, check_positive

FAST_BOUNDING_DURATIONS = (0.080, 0.100, 0.080, 0.100)
"""The authors' 1.5 m/s bounding durations (original_code_facts §3.2, MH HEAD): ``PlanOptions(durations=...)``."""


def _optional_positive(value, name: str, allow_zero: bool = False):
    return None if value is None else check_positive(value, name, allow_zero=allow_zero)


def _check_bool(value, name: str) -> None:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a bool, got {value!r}")


@dataclasses.dataclass(frozen=True)
class PlanOptions:
    """What a plan is.

    Attributes:
        horizon: the least planned time [s] (None: one gait cycle of ``durations``).
        planner_dt: the plans' knot spacing [s].
        min_phase: the shortest remaining duration [s] a plan gives the current phase.
        durations: nominal (back stance, flight, front stance, flight) durations [s] (None: the paper's 80/72/72/72 ms).
        height_offset: the reference postures' trunk this much above the authors' [m], in [-0.1, 0.1].
        friction: the plans' friction coefficient (None: the model's 0.6; below it, a friction margin).
    """

    horizon: float | None = None
    planner_dt: float = 0.0025
    min_phase: float = 0.01
    durations: tuple | None = None
    height_offset: float = 0.04
    friction: float | None = 0.45

    def __post_init__(self) -> None:
        _optional_positive(self.horizon, "horizon")
        check_positive(self.planner_dt, "planner_dt")
        check_positive(self.min_phase, "min_phase")
        if self.durations is not None:
            if isinstance(self.durations, str) or len(self.durations) != 4 or any(
                    isinstance(d, bool) or not (float(d) > 0) for d in self.durations):
                raise ValueError(f"durations must be 4 positive numbers [s], got {self.durations!r}")
            object.__setattr__(self, "durations", tuple(float(d) for d in self.durations))
        check_height_offset(self.height_offset)
        _optional_positive(self.friction, "friction")


@dataclasses.dataclass(frozen=True)
class ReplanOptions:
    """When the MPC plans again and how far each re-plan is solved.

    Attributes:
        period: env time between periodic re-plans [s].
        iterations: DDP iterations of a warm-started periodic re-plan (1: a real-time iteration).
        warmup_iterations: DDP iterations of a plan from scratch (the first, an unshiftable one, a restart).
        restart_ratio: a re-plan whose objective ends above this many times the previous plan's is solved again from
            scratch, the better plan kept (None: never; > 1).
        time_budget: wall-clock limit of one re-plan [s] (None: none; a stopped re-plan keeps its best iterate).
        feedback_threshold: re-plan at once when the feedback term asks a motor for more than this fraction of the
            torque limit (None: periodic re-plans only).
        feedback_iterations: DDP iterations per outer iteration of such a feedback re-plan (None: as a periodic one).
        feedback_al_iterations: outer (augmented-Lagrangian) iterations of a feedback re-plan.
    """

    period: float = 0.02
    iterations: int = 1
    warmup_iterations: int = 30
    restart_ratio: float | None = 10.0
    time_budget: float | None = None
    feedback_threshold: float | None = 0.5
    feedback_iterations: int | None = 3
    feedback_al_iterations: int = 3

    def __post_init__(self) -> None:
        check_positive(self.period, "period")
        check_int(self.iterations, "iterations", minimum=1)
        check_int(self.warmup_iterations, "warmup_iterations", minimum=1)
        if self.restart_ratio is not None and not (check_positive(self.restart_ratio, "restart_ratio") > 1.0):
            raise ValueError(f"restart_ratio must be None or > 1, got {self.restart_ratio!r}")
        _optional_positive(self.time_budget, "time_budget")
        _optional_positive(self.feedback_threshold, "feedback_threshold")
        if self.feedback_iterations is not None:
            check_int(self.feedback_iterations, "feedback_iterations", minimum=1)
        check_int(self.feedback_al_iterations, "feedback_al_iterations", minimum=1)


@dataclasses.dataclass(frozen=True)
class SpeedOptions:
    """The plans' forward-speed reference.

    Attributes:
        ramp: the largest gap [m/s] between a plan's speed reference and the measured speed (None: no limit).
        acceleration: the largest rate [m/s^2] of the reference from the start speed to the target (None: no limit).
        integral_gain: integral action [1/s] on the cycle-mean speed error (None: off).
        bias_limit: the largest integral correction [m/s].
    """

    ramp: float | None = 0.5
    acceleration: float | None = 1.0
    integral_gain: float | None = 1.5
    bias_limit: float = 0.5

    def __post_init__(self) -> None:
        _optional_positive(self.ramp, "ramp")
        _optional_positive(self.acceleration, "acceleration")
        _optional_positive(self.integral_gain, "integral_gain")
        check_positive(self.bias_limit, "bias_limit", allow_zero=True)


@dataclasses.dataclass(frozen=True)
class ScheduleOptions:
    """The contact-schedule estimator: the current contact phase from the state and the flags, and the phases ahead.

    Attributes:
        debounce_steps: control steps a landing foot must touch before a flight ends early.
        min_flight: the fraction of a nominal flight before which a touchdown is a graze, in [0, 1].
        touchdown_height: from a flight's nominal end, a landing foot this near the ground [m] has landed (None: the
            flags alone).
        ground_search_speed: before the feet have measured the ground, a late flight's plans lower it at this rate
            [m/s] (None: no search).
        lost_stance_steps: control steps off the ground after which a stance is lost (0: never).
        double_stance: duration [s] of the double stance a touchdown on both feet starts (None: none).
        flight_reach: a flight lasts until its landing hip is this many leg lengths above the ground, in (0, 1] (None:
            its nominal duration).
        restep: plan and take a second step of the other foot when the landing hip leaves reach.
    """

    debounce_steps: int = 2
    min_flight: float = 0.3
    touchdown_height: float | None = 0.01
    ground_search_speed: float | None = 0.5
    lost_stance_steps: int = 1
    double_stance: float | None = 0.04
    flight_reach: float | None = 0.85
    restep: bool = True

    def __post_init__(self) -> None:
        check_int(self.debounce_steps, "debounce_steps", minimum=1)
        if isinstance(self.min_flight, bool) or not (0.0 <= float(self.min_flight) <= 1.0):
            raise ValueError(f"min_flight must be in [0, 1], got {self.min_flight!r}")
        _optional_positive(self.touchdown_height, "touchdown_height")
        _optional_positive(self.ground_search_speed, "ground_search_speed")
        check_int(self.lost_stance_steps, "lost_stance_steps", minimum=0)
        _optional_positive(self.double_stance, "double_stance")
        if self.flight_reach is not None and check_in_range(self.flight_reach, 0.0, 1.0, "flight_reach") == 0.0:
            raise ValueError("flight_reach must be in (0, 1] (a fraction of the leg length) or None, got 0.0")
        _check_bool(self.restep, "restep")


@dataclasses.dataclass(frozen=True)
class EstimatorOptions:
    """The state estimator: the model-based filter, the bias estimate and the delay estimate.

    Attributes:
        position_noise: the observed positions' noise [m, rad], a standard deviation.
        velocity_noise: the observed velocities' noise [m/s, rad/s].
        acceleration_noise: the accelerations the model misses [m/s^2, rad/s^2].
        innovation_gate: the normalized innovation squared beyond which an observation is an outlier.
        restart_steps: consecutive outliers that restart the estimate from the observation.
        bias_memory: time constant [s] of the sensor-bias estimate from the feet on the ground (None: none).
        delay_search: control steps by which the executed delay may differ from the announced one (0: trusted).
    """

    position_noise: float = 0.01
    velocity_noise: float = 0.1
    acceleration_noise: float = 3.0
    innovation_gate: float = 35.0
    restart_steps: int = 2
    bias_memory: float | None = 1.0
    delay_search: int = 1

    def __post_init__(self) -> None:
        for name in ("position_noise", "velocity_noise", "acceleration_noise", "innovation_gate"):
            check_positive(getattr(self, name), name)
        check_int(self.restart_steps, "restart_steps", minimum=1)
        _optional_positive(self.bias_memory, "bias_memory")
        check_int(self.delay_search, "delay_search", minimum=0)


@dataclasses.dataclass(frozen=True)
class MotionOptions:
    """The MPC of a planned motion ([`MotionMPCPolicy`][hsddp_gym.planners.policies.mpc.motion.MotionMPCPolicy]; the
    bounding MPC does not use them).

    Attributes:
        retime: a flight's time left from the ballistic centre of mass
            ([`flight_time_to_go`][hsddp_gym.planners.policies.mpc.motion.flight_time_to_go]); False (the default,
            measured the more robust on the backflip): its nominal duration less the time spent in it (fixed timing;
            the landing itself is the contacts' either way).
        hold_horizon: the least planned duration [s] of the motion's last phase (after the motion, the plans hold its
            final reference).
        max_flight_stretch: a retimed flight lasts at most this many times its nominal duration.
        bias_correction: the motion's plans start from the state less the estimated forward-speed bias
            ([`Odometry`][hsddp_gym.planners.policies.estimation.Odometry]), and on a terrain the trunk x is integrated
            without it; the height bias stays where the model puts the ground. A landing placed in the world moves
            with it (a gap's far rim); the bounding MPC keeps the measured state (its speed integral takes up the speed
            bias) and does not use it.
        mass_estimate: the motion's plans use a model whose trunk has the mass the stances show
            ([`MassEstimate`][hsddp_gym.planners.policies.estimation.MassEstimate]), rounded to a multiple of
            ``mass_step`` (one model per multiple, built once); False: the nominal model.
        mass_step: the grid [fraction of the nominal trunk mass] of the plans' trunk mass (> 0).
    """

    retime: bool = False
    hold_horizon: float = 0.25
    max_flight_stretch: float = 2.0
    bias_correction: bool = True
    mass_estimate: bool = True
    mass_step: float = 0.01

    def __post_init__(self) -> None:
        _check_bool(self.retime, "retime")
        _check_bool(self.bias_correction, "bias_correction")
        _check_bool(self.mass_estimate, "mass_estimate")
        check_positive(self.mass_step, "mass_step")
        check_positive(self.hold_horizon, "hold_horizon")
        if not check_positive(self.max_flight_stretch, "max_flight_stretch") >= 1.0:
            raise ValueError(f"max_flight_stretch must be >= 1, got {self.max_flight_stretch!r}")


GROUPS = {"plan": PlanOptions, "replan": ReplanOptions, "speed": SpeedOptions, "schedule": ScheduleOptions,
          "estimator": EstimatorOptions, "motion": MotionOptions}
"""The option groups by their field name in [`MPCOptions`][MPCOptions]."""


@dataclasses.dataclass(frozen=True)
class MPCOptions:
    """Settings of [`MPCPolicy`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy], in groups (each group's fields are
    documented on its class).

    Attributes:
        plan: [`PlanOptions`][PlanOptions], what a plan is.
        replan: [`ReplanOptions`][ReplanOptions], when the MPC plans again and how far.
        speed: [`SpeedOptions`][SpeedOptions], the plans' speed reference.
        schedule: [`ScheduleOptions`][ScheduleOptions], the contact-schedule estimator.
        estimator: [`EstimatorOptions`][EstimatorOptions], the state estimator.
        motion: [`MotionOptions`][MotionOptions], the MPC of a planned motion.
        min_stance_force: the least normal force [N] every planned stance foot must push with, the torques projected
            onto that set (None: the feedback law's torques as they are).

    ``MPCOptions().replace(replan_period=0.01)`` or ``.replace(replan=ReplanOptions(period=0.01))`` changes settings;
    [`from_record`][from_record] reads them back from JSON, flat (earlier versions) or grouped (``dataclasses.asdict``).
    """

    plan: PlanOptions = PlanOptions()
    replan: ReplanOptions = ReplanOptions()
    speed: SpeedOptions = SpeedOptions()
    schedule: ScheduleOptions = ScheduleOptions()
    estimator: EstimatorOptions = EstimatorOptions()
    motion: MotionOptions = MotionOptions()
    min_stance_force: float | None = 0.0

    def __post_init__(self) -> None:
        for name, cls in GROUPS.items():
            if not isinstance(getattr(self, name), cls):
                raise TypeError(f"{name} must be a {cls.__name__}, got {type(getattr(self, name)).__name__}")
        _optional_positive(self.min_stance_force, "min_stance_force", allow_zero=True)

    def replace(self, **changes) -> MPCOptions:
        """A copy with ``changes``: groups by name (``schedule=ScheduleOptions(...)``), ``min_stance_force``, or single
        settings by their flat name ([`FLAT_FIELDS`][FLAT_FIELDS], e.g. ``touchdown_height=None``,
        ``replan_period=0.01``)."""
        groups = {name: {} for name in GROUPS}
        top = {}
        for key, value in changes.items():
            if key in GROUPS or key == "min_stance_force":
                top[key] = value
            elif key in FLAT_FIELDS:
                group, field = FLAT_FIELDS[key]
                groups[group][field] = value
            else:
                raise ValueError(f"MPCOptions has no setting {key!r}; settings: {sorted(FLAT_FIELDS)} or the groups "
                                 f"{sorted(GROUPS)}")
        out = dataclasses.replace(self, **top)
        edits = {name: dataclasses.replace(getattr(out, name), **f) for name, f in groups.items() if f}
        return dataclasses.replace(out, **edits) if edits else out

    def flat(self) -> dict:
        """Every setting by its flat name ([`FLAT_FIELDS`][FLAT_FIELDS]): ``{name: value}``."""
        return {name: getattr(getattr(self, group), field) if group else self.min_stance_force
                for name, (group, field) in FLAT_FIELDS.items()}

    @classmethod
    def from_record(cls, options) -> MPCOptions:
        """The options stored in a record (JSON), grouped (``dataclasses.asdict`` of an ``MPCOptions``) or flat (the
        names of earlier versions, [`FLAT_FIELDS`][FLAT_FIELDS]), back as ``MPCOptions``; None or ``{}`` are the
        defaults.

        A setting this version no longer has ([`FIXED_SETTINGS`][FIXED_SETTINGS]) is accepted silently when it holds the
        value this version always uses, and left out with a ``UserWarning`` naming it otherwise; an unknown name is left
        out with a ``UserWarning`` too. ``weights`` None (the paper's weights in earlier versions) counts as
        ``"paper"``."""
        if options is None:
            return cls()
        if isinstance(options, MPCOptions):
            return options
        if not isinstance(options, dict):
            raise TypeError(f"options must be a dict of MPCOptions settings, got {type(options).__name__}")
        changes, dropped = {}, []
        for key, value in options.items():
            if key in GROUPS:
                if not isinstance(value, dict):
                    raise TypeError(f"options[{key!r}] must be a dict of {GROUPS[key].__name__} fields, got "
                                    f"{type(value).__name__}")
                known = {f.name for f in dataclasses.fields(GROUPS[key])}
                dropped += [f"{key}.{k}" for k in value if k not in known]
                changes[key] = GROUPS[key](**{k: v for k, v in value.items() if k in known})
            elif key in FLAT_FIELDS or key == "min_stance_force":
                changes[key] = value
            elif key in FIXED_SETTINGS:
                value = "paper" if key == "weights" and value is None else value
                if value != FIXED_SETTINGS[key] and not (isinstance(FIXED_SETTINGS[key], float)
                                                          and isinstance(value, (int, float))
                                                          and float(value) == FIXED_SETTINGS[key]):
                    dropped.append(f"{key}={value!r} (this version always uses {FIXED_SETTINGS[key]!r})")
            else:
                dropped.append(key)
        if dropped:
            warnings.warn(f"MPCOptions.from_record: left out settings this version does not have: {dropped}",
                          UserWarning, stacklevel=2)
        if changes.get("durations") is not None:
            changes["durations"] = tuple(changes["durations"])
        return cls().replace(**changes)


FLAT_FIELDS = {
    # plan
    "horizon": ("plan", "horizon"), "planner_dt": ("plan", "planner_dt"), "min_phase": ("plan", "min_phase"),
    "durations": ("plan", "durations"), "height_offset": ("plan", "height_offset"),
    "plan_friction": ("plan", "friction"),
    # replan
    "replan_period": ("replan", "period"), "max_iterations": ("replan", "iterations"),
    "warmup_iterations": ("replan", "warmup_iterations"), "restart_ratio": ("replan", "restart_ratio"),
    "time_budget": ("replan", "time_budget"), "replan_feedback": ("replan", "feedback_threshold"),
    "feedback_iterations": ("replan", "feedback_iterations"),
    "feedback_al_iterations": ("replan", "feedback_al_iterations"),
    # speed
    "speed_ramp": ("speed", "ramp"), "speed_acceleration": ("speed", "acceleration"),
    "speed_integral_gain": ("speed", "integral_gain"), "speed_bias_limit": ("speed", "bias_limit"),
    # schedule
    "debounce_steps": ("schedule", "debounce_steps"), "min_flight": ("schedule", "min_flight"),
    "touchdown_height": ("schedule", "touchdown_height"), "ground_search_speed": ("schedule", "ground_search_speed"),
    "lost_stance_steps": ("schedule", "lost_stance_steps"), "double_stance": ("schedule", "double_stance"),
    "flight_reach": ("schedule", "flight_reach"), "restep": ("schedule", "restep"),
    # estimator
    "filter_position_noise": ("estimator", "position_noise"), "filter_velocity_noise": ("estimator", "velocity_noise"),
    "filter_acceleration_noise": ("estimator", "acceleration_noise"),
    "filter_innovation_gate": ("estimator", "innovation_gate"), "filter_restart_steps": ("estimator", "restart_steps"),
    "bias_memory": ("estimator", "bias_memory"), "delay_search": ("estimator", "delay_search"),
    # motion
    "retime": ("motion", "retime"), "hold_horizon": ("motion", "hold_horizon"),
    "max_flight_stretch": ("motion", "max_flight_stretch"), "bias_correction": ("motion", "bias_correction"),
    "mass_estimate": ("motion", "mass_estimate"), "mass_step": ("motion", "mass_step"),
    # the feedback law
    "min_stance_force": (None, "min_stance_force"),
}
"""Each setting's flat name (earlier versions' ``MPCOptions`` fields) -> ``(group, field)`` (group None: a field of
[`MPCOptions`][MPCOptions] itself)."""

FIXED_SETTINGS = {
    "method": "al-reb", "integrator": "semi_implicit", "refresh_gains": True, "weights": "later", "z_velocity": "code",
    "state_filter": True, "latency_compensation": True, "fine_dt": None, "fine_phases": 2, "latency_steps": 0,
    "action_delay": None, "warm_start_kd": 0.1, "reb_delta": 0.2, "reb_eps": 1e-4, "sigma_max": 500.0,
}
"""Settings of earlier versions that this one fixes, with the value it always uses: the constraint handling (AL on
the switching constraints, relaxed barriers), the integrator, the gains' refresh, the authors' later cost weights and
vertical-velocity references, the state filter and the latency compensation (always on), one knot grid, no simulated
solver latency, the env's announced action delay, and the constants
[`WARM_START_KD`][hsddp_gym.planners.policies.mpc.planner.WARM_START_KD], ``REB_DELTA``, ``REB_EPS`` and
``SIGMA_MAX`` of the planner."""
