"""Rollout of the time-switched hybrid system (paper eq. 14): discrete steps inside each phase and the
reset map at every switch."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from hsddp_gym.core.conventions import NGRF, NU, NX, Mode
from hsddp_gym.core.dynamics import HybridDynamics
from hsddp_gym.core.schedule import ModeSchedule
from hsddp_gym.util.validation import check_array, check_in_range, check_vector

Controller = Callable[[np.ndarray, Mode, int, int], np.ndarray]
"""``controller(x (14,), mode, phase, k) -> u (4,)``: a feedback law used by [`rollout`][rollout]."""


@dataclasses.dataclass
class Trajectory:
    """A hybrid trajectory over ``N`` steps and ``n`` phases.

    Attributes:
        X: ``(N+1, 14)`` states; ``X[k]`` is the state at the start of step ``k`` (after the reset map at
            a phase start), ``X[N]`` the final state (before any final reset).
        X_pre: ``(n, 14)`` the state at the end of each phase, before its reset map (``x^-``).
        U: ``(N, 4)`` controls. GRF: ``(N, 4)`` ground forces during each step. modes: ``(N,)`` ints.
        phase_of_knot: ``(N,)`` phase index of each step. phase_start: ``(n+1,)`` first step of each phase
            (last entry ``N``). impulses: ``(n, 4)`` ground impulse at the end of each phase [N s].
        dt: step [s]. schedule: the mode schedule.
    """

    X: np.ndarray
    X_pre: np.ndarray
    U: np.ndarray
    GRF: np.ndarray
    modes: np.ndarray
    phase_of_knot: np.ndarray
    phase_start: np.ndarray
    impulses: np.ndarray
    dt: float
    schedule: ModeSchedule

    @property
    def times(self) -> np.ndarray:
        """``(N+1,)`` time of each state [s]."""
        return self.dt * np.arange(self.X.shape[0])

    @property
    def is_finite(self) -> bool:
        return bool(np.all(np.isfinite(self.X)) and np.all(np.isfinite(self.U)))


def knot_layout(schedule: ModeSchedule, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(modes (N,), phase_of_knot (N,), phase_start (n+1,))`` for a schedule and step."""
    steps = schedule.knots(dt)
    phase_start = np.concatenate([[0], np.cumsum(steps)]).astype(np.int64)
    phase_of_knot = np.repeat(np.arange(len(schedule)), steps)
    modes = np.array([int(schedule.modes[i]) for i in phase_of_knot], dtype=np.int64)
    return modes, phase_of_knot, phase_start


def rollout(dynamics: HybridDynamics, schedule: ModeSchedule, x0: np.ndarray, controls=None,
            controller: Controller | None = None, restitution: float = 0.0, apply_final_reset: bool = False
            ) -> Trajectory:
    """Roll out ``x0`` through the schedule under open-loop ``controls (N, 4)`` or a ``controller``.

    Args:
        dynamics: the hybrid dynamics (its ``dt`` is the step).
        schedule: modes and durations; phase ``i`` takes ``round(T_i / dt)`` steps.
        x0: initial state (14,).
        controls: ``(N, 4)`` open-loop torques (exclusive with ``controller``).
        controller: ``controller(x, mode, phase, k) -> u (4,)``.
        restitution: coefficient of restitution at touchdowns (paper: 0).
        apply_final_reset: also apply the reset map at the end of the last phase to ``X[N]``.
    Returns:
        A [`Trajectory`][Trajectory]. States that become non-finite stop the rollout early with NaN after them.
    """
    if not isinstance(dynamics, HybridDynamics):
        raise TypeError(f"dynamics must be a HybridDynamics, got {type(dynamics).__name__}")
    if not isinstance(schedule, ModeSchedule):
        raise TypeError(f"schedule must be a ModeSchedule, got {type(schedule).__name__}")
    x0 = check_vector(x0, NX, "x0")
    e = check_in_range(restitution, 0.0, 1.0, "restitution")
    modes, phase_of_knot, phase_start = knot_layout(schedule, dynamics.dt)
    n_steps = modes.shape[0]
    if (controls is None) == (controller is None):
        raise ValueError("pass exactly one of controls (N, 4) or controller")
    if controls is not None:
        controls = check_array(controls, (n_steps, NU), "controls")
    n_phases = len(schedule)
    X = np.full((n_steps + 1, NX), np.nan)
    X_pre = np.full((n_phases, NX), np.nan)
    U = np.full((n_steps, NU), np.nan)
    GRF = np.full((n_steps, NGRF), np.nan)
    impulses = np.zeros((n_phases, NGRF))
    X[0] = x0
    x = x0.copy()
    for i in range(n_phases):
        mode = schedule.modes[i]
        for k in range(phase_start[i], phase_start[i + 1]):
            u = controls[k] if controls is not None else np.asarray(controller(x, mode, i, k), dtype=np.float64)
            if u.shape != (NU,):
                raise ValueError(f"controller must return shape ({NU},), got {u.shape}")
            U[k] = u
            dynamics.simulate_step(x, u, int(mode), X[k + 1], GRF[k])
            x = X[k + 1]
            if not np.all(np.isfinite(x)):
                return Trajectory(X, X_pre, U, GRF, modes, phase_of_knot, phase_start, impulses, dynamics.dt,
                                  schedule)
        X_pre[i] = x
        if i + 1 < n_phases or apply_final_reset:
            x_plus, impulses[i] = dynamics._reset(x, schedule.next_mode(i), e)
            X[phase_start[i + 1]] = x_plus
            x = X[phase_start[i + 1]]
    return Trajectory(X, X_pre, U, GRF, modes, phase_of_knot, phase_start, impulses, dynamics.dt, schedule)
