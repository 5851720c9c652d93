"""Every policy in three simulators: the planner's own hybrid model hsddp_gym/BoundingKKT-v0 (pinned feet, KKT
contact dynamics, touchdown reset maps), hsddp_gym/Bounding-v0 (exact-LCP contacts) and its MuJoCo twin
hsddp_gym/BoundingMuJoCo-v0 (soft contacts), same protocol as ``compare_policies.py`` (``--episodes`` seeded
0, 1, ..., default env settings, 1000-step limit, deterministic actions).

Policies: ``mpc``, ``heuristic``, and the trained ``bc`` / ``dagger`` / ``ppo`` / ``sac`` read from run
directories (``--bc DIR`` ...; skipped with a note when the files are missing). Writes ``two_simulators.md`` and
``two_simulators.json`` into ``--out`` (atomically) and prints the table.

Usage::

    python experiments/two_simulators.py --out runs/two_sims --policies mpc heuristic bc sac --bc runs/bc \\
        --sac runs/sac [--episodes 10] [--max-episode-steps N]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from tqdm import tqdm

from hsddp_gym.reports.store import machine_info, write_record
from hsddp_gym.util.io import atomic_path, write_json

ENVS = {"planner's model (BoundingKKT-v0)": "hsddp_gym/BoundingKKT-v0",
        "exact LCP (Bounding-v0)": "hsddp_gym/Bounding-v0",
        "MuJoCo (BoundingMuJoCo-v0)": "hsddp_gym/BoundingMuJoCo-v0"}
REFERENCE = "exact LCP (Bounding-v0)"
"""The column the "kept" ratio divides by."""
MUJOCO = "MuJoCo (BoundingMuJoCo-v0)"
POLICIES = ("mpc", "heuristic", "bc", "dagger", "ppo", "sac")


def evaluate(policy, env_id: str, episodes: int, max_episode_steps: int | None) -> dict:
    """Summary (:func:`hsddp_gym.rollout.episodes.summarize`) of ``episodes`` seeded episodes; for the
    planner's model also its friction demand: ``friction_over_mu`` (fraction of control steps in which a pinned
    foot needed ``|f_x| > mu f_z``) and ``max_friction_ratio`` (the largest ``|f_x| / f_z``)."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the ids)
    from hsddp_gym.rollout.episodes import run_episode, summarize

    class FrictionDemand(gym.Wrapper):
        """Counts the control steps whose ``info["friction_ratio"]`` exceeds the env's ``mu``."""

        def __init__(self, inner):
            super().__init__(inner)
            self.steps, self.over, self.worst = 0, 0, 0.0

        def step(self, action):
            out = self.env.step(action)
            ratio = out[-1].get("friction_ratio")
            if ratio is not None:
                self.steps += 1
                self.over += ratio > self.env.unwrapped.sim.mu
                self.worst = max(self.worst, ratio)
            return out

    limit = {} if max_episode_steps is None else {"max_episode_steps": int(max_episode_steps)}
    env = FrictionDemand(gym.make(env_id, **limit))
    try:
        summary = summarize([run_episode(env, policy, i) for i in range(episodes)])
    finally:
        env.close()
    if env.steps:
        summary["friction_over_mu"] = env.over / env.steps
        summary["max_friction_ratio"] = env.worst
    return summary


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="runs/two_sims", help="output directory (default: %(default)s)")
    p.add_argument("--policies", nargs="+", choices=POLICIES, default=["mpc", "heuristic", "bc", "sac"],
                   help="policies to run (default: %(default)s)")
    for name in POLICIES[2:]:
        p.add_argument(f"--{name}", default=None, help=f"{name} run directory (policy.npz / model.zip + summary.json)")
    p.add_argument("--episodes", type=int, default=10, help="episodes per policy and simulator (default: 10)")
    p.add_argument("--max-episode-steps", type=int, default=None, help="time limit (default: the env's 1000)")
    p.add_argument("--record", default=None, metavar="FILE.json",
                   help="also write the results as a record of the results store (results/robustness/simulators.json)")
    args = p.parse_args(argv)
    machine = machine_info()
    if args.episodes < 1:
        p.error(f"--episodes must be >= 1, got {args.episodes}")
    from hsddp_gym.benchmarks.comparison import build  # the same policy construction as the one-env comparison

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows, notes = {}, []
    jobs = [(name, label) for name in args.policies for label in ENVS]
    for name, label in tqdm(jobs, desc="policy x simulator"):
        run_dir = getattr(args, name, None) if name in POLICIES[2:] else None
        try:
            policy, _ = build(name, Path(run_dir) if run_dir else None)
        except FileNotFoundError as exc:
            if f"{name}: skipped" not in " ".join(notes):
                notes.append(f"{name}: skipped ({exc})")
            continue
        rows.setdefault(name, {})[label] = evaluate(policy, ENVS[label], args.episodes, args.max_episode_steps)
    lines = ["| policy | " + " | ".join(ENVS) + " | kept in MuJoCo |", "|---" * (len(ENVS) + 2) + "|"]
    for name, by_env in rows.items():
        cells = []
        for label in ENVS:
            s = by_env[label]
            cell = (f"{s['mean_return']:.1f} ± {s['std_return']:.1f}, {s['falls']}/{s['episodes']} falls, "
                    f"{s['mean_forward_speed']:.3f} m/s")
            if "friction_over_mu" in s:
                cell += (f"; \\|f_x\\|/f_z > μ in {100.0 * s['friction_over_mu']:.1f} % of control steps "
                         f"(max {s['max_friction_ratio']:.2f})")
            cells.append(cell)
        a, b = by_env[REFERENCE]["mean_return"], by_env[MUJOCO]["mean_return"]
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {100.0 * b / a:.1f} % |")
    table = "\n".join(lines + [""] + notes)
    print(table)
    with atomic_path(out / "two_simulators.md") as tmp:
        Path(tmp).write_text(table + "\n")
    write_json(out / "two_simulators.json", {"episodes": args.episodes, "max_episode_steps": args.max_episode_steps,
                                             "envs": ENVS, "results": rows, "notes": notes})
    if args.record:
        slim = {name: {label: {k: v for k, v in s.items() if k != "episodes_detail"} for label, s in by_env.items()}
                for name, by_env in rows.items()}
        write_record(args.record, {"episodes": args.episodes, "max_episode_steps": args.max_episode_steps,
                                   "envs": ENVS, "reference": REFERENCE, "mujoco": MUJOCO, "results": slim,
                                   "notes": notes},
                     "Each policy in the planner's own model, the exact-LCP env and the MuJoCo twin, seeds 0.. of "
                     "each", machine=machine)
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
