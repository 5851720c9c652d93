"""Imitation learners under the robustness suite: one command, from the MPC's demonstrations to the table.

Builds, in ``--out`` (each step reused when its output exists and the settings in ``OUT/settings.json`` match,
the source code included; other settings, or changed code, e.g. a new MPC, are refused unless ``--overwrite``,
which starts over):

1. ``ds_default``: ``--demos`` MPC episodes of the plain env with DART noise (``--action-noise``) and the plan's
   feedback gains (seeds 1000..);
2. ``ds_perturbed``: ``--perturbed-demos`` MPC episodes cycling over the perturbations of the suite
   (:data:`TRAIN_PERTURBATIONS`, every condition but the target speeds; seeds 2000..), DART noise; the MPC acts
   on the true state, the stored observations are the perturbed ones;
3. ``ds_speeds``: ``--speed-demos`` episodes at each of 0.5, 1.0, 1.5, 2.0 m/s (seeds 3000..), DART noise;

and trains (BC recipe: gait-clock features, cosine lr decay, ``--epochs``; the seeds of ``--train-seeds``, default 0):

* ``bc``: BC on ``ds_default`` (plain BC from DART demos);
* ``bc_few``: BC on the first ``--few`` episodes of ``ds_default``;
* ``bc_gains_few``: the same ``--few`` episodes plus ``--gain-copies`` feedback-gain copies per step (state
  offsets ``--gain-noise``, default 0.01 / 0.1, the library's);
* ``bc_gains_few_small``: the same with ``--small-gain-copies`` copies at the smaller offsets
  ``--small-gain-noise`` (default 2 copies at 0.003 / 0.03);
* ``bc_perturbed``: BC on ``ds_perturbed``;
* ``dagger_perturbed``: DAgger from ``ds_perturbed``, ``--dagger-rounds`` rounds of ``--dagger-episodes``
  pure-learner rollouts (beta 0, noise ``--rollout-noise``) cycling over the same perturbations (seeds
  10000 + 1000 round + j), relabelled by the MPC on the true state;
* ``bc_perturbed_queue``, ``dagger_perturbed_queue``: the same two with the latency queue in the input
  (``action_queue`` = :data:`QUEUE_SLOTS`: the actions sent and not yet executed, which the MPC's latency
  compensation predicts over; :func:`hsddp_gym.learning.features.action_queue_features`);
* ``bc_speed``: speed-conditioned BC (``speed_input``) on ``ds_speeds``;
* ``bc_speed_perturbed``: speed-conditioned BC on ``ds_speeds`` and ``ds_perturbed`` pooled;
* ``dagger_speed_perturbed``: speed-conditioned DAgger from ``ds_speeds`` and ``ds_perturbed`` pooled, its rollouts
  cycling over the perturbations and the other training speeds (``--dagger-conditions``, default
  :data:`DAGGER_SPEED_CONDITIONS`; a condition named twice gets twice the rollouts), as many rollouts per round as
  ``--dagger-episodes`` gives each perturbation (one each by default: 12);
* ``dagger_speed_est``: speed-conditioned DAgger behind the MPC's perception (``DAggerConfig.estimator``: the learner
  sees the state filter's estimate predicted over the action delay, in its rollouts and when evaluated), from
  ``ds_speeds`` (undisturbed, where the estimate is the observation), its rollouts as ``dagger_speed_perturbed``'s;

each with every seed of ``--train-seeds`` (labels ``NAME`` for seed 0, ``NAME@seedS`` for the others; with two or
more seeds the table ends with each learner's falls over the seeds, mean and 95 % interval; with ``--ensemble`` each
learner's training seeds also act together, ``NAME@ens``: the mean action of those networks,
:func:`hsddp_gym.learning.ensemble.load_mlp_ensemble`).

Then every learner runs in every condition of ``--conditions`` (default: the benchmark suite,
``hsddp_gym.envs.perturbations.SUITE``) on the evaluation seeds
(7000-7019 by default, the MPC's protocol: ``experiments/robustness.py``), with ``--estimated`` once more behind the
MPC's perception (``NAME+est``: :class:`~hsddp_gym.planners.policies.estimated_state.EstimatedStatePolicy`, the
state filter and the model's prediction over the action delay), and ``OUT/imitation_robustness.md`` /
``.json`` (written atomically) hold the table next to the MPC and heuristic figures of ``--reference`` (a
``robustness.json``; they are not re-measured), and the goal check: within 1 fall of the MPC in every condition,
and speed tracking within 10 % at 0.5-2.0 m/s. The MPC episodes and the evaluations run on ``--workers``
processes; data and results do not depend on it.

Usage::

    python experiments/imitation_robustness.py --out runs/imitation_robustness --workers 2
    python experiments/imitation_robustness.py --out /tmp/smoke --demos 2 --few 1 --perturbed-demos 2 \\
        --speed-demos 1 --dagger-rounds 1 --dagger-episodes 2 --epochs 2 --seeds 1 --max-steps 30 \\
        --conditions default push   # the smoke version (CI)
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

from hsddp_gym.util.io import atomic_path, write_json

TRAIN_PERTURBATIONS = ("default", "reset_noise_x4", "obs_noise", "delay_5ms", "delay_10ms", "push", "friction_0.4",
                       "mass_+15", "mass_-15")
"""The conditions of the perturbed demonstrations and DAgger rollouts (the suite without the target speeds)."""
TRAIN_SPEEDS = ("speed_0.5", "default", "speed_1.5", "speed_2.0")
"""The conditions of the speed demonstrations (0.5, 1.0, 1.5, 2.0 m/s; 1.25 m/s is held out)."""
DAGGER_SPEED_CONDITIONS = TRAIN_PERTURBATIONS + ("speed_0.5", "speed_1.5", "speed_2.0")
"""The conditions of ``dagger_speed_perturbed``'s and ``dagger_speed_est``'s rollouts: the perturbations and the
training speeds."""
SPEED_CONDITIONS = ("speed_0.5", "default", "speed_1.25", "speed_1.5", "speed_2.0")
"""Where the speed-tracking goal (within 10 %) is checked."""
LEARNERS = ("bc", "bc_few", "bc_gains_few", "bc_gains_few_small", "bc_perturbed", "dagger_perturbed",
            "bc_perturbed_queue", "dagger_perturbed_queue", "bc_speed", "bc_speed_perturbed", "dagger_speed_perturbed",
            "dagger_speed_est")
QUEUE_SLOTS = 2
"""Latency-queue slots of the ``*_queue`` learners (``BCConfig.action_queue``): the suite's longest delay."""
REFERENCE = ("results/robustness/suite.json",)
"""The MPC's and the heuristic's evaluation record in the results store (the MPC with its default options; the heuristic
bare and behind the estimator), or robustness.json files of ``experiments/robustness.py``: the first file holding a
policy gives its row."""
REFERENCE_POLICIES = ("mpc", "heuristic", "heuristic+est")
"""The reference rows of the table (from ``--reference``), where the reference files hold them."""
FALL_MARGIN = 1
SPEED_TOLERANCE = 0.10


