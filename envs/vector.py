"""``gym.make_vec("hsddp_gym/Bounding-v0", num_envs=N, vectorization_mode="vector_entry_point")``: N robots of
[`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] stepped together by one compiled call
([`hsddp_gym.core.batch_contact`][hsddp_gym.core.batch_contact]), with the transitions of N single envs (see
[`BoundingVectorEnv`][BoundingVectorEnv])."""

from __future__ import annotations

import math
import numbers

import numba
import numpy as np
import pinocchio as pin
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from hsddp_gym.core import batch_contact
from hsddp_gym.core.batch_model import kernel_params, model_cache
from hsddp_gym.core.contact_lcp import SEPARATE
from hsddp_gym.core.conventions import IPITCH, IZ, NGRF, NQ, NU, NX
from hsddp_gym.core.observation import RESET_CONTACT_HEIGHT, ObservationLayout
from hsddp_gym.envs.bounding import _MAX_PENETRATION_AT_RESET, DEFAULT_MAX_EPISODE_STEPS, BoundingEnv, pop_due_pushes
from hsddp_gym.envs.perturbations import PUSH_SALT, PushDistribution, episode_generator
from hsddp_gym.util.validation import check_int, check_positive, real_array

UNSUPPORTED_KWARGS = ("render_mode", "width", "height", "render_grf")
"""BoundingEnv arguments the vector env does not take (it does not render)."""
RESET_OPTION_KEYS = ("state", "time", "reset_mask")
"""The reset options of the vector envs (the single env's ``"push"`` is not offered: their ``push`` argument)."""
INFO_KEYS = ("x_position", "x_velocity", "reward_forward", "reward_ctrl", "reward_healthy", "contact", "foot_heights",
             "grf", "qpos", "qvel", "time", "invalid_state")
"""The batched ``info`` keys (each with its ``_key`` mask): the single env's keys, one row per robot."""
_MASK_KEYS = tuple("_" + key for key in INFO_KEYS)

# ------------------------------------------------------------------------------ the env parameter vector
EP_DT = 0  # the control period [s]
EP_TARGET_SPEED = 1  # [m/s]
EP_TRACKING_SIGMA = 2  # the forward reward's width [m/s]
EP_FORWARD_WEIGHT = 3
EP_CTRL_WEIGHT = 4
EP_HEALTHY_WEIGHT = 5
EP_TERMINATE_UNHEALTHY = 6  # 1.0: a fall ends the episode, 0.0: it does not
EP_Z_LOW = 7  # healthy_z_range (open interval) [m]
EP_Z_HIGH = 8
EP_PITCH_LOW = 9  # healthy_pitch_range (open interval) [rad]
EP_PITCH_HIGH = 10
EP_GAIT_PERIOD = 11  # the observation's phase clock [s]
N_ENV_PARAMS = 12
"""Length of the env parameter vector ([`env_params`][env_params]): the single env's reward and termination settings,
read by the compiled step's bookkeeping at the ``EP_*`` slots."""


def env_params(env: BoundingEnv) -> np.ndarray:
    """The env parameter vector (N_ENV_PARAMS,) of a [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (its control
    period, reward weights, healthy ranges, gait period) at the ``EP_*`` slots."""
    if not isinstance(env, BoundingEnv):
        raise TypeError(f"env must be a BoundingEnv, got {type(env).__name__}")
    p = np.zeros(N_ENV_PARAMS)
    p[EP_DT] = env.dt
    p[EP_TARGET_SPEED] = env.target_speed
    p[EP_TRACKING_SIGMA] = env.tracking_sigma
    p[EP_FORWARD_WEIGHT] = env.forward_reward_weight
    p[EP_CTRL_WEIGHT] = env.ctrl_cost_weight
    p[EP_HEALTHY_WEIGHT] = env.healthy_reward_weight
    p[EP_TERMINATE_UNHEALTHY] = float(env.terminate_when_unhealthy)
    p[EP_Z_LOW], p[EP_Z_HIGH] = env.healthy_z_range
    p[EP_PITCH_LOW], p[EP_PITCH_HIGH] = env.healthy_pitch_range
    p[EP_GAIT_PERIOD] = env.gait_period
    return p



