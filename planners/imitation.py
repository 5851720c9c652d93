"""Learning from demonstrations in plain PyTorch: behaviour cloning and DAgger (no ``imitation`` dependency).

**Behaviour cloning** (:func:`train_bc`, defaults in :class:`BCConfig`): an MLP ``obs -> action`` with two
hidden layers of 256 ReLU units and a tanh output (the env's actions are normalized torques in [-1, 1]),
trained with Adam (lr 1e-3, batch 256, no weight decay) on the mean squared error to the demonstrated
normalized actions, for ``epochs`` passes over the data. Observations are standardized with the mean and
standard deviation of the training data (std floored at 1e-3, result clipped to +-10, as SB3's
VecNormalize). ``lr_decay`` anneals the step with a cosine schedule to 0 over the epochs. Seeded:
``torch.manual_seed(seed)`` for the initialization and a seeded generator for the
minibatch order, one CPU thread, so a run is reproducible.

The trained policy is an :class:`MLPPolicy`, a :class:`~planners.policies.Policy` whose inference is NumPy
only (no torch at evaluation), saved as ``.npz`` (weights + normalization + config as JSON; loading never
unpickles).

**Inputs** (``BCConfig.features``): ``"obs"`` (default) feeds the observation; ``"gait_clock"`` appends the
7 features of the MPC's gait clock (:class:`planners.mpc.GaitClock`: phase one-hot, time in phase, cycle
sin/cos). The MPC's phase is advanced by the observed touchdowns and drifts from the observation's clock
``2 pi t / gait_period`` (about 0.2 cycles per second, a whole cycle over a 5 s episode), so its action is
not a function of the observation alone; the clock, however, is a deterministic function of the observation
history (contact flags, pitch rate, step count), which :class:`MLPPolicy` replays while acting (it then has
memory, cleared by ``reset()``) and :func:`build_inputs` replays per demonstration episode.

**Demonstrations** (:func:`load_demonstrations`) come from a Minari dataset (``minari.load_dataset`` /
:func:`hsddp_gym.datasets.load_minari`, the default) or from a dataset's ``episodes.npz``
(:func:`hsddp_gym.datasets.load_npz`): pairs (observation t, action t) of the first ``episodes`` episodes;
for datasets recorded with DART noise injection (``hsddp-gym dataset --action-noise``) the label is the
expert's clean action ``infos["expert_action"]``, not the noisy executed one.

**DAgger** (:func:`train_dagger`, Ross et al. 2011): round 0 trains BC on the initial demonstrations (or on
``episodes_per_round`` expert episodes if none are given). In round ``i >= 1`` the executed action is the
expert's with probability ``beta_i = beta_decay ** i`` and the learner's otherwise (drawn per step from a
seeded generator); the expert runs *alongside* on the same env states for the whole episode -- it is
queried at every visited observation, so a policy with memory (gait clock, plan cursor, MPC warm start)
keeps its memory consistent -- and its action is the label of that observation. The labels are added to the
aggregate data and BC is retrained from scratch on it (or, with ``warm_start``, fine-tuned from the previous
round's network). ``rollout_noise`` adds DART-style Gaussian noise to the executed actions of rounds
``>= 1`` (labels stay clean); ``rollout_steps`` truncates their rollouts. ``expert_labels`` counts every
expert label used for training (the initial demonstrations' actions included).
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hsddp_gym.io import read_npz, write_npz
from planners.policies import EnvInterface, Policy

ACTIVATIONS = ("relu", "tanh")
FEATURES = ("obs", "gait_clock")
"""Inputs of the MLP: ``obs`` (the observation) or ``gait_clock`` (the observation plus the 7
:meth:`planners.mpc.GaitClock.features` of the MPC's gait clock, rebuilt from the observation history)."""


# ================================================================================================ config
@dataclasses.dataclass(frozen=True)
class BCConfig:
    """Behaviour-cloning settings (defaults documented in the module docstring)."""

    hidden: tuple = (256, 256)
    activation: str = "relu"
    lr: float = 1e-3
    batch_size: int = 256
    epochs: int = 50
    weight_decay: float = 0.0
    seed: int = 0
    std_floor: float = 1e-3
    obs_clip: float = 10.0
    threads: int = 1
    features: str = "obs"
    lr_decay: bool = False

    def __post_init__(self) -> None:
        if self.features not in FEATURES:
            raise ValueError(f"features must be one of {FEATURES}, got {self.features!r}")
        if self.activation not in ACTIVATIONS:
            raise ValueError(f"activation must be one of {ACTIVATIONS}, got {self.activation!r}")
        if not self.hidden or any(int(h) < 1 for h in self.hidden):
            raise ValueError(f"hidden must be a non-empty sequence of positive sizes, got {self.hidden!r}")
        for name in ("lr", "std_floor", "obs_clip"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)!r}")
        for name in ("batch_size", "epochs", "threads"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)!r}")

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["hidden"] = [int(h) for h in self.hidden]
        return d


