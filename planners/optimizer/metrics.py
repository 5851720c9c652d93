"""Numbers that describe a planned hybrid trajectory (the fields of the CLI's ``summary.json``)."""

from __future__ import annotations

import numpy as np

from hsddp_gym.core.conventions import IPITCH, IZ, NQ
from hsddp_gym.planners.optimizer.objective import ConstraintState, Objective
from hsddp_gym.planners.optimizer.problem import HybridProblem


def task_cost(problem: HybridProblem, X, X_pre, U, GRF) -> float:
    """Penalty-free cost (paper eq. 18 with the weights of the problem)."""
    cs = ConstraintState(sigma=0.0, lam=np.zeros(problem.n_phases), use_al=False, use_reb=False,
                         delta_torque=1.0, delta_grf=1.0, eps_torque=0.0, eps_grf=0.0)
    return Objective(problem).evaluate(X, X_pre, U, GRF, cs).task


def trajectory_summary(problem: HybridProblem, X: np.ndarray, X_pre: np.ndarray, U: np.ndarray, GRF: np.ndarray
                       ) -> dict:
    """Metrics of a trajectory on ``problem``'s schedule.

    Returns a dict with ``avg_forward_speed`` [m/s], ``min_body_height`` [m], ``max_abs_pitch`` [rad],
    ``touchdown_foot_heights`` (list, one per touchdown: height of the landing foot at the switch above the
    terrain under it, ``problem.terrain``, the paper's g), ``switching_violation`` (sum g^2),
    ``max_touchdown_error`` (max |g|) [m],
    ``max_abs_torque`` [N m], ``min_normal_grf`` [N],
    ``max_friction_violation`` (max |f_x| - mu f_z over stance knots) [N], ``cost`` (eq. 18).
    """
    robot = problem.dynamics.robot
    terrain = problem.terrain
    if terrain is None or terrain.is_flat:
        g = [float(robot.foot_heights(X_pre[i, :NQ])[foot])
             for i, foot in zip(problem.switch_phase, problem.switch_foot) if foot >= 0]
    else:  # height above the terrain under the foot
        g = [float(p[1] - terrain.height(float(p[0])))
             for p in (robot.foot_positions(X_pre[i, :NQ])[foot]
                       for i, foot in zip(problem.switch_phase, problem.switch_foot) if foot >= 0)]
    mu = problem.constraints.friction
    st = problem.stance
    fz = GRF[:, 1::2][st]
    fric = (np.abs(GRF[:, 0::2]) - mu * GRF[:, 1::2])[st]
    T = problem.schedule.total_time
    return {
        "avg_forward_speed": float((X[-1, 0] - X[0, 0]) / T),
        "min_body_height": float(np.min(X[:, IZ])),
        "max_abs_pitch": float(np.max(np.abs(X[:, IPITCH]))),
        "touchdown_foot_heights": g,
        "switching_violation": float(np.sum(np.square(g))),
        "max_touchdown_error": float(np.max(np.abs(g))) if g else 0.0,
        "max_abs_torque": float(np.max(np.abs(U))),
        "min_normal_grf": float(np.min(fz)) if fz.size else float("nan"),
        "max_friction_violation": float(np.max(fric)) if fric.size else float("nan"),
        "cost": task_cost(problem, X, X_pre, U, GRF),
        "total_time": T,
    }
