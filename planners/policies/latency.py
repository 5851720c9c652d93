"""Online estimation of an action delay from the robot's response to the policy's own actions.

A policy that compensates a latency ([`MPCPolicy`][hsddp_gym.planners.policies.mpc.agent.MPCPolicy], behind
[`ActionDelay`][hsddp_gym.envs.perturbations.wrappers.ActionDelay]) is told the delay by the env
(``action_delay_steps``). When the delay it is told is wrong by a control step, its state filter propagates the estimate
with the wrong torque and its prediction over the delay uses the wrong actions: the closed loop is one step out of phase
and falls.

[`DelayEstimator`][DelayEstimator] tells the delays apart by what they predict. Every control step it predicts the new
state from the previous estimate once per candidate delay ``d`` (the announced one and its neighbours), holding the
torque of the action returned ``d + 1`` steps ago, and compares the predicted velocities with the measured ones. Each
step's squared errors are normalized to shares (they sum to 1 over the candidates, so a push or an impact that no
candidate predicts cannot outweigh the steps before it) and summed with exponential forgetting; the estimate moves
to a candidate whose score is below the current one's by more than a margin (hysteresis), so that steps whose
actions do not tell the delays apart (a constant torque) leave it where it is.
"""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NQ, NU, NX
from hsddp_gym.planners.policies.estimation import ContactModelPredictor, check_ground
from hsddp_gym.util.validation import check_in_range, check_int, check_positive, check_vector


class DelayEstimator:
    """The action delay [control steps] most consistent with the measured response (see the module docstring).

    Args:
        predictor: the model that predicts one control period under a torque.
        announced: the delay the env announces (the first estimate), >= 0.
        search: candidates are ``announced - search .. announced + search`` (those >= 0).
        forgetting: the factor the scores are multiplied by every step, in (0, 1) (0.9: about the last 10 steps,
            50 ms at 200 Hz, count).
        margin: how far below the current candidate's score another's must fall for the estimate to move to it
            (> 0; scores are sums of shares, at most ``1 / (1 - forgetting)``).
        velocity_scale: the weights of the velocity errors (7,) [m/s, rad/s] (each error is divided by its
            scale before squaring; default 1 for the trunk's velocities and 10 for the joints').

    Attributes:
        candidates: the candidate delays (ascending). delay: the current estimate. scores: ``(len(candidates),)``.
        switches: how many times the estimate has moved since [`reset`][reset].
    """

    def __init__(self, predictor: ContactModelPredictor, announced: int, search: int = 1, forgetting: float = 0.9,
                 margin: float = 2.0, velocity_scale=None) -> None:
        if not isinstance(predictor, ContactModelPredictor):
            raise TypeError(f"predictor must be a ContactModelPredictor, got {type(predictor).__name__}")
        self.predictor = predictor
        self.announced = check_int(announced, "announced", minimum=0)
        search = check_int(search, "search", minimum=0)
        self.candidates = tuple(range(max(0, self.announced - search), self.announced + search + 1))
        self.forgetting = check_in_range(forgetting, 0.0, 1.0, "forgetting")
        if not 0.0 < self.forgetting < 1.0:
            raise ValueError(f"forgetting must be in (0, 1), got {forgetting!r}")
        self.margin = check_positive(margin, "margin")
        scale = np.array([1.0, 1.0, 1.0, 10.0, 10.0, 10.0, 10.0]) if velocity_scale is None \
            else check_vector(velocity_scale, NX - NQ, "velocity_scale")
        if not np.all(scale > 0.0):
            raise ValueError(f"velocity_scale must be > 0, got {velocity_scale!r}")
        self._weight = 1.0 / (scale * scale)
        self.reset()

    @property
    def history(self) -> int:
        """How many past actions [`update`][update] needs: the largest candidate + 1."""
        return self.candidates[-1] + 1

    def reset(self) -> None:
        """Back to the announced delay, scores cleared."""
        self.delay = self.announced
        self.scores = np.zeros(len(self.candidates))
        self.switches = 0

    def update(self, x_prev: np.ndarray, y: np.ndarray, torques, ground: float = 0.0) -> int:
        """Score the candidates on one control period and return the (possibly moved) estimate.

        Args:
            x_prev: the state estimate (14,) at the start of the period.
            y: the state measured (14,) at its end.
            torques: ``(history, 4)`` [N m] the torques of the last [`history`][history] actions returned, oldest first
                (row ``-1 - d`` is what a delay of ``d`` steps executed over the period).
            ground: the height [m] of the model's ground ([`ContactModelPredictor.step`][ContactModelPredictor.step]).
        Returns:
            The delay estimate [control steps].
        """
        ground = check_ground(ground)
        torques = np.asarray(torques, dtype=np.float64)
        if torques.shape != (self.history, NU):
            raise ValueError(f"torques must have shape ({self.history}, {NU}), got {torques.shape}")
        errors = np.empty(len(self.candidates))
        try:
            for i, d in enumerate(self.candidates):
                xp, _ = self.predictor.step(x_prev, torques[-1 - d], ground=ground)
                e = y[NQ:] - xp[NQ:]
                errors[i] = float(np.dot(self._weight, e * e))
        except (ArithmeticError, ValueError, RuntimeError):
            return self.delay
        total = float(errors.sum())
        if not np.isfinite(total):
            return self.delay
        self.scores *= self.forgetting
        if total > 0.0:
            self.scores += errors / total
        current = self.candidates.index(self.delay)
        best = int(np.argmin(self.scores))
        if self.scores[best] < self.scores[current] - self.margin:
            self.delay = self.candidates[best]
            self.switches += 1
        return self.delay
