"""The pushes a task's MPC falls after, one by one: which push, the state it met, and how close the MPC's best plan
after it came to a feasible landing.

Usage: python experiments/push_failures.py --env hsddp_gym/Backflip-v0 [--first-seed 59100] [--seeds 20]
       [--window 0.3] [--out runs/push_failures/backflip.json]

Each episode runs the task's MPC (``make_policy("mpc", env)``) under the ``push`` condition of
``hsddp_gym.envs.perturbations`` (the task's push window and sizes, drawn from the episode seed, as in the robustness
benchmark). For every episode the table gives the push (``info["push"]``: time [s] and trunk-velocity change
``dvx, dvz, dpitch_rate``), whether the task succeeded, the motion's phase and the estimated trunk state at the push
(height [m], pitch [rad], forward and vertical speed [m/s], pitch rate [rad/s]), and the smallest switching-constraint
violation (``Solution.switching_violation``, the sum of the squared touchdown residuals [m^2]) over the plans made in
the ``--window`` seconds after the push: a best plan that still misses its landings by centimetres says the push left
no landing the planner found.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def run_episode_after_push(env_id: str, seed: int, window: float) -> dict:
    """One pushed episode of ``env_id``'s MPC from seed ``seed``: the push, the outcome, the state and phase at the push
    and the switching violations of the plans made within ``window`` [s] after it."""
    import hsddp_gym  # noqa: F401  (registers the envs)
    from hsddp_gym.envs.perturbations import make_env
    from hsddp_gym.rollout.policies import make_policy

    env = make_env("push", env_id=env_id)
    policy = make_policy("mpc", env)
    obs, info = env.reset(seed=seed)
    policy.reset()
    push = info["push"]
    dt = env.unwrapped.dt
    at_push, violations, last = None, [], None
    terminated = truncated = False
    steps = 0
    while not (terminated or truncated):
        action = policy.act(obs)
        t = steps * dt
        if at_push is None and t >= push["time"] - 1e-9:
            x = policy.last_estimate
            at_push = {"phase": int(getattr(policy, "phase", -1)), "height": float(x[1]), "pitch": float(x[2]),
                       "vx": float(x[7]), "vz": float(x[8]), "pitch_rate": float(x[9])}
        solution = policy.last_solution
        if at_push is not None and t <= push["time"] + window and solution is not None and solution is not last:
            violations.append(float(solution.switching_violation))
        last = solution
        obs, _, terminated, truncated, info = env.step(action)
        steps += 1
    env.close()
    return {"seed": seed, "push_time": float(push["time"]), "delta_v": [float(v) for v in push["delta_v"]],
            "success": bool(info.get("success", not terminated)), "fell": bool(terminated), "steps": steps,
            "at_push": at_push, "best_switching_violation": min(violations) if violations else None,
            "plans_after_push": len(violations)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--env", required=True, help="the task env whose MPC is pushed (e.g. hsddp_gym/Backflip-v0)")
    p.add_argument("--first-seed", type=int, default=59100, help="first episode seed (default: %(default)s)")
    p.add_argument("--seeds", type=int, default=20, help="episodes, seeds first-seed, first-seed + 1, ... (default: "
                                                          "%(default)s)")
    p.add_argument("--window", type=float, default=0.3,
                   help="seconds after the push whose plans are searched for the best one (default: %(default)s)")
    p.add_argument("--workers", type=int, default=1, help="worker processes (default: %(default)s)")
    p.add_argument("--out", default=None, help="also write the rows as JSON to this file")
    args = p.parse_args(argv)
    if args.seeds < 1 or args.first_seed < 0 or args.window <= 0 or args.workers < 1:
        p.error("--seeds and --workers must be >= 1, --first-seed >= 0 and --window > 0")
    from hsddp_gym.registry import ENV_TASKS

    if args.env not in ENV_TASKS or ENV_TASKS[args.env].motion is None:
        p.error(f"--env must be a task env with a motion MPC, got {args.env!r}")
    from hsddp_gym.util.parallel import run_parallel

    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    rows = run_parallel(_row, [(args.env, s, args.window) for s in seeds], workers=args.workers)
    print(f"{args.env}: the MPC under the push condition, seeds {seeds[0]}-{seeds[-1]}")
    print(f"{'seed':>6} {'t [s]':>6} {'dvx':>6} {'dvz':>6} {'dpitch':>7} {'ok':>3} {'phase':>5} {'z':>6} {'pitch':>6} "
          f"{'vx':>6} {'vz':>6} {'wy':>6} {'best g^2 [m^2]':>15}")
    for r in rows:
        a = r["at_push"] or {}
        v = r["best_switching_violation"]
        print(f"{r['seed']:>6} {r['push_time']:6.2f} {r['delta_v'][0]:6.2f} {r['delta_v'][1]:6.2f} "
              f"{r['delta_v'][2]:7.2f} {'yes' if r['success'] else 'NO':>3} {a.get('phase', -1):>5} "
              f"{a.get('height', np.nan):6.3f} {a.get('pitch', np.nan):6.2f} {a.get('vx', np.nan):6.2f} "
              f"{a.get('vz', np.nan):6.2f} {a.get('pitch_rate', np.nan):6.2f} "
              f"{'-' if v is None else format(v, '15.2e'):>15}")
    if args.out:
        import json
        from pathlib import Path

        from hsddp_gym.util.io import atomic_path

        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(args.out) as tmp:
            tmp.write_text(json.dumps({"env": args.env, "window": args.window, "rows": rows}, indent=1))
        print(f"wrote {args.out}")
    return 0


def _row(task: tuple) -> dict:
    return run_episode_after_push(*task)


if __name__ == "__main__":
    sys.exit(main())
