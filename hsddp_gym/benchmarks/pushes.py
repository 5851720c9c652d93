"""The push benchmark (``experiments/push_robustness.py``): falls of the policies on ``hsddp_gym/Bounding-v0`` after
a body-velocity change mid-episode, per (policy, push, push time, seed), run in parallel
([`hsddp_gym.util.parallel.run_parallel`][hsddp_gym.util.parallel.run_parallel]) and tabled.
"""

from __future__ import annotations

from hsddp_gym.util.parallel import run_parallel

DEFAULT_PUSHES = [
    (-1.0, 0.0, 0.0), (1.0, 0.0, 0.0), (-1.5, 0.0, 0.0), (1.5, 0.0, 0.0), (3.0, 0.0, 0.0),
    (0.0, -1.0, 0.0), (0.0, -1.5, 0.0), (0.0, -2.5, 0.0),
    (0.0, 0.0, 6.0), (0.0, 0.0, -6.0), (0.0, 0.0, 8.0), (0.0, 0.0, -10.0), (0.0, 0.0, 10.0),
]
"""The default grid ``[dvx, dvz, dpitch_rate]`` (m/s, m/s, rad/s): pushes along each axis of growing size."""


POLICIES = ("mpc", "mpc-options", "heuristic", "random")
"""``mpc``: the MPC with its default options; ``mpc-options``: ``MPCOptions.from_record(OPTIONS)``, ``--mpc-options``
(ablations); ``heuristic``: the contact-event heuristic; ``random``: uniform actions."""


def push_policy(name: str, env, mpc_options: dict | None = None):
    """The policy ``name`` ([`POLICIES`][POLICIES]) for ``env`` (``mpc_options``: the ``mpc-options`` policy's
    fields)."""
    from hsddp_gym.rollout.policies import PolicySpec, make_policy

    if name not in POLICIES:
        raise ValueError(f"policy must be one of {list(POLICIES)}, got {name!r}")
    if name == "mpc-options":
        return make_policy(PolicySpec("mpc", options=dict(mpc_options or {})), env)
    return make_policy(PolicySpec(name), env)


def push_label(dv) -> str:
    return "[" + ", ".join(f"{v:+g}" for v in dv) + "]"


def run_one(task: tuple) -> dict:
    """One pushed episode: ``task = (policy name, push (3,), seed, push time [s], steps, mpc_options)``."""
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the env)
    from hsddp_gym.rollout.episodes import run_episode

    name, dv, seed, push_time, steps, mpc_options = task
    env = gym.make("hsddp_gym/Bounding-v0")
    try:
        policy = push_policy(name, env, mpc_options)
        res = run_episode(env, policy, seed, options={"push": {"delta_v": list(dv), "time": push_time}},
                          max_steps=steps)
        stats = getattr(policy, "stats", {})
        return {"seed": seed, "push_time_s": push_time, "fell": bool(res.fell),
                "fall_time_s": res.length * env.unwrapped.dt if res.fell else None,
                "planner_failures": int(stats.get("planner_failures", 0))}
    finally:
        env.close()


def run_grid(policies, pushes, seeds: int, first_seed: int, push_times, steps: int, workers: int = 1,
             progress: bool = True, mpc_options: dict | None = None, backend: str = "local",
             address: str | None = None) -> dict:
    """``{policy: {push label: {"delta_v", "falls", "episodes", "runs": [per episode]}}}`` (``mpc_options``: the
    fields of the ``mpc-options`` policy; ``backend``/``address``:
    [`hsddp_gym.util.parallel.run_parallel`][hsddp_gym.util.parallel.run_parallel])."""
    tasks = [(name, tuple(dv), seed, float(t), steps, mpc_options) for name in policies for dv in pushes
             for t in push_times for seed in range(first_seed, first_seed + seeds)]
    from tqdm import tqdm

    with tqdm(total=len(tasks), desc="pushed episodes", disable=not progress) as bar:
        runs = run_parallel(run_one, tasks, workers=workers, backend=backend, address=address,
                            on_result=lambda i, r: bar.update(1))
    results: dict = {name: {} for name in policies}
    for task, run in zip(tasks, runs):
        cell = results[task[0]].setdefault(push_label(task[1]), {"delta_v": list(task[1]), "runs": []})
        cell["runs"].append(run)
    for name in policies:
        for label, cell in results[name].items():
            cell["episodes"] = len(cell["runs"])
            cell["falls"] = sum(r["fell"] for r in cell["runs"])
            if progress:
                print(f"{name:<13} push {label:<18} falls {cell['falls']}/{cell['episodes']}", flush=True)
    return results


def markdown(results: dict, push_times, steps: int, dt: float) -> str:
    policies = list(results)
    labels = list(results[policies[0]])
    times = ", ".join(f"{t:g}" for t in push_times)
    lines = [f"Falls / episodes after a push at t = {times} s ({steps} steps = {steps * dt:g} s per episode)",
             "", "| push [dvx, dvz, dpitch_rate] | " + " | ".join(policies) + " |",
             "|---|" + "---|" * len(policies)]
    for label in labels:
        cells = [f"{results[p][label]['falls']}/{results[p][label]['episodes']}" for p in policies]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    totals = [f"{sum(c['falls'] for c in results[p].values())}/{sum(c['episodes'] for c in results[p].values())}"
              for p in policies]
    lines.append("| total | " + " | ".join(totals) + " |")
    return "\n".join(lines) + "\n"
