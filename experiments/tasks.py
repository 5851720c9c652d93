"""The plan-tracking tasks (``--task``): the HS-DDP expert of ``hsddp_gym/Backflip-v0``, ``hsddp_gym/GapJump-v0``,
``hsddp_gym/BoxJump-v0`` or a gait transition (``hsddp_gym/StandToBound-v0``, ``hsddp_gym/BoundPronkBound-v0``,
``hsddp_gym/BoundToStop-v0``) in the env and its MuJoCo twin, and BC (and DAgger) from its demonstrations, on unseen
seeds.

Each policy plays ``--episodes`` episodes seeded ``--seed, --seed + 1, ...`` (default 9600-9619 for the backflip,
9650-9669 for the jumps, 9700-9719 for the gait transitions: seeds no dataset uses) of the default task (400 steps =
2 s, 300 for stand-to-bound and bound-to-stop; reset noise 0.01); per episode the return, a fall, the task's own
measures (the backflip: the lowest and final pitch and the lowest trunk clearance; the jumps: the final trunk x and
pitch and the lowest trunk height over the ground; the transitions: the mean and final forward speed, the final
pitch, the lowest trunk height and the pronk stances) and the task's success (``info["success"]`` at the episode's
last step).

    hsddp-gym dataset --env hsddp_gym/GapJump-v0 --policy expert --episodes 24 --seed 1000 --action-noise 0.01 \\
        --out runs/gap_jump_expert24_dart
    hsddp-gym train --algo bc --dataset runs/gap_jump_expert24_dart --seed 0 --out runs/gap_jump_bc_s0
    python experiments/tasks.py --task gap_jump --mujoco --bc runs/gap_jump_bc_s0 ... \\
        --record results/tasks/gap_jump.json --made-with "hsddp-gym dataset ..." "hsddp-gym train ..."

``--bc`` / ``--dagger`` take ``hsddp-gym train --algo bc|dagger --out DIR`` runs (BC's dataset and DAgger's env must
be the task's env), evaluated with their final weights. ``experiments/backflip.py`` is this script with ``--task
backflip``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np


@dataclasses.dataclass(frozen=True)
class Task:
    """What the script needs of a task: its envs, seeds, the expert, the per-episode measures and the record's
    words."""

    env_id: str
    twin_id: str
    first_seed: int
    expert: str  # the name of the expert's factory in hsddp_gym.workflows
    start: Callable  # info at reset -> the episode's accumulator (dict)
    update: Callable  # (acc, info) -> None, at every step
    finish: Callable  # (acc, info at the last step) -> the episode's measures (dict)
    per_episode: tuple  # the per-episode values the record keeps
    summarize: Callable  # episodes -> the row's measures (dict)
    describe: Callable  # row -> the printed measures (str)
    success_rule: str
    description: str
    episode_start: str  # for the help text
    max_episode_steps: int = 400  # the registered TimeLimit


# ------------------------------------------------------------------ the backflip
def _flip_start(info) -> dict:
    return {"min_pitch": float(info["qpos"][2]), "clearance": float(info["trunk_clearance"])}


def _flip_update(acc, info) -> None:
    acc["min_pitch"] = min(acc["min_pitch"], float(info["qpos"][2]))
    acc["clearance"] = min(acc["clearance"], float(info["trunk_clearance"]))


def _flip_finish(acc, info) -> dict:
    return {"min_pitch": round(acc["min_pitch"], 4), "final_pitch": round(float(info["qpos"][2]), 4),
            "min_trunk_clearance": round(acc["clearance"], 4)}


def _flip_summary(eps) -> dict:
    return {"mean_final_pitch": float(np.mean([e["final_pitch"] for e in eps])),
            "mean_min_pitch": float(np.mean([e["min_pitch"] for e in eps])),
            "min_trunk_clearance": float(np.min([e["min_trunk_clearance"] for e in eps]))}


# ------------------------------------------------------------------ the jumps
def _height(info) -> float:
    return float(info["qpos"][1]) - float(info["ground_height"])


def _jump_start(info) -> dict:
    return {"min_height": _height(info)}


def _jump_update(acc, info) -> None:
    if not info.get("invalid_state", False):
        acc["min_height"] = min(acc["min_height"], _height(info))


def _jump_finish(acc, info) -> dict:
    return {"final_x": round(float(info["x_position"]), 4), "final_pitch": round(float(info["qpos"][2]), 4),
            "min_trunk_height": round(acc["min_height"], 4)}


def _jump_summary(eps) -> dict:
    return {"mean_final_x": float(np.mean([e["final_x"] for e in eps])),
            "mean_final_pitch": float(np.mean([e["final_pitch"] for e in eps])),
            "min_trunk_height": float(np.min([e["min_trunk_height"] for e in eps]))}


_JUMP_RULE = ("no fall (the trunk centre never below 0.12 m over the ground under it, a gap bridged at its rims' "
              "level; no foot 2 cm into the gap), and for the last 50 steps (0.25 s) the trunk 0.3 m past the far "
              "edge with both feet past it, |pitch| <= 0.6 rad, the trunk centre at least 0.15 m above the ground "
              "(hsddp_gym.envs.jumps.JumpTask.success)")


def _jump_task(env_id: str, what: str) -> Task:
    return Task(env_id=env_id, twin_id=env_id.replace("-v0", "MuJoCo-v0"), first_seed=9650, expert="jump_expert",
                start=_jump_start, update=_jump_update, finish=_jump_finish,
                per_episode=("seed", "return", "length", "fell", "success", "final_x"), summarize=_jump_summary,
                describe=lambda r: (f"final x {r['mean_final_x']:.2f} m  lowest trunk height "
                                    f"{r['min_trunk_height']:.3f} m"),
                success_rule=_JUMP_RULE,
                description=(f"The jump {what}: the HS-DDP jump expert ({env_id.split('/')[-1]} and its MuJoCo twin) "
                             "and BC from its demonstrations on unseen seeds."),
                episode_start="bounding")


# ------------------------------------------------------------------ the gait transitions
def _gait_start(info) -> dict:
    return {"min_height": float(info["qpos"][1]), "x0": float(info["x_position"]), "t0": float(info["time"])}


def _gait_update(acc, info) -> None:
    if not info.get("invalid_state", False):
        acc["min_height"] = min(acc["min_height"], float(info["qpos"][1]))


def _gait_finish(acc, info) -> dict:
    t = max(float(info["time"]) - acc["t0"], 1e-9)
    return {"mean_speed": round((float(info["x_position"]) - acc["x0"]) / t, 4),
            "final_speed": round(float(info["qvel"][0]), 4), "final_pitch": round(float(info["qpos"][2]), 4),
            "min_trunk_height": round(acc["min_height"], 4), "pronk_stances": int(info["pronk_stances"])}


def _gait_summary(eps) -> dict:
    return {"mean_final_speed": float(np.mean([e["final_speed"] for e in eps])),
            "mean_speed": float(np.mean([e["mean_speed"] for e in eps])),
            "min_trunk_height": float(np.min([e["min_trunk_height"] for e in eps]))}


_BOUNDING_RULE = ("bounding over the last 60 steps (0.3 s): back stance alone and front stance alone at least 4 steps "
                  "each, both feet down at most 20 % of them, mean forward speed within 0.3 m/s of 1 m/s")
_TRANSITION_RULES = {
    "stand_to_bound": f"no fall, past the plan (0.84 s), and {_BOUNDING_RULE}",
    "bound_pronk_bound": (f"no fall, past the plan (1.59 s), at least 2 double stances of 30 ms or more (the pronk), "
                          f"and {_BOUNDING_RULE}"),
    "bound_to_stop": ("no fall, past the plan (0.99 s), both feet down over the last 60 steps (0.3 s) and at the end "
                      "trunk speed <= 0.1 m/s, |pitch rate| <= 0.5 rad/s, |pitch| <= 0.3 rad, trunk centre >= 0.15 m"),
}


def _transition_task(task: str, env_id: str, what: str, start: str) -> Task:
    from hsddp_gym.envs.transitions import MAX_EPISODE_STEPS

    return Task(env_id=env_id, twin_id=env_id.replace("-v0", "MuJoCo-v0"), first_seed=9700,
                expert="transition_expert", start=_gait_start, update=_gait_update, finish=_gait_finish,
                per_episode=("seed", "return", "length", "fell", "success", "final_speed"), summarize=_gait_summary,
                describe=lambda r: (f"final speed {r['mean_final_speed']:.2f} m/s  lowest trunk height "
                                    f"{r['min_trunk_height']:.3f} m"),
                success_rule=f"{_TRANSITION_RULES[task]} (hsddp_gym.envs.transitions.TransitionTask.success)",
                description=(f"The gait transition {what}: the HS-DDP transition expert ({env_id.split('/')[-1]} "
                             "and its MuJoCo twin) and BC from its demonstrations on unseen seeds."),
                episode_start=start, max_episode_steps=MAX_EPISODE_STEPS[task])


TASKS = {
    "backflip": Task(
        env_id="hsddp_gym/Backflip-v0", twin_id="hsddp_gym/BackflipMuJoCo-v0", first_seed=9600,
        expert="backflip_expert", start=_flip_start, update=_flip_update, finish=_flip_finish,
        per_episode=("seed", "return", "length", "fell", "success", "final_pitch"), summarize=_flip_summary,
        describe=lambda r: (f"final pitch {r['mean_final_pitch']:.3f}  min trunk clearance "
                            f"{r['min_trunk_clearance']:.3f} m"),
        success_rule=("no fall (the trunk never touched the ground), a full turn, and at the end upright (pitch "
                      "within 0.3 rad of -2 pi, trunk at least 0.15 m high) on both feet and still (trunk speed <= "
                      "0.3 m/s, pitch rate <= 1 rad/s) (hsddp_gym.envs.backflip.backflip_success)"),
        description=("The backflip task: the HS-DDP backflip expert (Backflip-v0 and its MuJoCo twin) and BC (and "
                     "DAgger) from its demonstrations on unseen seeds."),
        episode_start="standing"),
    "gap_jump": _jump_task("hsddp_gym/GapJump-v0", "over a 0.3 m gap"),
    "box_jump": _jump_task("hsddp_gym/BoxJump-v0", "onto a 0.1 m box"),
    "stand_to_bound": _transition_task("stand_to_bound", "hsddp_gym/StandToBound-v0",
                                       "from standing into a bound at 1 m/s", "standing"),
    "bound_pronk_bound": _transition_task("bound_pronk_bound", "hsddp_gym/BoundPronkBound-v0",
                                          "from a bound into a pronk and back", "bounding"),
    "bound_to_stop": _transition_task("bound_to_stop", "hsddp_gym/BoundToStop-v0",
                                      "from a bound to rest standing", "bounding"),
}
"""The tasks of ``--task``."""


def run_episodes(task: Task, env, policy, seeds) -> list[dict]:
    """Play one episode per seed; per episode: seed, return, length, fell, the task's measures, success."""
    out = []
    for seed in seeds:
        policy.reset()
        obs, info = env.reset(seed=int(seed))
        acc = task.start(info)
        ret, n = 0.0, 0
        while True:
            obs, reward, terminated, truncated, info = env.step(policy(obs))
            ret += reward
            n += 1
            task.update(acc, info)
            if terminated or truncated:
                break
        out.append({"seed": int(seed), "return": round(float(ret), 3), "length": n, "fell": bool(terminated),
                    **task.finish(acc, info), "success": bool(info["success"])})
    return out