def parse_autoreset_mode(value) -> AutoresetMode:
    """``autoreset_mode`` of a vector env of this package: ``"next_step"`` / ``"same_step"`` (also Gymnasium's
    ``"NextStep"`` / ``"SameStep"``, or the `AutoresetMode`); ValueError naming it otherwise (DISABLED is not
    offered)."""
    names = {"nextstep": AutoresetMode.NEXT_STEP, "samestep": AutoresetMode.SAME_STEP}
    if isinstance(value, AutoresetMode):
        mode = value
    elif isinstance(value, str) and value.replace("_", "").lower() in names:
        mode = names[value.replace("_", "").lower()]
    else:
        mode = None
    if mode not in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
        raise ValueError(f"autoreset_mode must be 'next_step' or 'same_step', got {value!r} (DISABLED is not offered)")
    return mode


def robot_seeds(seed, n: int) -> list:
    """The reset seed of each of ``n`` robots, as ``SyncVectorEnv.reset``: None for all, ``seed + i`` from an int,
    or a list of ``n`` seeds (TypeError / ValueError naming ``seed`` otherwise)."""
    if seed is None:
        return [None] * n
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        return [int(seed) + i for i in range(n)]
    if isinstance(seed, (list, tuple)):
        if len(seed) != n:
            raise ValueError(f"seed as a list must have num_envs={n} entries, got {len(seed)}")
        return list(seed)
    raise TypeError(f"seed must be None, an int or a list of num_envs ints, got {type(seed).__name__}")


def parse_reset_options(options, n: int, owner: str) -> tuple:
    """A vector env's ``reset`` ``options`` ([`RESET_OPTION_KEYS`][RESET_OPTION_KEYS]) for ``n`` robots, checked
    (TypeError / ValueError naming the option and ``owner``, the vector env's name).

    Returns:
        ``(mask, states, times)``: ``mask`` (n,) bool of the robots to reset (None: all), ``states`` (n, 14) float64
        (each row still to be checked as a start state by the single env) or None, ``times`` (n,) float64 >= 0 or None.
    """
    if options is None:
        return None, None, None
    if not isinstance(options, dict):
        raise TypeError(f"options must be a dict or None, got {type(options).__name__}")
    unknown = sorted(set(options) - set(RESET_OPTION_KEYS))
    if unknown:
        raise ValueError(f"unknown reset option(s) {unknown} for {owner}; allowed: {list(RESET_OPTION_KEYS)} (the "
                         "single env's 'push' is not offered: use the push argument)")
    mask = options.get("reset_mask")
    if mask is not None:
        if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_ or mask.shape != (n,):
            raise ValueError(f"options['reset_mask'] must be a bool numpy array of shape ({n},), got {mask!r}")
        if not mask.any():
            raise ValueError("options['reset_mask'] must select at least one robot")
    states = None
    if options.get("state") is not None:
        states = real_array(options["state"], "options['state']").astype(np.float64, copy=False)
        if states.shape != (n, NX):
            raise ValueError(f"options['state'] must have shape ({n}, {NX}) (one state per robot), got "
                             f"{states.shape}")
    times = None
    if options.get("time") is not None:
        t = options["time"]
        if isinstance(t, numbers.Real) and not isinstance(t, bool):
            times = np.full(n, check_positive(t, "options['time']", allow_zero=True))
        else:
            arr = real_array(t, "options['time']")
            if arr.shape != (n,):
                raise ValueError(f"options['time'] must be a number or have shape ({n},), got {arr.shape}")
            times = np.array([check_positive(float(v), f"options['time'][{i}]", allow_zero=True)
                              for i, v in enumerate(arr.tolist())])
    return mask, states, times


@numba.njit(cache=True)
def _prepare(actions, values, u, limit, x, x_before, autoreset, next_step, stepped):
    """The per-robot work before a step (BoundingEnv.step's action handling), in one compiled pass: ``values (N, 4)``
    the actions ``actions (N, 4)`` (any real dtype) as float64 clipped to [-1, 1], ``u (N, 4)`` = ``values * limit``
    the commanded torques, ``x_before (N,)`` the trunk x of ``x (N, 14)``, ``stepped (N,)`` the robots to step (all,
    or those not autoreset in NEXT_STEP mode, ``autoreset (N,)``). Returns the first robot with a non-finite
    action (the caller raises), or -1."""
    for r in range(actions.shape[0]):
        for j in range(NU):
            a = np.float64(actions[r, j])
            if not math.isfinite(a):
                return r
            values[r, j] = 1.0 if a > 1.0 else (-1.0 if a < -1.0 else a)  # the single env's clip
            u[r, j] = values[r, j] * limit
        x_before[r] = x[r, 0]
        stepped[r] = not (next_step and autoreset[r])
    return -1


