"""``gym.make_vec(ID, num_envs=N)`` for every task env of the bounding family (``Backflip-v0``, ``GapJump-v0``,
``BoxJump-v0``, ``StandToBound-v0``, ``BoundPronkBound-v0``, ``BoundToStop-v0``, ``Pronking-v0``, ``Terrain-v0``):
N robots whose physics runs in one compiled call per control step, with the transitions of N single envs
(see [`TaskVectorEnv`][TaskVectorEnv]).

``hsddp_gym/Bounding-v0`` has its own, wholly compiled vector env
([`BoundingVectorEnv`][hsddp_gym.envs.vector.BoundingVectorEnv]); here only the physics is compiled and batched,
and each robot's reward, termination, observation and info are its single env's own Python code, so that every
task is served by one mechanism and the numbers cannot drift from the single env's."""

from __future__ import annotations

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from hsddp_gym.core.compiled_contact import CompiledContactSimulator, SimulatorBatch
from hsddp_gym.core.conventions import NU
from hsddp_gym.envs.backflip import BackflipEnv
from hsddp_gym.envs.bounding import BoundingEnv
from hsddp_gym.envs.jumps import JumpEnv
from hsddp_gym.envs.perturbations import PUSH_SALT, PushDistribution, episode_generator
from hsddp_gym.envs.pronking import PronkingEnv
from hsddp_gym.envs.transitions import TransitionEnv
from hsddp_gym.envs.vector import UNSUPPORTED_KWARGS, parse_autoreset_mode, parse_reset_options, robot_seeds
from hsddp_gym.util.validation import check_int, real_array

_BASE_SCALARS = (int, float, bool)


def _array_like(first, num_envs: int) -> np.ndarray | None:
    """The ``(num_envs, ...)`` array ``_add_info`` makes for a key whose first value is ``first`` (None: a nested dict,
    batched in turn)."""
    if isinstance(first, dict):
        return None
    if type(first) in _BASE_SCALARS or issubclass(type(first), np.number):
        return np.zeros(num_envs, dtype=type(first))
    if isinstance(first, np.ndarray):
        return np.zeros((num_envs, *first.shape), dtype=first.dtype)
    return np.full(num_envs, fill_value=None, dtype=object)


def _one_flat_info_per_robot(entries: list) -> bool:
    """Robot ``i``'s info is ``entries[i]``, every info has the first one's keys in its order, and no value is a
    dict or under ``"final_obs"`` (the common step: [`batch_infos`][batch_infos]'s fast path)."""
    keys = list(entries[0][1])
    if "final_obs" in keys:
        return False
    for k, (i, info) in enumerate(entries):
        if i != k or list(info) != keys:
            return False
    return not any(isinstance(v, dict) for v in entries[0][1].values())


def _batch_flat_infos(num_envs: int, infos: list) -> dict:
    """[`batch_infos`][batch_infos] of one info per robot, all with the same keys and no dict values."""
    out: dict = {}
    for key, first in infos[0].items():
        array = _array_like(first, num_envs)
        values = [info[key] for info in infos]
        if array.dtype == object:
            for i, value in enumerate(values):
                array[i] = value
        else:
            array[...] = values
        out[key] = array
        out[f"_{key}"] = np.ones(num_envs, dtype=np.bool_)
    return out


def batch_infos(num_envs: int, entries: list) -> dict:
    """The batched info of a vector env from its robots' infos, as ``VectorEnv._add_info`` builds it entry by entry,
    in one pass per key: every key with its ``(num_envs,)`` bool mask ``"_key"``; a key's array takes its dtype and
    shape from the first entry holding it (Python and NumPy numbers: ``(num_envs,)`` of that type; arrays:
    ``(num_envs, *shape)``; nested dicts: batched in turn; ``"final_obs"`` and anything else: an object array).

    Args:
        num_envs: the number of robots.
        entries: ``[(robot index, info dict), ...]`` in the order ``_add_info`` would add them (a later entry of the
            same robot overwrites an earlier one's values).

    Returns:
        The batched info (the same keys, order, dtypes and values as the ``_add_info`` chain).
    """
    if len(entries) == num_envs and _one_flat_info_per_robot(entries):
        return _batch_flat_infos(num_envs, [info for _, info in entries])
    by_key: dict = {}
    for i, info in entries:
        for key, value in info.items():
            items = by_key.get(key)
            if items is None:
                by_key[key] = items = []
            items.append((i, value))
    out: dict = {}
    for key, items in by_key.items():
        first = items[0][1]
        array = np.full(num_envs, fill_value=None, dtype=object) if key == "final_obs" else _array_like(first, num_envs)
        if array is None:
            array = batch_infos(num_envs, items)
        else:
            robots = [i for i, _ in items]
            if array.dtype != object and robots == list(range(num_envs)):
                array[...] = [value for _, value in items]  # every robot once, in order: one assignment
            else:
                for i, value in items:
                    array[i] = value
        mask = np.zeros(num_envs, dtype=np.bool_)
        mask[[i for i, _ in items]] = True
        out[key] = array
        out[f"_{key}"] = mask
    return out