def _log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


def build_datasets(args, out: Path) -> dict:
    """The three datasets (generated unless they exist); returns ``{name: {"path", "wall_time_s"}}``."""
    from hsddp_gym.datasets.generation import generate_dataset

    plan = {
        "ds_default": dict(episodes=args.demos, seed=1000, include_gains=True, conditions=None),
        "ds_perturbed": dict(episodes=args.perturbed_demos, seed=2000, include_gains=False,
                             conditions=list(TRAIN_PERTURBATIONS)),
        "ds_speeds": dict(episodes=args.speed_demos * len(TRAIN_SPEEDS), seed=3000, include_gains=False,
                          conditions=list(TRAIN_SPEEDS)),
    }
    info = {}
    for name, kw in plan.items():
        path = out / name
        t0 = time.perf_counter()
        if (path / "metadata.json").exists():
            _log(f"{name}: reusing {path}")
        else:
            _log(f"{name}: {kw['episodes']} MPC episodes" + (f" over {kw['conditions']}" if kw["conditions"] else ""))
            generate_dataset("mpc", kw["episodes"], path, seed=kw["seed"], workers=args.workers,
                             include_gains=kw["include_gains"], action_noise=args.action_noise,
                             max_episode_steps=args.max_steps, conditions=kw["conditions"],
                             progress=not args.quiet)
        meta = json.loads((path / "metadata.json").read_text())
        info[name] = {"path": str(path), "episodes": meta["episodes"], "transitions": meta["total_steps"],
                      "falls": meta["falls"], "seeds": [meta["episode_seeds"][0], meta["episode_seeds"][-1]],
                      "conditions": meta.get("conditions", {}).get("names"),
                      "generation_time_s": meta["generation_time_s"], "reference_time_s": meta["reference_time_s"],
                      "wall_time_s": time.perf_counter() - t0}
    return info