@numba.njit(cache=True)
def _finish(x, x_before, values, contact, heights, impulse, t0, sim_time, stepped, env_p, bounds, low, high, skip,
            obs, reward, terminated, valid, x_velocity, grf, rewards3, elapsed, max_steps, truncated, done):
    """Observation, reward, termination of the robots with ``stepped[r]`` after their step (BoundingEnv.step), and
    the episode bookkeeping of every robot: ``elapsed (N,)`` steps (+1 if stepped), ``truncated (N,)`` (a stepped
    robot at ``max_steps``; ``max_steps`` < 0: no limit), ``done (N,)`` = stepped and (terminated or truncated).

    ``env_p`` (N_ENV_PARAMS,) the env parameter vector ([`env_params`][env_params]); ``bounds (14,)`` the valid-state
    bounds; ``low``, ``high`` the float32 observation box; ``values (N, 4)`` the clipped actions. Returns the number of
    robots done."""
    dt = env_p[EP_DT]
    n_done = 0
    for r in range(x.shape[0]):
        truncated[r] = False
        done[r] = False
        if not stepped[r]:
            continue
        elapsed[r] += 1
        truncated[r] = max_steps >= 0 and elapsed[r] >= max_steps
        xr = x[r]
        ok = True
        for i in range(NX):
            if not abs(xr[i]) <= bounds[i]:
                ok = False
        valid[r] = ok
        if not ok:
            heights[r, 0] = np.nan
            heights[r, 1] = np.nan
            contact[r, 0] = False
            contact[r, 1] = False
        for i in range(NGRF):
            grf[r, i] = impulse[r, i] / dt
        xv = (xr[0] - x_before[r]) / dt
        x_velocity[r] = xv
        healthy = (ok and env_p[EP_Z_LOW] < xr[IZ] < env_p[EP_Z_HIGH]
                   and env_p[EP_PITCH_LOW] < xr[IPITCH] < env_p[EP_PITCH_HIGH])
        a = values[r]
        ctrl = -env_p[EP_CTRL_WEIGHT] * (a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + a[3] * a[3])
        d = (xv - env_p[EP_TARGET_SPEED]) / env_p[EP_TRACKING_SIGMA]
        # d * d: the single env's arithmetic, exactly
        fwd = env_p[EP_FORWARD_WEIGHT] * math.exp(-(d * d)) if ok else 0.0
        alive = env_p[EP_HEALTHY_WEIGHT] if healthy else 0.0
        rewards3[r, 0] = fwd
        rewards3[r, 1] = ctrl
        rewards3[r, 2] = alive
        reward[r] = fwd + ctrl + alive
        terminated[r] = (not ok) or (env_p[EP_TERMINATE_UNHEALTHY] != 0.0 and not healthy)
        done[r] = terminated[r] or truncated[r]
        n_done += done[r]
        cycles = (t0[r] + sim_time[r]) / env_p[EP_GAIT_PERIOD]
        _fill_obs(obs[r], xr, contact[r, 0], contact[r, 1], cycles, low, high, skip)
    return n_done


@numba.njit(cache=True)
def _fill_obs(o, xr, front, back, cycles, low, high, skip):
    """hsddp_gym.core.observation.fill_observation for one robot."""
    nq = NQ - skip
    for i in range(nq):
        o[i] = np.float32(xr[skip + i])
    for i in range(NQ):
        o[nq + i] = np.float32(xr[NQ + i])
    c = nq + NQ
    o[c] = 1.0 if front else 0.0
    o[c + 1] = 1.0 if back else 0.0
    angle = 2.0 * math.pi * cycles
    o[c + 2] = np.float32(math.sin(angle))
    o[c + 3] = np.float32(math.cos(angle))
    for i in range(o.shape[0]):
        if o[i] != o[i]:  # NaN of an invalid state
            o[i] = 0.0
        elif o[i] > high[i]:
            o[i] = high[i]
        elif o[i] < low[i]:
            o[i] = low[i]


