"""Local labels from the expert's feedback gains: more supervision per demonstration.

A planner-based expert acts with a local feedback law ``u = u_bar + K (x - x_bar)`` (the HS-DDP plan's gains,
recorded in a dataset with ``hsddp-gym dataset --gains``). Next to every demonstrated pair (observation of
state ``x``, action) the law also gives the expert's action at nearby states, ``u(x + dx) = u(x) + K dx`` (up to
the clip to the torque limit), without running the expert again: DART-style noise injection (Laskey et al.
2017) done offline, or a finite-difference version of a loss on the policy's Jacobian against ``K``
(Sobolev training, Czarnecki et al. 2017). [`gain_augmented_pairs`][gain_augmented_pairs] draws ``copies`` perturbed
copies of every pair whose action came from the law (``expert_tracking``), with state offsets
``dx ~ N(0, diag(position_std^2, velocity_std^2))`` on the observed positions and velocities (the trunk ``x``
is never perturbed: ``K`` has no x column), and labels them with the law. Contact flags, the gait phase and
the gait-clock features of a copy are those of its pair (a small state offset does not change the contact
mode the law was computed for).
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ, NX
from hsddp_gym.core.observation import DEFAULT_LAYOUT, ObservationLayout
from hsddp_gym.learning.demonstrations import FeedbackLaw
from hsddp_gym.util.validation import check_positive


def gain_augmented_pairs(inputs: np.ndarray, feedback: FeedbackLaw, copies: int, position_std: float = 0.01,
                         velocity_std: float = 0.1, seed: int = 0, layout: ObservationLayout = DEFAULT_LAYOUT
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Perturbed inputs and their feedback-law labels.

    Args:
        inputs: ``(N, d)`` the learner's inputs of the demonstrations (observation first, ``layout``; extra
            features after it are copied unchanged).
        feedback: the expert's law at the same N pairs.
        copies: perturbed copies per tracked pair (>= 1).
        position_std: [m or rad] of the offsets of the observed positions (>= 0); velocity_std: [m/s or
            rad/s] of the velocities (>= 0).
        seed: seed of the offsets.
    Returns:
        ``(inputs (M, d), labels (M, 4))`` with ``M = copies * (number of tracked pairs)``; labels are
        ``clip(u_bar + K (x + dx - x_bar), -1, 1)``.
    """
    inputs = np.asarray(inputs, dtype=np.float64)
    if inputs.ndim != 2 or inputs.shape[1] < layout.size:
        raise ValueError(f"inputs must have shape (N, >= {layout.size}), got {inputs.shape}")
    if len(feedback.state) != len(inputs):
        raise ValueError(f"feedback has {len(feedback.state)} rows, inputs {len(inputs)}")
    copies = int(copies)
    if copies < 1:
        raise ValueError(f"copies must be >= 1, got {copies}")
    position_std = check_positive(position_std, "position_std", allow_zero=True)
    velocity_std = check_positive(velocity_std, "velocity_std", allow_zero=True)
    rows = np.repeat(np.flatnonzero(feedback.tracking), copies)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x6A1]))
    skip = layout.skipped_qpos
    dx = np.zeros((len(rows), NX))
    dx[:, max(skip, 1):NQ] = position_std * rng.standard_normal((len(rows), NQ - max(skip, 1)))
    dx[:, NQ:] = velocity_std * rng.standard_normal((len(rows), NX - NQ))
    out = inputs[rows].copy()
    out[:, layout.qpos] += dx[:, skip:NQ]
    out[:, layout.qvel] += dx[:, NQ:]
    return out, feedback.action(dx, rows)
