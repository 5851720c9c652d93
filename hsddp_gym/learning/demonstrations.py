"""Demonstrations (observation, label) pairs loaded from a Minari dataset or a dataset's episodes.npz."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np


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
        source: a ``MinariDataset``, a :class:`hsddp_gym.datasets.storage.FlatDataset`, a dataset directory written
            by :func:`hsddp_gym.datasets.generation.generate_dataset`, or an ``episodes.npz`` file.
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
    available = source.n_episodes if isinstance(source, datasets.FlatDataset) else source.total_episodes
    if episodes is not None and not 1 <= int(episodes) <= available:
        raise ValueError(f"episodes must be in 1 .. {available} (the dataset's episodes), got {episodes}")
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
