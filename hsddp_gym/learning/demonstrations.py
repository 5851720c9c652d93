"""Demonstrations (observation, label) pairs loaded from a Minari dataset or a dataset's episodes.npz."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

# ================================================================================================ data
FEEDBACK_KEYS = ("qpos", "qvel", "expert_state_nominal", "expert_action_nominal", "expert_feedback_gain",
                 "expert_tracking")
"""The ``infos`` keys [`FeedbackLaw`][FeedbackLaw] is read from (a dataset generated with gains, ``--gains``)."""


@dataclasses.dataclass
class FeedbackLaw:
    """The expert's local feedback law at every demonstration: ``u = u_bar + K (x - x_bar)`` in normalized action
    units (torques / torque limit), from a dataset recorded with ``include_gains`` (``hsddp-gym dataset --gains``).

    Attributes:
        state: ``x (N, 14)`` the true state of each observation (``infos`` qpos, qvel).
        nominal_state: ``x_bar (N, 14)``; nominal_action: ``u_bar (N, 4)`` (normalized, not clipped);
        gain: ``K (N, 4, 14)`` (normalized; column 0, the trunk x, is zero);
        tracking: ``(N,)`` bool, True where the action came from this law (elsewhere the law is stale and
            must not be used: the MPC was between plans, or a fallback acted).
    """

    state: np.ndarray
    nominal_state: np.ndarray
    nominal_action: np.ndarray
    gain: np.ndarray
    tracking: np.ndarray

    def action(self, dx: np.ndarray | None = None, rows=None) -> np.ndarray:
        """``clip(u_bar + K (x + dx - x_bar), -1, 1)`` ``(n, 4)`` at the rows ``rows`` (default all) for state
        offsets ``dx (n, 14)`` (default 0)."""
        rows = slice(None) if rows is None else rows
        x = self.state[rows] if dx is None else self.state[rows] + dx
        u = self.nominal_action[rows] + np.einsum("nux,nx->nu", self.gain[rows], x - self.nominal_state[rows])
        return np.clip(u, -1.0, 1.0)

    def take(self, keep) -> FeedbackLaw:
        return FeedbackLaw(*(getattr(self, f.name)[keep] for f in dataclasses.fields(self)))

    @staticmethod
    def concat(a: FeedbackLaw, b: FeedbackLaw) -> FeedbackLaw:
        return FeedbackLaw(*(np.concatenate([getattr(a, f.name), getattr(b, f.name)])
                             for f in dataclasses.fields(FeedbackLaw)))

    @classmethod
    def from_infos(cls, infos: dict, rows: slice) -> FeedbackLaw:
        """From one episode's ``infos`` (arrays of T + 1 rows), the rows ``rows`` (the observations acted on)."""
        state = np.concatenate([np.asarray(infos["qpos"]), np.asarray(infos["qvel"])], axis=1)[rows]
        return cls(state.astype(np.float64), np.asarray(infos["expert_state_nominal"], dtype=np.float64)[rows],
                   np.asarray(infos["expert_action_nominal"], dtype=np.float64)[rows],
                   np.asarray(infos["expert_feedback_gain"], dtype=np.float64)[rows],
                   np.asarray(infos["expert_tracking"], dtype=bool)[rows])