def train_learners(args, out: Path, data: dict) -> dict:
    """Every learner of :data:`LEARNERS` selected by ``--learners`` (trained unless its policy exists)."""
    from hsddp_gym.learning.bc import BCConfig, run_bc
    from hsddp_gym.learning.dagger import DAggerConfig, run_dagger

    base = BCConfig(epochs=args.epochs, features="gait_clock", lr_decay=True, seed=0)
    ds = {k: v["path"] for k, v in data.items()}
    specs = {
        "bc": dict(dataset=ds["ds_default"], demos=None, config=base),
        "bc_few": dict(dataset=ds["ds_default"], demos=args.few, config=base),
        "bc_gains_few": dict(dataset=ds["ds_default"], demos=args.few,
                             config=dataclasses.replace(base, gain_copies=args.gain_copies,
                                                        gain_position_std=args.gain_noise[0],
                                                        gain_velocity_std=args.gain_noise[1])),
        "bc_gains_few_small": dict(dataset=ds["ds_default"], demos=args.few,
                                   config=dataclasses.replace(base, gain_copies=args.small_gain_copies,
                                                              gain_position_std=args.small_gain_noise[0],
                                                              gain_velocity_std=args.small_gain_noise[1])),
        "bc_perturbed": dict(dataset=ds["ds_perturbed"], demos=None, config=base),
        "bc_perturbed_queue": dict(dataset=ds["ds_perturbed"], demos=None,
                                   config=dataclasses.replace(base, action_queue=QUEUE_SLOTS)),
        "bc_speed": dict(dataset=ds["ds_speeds"], demos=None,
                         config=dataclasses.replace(base, speed_input=True)),
        "bc_speed_perturbed": dict(dataset=[ds["ds_speeds"], ds["ds_perturbed"]], demos=None,
                                   config=dataclasses.replace(base, speed_input=True)),
    }
    trained = {}
    for seed, name in ((seed, name) for seed in args.train_seeds for name in args.learners):
        label = run_label(name, seed)
        path = out / "learners" / label
        t0 = time.perf_counter()
        if (path / "policy.npz").exists() and (path / "summary.json").exists():
            _log(f"{label}: reusing {path}")
        elif name.startswith("dagger_"):
            speeds = name in ("dagger_speed_perturbed", "dagger_speed_est")
            estimator = name == "dagger_speed_est"
            conditions = tuple(args.dagger_conditions) if speeds else TRAIN_PERTURBATIONS
            episodes = args.dagger_episodes if not speeds else len(conditions) * -(
                -args.dagger_episodes // len(TRAIN_PERTURBATIONS))
            _log(f"{label}: DAgger, {args.dagger_rounds} rounds x {episodes} rollouts")
            bc = dataclasses.replace(base, action_queue=QUEUE_SLOTS) if name.endswith("_queue") else base
            bc = dataclasses.replace(bc, speed_input=True) if speeds else bc
            cfg = DAggerConfig(rounds=args.dagger_rounds, episodes_per_round=episodes, beta_decay=0.0,
                               bc=bc, seed=10000, max_episode_steps=args.max_steps,
                               rollout_noise=args.rollout_noise, conditions=conditions, estimator=estimator)
            # run_dagger gives its seed to the config and the BC (rollout seeds 10000 + 100 seed + 1000 round + j,
            # apart from the data's)
            initial = ds["ds_speeds"] if estimator else [ds["ds_speeds"], ds["ds_perturbed"]] if speeds else \
                ds["ds_perturbed"]
            run_dagger("mpc", path, seed=10000 + 100 * seed, config=cfg, dataset=initial, fmt="npz",
                       eval_episodes=0, progress=not args.quiet, workers=args.workers)
        else:
            s = specs[name]
            _log(f"{label}: BC")
            run_bc(s["dataset"], path, seed=seed, config=s["config"], demos=s["demos"], fmt="npz", eval_episodes=0,
                   progress=not args.quiet)
        summary = json.loads((path / "summary.json").read_text())
        trained[label] = {"learner": name, "training_seed": seed, "dir": str(path),
                          "wall_time_s": time.perf_counter() - t0, "training_wall_time_s": summary.get("wall_time_s"),
                          "expert_labels": summary.get("expert_labels"), "transitions": summary.get("transitions"),
                          "gain_labels": summary.get("gain_labels"),
                          "demonstrations": summary.get("demonstrations", summary.get("initial_demonstrations")),
                          "config": summary.get("config"), "estimator": name == "dagger_speed_est"}
    return trained


def run_label(name: str, seed: int) -> str:
    """The label (and directory under ``learners/``) of learner ``name`` trained with seed ``seed``: the name for seed
    0, ``name@seedS`` for the others."""
    return name if int(seed) == 0 else f"{name}@seed{int(seed)}"


def over_seeds(results: dict, learners: dict, conditions) -> dict:
    """Per learner trained with several seeds: per condition the falls of each seed and their mean with the 95 %
    Student-t interval of the mean, and the same for the total."""
    from hsddp_gym.learning.reporting import mean_ci95

    runs: dict = {}
    for label, info in learners.items():
        runs.setdefault(info["learner"], []).append(label)
    out = {}
    for name, labels in runs.items():
        if len(labels) < 2:
            continue
        cells = {}
        for c in [*conditions, "total"]:
            falls = [sum(results[lb][cc]["falls"] for cc in conditions) if c == "total" else results[lb][c]["falls"]
                     for lb in labels]
            mean, half = mean_ci95(falls)
            cells[c] = {"falls": falls, "mean": mean, "ci95": half}
        out[name] = {"runs": labels, "seeds": [learners[lb]["training_seed"] for lb in labels], "cells": cells}
    return out


def seeds_markdown(summary: dict, conditions) -> str:
    """The table of :func:`over_seeds`: mean falls ± 95 % interval over the training seeds, and each seed's."""
    if not summary:
        return ""
    names = list(summary)
    lines = ["", "Over training seeds: mean falls of 20 ± 95 % interval of the mean (each seed's falls)", "",
             "| condition | " + " | ".join(f"{n} (seeds {', '.join(map(str, summary[n]['seeds']))})" for n in names)
             + " |", "|---|" + "---|" * len(names)]
    for c in [*conditions, "total"]:
        row = [f"{summary[n]['cells'][c]['mean']:.1f} ± {summary[n]['cells'][c]['ci95']:.1f} "
               f"({', '.join(map(str, summary[n]['cells'][c]['falls']))})" for n in names]
        lines.append(f"| {c} | " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"


def goal_check(results: dict, reference: dict | None, conditions) -> dict:
    """Per learner: the conditions where it falls more than ``FALL_MARGIN`` more often than the MPC, and the
    speed conditions where its mean speed misses the target by more than ``SPEED_TOLERANCE`` (or every
    episode fell)."""
    mpc = (reference or {}).get("mpc")
    out = {}
    for label, cells in results.items():
        falls = ({c: [cells[c]["falls"], mpc[c]["falls"]] for c in conditions
                  if c in mpc and cells[c]["falls"] > mpc[c]["falls"] + FALL_MARGIN} if mpc else None)
        speed = {c: cells[c]["speed_error"] for c in SPEED_CONDITIONS if c in cells
                 and (cells[c]["speed_error"] is None or abs(cells[c]["speed_error"]) > SPEED_TOLERANCE)}
        out[label] = {"falls_beyond_mpc_plus_1": falls, "speed_misses": speed,
                      "total_falls": sum(cells[c]["falls"] for c in conditions),
                      "episodes": sum(cells[c]["episodes"] for c in conditions)}
    return out


def _cell(s: dict) -> str:
    speed = "-" if s["mean_speed"] is None else f"{s['mean_speed']:.2f} ({100 * s['speed_error']:+.0f} %)"
    return f"**{s['falls']}**/{s['episodes']}, {speed}"


def markdown(results: dict, reference: dict | None, conditions, goals: dict, command: str) -> str:
    from hsddp_gym.envs.perturbations import get_condition

    ref = {k: v for k, v in (reference or {}).items() if k in REFERENCE_POLICIES}
    labels = [f"{k} (ref.)" for k in ref] + list(results)
    cols = {**{f"{k} (ref.)": v for k, v in ref.items()}, **results}
    lines = [f"`{command}`", "",
             "Falls / episodes, mean forward speed [m/s] of the episodes that did not fall (error to the target); "
             "(ref.): from the reference robustness.json, not re-measured", "",
             "| condition | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
    for c in conditions:
        row = [_cell(cols[lb][c]) if c in cols[lb] else "-" for lb in labels]
        lines.append(f"| {c}: {get_condition(c).description} | " + " | ".join(row) + " |")
    totals = []
    for lb in labels:
        cs = [c for c in conditions if c in cols[lb]]
        totals.append(f"{sum(cols[lb][c]['falls'] for c in cs)}/{sum(cols[lb][c]['episodes'] for c in cs)}")
    lines.append("| total falls | " + " | ".join(totals) + " |")
    lines += ["", "Goal check (within 1 fall of the MPC in every condition; speed within 10 % at 0.5-2.0 m/s):", ""]
    for label, g in goals.items():
        f = g["falls_beyond_mpc_plus_1"]
        falls = ("no MPC reference" if f is None else "met" if not f else
                 "missed in " + ", ".join(f"{c} ({a} vs MPC {b})" for c, (a, b) in f.items()))
        sp = g["speed_misses"]
        speed = "met" if not sp else "missed at " + ", ".join(
            f"{c} ({'all fell' if e is None else f'{100 * e:+.0f} %'})" for c, e in sp.items())
        lines.append(f"* **{label}**: falls {falls}; speed {speed}")
    return "\n".join(lines) + "\n"


SETTINGS = ("demos", "few", "perturbed_demos", "speed_demos", "dagger_rounds", "dagger_episodes", "rollout_noise",
            "epochs", "gain_copies", "gain_noise", "small_gain_copies", "small_gain_noise", "action_noise",
            "max_steps", "dagger_conditions")
"""The arguments the datasets and learners depend on (checked against ``OUT/settings.json`` before reuse)."""


def main(argv: list[str] | None = None) -> int:
    from hsddp_gym.envs.perturbations import CONDITIONS, SUITE

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="runs/imitation_robustness", help="output directory (default: %(default)s)")
    p.add_argument("--demos", type=int, default=24, help="plain DART demonstrations (default: %(default)s)")
    p.add_argument("--few", type=int, default=5,
                   help="demonstrations of bc_few / bc_gains_few (<= --demos; default: %(default)s)")
    p.add_argument("--perturbed-demos", type=int, default=27,
                   help=f"demonstrations cycling over the {len(TRAIN_PERTURBATIONS)} perturbations "
                        "(default: %(default)s)")
    p.add_argument("--speed-demos", type=int, default=6,
                   help=f"demonstrations per training speed {TRAIN_SPEEDS} (default: %(default)s)")
    p.add_argument("--dagger-rounds", type=int, default=3, help="DAgger relabelling rounds (default: %(default)s)")
    p.add_argument("--dagger-episodes", type=int, default=len(TRAIN_PERTURBATIONS),
                   help="DAgger rollouts per round (default: %(default)s, one per perturbation)")
    p.add_argument("--dagger-conditions", nargs="+", default=list(DAGGER_SPEED_CONDITIONS), choices=list(CONDITIONS),
                   metavar="CONDITION",
                   help="the conditions dagger_speed_perturbed's and dagger_speed_est's rollouts cycle over; a "
                        "condition named k times gets k times the rollouts (default: the perturbations and the "
                        "training speeds 0.5, 1.5, 2.0 m/s)")
    p.add_argument("--rollout-noise", type=float, default=0.02,
                   help="DAgger rollouts' action noise (default: %(default)s)")
    p.add_argument("--epochs", type=int, default=100, help="BC epochs (default: %(default)s)")
    p.add_argument("--gain-copies", type=int, default=8, help="bc_gains_few's copies per step (default: %(default)s)")
    p.add_argument("--gain-noise", type=float, nargs=2, default=[0.01, 0.1], metavar=("POS", "VEL"),
                   help="bc_gains_few's state offsets [m or rad, m/s or rad/s] (default: %(default)s)")
    p.add_argument("--small-gain-copies", type=int, default=2,
                   help="bc_gains_few_small's copies per step (default: %(default)s)")
    p.add_argument("--small-gain-noise", type=float, nargs=2, default=[0.003, 0.03], metavar=("POS", "VEL"),
                   help="bc_gains_few_small's state offsets (default: %(default)s)")
    p.add_argument("--action-noise", type=float, default=0.04, help="DART noise of the datasets (default: %(default)s)")
    p.add_argument("--learners", nargs="+", default=list(LEARNERS), choices=LEARNERS,
                   help="learners to train and evaluate (default: all)")
    p.add_argument("--train-seeds", nargs="+", type=int, default=[0],
                   help="training seeds of every learner (BC's seed; DAgger's rollouts from 10000 + 100 seed); seed 0 "
                        "is labelled by the learner's name, the others NAME@seedS, and with two or more the table "
                        "gains each learner's falls over the seeds with a 95 %% interval (default: %(default)s)")
    p.add_argument("--ensemble", action="store_true",
                   help="with two or more --train-seeds, also evaluate each learner's seeds together, labelled "
                        "NAME@ens: the mean action of its networks (hsddp_gym.learning.ensemble)")
    p.add_argument("--conditions", nargs="+", default=list(SUITE), choices=list(CONDITIONS),
                   help="evaluation conditions (default: the benchmark suite, hsddp_gym.envs.perturbations.SUITE: "
                        "every condition but push_x3)")
    p.add_argument("--seeds", type=int, default=20, help="evaluation episodes per condition (default: %(default)s)")
    p.add_argument("--first-seed", type=int, default=7000, help="first evaluation seed (default: %(default)s)")
    p.add_argument("--max-steps", type=int, default=None,
                   help="episode length cap of the datasets, rollouts and evaluations (smoke runs; default: the "
                        "env's 1000)")
    p.add_argument("--reference", nargs="+", default=list(REFERENCE),
                   help="robustness.json file(s) with the MPC and heuristic rows of the table, the first file holding "
                        "a policy giving its row (default: %(default)s; 'none': no reference)")
    p.add_argument("--estimated", action="store_true",
                   help="also evaluate every learner behind the MPC's perception (EstimatedStatePolicy: its state "
                        "filter and its prediction over the action delay), labelled LABEL+est")
    p.add_argument("--workers", type=int, default=1, help="worker processes (default: %(default)s)")
    p.add_argument("--overwrite", action="store_true", help="discard the outputs of a run with other settings")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    args = p.parse_args(argv)
    for name in ("demos", "few", "perturbed_demos", "speed_demos", "dagger_episodes", "epochs", "seeds", "workers"):
        if getattr(args, name) < 1:
            p.error(f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}")
    if args.ensemble and len(args.train_seeds) < 2:
        p.error(f"--ensemble needs two or more --train-seeds, got {args.train_seeds}")
    if any(seed < 0 for seed in args.train_seeds) or len(set(args.train_seeds)) != len(args.train_seeds):
        p.error(f"--train-seeds must be distinct integers >= 0, got {args.train_seeds}")
    most = args.dagger_episodes if not {"dagger_speed_perturbed", "dagger_speed_est"} & set(args.learners) else max(
        args.dagger_episodes, len(DAGGER_SPEED_CONDITIONS) * -(-args.dagger_episodes // len(TRAIN_PERTURBATIONS)))
    if len(args.train_seeds) > 1 and most > 100:
        p.error(f"--dagger-episodes must give <= 100 rollouts per round with several --train-seeds (the rollout seeds "
                f"of training seed S start at 10000 + 100 S), got {args.dagger_episodes} ({most} rollouts)")
    for name in ("dagger_rounds", "gain_copies", "first_seed"):
        if getattr(args, name) < 0:
            p.error(f"--{name.replace('_', '-')} must be >= 0, got {getattr(args, name)}")
    if args.few > args.demos:
        p.error(f"--few must be <= --demos ({args.demos}), got {args.few}")
    if "bc_gains_few" in args.learners and args.gain_copies < 1:
        p.error("--gain-copies must be >= 1 for the bc_gains_few learner")
    if "bc_gains_few_small" in args.learners and args.small_gain_copies < 1:
        p.error("--small-gain-copies must be >= 1 for the bc_gains_few_small learner")
    for flag in ("gain_noise", "small_gain_noise"):
        if not all(v >= 0 for v in getattr(args, flag)):
            p.error(f"--{flag.replace('_', '-')} must be two numbers >= 0, got {getattr(args, flag)}")
    for name in ("rollout_noise", "action_noise"):
        if not getattr(args, name) >= 0:
            p.error(f"--{name.replace('_', '-')} must be >= 0, got {getattr(args, name)}")
    if args.action_noise == 0:
        p.error("--action-noise must be > 0 (BC needs DART demonstrations)")
    if args.max_steps is not None and args.max_steps < 1:
        p.error(f"--max-steps must be >= 1, got {args.max_steps}")
    reference = None
    if args.reference != ["none"]:
        reference = {}
        for f in args.reference:
            if not Path(f).is_file():
                p.error(f"--reference: no such file {f!r} (or 'none')")
            ref = json.loads(Path(f).read_text())
            ref = ref.get("data", ref)  # a record of the results store holds robustness.json's fields in "data"
            if args.max_steps is None and ref.get("max_steps") is None and ref.get("seeds") != list(
                    range(args.first_seed, args.first_seed + args.seeds)):
                print(f"note: --reference {f} was measured on other seeds", file=sys.stderr)
            for name, cells in ref["results"].items():
                reference.setdefault(name, cells)

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from hsddp_gym.datasets.generation import _code_fingerprint

    # the source of hsddp_gym/planners/envs too: after a change of the MPC a rerun must not reuse the old data
    settings = {**{k: getattr(args, k) for k in SETTINGS}, "code_sha256": _code_fingerprint()}
    sfile = out / "settings.json"
    if sfile.exists():
        old = json.loads(sfile.read_text())
        if old != settings:
            if not args.overwrite:
                diff = sorted(k for k in settings if old.get(k) != settings[k])
                what = [d if d != "code_sha256" else "code_sha256: the source of hsddp_gym/planners/envs changed"
                        for d in diff]
                p.error(f"{out} holds a run with other settings ({', '.join(what)}); another --out, or --overwrite "
                        "(discards its datasets and learners)")
            import shutil

            for sub in ("ds_default", "ds_perturbed", "ds_speeds", "learners"):
                shutil.rmtree(out / sub, ignore_errors=True)
    write_json(sfile, settings)

    from hsddp_gym.benchmarks.robustness import run_benchmark

    command = " ".join(["python", *sys.argv]) if argv is None else "python experiments/imitation_robustness.py " + \
        " ".join(argv)
    t0 = time.perf_counter()
    data = build_datasets(args, out)
    t_data = time.perf_counter() - t0
    learners = train_learners(args, out, data)
    t_train = time.perf_counter() - t0 - t_data
    policies = {label: {"kind": "dagger" if info["learner"].startswith("dagger") else "bc", "dir": info["dir"],
                        "estimator": info["estimator"]} for label, info in learners.items()}
    if args.estimated:
        for label, info in list(learners.items()):
            if info["estimator"]:
                continue  # trained behind the estimator: evaluated behind it already
            policies[f"{label}+est"] = {**policies[label], "estimator": True}
            learners[f"{label}+est"] = {**info, "learner": f"{info['learner']}+est", "estimator": True}
    if args.ensemble:  # each learner's training seeds as one policy (evaluated as its members were trained)
        for name in args.learners:
            members = [info for info in learners.values() if info["learner"] == name]
            policies[f"{name}@ens"] = {"kind": "dagger" if name.startswith("dagger") else "bc",
                                       "dirs": [info["dir"] for info in members], "estimator": members[0]["estimator"]}
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    _log(f"evaluating {len(policies)} learners x {len(args.conditions)} conditions x {len(seeds)} seeds")
    t1 = time.perf_counter()
    results = run_benchmark(policies, args.conditions, seeds, args.max_steps, args.workers, not args.quiet)
    t_eval = time.perf_counter() - t1
    goals = goal_check({k: {c: v for c, v in cells.items()} for k, cells in results.items()}, reference,
                       args.conditions)
    seeds_summary = over_seeds(results, learners, args.conditions)
    import os

    write_json(out / "imitation_robustness.json", {
        "command": command, "settings": settings, "seeds": seeds, "conditions": args.conditions,
        "train_perturbations": list(TRAIN_PERTURBATIONS), "train_speeds": list(TRAIN_SPEEDS),
        "datasets": data, "learners": learners, "reference": args.reference,
        "wall_time_s": {"datasets": t_data, "training": t_train, "evaluation": t_eval,
                        "total": time.perf_counter() - t0},
        "load_average_at_end": list(os.getloadavg()), "workers": args.workers,
        "goals": goals, "results": results, "over_seeds": seeds_summary})
    table = markdown(results, reference, args.conditions, goals, command) + seeds_markdown(seeds_summary,
                                                                                           args.conditions)
    with atomic_path(out / "imitation_robustness.md") as tmp:
        tmp.write_text(table)
    print("\n" + table)
    _log(f"wrote {out / 'imitation_robustness.md'} and .json (datasets {t_data:.0f} s, training {t_train:.0f} s, "
         f"evaluation {t_eval:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
