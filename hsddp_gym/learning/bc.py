"""Behaviour cloning: an MLP trained on demonstrations ([`train_bc`][train_bc]), its NumPy policy
([`MLPPolicy`][MLPPolicy]), and the whole job with evaluation and curves ([`run_bc`][run_bc])."""

from __future__ import annotations

import collections
import dataclasses
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from hsddp_gym.core.conventions import NU
from hsddp_gym.learning.demonstrations import Demonstrations, load_demonstrations
from hsddp_gym.learning.features import (
    FEATURES,
    QUEUE_SLOT_SIZE,
    build_inputs,
    make_gait_clock,
    queue_row,
)
from hsddp_gym.learning.gain_labels import gain_augmented_pairs
from hsddp_gym.learning.reporting import eval_brief, evaluate_policy_episodes, plot_curve, write_csv
from hsddp_gym.planners.policies.base import EnvInterface, Policy
from hsddp_gym.util.io import read_npz, write_npz
from hsddp_gym.util.validation import check_int

ACTIVATIONS = ("relu", "tanh")


# ================================================================================================ config
@dataclasses.dataclass(frozen=True)
class BCConfig:
    """Behaviour-cloning settings (defaults documented in the module docstring).

    ``input_noise``: ``(position_std, velocity_std)`` [m or rad, m/s or rad/s] of Gaussian noise added to the observed
    positions and velocities of every minibatch's inputs (fresh noise per minibatch; contact flags, clock and extra
    features untouched), the labels unchanged: the learner is taught the expert's action for the true state from a
    noisy measurement of it, as under observation noise (``ObservationNoise``); ``(0, 0)``: none.
    """

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
    gain_copies: int = 0
    gain_position_std: float = 0.01
    gain_velocity_std: float = 0.1
    speed_input: bool = False
    action_queue: int = 0
    input_noise: tuple = (0.0, 0.0)

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
        if not isinstance(self.speed_input, (bool, np.bool_)):
            raise TypeError(f"speed_input must be a bool, got {type(self.speed_input).__name__}")
        check_int(self.gain_copies, "gain_copies", minimum=0)
        check_int(self.action_queue, "action_queue", minimum=0)
        for name in ("gain_position_std", "gain_velocity_std"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        noise = tuple(self.input_noise) if isinstance(self.input_noise, (tuple, list)) else ()
        if len(noise) != 2 or not all(isinstance(v, (int, float)) and v >= 0 and np.isfinite(v) for v in noise):
            raise ValueError(f"input_noise must be (position_std, velocity_std), both >= 0, got {self.input_noise!r}")
        object.__setattr__(self, "input_noise", tuple(float(v) for v in noise))

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        d["hidden"] = [int(h) for h in self.hidden]
        d["input_noise"] = list(self.input_noise)
        return d


# ================================================================================================ policy
class MLPPolicy(Policy):
    """A deterministic MLP policy ``action = tanh(W_L f(... f(W_1 z + b_1)) + b_L)`` with ``z`` the clipped,
    standardized observation; NumPy inference.

    Args:
        weights: ``[(W (out, in), b (out,)), ...]`` float arrays, last layer linear before the tanh.
        obs_mean: standardization of the inputs, their mean (obs_dim, plus 7 with ``gait_clock`` features, plus
            5 per slot with ``action_queue``, plus 1 with ``speed_input``).
        obs_std: their standard deviation (the same size).
        config: the [`BCConfig`][BCConfig] it was trained with.
        clock: the [`hsddp_gym.planners.policies.mpc.GaitClock`][hsddp_gym.planners.policies.mpc.clock.GaitClock] (or
            its parameters as a dict) for ``gait_clock``
            features; the policy then has memory (the clock), reset by `reset`.

    With ``config.action_queue`` slots the policy also remembers the actions it sent: it sees the
    ``interface.action_delay_steps`` of them that the env has not executed yet
    ([`action_queue_features`][hsddp_gym.learning.features.action_queue_features]), as the MPC's latency compensation
    does; a caller that sends another action than the one returned (DART noise, a DAgger mixture) says so through
    [`note_sent_action`][note_sent_action]. A delay larger than the slots raises ``ValueError`` naming ``action_queue``.
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
            from hsddp_gym.planners.policies.mpc import GaitClock

            clock = GaitClock.from_settings(clock)
        if config.features == "gait_clock":
            clock = clock if clock is not None else make_gait_clock(interface)
            self.clock = clock.copy()
            self.clock.reset()
            n_in = interface.layout.size + self.clock.N_FEATURES
        else:
            self.clock = None
            n_in = interface.layout.size
        self.delay = int(interface.action_delay_steps)
        if self.delay > int(config.action_queue) > 0:
            raise ValueError(f"the env's action delay ({self.delay} control steps) exceeds action_queue "
                             f"({config.action_queue}): the policy cannot see its whole latency queue")
        n_in += QUEUE_SLOT_SIZE * int(config.action_queue) + (1 if config.speed_input else 0)
        if self.obs_mean.shape != (n_in,):
            raise ValueError(f"obs_mean must have shape ({n_in},), got {self.obs_mean.shape}")
        self._sent: collections.deque = collections.deque()
        self.reset()

    def reset(self) -> None:
        if self.clock is not None:
            self.clock.reset()
        # the env executes zero torques for its first `delay` steps (ActionDelay's initial queue)
        self._sent = collections.deque(np.zeros(NU) for _ in range(self.delay))

    def note_sent_action(self, action) -> None:
        """The action actually sent in place of the last one `act` returned (with ``action_queue``; a no-op
        otherwise)."""
        if self.config.action_queue and self.delay:
            self._sent[-1] = np.asarray(action, dtype=np.float64).reshape(NU)

    def _queue_features(self) -> np.ndarray:
        """``(5 action_queue,)``: this step's row of
        [`action_queue_features`][hsddp_gym.learning.features.action_queue_features]."""
        return queue_row(self._sent, self.config.action_queue)

    def with_interface(self, interface: EnvInterface) -> MLPPolicy:
        """The same network acting in another env (``interface``: e.g. its target speed for ``speed_input``),
        with a fresh memory."""
        return MLPPolicy(interface, weights=self.weights, obs_mean=self.obs_mean, obs_std=self.obs_std,
                         config=self.config, info=self.info, clock=self.clock)

    def _reset_copy_state(self) -> None:
        if self.clock is not None:
            self.clock = self.clock.copy()

    def forward(self, obs: np.ndarray) -> np.ndarray:
        """Actions ``(n, 4)`` for network inputs ``(n, n_in)`` (float64): observations, with the gait-clock
        features appended for ``features='gait_clock'`` (see [`build_inputs`][build_inputs])."""
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
            x, mode, _ = self._parse(obs)
            self.clock.observe(mode, x)
            z = np.concatenate([z, self.clock.features()])
            self.clock.tick()
        if self.config.action_queue:
            z = np.concatenate([z, self._queue_features()])
        if self.config.speed_input:
            z = np.concatenate([z, [self.interface.target_speed]])
        action = self.forward(z[None])[0].astype(np.float32)
        if self.config.action_queue and self.delay:
            self._sent.popleft()
            self._sent.append(action.astype(np.float64))
        return action

    def save(self, path) -> Path:
        """Write ``.npz``: ``W0, b0, W1, ...``, ``obs_mean``, ``obs_std`` and ``meta`` (JSON: config, info)."""
        arrays = {"obs_mean": self.obs_mean, "obs_std": self.obs_std}
        for i, (W, b) in enumerate(self.weights):
            arrays[f"W{i}"], arrays[f"b{i}"] = W, b
        meta = {"config": self.config.to_dict(), "n_layers": len(self.weights), "info": self.info,
                "clock": self.clock.settings() if self.clock is not None else None,
                "layout_exclude_current_positions": bool(self.interface.layout.exclude_current_positions)}
        arrays["meta"] = np.array(json.dumps(meta))
        return write_npz(path, **arrays)

    @classmethod
    def load(cls, path, interface: EnvInterface | None = None) -> MLPPolicy:
        """Read a policy written by [`save`][save] (no pickle). ``interface``: the env's (default: defaults)."""
        d = read_npz(path)
        meta = json.loads(str(d["meta"]))
        cfg = dict(meta["config"])
        cfg["hidden"] = tuple(cfg["hidden"])
        weights = [(d[f"W{i}"], d[f"b{i}"]) for i in range(meta["n_layers"])]
        return cls(interface if interface is not None else EnvInterface(), weights=weights, obs_mean=d["obs_mean"],
                   obs_std=d["obs_std"], config=BCConfig(**cfg), info=meta.get("info"), clock=meta.get("clock"))


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
            ``interface``, [`make_gait_clock`][make_gait_clock]).
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
    n_demo = len(obs)
    if config.gain_copies:
        if demos.feedback is None:
            raise ValueError("gain_copies needs demonstrations with the expert's feedback gains (a dataset "
                             "generated with include_gains=True, hsddp-gym dataset --gains)")
        extra_in, extra_act = gain_augmented_pairs(obs, demos.feedback, config.gain_copies,
                                                   config.gain_position_std, config.gain_velocity_std,
                                                   config.seed, interface.layout)
        obs, acts = np.concatenate([obs, extra_in]), np.concatenate([acts, extra_act])
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
    noise = None  # per input column, the std of the input noise in standardized units
    if any(config.input_noise):
        scale = np.zeros(X.shape[1])
        layout = interface.layout
        scale[layout.qpos] = config.input_noise[0] / std[layout.qpos]
        scale[layout.qvel] = config.input_noise[1] / std[layout.qvel]
        noise = torch.as_tensor(scale, dtype=torch.float32)
    losses = []
    for epoch in range(int(config.epochs)):
        perm = torch.randperm(n, generator=gen)
        total = 0.0
        for start in range(0, n, bs):
            idx = perm[start:start + bs]
            xb = X[idx]
            if noise is not None:  # standardized and clipped as the policy's inputs are
                xb = torch.clamp(xb + noise * torch.randn(len(idx), X.shape[1], generator=gen), -config.obs_clip,
                                 config.obs_clip)
            loss = ((net(xb) - Y[idx]) ** 2).mean()
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
    history = {"loss": losses, "wall_time_s": time.perf_counter() - t0, "transitions": int(n_demo),
               "gain_labels": int(n - n_demo), "episodes": demos.n_episodes}
    policy = MLPPolicy(interface, weights=weights, obs_mean=mean, obs_std=std, config=config,
                       info={"transitions": int(n_demo), "gain_labels": int(n - n_demo),
                             "episodes": demos.n_episodes, "final_loss": losses[-1]},
                       clock=clock if config.features == "gait_clock" else None)
    return policy, history