class TaskVectorEnv(VectorEnv):
    """``num_envs`` robots of a task env of the bounding family in one `gymnasium.vector.VectorEnv`.

    Each robot is a single env of [`env_class`][TaskVectorEnv.env_class] built with the same arguments; a control step
    runs its three parts ([`BoundingEnv`][hsddp_gym.envs.bounding.BoundingEnv]'s ``_begin_step``, ``_simulate_step``,
    ``_end_step``) for all robots, the middle one (``frame_skip`` contact-simulation steps, most of the time) for all
    of them in one call of the compiled kernel ([`SimulatorBatch`][hsddp_gym.core.compiled_contact.SimulatorBatch],
    one call per distinct robot, friction and terrain), the single env's own code for the rest. The transitions are
    therefore bit-identical to N single envs ``gym.make(ID)`` in a ``SyncVectorEnv`` (observations, rewards,
    terminations, truncations and the batched info with its masks; ``tests/test_task_vector_env.py``). A robot whose
    random push (``push``) falls in the control step runs its step alone, split at the push, as the single env does.

    ``reset(seed=s)`` seeds robot ``i`` with ``s + i`` (a list: one seed per robot), as ``SyncVectorEnv``.
    Autoreset: ``"next_step"`` (default) or ``"same_step"``, as in
    [`BoundingVectorEnv`][hsddp_gym.envs.vector.BoundingVectorEnv] (and ``SyncVectorEnv``).

    Args:
        num_envs: number of robots (>= 1).
        max_episode_steps: truncate an episode after this many steps (int >= 1), or None for no limit
            (``gym.make_vec`` passes the registered limit).
        autoreset_mode: ``"next_step"`` / ``"same_step"`` (also ``"NextStep"`` / ``"SameStep"``, or the
            `AutoresetMode`).
        push: random pushes in every episode (a
            [`PushDistribution`][hsddp_gym.envs.perturbations.wrappers.PushDistribution] or a dict of its fields):
            robot ``i`` reset with seed ``s`` moves exactly as
            ``RandomPush(gym.make(ID), **push)`` reset with ``s``. None: no pushes.
        **kwargs: the arguments of the single env (validated by it), except the rendering ones
            ([`UNSUPPORTED_KWARGS`][hsddp_gym.envs.vector.UNSUPPORTED_KWARGS]) and ``energy_consistent=False`` (the
            legacy scheme is not compiled), which raise.

    Spaces: the single env's, batched. Actions ``(num_envs, 4)`` (each row checked and clipped as the single env
    does; another shape, or a row that is not finite, raises ValueError naming ``actions`` (and the robots) before any
    robot moves; the row of a robot reset at this step is ignored, as ``SyncVectorEnv`` ignores it). The episode's
    random pushes are not in ``info`` (as in [`BoundingVectorEnv`][hsddp_gym.envs.vector.BoundingVectorEnv]).
    ``reset(options=...)`` accepts ``"state"`` ((num_envs, 14): one start state per robot, checked by its env),
    ``"time"`` (a float or (num_envs,)) and ``"reset_mask"`` ((num_envs,) bool: reset only those robots).
    [`envs`][TaskVectorEnv.envs] gives the robots' single envs (to read, not to step).
    """

    env_class: type[BoundingEnv] = BoundingEnv
    """The single env of every robot (a subclass sets it)."""
    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, max_episode_steps: int | None = None,
                 autoreset_mode: str | AutoresetMode = AutoresetMode.NEXT_STEP, push=None, **kwargs) -> None:
        self.num_envs = check_int(num_envs, "num_envs", minimum=1)
        if max_episode_steps is not None:
            max_episode_steps = check_int(max_episode_steps, "max_episode_steps", minimum=1)
        self.max_episode_steps = max_episode_steps
        self.autoreset_mode = parse_autoreset_mode(autoreset_mode)
        self.push: PushDistribution | None = None if push is None else PushDistribution.parse(push, "push")
        """The random pushes of every episode (None: none)."""
        name = type(self).__name__
        unsupported = sorted(set(kwargs) & set(UNSUPPORTED_KWARGS))
        if unsupported:
            raise TypeError(f"{name} does not render; unsupported argument(s) {unsupported}")
        if "energy_consistent" in kwargs and kwargs["energy_consistent"] is not True:
            raise ValueError(f"{name} compiles only the energy-consistent scheme: energy_consistent must be True, "
                             f"got {kwargs['energy_consistent']!r}")
        try:
            self.envs: list[BoundingEnv] = [self.env_class(**kwargs) for _ in range(self.num_envs)]
            """The robots' single envs (unwrapped), stepped by this env only."""
        except TypeError as exc:
            if "unexpected keyword argument" in str(exc):
                raise TypeError(f"{name}: {exc}") from exc
            raise
        for env in self.envs:
            if not isinstance(env.sim, CompiledContactSimulator):  # pragma: no cover - energy_consistent is checked
                raise ValueError(f"{name} needs the compiled simulator, got {type(env.sim).__name__}")
        self.env_kwargs = dict(kwargs)
        first = self.envs[0]
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode,
                         "render_fps": first.metadata["render_fps"]}
        self.render_mode = None
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.dt = first.dt
        self._batch = SimulatorBatch(env.sim for env in self.envs)
        self._u = self._batch.arrays["_ub"]
        n = self.num_envs
        self._obs = np.zeros((n,) + self.single_observation_space.shape, dtype=self.single_observation_space.dtype)
        self._reward = np.zeros(n)
        self._terminated = np.zeros(n, dtype=np.bool_)
        self._truncated = np.zeros(n, dtype=np.bool_)
        self._elapsed = np.zeros(n, dtype=np.int64)
        self._autoreset = np.zeros(n, dtype=np.bool_)
        self._batched = np.zeros(n, dtype=np.bool_)
        self._all = np.ones(n, dtype=np.bool_)
        self._impulses: list = [None] * n
        self._push_rngs: list[np.random.Generator | None] = [None] * n
        self._needs_reset = True

    # ------------------------------------------------------------------ seeding
    @property
    def np_random_seed(self) -> tuple:
        """The seed of each robot's generator, as ``SyncVectorEnv.np_random_seed``."""
        return tuple(env.np_random_seed for env in self.envs)

    # ------------------------------------------------------------------ reset
    def _reset_one(self, i: int, seed, state, t0: float | None) -> tuple:
        """Robot ``i``'s reset (``state``: its start state or None; ``t0`` the clock or None), with the episode's
        random pushes drawn as [`RandomPush`][hsddp_gym.envs.perturbations.wrappers.RandomPush] draws them."""
        env = self.envs[i]
        options = {}
        if state is not None:
            options["state"] = state
        if t0 is not None:
            options["time"] = t0
        if self.push is not None:
            rng = episode_generator(seed, PUSH_SALT, self._push_rngs[i], lambda: env.np_random)
            self._push_rngs[i] = rng
            pushes = self.push.draw(rng)
            options["push"] = pushes[0] if self.push.count == 1 else pushes
        try:
            obs, info = env.reset(seed=seed, options=options or None)
        except ValueError as exc:
            raise ValueError(f"robot {i}: {exc}") from exc
        self._obs[i] = obs
        self._reward[i] = 0.0
        self._terminated[i] = self._truncated[i] = self._autoreset[i] = False
        self._elapsed[i] = 0
        return info

    def reset(self, *, seed=None, options: dict | None = None):
        """Reset every robot (or those of ``options["reset_mask"]``); see the class docstring.

        Returns:
            ``(observations (num_envs, obs_dim), info)`` (batched info, every key with its mask).
        """
        seeds = robot_seeds(seed, self.num_envs)
        mask, states, times = parse_reset_options(options, self.num_envs, type(self).__name__)
        mask = self._all if mask is None else mask
        entries = [(int(i), self._reset_one(int(i), seeds[i], None if states is None else states[i],
                                            None if times is None else float(times[i])))
                   for i in np.flatnonzero(mask)]
        self._needs_reset = False
        return self._obs.copy(), batch_infos(self.num_envs, entries)

    # ------------------------------------------------------------------ step
    def step(self, actions):
        """Step every robot (in NEXT_STEP mode a robot whose episode ended is reset instead); see the class
        docstring.

        Returns:
            ``(observations, rewards (num_envs,) float64, terminated, truncated, info)``.
        """
        if self._needs_reset:
            raise RuntimeError(f"{type(self).__name__}.step() called before reset()")
        a = real_array(actions, "actions")
        if a.shape != (self.num_envs, NU):
            raise ValueError(f"actions must have shape ({self.num_envs}, {NU}), got {a.shape}")
        next_step = self.autoreset_mode == AutoresetMode.NEXT_STEP
        envs, batched, impulses = self.envs, self._batched, self._impulses
        resetting = self._autoreset.copy() if next_step else np.zeros(self.num_envs, dtype=np.bool_)
        finite = np.isfinite(a).all(axis=1) | resetting  # a resetting robot's action is ignored, as SyncVectorEnv does
        if not finite.all():  # checked before any robot moves
            bad = np.flatnonzero(~finite).tolist()
            raise ValueError(f"actions must be finite: the rows of robots {bad} are not ({a[bad].tolist()})")
        batched[:] = False
        for i, env in enumerate(envs):  # the steps' first parts; the robots without a push due run batched
            if resetting[i]:
                continue
            env._begin_step(a[i])
            if env._due_pushes:
                impulses[i] = env._simulate_step()
            else:
                self._u[i] = env._u
                batched[i] = True
        if batched.any():
            self._batch.run(batched, envs[0].frame_skip)
        entries: list = []
        for i, env in enumerate(envs):
            if resetting[i]:
                env_info = self._reset_one(i, None, None, None)
            else:
                obs, reward, terminated, _, env_info = env._end_step(env.sim.impulse if batched[i] else impulses[i])
                impulses[i] = None
                self._elapsed[i] += 1
                truncated = self.max_episode_steps is not None and self._elapsed[i] >= self.max_episode_steps
                self._obs[i], self._reward[i] = obs, reward
                self._terminated[i], self._truncated[i] = terminated, truncated
                if not next_step and (terminated or truncated):
                    entries.append((i, {"final_obs": obs, "final_info": env_info}))
                    reward_i, term_i, trunc_i = self._reward[i], terminated, truncated
                    env_info = self._reset_one(i, None, None, None)
                    self._reward[i], self._terminated[i], self._truncated[i] = reward_i, term_i, trunc_i
            entries.append((i, env_info))
        self._autoreset[:] = self._terminated | self._truncated
        return (self._obs.copy(), self._reward.copy(), self._terminated.copy(), self._truncated.copy(),
                batch_infos(self.num_envs, entries))

    def close_extras(self, **kwargs) -> None:
        """Close the robots' single envs."""
        for env in self.envs:
            env.close()


