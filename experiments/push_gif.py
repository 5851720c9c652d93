"""A side-by-side GIF of one push: two policies (by default the contact-event heuristic, left, and the default
HS-DDP MPC, right; or one) in one env, same seed, same push, from shortly before the push until ``--after`` seconds
after it (or the fall).

Each panel is :func:`hsddp_gym.viz.render.render_state` of the episode's states, captioned with the policy, the
env time and, once it has happened, "FELL". Every ``--stride``-th control step is drawn and the GIF plays in
real time. The default is a +8 rad/s nose-down push at t = 1.05 s on seed 100 of Bounding-v0, one of the README's
push sweep (``experiments/push_robustness.py``) where the heuristic falls and the MPC bounds on. ``--env`` runs
another task's env (its ``mpc`` and ``expert``, ``hsddp_gym.rollout.policies.make_policy``), ``--policies`` names
the panels' policies.

Usage::

    python experiments/push_gif.py --out docs/figures/push_nose_down.gif [--seed 100] [--push 1.05 0 0 8]
    python experiments/push_gif.py --env hsddp_gym/Backflip-v0 --policies mpc --seed 58300 --push 0.5 0.4 0.4 2 \\
        --before 0.1 --after 0.8 --stride 10 --out docs/figures/backflip_mpc_push.gif
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

PANELS = {"heuristic": "contact-event heuristic", "mpc": "HS-DDP MPC", "expert": "plan-tracking expert"}
"""The policies a panel can show, and their captions."""


def episode_states(policy_name: str, seed: int, push: dict, steps: int, env_id: str = "hsddp_gym/Bounding-v0"
                   ) -> tuple[np.ndarray, bool, float]:
    """``(states (T+1, 14), fell, control period [s])`` of one pushed episode of ``policy_name`` (a key of
    [`PANELS`][PANELS]) in ``env_id``."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the env)
    from hsddp_gym.rollout.episodes import run_episode
    from hsddp_gym.rollout.policies import make_policy

    env = gym.make(env_id)
    policy = make_policy(policy_name, env)
    res = run_episode(env, policy, seed, options={"push": push}, max_steps=steps)  # with the policy's reset options
    dt = env.unwrapped.dt
    env.close()
    return res.states, res.fell, dt


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="runs/push_gif/push.gif", help="output GIF (default: %(default)s)")
    p.add_argument("--seed", type=int, default=100, help="episode seed (default: %(default)s)")
    p.add_argument("--push", type=float, nargs=4, default=(1.05, 0.0, 0.0, 8.0), metavar=("T", "DVX", "DVZ", "DPITCH"),
                   help="push time [s] and velocity change (m/s, m/s, rad/s) (default: %(default)s)")
    p.add_argument("--before", type=float, default=0.2, help="seconds shown before the push (default: %(default)s)")
    p.add_argument("--after", type=float, default=1.0, help="seconds shown after the push (default: %(default)s)")
    p.add_argument("--stride", type=int, default=4, help="control steps per frame (default: %(default)s)")
    p.add_argument("--env", default="hsddp_gym/Bounding-v0", help="the env (a task's env id; default: %(default)s)")
    p.add_argument("--policies", nargs="+", default=("heuristic", "mpc"), choices=sorted(PANELS), metavar="POLICY",
                   help=f"the panels' policies, one or two of {sorted(PANELS)}, left to right (default: "
                        "%(default)s)")
    args = p.parse_args(argv)
    if len(args.policies) > 2:
        p.error(f"--policies takes one or two policies, got {len(args.policies)}")
    t_push = args.push[0]
    if not (0 <= args.before <= t_push):
        p.error(f"--before must be in [0, push time {t_push}], got {args.before}")
    if not args.after > 0:
        p.error(f"--after must be > 0, got {args.after}")
    if args.stride < 1:
        p.error(f"--stride must be >= 1, got {args.stride}")
    from hsddp_gym.envs.bounding import DEFAULT_FRAME_SKIP, DEFAULT_SIM_TIMESTEP
    from hsddp_gym.viz.render import render_state, save_gif

    push = {"delta_v": list(args.push[1:]), "time": t_push}
    panels = []
    for name in args.policies:
        label = PANELS[name]
        steps = int(round((t_push + args.after) / (DEFAULT_FRAME_SKIP * DEFAULT_SIM_TIMESTEP)))
        states, fell, dt = episode_states(name, args.seed, push, steps, args.env)
        print(f"{label}: {'fell' if fell else 'did not fall'} ({states.shape[0] - 1} steps)", flush=True)
        panels.append((label, states, fell))
    first = int(round((t_push - args.before) / dt))
    last = int(round((t_push + args.after) / dt))
    frames = []
    for k in range(first, last + 1, args.stride):
        row = []
        for label, states, fell in panels:
            i = min(k, states.shape[0] - 1)
            caption = f"{label}  t = {k * dt:.2f} s" + ("  FELL" if fell and k >= states.shape[0] - 1 else "")
            if abs(k * dt - t_push) < 0.5 * args.stride * dt + 1e-9:
                caption += "  PUSH"
            row.append(render_state(states[i], width=360, height=240, text=caption))
        frames.append(np.concatenate(row, axis=1))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    save_gif(frames, out, fps=1.0 / (args.stride * dt))
    print(f"wrote {out} ({len(frames)} frames)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
