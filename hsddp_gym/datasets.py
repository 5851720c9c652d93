"""Demonstration datasets of ``hsddp_gym/Bounding-v0``: parallel, seeded generation; Minari + npz output.

Generation
----------
:func:`generate_dataset` runs ``episodes`` episodes of a policy, episode ``i`` reset with seed ``seed + i``
and played by a *fresh* policy built for it (:class:`PolicySpec`, or any picklable factory
``factory(env, episode_seed) -> (policy, reset_options)``), so an episode depends only on its seed: the same
``seed`` and ``episodes`` give identical arrays whatever the number of worker processes. Workers are
``spawn``-started processes (:class:`concurrent.futures.ProcessPoolExecutor`; ``workers=1`` runs in this
process); a tqdm bar counts finished episodes.

Built-in policies (:data:`POLICIES`): ``mpc`` (:class:`planners.mpc.MPCPolicy`, options = ``MPCOptions``
fields), ``expert`` (:class:`planners.policies.PlanTrackingExpert` tracking the HS-DDP plan
``planners.tasks.plan_bounding("al-reb", cycles=5).solution``, solved once and stored as ``expert_plan.npz``
in the dataset; every episode is reset with ``options={"state": plan.X[0]}``, i.e. *without* reset noise,
so all expert episodes are identical -- the seed is recorded but has no effect; after the plan's 1.48 s the
default MPC takes over), ``heuristic``
(:class:`planners.policies.HeuristicPolicy`) and ``random`` (:class:`planners.policies.RandomPolicy`
seeded with the episode seed).

DART noise injection (``action_noise > 0``, Laskey et al. 2017): the executed actions are the policy's plus
Gaussian noise (seeded by the episode seed), so the episodes visit the states around the policy's
trajectory from which it recovers; the policy's clean actions are stored in ``infos["expert_action"]``
and are the labels :func:`planners.imitation.load_demonstrations` uses.

Output (``out`` is one directory, created atomically)
----------------------------------------------------
::

    out/minari/<dataset_id>/data/{main_data.hdf5, metadata.json}   a Minari dataset (MINARI_DATASETS_PATH=out/minari)
    out/episodes.npz       the same data as flat arrays (see :func:`load_npz`), no pickle
    out/metadata.json      the dataset metadata (also stored in Minari's metadata under "hsddp_gym")
    out/expert_plan.npz    the tracked plan (``expert`` only; :meth:`planners.solution.Solution.load`)

Load it with ``load_minari(out)`` (sets ``MINARI_DATASETS_PATH`` for the call) or
``MINARI_DATASETS_PATH=out/minari python -c "import minari; minari.load_dataset('<dataset_id>')"``, and
``load_npz(out)``. Everything is written into a hidden sibling ``.<name>.tmp-*`` directory that is renamed
onto ``out`` only when complete: an interrupted or failed run leaves no dataset, never a half-written
``out``. An existing ``out`` is replaced only with ``overwrite=True`` (the old directory is moved aside, the
new one renamed in, the old one deleted).

Resume or refuse: finished episodes are checkpointed into the hidden sibling ``.<name>.partial`` as they
arrive (with the run's settings; deleted once the dataset is published). A rerun with the same settings and
code resumes from them (same data as an uninterrupted run); with other settings it refuses with a message
naming the differences unless ``resume=False`` / ``overwrite=True`` (CLI ``--no-resume`` / ``--overwrite``)
discards them. A run holds a lock there, so two runs never write the same ``out``; temporary directories
of a killed run are removed by the next run.

Per-step data (Minari conventions)
----------------------------------
``observations (T+1, 17)`` float32 (reset observation first), ``actions (T, 4)`` float32 (normalized torques
in [-1, 1]), ``rewards (T,)``, ``terminations (T,)`` (falls), ``truncations (T,)`` (time limit only).

``infos`` has the same keys and shapes at every one of the T+1 rows. **Row t describes observation t**: the
env's info for it (the reset info for t = 0, the info returned by step t-1 after) and the policy's decision
taken at it (for t < T; the last row, where no action is taken, repeats the last decision's values with
``replanned = planner_failed = False``). Keys:

* from the env (:class:`envs.bounding.BoundingEnv`): ``qpos (7,)``, ``qvel (7,)``, ``contact (2,)`` bool
  ``[front, back]``, ``x_position``, ``x_velocity``, ``reward_forward``, ``reward_ctrl``, ``reward_healthy``,
  ``foot_heights (2,)``, ``grf (4,)``, ``time`` (whatever keys the env's reset info has; every step is
  checked against them);
* from the policy (:data:`DECISION_SCHEMA`): ``expert_state_nominal (14,)`` x-bar and
  ``expert_action_nominal (4,)`` u-bar / torque_limit (normalized, not clipped) of the plan knot whose
  feedback law ``u = u-bar + K (x - x-bar)`` produced the action, ``expert_tracking`` (True when it did;
  otherwise the nominal holds its last value, zeros before any), ``solver_iterations`` (DDP iterations),
  ``solver_converged``, ``max_violation`` (largest constraint violation of the plan: touchdown foot height
  [m], torque [N m], friction and negative normal force [N], each in its own unit) and ``solve_ms`` of the
  latest solve, ``replanned`` (a solve was attempted at this step), ``planner_failed`` (it failed; the old
  plan kept acting); with ``include_gains=True`` also ``expert_feedback_gain (4, 14)`` = K / torque_limit
  (column 0, the trunk x, is zero: the trackers do not feed it back). The MPC fills the solver fields from
  its re-plans; the expert from its single offline solve, then from its fallback MPC's re-plans; policies without a
  planner (heuristic, random, learned) with zeros.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import dataclasses
import functools
import json
import multiprocessing
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hsddp_gym.conventions import NU, NX
from hsddp_gym.io import json_default, read_npz, write_json, write_npz
from hsddp_gym.validation import check_positive

ENV_ID = "hsddp_gym/Bounding-v0"
POLICIES = ("mpc", "expert", "heuristic", "random")
EXPERT_PLAN = {"method": "al-reb", "cycles": 5}
"""The expert's plan: ``planners.tasks.plan_bounding("al-reb", cycles=5)`` (paper task 1, 1 m/s)."""
REF_MIN_EPISODES = 5
"""Episodes of the random policy (seeds ``seed .. seed + 4``) averaged into ``ref_min_score``."""
REF_MAX_EPISODES = 5
"""With DART noise, clean (noise-free) episodes of the policy (seeds ``seed .. seed + 4``, at most
``episodes``) averaged into ``ref_max_score``; without noise it is the mean return of the dataset's episodes."""
NOISE_STREAM = 7919
"""First entry of the seed sequence of the DART action noise (``[NOISE_STREAM, episode seed]``)."""
CHECKPOINT_FORMAT = 1
"""Version of the checkpoint layout of an interrupted run (``.<name>.partial``, see :func:`generate_dataset`)."""
NONDETERMINISTIC_INFOS = ("solve_ms",)
"""``infos`` keys that hold wall-clock times: the only data that differ between runs with the same seed."""

