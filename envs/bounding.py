"""``hsddp_gym/Bounding-v0``: the planar MIT Mini Cheetah with state-based contacts (see
[`BoundingEnv`][BoundingEnv])."""

from __future__ import annotations

import math
import numbers

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from hsddp_gym.core.contact import ContactSimulator, check_motor_speed_limits
from hsddp_gym.core.conventions import IPITCH, IX, IZ, NGRF, NQ, NU, NX
from hsddp_gym.core.model import CheetahModel
from hsddp_gym.core.observation import RESET_CONTACT_HEIGHT, ObservationLayout, fill_observation
from hsddp_gym.core.params import DEFAULT_PARAMS
from hsddp_gym.core.references import paper_initial_state
from hsddp_gym.core.terrain import SAMPLE_KINDS, Terrain
from hsddp_gym.util.validation import check_in_range, check_int, check_positive, check_vector, real_array

DEFAULT_FRAME_SKIP = 5
DEFAULT_SIM_TIMESTEP = 1e-3
DEFAULT_MAX_EPISODE_STEPS = 1000
DEFAULT_MOTOR_SPEED_LIMITS = (36.0, 50.0)
DEFAULT_TARGET_SPEED = 1.0
"""Desired forward speed [m/s] of the task (the paper's 1 m/s bound)."""
_MAX_PENETRATION_AT_RESET = 1e-3
_OPTION_KEYS = ("state", "push", "time")
RESET_MAX_LINEAR_SPEED = 10.0
"""Largest trunk speed ``|vx|``, ``|vz|`` [m/s] that ``reset(options={"state": x})`` accepts."""
RESET_MAX_PITCH_RATE = 50.0
"""Largest trunk pitch rate [rad/s] that ``reset(options={"state": x})`` accepts."""
RESET_MAX_JOINT_RATE = 100.0
"""Largest joint rate [rad/s] that ``reset(options={"state": x})`` accepts (twice the motors' no-load speed)."""
RESET_VELOCITY_BOUNDS = (RESET_MAX_LINEAR_SPEED, RESET_MAX_LINEAR_SPEED, RESET_MAX_PITCH_RATE) \
    + (RESET_MAX_JOINT_RATE,) * NU
"""Bounds (7,) on ``|v|`` of a reset state, in state order ``[vx, vz, pitch rate, 4 joint rates]``."""
TERRAIN_KINDS = tuple("random_" + kind for kind in SAMPLE_KINDS)
"""The ``terrain=`` strings of seeded random profiles: ``"random_steps"``, ``"random_slopes"``, ``"random_mixed"``
([`hsddp_gym.core.terrain.Terrain.sample`][hsddp_gym.core.terrain.Terrain.sample] with its defaults, one profile per
episode)."""
_STATE_NAMES = ("x", "z", "pitch", "hip_front", "knee_front", "hip_back", "knee_back",
                "vx", "vz", "pitch_rate", "hip_front_rate", "knee_front_rate", "hip_back_rate", "knee_back_rate")


def _check_range(value, name: str) -> tuple[float, float]:
    """A pair ``(lo, hi)`` of finite floats with ``lo < hi`` (tuple or list, e.g. from JSON)."""
    if not isinstance(value, (tuple, list, np.ndarray)) or len(value) != 2:
        raise TypeError(f"{name} must be a pair (low, high), got {value!r}")
    lo, hi = value
    for v in (lo, hi):
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(float(v)):
            raise ValueError(f"{name} must hold two finite numbers, got {value!r}")
    if not float(lo) < float(hi):
        raise ValueError(f"{name} must satisfy low < high, got {value!r}")
    return float(lo), float(hi)


