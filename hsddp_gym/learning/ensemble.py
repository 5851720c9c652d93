"""A policy ensemble: the mean action of several independently trained learners.

Learners trained on the same recipe with different seeds fall on different episodes (DAgger learners of three
training seeds fall mostly on different evaluation episodes).
Averaging their actions is the classic variance reduction of bagging; for a policy it also smooths the
idiosyncratic corrections each network learned off the expert's states. Each member keeps its own memory (its
gait clock, its latency queue); members trained behind the MPC's perception share one estimator
([`EstimatedStatePolicy`][hsddp_gym.planners.policies.estimated_state.EstimatedStatePolicy]) around the ensemble, as
each of them acted behind one alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from hsddp_gym.core.conventions import NU
from hsddp_gym.planners.policies.base import EnvInterface, Policy


class EnsemblePolicy(Policy):
    """``act(obs) = mean_i members[i].act(obs)`` (float32 (4,)), every member on the same observation.

    Args:
        members: two or more policies (or one: then the ensemble acts exactly as it) for the same env: equal
            ``interface`` (observation layout, target speed, action delay).
    """

    def __init__(self, members: Sequence[Policy]) -> None:
        members = list(members) if isinstance(members, (list, tuple)) else members
        if not isinstance(members, list) or not members:
            raise ValueError(f"members must be a non-empty list of policies, got {members!r}")
        for i, m in enumerate(members):
            if not isinstance(m, Policy):
                raise TypeError(f"members[{i}] must be a Policy, got {type(m).__name__}")
            if m.interface != members[0].interface:
                raise ValueError(f"members[{i}] acts for another env than members[0] (their interfaces differ: "
                                 f"{m.interface} vs {members[0].interface})")
        super().__init__(members[0].interface)
        self.members = members

    def reset(self) -> None:
        for m in self.members:
            m.reset()

    def act(self, obs: np.ndarray) -> np.ndarray:
        total = np.zeros(NU)
        for m in self.members:
            total += np.asarray(m.act(obs), dtype=np.float64)
        return (total / len(self.members)).astype(np.float32)

    def note_sent_action(self, action) -> None:
        """Tell every member that listens (a latency queue) the action actually sent."""
        for m in self.members:
            note = getattr(m, "note_sent_action", None)
            if note is not None:
                note(action)

    def with_interface(self, interface: EnvInterface) -> EnsemblePolicy:
        """The same members acting in another env (each member's ``with_interface``), with fresh memory."""
        return EnsemblePolicy([m.with_interface(interface) for m in self.members])

    def _reset_copy_state(self) -> None:
        self.members = [m.spawn() for m in self.members]


def load_mlp_learner(run_dirs, interface: EnvInterface = EnvInterface()) -> Policy:
    """A trained ``hsddp-gym train --algo bc|dagger`` learner for the env of ``interface``, as it was trained to act:
    one run directory (``DIR/policy.npz``) gives its network, several the mean-action [`EnsemblePolicy`][EnsemblePolicy]
    of theirs. A learner trained behind the MPC's perception (``info["estimator"]``, DAgger's ``--estimator``) acts
    behind one [`EstimatedStatePolicy`][hsddp_gym.planners.policies.estimated_state.EstimatedStatePolicy] (shared by the
    members of an ensemble); mixing such members with plain ones raises ``ValueError``. The one loader of MLP learners
    (``hsddp_gym.workflows.make_policy``, the robustness benchmark and the policy comparison use it).

    Args:
        run_dirs: a run directory (str or Path) or a non-empty list of them.
        interface: the env's interface.
    """
    from hsddp_gym.learning.bc import MLPPolicy

    single = isinstance(run_dirs, (str, Path))
    dirs = [run_dirs] if single else (list(run_dirs) if isinstance(run_dirs, (list, tuple)) else None)
    if not dirs:
        raise ValueError(f"run_dirs must be a run directory or a non-empty list of them, got {run_dirs!r}")
    nets = []
    for i, d in enumerate(dirs):
        path = Path(d) / "policy.npz"
        if not path.exists():
            raise FileNotFoundError(f"run_dirs{'' if single else f'[{i}]'}: no {path}")
        nets.append(MLPPolicy.load(path, interface))
    behind = {bool(n.info.get("estimator")) for n in nets}
    if len(behind) > 1:
        raise ValueError("run_dirs mixes learners trained behind the MPC's perception (--estimator) with plain "
                         "ones; an ensemble acts behind one estimator or none")

    def build(i: EnvInterface) -> Policy:
        members = [n.with_interface(i) for n in nets]
        return members[0] if single else EnsemblePolicy(members)

    if behind.pop():
        from hsddp_gym.planners.policies.estimated_state import EstimatedStatePolicy

        return EstimatedStatePolicy.around(build, interface)
    return nets[0] if single else EnsemblePolicy(nets)


def load_mlp_ensemble(run_dirs: Sequence, interface: EnvInterface = EnvInterface()) -> Policy:
    """The mean-action ensemble of two or more (or one) ``hsddp-gym train --algo bc|dagger`` runs:
    [`load_mlp_learner`][load_mlp_learner] with a list of run directories (a single directory, not in a list, raises
    ``ValueError``).

    Args:
        run_dirs: one or more run directories (str or Path), in a list or tuple.
        interface: the env's interface.
    """
    if isinstance(run_dirs, (str, Path)) or not list(run_dirs):
        raise ValueError(f"run_dirs must be a non-empty list of run directories, got {run_dirs!r}")
    return load_mlp_learner(list(run_dirs), interface)
