"""The warm start of a re-plan: the previous plan shifted onto the new problem, phase by phase."""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import NU, NX
from hsddp_gym.planners.optimizer.problem import HybridProblem
from hsddp_gym.planners.optimizer.solution import Solution
from hsddp_gym.planners.policies.tracking import PlanTracker


def shift_plan(problem: HybridProblem, x: np.ndarray, tracker: PlanTracker, previous: Solution,
               multipliers: np.ndarray | None, previous_problem: HybridProblem | None = None):
    """The previous plan ``previous`` (whose cursor is ``tracker``'s, now) shifted onto ``problem`` from the state
    ``x`` (14,): ``(U (N, 4), X (N+1, 14), K (N, 4, 14), lam (m,))``, or None when it does not cover the problem.

    The previous plan's phase that matches the problem's first is the cursor's, the one before it (the contact switch
    is late) or the one after it (early); from there each phase of the same mode is sampled at the problem's knot
    times (controls, states and gains for a feedback first rollout, the AL ``multipliers`` phase by phase, zeros
    without them). A phase beyond the previous plan copies the same mode one cycle (four phases) earlier. The states'
    trunk x is moved to ``x``'s. ``multipliers`` has one value per switching-constraint row of ``previous_problem``
    (``HybridProblem.switch_phase``, ``switch_foot``; None: one per phase), and the returned ``lam`` one per row of
    ``problem``: a row takes the multiplier of the row of the same landing foot in its phase's source phase."""
    tr, prev = tracker, previous
    N = problem.n_knots
    U = np.zeros((N, NU))
    X = np.zeros((N + 1, NX))
    K = np.zeros((N, NU, NX))
    src = np.full(problem.n_phases, -1)  # per phase of the problem: the previous plan's phase it is sampled from
    have = np.zeros(N, dtype=bool)
    prev_len = np.diff(prev.phase_start)
    first = problem.schedule.modes[0]
    if tr.modes[tr.phase] == first:
        p0, offset0 = tr.phase, tr.local_time
    elif tr.phase > 0 and tr.modes[tr.phase - 1] == first:
        p0 = tr.phase - 1
        offset0 = (prev_len[p0] - 1) * tr.phase_dt[p0]
    elif tr.phase + 1 < tr.n_phases and tr.modes[tr.phase + 1] == first:
        p0, offset0 = tr.phase + 1, 0.0
    else:
        return None
    for j in range(problem.n_phases):
        a, b = problem.phase_start[j], problem.phase_start[j + 1]
        p = p0 + j
        local = np.arange(b - a)  # knot index within the phase
        if p < tr.n_phases and tr.modes[p] == problem.schedule.modes[j]:
            src[j] = p
            offset = offset0 if j == 0 else 0.0
            t_local = offset + local * problem.phase_dt[j]
            kp = prev.phase_start[p] + np.minimum((t_local / tr.phase_dt[p] + 1e-9).astype(np.int64),
                                                  prev_len[p] - 1)
            U[a:b], X[a:b], K[a:b] = prev.U[kp], prev.X[kp], prev.K[kp]
            have[a:b] = True
        elif j >= 4:
            src[j] = src[j - 4]
            s0 = problem.phase_start[j - 4]
            ks = s0 + np.minimum(local, problem.phase_start[j - 3] - s0 - 1)  # all before a
            U[a:b], X[a:b], K[a:b] = U[ks], X[ks], K[ks]
            have[a:b] = have[ks]
    if not have.all():
        return None
    lam = np.zeros(problem.n_switching)
    if multipliers is not None:
        rows = (np.arange(tr.n_phases), np.full(tr.n_phases, -2)) if previous_problem is None else \
            (previous_problem.switch_phase, previous_problem.switch_foot)
        value = {}
        for i, (p, f) in enumerate(zip(*rows)):
            value[int(p), int(f)] = multipliers[i]
            value.setdefault((int(p), -2), multipliers[i])  # a phase's first row, for a row of another foot
        for r, (j, f) in enumerate(zip(problem.switch_phase, problem.switch_foot)):
            key = (int(src[j]), int(f)) if (int(src[j]), int(f)) in value else (int(src[j]), -2)
            lam[r] = value.get(key, 0.0)
    X[N] = X[N - 1]
    X[:, 0] += x[0] - X[0, 0]
    return U, X, K, lam