DECISION_SCHEMA: dict[str, tuple[tuple, str]] = {
    "expert_state_nominal": ((NX,), "float64"),
    "expert_action_nominal": ((NU,), "float64"),
    "expert_tracking": ((), "bool"),
    "solver_iterations": ((), "int64"),
    "solver_converged": ((), "bool"),
    "max_violation": ((), "float64"),
    "solve_ms": ((), "float64"),
    "replanned": ((), "bool"),
    "planner_failed": ((), "bool"),
}
"""Shape and dtype of the policy-decision keys of ``infos`` (see the module docstring)."""
GAIN_KEY = "expert_feedback_gain"


# ================================================================================================ policies
@dataclasses.dataclass(frozen=True)
class PolicySpec:
    """A picklable recipe for the policy of one episode (the default ``policy_factory``).

    Args:
        name: one of :data:`POLICIES`.
        options: ``MPCOptions`` fields for ``mpc`` (JSON-serializable values); unused otherwise.
        plan_path: the expert's plan (``.npz`` of :meth:`planners.solution.Solution.save`); ``expert`` only.
    """

    name: str
    options: dict = dataclasses.field(default_factory=dict)
    plan_path: str | None = None

    def __post_init__(self) -> None:
        if self.name not in POLICIES:
            raise ValueError(f"policy name must be one of {POLICIES}, got {self.name!r}")
        if self.name == "expert" and self.plan_path is None:
            raise ValueError("the expert policy needs plan_path (its plan, saved with Solution.save)")

    def __call__(self, env, episode_seed: int):
        """``(policy, reset_options)`` for an episode of ``env`` seeded ``episode_seed``."""
        from planners.policies import HeuristicPolicy, PlanTrackingExpert, RandomPolicy

        if self.name == "mpc":
            from planners.mpc import MPCOptions, MPCPolicy

            return MPCPolicy.from_env(env, options=MPCOptions(**_mpc_options(self.options))), None
        if self.name == "expert":
            sol = _load_plan(str(self.plan_path))
            return PlanTrackingExpert.from_env(env, solution=sol), {"state": sol.X[0].copy()}
        if self.name == "heuristic":
            return HeuristicPolicy.from_env(env), None
        return RandomPolicy.from_env(env, seed=int(episode_seed)), None

    def describe(self) -> dict:
        """JSON description (name and the full options in effect)."""
        d = {"name": self.name, "class": {"mpc": "planners.mpc.MPCPolicy", "expert": "planners.policies."
                                          "PlanTrackingExpert", "heuristic": "planners.policies.HeuristicPolicy",
                                          "random": "planners.policies.RandomPolicy"}[self.name]}
        if self.name == "mpc":
            from planners.mpc import MPCOptions

            d["options"] = dataclasses.asdict(MPCOptions(**_mpc_options(self.options)))
        elif self.name == "expert":
            d["options"] = {"plan": dict(EXPERT_PLAN), "plan_file": "expert_plan.npz",
                            "reset_options": "{'state': plan.X[0]} (no reset noise)",
                            "fallback_after_plan": "planners.mpc.MPCPolicy (default options)"}
        elif self.name == "random":
            d["options"] = {"seed": "episode seed"}
        else:
            d["options"] = {}
        return d


def _mpc_options(options: dict) -> dict:
    opts = dict(options)
    if opts.get("durations") is not None:
        opts["durations"] = tuple(opts["durations"])
    return opts


@functools.lru_cache(maxsize=4)
def _load_plan(path: str):
    from planners.solution import Solution

    return Solution.load(path)


def solve_expert_plan(path) -> dict:
    """Solve the expert's plan (:data:`EXPERT_PLAN`), save it to ``path`` and return its summary."""
    from planners.tasks import plan_bounding

    result = plan_bounding(EXPERT_PLAN["method"], cycles=EXPERT_PLAN["cycles"])
    result.solution.save(path)
    keep = ("status", "converged", "al_iterations", "ddp_iterations", "switching_violation", "cost",
            "avg_forward_speed", "solve_time_s")
    return {k: result.summary[k] for k in keep if k in result.summary}


# ================================================================================================ episodes
@dataclasses.dataclass
class Episode:
    """One recorded episode (Minari layout): ``observations (T+1, d)``, ``actions (T, 4)``, ``rewards (T,)``,
    ``terminations (T,)``, ``truncations (T,)``, ``infos`` {key: (T+1, ...)}."""

    index: int
    seed: int
    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    infos: dict
    wall_time: float = 0.0

    @property
    def length(self) -> int:
        return int(len(self.actions))

    @property
    def episode_return(self) -> float:
        return float(np.sum(self.rewards))


_CAPTURE: dict = {}


@contextlib.contextmanager
def capture_plan_controls():
    """While active, every :meth:`planners.tracking.PlanTracker.control` call records the knot it used in
    the returned dict (``"X"``, ``"U"``, ``"K"`` of that knot).

    The trackers of :class:`~planners.policies.PlanTrackingExpert` and :class:`~planners.mpc.MPCPolicy`
    advance their cursor right after computing the control, so the knot cannot be read afterwards; this
    wraps the method (class level, restored on exit) for the duration of one episode in this process.
    """
    from planners.tracking import PlanTracker

    original = PlanTracker.control
    slot: dict = {}

    def control(self, x):
        k = self.knot
        slot["X"], slot["U"], slot["K"] = self.X[k], self.U[k], self.K[k]
        return original(self, x)

    PlanTracker.control = control
    try:
        yield slot
    finally:
        PlanTracker.control = original