def summary(task: Task, episodes: list[dict]) -> dict:
    r = np.array([e["return"] for e in episodes])
    return {"episodes": len(episodes), "mean_return": float(r.mean()), "std_return": float(r.std()),
            "successes": int(sum(e["success"] for e in episodes)), "falls": int(sum(e["fell"] for e in episodes)),
            **task.summarize(episodes)}


def evaluate(task: Task, label: str, env_id: str, make, seeds, quiet: bool) -> dict:
    import gymnasium as gym

    import hsddp_gym  # noqa: F401  (registers the envs)

    env = gym.make(env_id)
    policy = make(env)
    t = time.perf_counter()
    eps = run_episodes(task, env, policy, seeds)
    env.close()
    row = {"label": label, "env_id": env_id, **summary(task, eps), "wall_time_s": time.perf_counter() - t,
           "per_episode": [{k: e[k] for k in task.per_episode} for e in eps]}
    if not quiet:
        print(f"{label:28s} {env_id:30s} return {row['mean_return']:8.1f} ± {row['std_return']:6.1f}  success "
              f"{row['successes']}/{row['episodes']}  falls {row['falls']}  {task.describe(row)}", flush=True)
    return row


def main(argv=None, task: str | None = None) -> int:
    """The script; ``task``: a fixed task (``experiments/backflip.py``), else ``--task`` chooses it."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    if task is None:
        p.add_argument("--task", choices=sorted(TASKS), required=True)
    p.add_argument("--seed", type=int, default=None,
                   help="first evaluation seed (default: 9600 for the backflip, 9650 for the jumps, 9700 for the "
                        "gait transitions)")
    p.add_argument("--episodes", type=int, default=20, help="episodes per policy (default: %(default)s)")
    p.add_argument("--bc", nargs="*", default=[], help="BC runs (hsddp-gym train --algo bc --out DIR) on a dataset "
                                                       "of the task's env, one per training seed")
    p.add_argument("--dagger", nargs="*", default=[], help="DAgger runs (hsddp-gym train --algo dagger --env "
                                                           "TASK_ENV --out DIR), one per training seed")
    p.add_argument("--mujoco", action="store_true", help="also run the expert in the task's MuJoCo twin")
    p.add_argument("--record", default=None, help="write the results record (results/tasks/TASK.json)")
    p.add_argument("--made-with", nargs="*", default=[],
                   help="the commands that made the dataset and the learners' runs (stored in the record)")
    p.add_argument("--quiet", action="store_true")
    args = p.parse_args(argv)
    spec = TASKS[task if task is not None else args.task]
    env_id = spec.env_id

    for flag, runs, algo in (("--bc", args.bc, "bc"), ("--dagger", args.dagger, "dagger")):
        for run in runs:
            f = Path(run) / "summary.json"
            if not f.exists():
                p.error(f"{flag}: {run} has no summary.json (not a finished hsddp-gym train run)")
            train = json.loads(f.read_text())
            if train.get("algo") != algo or train.get("env_id") != env_id:
                p.error(f"{flag}: {run} is a {train.get('algo')} run in {train.get('env_id')}, not {algo} in "
                        f"{env_id}")

    from hsddp_gym import workflows
    from hsddp_gym.learning.reporting import imitation_run_fields
    from hsddp_gym.workflows import load_policy

    expert = getattr(workflows, spec.expert)
    first = spec.first_seed if args.seed is None else args.seed
    seeds = list(range(first, first + args.episodes))
    rows = [evaluate(spec, "expert", env_id, expert, seeds, args.quiet)]
    if args.mujoco:
        rows.append(evaluate(spec, "expert", spec.twin_id, expert, seeds, args.quiet))
    bc_rows = []
    for run in args.bc:
        fields = imitation_run_fields(run, "bc")
        row = evaluate(spec, f"BC (training seed {fields['training_seed']})", env_id,
                       lambda env, run=run: load_policy(f"bc:{run}", env), seeds, args.quiet)
        bc_rows.append({**row, **fields})
    dagger_rows = []
    for run in args.dagger:
        fields = imitation_run_fields(run, "dagger")
        iterations = f"{fields['rounds']} iteration{'s' if fields['rounds'] != 1 else ''}"
        row = evaluate(spec, f"DAgger, {iterations} (training seed {fields['training_seed']})", env_id,
                       lambda env, run=run: load_policy(f"dagger:{run}", env), seeds, args.quiet)
        dagger_rows.append({**row, **fields})
    if args.record:
        from hsddp_gym.reports.store import invoked_command, without_option, write_record

        data = {"env_id": env_id, "seeds": seeds, "max_episode_steps": spec.max_episode_steps, "rows": rows,
                "bc": bc_rows,
                "dagger": dagger_rows, "success_rule": spec.success_rule}
        write_record(args.record, data, spec.description,
                     command=list(args.made_with) + [invoked_command(without_option(argv, "--made-with"))])
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