# ================================================================================================ features
def make_gait_clock(interface: EnvInterface = EnvInterface(), mpc_options: dict | None = None):
    """The :class:`planners.mpc.GaitClock` of an :class:`planners.mpc.MPCPolicy` built for ``interface``
    with ``MPCOptions(**mpc_options)`` (default options)."""
    from planners.mpc import MPCOptions, MPCPolicy

    o = MPCOptions(**dict(mpc_options or {}))
    return MPCPolicy(interface, o).clock.copy()


_CLOCK_EXTRA = ("lost_stance_steps",)
"""Optional :class:`planners.mpc.GaitClock` settings, saved (and passed back) only when the clock has them."""


def _clock_params(clock) -> dict:
    params = {"durations": list(clock.durations), "dt": clock.dt, "debounce_steps": clock.debounce_steps,
              "min_flight": clock.min_flight, "max_wait": clock.max_wait}
    params.update({k: getattr(clock, k) for k in _CLOCK_EXTRA if getattr(clock, k, None)})
    return params


def _clock_from_params(params: dict):
    from planners.mpc import GaitClock

    extra = {k: params[k] for k in _CLOCK_EXTRA if params.get(k)}
    return GaitClock(tuple(params["durations"]), params["dt"], params["debounce_steps"], params["min_flight"],
                     params["max_wait"], **extra)


def gait_clock_features(obs: np.ndarray, clock, layout=None) -> np.ndarray:
    """``(T, 7)`` gait-clock features of one episode's observations ``obs (T, d)`` in order: the clock is
    reset, then for every observation updated from its contact flags and pitch rate, read, and ticked
    (exactly what :class:`MLPPolicy` and :class:`planners.mpc.MPCPolicy` do while acting)."""
    from hsddp_gym.conventions import IPITCH, NQ
    from hsddp_gym.observation import DEFAULT_LAYOUT, state_from_observation

    layout = layout if layout is not None else DEFAULT_LAYOUT
    clock = clock.copy()
    clock.reset()
    out = np.zeros((len(obs), clock.N_FEATURES))
    for t, o in enumerate(np.asarray(obs)):
        x, mode, _ = state_from_observation(o, layout)
        clock.update(mode, float(x[NQ + IPITCH]))
        out[t] = clock.features()
        clock.tick()
    return out


def _episode_runs(episode: np.ndarray) -> list[tuple[int, int]]:
    """``[(start, stop), ...]`` of the contiguous runs of equal episode ids."""
    episode = np.asarray(episode)
    if len(episode) == 0:
        return []
    cuts = np.flatnonzero(np.diff(episode) != 0) + 1
    edges = [0, *cuts.tolist(), len(episode)]
    return list(zip(edges[:-1], edges[1:]))


def build_inputs(demos: Demonstrations, config: BCConfig, clock=None, layout=None) -> np.ndarray:
    """The MLP inputs (float64) of ``demos`` for ``config.features`` (``clock``: a GaitClock for
    ``gait_clock``; each episode -- a contiguous run of one episode id -- starts from a reset clock)."""
    obs = np.asarray(demos.obs, dtype=np.float64)
    if config.features == "obs":
        return obs
    if clock is None:
        raise ValueError("features='gait_clock' needs a gait clock")
    feats = np.zeros((len(obs), clock.N_FEATURES))
    for a, b in _episode_runs(demos.episode):
        feats[a:b] = gait_clock_features(obs[a:b], clock, layout)
    return np.concatenate([obs, feats], axis=1)