def _check_bool(value, name: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a bool, got {type(value).__name__}")
    return bool(value)


def check_terrain_option(terrain, name: str = "terrain"):
    """The env's ``terrain=`` argument checked: None (flat), a [`Terrain`][hsddp_gym.core.terrain.Terrain], a dict of
    [`Terrain.to_dict`][Terrain.to_dict] (JSON: becomes a Terrain) or one of [`TERRAIN_KINDS`][TERRAIN_KINDS]; errors
    name ``name``."""
    if terrain is None or isinstance(terrain, Terrain):
        return terrain
    if isinstance(terrain, dict):
        return Terrain.from_dict(terrain, name)
    if isinstance(terrain, str):
        if terrain not in TERRAIN_KINDS:
            raise ValueError(f"{name} must be None, a Terrain, a dict of Terrain.to_dict() or one of "
                             f"{list(TERRAIN_KINDS)}, got {terrain!r}")
        return terrain
    raise TypeError(f"{name} must be None, a Terrain, a dict or a str, got {type(terrain).__name__}")


def pop_due_pushes(pushes: list, frame_start: float, n: int, h: float) -> list:
    """Remove from ``pushes`` (scheduled ``[(time [s], delta_v (3,)), ...]`` in time order) those that come in the
    control step of ``n`` simulation steps of ``h`` seconds starting at episode time ``frame_start``, and return
    them as ``[(k, delta_v), ...]``: a push acts after the first ``k`` simulation steps of the frame (``k`` the
    first step at or after its time, 0 <= k <= n, non-decreasing). One rule for the single env and the compiled
    vector env ([`hsddp_gym.envs.vector.BoundingVectorEnv`][hsddp_gym.envs.vector.BoundingVectorEnv])."""
    due, done = [], 0
    end = frame_start + n * h - 1e-12
    while pushes and pushes[0][0] < end:
        t_push, delta_v = pushes.pop(0)
        done = min(n, max(done, math.ceil((t_push - frame_start) / h - 1e-9)))
        due.append((done, delta_v))
    return due


class BoundingEnv(gym.Env):
    r"""Planar MIT Mini Cheetah on flat ground: run forward at a target speed without falling.

    ## Description
    The planar (sagittal) Mini Cheetah of Li & Wensing (RA-L 2020): a 5.46 kg trunk with a front and a back
    two-link leg (each planar leg stands for a left-right pair), 7 degrees of freedom
    (``q = [x, z, pitch, hip_front, knee_front, hip_back, knee_back]``, see
    [`hsddp_gym.core.conventions`][hsddp_gym.core.conventions]), four torque-controlled joints, point feet. **Contacts
    are decided by the state, not by a schedule**: each foot may fly, touch down (inelastic impact, restitution 0),
    stick, slide (Coulomb friction, ``mu = 0.6``) or lift off, in any combination, simulated by a velocity-level
    time-stepping scheme whose per-step contact LCP is solved exactly
    ([`hsddp_gym.core.contact`][hsddp_gym.core.contact]) at a 1 ms step, followed by a position and an energy projection
    (``energy_consistent``). The motors are ideal torque sources up to 36 rad/s; above it a torque that drives its joint
    further is cut linearly to zero at 50 rad/s (back-EMF limit, ``motor_speed_limits``), which keeps the light legs (no
    rotor inertia is modelled) from spinning up without bound under random actions. The task suits bounding (back
    stance, flight, front stance, flight; the paper's cycle is 0.296 s), but any gait that tracks the target speed
    is rewarded.

    ## Action space
    ``Box(-1, 1, (4,), float32)``: normalized joint torques ``[hip_front, knee_front, hip_back, knee_back]``;
    the torque is ``action * torque_limit`` (33 N m). The action is held for ``frame_skip`` simulation steps
    (control period ``dt = frame_skip * sim_timestep``, default 5 ms = 200 Hz). Actions outside the box are
    clipped to it (the clipped action enters the control cost); an action with NaN/inf entries, entries too
    large for a float (e.g. ``10**400``) or a shape other than (4,) raises ``ValueError``; a complex, boolean,
    string or other non-real action raises ``TypeError``.

    ## Observation space
    ``Box(low, high, (17,), float32)`` by default (18 with ``exclude_current_positions_from_observation=False``),
    documented in [`hsddp_gym.core.observation`][hsddp_gym.core.observation]:

    | index | observation | unit |
    |---|---|---|
    | 0 | trunk height z | m |
    | 1 | trunk pitch (positive nose-down) | rad |
    | 2-5 | hip_front, knee_front, hip_back, knee_back angles | rad |
    | 6-7 | trunk vx, vz | m/s |
    | 8 | pitch rate | rad/s |
    | 9-12 | joint rates | rad/s |
    | 13-14 | contact flags front, back (1: the ground pushed the foot during the last 1 ms step) | - |
    | 15-16 | sin, cos of the gait clock ``2 pi t / gait_period`` | - |

    At reset, before any step, a foot is flagged when it is at most 1 mm above the ground.
    The trunk ``x`` is excluded by default (as HalfCheetah-v5) and always reported in ``info``. The bounds
    are finite and generous; values beyond them are clipped. ``env.unwrapped.observation_structure`` gives
    the block sizes and
    [`hsddp_gym.core.observation.state_from_observation`][hsddp_gym.core.observation.state_from_observation] with
    ``env.unwrapped.observation_layout`` maps an observation back to ``(state (14,), contact Mode, phase)``.

    ## Rewards
    ``reward = forward_reward_weight * r_track - ctrl_cost_weight * ||a||^2 + healthy_reward * is_healthy``,
    with ``r_track = exp(-((v - target_speed) / tracking_sigma)^2)`` in ``[0, 1]`` and ``v`` the trunk's mean
    forward velocity over the control step (x displacement / dt, as HalfCheetah), ``a`` the clipped action.
    The bounded Gaussian tracking term rewards the target speed, not the fastest possible one, and is
    smooth around it. The healthy reward is paid only on healthy steps (Hopper-v5 semantics). The reward is a
    Python ``float``; its terms are in ``info`` (``reward_forward``, ``reward_ctrl`` (negative),
    ``reward_healthy``).

    ## Starting state
    The paper's initial state
    ([`hsddp_gym.core.references.paper_initial_state`][hsddp_gym.core.references.paper_initial_state]: mid back stance,
    back foot 0.2 mm above the ground, 0.9 m/s forward) plus uniform noise ``U(-s, s)`` on ``q`` and Gaussian noise ``s
    N(0, 1)`` on ``v`` (``s = reset_noise_scale``), drawn from ``self.np_random``; if the noise puts a foot below the
    ground, the trunk is raised until the lowest foot is at height 0. ``reset(options=...)`` accepts:

    * ``"state"``: a state (14,) to start from exactly (no noise): finite, positions inside the observation
      bounds, ``|vx|, |vz| <= 10 m/s``, ``|pitch rate| <= 50 rad/s``, ``|joint rates| <= 100 rad/s``
      ([`RESET_VELOCITY_BOUNDS`][RESET_VELOCITY_BOUNDS]); feet may not be more than 1 mm below the ground. A violation
      raises ``ValueError`` naming the entry (e.g. ``options['state'][10] (hip_front_rate)``);
    * ``"time"``: the initial clock time [s] (>= 0, default 0), which sets the gait phase;
    * ``"push"``: either a velocity change (3,) ``[dvx, dvz, dpitch_rate]`` applied right after the reset, or
      ``{"delta_v": (3,), "time": t}`` applied at the first simulation step at or after ``t`` seconds of
      episode time (a robustness test), or a list of such dicts (a push schedule, applied in time order).
      ``env.unwrapped.apply_push(delta_v)`` pushes at any moment.

    ## Episode end
    ``terminated`` is True when the robot is unhealthy and ``terminate_when_unhealthy`` is True: the trunk
    height leaves ``healthy_z_range`` or the pitch leaves ``healthy_pitch_range`` (a fall); an invalid state
    (non-finite, or speeds beyond the observation bounds of 100 m/s and 1000 rad/s: a numerical blow-up)
    always terminates, is reported as ``info["invalid_state"] = True`` (with the raw non-finite ``qpos`` /
    ``qvel`` in ``info``; the observation itself stays inside its box, NaN entries as 0, so that buffers stay
    finite) and any further ``step`` raises ``RuntimeError`` until ``reset``.
    Truncation comes only from the registered ``TimeLimit`` (1000 control steps = 5 s at the default rate,
    about 17 bounding cycles); ``step`` itself always returns ``truncated=False``.

    ## Info
    Same keys at reset and at every step (Minari-compatible): ``x_position``, ``x_velocity`` (mean over the
    step; the instantaneous vx at reset), ``reward_forward``, ``reward_ctrl``, ``reward_healthy`` (0 at
    reset), ``contact`` (2,) bool flags ``[front, back]``, ``foot_heights`` (2,) [m], ``grf`` (4,) mean ground
    force over the step ``[f_front_x, f_front_z, f_back_x, f_back_z]`` [N] (zeros at reset), ``qpos`` (7,),
    ``qvel`` (7,), ``time`` [s], ``invalid_state`` (bool: the simulation blew up, see Episode end).

    ## Arguments
    | parameter | default | description |
    |---|---|---|
    | ``frame_skip`` | 5 | simulation steps per action; ``dt = frame_skip * sim_timestep`` |
    | ``sim_timestep`` | 0.001 | simulation step [s] |
    | ``target_speed`` | 1.0 | desired forward speed [m/s] (the paper's task) |
    | ``tracking_sigma`` | 0.5 | width of the Gaussian tracking reward [m/s] |
    | ``forward_reward_weight`` | 1.0 | weight of ``r_track`` |
    | ``ctrl_cost_weight`` | 0.1 | weight of ``||a||^2`` |
    | ``healthy_reward`` | 0.5 | reward per healthy step |
    | ``terminate_when_unhealthy`` | True | end the episode on a fall |
    | ``healthy_z_range`` | (0.12, 0.5) | healthy trunk heights [m] |
    | ``healthy_pitch_range`` | (-0.8, 0.8) | healthy pitch angles [rad] |
    | ``reset_noise_scale`` | 0.01 | scale of the reset noise |
    | ``exclude_current_positions_from_observation`` | True | leave the trunk x out of the observation |
    | ``gait_period`` | 0.296 | period of the observation's phase clock [s] |
    | ``torque_limit`` | 33.0 | torque of a full action [N m] |
    | ``friction`` | 0.6 | Coulomb friction coefficient |
    | ``trunk_mass_scale`` | 1.0 | factor on the trunk's mass and rotational inertia (4) |
    | ``gravity`` | 9.81 | gravitational acceleration [m/s^2] (0 for energy tests) |
    | ``contact_erp`` | 1.0 | legacy scheme: fraction of a penetration removed per step (1) |
    | ``motor_speed_limits`` | (36.0, 50.0) | torque-speed limit ``(w_full, w_zero)`` [rad/s] or None (2) |
    | ``energy_consistent`` | True | energy-consistent stepping (3); False: the legacy scheme |
    | ``render_mode`` | None | ``"rgb_array"`` or ``"human"`` |
    | ``width``, ``height`` | 480, 320 | image size of ``render`` [px] |
    | ``render_grf`` | True | draw ground-force arrows |
    | ``terrain`` | None | the ground's profile (5): None (flat), a ``Terrain``, its ``to_dict()`` or a random kind |

    (1) The legacy scheme's position correction; the default scheme projects contact feet exactly onto the
    ground (and sticking feet onto their positions) every step.
    (2) Full torque up to ``w_full``; a torque driving its joint faster is cut linearly to 0 at ``w_zero``;
    braking torques are not limited. None: ideal torque sources, the planner's model.
    (3) [`hsddp_gym.core.contact`][hsddp_gym.core.contact]: a mass-metric position projection (sticking feet do not
    creep, contact feet and any foot that crossed the ground end each step on it: no tunnelling at any joint rate) and
    an energy projection, so that per simulation step ``E(t+h) - E(t) <= tau . dq`` (+1e-9 J, tested); in free
    flight the centroidal momentum changes by gravity's impulse only and, with zero torque, the energy is kept
    (both to round-off, at any joint rate). The env
    steps it through the vector env's compiled kernel
    ([`CompiledContactSimulator`][hsddp_gym.core.compiled_contact.CompiledContactSimulator], equal to the reference
    ``ContactSimulator`` to round-off), so ``gym.make_vec(..., vectorization_mode="vector_entry_point")``
    gives bit-identical transitions; the kernel is compiled once per machine (about a minute, announced on
    stderr, cached on disk).
    (4) A model-mismatch test ([`hsddp_gym.envs.perturbations`][hsddp_gym.envs.perturbations]): the simulated trunk is
    heavier or lighter than the 5.46 kg every planner and policy assumes; its inertia scales with it (same shape, other
    density).

    (5) [`hsddp_gym.core.terrain`][hsddp_gym.core.terrain]: steps, slopes and gaps (deep drops). The feet contact its
    continuous simulated surface ([`surface_vertices`][hsddp_gym.core.terrain.Terrain.surface_vertices]: a jump is a 1
    mm wide riser) along the local normal, with the friction cone in the local frame; the after-step projection puts
    contact feet, and any foot that ended below it, onto it. ``info["foot_heights"]``, the reset contact flags and the
    reset's lift of a foot below the ground measure from the surface under each foot; the healthy trunk height is ``z -
    g(x)`` with ``g`` the ground under the trunk ([`support_heights`][hsddp_gym.core.terrain.Terrain.support_heights]: a
    gap is bridged at its near edge's level, so falling into it ends the episode); ``info`` then also holds
    ``ground_height`` (that ``g``). The observation keeps the absolute trunk height and the reward the horizontal speed.
    A string of [`TERRAIN_KINDS`][TERRAIN_KINDS] draws a new profile at every reset from ``self.np_random`` (before the
    reset noise), so the reset seed fixes it (flat until the first reset). Only the energy-consistent scheme simulates a
    terrain; ``gym.make_vec`` of ``hsddp_gym/Terrain-v0`` (``"random_mixed"``) builds
    [`TaskVectorEnv`][hsddp_gym.envs.task_vector.TaskVectorEnv], which batches the robots standing on the same terrain
    (the wholly compiled ``Bounding-v0`` vector env simulates the flat ground only).

    Every argument is JSON-serializable (a ``terrain`` as its ``to_dict()`` or a string), so Minari can rebuild the
    env from its spec.

    Why the defaults: the legs are light (no rotor inertia is modelled: about 1e-3 kg m^2 seen by a swinging
    knee), so a joint damping gain ``kd`` held for a control period ``dt`` is unstable once
    ``kd * dt / I > 2``: about 0.2 N m s/rad at 100 Hz, 0.4 at 200 Hz, 2 at 1 kHz. ``frame_skip=5``
    (200 Hz) keeps 14-16 decisions per 72-80 ms bounding phase and lets a learned policy damp its legs,
    while 100 Hz leaves almost no stable feedback. The contact-event heuristic policy and the MPC (which
    plans on a 5 ms grid) are designed for the default; tracking a 1 ms plan's stiff DDP gains may prefer
    ``frame_skip=1``.
    1000 steps (5 s) span about 17 bounding cycles, enough to expose drift, and keep episodes short for
    PPO/SAC; use ``gym.make(..., max_episode_steps=...)`` to change it.

    ## Version history
    * v0: initial release (state-based contact simulation, 1 ms step, 200 Hz control by default).
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": int(round(1.0 / (DEFAULT_FRAME_SKIP
                                                                                        * DEFAULT_SIM_TIMESTEP)))}

    def __init__(self, frame_skip: int = DEFAULT_FRAME_SKIP, sim_timestep: float = DEFAULT_SIM_TIMESTEP,
                 target_speed: float = DEFAULT_TARGET_SPEED, tracking_sigma: float = 0.5,
                 forward_reward_weight: float = 1.0,
                 ctrl_cost_weight: float = 0.1, healthy_reward: float = 0.5, terminate_when_unhealthy: bool = True,
                 healthy_z_range=(0.12, 0.5), healthy_pitch_range=(-0.8, 0.8), reset_noise_scale: float = 0.01,
                 exclude_current_positions_from_observation: bool = True, gait_period: float = 0.296,
                 torque_limit: float = DEFAULT_PARAMS.torque_limit, friction: float = DEFAULT_PARAMS.friction,
                 gravity: float = DEFAULT_PARAMS.gravity, contact_erp: float = 1.0, trunk_mass_scale: float = 1.0,
                 motor_speed_limits=DEFAULT_MOTOR_SPEED_LIMITS, energy_consistent: bool = True,
                 render_mode: str | None = None,
                 width: int = 480, height: int = 320, render_grf: bool = True, terrain=None) -> None:
        self.frame_skip = check_int(frame_skip, "frame_skip", minimum=1)
        self.sim_timestep = check_positive(sim_timestep, "sim_timestep")
        if self.sim_timestep > 0.01:
            raise ValueError(f"sim_timestep must be <= 0.01 s for a stable contact simulation, got {sim_timestep!r}")
        if isinstance(target_speed, bool) or not isinstance(target_speed, numbers.Real) \
                or not math.isfinite(float(target_speed)):
            raise ValueError(f"target_speed must be a finite number [m/s], got {target_speed!r}")
        self.target_speed = float(target_speed)
        self.tracking_sigma = check_positive(tracking_sigma, "tracking_sigma")
        self.forward_reward_weight = check_positive(forward_reward_weight, "forward_reward_weight", allow_zero=True)
        self.ctrl_cost_weight = check_positive(ctrl_cost_weight, "ctrl_cost_weight", allow_zero=True)
        self.healthy_reward_weight = check_positive(healthy_reward, "healthy_reward", allow_zero=True)
        self.terminate_when_unhealthy = _check_bool(terminate_when_unhealthy, "terminate_when_unhealthy")
        self.healthy_z_range = _check_range(healthy_z_range, "healthy_z_range")
        self.healthy_pitch_range = _check_range(healthy_pitch_range, "healthy_pitch_range")
        self.reset_noise_scale = check_positive(reset_noise_scale, "reset_noise_scale", allow_zero=True)
        exclude = _check_bool(exclude_current_positions_from_observation,
                              "exclude_current_positions_from_observation")
        self.gait_period = check_positive(gait_period, "gait_period")
        self.torque_limit = check_positive(torque_limit, "torque_limit")
        friction = check_positive(friction, "friction", allow_zero=True)
        gravity = check_positive(gravity, "gravity", allow_zero=True)
        contact_erp = check_in_range(contact_erp, 0.0, 1.0, "contact_erp")
        motor_speed_limits = check_motor_speed_limits(motor_speed_limits)
        energy_consistent = _check_bool(energy_consistent, "energy_consistent")
        self.trunk_mass_scale = check_positive(trunk_mass_scale, "trunk_mass_scale")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.render_mode = render_mode
        self.width = check_int(width, "width", minimum=16)
        self.height = check_int(height, "height", minimum=16)
        self.render_grf = _check_bool(render_grf, "render_grf")

        self.terrain_option = check_terrain_option(terrain)
        """The ``terrain`` argument (a Terrain, a random kind of [`TERRAIN_KINDS`][TERRAIN_KINDS] or None)."""
        if self.terrain_option is not None and not energy_consistent:
            raise ValueError("terrain needs energy_consistent=True (only the energy-consistent scheme simulates a "
                             "terrain)")
        if isinstance(self.terrain_option, Terrain) and self.terrain_option.is_flat:
            self.terrain_option = None  # a flat profile is the flat ground: the same code, bit for bit
        self.terrain: Terrain | None = self.terrain_option if isinstance(self.terrain_option, Terrain) else None
        """The profile simulated now (None: flat ground; a random kind draws one at every reset)."""

        self.robot = CheetahModel(DEFAULT_PARAMS.with_trunk_mass_scale(self.trunk_mass_scale))
        self.sim = self._make_simulator(friction, gravity, contact_erp, motor_speed_limits, energy_consistent)
        self.observation_layout = ObservationLayout(exclude_current_positions=exclude)
        low, high = self.observation_layout.bounds()
        self.observation_space = spaces.Box(low=low, high=high, dtype=np.float32)
        self.action_space = spaces.Box(low=-1.0, high=1.0, shape=(NU,), dtype=np.float32)
        self.metadata = {**type(self).metadata, "render_fps": int(round(1.0 / self.dt))}
        _, high = ObservationLayout(exclude_current_positions=False).bounds()
        self._state_bounds = np.concatenate([np.full(NQ, 1e300), high[NQ:NX].astype(np.float64)])
        self._abs_x = np.zeros(NX)

        self.init_state = paper_initial_state(self.robot.params)
        self._t0 = 0.0
        self._contact = np.zeros(2, dtype=bool)
        self._grf = np.zeros(NGRF)
        self._u = np.zeros(NU)
        self._pushes: list = []  # scheduled pushes, in time order: [(time, delta_v (3,)), ...]
        self._step_values = [0.0] * NU  # the step in progress (_begin_step): clipped action, trunk x, pushes due
        self._x_before = 0.0
        self._due_pushes: list | None = None
        self._x_velocity = 0.0
        self._last_rewards = (0.0, 0.0, 0.0)
        self._figure = None
        self._heights = np.zeros(2)
        self._invalid = False
        self.sim.set_state(self.init_state)
        self._update_feet(at_reset=True)

    def _make_simulator(self, friction, gravity, contact_erp, motor_speed_limits, energy_consistent):
        """The simulator (checked physics arguments); [`hsddp_gym.envs.mujoco_twin`][hsddp_gym.envs.mujoco_twin]
        overrides it.

        The energy-consistent scheme (the default) steps through the compiled kernel of the vector env
        ([`CompiledContactSimulator`][hsddp_gym.core.compiled_contact.CompiledContactSimulator], one robot), so that
        this env and [`BoundingVectorEnv`][hsddp_gym.envs.vector.BoundingVectorEnv] give bit-identical transitions; the
        legacy scheme is [`ContactSimulator`][hsddp_gym.core.contact.ContactSimulator] (Python). ``contact_erp`` acts on
        the legacy scheme only."""
        if energy_consistent:
            from hsddp_gym.core.compiled_contact import CompiledContactSimulator  # numba: imported on first use

            return CompiledContactSimulator(self.robot, timestep=self.sim_timestep, friction=friction,
                                            gravity=gravity, motor_speed_limits=motor_speed_limits,
                                            torque_limit=self.torque_limit, terrain=self.terrain)
        return ContactSimulator(self.robot, timestep=self.sim_timestep, friction=friction, gravity=gravity,
                                erp=contact_erp, motor_speed_limits=motor_speed_limits,
                                torque_limit=self.torque_limit, energy_consistent=energy_consistent)

    # ------------------------------------------------------------------ properties
    @property
    def dt(self) -> float:
        """Control period [s] = ``frame_skip * sim_timestep``."""
        return self.frame_skip * self.sim_timestep

    @property
    def observation_structure(self) -> dict:
        """Sizes of the observation blocks: ``skipped_qpos, qpos, qvel, contact, phase``."""
        return self.observation_layout.structure

    @property
    def state(self) -> np.ndarray:
        """A copy of the simulator state (14,)."""
        return self.sim.x.copy()

    @property
    def time(self) -> float:
        """Episode clock [s] (the ``time`` reset option plus the simulated time)."""
        return self._t0 + self.sim.time

    @property
    def contact(self) -> np.ndarray:
        """Current contact flags (2,) bool ``[front, back]``."""
        return self._contact.copy()

    @property
    def is_healthy(self) -> bool:
        """A valid state ([`valid_state`][valid_state]) with trunk height and pitch inside their healthy ranges."""
        return self._healthy(self.valid_state())

    def _healthy(self, valid: bool) -> bool:
        if not valid:
            return False
        x = self.sim.x
        z, pitch = float(x[IZ]), float(x[IPITCH])
        if self.terrain is not None:
            z -= self.ground_height(float(x[IX]))
        zlo, zhi = self.healthy_z_range
        plo, phi = self.healthy_pitch_range
        return zlo < z < zhi and plo < pitch < phi

    def ground_height(self, x: float) -> float:
        """The ground [m] the trunk height is measured from at trunk ``x`` [m]: 0 on flat ground, else the terrain's
        [`support_heights`][hsddp_gym.core.terrain.Terrain.support_heights] (a gap bridged at its near edge's level)."""
        if self.terrain is None:
            return 0.0
        return self.terrain.support_height(float(x))

    def foot_clearances(self, q) -> np.ndarray:
        """Heights (2,) [m] of the feet of configuration ``q`` (7,) above the ground under each (the simulated
        surface of the terrain, if any)."""
        if self.terrain is None:
            return self.robot.foot_heights(q)
        feet = self.robot.foot_positions(q)
        return feet[:, 1] - self.terrain.surface_heights(feet[:, 0])

    def valid_state(self) -> bool:
        """The state is finite and its speeds are inside the observation bounds (100 m/s, 1000 rad/s);
        anything else is a numerical blow-up and ends the episode."""
        x = self.sim.x
        np.abs(x, out=self._abs_x)
        return bool((self._abs_x <= self._state_bounds).all())  # False for NaN

    # ------------------------------------------------------------------ gym API
    def _get_obs(self) -> np.ndarray:
        obs = np.empty(self.observation_layout.size, dtype=np.float32)
        fill_observation(obs, self.sim.x, self._contact[0], self._contact[1], self.time / self.gait_period,
                         self.observation_layout.exclude_current_positions)
        return obs

    def _update_feet(self, valid: bool = True, at_reset: bool = False) -> None:
        """Foot heights and contact flags of the current state: after a step, the flag of a foot is set
        when the ground pushed it during the last simulation step; at reset, when it is at most
        ``RESET_CONTACT_HEIGHT`` (1 mm) above the ground."""
        heights, contact = self._heights, self._contact
        if not valid:
            heights[:] = np.nan
            contact[:] = False
            return
        heights[0], heights[1] = self.sim.foot_heights_fast()
        if at_reset:
            contact[0] = heights[0] <= RESET_CONTACT_HEIGHT
            contact[1] = heights[1] <= RESET_CONTACT_HEIGHT
        else:
            contact[:] = self.sim.contact

    def _get_info(self) -> dict:
        x = self.sim.x
        heights = self._heights.copy()
        fwd, ctrl, healthy = self._last_rewards
        info = {
            "x_position": float(x[IX]),
            "x_velocity": float(self._x_velocity),
            "reward_forward": fwd,
            "reward_ctrl": ctrl,
            "reward_healthy": healthy,
            "contact": self._contact.copy(),
            "foot_heights": heights,
            "grf": self._grf.copy(),
            "qpos": x[:NQ].copy(),
            "qvel": x[NQ:].copy(),
            "time": float(self.time),
            "invalid_state": self._invalid,
        }
        if self.terrain is not None:
            info["ground_height"] = self.ground_height(float(x[IX])) if np.isfinite(x[IX]) else float("nan")
        return info

    def _check_reset_state(self, state) -> np.ndarray:
        """``options["state"]`` as a float array (14,): finite, positions inside the observation bounds and
        ``|v| <= RESET_VELOCITY_BOUNDS``; raises ValueError naming the offending entry."""
        x = check_vector(state, NX, "options['state']")
        low, high = ObservationLayout(exclude_current_positions=False).bounds()
        for i in range(NQ):
            if not float(low[i]) <= x[i] <= float(high[i]):
                raise ValueError(f"options['state'][{i}] ({_STATE_NAMES[i]}) must be in [{float(low[i]):g}, "
                                 f"{float(high[i]):g}], got {x[i]!r}")
        for i, bound in enumerate(RESET_VELOCITY_BOUNDS):
            if abs(x[NQ + i]) > bound:
                raise ValueError(f"options['state'][{NQ + i}] ({_STATE_NAMES[NQ + i]}) must satisfy |v| <= {bound:g} "
                                 f"(RESET_VELOCITY_BOUNDS), got {x[NQ + i]!r}")
        return x

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Reset to the (noisy) paper initial state or to ``options["state"]``; see the class docstring.

        Returns:
            ``(observation, info)``.
        """
        super().reset(seed=seed)
        options = {} if options is None else options
        if not isinstance(options, dict):
            raise TypeError(f"options must be a dict or None, got {type(options).__name__}")
        unknown = sorted(set(options) - set(_OPTION_KEYS))
        if unknown:
            raise ValueError(f"unknown reset option(s) {unknown}; allowed: {list(_OPTION_KEYS)}")
        t0 = 0.0 if options.get("time") is None else check_positive(options["time"], "options['time']",
                                                                     allow_zero=True)
        push_now, self._pushes = self._parse_push(options.get("push"))
        if isinstance(self.terrain_option, str):  # a new random profile, drawn before the reset noise
            self.terrain = Terrain.sample(self.np_random, self.terrain_option[len("random_"):])
            self.sim.set_terrain(self.terrain)
        if options.get("state") is not None:
            x = self._check_reset_state(options["state"])
            heights = self.foot_clearances(x[:NQ])
            if heights.min() < -_MAX_PENETRATION_AT_RESET:
                raise ValueError(f"options['state'] puts a foot {-heights.min():.4g} m below the ground "
                                 f"(at most {_MAX_PENETRATION_AT_RESET} m allowed)")
        else:
            x = self.init_state.copy()
            s = self.reset_noise_scale
            x[:NQ] += self.np_random.uniform(low=-s, high=s, size=NQ)
            x[NQ:] += s * self.np_random.standard_normal(NQ)
            lowest = float(self.foot_clearances(x[:NQ]).min())
            if lowest < 0.0:
                x[IZ] -= lowest
        self.sim.set_state(x)
        if push_now is not None:
            self.sim.v[:3] += push_now
        self._t0 = t0
        valid = self.valid_state()  # False only if a huge immediate push made it blow past the bounds
        self._invalid = not valid
        self._update_feet(valid, at_reset=True)
        self._grf[:] = 0.0
        self._x_velocity = float(self.sim.v[0])
        self._last_rewards = (0.0, 0.0, 0.0)
        if self.render_mode == "human":
            self.render()
        return self._get_obs(), self._get_info()

    def step(self, action):
        """Hold the torques ``action * torque_limit`` for ``frame_skip`` simulation steps.

        Args:
            action: (4,) normalized torques; clipped to [-1, 1]; NaN/inf, overflowing entries or a wrong shape
                raise ValueError, non-real entries TypeError; after an invalid state, RuntimeError until reset.
        Returns:
            ``(observation, reward (float), terminated, truncated (always False), info)``.
        """
        self._begin_step(action)
        return self._end_step(self._simulate_step())

    # The step in three parts, so that the vector env of the task envs
    # (hsddp_gym.envs.task_vector.TaskVectorEnv) can run the middle one for many robots in one compiled call:
    # _begin_step (the action, the pushes due), _simulate_step (the physics), _end_step (reward, termination,
    # observation, info). A task overrides _begin_step and _end_step, never step.
    def _begin_step(self, action) -> None:
        """The step's first part: check and clip ``action`` (its values in ``self._step_values``, the torques in
        ``self._u``), note the trunk x and pop the pushes due in this control step (``self._due_pushes``)."""
        if self._invalid:
            raise RuntimeError("step() called after the simulation reached an invalid (non-finite or blown-up) "
                               "state; call reset() first (info['invalid_state'] was True)")
        values = self._parse_action(action)
        values = [1.0 if v > 1.0 else (-1.0 if v < -1.0 else v) for v in values]  # clip to the box
        self._step_values = values
        limit = self.torque_limit
        u = self._u
        u[0], u[1], u[2], u[3] = values[0] * limit, values[1] * limit, values[2] * limit, values[3] * limit
        self._x_before = float(self.sim.x[IX])
        self._due_pushes = (pop_due_pushes(self._pushes, self.time, self.frame_skip, self.sim_timestep)
                            if self._pushes else None)

    def _simulate_step(self):
        """The step's physics: ``frame_skip`` simulation steps with the torques ``self._u``, split at the pushes due.

        Returns:
            The ground impulses summed over the control step, grf layout (4,) [N s].
        """
        sim, n = self.sim, self.frame_skip
        due = self._due_pushes
        if not due:
            return sim.run(self._u, n)
        impulse, done = [0.0] * NGRF, 0  # split the frame at the first simulation step at or after each push time
        for k, delta_v in due:
            if k > done:
                impulse = [i + r for i, r in zip(impulse, sim.run(self._u, k - done))]
                done = k
            sim.v[:3] += delta_v
        if n > done:
            impulse = [i + r for i, r in zip(impulse, sim.run(self._u, n - done))]
        return impulse

    def _end_step(self, impulse) -> tuple:
        """The step's last part, after the physics left ``impulse`` (4,) [N s]: contact flags, reward, termination,
        observation and info.

        Returns:
            ``(observation, reward (float), terminated, truncated (always False), info)``.
        """
        sim, values = self.sim, self._step_values
        dt = self.dt
        grf = self._grf
        grf[0], grf[1], grf[2], grf[3] = impulse[0] / dt, impulse[1] / dt, impulse[2] / dt, impulse[3] / dt
        finite = self.valid_state()
        self._invalid = not finite
        self._update_feet(finite)
        self._x_velocity = (float(sim.x[IX]) - self._x_before) / dt
        healthy = self._healthy(finite)
        ctrl = -self.ctrl_cost_weight * sum(v * v for v in values)
        if finite:
            d = (self._x_velocity - self.target_speed) / self.tracking_sigma
            fwd = self.forward_reward_weight * math.exp(-(d * d))  # d * d, as the vector env's compiled _finish
        else:
            fwd = 0.0
        alive = self.healthy_reward_weight if healthy else 0.0
        self._last_rewards = (fwd, ctrl, alive)
        reward = float(fwd + ctrl + alive)
        terminated = (not finite) or (self.terminate_when_unhealthy and not healthy)
        if self.render_mode == "human":
            self.render()
        return self._get_obs(), reward, bool(terminated), False, self._get_info()

    @staticmethod
    def _parse_action(action) -> list:
        """The action as a list of 4 finite Python floats (not yet clipped); raises naming ``action``."""
        a = real_array(action, "action")
        if a.shape != (NU,):
            raise ValueError(f"action must have shape ({NU},), got {a.shape}")
        values = [float(v) for v in a.tolist()]
        if not all(map(math.isfinite, values)):
            raise ValueError(f"action must be finite, got {a}")
        return values

    # ------------------------------------------------------------------ pushes
    @staticmethod
    def _check_delta_v(delta_v, name: str) -> np.ndarray:
        return check_vector(delta_v, 3, name)

    def _parse_push(self, push):
        """``(immediate delta_v or None, scheduled [(time, delta_v), ...] in time order)`` from the ``push``
        option."""
        if push is None:
            return None, []
        if isinstance(push, dict):
            return None, [self._parse_scheduled_push(push, "options['push']")]
        if isinstance(push, list) and all(isinstance(p, dict) for p in push):
            scheduled = [self._parse_scheduled_push(p, f"options['push'][{i}]") for i, p in enumerate(push)]
            return None, sorted(scheduled, key=lambda p: p[0])
        return self._check_delta_v(push, "options['push']"), []

    def _parse_scheduled_push(self, push: dict, name: str) -> tuple:
        extra = sorted(set(push) - {"delta_v", "time"})
        if extra or "delta_v" not in push or "time" not in push:
            raise ValueError(f"{name} as a dict needs exactly the keys 'delta_v' and 'time', got {sorted(push)}")
        t = check_positive(push["time"], f"{name}['time']", allow_zero=True)
        return t, self._check_delta_v(push["delta_v"], f"{name}['delta_v']")

    def apply_push(self, delta_v) -> np.ndarray:
        """Push the trunk now: an instantaneous change ``delta_v`` (3,) = ``[dvx, dvz, dpitch_rate]``
        [m/s, m/s, rad/s] of the base velocities (joint rates unchanged; the contact solver handles feet on
        the ground at the next step).

        Returns:
            The observation after the push (float32).
        """
        self.sim.v[:3] += self._check_delta_v(delta_v, "delta_v")
        return self._get_obs()

    # ------------------------------------------------------------------ rendering
    def render(self):
        """``rgb_array``: an ``(height, width, 3)`` uint8 image; ``human``: show it in a matplotlib window
        (a no-op with a warning on a non-interactive backend, e.g. headless CI) and return None."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human' "
                            "to gym.make / BoundingEnv")
            return None
        from hsddp_gym.viz.render import render_state

        x = self.sim.x
        if not np.all(np.isfinite(x)):
            x = np.nan_to_num(x)
        frame = render_state(x, robot=self.robot, width=self.width, height=self.height,
                             grf=self._grf if self.render_grf else None, contact=self._contact, terrain=self.terrain,
                             text=f"t = {self.time:5.2f} s   vx = {self._x_velocity:+.2f} m/s")
        if self.render_mode == "rgb_array":
            return frame
        self._show(frame)
        return None

    def _show(self, frame: np.ndarray) -> None:
        import matplotlib

        backend = matplotlib.get_backend().lower()
        if backend in ("agg", "pdf", "ps", "svg", "pgf", "cairo", "template") or "inline" in backend:
            if self._figure is None:
                gym.logger.warn(f"render_mode='human' needs an interactive matplotlib backend; '{backend}' is "
                                "not interactive (headless?), so frames are not shown")
                self._figure = False
            return
        import matplotlib.pyplot as plt

        if not self._figure:
            fig, ax = plt.subplots(figsize=(self.width / 100.0, self.height / 100.0), dpi=100)
            ax.set_axis_off()
            fig.subplots_adjust(0, 0, 1, 1)
            self._figure = (fig, ax.imshow(frame))
            plt.show(block=False)
        fig, image = self._figure
        image.set_data(frame)
        fig.canvas.draw_idle()
        plt.pause(max(1e-3, 1.0 / self.metadata["render_fps"]))

    def close(self) -> None:
        """Close the human-mode window, if any."""
        if self._figure:
            import matplotlib.pyplot as plt

            plt.close(self._figure[0])
        self._figure = None