@numba.njit(cache=True)
def _noisy_state(init, uniform, scale, normal, x):
    """``x`` (14,) = the start state ``init`` (14,) plus the reset noise (BoundingEnv.reset's arithmetic): ``uniform``
    (7,) added to the positions, ``scale * normal`` (7,) to the velocities."""
    for j in range(NQ):
        x[j] = init[j] + uniform[j]
        x[NQ + j] = init[NQ + j] + scale * normal[j]


@numba.njit(cache=True)
def _reset_row(i, bounds, front, back, cycles, t0, x, lcp_states, sim_time, t0s, elapsed, valid, heights, contact, grf,
               impulse, x_velocity, rewards3, reward, terminated, truncated, autoreset, obs, low, high, skip):
    """The bookkeeping of BoundingEnv.reset for robot ``i`` whose start state is ``x[i]``, in one compiled call:
    clock, foot states, counters cleared; the state valid when inside ``bounds`` (14,); ``front``, ``back`` its
    foot heights (a foot at most RESET_CONTACT_HEIGHT high is in contact; an invalid state has NaN heights and no
    contact); ``cycles`` the gait phase of ``t0``; the observation."""
    ok = True
    for j in range(NX):
        if not abs(x[i, j]) <= bounds[j]:
            ok = False
    if not ok:  # pragma: no cover - a checked reset state is always valid
        front = np.nan
        back = np.nan
    lcp_states[i, 0] = SEPARATE
    lcp_states[i, 1] = SEPARATE
    sim_time[i] = 0.0
    t0s[i] = t0
    elapsed[i] = 0
    valid[i] = ok
    heights[i, 0] = front
    heights[i, 1] = back
    contact[i, 0] = front <= RESET_CONTACT_HEIGHT
    contact[i, 1] = back <= RESET_CONTACT_HEIGHT
    for j in range(NGRF):
        grf[i, j] = 0.0
        impulse[i, j] = 0.0
    x_velocity[i] = x[i, NQ]
    for j in range(3):
        rewards3[i, j] = 0.0
    reward[i] = 0.0
    terminated[i] = False
    truncated[i] = False
    autoreset[i] = False
    _fill_obs(obs[i], x[i], contact[i, 0], contact[i, 1], cycles, low, high, skip)