def _max_violation(sol) -> float:
    vals = [float(np.max(np.abs(sol.switching))) if np.size(sol.switching) else 0.0]
    if sol.log:
        rec = sol.log[-1]
        vals += [rec.max_torque_violation, rec.max_friction_violation, -rec.min_normal_grf]
    vals = [v for v in vals if np.isfinite(v)]
    return float(max([0.0, *vals]))


class DecisionRecorder:
    """Builds the policy-decision ``infos`` (:data:`DECISION_SCHEMA`) around ``policy(obs)`` calls."""

    def __init__(self, policy, torque_limit: float, include_gains: bool = False) -> None:
        self.policy = policy
        self.torque_limit = float(torque_limit)
        self.include_gains = include_gains
        self.last = {k: np.zeros(shape, dtype=dtype) for k, (shape, dtype) in DECISION_SCHEMA.items()}
        if include_gains:
            self.last[GAIN_KEY] = np.zeros((NU, NX))
        sol = getattr(policy, "solution", None)
        if sol is not None and hasattr(sol, "ddp_iterations"):  # a plan solved offline (the expert)
            self.last["solver_iterations"] = np.array(int(sol.ddp_iterations))
            self.last["solver_converged"] = np.array(bool(sol.converged))
            self.last["max_violation"] = np.array(_max_violation(sol))
            self.last["solve_ms"] = np.array(1e3 * float(sol.solve_time))

    def act(self, obs, slot: dict) -> tuple[np.ndarray, dict]:
        """``(action (4,) float32, decision info)`` for one observation."""
        stats = getattr(self.policy, "stats", None)
        planner = isinstance(stats, dict) and "solve_ms" in stats and "replans" in stats
        n_solves = len(stats["solve_ms"]) if planner else 0
        n_ok = stats["replans"] if planner else 0
        slot.clear()
        action = np.asarray(self.policy(obs), dtype=np.float32)
        d = {k: v.copy() for k, v in self.last.items()}
        d["replanned"] = np.array(False)
        d["planner_failed"] = np.array(False)
        d["expert_tracking"] = np.array("U" in slot)
        if "U" in slot:
            d["expert_state_nominal"] = np.array(slot["X"], dtype=np.float64)
            d["expert_action_nominal"] = np.array(slot["U"], dtype=np.float64) / self.torque_limit
            if self.include_gains:
                K = np.array(slot["K"], dtype=np.float64) / self.torque_limit
                K[:, 0] = 0.0
                d[GAIN_KEY] = K
        if planner and len(stats["solve_ms"]) > n_solves:
            d["replanned"] = np.array(True)
            d["solve_ms"] = np.array(float(stats["solve_ms"][-1]))
            if stats["replans"] > n_ok:
                sol = self.policy.last_solution
                d["solver_iterations"] = np.array(int(stats["iterations"][-1]))
                d["solver_converged"] = np.array(bool(getattr(sol, "converged", False)))
                d["max_violation"] = np.array(_max_violation(sol) if sol is not None else 0.0)
            else:
                d["planner_failed"] = np.array(True)
                d["solver_iterations"] = np.array(0)
                d["solver_converged"] = np.array(False)
        self.last = d
        return action, d

    def final(self) -> dict:
        """The last row's decision values (no action at the final observation)."""
        d = {k: v.copy() for k, v in self.last.items()}
        d["replanned"] = np.array(False)
        d["planner_failed"] = np.array(False)
        return d


def _info_schema(info: dict) -> dict:
    return {k: (np.asarray(v).shape, np.asarray(v).dtype) for k, v in info.items()}


def _check_info(info: dict, schema: dict, step: int) -> None:
    if set(info) != set(schema):
        raise ValueError(f"env info keys changed at step {step}: expected {sorted(schema)}, got {sorted(info)}")
    for k, (shape, _) in schema.items():
        if np.asarray(info[k]).shape != shape:
            raise ValueError(f"env info[{k!r}] changed shape at step {step}: {shape} -> {np.asarray(info[k]).shape}")


def record_episode(env, policy, seed: int, options: dict | None = None, index: int = 0,
                   include_gains: bool = False, action_noise: float = 0.0) -> Episode:
    """Play one episode of ``env`` with ``policy`` from ``env.reset(seed=seed, options=options)``.

    ``policy`` is any callable ``obs -> action`` with an optional ``reset()``; planner statistics and the
    tracked plan knot are recorded when it has them (see the module docstring).

    ``action_noise > 0`` (DART noise injection): the executed (and recorded) action is
    ``clip(a + action_noise * N(0, I), -1, 1)`` with ``a`` the policy's action, the noise drawn from
    ``np.random.default_rng([NOISE_STREAM, seed])``; ``a`` itself is stored in ``infos["expert_action"]``
    (row t: the clean action at observation t; the last row repeats the last one) -- the label for imitation.
    """
    action_noise = check_positive(action_noise, "action_noise", allow_zero=True)
    noise_rng = np.random.default_rng([NOISE_STREAM, int(seed)]) if action_noise > 0 else None
    t0 = time.perf_counter()
    obs, info = env.reset(seed=int(seed), options=options)
    if hasattr(policy, "reset"):
        policy.reset()
    schema = _info_schema(info)
    torque_limit = float(getattr(env.unwrapped, "torque_limit", 1.0))
    rec = DecisionRecorder(policy, torque_limit, include_gains)
    observations, actions, rewards, terms, truncs, rows = [obs], [], [], [], [], []
    with capture_plan_controls() as slot:
        while True:
            action, decision = rec.act(obs, slot)
            if noise_rng is not None:
                decision = {**decision, "expert_action": action.copy()}
                action = np.clip(action + action_noise * noise_rng.standard_normal(action.shape), -1.0,
                                 1.0).astype(np.float32)
            rows.append({**info, **decision})
            obs, reward, terminated, truncated, info = env.step(action)
            _check_info(info, schema, len(actions))
            observations.append(obs)
            actions.append(action)
            rewards.append(float(reward))
            terms.append(bool(terminated))
            truncs.append(bool(truncated))
            if terminated or truncated:
                break
    final = rec.final()
    if noise_rng is not None:
        final["expert_action"] = rows[-1]["expert_action"].copy()
    rows.append({**info, **final})
    infos = {k: np.stack([np.asarray(r[k]) for r in rows]) for k in rows[0]}
    if noise_rng is not None:
        infos["expert_action"] = infos["expert_action"].astype(np.float32)
    for k, (shape, dtype) in DECISION_SCHEMA.items():
        infos[k] = infos[k].astype(dtype, copy=False).reshape(len(rows), *shape)
    return Episode(index=int(index), seed=int(seed), observations=np.asarray(observations, dtype=np.float32),
                   actions=np.asarray(actions, dtype=np.float32), rewards=np.asarray(rewards, dtype=np.float64),
                   terminations=np.asarray(terms, dtype=bool), truncations=np.asarray(truncs, dtype=bool),
                   infos=infos, wall_time=time.perf_counter() - t0)