def run_bc(dataset, out, seed: int = 0, config: BCConfig | None = None, demos: int | None = None,
           fmt: str = "minari", eval_episodes: int = 10, curve: list | None = None,
           env_kwargs: dict | None = None, max_episode_steps: int | None = None, progress: bool = True) -> dict:
    """Train BC on a dataset directory (or a list of them, e.g. at several target speeds: their demonstrations
    are pooled, ``demos`` and ``curve`` count episodes per dataset, the first one's metadata give the default
    evaluation env) and write into ``out``: ``policy.npz``, ``summary.json``,
    ``loss.csv`` and, with ``curve`` (numbers of demonstration episodes), ``curve.csv`` / ``curve.png`` of
    the evaluation return of BC trained on the first n episodes.

    The evaluation uses the comparison protocol (``eval_episodes`` episodes, seeds 0, 1, ..., default reset
    noise, the env's 1000-step limit unless ``max_episode_steps``) in the env the (first) dataset was recorded in
    (its metadata's ``env_id``).
    """
    from hsddp_gym.datasets.collection import make_env
    from hsddp_gym.datasets.storage import read_metadata, resolve_dataset_dir
    from hsddp_gym.util.extras import require
    from hsddp_gym.util.io import write_json

    require(["torch"] + (["minari", "h5py"] if fmt == "minari" else []), "run_bc")
    sources = list(dataset) if isinstance(dataset, (list, tuple)) else [dataset]
    if not sources:
        raise ValueError("dataset must be a dataset directory or a non-empty list of them")
    if curve and len(sources) > 1:
        raise ValueError("curve needs a single dataset (the learning curve counts its first n episodes)")
    sources = [resolve_dataset_dir(d, "dataset") for d in sources]
    metas = [read_metadata(d) for d in sources]
    meta = metas[0]
    n_available = min(int(m["episodes"]) for m in metas)
    if demos is not None and not 1 <= int(demos) <= n_available:
        where = sources[0] if len(sources) == 1 else "the smallest of the datasets"
        raise ValueError(f"demos must be in 1 .. {n_available} (the episodes of {where}), got {demos}")
    n_used = int(demos) if demos is not None else n_available
    if curve and any(not 1 <= int(c) <= n_used for c in curve):
        raise ValueError(f"curve must hold numbers of episodes in 1 .. {n_used} (the episodes used), got {list(curve)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    config = dataclasses.replace(config or BCConfig(), seed=int(seed))
    dataset = str(sources[0]) if len(sources) == 1 else [str(d) for d in sources]
    env_kwargs = dict(meta.get("env_kwargs", {}) if env_kwargs is None else env_kwargs)
    env_id = meta.get("env_id")
    env = make_env(env_kwargs, max_episode_steps, env_id=env_id)
    interface = EnvInterface.from_env(env)
    env.close()
    data = load_demonstrations(sources if len(sources) > 1 else sources[0], episodes=demos, fmt=fmt)
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
    policy.info.update(dataset=dataset, dataset_id=meta.get("dataset_id"))
    policy.save(out / "policy.npz")
    write_csv(out / "loss.csv", ["epoch", "loss"], [[i + 1, f"{v:.6g}"] for i, v in enumerate(hist["loss"])])
    summary = {"algo": "bc", "dataset": dataset, "dataset_id": meta.get("dataset_id"),
               "dataset_policy": meta.get("policy", {}).get("name"), "format": fmt, "seed": int(seed),
               "demonstrations": data.n_episodes, "transitions": len(data), "expert_labels": len(data),
               "gain_labels": hist["gain_labels"],
               "config": config.to_dict(), "loss": hist["loss"], "final_loss": hist["loss"][-1],
               "wall_time_s": hist["wall_time_s"], "env_id": env_id or "hsddp_gym/Bounding-v0",
               "env_kwargs": env_kwargs,
               "max_episode_steps": max_episode_steps,
               "files": ["policy.npz", "loss.csv", "summary.json"]}
    if eval_episodes > 0:
        summary["eval"] = eval_brief(evaluate_policy_episodes(policy, eval_episodes, 0, env_kwargs,
                                                               max_episode_steps, env_id=env_id))
    if curve:
        rows, points = [], []
        for n in sorted({int(c) for c in curve}):
            sub = data if n >= data.n_episodes else data.first_episodes(n)
            p, h = (policy, hist) if sub is data else train_bc(sub, config, interface, clock=clock)
            ev = evaluate_policy_episodes(p, max(eval_episodes, 1), 0, env_kwargs, max_episode_steps, env_id=env_id)
            rows.append([n, len(sub), f"{ev['mean_return']:.6g}", f"{ev['std_return']:.6g}", ev["falls"],
                         f"{h['wall_time_s']:.3f}"])
            points.append({"demonstrations": n, "transitions": len(sub), "mean_return": ev["mean_return"],
                           "std_return": ev["std_return"], "falls": ev["falls"]})
        write_csv(out / "curve.csv", ["demonstrations", "transitions", "mean_return", "std_return", "falls",
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