class BoundingVectorEnv(VectorEnv):
    """``num_envs`` robots of ``hsddp_gym/Bounding-v0`` in one `gymnasium.vector.VectorEnv`.

    Every robot follows the single env exactly: the same physics
    ([`hsddp_gym.core.batch_contact`][hsddp_gym.core.batch_contact], the scheme of
    [`ContactSimulator`][hsddp_gym.core.contact.ContactSimulator] compiled for N robots, equal to it up to round-off;
    the single env steps through the same compiled code, so the transitions are bit-identical,
    ``tests/test_vector_env.py``), reset noise, reward, termination (falls; an invalid state always terminates with
    ``info["invalid_state"]``), observation and info keys, and the registered time limit (``max_episode_steps``,
    truncation). ``reset(seed=s)`` seeds robot ``i`` with ``s + i`` (a list gives one seed per robot), as
    `gymnasium.vector.SyncVectorEnv`, so that the transitions equal those of N single envs
    ``gym.make("hsddp_gym/Bounding-v0")`` reset with the seeds ``s + i``.

    Autoreset: ``autoreset_mode="next_step"`` (the default, as ``SyncVectorEnv``): the step after a robot's
    episode ended resets it (its action is ignored, reward 0, ``terminated = truncated = False``) and returns
    the reset observation and info; ``"same_step"``: a robot whose episode ends is reset in the same step, its
    last observation and info in ``info["final_obs"]`` (object array, None for the others) and
    ``info["final_info"]`` (batched, with masks), as ``SyncVectorEnv``.

    Args:
        num_envs: number of robots (>= 1).
        max_episode_steps: truncate an episode after this many steps (int >= 1), or None for no limit
            (``gym.make_vec`` passes the registered 1000).
        autoreset_mode: ``"next_step"`` / ``"same_step"`` (also Gymnasium's ``"NextStep"`` / ``"SameStep"``, or the
            `AutoresetMode`).
        **kwargs: the arguments of [`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv] (validated by it), except
            the rendering ones ([`UNSUPPORTED_KWARGS`][UNSUPPORTED_KWARGS]) and ``energy_consistent=False`` (the legacy
            scheme is not compiled), which raise.

    Spaces: ``single_observation_space`` / ``single_action_space`` are the single env's; observations
    ``(num_envs, 17)`` float32, actions ``(num_envs, 4)`` (clipped to [-1, 1]; non-finite entries or another
    shape raise ValueError). ``reset(options=...)`` accepts ``"state"`` ((num_envs, 14): one start state per
    robot, checked as the single env's ``options["state"]``), ``"time"`` (a float or (num_envs,)), and
    ``"reset_mask"`` ((num_envs,) bool: reset only those robots); the single env's ``"push"`` is not offered.

    Random pushes (training under perturbation): ``push`` (a
    [`PushDistribution`][hsddp_gym.envs.perturbations.wrappers.PushDistribution] or a dict of its fields, ``{}`` its
    defaults) gives every robot random pushes in every episode, drawn at each of its resets as
    [`RandomPush`][hsddp_gym.envs.perturbations.wrappers.RandomPush] draws them, and applied at the same simulation step
    as the single env's ``push`` reset option: robot ``i`` reset with seed ``s`` moves exactly as
    ``RandomPush(gym.make("hsddp_gym/Bounding-v0"), **push)`` reset with ``s`` (``tests/test_vector_env.py``).
    The schedule of robot ``i``'s episode is [`scheduled_pushes`][scheduled_pushes] (not in ``info``).
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = DEFAULT_MAX_EPISODE_STEPS,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP, push=None, **kwargs) -> None:
        self.num_envs = check_int(num_envs, "num_envs", minimum=1)
        self.push: PushDistribution | None = None if push is None else PushDistribution.parse(push, "push")
        """The random pushes of every episode (None: none)."""
        if max_episode_steps is not None:
            max_episode_steps = check_int(max_episode_steps, "max_episode_steps", minimum=1)
        self.max_episode_steps = max_episode_steps
        self.autoreset_mode = mode = parse_autoreset_mode(autoreset_mode)
        unsupported = sorted(set(kwargs) & set(UNSUPPORTED_KWARGS))
        if unsupported:
            raise TypeError(f"BoundingVectorEnv does not render; unsupported argument(s) {unsupported}")
        if kwargs.get("terrain") is not None:
            raise ValueError("BoundingVectorEnv simulates the flat ground only: terrain must be None, got "
                             f"{kwargs['terrain']!r} (use hsddp_gym.envs.task_vector.TaskVectorEnv, which gym.make_vec "
                             "builds for hsddp_gym/Terrain-v0)")
        if "energy_consistent" in kwargs and kwargs["energy_consistent"] is not True:
            raise ValueError("BoundingVectorEnv compiles only the energy-consistent scheme: energy_consistent must "
                             f"be True, got {kwargs['energy_consistent']!r}")
        try:
            template = BoundingEnv(**kwargs)  # validates every argument, names the offending one
        except TypeError as exc:
            if "unexpected keyword argument" in str(exc):
                raise TypeError(f"BoundingVectorEnv: {exc}") from exc
            raise
        self.template = template
        """A single [`BoundingEnv`][BoundingEnv] built with the same arguments: the validated settings, the robot model,
        the reset-state checks (it is never stepped)."""
        self.env_kwargs = dict(kwargs)
        self.metadata = {**type(self).metadata, "autoreset_mode": mode, "render_fps": template.metadata["render_fps"]}
        self.render_mode = None
        self.single_observation_space = template.observation_space
        self.single_action_space = template.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_layout: ObservationLayout = template.observation_layout
        self.dt = template.dt

        batch_contact.warm_up()
        self._p = kernel_params(template.sim)
        self._env_p = env_params(template)
        self._bounds = template._state_bounds.copy()
        self._low, self._high = (b.astype(np.float32) for b in template.observation_layout.bounds())
        self._skip = template.observation_layout.skipped_qpos
        n = self.num_envs
        self._x = np.tile(template.init_state, (n, 1))
        self._u = np.zeros((n, NU))
        self._values = np.zeros((n, NU))
        self._lcp_states = np.full((n, 2), SEPARATE, dtype=np.int64)
        self._contact = np.zeros((n, 2), dtype=np.bool_)
        self._impulse = np.zeros((n, NGRF))
        self._sim_time = np.zeros(n)
        self._t0 = np.zeros(n)
        self._heights = np.zeros((n, 2))
        self.counters = np.zeros((n, 4), dtype=np.int64)
        """Per robot ``[lcp_fallbacks, energy_projections, momentum_fallbacks, energy_deficits]`` since creation
        ([`hsddp_gym.core.batch_contact.COUNTER_NAMES`][hsddp_gym.core.batch_contact.COUNTER_NAMES])."""
        self._scratch = batch_contact.kernel_scratch()
        self._model_cache = model_cache(n)
        self._obs = np.zeros((n, template.observation_layout.size), dtype=np.float32)
        self._reward = np.zeros(n)
        self._terminated = np.zeros(n, dtype=np.bool_)
        self._truncated = np.zeros(n, dtype=np.bool_)
        self._valid = np.ones(n, dtype=np.bool_)
        self._x_velocity = np.zeros(n)
        self._grf = np.zeros((n, NGRF))
        self._rewards3 = np.zeros((n, 3))
        self._x_before = np.zeros(n)
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._max_steps = -1 if max_episode_steps is None else max_episode_steps
        self._done = np.zeros(n, dtype=np.bool_)
        self._autoreset_pending = False
        self._autoreset = np.zeros(n, dtype=np.bool_)
        self._stepped = np.zeros(n, dtype=np.bool_)
        self._all = np.ones(n, dtype=np.bool_)
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._rng_seeds: list[int | None] = [None] * n
        self._push_rngs: list[np.random.Generator | None] = [None] * n
        self._push_schedules: list[list] = [[] for _ in range(n)]
        self._next_push = np.full(n, np.inf)  # each robot's next scheduled push time (inf: none)
        self._needs_reset = True

    # ------------------------------------------------------------------ seeding
    @property
    def np_random_seed(self) -> tuple:
        """The seed of each robot's generator, as ``SyncVectorEnv.np_random_seed``."""
        for i in range(self.num_envs):
            self._rng(i)
        return tuple(self._rng_seeds)

    def _rng(self, i: int) -> np.random.Generator:
        if self._rngs[i] is None:
            self._rngs[i], self._rng_seeds[i] = seeding.np_random()
        return self._rngs[i]

    # ------------------------------------------------------------------ reset
    def _foot_heights(self, q: np.ndarray) -> tuple[float, float]:
        """``template.robot.foot_heights(q)`` (Pinocchio, the same numbers) unchecked, as two floats ``(front,
        back)``: the single env's ``foot_heights_fast`` on the template's simulator."""
        sim = self.template.sim
        model, data = sim.model, sim.data
        pin.forwardKinematics(model, data, q)
        return (float(pin.updateFramePlacement(model, data, sim._fids[0]).translation[2]),
                float(pin.updateFramePlacement(model, data, sim._fids[1]).translation[2]))

    def _reset_one(self, i: int, seed, state, t0: float) -> None:
        """BoundingEnv.reset for robot ``i`` (state: a checked (14,) array or None), after RandomPush.reset's
        draws of the episode's pushes (with ``push``)."""
        template = self.template
        if self.push is not None:
            rng = episode_generator(seed, PUSH_SALT, self._push_rngs[i], lambda: self._rng(i))
            self._push_rngs[i] = rng
            self._push_schedules[i] = sorted(((float(p["time"]), np.asarray(p["delta_v"], dtype=np.float64))
                                              for p in self.push.draw(rng)), key=lambda p: p[0])
            self._next_push[i] = self._push_schedules[i][0][0] if self._push_schedules[i] else np.inf
        if seed is not None:
            self._rngs[i], self._rng_seeds[i] = seeding.np_random(seed)
        x = self._x[i]
        if state is not None:
            x[:] = state
            front, back = self._foot_heights(x[:NQ])  # x is finite: checked
        else:
            rng = self._rng(i)
            s = template.reset_noise_scale
            _noisy_state(template.init_state, rng.uniform(low=-s, high=s, size=NQ), s, rng.standard_normal(NQ), x)
            front, back = self._foot_heights(x[:NQ])
            lowest = min(front, back)
            if lowest < 0.0:
                x[IZ] -= lowest
                front, back = self._foot_heights(x[:NQ])  # of the lifted state (as the single env's)
        _reset_row(i, self._bounds, front, back, t0 / template.gait_period, t0, self._x, self._lcp_states,
                   self._sim_time, self._t0, self._elapsed, self._valid, self._heights, self._contact, self._grf,
                   self._impulse,
                   self._x_velocity, self._rewards3, self._reward, self._terminated, self._truncated,
                   self._autoreset, self._obs, self._low, self._high, self._skip)

    def _parse_options(self, options) -> tuple:
        """``(mask (N,) bool, states [x (14,) or None per robot] or None, t0 (N,))`` of ``reset``'s ``options``, each
        start state checked as the single env checks it."""
        n = self.num_envs
        mask, raw, times = parse_reset_options(options, n, "BoundingVectorEnv")
        mask = self._all if mask is None else mask
        states = None
        if raw is not None:
            states = []
            for i in range(n):
                if not mask[i]:
                    states.append(None)
                    continue
                try:
                    x = self.template._check_reset_state(raw[i])
                except ValueError as exc:
                    raise ValueError(f"robot {i}: {exc}") from exc
                heights = self.template.robot.foot_heights(x[:NQ])
                if heights.min() < -_MAX_PENETRATION_AT_RESET:
                    raise ValueError(f"robot {i}: options['state'] puts a foot {-heights.min():.4g} m below the "
                                     f"ground (at most {_MAX_PENETRATION_AT_RESET} m allowed)")
                states.append(x)
        return mask, states, np.zeros(n) if times is None else times

    def reset(self, *, seed=None, options: dict | None = None):
        """Reset every robot (or those of ``options["reset_mask"]``); see the class docstring.

        Returns:
            ``(observations (num_envs, obs_dim) float32, info)`` (batched info, every key with its mask).
        """
        seeds = robot_seeds(seed, self.num_envs)
        mask, states, t0 = self._parse_options(options)
        for i in range(self.num_envs):
            if mask[i]:
                self._reset_one(i, seeds[i], None if states is None else states[i], float(t0[i]))
        self._needs_reset = False
        return self._obs.copy(), self._info()

    # ------------------------------------------------------------------ step
    def _check_actions(self, actions) -> None:
        """Check the actions (real, shape (num_envs, 4), finite: else TypeError / ValueError naming the robots) and
        load them ([`_prepare`][_prepare]: clipped values, torques, the trunk x before the step, the robots to step)."""
        a = real_array(actions, "actions")
        if a.shape != (self.num_envs, NU):
            raise ValueError(f"actions must have shape ({self.num_envs}, {NU}), got {a.shape}")
        if _prepare(a, self._values, self._u, self.template.torque_limit, self._x, self._x_before, self._autoreset,
                    self.autoreset_mode == AutoresetMode.NEXT_STEP, self._stepped) >= 0:
            values = a.astype(np.float64)
            bad = sorted({int(r) for r in np.nonzero(~np.isfinite(values))[0]})
            raise ValueError(f"actions must be finite; robot(s) {bad} got non-finite entries")

    def step(self, actions):
        """Step every robot (an autoreset robot is reset instead, NEXT_STEP mode); see the class docstring.

        Returns:
            ``(observations, rewards (num_envs,) float64, terminated, truncated, info)``.
        """
        if self._needs_reset:
            raise RuntimeError("BoundingVectorEnv.step() called before reset()")
        self._check_actions(actions)
        next_step = self.autoreset_mode == AutoresetMode.NEXT_STEP
        stepped = self._stepped
        due = self._due_pushes() if self.push is not None else None
        bulk = stepped
        if due:
            bulk = stepped.copy()
            bulk[list(due)] = False
        self._run(self.template.frame_skip, bulk)
        if due:
            for i, pushes in due.items():
                self._run_pushed(i, pushes)
        n_done = _finish(self._x, self._x_before, self._values, self._contact, self._heights, self._impulse,
                         self._t0, self._sim_time, stepped, self._env_p, self._bounds, self._low, self._high,
                         self._skip, self._obs, self._reward, self._terminated, self._valid, self._x_velocity,
                         self._grf, self._rewards3, self._elapsed, self._max_steps, self._truncated, self._done)
        done = self._done  # a robot reset in this step did not end
        final = None
        if next_step:
            if self._autoreset_pending:
                for i in np.nonzero(~stepped)[0]:
                    self._reset_one(int(i), None, None, 0.0)  # clears reward, terminated, truncated
            self._autoreset[:] = done
            self._autoreset_pending = n_done > 0
        elif n_done:
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.nonzero(done)[0]:
                final_obs[i] = self._obs[i].copy()
            final_info = self._info(mask=done)
            final = (final_obs, final_info, done.copy())
        obs, reward = self._obs.copy(), self._reward.copy()
        terminated, truncated = self._terminated.copy(), self._truncated.copy()
        if final is not None:
            for i in np.nonzero(final[2])[0]:
                self._reset_one(int(i), None, None, 0.0)
            obs = self._obs.copy()
        info = self._info()
        if final is not None:
            info["final_obs"], info["_final_obs"] = final[0], final[2]
            info["final_info"], info["_final_info"] = final[1], final[2]
        return obs, reward, terminated, truncated, info

    def _run(self, n: int, active: np.ndarray) -> None:
        """``n`` simulation steps of the robots of ``active`` ((num_envs,) bool)."""
        batch_contact.step_batch(self._p, self._x, self._u, n, active, self._lcp_states, self._contact, self._impulse,
                                 self._sim_time, self._heights, self.counters, self._model_cache, self._scratch)

    def _due_pushes(self) -> dict:
        """``{robot: [(k, delta_v), ...]}``: the robots to be stepped whose scheduled pushes come in this control
        step ([`pop_due_pushes`][hsddp_gym.envs.bounding.pop_due_pushes], removed from their schedules)."""
        n, h = self.template.frame_skip, self.template.sim_timestep
        due = {}
        # a cheap vectorized screen (pop_due_pushes' own test, elementwise), then the rule for those robots only
        soon = self._stepped & (self._next_push < self._t0 + self._sim_time + n * h - 1e-12)
        for i in np.nonzero(soon)[0]:
            schedule = self._push_schedules[i]
            pushes = pop_due_pushes(schedule, float(self._t0[i] + self._sim_time[i]), n, h)
            if pushes:
                due[int(i)] = pushes
            self._next_push[i] = schedule[0][0] if schedule else np.inf
        return due

    def _run_pushed(self, i: int, pushes: list) -> None:
        """Robot ``i``'s control step split at its pushes (the single env's arithmetic: its impulses summed over
        the pieces in the same order)."""
        n = self.template.frame_skip
        one = np.zeros(self.num_envs, dtype=np.bool_)
        one[i] = True
        impulse, done = [0.0] * NGRF, 0
        for k, delta_v in pushes:
            if k > done:
                self._run(k - done, one)
                impulse = [a + r for a, r in zip(impulse, self._impulse[i])]
                done = k
            self._x[i, NQ:NQ + 3] += delta_v
        if n > done:
            self._run(n - done, one)
            impulse = [a + r for a, r in zip(impulse, self._impulse[i])]
        self._impulse[i] = impulse

    def scheduled_pushes(self, i: int) -> list:
        """Robot ``i``'s pushes still to come this episode: ``[(time [s], delta_v (3,)), ...]`` in time order
        (empty without ``push``)."""
        check_int(i, "i", minimum=0)
        if i >= self.num_envs:
            raise ValueError(f"i must be < num_envs={self.num_envs}, got {i}")
        return [(t, dv.copy()) for t, dv in self._push_schedules[i]]

    def _info(self, mask: np.ndarray | None = None) -> dict:
        """The batched info (the single env's keys, [`INFO_KEYS`][INFO_KEYS]), each key with its ``_key`` mask."""
        x = self._x
        valid = self._valid
        mask = self._all if mask is None else mask
        info = {
            "x_position": x[:, 0].copy(),
            "x_velocity": self._x_velocity.copy(),
            "reward_forward": self._rewards3[:, 0].copy(),
            "reward_ctrl": self._rewards3[:, 1].copy(),
            "reward_healthy": self._rewards3[:, 2].copy(),
            "contact": self._contact.copy(),
            "foot_heights": self._heights.copy(),
            "grf": self._grf.copy(),
            "qpos": x[:, :NQ].copy(),
            "qvel": x[:, NQ:].copy(),
            "time": self._t0 + self._sim_time,
            "invalid_state": ~valid,
        }
        masks = np.empty((len(INFO_KEYS), self.num_envs), dtype=np.bool_)
        masks[:] = mask  # one fresh array, a row (view) per key
        info.update(zip(_MASK_KEYS, masks))
        return info

    def close_extras(self, **kwargs) -> None:
        """Nothing to release (no processes, no windows)."""