@dataclasses.dataclass(frozen=True)
class EpisodeTask:
    """Everything a worker needs for one episode (picklable)."""

    index: int
    seed: int
    policy_factory: Callable
    env_kwargs: dict
    max_episode_steps: int | None
    include_gains: bool = False
    action_noise: float = 0.0


def make_env(env_kwargs: dict | None = None, max_episode_steps: int | None = None):
    """``gym.make("hsddp_gym/Bounding-v0", **env_kwargs)`` with an optional time-limit override."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the env)

    kw = dict(env_kwargs or {})
    if max_episode_steps is not None:
        kw["max_episode_steps"] = int(max_episode_steps)
    return gym.make(ENV_ID, **kw)


def run_episode_task(task: EpisodeTask) -> Episode:
    """Worker entry point (top level, spawn-safe): a fresh env and policy, one recorded episode."""
    env = make_env(task.env_kwargs, task.max_episode_steps)
    try:
        policy, options = task.policy_factory(env, task.seed)
        return record_episode(env, policy, task.seed, options, index=task.index, include_gains=task.include_gains,
                              action_noise=task.action_noise)
    finally:
        env.close()


THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")


@contextlib.contextmanager
def _child_threads(threads: int):
    """Set the BLAS/OpenMP/numba thread counts in ``os.environ`` while worker processes are started.

    A spawned worker imports NumPy (hence OpenBLAS) while it unpickles its first task -- before any pool
    initializer runs -- so the limit must already be in the environment it inherits. Values the user set are
    kept; the parent's own (already loaded) libraries are unaffected.
    """
    old = {v: os.environ.get(v) for v in THREAD_VARS}
    for v in THREAD_VARS:
        os.environ.setdefault(v, str(int(threads)))
    try:
        yield
    finally:
        for v, value in old.items():
            if value is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = value


def checkpoint_path(directory, index: int, prefix: str = "episode") -> Path:
    """``directory/<prefix>-<index:06d>.npz``: the checkpoint of one finished episode."""
    return Path(directory) / f"{prefix}-{int(index):06d}.npz"


def save_episode(path, episode: Episode) -> Path:
    """Write one :class:`Episode` to ``.npz`` atomically (uncompressed, no pickle)."""
    from hsddp_gym.io import atomic_path

    arrays = {"index": np.array(episode.index), "seed": np.array(episode.seed),
              "wall_time": np.array(episode.wall_time), "observations": episode.observations,
              "actions": episode.actions, "rewards": episode.rewards, "terminations": episode.terminations,
              "truncations": episode.truncations, **{f"infos/{k}": v for k, v in episode.infos.items()}}
    with atomic_path(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)
    return Path(path)


def load_episode(path) -> Episode:
    """Read an :class:`Episode` written by :func:`save_episode` (never unpickles)."""
    d = read_npz(path)
    return Episode(index=int(d["index"]), seed=int(d["seed"]), observations=d["observations"],
                   actions=d["actions"], rewards=d["rewards"], terminations=d["terminations"],
                   truncations=d["truncations"],
                   infos={k[len("infos/"):]: v for k, v in d.items() if k.startswith("infos/")},
                   wall_time=float(d["wall_time"]))


def collect_episodes(policy_factory: Callable, episodes: int, seed: int = 0, workers: int = 1,
                     env_kwargs: dict | None = None, max_episode_steps: int | None = None,
                     include_gains: bool = False, progress: bool = True, desc: str = "episodes",
                     action_noise: float = 0.0, checkpoint_dir=None, checkpoint_prefix: str = "episode"
                     ) -> list[Episode]:
    """Record ``episodes`` episodes (episode ``i`` seeded ``seed + i``) with ``workers`` processes.

    Args:
        policy_factory: picklable ``(env, episode_seed) -> (policy, reset_options or None)`` (e.g. a
            :class:`PolicySpec`); called once per episode, in the worker.
        workers: 1 runs in this process; more use ``spawn``-started worker processes (one BLAS/OpenMP
            thread each).
        action_noise: DART noise on the executed actions (see :func:`record_episode`).
        checkpoint_dir: if given, every finished episode is saved there (:func:`checkpoint_path`, written
            atomically as it arrives) and episodes already saved there are loaded instead of being run again
            (the caller makes sure they were recorded with the same settings; :func:`generate_dataset` does).
        checkpoint_prefix: file-name prefix of the checkpoints.
    Returns:
        The episodes in index order (identical for any ``workers``, and whether loaded or recorded).
    """
    episodes, workers = int(episodes), int(workers)
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    from tqdm import tqdm

    tasks = [EpisodeTask(i, int(seed) + i, policy_factory, dict(env_kwargs or {}), max_episode_steps, include_gains,
                         float(action_noise)) for i in range(episodes)]
    results: list[Episode | None] = [None] * episodes
    if checkpoint_dir is not None:
        Path(checkpoint_dir).mkdir(parents=True, exist_ok=True)
        for t in tasks:
            path = checkpoint_path(checkpoint_dir, t.index, checkpoint_prefix)
            if path.exists():
                ep = load_episode(path)
                if ep.seed != t.seed or ep.index != t.index:
                    raise ValueError(f"checkpoint {path} holds episode {ep.index} (seed {ep.seed}), expected "
                                     f"episode {t.index} (seed {t.seed})")
                results[t.index] = ep
    todo = [t for t in tasks if results[t.index] is None]
    steps = sum(ep.length for ep in results if ep is not None)
    bar = tqdm(total=episodes, initial=episodes - len(todo), desc=desc, unit="ep", disable=not progress)

    def done(ep: Episode) -> None:
        nonlocal steps
        if checkpoint_dir is not None:
            save_episode(checkpoint_path(checkpoint_dir, ep.index, checkpoint_prefix), ep)
        results[ep.index] = ep
        steps += ep.length
        bar.update(1)
        bar.set_postfix(steps=steps)

    try:
        if workers == 1:
            for t in todo:
                done(run_episode_task(t))
        elif todo:
            ctx = multiprocessing.get_context("spawn")
            pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(todo)), mp_context=ctx)
            try:
                with _child_threads(1):  # the workers are started by the submits
                    futures = [pool.submit(run_episode_task, t) for t in todo]
                for fut in cf.as_completed(futures):
                    done(fut.result())
            except BaseException:
                pool.shutdown(wait=False, cancel_futures=True)
                raise
            pool.shutdown(wait=True)
    finally:
        bar.close()
    return results  # type: ignore[return-value]


# ================================================================================================ writing
@contextlib.contextmanager
def minari_root(path):
    """Set ``MINARI_DATASETS_PATH`` to ``path`` for the duration of the block (restored after)."""
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(path)
    try:
        yield Path(path)
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old


def default_dataset_id(policy_name: str) -> str:
    """``hsddp_gym/bounding/<policy>-v0``."""
    return f"hsddp_gym/bounding/{policy_name}-v0"


def episodes_to_arrays(episodes: list[Episode]) -> dict:
    """Flat arrays of ``episodes`` (the ``episodes.npz`` layout, see :func:`load_npz`)."""
    lengths = np.array([e.length for e in episodes], dtype=np.int64)
    arrays = {
        "observations": np.concatenate([e.observations for e in episodes]),
        "actions": np.concatenate([e.actions for e in episodes]),
        "rewards": np.concatenate([e.rewards for e in episodes]),
        "terminations": np.concatenate([e.terminations for e in episodes]),
        "truncations": np.concatenate([e.truncations for e in episodes]),
        "episode_starts": np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
        "observation_starts": np.concatenate([[0], np.cumsum(lengths + 1)]).astype(np.int64),
        "episode_lengths": lengths,
        "episode_seeds": np.array([e.seed for e in episodes], dtype=np.int64),
        "episode_returns": np.array([e.episode_return for e in episodes]),
    }
    for k in episodes[0].infos:
        arrays[f"infos/{k}"] = np.concatenate([e.infos[k] for e in episodes])
    return arrays


def write_dataset(episodes: list[Episode], out, dataset_id: str, env, metadata: dict, *,
                  ref_min_score: float, ref_max_score: float, overwrite: bool = False,
                  extra_files: dict | None = None, description: str | None = None,
                  algorithm_name: str = "hsddp_gym") -> Path:
    """Write ``episodes`` as a Minari dataset + ``episodes.npz`` + ``metadata.json`` into ``out`` atomically.

    Args:
        env: the ``gym.make``'d env the episodes were recorded in (its spec, with the kwargs and time
            limit, is stored so that ``recover_environment()`` rebuilds it).
        metadata: JSON-serializable; stored in ``metadata.json``, in the npz and in Minari's metadata.
        extra_files: ``{name: existing path}`` copied into the dataset directory.
    Raises:
        FileExistsError: ``out`` exists and ``overwrite`` is False.
    """
    out = Path(out)
    _check_target(out, overwrite)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=_parent(out)))
    try:
        _write_into(tmp, episodes, dataset_id, env, metadata, ref_min_score, ref_max_score, extra_files,
                    description, algorithm_name)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp creates 0700; the published dataset gets the usual permissions
        _publish(tmp, out, overwrite)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def _parent(out: Path) -> Path:
    parent = out.resolve().parent
    parent.mkdir(parents=True, exist_ok=True)
    return parent


def _check_target(out: Path, overwrite: bool) -> None:
    if out.exists() and not overwrite:
        raise FileExistsError(f"{out} already exists; pass overwrite=True (CLI: --overwrite) to replace it")
    if out.exists() and not out.is_dir():
        raise FileExistsError(f"{out} exists and is not a directory")


def _publish(tmp: Path, out: Path, overwrite: bool) -> None:
    if out.exists():
        if not overwrite:
            raise FileExistsError(f"{out} already exists; pass overwrite=True (CLI: --overwrite) to replace it")
        trash = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.resolve().parent))
        os.rename(out, trash / "old")
        try:
            os.rename(tmp, out)
        except BaseException:
            os.rename(trash / "old", out)
            raise
        finally:
            shutil.rmtree(trash, ignore_errors=True)
    else:
        os.rename(tmp, out)


def _write_into(tmp: Path, episodes, dataset_id, env, metadata, ref_min_score, ref_max_score, extra_files,
                description, algorithm_name) -> None:
    import warnings

    import minari
    from minari.data_collector import EpisodeBuffer

    for name, src in (extra_files or {}).items():
        shutil.copy2(str(src), tmp / name)  # copied: the source stays valid if this write fails
    buffers = [EpisodeBuffer(id=i, seed=e.seed, observations=e.observations, actions=e.actions,
                             rewards=e.rewards, terminations=e.terminations, truncations=e.truncations,
                             infos={k: v for k, v in e.infos.items()}) for i, e in enumerate(episodes)]
    with minari_root(tmp / "minari"), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*(author|author_email|code_permalink|eval_env).*")
        ds = minari.create_dataset_from_buffers(
            dataset_id, buffers, env=env, algorithm_name=algorithm_name, author="hsddp_gym",
            author_email="n/a", code_permalink="https://github.com/ (hsddp_gym, see metadata)",
            ref_min_score=float(ref_min_score), ref_max_score=float(ref_max_score),
            description=description or f"{metadata.get('policy', {}).get('name', '?')} demonstrations on {ENV_ID}",
            requirements=None)
        ds.storage.update_metadata({"hsddp_gym": json.loads(json.dumps(metadata, default=json_default))})
    arrays = episodes_to_arrays(episodes)
    arrays["metadata"] = np.array(json.dumps(metadata, default=json_default))
    write_npz(tmp / "episodes.npz", **arrays)
    write_json(tmp / "metadata.json", metadata)


def mean_random_return(env_kwargs: dict | None = None, max_episode_steps: int | None = None, seed: int = 0,
                       episodes: int = REF_MIN_EPISODES) -> tuple[float, list[float]]:
    """Mean return of :class:`~planners.policies.RandomPolicy` over ``episodes`` episodes seeded
    ``seed, seed + 1, ...`` (the ``ref_min_score``) and the returns."""
    eps = collect_episodes(PolicySpec("random"), episodes, seed, 1, env_kwargs, max_episode_steps, progress=False)
    returns = [e.episode_return for e in eps]
    return float(np.mean(returns)), returns


@dataclasses.dataclass
class DatasetResult:
    """What :func:`generate_dataset` wrote (``resumed_episodes``: episodes loaded from the checkpoints of an
    interrupted run instead of being recorded again)."""

    path: Path
    dataset_id: str
    episodes: int
    total_steps: int
    generation_time_s: float
    metadata: dict
    resumed_episodes: int = 0


# ================================================================================================ resume
def partial_dir(out) -> Path:
    """``<parent>/.<name>.partial``: where a run writing dataset ``out`` keeps its checkpoints."""
    out = Path(out)
    return out.resolve().parent / f".{out.name}.partial"


def _code_fingerprint() -> str:
    """SHA-256 of the source of the packages that produce the data (``hsddp_gym``, ``planners``, ``envs``):
    checkpoints recorded by other code are never resumed."""
    import hashlib
    import importlib.util

    h = hashlib.sha256()
    for pkg in ("hsddp_gym", "planners", "envs"):
        spec = importlib.util.find_spec(pkg)
        if spec is None or not spec.submodule_search_locations:
            continue
        root = Path(list(spec.submodule_search_locations)[0])
        for f in sorted(root.rglob("*.py")):
            h.update(f"{pkg}/{f.relative_to(root).as_posix()}\0".encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def _factory_id(factory) -> str:
    """A stable name of a policy factory (module-qualified class or function, plus dataclass fields)."""
    if dataclasses.is_dataclass(factory) and not isinstance(factory, type):
        fields = {f.name: getattr(factory, f.name) for f in dataclasses.fields(factory) if f.name != "plan_path"}
        return f"{type(factory).__module__}.{type(factory).__qualname__}{json.dumps(fields, default=str)}"
    target = factory if callable(factory) and hasattr(factory, "__qualname__") else type(factory)
    return f"{getattr(target, '__module__', '?')}.{getattr(target, '__qualname__', repr(target))}"


@contextlib.contextmanager
def _exclusive(partial: Path):
    """Create ``partial`` and hold an exclusive lock on ``partial/lock`` (released when the process ends,
    even when killed); refuse if another live run holds it. Then stale temporary siblings of the dataset
    (``.<name>.tmp-*`` / ``.old-*`` / ``.plan-*`` of a killed run) are removed."""
    partial.mkdir(parents=True, exist_ok=True)
    fh = open(partial / "lock", "a+")
    try:
        try:
            import fcntl
        except ImportError:  # pragma: no cover (not POSIX: no lock)
            fcntl = None
        if fcntl is not None:
            try:
                fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                raise FileExistsError(f"another run is generating this dataset (it holds {partial / 'lock'}); "
                                      "wait for it to finish") from None
        import re

        name = partial.name[1:-len(".partial")]
        pattern = re.compile(rf"\.{re.escape(name)}\.(tmp|old|plan)-[A-Za-z0-9_]{{8}}")
        for stale in partial.parent.iterdir():
            if stale.is_dir() and pattern.fullmatch(stale.name):
                shutil.rmtree(stale, ignore_errors=True)
        yield partial
    finally:
        fh.close()


def _has_checkpoints(partial: Path) -> bool:
    """Whether ``partial`` holds finished work (episodes, reference episodes, the expert's plan); hidden files
    are the temporaries of an interrupted atomic write."""
    return any(p.suffix == ".npz" and not p.name.startswith(".") for p in partial.iterdir())


def _prepare_checkpoints(partial: Path, settings: dict, resume: bool, overwrite: bool) -> int:
    """Check the checkpoints in ``partial`` against ``settings``; returns the number of episode checkpoints kept.

    Same settings (and code): resumed (``resume=True``). Otherwise they are discarded with ``resume=False``
    or ``overwrite=True`` and refused (:class:`FileExistsError` naming the differences) without.
    """
    settings_file = partial / "settings.json"
    found = sorted(partial.glob("episode-*.npz"))
    current = json.loads(json.dumps(settings, default=json_default))
    stored = None
    if not _has_checkpoints(partial):
        stored = current  # nothing recorded yet (a fresh directory, or a run killed before its first episode)
    elif settings_file.exists():
        with contextlib.suppress(ValueError):
            stored = json.loads(settings_file.read_text())
    if stored == current and resume:
        write_json(settings_file, current)
        return len(found)
    if stored != current and not (overwrite or not resume):
        diff = sorted(k for k in set(stored or {}) | set(current) if (stored or {}).get(k) != current.get(k))
        what = [f"{k} (the source of hsddp_gym/planners/envs changed since)" if k == "code_sha256" else k
                for k in diff]
        raise FileExistsError(
            f"an interrupted run left {len(found)} episode checkpoint(s) in {partial} recorded with other "
            f"settings (differing: {', '.join(what) or 'unreadable settings'}); rerun with the same settings to "
            "resume it, or pass resume=False / overwrite=True (CLI: --no-resume / --overwrite) to discard them")
    for f in partial.iterdir():
        if f.name != "lock":
            shutil.rmtree(f) if f.is_dir() else f.unlink()
    write_json(settings_file, current)
    return 0


def generate_dataset(policy: str | PolicySpec | Callable, episodes: int, out, seed: int = 0, workers: int = 1,
                     dataset_id: str | None = None, overwrite: bool = False, env_kwargs: dict | None = None,
                     max_episode_steps: int | None = None, policy_options: dict | None = None,
                     include_gains: bool = False, progress: bool = True, policy_name: str | None = None,
                     policy_description: dict | None = None, action_noise: float = 0.0,
                     resume: bool = True) -> DatasetResult:
    """Generate a demonstration dataset into ``out`` (see the module docstring).

    **Interrupted runs and reruns.** Every finished episode is checkpointed (atomically) into the hidden
    sibling directory ``.<name>.partial`` (:func:`partial_dir`, with the run's settings and, for ``expert``,
    its plan) and the dataset itself is written into a temporary directory renamed onto ``out`` only when
    complete, so an interrupted run (an exception, Ctrl-C, a kill) never leaves a half-written ``out``. A
    rerun with the same settings (policy and options, seed, env kwargs, time limit, gains, noise, dataset
    id, and the same source code; ``episodes`` and ``workers`` may differ) **resumes**: checkpointed
    episodes are loaded, the others recorded, the data identical to an uninterrupted run. A rerun with other
    settings **refuses** (:class:`FileExistsError` naming the differing settings) unless ``resume=False`` or
    ``overwrite=True`` discards the checkpoints. An existing ``out`` is never replaced without
    ``overwrite=True``. The checkpoints are deleted once the dataset is published; one run at a time may
    write a given ``out`` (a lock in the checkpoint directory, released when the process dies).

    Args:
        policy: a name of :data:`POLICIES`, a :class:`PolicySpec`, or a picklable factory
            ``(env, episode_seed) -> (policy, reset_options)`` (then give ``policy_name``).
        episodes: number of episodes; episode ``i`` is seeded ``seed + i``.
        workers: worker processes (the data do not depend on it).
        dataset_id: Minari id (default ``hsddp_gym/bounding/<policy>-v0``).
        overwrite: replace an existing ``out`` (and discard checkpoints recorded with other settings).
        env_kwargs: ``gym.make`` keyword arguments; max_episode_steps: time-limit override (default 1000).
        policy_options: ``MPCOptions`` fields for ``mpc``.
        include_gains: also store the plan's feedback gains (``expert_feedback_gain (4, 14)`` per step).
        action_noise: DART noise injection (:func:`record_episode`): the executed actions (``actions``) are
            the policy's plus Gaussian noise of this standard deviation (normalized units), the policy's clean
            actions are in ``infos["expert_action"]`` (what :func:`planners.imitation.load_demonstrations`
            uses as labels). Recorded in the metadata; ``ref_max_score`` then comes from
            :data:`REF_MAX_EPISODES` clean episodes of the policy (the expert's score, not the noisy one's).
        resume: resume from the checkpoints of an interrupted run with the same settings (False: discard
            any checkpoints and start over).
    Raises:
        FileExistsError: ``out`` exists and ``overwrite`` is False; checkpoints with other settings exist
            and neither ``resume=False`` nor ``overwrite``; another run is writing ``out``.
    """
    action_noise = check_positive(action_noise, "action_noise", allow_zero=True)
    if int(episodes) < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    if int(workers) < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    out = Path(out)
    _check_target(out, overwrite)
    env_kwargs = dict(env_kwargs or {})
    partial = partial_dir(out)
    plan_file = partial / "expert_plan.npz"
    if isinstance(policy, str):
        if policy == "expert":
            spec = PolicySpec("expert", plan_path=str(plan_file))
        else:
            spec = PolicySpec(policy, options=dict(policy_options or {}))
    else:
        spec = policy
    name = policy_name or (spec.name if isinstance(spec, PolicySpec) else type(spec).__name__)
    describe = policy_description or (spec.describe() if isinstance(spec, PolicySpec) else {"name": name})
    dataset_id = dataset_id or default_dataset_id(name)
    settings = {"checkpoint_format": CHECKPOINT_FORMAT, "dataset_id": dataset_id, "policy": describe,
                "policy_factory": _factory_id(spec), "seed": int(seed), "env_kwargs": env_kwargs,
                "max_episode_steps": max_episode_steps, "include_gains": bool(include_gains),
                "action_noise": action_noise, "code_sha256": _code_fingerprint()}
    _parent(out)
    with _exclusive(partial):
        _check_target(out, overwrite)  # again, under the lock
        _prepare_checkpoints(partial, settings, resume, overwrite)
        resumed = sum(checkpoint_path(partial, i).exists() for i in range(int(episodes)))
        if resumed and progress:
            print(f"resuming an interrupted run: {resumed} episode(s) checkpointed in {partial}", flush=True)
        try:
            eps, metadata, extra, gen_time = _generate(spec, name, describe, episodes, seed, workers, env_kwargs,
                                                       max_episode_steps, include_gains, progress, action_noise,
                                                       dataset_id, partial, plan_file, resumed)
            env = make_env(env_kwargs, max_episode_steps)
            try:
                write_dataset(eps, out, dataset_id, env, metadata, ref_min_score=metadata["ref_min_score"],
                              ref_max_score=metadata["ref_max_score"], overwrite=overwrite, extra_files=extra,
                              description=f"{name} demonstrations on {ENV_ID} ({len(eps)} episodes, seeds "
                                          f"{seed}..{seed + len(eps) - 1}); see the 'hsddp_gym' metadata entry")
            finally:
                env.close()
        except BaseException:
            if not _has_checkpoints(partial):  # nothing worth resuming
                shutil.rmtree(partial, ignore_errors=True)
            raise
        shutil.rmtree(partial, ignore_errors=True)
    return DatasetResult(out, dataset_id, len(eps), metadata["total_steps"], gen_time, metadata, resumed)


def _generate(spec, name, describe, episodes, seed, workers, env_kwargs, max_episode_steps, include_gains,
              progress, action_noise, dataset_id, partial, plan_file, resumed):
    """The episodes (checkpointed into ``partial``) and the metadata of :func:`generate_dataset`."""
    t0 = time.perf_counter()
    extra, plan_summary = {}, None
    if isinstance(spec, PolicySpec) and spec.name == "expert" and Path(spec.plan_path) == plan_file:
        summary_file = partial / "expert_plan.json"
        if plan_file.exists() and summary_file.exists():  # resumed: the plan the checkpoints were recorded with
            plan_summary = json.loads(summary_file.read_text())
        else:
            plan_summary = solve_expert_plan(plan_file)
            write_json(summary_file, plan_summary)
        extra["expert_plan.npz"] = plan_file
    plan_time = time.perf_counter() - t0
    t1 = time.perf_counter()
    eps = collect_episodes(spec, episodes, seed, workers, env_kwargs, max_episode_steps, include_gains,
                           progress, desc=f"{name} episodes", action_noise=action_noise, checkpoint_dir=partial)
    gen_time = time.perf_counter() - t1
    ref_min, random_returns = mean_random_return(env_kwargs, max_episode_steps, seed)
    returns = [e.episode_return for e in eps]
    if action_noise > 0:
        n_ref = min(int(episodes), REF_MAX_EPISODES)
        ref_eps = collect_episodes(spec, n_ref, seed, workers, env_kwargs, max_episode_steps, progress=progress,
                                   desc=f"{name} reference episodes (no noise)", checkpoint_dir=partial,
                                   checkpoint_prefix="reference")
        ref_returns = [e.episode_return for e in ref_eps]
        ref_source = (f"mean return of the {name} policy without action noise over {n_ref} episodes, seeds "
                      f"{seed}..{seed + n_ref - 1} (not in the dataset)")
    else:
        ref_returns = returns
        ref_source = f"mean return of the {name} episodes of this dataset"
    ref_max = float(np.mean(ref_returns))
    env = make_env(env_kwargs, max_episode_steps)
    spec_json, limit, control_dt = env.spec.to_json(), env.spec.max_episode_steps, float(env.unwrapped.dt)
    env.close()
    if plan_summary is not None:
        describe = {**describe, "plan_summary": plan_summary}
    metadata = {
        "dataset_id": dataset_id,
        "env_id": ENV_ID,
        "env_spec": json.loads(spec_json),
        "env_kwargs": env_kwargs,
        "max_episode_steps": int(limit) if limit else None,
        "control_dt": control_dt,
        "policy": describe,
        "seed": int(seed),
        "action_noise": action_noise,
        "action_noise_note": "DART: actions = clip(policy action + action_noise * N(0, I), -1, 1) were executed; "
                             "the policy's clean actions (labels) are infos/expert_action" if action_noise > 0
                             else "none: actions are the policy's",
        "episode_seeds": [e.seed for e in eps],
        "episodes": len(eps),
        "total_steps": int(sum(e.length for e in eps)),
        "falls": int(sum(bool(e.terminations[-1]) for e in eps)),
        "episode_returns": returns,
        "mean_return": float(np.mean(returns)),
        "ref_max_score": ref_max,
        "ref_max_score_source": ref_source,
        "ref_max_returns": ref_returns,
        "ref_min_score": ref_min,
        "ref_min_score_source": f"mean return of RandomPolicy over {REF_MIN_EPISODES} episodes, seeds "
                                f"{seed}..{seed + REF_MIN_EPISODES - 1}",
        "random_returns": random_returns,
        "infos_schema": {k: [list(v.shape[1:]), str(v.dtype)] for k, v in eps[0].infos.items()},
        "infos_alignment": "row t = observation t (reset info first) and the decision taken at it; the last "
                           "row repeats the last decision with replanned = planner_failed = False",
        "determinism": "the same seed, settings and code give identical data for any number of workers and "
                       f"across resumed runs, except the wall-clock times in infos/{', '.join(NONDETERMINISTIC_INFOS)}",
        "workers": int(workers),
        "resumed_episodes": int(resumed),
        "generation_time_s": gen_time,
        "generation_time_note": "wall time of the episodes recorded by this run (worker start-up included, the "
                                "expert's offline plan excluded: plan_time_s; resumed_episodes were loaded from "
                                "an interrupted run's checkpoints)",
        "plan_time_s": plan_time if plan_summary is not None else 0.0,
        "hsddp_gym_version": _version(),
    }
    return eps, metadata, extra, gen_time


def _version() -> str:
    import hsddp_gym

    return getattr(hsddp_gym, "__version__", "unknown")


# ================================================================================================ loading
def read_metadata(path) -> dict:
    """The ``metadata.json`` of a dataset directory."""
    return json.loads((Path(path) / "metadata.json").read_text())


def load_minari(path, dataset_id: str | None = None):
    """``minari.load_dataset`` of the dataset in directory ``path`` (``MINARI_DATASETS_PATH`` is set to
    ``path/minari`` for the call only; the returned dataset keeps reading from there)."""
    import minari

    path = Path(path)
    dataset_id = dataset_id or read_metadata(path)["dataset_id"]
    with minari_root(path / "minari"):
        return minari.load_dataset(dataset_id)


@dataclasses.dataclass
class FlatDataset:
    """The ``episodes.npz`` of a dataset: flat arrays and episode boundaries.

    ``observations (sum(T_i + 1), d)`` (each episode's T_i + 1 rows, episode i from
    ``observation_starts[i]``), ``actions / rewards / terminations / truncations (sum T_i, ...)`` (episode i
    from ``episode_starts[i]``), ``infos`` {key: (sum(T_i + 1), ...)} aligned with the observations.
    """

    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    episode_starts: np.ndarray
    observation_starts: np.ndarray
    episode_seeds: np.ndarray
    infos: dict
    metadata: dict

    @property
    def n_episodes(self) -> int:
        return int(len(self.episode_starts) - 1)

    def episode(self, i: int) -> dict:
        """Episode ``i`` as a dict with the Minari field names."""
        a, b = self.episode_starts[i], self.episode_starts[i + 1]
        oa, ob = self.observation_starts[i], self.observation_starts[i + 1]
        return {"observations": self.observations[oa:ob], "actions": self.actions[a:b], "rewards": self.rewards[a:b],
                "terminations": self.terminations[a:b], "truncations": self.truncations[a:b],
                "infos": {k: v[oa:ob] for k, v in self.infos.items()}, "seed": int(self.episode_seeds[i])}

    def transitions(self) -> tuple[np.ndarray, np.ndarray]:
        """``(obs (N, d), actions (N, 4))``: the observation each action was taken at."""
        keep = np.ones(len(self.observations), dtype=bool)
        keep[self.observation_starts[1:] - 1] = False  # the final observation of each episode
        return self.observations[keep], self.actions


def load_npz(path) -> FlatDataset:
    """Read ``episodes.npz`` (``path`` is the dataset directory or the file itself); never unpickles."""
    path = Path(path)
    d = read_npz(path / "episodes.npz" if path.is_dir() else path)
    infos = {k[len("infos/"):]: v for k, v in d.items() if k.startswith("infos/")}
    return FlatDataset(observations=d["observations"], actions=d["actions"], rewards=d["rewards"],
                       terminations=d["terminations"], truncations=d["truncations"],
                       episode_starts=d["episode_starts"], observation_starts=d["observation_starts"],
                       episode_seeds=d["episode_seeds"], infos=infos, metadata=json.loads(str(d["metadata"])))
