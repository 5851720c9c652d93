"""Uniform random actions from a seeded generator (the benchmark's lower reference)."""

from __future__ import annotations

import copy

import numpy as np

from hsddp_gym.core.conventions import NU
from hsddp_gym.planners.policies.base import EnvInterface, Policy


class RandomPolicy(Policy):
    """Uniform random actions from a seeded generator (``seed``); ``reset`` keeps the stream going.

    Through `predict` (and the SB3 adapter) env 0 continues this policy's stream from its current
    state -- the same actions as calling the policy -- without advancing it, and env ``k >= 1`` draws from
    the independent stream ``SeedSequence(entropy of seed, spawn_key=(k,))``.
    """

    def __init__(self, interface: EnvInterface = EnvInterface(), seed: int | None = 0) -> None:
        super().__init__(interface)
        self.seed = seed
        self._seed_seq = np.random.SeedSequence(seed)
        self._rng = np.random.default_rng(self._seed_seq)

    def _reset_copy_state(self) -> None:
        self._rng = copy.deepcopy(self._rng)  # its own generator (the parent's stream is not advanced)

    def _spawn_copies(self, n: int) -> list[Policy]:
        copies = []
        for k in range(n):
            twin = self.spawn()
            twin._rng = copy.deepcopy(self._rng) if k == 0 else np.random.default_rng(
                np.random.SeedSequence(self._seed_seq.entropy, spawn_key=(k,)))
            copies.append(twin)
        return copies

    def act(self, obs: np.ndarray) -> np.ndarray:
        return self._rng.uniform(-1.0, 1.0, NU).astype(np.float32)