@dataclasses.dataclass
class Demonstrations:
    """Labelled observations: ``obs (N, d)`` float32, ``actions (N, 4)`` float32, ``episode (N,)`` the
    episode each pair comes from (0-based, in dataset order), ``feedback`` the expert's local feedback law
    at each pair ([`FeedbackLaw`][FeedbackLaw]; None when the dataset has no gains), ``target_speed (N,)`` the env's
    target speed [m/s] of each pair's episode (from the dataset's metadata; None when unknown),
    ``sent_actions (N, 4)`` the action sent to the env at each pair (the label plus DART noise, or the
    learner's in a DAgger rollout; None when unknown) and ``action_delay (N,)`` the actuation delay [control steps]
    of each pair's episode ([`ActionDelay`][hsddp_gym.envs.perturbations.wrappers.ActionDelay]; None when unknown). The
    last two rebuild the learner's latency queue
    ([`hsddp_gym.learning.features.action_queue_features`][hsddp_gym.learning.features.action_queue_features])."""

    obs: np.ndarray
    actions: np.ndarray
    episode: np.ndarray
    feedback: FeedbackLaw | None = None
    target_speed: np.ndarray | None = None
    sent_actions: np.ndarray | None = None
    action_delay: np.ndarray | None = None

    @property
    def n_episodes(self) -> int:
        return int(self.episode.max() + 1) if len(self.episode) else 0

    def __len__(self) -> int:
        return int(len(self.obs))

    def first_episodes(self, n: int) -> Demonstrations:
        keep = self.episode < int(n)
        fb = self.feedback.take(keep) if self.feedback is not None else None
        return Demonstrations(self.obs[keep], self.actions[keep], self.episode[keep], fb,
                              *(None if a is None else a[keep] for a in self._per_pair()))

    def _per_pair(self) -> tuple:
        """The optional per-pair arrays, in field order after ``feedback``."""
        return self.target_speed, self.sent_actions, self.action_delay

    def concat(self, other: Demonstrations) -> Demonstrations:
        """Both sets of pairs (``other``'s episodes renumbered after these); the feedback laws, target speeds,
        sent actions and delays are kept only when both have them."""
        offset = self.n_episodes
        fb = (FeedbackLaw.concat(self.feedback, other.feedback)
              if self.feedback is not None and other.feedback is not None else None)
        extra = [np.concatenate([a, b]) if a is not None and b is not None else None
                 for a, b in zip(self._per_pair(), other._per_pair())]
        return Demonstrations(np.concatenate([self.obs, other.obs]), np.concatenate([self.actions, other.actions]),
                              np.concatenate([self.episode, other.episode + offset]), fb, *extra)