class BackflipVectorEnv(TaskVectorEnv):
    """[`TaskVectorEnv`][TaskVectorEnv] of [`BackflipEnv`][hsddp_gym.envs.backflip.BackflipEnv]
    (``hsddp_gym/Backflip-v0``)."""

    env_class = BackflipEnv


class JumpVectorEnv(TaskVectorEnv):
    """[`TaskVectorEnv`][TaskVectorEnv] of [`JumpEnv`][hsddp_gym.envs.jumps.JumpEnv] (``hsddp_gym/GapJump-v0``,
    ``hsddp_gym/BoxJump-v0``)."""

    env_class = JumpEnv


class TransitionVectorEnv(TaskVectorEnv):
    """[`TaskVectorEnv`][TaskVectorEnv] of [`TransitionEnv`][hsddp_gym.envs.transitions.TransitionEnv]
    (``hsddp_gym/StandToBound-v0``, ``hsddp_gym/BoundPronkBound-v0``, ``hsddp_gym/BoundToStop-v0``)."""

    env_class = TransitionEnv


class PronkingVectorEnv(TaskVectorEnv):
    """[`TaskVectorEnv`][TaskVectorEnv] of [`PronkingEnv`][hsddp_gym.envs.pronking.PronkingEnv]
    (``hsddp_gym/Pronking-v0``)."""

    env_class = PronkingEnv