# ================================================================================================ policy
class MLPPolicy(Policy):
    """A deterministic MLP policy ``action = tanh(W_L f(... f(W_1 z + b_1)) + b_L)`` with ``z`` the clipped,
    standardized observation; NumPy inference.

    Args:
        weights: ``[(W (out, in), b (out,)), ...]`` float arrays, last layer linear before the tanh.
        obs_mean, obs_std: standardization of the inputs (obs_dim, plus 7 with ``gait_clock`` features).
        config: the :class:`BCConfig` it was trained with.
        clock: the :class:`planners.mpc.GaitClock` (or its parameters as a dict) for ``gait_clock`` features;
            the policy then has memory (the clock), reset by :meth:`reset`.
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), weights=None, obs_mean=None, obs_std=None,
                 config: BCConfig = BCConfig(), info: dict | None = None, clock=None) -> None:
        super().__init__(interface)
        if weights is None or obs_mean is None or obs_std is None:
            raise ValueError("weights, obs_mean and obs_std are required")
        self.weights = [(np.asarray(W, dtype=np.float64), np.asarray(b, dtype=np.float64)) for W, b in weights]
        self.obs_mean = np.asarray(obs_mean, dtype=np.float64)
        self.obs_std = np.asarray(obs_std, dtype=np.float64)
        self.config = config
        self.info = dict(info or {})
        if isinstance(clock, dict):
            clock = _clock_from_params(clock)
        if config.features == "gait_clock":
            clock = clock if clock is not None else make_gait_clock(interface)
            self.clock = clock.copy()
            self.clock.reset()
            n_in = interface.layout.size + self.clock.N_FEATURES
        else:
            self.clock = None
            n_in = interface.layout.size
        if self.obs_mean.shape != (n_in,):
            raise ValueError(f"obs_mean must have shape ({n_in},), got {self.obs_mean.shape}")

    def reset(self) -> None:
        if self.clock is not None:
            self.clock.reset()

    def _reset_copy_state(self) -> None:
        if self.clock is not None:
            self.clock = self.clock.copy()

    def forward(self, obs: np.ndarray) -> np.ndarray:
        """Actions ``(n, 4)`` for network inputs ``(n, n_in)`` (float64): observations, with the gait-clock
        features appended for ``features='gait_clock'`` (see :func:`build_inputs`)."""
        z = np.clip((np.asarray(obs, dtype=np.float64) - self.obs_mean) / self.obs_std, -self.config.obs_clip,
                    self.config.obs_clip)
        for W, b in self.weights[:-1]:
            z = z @ W.T + b
            z = np.maximum(z, 0.0) if self.config.activation == "relu" else np.tanh(z)
        W, b = self.weights[-1]
        return np.tanh(z @ W.T + b)

    def act(self, obs: np.ndarray) -> np.ndarray:
        z = np.asarray(obs, dtype=np.float64)
        if self.clock is not None:
            from hsddp_gym.conventions import IPITCH, NQ

            x, mode, _ = self._parse(obs)
            self.clock.update(mode, float(x[NQ + IPITCH]))
            z = np.concatenate([z, self.clock.features()])
            self.clock.tick()
        return self.forward(z[None])[0].astype(np.float32)

    def save(self, path) -> Path:
        """Write ``.npz``: ``W0, b0, W1, ...``, ``obs_mean``, ``obs_std`` and ``meta`` (JSON: config, info)."""
        arrays = {"obs_mean": self.obs_mean, "obs_std": self.obs_std}
        for i, (W, b) in enumerate(self.weights):
            arrays[f"W{i}"], arrays[f"b{i}"] = W, b
        meta = {"config": self.config.to_dict(), "n_layers": len(self.weights), "info": self.info,
                "clock": _clock_params(self.clock) if self.clock is not None else None,
                "layout_exclude_current_positions": bool(self.interface.layout.exclude_current_positions)}
        arrays["meta"] = np.array(json.dumps(meta))
        return write_npz(path, **arrays)

    @classmethod
    def load(cls, path, interface: EnvInterface | None = None) -> MLPPolicy:
        """Read a policy written by :meth:`save` (no pickle). ``interface``: the env's (default: defaults)."""
        d = read_npz(path)
        meta = json.loads(str(d["meta"]))
        cfg = dict(meta["config"])
        cfg["hidden"] = tuple(cfg["hidden"])
        weights = [(d[f"W{i}"], d[f"b{i}"]) for i in range(meta["n_layers"])]
        return cls(interface if interface is not None else EnvInterface(), weights=weights, obs_mean=d["obs_mean"],
                   obs_std=d["obs_std"], config=BCConfig(**cfg), info=meta.get("info"), clock=meta.get("clock"))


# ================================================================================================ data
@dataclasses.dataclass
class Demonstrations:
    """Labelled observations: ``obs (N, d)`` float32, ``actions (N, 4)`` float32, ``episode (N,)`` the
    episode each pair comes from (0-based, in dataset order)."""

    obs: np.ndarray
    actions: np.ndarray
    episode: np.ndarray

    @property
    def n_episodes(self) -> int:
        return int(self.episode.max() + 1) if len(self.episode) else 0

    def __len__(self) -> int:
        return int(len(self.obs))

    def first_episodes(self, n: int) -> Demonstrations:
        keep = self.episode < int(n)
        return Demonstrations(self.obs[keep], self.actions[keep], self.episode[keep])

    def concat(self, other: Demonstrations) -> Demonstrations:
        offset = self.n_episodes
        return Demonstrations(np.concatenate([self.obs, other.obs]), np.concatenate([self.actions, other.actions]),
                              np.concatenate([self.episode, other.episode + offset]))