def load_demonstrations(source, episodes: int | None = None, fmt: str = "minari") -> Demonstrations:
    """(observation t, action t) pairs from a dataset.

    The action is the label: ``infos["expert_action"]`` when the dataset has it (datasets recorded with
    DART action noise, whose ``actions`` are the noisy executed ones), the recorded action otherwise.

    Args:
        source: a ``MinariDataset``, a
            [`hsddp_gym.datasets.storage.FlatDataset`][hsddp_gym.datasets.storage.FlatDataset], a dataset directory
            written by
            [`hsddp_gym.datasets.generation.generate_dataset`][hsddp_gym.datasets.generation.generate_dataset], an
            ``episodes.npz`` file, or a list of these (their pairs concatenated, e.g. demonstrations at several target
            speeds).
        episodes: use only the first ``episodes`` episodes (None: all; of each source for a list).
        fmt: for a directory, read the Minari dataset (``"minari"``, via ``minari.load_dataset``) or
            ``episodes.npz`` (``"npz"``).
    """
    from hsddp_gym import datasets

    if fmt not in ("minari", "npz"):
        raise ValueError(f"fmt must be 'minari' or 'npz', got {fmt!r}")
    if isinstance(source, (list, tuple)):
        if not source:
            raise ValueError("source must not be an empty list")
        parts = [load_demonstrations(s, episodes, fmt) for s in source]
        out = parts[0]
        for part in parts[1:]:
            out = out.concat(part)
        return out
    speed = delays = None
    if isinstance(source, (str, Path)):
        p = Path(source)
        meta_file = (p.parent if p.is_file() else p) / "metadata.json"
        if meta_file.exists():
            metadata = datasets.read_metadata(meta_file.parent)
            speed, delays = _target_speeds(metadata), _action_delays(metadata)
        if p.is_file():
            source = datasets.load_npz(p)
        elif fmt == "npz":
            source = datasets.load_npz(p)
        else:
            source = datasets.load_minari(p)
    obs, acts, sent, ep, laws = [], [], [], [], []
    available = source.n_episodes if isinstance(source, datasets.FlatDataset) else source.total_episodes
    if episodes is not None and not 1 <= int(episodes) <= available:
        raise ValueError(f"episodes must be in 1 .. {available} (the dataset's episodes), got {episodes}")
    if isinstance(source, datasets.FlatDataset):
        if source.metadata:
            speed = _target_speeds(source.metadata) if speed is None else speed
            delays = _action_delays(source.metadata) if delays is None else delays
        n = source.n_episodes if episodes is None else min(int(episodes), source.n_episodes)
        for i in range(n):
            e = source.episode(i)
            obs.append(e["observations"][:-1])
            acts.append(e["infos"]["expert_action"][:-1] if "expert_action" in e["infos"] else e["actions"])
            sent.append(e["actions"])
            ep.append(np.full(len(e["actions"]), i))
            if all(k in e["infos"] for k in FEEDBACK_KEYS):
                laws.append(FeedbackLaw.from_infos(e["infos"], slice(0, len(e["actions"]))))
    else:  # a MinariDataset
        n = source.total_episodes if episodes is None else min(int(episodes), source.total_episodes)
        for i, e in enumerate(source.iterate_episodes(episode_indices=list(range(n)))):
            obs.append(np.asarray(e.observations)[:-1])
            infos = e.infos if isinstance(e.infos, dict) else {}
            acts.append(np.asarray(infos["expert_action"])[:-1] if "expert_action" in infos else
                        np.asarray(e.actions))
            sent.append(np.asarray(e.actions))
            ep.append(np.full(len(e.actions), i))
            if all(k in infos for k in FEEDBACK_KEYS):
                laws.append(FeedbackLaw.from_infos(infos, slice(0, len(e.actions))))
    if not obs:
        raise ValueError("the dataset has no episodes")
    feedback = None
    if laws and len(laws) == len(obs):
        feedback = laws[0]
        for law in laws[1:]:
            feedback = FeedbackLaw.concat(feedback, law)
    if isinstance(speed, float):
        speed = [speed] * len(obs)
    if speed is not None:
        if len(speed) < len(obs):
            raise ValueError(f"the dataset's metadata give {len(speed)} episode target speeds for {len(obs)} "
                             "episodes")
        speed = np.concatenate([np.full(len(o), speed[i]) for i, o in enumerate(obs)])
    if isinstance(delays, int):
        delays = [delays] * len(obs)
    if delays is not None:
        if len(delays) < len(obs):
            raise ValueError(f"the dataset's metadata give {len(delays)} episode conditions for {len(obs)} episodes")
        delays = np.concatenate([np.full(len(o), delays[i], dtype=np.int64) for i, o in enumerate(obs)])
    return Demonstrations(np.concatenate(obs).astype(np.float32), np.concatenate(acts).astype(np.float32),
                          np.concatenate(ep).astype(np.int64), feedback, speed,
                          np.concatenate(sent).astype(np.float32), delays)


def _action_delays(metadata: dict) -> list[int] | int | None:
    """The actuation delay [control steps] of each episode of a dataset: from ``episode_conditions`` and the
    recorded condition definitions (datasets recorded under named conditions), else 0 for all of them (one int:
    a plain dataset, whose metadata record its ``env_kwargs``); None when the metadata say nothing."""
    if not isinstance(metadata, dict):
        return None
    names = metadata.get("episode_conditions")
    if names is not None:
        from hsddp_gym.envs.perturbations.conditions import get_condition

        definitions = (metadata.get("conditions") or {}).get("definitions") or {}
        return [int(definitions[c]["action_delay"]) if c in definitions else int(get_condition(c).action_delay)
                for c in names]
    return 0 if "env_kwargs" in metadata else None


def _target_speeds(metadata: dict) -> list[float] | float | None:
    """The target speed [m/s] of each episode of a dataset: ``episode_target_speeds`` (datasets recorded under
    named conditions, ``hsddp-gym dataset --condition``), else that of its env for all of them (one float:
    ``env_kwargs``, else the env's default); None when the metadata say nothing."""
    if not isinstance(metadata, dict):
        return None
    if metadata.get("episode_target_speeds") is not None:
        return [float(v) for v in metadata["episode_target_speeds"]]
    if "env_kwargs" not in metadata:
        return None
    from hsddp_gym.envs.bounding import DEFAULT_TARGET_SPEED

    return float(metadata["env_kwargs"].get("target_speed", DEFAULT_TARGET_SPEED))
