"""One comparison of every available policy on hsddp_gym/Bounding-v0 with the same protocol.

Protocol: ``--episodes`` (default 10) episodes seeded 0, 1, ..., default env (reset noise 0.01, 1000-step
limit), deterministic actions, via ``hsddp_gym.learning.reporting.evaluate_policy_episodes`` (which runs
``hsddp_gym.rollout.episodes.run_episode``). The plan-tracking expert is reset to its plan's initial state
(``options={"state": plan.X[0]}``: no reset noise, so its episodes are identical whatever the seed).

Policies: ``mpc`` (HS-DDP MPC, default options), ``expert`` (tracks the 5-cycle al-reb plan), ``heuristic``,
``random``, and the trained ones read from their run directories (skipped with a note when the files are
missing): ``bc`` and ``dagger`` (``policy.npz`` + ``summary.json`` of ``hsddp-gym train --algo bc|dagger``),
``ppo`` and ``sac`` (``model.zip`` + ``summary.json``, weights only, plus ``vecnormalize.npz`` for PPO); more
rows of a trained kind with ``--learned NAME@TAG=DIR`` (e.g. two PPO recipes side by side). Learners trained behind
the MPC's perception (DAgger's ``--estimator``) act behind it, as they were trained
(:func:`hsddp_gym.learning.ensemble.load_mlp_learner`).

Writes into ``--out``: ``compare.md`` and ``compare.json`` (mean +- std return, falls, forward speed, the
samples each policy learned from -- env steps for PPO/SAC, demonstration episodes and transitions for BC,
expert labels for DAgger -- and the training wall time) and ``curves.png`` (PPO/SAC return vs env steps;
BC and DAgger return vs expert-labelled transitions) when matplotlib is available.

Usage:
    python experiments/compare_policies.py --out runs/compare [--runs runs/train] [--episodes 10]
        [--policies mpc expert heuristic random bc dagger ppo sac] [--bc DIR] [--dagger DIR] [--ppo DIR] [--sac DIR]
        [--learned ppo@sde=DIR ...]
        [--max-episode-steps N]   (N < 1000 only for smoke tests: the protocol is the env's 1000-step limit)
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

from hsddp_gym.benchmarks.comparison import TRAINED, build
from hsddp_gym.learning.reporting import curve_band, mean_ci95
from hsddp_gym.reports.store import machine_info, write_record
from hsddp_gym.util.io import atomic_path, write_json

POLICIES = ("mpc", "expert", "heuristic", "random", "bc", "dagger", "ppo", "sac")


def expand_runs(name: str, paths) -> list[Path]:
    """The run directories of ``name``: each path that holds the run's files, or else its ``seed*`` subfolders
    that do (the layout of ``experiments/train_rl.py``: OUT/ALGO/seedS), in order."""
    found = []
    for p in paths:
        p = Path(p)
        if all((p / f).exists() for f in TRAINED[name]):
            found.append(p)
        elif p.is_dir():
            found += sorted(c for c in p.glob("seed*") if c.is_dir() and all((c / f).exists() for f in TRAINED[name]))
    return found


def aggregate(name: str, evals: list[dict], infos: list[dict]) -> dict:
    """One table row from the evaluations of one or several training seeds of a policy: the mean return over
    seeds with its 95 % Student-t interval (``ci95``, None for one seed), the std over all episodes, falls and
    episodes summed."""
    per_seed = [e["mean_return"] for e in evals]
    mean, half = mean_ci95(per_seed)
    returns = [r for e in evals for r in e["returns"]]
    times = [i.get("train_time_s") for i in infos if i.get("train_time_s") is not None]
    row = {"policy": name, "mean_return": mean, "ci95": None if len(evals) < 2 else half,
           "std_return": float(np.std(returns)), "returns": returns, "seed_mean_returns": per_seed,
           "training_seeds": len(evals) if kind_of(name) in TRAINED else None,
           "falls": int(sum(e["falls"] for e in evals)), "episodes": int(sum(e["episodes"] for e in evals)),
           "mean_forward_speed": float(np.mean([e["mean_forward_speed"] for e in evals])),
           "mean_episode_length": float(np.mean([e["mean_episode_length"] for e in evals])),
           "samples": samples_text(infos), "train_time_s": float(np.mean(times)) if times else None,
           "real_time_factor": evals[0].get("real_time_factor")}
    if evals[0].get("replans"):
        row.update(replans=evals[0]["replans"], planner_failures=evals[0]["planner_failures"],
                   mean_replan_ms=evals[0]["mean_replan_ms"])
    return row


def samples_text(infos: list[dict]) -> str:
    """What a row learned from: the one count of its training seeds, or the range of their counts."""
    counts = [i["samples_count"] for i in infos if "samples_count" in i]
    if len(counts) != len(infos) or len(set(counts)) == 1:
        return infos[0]["samples"]
    return f"{min(counts):,}–{max(counts):,} {infos[0]['samples_unit']}"


def kind_of(label: str) -> str:
    """The policy family of a row label: ``ppo@sde`` -> ``ppo``."""
    return label.split("@")[0]


def parse_learned(items: list[str]) -> dict[str, list[Path]]:
    """``--learned NAME@TAG=DIR`` items -> ``{label: [DIR, ...]}`` in order (a label given again adds training
    seeds to its row); ``ValueError`` naming the item for anything else."""
    out: dict[str, list[Path]] = {}
    for item in items:
        label, sep, path = item.partition("=")
        kind, at, tag = label.partition("@")
        if not sep or not path or kind not in TRAINED or not at or not tag:
            raise ValueError(f"--learned must be NAME@TAG=DIR with NAME one of {list(TRAINED)} and a TAG naming the "
                             f"row (e.g. ppo@sde=runs/ppo_sde/ppo), got {item!r}")
        out.setdefault(label, []).append(Path(path))
    return out


def _read_csv(path: Path) -> list[dict]:
    if not path.exists():
        return []
    with open(path) as fh:
        return list(csv.DictReader(fh))


def plot_curves(runs: dict, out: Path, expert_return: float | None = None) -> bool:
    """``out/curves.png``: PPO/SAC return against env steps (with several training seeds: the mean and the 95 %
    interval of their evaluation curves), BC/DAgger (the first run) against expert labels, and the expert's
    (MPC's) evaluation return as a dashed line in both (a family without runs gets no panel); ``runs``: name ->
    list of run directories. False when matplotlib is missing."""
    from hsddp_gym.viz.plotting import _plt, _save

    try:
        plt = _plt()
    except ImportError:  # matplotlib is in the viz extra
        return False
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 3.8))
    any_a = any_b = False
    rl = [label for label in runs if kind_of(label) in ("ppo", "sac")]
    imitation = [label for label in runs if kind_of(label) in ("bc", "dagger")]
    for i, name in enumerate(rl):
        dirs = runs.get(name) or []
        if len(dirs) > 1:  # several training seeds: mean and 95 % interval of the evaluation curves
            curves = []
            for d in dirs:
                ev = _read_csv(d / "eval_curve.csv")
                if len(ev) >= 2:
                    curves.append(([float(r["env_step"]) for r in ev], [float(r["mean_return"]) for r in ev]))
            if curves:
                band = curve_band(curves)
                a.plot(band["x"], band["mean"], color=f"C{i}", label=f"{name} eval, mean of {band['seeds']} seeds")
                a.fill_between(band["x"], band["low"], band["high"], color=f"C{i}", alpha=0.25,
                               label=f"{name} 95 % interval over seeds")
                if len({c[0][-1] for c in curves}) > 1:  # runs of unequal length: each seed beyond the common span
                    for k, (x, y) in enumerate(curves):
                        a.plot(x, y, color=f"C{i}", lw=0.7, alpha=0.5, ls=":",
                               label=f"{name} each seed" if k == 0 else None)
                any_a = True
            continue
        if not dirs:
            continue
        d = dirs[0]
        ev = _read_csv(d / "eval_curve.csv")
        tr = _read_csv(d / "curve.csv")
        if tr:
            x = np.array([float(r["env_step"]) for r in tr])
            y = np.array([float(r["episode_return"]) for r in tr])
            k = max(1, len(y) // 30)
            if len(y) >= k:
                a.plot(x[k - 1:], np.convolve(y, np.ones(k) / k, mode="valid"), color=f"C{i}", alpha=0.5,
                       label=f"{name} training episodes (mean of {k})")
                any_a = True
        if ev:
            a.errorbar([float(r["env_step"]) for r in ev], [float(r["mean_return"]) for r in ev],
                       yerr=[float(r["std_return"]) for r in ev], color=f"C{i}", marker="o", ms=3, capsize=2,
                       label=f"{name} deterministic eval")
            any_a = True
    spans = [max(line.get_xdata(), default=0) for line in a.get_lines()]
    if spans and min(spans) > 0 and max(spans) > 10 * min(spans):  # SAC's 0.4M beside PPO's 10M: both readable
        a.set_xscale("log")
    a.set_xlabel("env steps")
    a.set_ylabel("episode return")
    a.set_title("PPO / SAC")
    for i, name in enumerate(imitation, start=len(rl)):
        dirs = runs.get(name) or []
        d = dirs[0] if dirs else None
        rows = _read_csv(d / "curve.csv") if d is not None else []
        rows = [r for r in rows if r.get("mean_return")]
        if not rows:
            continue
        bc = kind_of(name) == "bc"
        x = [float(r["transitions"]) if bc else float(r["expert_labels"]) for r in rows]
        y = [float(r["mean_return"]) for r in rows]
        b.errorbar(x, y, yerr=[float(r["std_return"]) for r in rows],
                   color=f"C{i}", marker="o", ms=3, capsize=2,
                   label=f"{name} (first n demos)" if bc else f"{name} (per round)")
        for r, xi, yi in zip(rows, x, y):  # the number of demonstrations (BC) or the round (DAgger)
            tag = f"{int(float(r['demonstrations']))} demos" if bc else f"round {r['round']}"
            b.annotate(tag, (xi, yi), textcoords="offset points", xytext=(3, 4), fontsize=6, color=f"C{i}")
        any_b = True
    b.set_xlabel("expert-labelled transitions")
    b.set_ylabel("mean return (eval)")
    b.set_title("BC / DAgger")
    for ax, used in ((a, any_a), (b, any_b)):
        ax.grid(alpha=0.3)
        if used and expert_return is not None:
            ax.axhline(expert_return, color="k", ls="--", lw=1, label=f"HS-DDP MPC (expert) {expert_return:.0f}")
        if used:
            ax.legend(fontsize=7)
        else:
            ax.text(0.5, 0.5, "no runs", ha="center", va="center", transform=ax.transAxes)
    if any_a != any_b:  # one family only (e.g. a SAC-only comparison): its panel alone, full width
        fig.delaxes(b if any_a else a)
        (a if any_a else b).set_subplotspec(fig.add_gridspec(1, 1)[0])
        fig.set_size_inches(6.5, 3.8)
    fig.tight_layout()
    _save(fig, out / "curves.png")  # atomic
    return True


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="runs/compare",
                   help="output directory for compare.md, compare.json and curves.png (default: %(default)s)")
    p.add_argument("--runs", default="runs/train", help="default parent of the bc/dagger/ppo/sac run directories")
    for name in TRAINED:
        p.add_argument(f"--{name}", nargs="+", default=None,
                       help=f"{name} run directories, one per training seed, or folders of seed* runs (default: "
                            f"RUNS/{name}); several seeds give the mean and a 95 %% interval over seeds")
    p.add_argument("--learned", action="append", default=[], metavar="NAME@TAG=DIR",
                   help=f"one more row of a trained kind, NAME one of {list(TRAINED)}, labelled NAME@TAG (e.g. "
                        "ppo@sde=runs/ppo_sde/ppo beside --ppo runs/ppo_push/ppo); DIR a run directory or a folder "
                        "of seed* runs; the same label again adds training seeds to its row (repeatable)")
    p.add_argument("--episodes", type=int, default=10, help="episodes per policy, seeds 0.. (default: %(default)s)")
    p.add_argument("--policies", nargs="+", choices=POLICIES, default=list(POLICIES),
                   help="policies to evaluate; trained ones whose run directory lacks its files are skipped with a "
                        "note (default: all)")
    p.add_argument("--max-episode-steps", type=int, default=None,
                   help="time limit override, for smoke tests only (default: the env's 1000, the protocol)")
    p.add_argument("--rl-actions", choices=("deterministic", "stochastic"), default="deterministic",
                   help="ppo/sac: the mean action (the protocol) or draws of the policy's own distribution, as in "
                        "training, from a generator seeded at every episode (default: %(default)s)")
    p.add_argument("--rl-checkpoint", choices=("final", "best"), default="final",
                   help="ppo/sac: the weights at the end of training or the checkpoint of the best training-time "
                        "evaluation (best_model.zip; its own seeds, not the protocol's) (default: %(default)s)")
    p.add_argument("--record", default=None, metavar="FILE.json",
                   help="also write the rows as a record of the results store, e.g. results/policies/model_based.json")
    args = p.parse_args(argv)
    machine = machine_info()
    if args.episodes < 10:
        print(f"note: {args.episodes} episodes per policy (the protocol asks for at least 10)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from hsddp_gym.learning.reporting import evaluate_policy_episodes

    try:
        learned = parse_learned(args.learned)
    except ValueError as exc:
        p.error(str(exc))
    runs = {n: expand_runs(n, getattr(args, n) or [Path(args.runs) / n]) for n in TRAINED}
    runs.update({label: expand_runs(kind_of(label), paths) for label, paths in learned.items()})
    given = {**{n: getattr(args, n) or [args.runs] for n in TRAINED}, **learned}
    rows, notes = [], []
    for name in [*args.policies, *learned]:
        dirs = runs[name] if name in runs else [None]
        if not dirs:
            msg = (f"{name}: no run directory with {', '.join(TRAINED[kind_of(name)])} in "
                   f"{' '.join(str(g) for g in given[name])}")
            notes.append(f"skipped {msg}")
            print(f"skip: {msg}", flush=True)
            continue
        t = time.perf_counter()
        evals, infos = [], []
        for d in dirs:
            policy, info = build(kind_of(name), d, args.rl_actions, args.rl_checkpoint)
            evals.append(evaluate_policy_episodes(policy, args.episodes, 0, max_episode_steps=args.max_episode_steps))
            infos.append(info)
        row = aggregate(name, evals, infos)
        row["eval_wall_s"] = time.perf_counter() - t
        rows.append(row)
        spread = f"95 % CI ± {row['ci95']:6.1f} over {len(evals)} seeds" if row["ci95"] is not None else \
            f"± {row['std_return']:6.1f}"
        print(f"{name:<10} return {row['mean_return']:8.1f} {spread}  falls {row['falls']}/{row['episodes']}  "
              f"speed {row['mean_forward_speed']:+.2f} m/s  length {row['mean_episode_length']:.0f}  "
              f"({row['eval_wall_s']:.0f} s)", flush=True)
    limit = "" if args.max_episode_steps is None else f", time limit {args.max_episode_steps} steps"
    lines = [f"# Policies on hsddp_gym/Bounding-v0 ({args.episodes} episodes, seeds 0..{args.episodes - 1}, "
             f"deterministic{limit}{'; ppo/sac: stochastic actions' if args.rl_actions == 'stochastic' else ''}"
             f"{'; ppo/sac: best checkpoint' if args.rl_checkpoint == 'best' else ''})",
             "",
             "| policy | return | of the MPC's | training seeds | falls | forward speed [m/s] | episode length | "
             "learned from | training wall time (per seed) |", "|---|---|---|---|---|---|---|---|---|"]
    reference = next((r["mean_return"] for r in rows if r["policy"] == "mpc"), None)
    for r in rows:
        r["of_mpc"] = None if reference is None else r["mean_return"] / reference
        tt = "-" if r["train_time_s"] is None else f"{r['train_time_s']:.0f} s"
        ret = (f"{r['mean_return']:.1f} ± {r['ci95']:.1f} (95 % CI)" if r["ci95"] is not None
               else f"{r['mean_return']:.1f} ± {r['std_return']:.1f} (std)")
        seeds = "-" if r["training_seeds"] is None else str(r["training_seeds"])
        share = "-" if r["of_mpc"] is None else f"{100 * r['of_mpc']:.0f} %"
        lines.append(f"| {r['policy']} | {ret} | {share} | {seeds} | {r['falls']}/{r['episodes']} | "
                     f"{r['mean_forward_speed']:.2f} | {r['mean_episode_length']:.0f} | {r['samples']} | {tt} |")
    lines += ["", "Return: mean ± std over the episodes for a single policy; for learned policies with several "
              "training seeds, the mean over seeds of each seed's mean return ± the 95 % Student-t interval of that "
              "mean (falls and episodes summed over seeds); \"of the MPC's\": that mean over the MPC's mean return "
              "(run with --policies mpc).",
              "The expert starts every episode at its plan's initial state (no reset noise).",
              "Return per step is at most 1.5 (tracking 1 + healthy 0.5, minus the control cost); 1000 steps."]
    lines += [f"- {n}" for n in notes]
    plotted = plot_curves({n: d for n, d in runs.items() if d and n in {r["policy"] for r in rows}}, out, reference)
    if plotted:
        lines += ["", "![curves](curves.png)"]
    with atomic_path(out / "compare.md") as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    write_json(out / "compare.json", {"episodes": args.episodes, "seeds": list(range(args.episodes)),
                                      "max_episode_steps": args.max_episode_steps, "rows": rows,
                                      "notes": notes, "runs": {n: [str(x) for x in d] for n, d in runs.items()}})
    print("\n".join(lines))
    print(f"wrote {out / 'compare.md'}, {out / 'compare.json'}" + (", curves.png" if plotted else ""))
    if args.record:
        write_record(args.record, {"episodes": args.episodes, "seeds": list(range(args.episodes)),
                                   "max_episode_steps": args.max_episode_steps, "rl_actions": args.rl_actions,
                                   "rl_checkpoint": args.rl_checkpoint,
                                   "rows": [{k: v for k, v in r.items() if k != "returns"} for r in rows],
                                   "notes": notes},
                     f"{', '.join(r['policy'] for r in rows)} under the comparison protocol ({args.episodes} "
                     f"episodes, seeds 0-{args.episodes - 1}, the default env)", machine=machine)
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