def load_demonstrations(source, episodes: int | None = None, fmt: str = "minari") -> Demonstrations:
    """(observation t, action t) pairs from a dataset.

    The action is the label: ``infos["expert_action"]`` when the dataset has it (datasets recorded with
    DART action noise, whose ``actions`` are the noisy executed ones), the recorded action otherwise.

    Args:
        source: a ``MinariDataset``, a :class:`hsddp_gym.datasets.FlatDataset`, a dataset directory written
            by :func:`hsddp_gym.datasets.generate_dataset`, or an ``episodes.npz`` file.
        episodes: use only the first ``episodes`` episodes (None: all).
        fmt: for a directory, read the Minari dataset (``"minari"``, via ``minari.load_dataset``) or
            ``episodes.npz`` (``"npz"``).
    """
    from hsddp_gym import datasets

    if fmt not in ("minari", "npz"):
        raise ValueError(f"fmt must be 'minari' or 'npz', got {fmt!r}")
    if isinstance(source, (str, Path)):
        p = Path(source)
        if p.is_file():
            source = datasets.load_npz(p)
        elif fmt == "npz":
            source = datasets.load_npz(p)
        else:
            source = datasets.load_minari(p)
    obs, acts, ep = [], [], []
    if isinstance(source, datasets.FlatDataset):
        n = source.n_episodes if episodes is None else min(int(episodes), source.n_episodes)
        for i in range(n):
            e = source.episode(i)
            obs.append(e["observations"][:-1])
            acts.append(e["infos"]["expert_action"][:-1] if "expert_action" in e["infos"] else e["actions"])
            ep.append(np.full(len(e["actions"]), i))
    else:  # a MinariDataset
        n = source.total_episodes if episodes is None else min(int(episodes), source.total_episodes)
        for i, e in enumerate(source.iterate_episodes(episode_indices=list(range(n)))):
            obs.append(np.asarray(e.observations)[:-1])
            infos = e.infos if isinstance(e.infos, dict) else {}
            acts.append(np.asarray(infos["expert_action"])[:-1] if "expert_action" in infos else
                        np.asarray(e.actions))
            ep.append(np.full(len(e.actions), i))
    if not obs:
        raise ValueError("the dataset has no episodes")
    return Demonstrations(np.concatenate(obs).astype(np.float32), np.concatenate(acts).astype(np.float32),
                          np.concatenate(ep).astype(np.int64))


# ================================================================================================ BC
def _activation(name: str):
    import torch.nn as nn

    return nn.ReLU if name == "relu" else nn.Tanh


