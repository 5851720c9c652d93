"""How well the plan-tracking expert reproduces the 5-cycle ``al-reb`` HS-DDP plan in hsddp_gym/Bounding-v0.

The plan (paper task 1, 1480 knots of 1 ms) is computed, the env is reset to its initial state
(``options={"state": X[0]}``) and :func:`hsddp_gym.planners.policies.experts.bounding_expert` acts with the plan's
feedback law at the env's control rate while the env's own contacts decide the touchdowns. Over the tracked part
(until the touchdown that ends the plan) the state of the env is compared, step by step, with the plan's state
at the cursor that produced the action. Printed and written to ``OUT/expert_tracking.json``: the maximum and
RMS error of the trunk height, pitch, joint angles and trunk velocities, the trunk x at the end of the plan
against the plan's, and the rest of the episode (the expert hands over to the MPC).

Usage::

    python experiments/expert_tracking.py --out runs/expert_tracking
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from hsddp_gym.core.conventions import IPITCH, IZ, NQ
from hsddp_gym.util.io import write_json


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="runs/expert_tracking", help="output directory (default: %(default)s)")
    parser.add_argument("--steps", type=int, default=1000,
                        help="control steps of the episode, the MPC's after the plan (default: %(default)s)")
    args = parser.parse_args(argv)
    if args.steps < 1:
        parser.error(f"--steps must be >= 1, got {args.steps}")

    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the env)
    from hsddp_gym.rollout.episodes import Returns, run_episode
    from hsddp_gym.rollout.policies import make_policy

    env = gym.make("hsddp_gym/Bounding-v0", max_episode_steps=args.steps)
    expert = make_policy("expert", env)  # starts at its plan's first state (expert.reset_options)
    sol = expert.solution

    class Tracked:
        """The env's state before each action that came from the plan."""

        def __init__(self):
            self.states = []

        def on_reset(self, env, obs, info):
            self.x, self.before = np.concatenate([info["qpos"], info["qvel"]]), len(expert.nominal_states)

        def on_step(self, env, action, obs, reward, terminated, truncated, info):
            if len(expert.nominal_states) > self.before:  # this action came from the plan
                self.states.append(self.x)
            self.on_reset(env, obs, info)

    seen, returns = Tracked(), Returns()
    res = run_episode(env, expert, 0, max_steps=args.steps, observers=(seen, returns))
    states, tracked, ret, fell = seen.states, len(seen.states), returns.total, res.fell
    env.close()
    X_env, X_nom = np.array(states), np.array(expert.nominal_states)
    d = X_env - X_nom
    joints = slice(3, NQ)

    def stats(err):
        err = np.abs(err)
        return {"max": float(err.max()), "rms": float(np.sqrt(np.mean(err ** 2)))}

    plan_end_x = float(sol.X[-1][0])
    summary = {
        "plan_duration_s": float(sol.times[-1]),
        "tracked_steps": tracked,
        "tracked_time_s": tracked * float(env.unwrapped.dt),
        "trunk_height_m": stats(d[:, IZ]),
        "pitch_rad": stats(d[:, IPITCH]),
        "joint_angles_rad": stats(d[:, joints]),
        "trunk_velocity_m_s": stats(np.linalg.norm(d[:, NQ:NQ + 2], axis=1)),
        "trunk_x_at_handover_m": float(X_env[-1, 0]), "plan_x_at_handover_m": float(X_nom[-1, 0]),
        "plan_final_x_m": plan_end_x,
        "episode_return": ret, "fell": fell,
    }
    out = Path(args.out)
    write_json(out / "expert_tracking.json", summary)
    print(f"tracked the plan for {tracked} control steps ({summary['tracked_time_s']:.3f} s of "
          f"{sol.times[-1]:.3f} s planned)")
    for key in ("trunk_height_m", "pitch_rad", "joint_angles_rad", "trunk_velocity_m_s"):
        print(f"  {key:<20} max {summary[key]['max']:.4f}  rms {summary[key]['rms']:.4f}")
    print(f"  trunk x at the handover {summary['trunk_x_at_handover_m']:.3f} m, plan "
          f"{summary['plan_x_at_handover_m']:.3f} m (plan's last knot {plan_end_x:.3f} m)")
    print(f"episode: return {ret:.1f}, {'fell' if fell else 'no fall'}; wrote {out / 'expert_tracking.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
