"""A prototype of re-planning the backflip online (the "What did not work" page's entry; not a policy of the package).

Every ``--period`` of env time HS-DDP re-plans what remains of the backflip's phases (push, back stance, flight,
landing; ``hsddp_gym.planners.motions.problems.backflip_problem``) from the observed state on a ``--planner-dt``
grid: ``--iterations`` DDP iterations warm-started from the previous plan shifted to the new state
(``hsddp_gym.planners.policies.mpc.warm_start.shift_plan``), ``--warmup-iterations`` from the expert's offline plan at
the start; the plan's law ``u = U_k + K_k (x - X_k)`` acts in between, its cursor moved over touchdowns by the feet
seen clear of the ground (``FootClearance``); after the last phase the landing posture is held. ``--window N``
re-plans only the current phase and the next ``N - 1`` (each phase's end reference its terminal cost); ``--window
0`` the whole remaining motion. Prints, per episode of ``hsddp_gym/Backflip-v0``, the fall, the success and the
re-plans.

    python experiments/backflip_replanning.py --episodes 3 --first-seed 56900 --window 0
    python experiments/backflip_replanning.py --episodes 3 --first-seed 56900 --window 2
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time

import numpy as np


def make_policy(interface, planner_dt: float, period: float, iterations: int, warmup_iterations: int, window: int):
    """The prototype as a [`Policy`][hsddp_gym.planners.policies.base.Policy] for ``interface``."""
    from hsddp_gym.core.conventions import NQ, Mode
    from hsddp_gym.core.dynamics import HybridDynamics
    from hsddp_gym.planners.motions.planning import plan_backflip_held
    from hsddp_gym.planners.motions.problems import (
        BACKFLIP_FOOT_CLEARANCE,
        BACKFLIP_KNEE_CLEARANCE,
        JOINT_LIMITS,
        backflip_problem,
        motion_problem,
    )
    from hsddp_gym.planners.optimizer.hsddp import HSDDP
    from hsddp_gym.planners.optimizer.solution import SolverOptions
    from hsddp_gym.planners.policies.base import Policy
    from hsddp_gym.planners.policies.mpc.planner import REB_DELTA, REB_EPS, SIGMA_MAX
    from hsddp_gym.planners.policies.mpc.warm_start import shift_plan
    from hsddp_gym.planners.policies.touchdown import FootClearance
    from hsddp_gym.planners.policies.tracking import PlanTracker
    from hsddp_gym.planners.policies.tracking_policy import HOLD_KD, HOLD_KP

    offline = plan_backflip_held(max(1, round(interface.control_dt / 1e-3)))
    phases = backflip_problem()[1]
    dynamics = HybridDynamics(dt=planner_dt, integrator="semi_implicit")

    class BackflipReplanning(Policy):
        def reset(self) -> None:
            self.solver, self.cs, self.plan, self.multipliers = HSDDP(SolverOptions()), None, None, None
            self.since, self.done = np.inf, False
            self.stats = {"replans": 0, "planner_failures": 0, "solve_ms": []}

        def where(self) -> tuple[int, float]:
            """(the phase of the motion, the time spent in it)."""
            if self.plan is None:
                return 0, 0.0
            tracker, k0, e0 = self.plan
            return k0 + tracker.phase, tracker.local_time + (e0 if tracker.phase == 0 else 0.0)

        def problem(self, x, k: int, e: float):
            chosen = phases[k:] if window == 0 else phases[k:k + window]
            grid = [max(1, round(max(chosen[0].duration - e, 0.01) / planner_dt)) * planner_dt]
            grid += [max(1, round(p.duration / planner_dt)) * planner_dt for p in chosen[1:]]
            chosen = [dataclasses.replace(p, duration=d) for p, d in zip(chosen, grid)]
            after = phases[k + len(chosen)].mode if k + len(chosen) < len(phases) else Mode.DOUBLE_STANCE
            return motion_problem(chosen, x, after, dynamics, joint_limits=JOINT_LIMITS,
                                  knee_clearance=BACKFLIP_KNEE_CLEARANCE, swing_foot_clearance=BACKFLIP_FOOT_CLEARANCE)

        def offline_start(self, problem, k: int, e: float):
            """``(U, X, K)`` of the offline plan at the problem's knot times."""
            times = []
            for j in range(problem.n_phases):
                base = float(np.sum(offline.schedule.durations[:k + j])) + (e if j == 0 else 0.0)
                n = problem.phase_start[j + 1] - problem.phase_start[j]
                times += [base + i * problem.phase_dt[j] for i in range(n)]
            idx = np.minimum((np.array(times) / 1e-3 + 1e-9).astype(int), len(offline.U) - 1)
            return offline.U[idx], np.vstack([offline.X[idx], offline.X[idx[-1:]]]), offline.K[idx]

        def replan(self, x) -> None:
            k, e = self.where()
            if k >= len(phases):
                return
            t0 = time.perf_counter()
            problem = self.problem(x, k, e)
            shifted = None
            if self.plan is not None:
                try:
                    shifted = shift_plan(problem, x, self.plan[0], self.solution, self.multipliers)
                except ValueError:
                    shifted = None
            cs = None
            if shifted is None:
                (U, X, K), n = self.offline_start(problem, k, e), warmup_iterations if self.plan is None else iterations
            else:
                U, X, K, lam = shifted
                n = iterations
                if self.cs is not None:
                    cs = self.cs.copy()
                    cs.lam, cs.sigma = lam, min(cs.sigma, SIGMA_MAX)
                    cs.delta_torque = cs.delta_grf = REB_DELTA
                    cs.eps_torque = cs.eps_grf = REB_EPS
            self.solver.options = SolverOptions(max_ddp_iterations=n, max_total_ddp_iterations=n,
                                                max_al_iterations=4 if self.plan is None else 2)
            X = X.copy()
            X[:, 0] += x[0] - X[0, 0]
            sol = None
            for X_init, K_init in ((X, K), (None, None)):
                try:
                    sol = self.solver.solve(problem, np.clip(U, -interface.torque_limit, interface.torque_limit),
                                            X_init=X_init, K_init=K_init, constraint_state=cs)
                    break
                except ValueError:
                    continue
            if sol is None or not np.all(np.isfinite(sol.X)):
                self.stats["planner_failures"] += 1
                return
            self.cs = self.solver.last_constraint_state
            self.multipliers = None if self.cs is None else self.cs.lam.copy()
            self.solution = sol
            self.plan = (PlanTracker.from_solution(sol, problem, touchdown=FootClearance()), k, e)
            self.stats["replans"] += 1
            self.stats["solve_ms"].append(1e3 * (time.perf_counter() - t0))

        def act(self, obs):
            x, mode, _ = self._parse(obs)
            if self.done:
                tracker = self.plan[0]
                u = tracker.U[-1] + HOLD_KP * (tracker.X[-1][3:NQ] - x[3:NQ]) - HOLD_KD * x[NQ + 3:]
                return self.interface.action_from_torque(u)
            if self.plan is not None:
                before = self.plan[0].phase
                self.plan[0].sync(mode, x)
                if self.plan[0].phase != before:
                    self.since = np.inf
            if self.since >= period - 1e-9:
                self.since = 0.0
                self.replan(x)
            tracker = self.plan[0]
            k, _ = self.where()
            if tracker.finished or (k == len(phases) - 1 and tracker.phase == tracker.n_phases - 1
                                    and tracker.time >= float(np.sum(np.diff(tracker.phase_start)
                                                                     * tracker.phase_dt)) - 1e-9):
                self.done = True
            u = tracker.control(x)
            tracker.advance(self.interface.control_dt)
            self.since += self.interface.control_dt
            return self.interface.action_from_torque(u)

    policy = BackflipReplanning(interface)
    policy.reset()
    return policy


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--episodes", type=int, default=3, help="episodes (default %(default)s)")
    p.add_argument("--first-seed", type=int, default=56900, help="the first episode's seed (default %(default)s)")
    p.add_argument("--window", type=int, default=2,
                   help="phases re-planned: the current one and the next N - 1 (0: all that remain; default "
                        "%(default)s)")
    p.add_argument("--planner-dt", type=float, default=0.0025, help="the plans' knot spacing [s] (default %(default)s)")
    p.add_argument("--period", type=float, default=0.02, help="env time between re-plans [s] (default %(default)s)")
    p.add_argument("--iterations", type=int, default=1, help="DDP iterations per re-plan (default %(default)s)")
    p.add_argument("--warmup-iterations", type=int, default=10,
                   help="DDP iterations of the first plan, from the offline plan (default %(default)s)")
    args = p.parse_args(argv)
    if args.episodes < 1 or args.window < 0 or args.iterations < 1 or args.warmup_iterations < 1:
        p.error("--episodes, --iterations and --warmup-iterations must be >= 1, --window >= 0")
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the envs)
    from hsddp_gym.planners.policies.base import EnvInterface
    from hsddp_gym.rollout.episodes import run_episode

    env = gym.make("hsddp_gym/Backflip-v0")
    policy = make_policy(EnvInterface.from_env(env), args.planner_dt, args.period, args.iterations,
                         args.warmup_iterations, args.window)
    successes = 0
    for seed in range(args.first_seed, args.first_seed + args.episodes):
        info = {}
        res = run_episode(env, policy, seed, observers=(_LastInfo(info),))
        successes += bool(info.get("success", False))
        ms = policy.stats["solve_ms"]
        fall = f"fell at {res.simulated_time:.2f} s" if res.fell else "no fall"
        print(f"seed {seed}: {fall}, "
              f"success {bool(info.get('success', False))}, re-plans {policy.stats['replans']} "
              f"({policy.stats['planner_failures']} failed, {np.mean(ms) if ms else float('nan'):.1f} ms each)")
    print(f"{successes} of {args.episodes} successes")
    env.close()
    return 0


class _LastInfo:
    """Keeps the last step's ``info`` (an observer of the episode loop)."""

    def __init__(self, into: dict) -> None:
        self.into = into

    def on_reset(self, env, obs, info) -> None:
        self.into.clear()

    def on_step(self, env, action, obs, reward, terminated, truncated, info) -> None:
        self.into.clear()
        self.into.update(info)


if __name__ == "__main__":
    sys.exit(main())