def train_bc(demos: Demonstrations, config: BCConfig = BCConfig(), interface: EnvInterface = EnvInterface(),
             callback: Callable | None = None, clock=None, init: MLPPolicy | None = None
             ) -> tuple[MLPPolicy, dict]:
    """Behaviour cloning on ``demos`` (see the module docstring).

    Args:
        callback: called after every epoch with ``(epoch, mean_loss)``.
        clock: the gait clock for ``config.features == "gait_clock"`` (default: the default MPC's for
            ``interface``, :func:`make_gait_clock`).
        init: warm start: start from this policy's weights and keep its input standardization (its layer
            sizes, activation and features must match ``config``) instead of a fresh initialization.
    Returns:
        ``(policy, history)`` with ``history = {"loss": [mean training loss per epoch], "wall_time_s",
        "transitions"}``.
    """
    import torch
    import torch.nn as nn

    if len(demos) == 0:
        raise ValueError("demos is empty")
    torch.set_num_threads(int(config.threads))
    torch.manual_seed(int(config.seed))
    t0 = time.perf_counter()
    if config.features == "gait_clock" and clock is None:
        clock = make_gait_clock(interface)
    obs = build_inputs(demos, config, clock, interface.layout)
    acts = np.clip(np.asarray(demos.actions, dtype=np.float64), -1.0, 1.0)
    if init is not None:
        if (tuple(int(h) for h in init.config.hidden) != tuple(int(h) for h in config.hidden)
                or init.config.activation != config.activation or init.config.features != config.features):
            raise ValueError("init must have the hidden sizes, activation and features of config")
        mean, std = init.obs_mean.copy(), init.obs_std.copy()
    else:
        mean = obs.mean(axis=0)
        std = np.maximum(obs.std(axis=0), config.std_floor)
    z = np.clip((obs - mean) / std, -config.obs_clip, config.obs_clip)
    X = torch.as_tensor(z, dtype=torch.float32)
    Y = torch.as_tensor(acts, dtype=torch.float32)
    layers, size = [], X.shape[1]
    for h in config.hidden:
        layers += [nn.Linear(size, int(h)), _activation(config.activation)()]
        size = int(h)
    layers += [nn.Linear(size, Y.shape[1]), nn.Tanh()]
    net = nn.Sequential(*layers)
    if init is not None:
        with torch.no_grad():
            for m, (W, b) in zip([m for m in net if isinstance(m, nn.Linear)], init.weights):
                m.weight.copy_(torch.as_tensor(W, dtype=torch.float32))
                m.bias.copy_(torch.as_tensor(b, dtype=torch.float32))
    opt = torch.optim.Adam(net.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, int(config.epochs)) if config.lr_decay else None
    gen = torch.Generator().manual_seed(int(config.seed))
    n, bs = len(X), min(int(config.batch_size), len(X))
    losses = []
    for epoch in range(int(config.epochs)):
        perm = torch.randperm(n, generator=gen)
        total = 0.0
        for start in range(0, n, bs):
            idx = perm[start:start + bs]
            loss = ((net(X[idx]) - Y[idx]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(idx)
        losses.append(total / n)
        if sched is not None:
            sched.step()
        if callback is not None:
            callback(epoch, losses[-1])
    linears = [m for m in net if isinstance(m, nn.Linear)]
    weights = [(m.weight.detach().numpy().astype(np.float64), m.bias.detach().numpy().astype(np.float64))
               for m in linears]
    history = {"loss": losses, "wall_time_s": time.perf_counter() - t0, "transitions": int(n),
               "episodes": demos.n_episodes}
    policy = MLPPolicy(interface, weights=weights, obs_mean=mean, obs_std=std, config=config,
                       info={"transitions": int(n), "episodes": demos.n_episodes, "final_loss": losses[-1]},
                       clock=clock if config.features == "gait_clock" else None)
    return policy, history


# ================================================================================================ DAgger
@dataclasses.dataclass(frozen=True)
class DAggerConfig:
    """DAgger settings.

    Attributes:
        rounds: relabelling rounds after round 0. episodes_per_round: learner/mixture episodes per round
            (and expert episodes of round 0 when no initial demonstrations are given).
        beta_decay: ``beta_i = beta_decay ** i`` (round 0: 1, pure expert). 0 gives pure learner rollouts.
        bc: the BC settings used in every round (retrained from scratch on the aggregate data).
        seed: episode ``j`` of round ``i`` is reset with seed ``seed + 1000 * i + j``; the mixture draws come
            from ``np.random.default_rng([seed, i, j])``.
        max_episode_steps: time-limit override of the rollouts (None: the env's 1000).
        rollout_noise: DART-style noise in rounds >= 1: the executed action (expert's or learner's) gets
            i.i.d. Gaussian noise of this std (normalized units, clipped to [-1, 1]) drawn from the round's
            generator, so the aggregate data covers the recoveries from perturbed states; the label stays the
            expert's clean action (0: none).
        warm_start: rounds >= 1 start training from the previous round's network and input standardization
            (``epochs`` per round, lr schedule restarted) instead of a fresh initialization.
        rollout_steps: truncate the relabelling rollouts of rounds >= 1 after this many steps (None: run to
            the end of the episode). The learner's falls happen in the first ~150 steps (the start transient
            from the reset noise), so short rollouts spend the label budget on many initial states instead of
            on steady bounding. Only the labelled steps count; the evaluation is not truncated.
    """

    rounds: int = 4
    episodes_per_round: int = 5
    beta_decay: float = 0.5
    bc: BCConfig = BCConfig()
    seed: int = 0
    max_episode_steps: int | None = None
    rollout_noise: float = 0.0
    warm_start: bool = False
    rollout_steps: int | None = None

    def __post_init__(self) -> None:
        if int(self.rounds) < 0:
            raise ValueError(f"rounds must be >= 0, got {self.rounds!r}")
        if int(self.episodes_per_round) < 1:
            raise ValueError(f"episodes_per_round must be >= 1, got {self.episodes_per_round!r}")
        if not 0.0 <= float(self.beta_decay) <= 1.0:
            raise ValueError(f"beta_decay must be in [0, 1], got {self.beta_decay!r}")
        if self.rollout_steps is not None and int(self.rollout_steps) < 1:
            raise ValueError(f"rollout_steps must be >= 1 or None, got {self.rollout_steps!r}")
        if not float(self.rollout_noise) >= 0.0:
            raise ValueError(f"rollout_noise must be >= 0, got {self.rollout_noise!r}")

    def beta(self, round_index: int) -> float:
        return 1.0 if round_index == 0 else float(self.beta_decay) ** int(round_index)


@dataclasses.dataclass
class DAggerResult:
    """``policy`` (the last round's learner), ``data`` (aggregate labels), ``history`` (one dict per round:
    ``round, beta, episodes, new_labels, expert_labels, transitions, rollout_mean_return, expert_actions_fraction,
    final_loss, eval`` (if evaluated)), ``expert_labels`` (total) and ``wall_time_s``."""

    policy: MLPPolicy
    data: Demonstrations
    history: list
    expert_labels: int
    wall_time_s: float


def dagger_rollout(env, learner, expert, beta: float, seed: int, rng: np.random.Generator,
                   options: dict | None = None, noise: float = 0.0, max_steps: int | None = None
                   ) -> tuple[np.ndarray, np.ndarray, float, int]:
    """One episode (stopped after ``max_steps`` steps if given) in which the expert labels every visited
    observation and the executed action is the expert's with probability ``beta`` (the learner's otherwise),
    plus Gaussian noise of std ``noise`` (clipped to [-1, 1]; the label stays clean). Returns ``(obs (T, d),
    expert actions (T, 4), return, expert acts)``."""
    obs, _ = env.reset(seed=int(seed), options=options)
    expert.reset()
    if learner is not None:
        learner.reset()
    O, A, ret, n_expert = [], [], 0.0, 0
    while True:
        label = np.asarray(expert(obs), dtype=np.float32)
        O.append(np.asarray(obs, dtype=np.float32))
        A.append(label)
        use_expert = learner is None or rng.random() < beta
        n_expert += int(use_expert)
        action = label if use_expert else np.asarray(learner(obs), dtype=np.float32)
        if noise > 0:
            action = np.clip(action + noise * rng.standard_normal(action.shape), -1.0, 1.0).astype(np.float32)
        obs, reward, terminated, truncated, _ = env.step(action)
        ret += float(reward)
        if terminated or truncated or (max_steps is not None and len(O) >= int(max_steps)):
            break
    return np.array(O), np.array(A), ret, n_expert


def train_dagger(expert_factory: Callable, config: DAggerConfig = DAggerConfig(),
                 initial: Demonstrations | None = None, env_kwargs: dict | None = None,
                 evaluate: Callable | None = None, progress: bool = True, clock=None) -> DAggerResult:
    """DAgger with any expert (see the module docstring).

    Args:
        expert_factory: ``(env, episode_seed) -> (expert Policy, reset_options or None)``, e.g.
            :class:`hsddp_gym.datasets.PolicySpec`; one expert is built per rollout.
        initial: round-0 demonstrations (None: ``episodes_per_round`` expert episodes are recorded).
        evaluate: optional ``policy -> dict`` called on each round's learner (stored in the history).
        clock: the gait clock of ``gait_clock`` features (default: the default MPC's, :func:`make_gait_clock`).
    """
    from tqdm import tqdm

    from hsddp_gym.datasets import make_env

    t0 = time.perf_counter()
    env = make_env(env_kwargs, config.max_episode_steps)
    interface = EnvInterface.from_env(env)
    history = []
    data = initial
    expert_labels = 0
    bar = tqdm(total=config.rounds + 1, desc="DAgger rounds", unit="round", disable=not progress)
    learner = None
    for r in range(config.rounds + 1):
        beta = config.beta(r)
        new, returns, expert_acts, n_eps = None, [], 0, 0
        if r > 0 or data is None:
            parts = []
            for j in range(config.episodes_per_round):
                seed = config.seed + 1000 * r + j
                expert, options = expert_factory(env, seed)
                O, A, ret, ne = dagger_rollout(env, learner if r > 0 else None, expert, beta, seed,
                                               np.random.default_rng([config.seed, r, j]), options,
                                               noise=float(config.rollout_noise) if r > 0 else 0.0,
                                               max_steps=config.rollout_steps if r > 0 else None)
                parts.append(Demonstrations(O, A, np.full(len(O), j)))
                returns.append(ret)
                expert_acts += ne
            new = parts[0]
            for p in parts[1:]:
                new = new.concat(p)
            n_eps = len(parts)
            data = new if data is None else data.concat(new)
            expert_labels += len(new)
        else:
            expert_labels += len(data)  # the initial demonstrations' actions are expert labels too
        learner, hist = train_bc(data, dataclasses.replace(config.bc, seed=config.bc.seed + r), interface,
                                 clock=clock, init=learner if config.warm_start else None)
        rec = {"round": r, "beta": beta, "episodes": n_eps, "new_labels": int(len(new)) if new is not None else
               int(len(data)), "expert_labels": int(expert_labels), "transitions": int(len(data)),
               "rollout_mean_return": float(np.mean(returns)) if returns else None,
               "expert_actions_fraction": (expert_acts / len(new)) if new is not None and len(new) else 1.0,
               "final_loss": hist["loss"][-1], "bc_wall_time_s": hist["wall_time_s"]}
        if evaluate is not None:
            rec["eval"] = evaluate(learner)
        history.append(rec)
        bar.update(1)
        bar.set_postfix(labels=expert_labels)
    bar.close()
    env.close()
    learner.info.update(expert_labels=int(expert_labels), dagger_rounds=int(config.rounds))
    return DAggerResult(learner, data, history, int(expert_labels), time.perf_counter() - t0)


# ================================================================================================ evaluation
def evaluate_policy_episodes(policy, episodes: int = 10, seed: int = 0, env_kwargs: dict | None = None,
                             max_episode_steps: int | None = None, reset_options: dict | None = None) -> dict:
    """The comparison protocol: ``episodes`` episodes seeded ``seed, seed + 1, ...``, the policy's
    deterministic actions; returns :func:`planners.evaluation.summarize` (mean/std return, falls, forward
    speed, episode length, ...)."""
    from hsddp_gym.datasets import make_env
    from planners.evaluation import run_episode, summarize

    env = make_env(env_kwargs, max_episode_steps)
    try:
        results = [run_episode(env, policy, seed + i, options=reset_options) for i in range(int(episodes))]
    finally:
        env.close()
    return summarize(results)


# ================================================================================================ runs
def plot_curve(path, x, y, yerr=None, xlabel: str = "", ylabel: str = "mean return", title: str = "",
               reference: dict | None = None) -> bool:
    """A line plot with error bars saved to ``path`` (False when matplotlib is missing)."""
    from hsddp_gym.plotting import _plt, _save

    try:
        plt = _plt()
    except ImportError:  # the viz extra is optional
        return False
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.errorbar(x, y, yerr=yerr, marker="o", ms=4, capsize=3)
    for i, (name, value) in enumerate((reference or {}).items()):
        if value is not None:
            ax.axhline(value, ls="--", lw=1, color=f"C{i + 1}", label=name)
    if reference:
        ax.legend(fontsize=8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    _save(fig, path)  # atomic
    return True


def _write_csv(path, header, rows) -> None:
    import csv

    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


def _eval_brief(summary: dict) -> dict:
    keys = ("episodes", "seeds", "mean_return", "std_return", "returns", "falls", "mean_forward_speed",
            "mean_episode_length")
    return {k: summary[k] for k in keys if k in summary}


def run_bc(dataset, out, seed: int = 0, config: BCConfig | None = None, demos: int | None = None,
           fmt: str = "minari", eval_episodes: int = 10, curve: list | None = None,
           env_kwargs: dict | None = None, max_episode_steps: int | None = None, progress: bool = True) -> dict:
    """Train BC on a dataset directory and write into ``out``: ``policy.npz``, ``summary.json``,
    ``loss.csv`` and, with ``curve`` (numbers of demonstration episodes), ``curve.csv`` / ``curve.png`` of
    the evaluation return of BC trained on the first n episodes.

    The evaluation uses the comparison protocol (``eval_episodes`` episodes, seeds 0, 1, ..., default reset
    noise, the env's 1000-step limit unless ``max_episode_steps``).
    """
    from hsddp_gym.datasets import make_env, read_metadata
    from hsddp_gym.io import write_json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    config = dataclasses.replace(config or BCConfig(), seed=int(seed))
    meta = read_metadata(dataset)
    env_kwargs = dict(meta.get("env_kwargs", {}) if env_kwargs is None else env_kwargs)
    env = make_env(env_kwargs, max_episode_steps)
    interface = EnvInterface.from_env(env)
    env.close()
    data = load_demonstrations(dataset, episodes=demos, fmt=fmt)
    loss_bar = None
    if progress:
        from tqdm import tqdm

        loss_bar = tqdm(total=config.epochs, desc="BC epochs", unit="epoch")

    def cb(epoch, loss):
        if loss_bar is not None:
            loss_bar.update(1)
            loss_bar.set_postfix(loss=f"{loss:.4g}")

    clock = None
    if config.features == "gait_clock":
        pol_meta = meta.get("policy", {})
        opts = pol_meta.get("options") if isinstance(pol_meta, dict) and pol_meta.get("name") == "mpc" else None
        clock = make_gait_clock(interface, opts)
    policy, hist = train_bc(data, config, interface, callback=cb, clock=clock)
    if loss_bar is not None:
        loss_bar.close()
    policy.info.update(dataset=str(dataset), dataset_id=meta.get("dataset_id"))
    policy.save(out / "policy.npz")
    _write_csv(out / "loss.csv", ["epoch", "loss"], [[i + 1, f"{v:.6g}"] for i, v in enumerate(hist["loss"])])
    summary = {"algo": "bc", "dataset": str(dataset), "dataset_id": meta.get("dataset_id"),
               "dataset_policy": meta.get("policy", {}).get("name"), "format": fmt, "seed": int(seed),
               "demonstrations": data.n_episodes, "transitions": len(data), "expert_labels": len(data),
               "config": config.to_dict(), "loss": hist["loss"], "final_loss": hist["loss"][-1],
               "wall_time_s": hist["wall_time_s"], "env_kwargs": env_kwargs, "max_episode_steps": max_episode_steps,
               "files": ["policy.npz", "loss.csv", "summary.json"]}
    if eval_episodes > 0:
        summary["eval"] = _eval_brief(evaluate_policy_episodes(policy, eval_episodes, 0, env_kwargs,
                                                               max_episode_steps))
    if curve:
        rows, points = [], []
        for n in sorted({min(int(c), data.n_episodes) for c in curve if int(c) >= 1}):
            sub = data if n >= data.n_episodes else data.first_episodes(n)
            p, h = (policy, hist) if sub is data else train_bc(sub, config, interface, clock=clock)
            ev = evaluate_policy_episodes(p, max(eval_episodes, 1), 0, env_kwargs, max_episode_steps)
            rows.append([n, len(sub), f"{ev['mean_return']:.6g}", f"{ev['std_return']:.6g}", ev["falls"],
                         f"{h['wall_time_s']:.3f}"])
            points.append({"demonstrations": n, "transitions": len(sub), "mean_return": ev["mean_return"],
                           "std_return": ev["std_return"], "falls": ev["falls"]})
        _write_csv(out / "curve.csv", ["demonstrations", "transitions", "mean_return", "std_return", "falls",
                                       "train_wall_time_s"], rows)
        summary["curve"] = points
        summary["files"].append("curve.csv")
        if points and plot_curve(out / "curve.png", [p["demonstrations"] for p in points],
                                 [p["mean_return"] for p in points], [p["std_return"] for p in points],
                                 "demonstration episodes", title="BC vs number of demonstrations",
                                 reference={"dataset policy (ref_max_score)": meta.get("ref_max_score"),
                                            "random (ref_min_score)": meta.get("ref_min_score")}):
            summary["files"].append("curve.png")
    write_json(out / "summary.json", summary)
    return summary


def run_dagger(expert: str, out, seed: int = 0, config: DAggerConfig | None = None, dataset=None,
               demos: int | None = None, fmt: str = "minari", eval_episodes: int = 10,
               env_kwargs: dict | None = None, mpc_options: dict | None = None, progress: bool = True) -> dict:
    """DAgger with a built-in expert (``heuristic``, ``mpc`` or ``expert``) and write into ``out``:
    ``policy.npz``, ``dagger_data.npz`` (aggregate labels), ``summary.json``, ``curve.csv`` / ``curve.png``
    (evaluation return after each round vs expert labels).

    Args:
        dataset: optional dataset directory whose first ``demos`` episodes are the round-0 demonstrations.
    """
    from hsddp_gym.datasets import PolicySpec, solve_expert_plan
    from hsddp_gym.io import write_json

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    config = dataclasses.replace(config or DAggerConfig(), seed=int(seed),
                                 bc=dataclasses.replace((config or DAggerConfig()).bc, seed=int(seed)))
    env_kwargs = dict(env_kwargs or {})
    files = ["policy.npz", "dagger_data.npz", "summary.json", "curve.csv"]
    plan = None
    if expert == "expert":
        plan = solve_expert_plan(out / "expert_plan.npz")
        spec = PolicySpec("expert", plan_path=str(out / "expert_plan.npz"))
        files.append("expert_plan.npz")
    else:
        spec = PolicySpec(expert, options=dict(mpc_options or {}))
    initial = load_demonstrations(dataset, episodes=demos, fmt=fmt) if dataset is not None else None

    def evaluate(p):
        if eval_episodes <= 0:
            return None
        return _eval_brief(evaluate_policy_episodes(p, eval_episodes, 0, env_kwargs, config.max_episode_steps))

    clock = None
    if config.bc.features == "gait_clock":
        from hsddp_gym.datasets import make_env

        env = make_env(env_kwargs, config.max_episode_steps)
        clock = make_gait_clock(EnvInterface.from_env(env), mpc_options if expert == "mpc" else None)
        env.close()
    res = train_dagger(spec, config, initial, env_kwargs, evaluate=evaluate, progress=progress, clock=clock)
    res.policy.save(out / "policy.npz")
    write_npz(out / "dagger_data.npz", obs=res.data.obs, actions=res.data.actions, episode=res.data.episode)
    rows = [[h["round"], h["beta"], h["expert_labels"], h["transitions"],
             f"{h['eval']['mean_return']:.6g}" if h.get("eval") else "", f"{h['eval']['std_return']:.6g}"
             if h.get("eval") else "", h["eval"]["falls"] if h.get("eval") else ""] for h in res.history]
    _write_csv(out / "curve.csv", ["round", "beta", "expert_labels", "transitions", "mean_return", "std_return",
                                   "falls"], rows)
    evals = [h for h in res.history if h.get("eval")]
    if evals and plot_curve(out / "curve.png", [h["expert_labels"] for h in evals],
                            [h["eval"]["mean_return"] for h in evals], [h["eval"]["std_return"] for h in evals],
                            "expert labels", title=f"DAgger ({expert} expert) vs expert labels"):
        files.append("curve.png")
    summary = {"algo": "dagger", "expert": spec.describe(), "seed": int(seed), "config": {
        **{k: v for k, v in dataclasses.asdict(config).items() if k != "bc"}, "bc": config.bc.to_dict()},
        "initial_dataset": None if dataset is None else str(dataset), "initial_demonstrations":
        None if initial is None else initial.n_episodes, "expert_labels": res.expert_labels,
        "transitions": len(res.data), "history": res.history, "wall_time_s": res.wall_time_s,
        "env_kwargs": env_kwargs, "max_episode_steps": config.max_episode_steps, "files": files}
    if plan is not None:
        summary["expert_plan"] = plan
    if res.history and res.history[-1].get("eval"):
        summary["eval"] = res.history[-1]["eval"]
    write_json(out / "summary.json", summary)
    return summary
