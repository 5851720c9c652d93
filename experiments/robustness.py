"""Robustness benchmark: the named perturbations of ``hsddp_gym.envs.perturbations.CONDITIONS`` x any policy.

Each (policy, condition, seed) is one episode of the condition's env (``make_env(condition)``: env kwargs and
wrappers, every random draw seeded from the episode seed) reset with ``seed``, run to the env's 1000-step
time limit (5 s) or a fall. Policies:

* ``mpc``: ``MPCPolicy`` with the default ``MPCOptions()`` (it reads the env's action delay, if any, from
  ``EnvInterface.from_env``); ``mpc-options``: ``MPCOptions(**json)`` from ``--mpc-options`` (ablations; give
  ``--label`` to name it);
* ``heuristic``: the contact-event heuristic; ``random``;
* learned ones, ``--learned NAME=DIR`` (NAME ``bc`` / ``dagger``: ``DIR/policy.npz``; ``ppo`` / ``sac``:
  ``DIR/model.zip`` + ``summary.json``, ``--rl-checkpoint best`` for the best training-time evaluation's weights;
  ``NAME@TAG=DIR`` labels one of several of a kind, e.g. training seeds), skipped with a note when the files are
  missing; ``bc`` / ``dagger`` with several directories, ``NAME=DIR1,DIR2,...``, is their mean-action ensemble
  (:func:`hsddp_gym.learning.ensemble.load_mlp_ensemble`);
* ``--estimated LABEL ...``: those policies once more behind the MPC's own perception
  (:class:`~hsddp_gym.planners.policies.estimated_state.EstimatedStatePolicy`: the state filter under observation
  noise, the model's prediction over an action delay), labelled ``LABEL+est``.

**Contact models.** Beside the suite, ``--conditions`` takes the contact-model conditions, which always run in the
MuJoCo twin whatever ``--simulator`` says: ``contact_family`` draws a contact model per episode from the episode seed
(``ContactModel.sample``: friction cone, solref, solimp, foot radius, impratio, time step, friction) and
``contact_<corner>`` runs one named corner of ``hsddp_gym.envs.mujoco_twin.CONTACT_CORNERS`` (softest, stiffest,
pyramidal, large_feet, low_friction, coarse_step). Their rows also give the mean time to fall, and the episodes of
``contact_family`` record their model (``contact_model``), so falls can be read against the drawn parameters.

**Conditions of a real robot.** ``--conditions`` also takes the hardware conditions
(``hsddp_gym.envs.perturbations.HARDWARE_CONDITIONS``, not in the suite): a latency other than the one the policies are
told (``delay_5ms_announced_0ms``, ``delay_10ms_announced_5ms``, ``delay_5ms_announced_10ms``,
``delay_15ms_announced_10ms``: executed, then announced; ``delay_jitter``: 10 ms announced, 5, 10 or 15 ms executed,
drawn per episode), a constant sensor bias (``sensor_bias``: +0.03 rad pitch, +0.05 m/s forward velocity, -0.02 m
height; ``sensor_bias_random``: a bias drawn per episode; ``sensor_bias_x2``: ``sensor_bias`` twice over), a push timed
by the contact phase (``push_flight``, ``push_stance``: at the first control step in flight, resp. in stance, after
t ~ U(1, 4) s, dv up to 1.0 m/s, 1.0 m/s, 7 rad/s) and several at once (``noise_bias_latency``: ``obs_noise``'s noise,
``sensor_bias_random``'s bias, 10 ms of latency announced as 5 ms). Each of their episodes records what was drawn
(``perturbation``: the executed and announced delay, the bias, the applied push).

**Seeds.** The default evaluation seeds are 7000-7019 (``--first-seed 7000 --seeds 20``); they were not used to
develop or tune anything, with one exception: the scuff rule of the MPC's gait clock (a contact counts as a landing
only after a swing of at least ``min_flight`` of the flight) was found on seed 7012 of the ``obs_noise`` condition.
Development used seeds 500-899.
``--seed-list S [S ...]`` runs exactly those seeds (e.g. an earlier run's ``fall_seeds``, or a subset of pushes
chosen by their draw).

Per cell: falls / episodes, mean return (all episodes), mean forward speed of the episodes that did not fall
(and its error to the target), real-time factor (simulated / wall time, policy + simulation), and for the MPC the
planner failures and mean re-plan time. Writes ``OUT/robustness.json`` (every episode), ``OUT/robustness.md``
(the table) and ``OUT/robustness.png`` (falls and speed per condition). Episodes are independent:
``--workers`` runs them in parallel with the same results (timings aside).

Usage::

    python experiments/robustness.py --out runs/robustness --policies mpc heuristic --seeds 20 --workers 2
        [--conditions default obs_noise ...] [--learned bc=runs/train/bc]
    python experiments/robustness.py --out runs/contact --policies mpc heuristic --seeds 5 --first-seed 9000
        --conditions contact_family contact_softest contact_stiffest contact_pyramidal contact_large_feet
        contact_low_friction contact_coarse_step
    python experiments/robustness.py --out runs/extra --policies mpc heuristic --seeds 20 --first-seed 9300
        --conditions delay_10ms_announced_5ms delay_jitter sensor_bias sensor_bias_random push_flight push_stance
        push_x3
    python experiments/robustness.py --out runs/robustness_table --combine runs/a/robustness.json runs/b/robustness.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from hsddp_gym.reports.store import machine_info, write_record
from hsddp_gym.util.io import atomic_path, write_json
from hsddp_gym.util.parallel import add_backend_arguments, check_backend, run_parallel
from hsddp_gym.viz.plotting import plot_robustness

BUILTIN = ("mpc", "mpc-options", "heuristic", "random")
LEARNED = {"bc": "policy.npz", "dagger": "policy.npz", "ppo": "model.zip", "sac": "model.zip"}
EVAL_FIRST_SEED = 7000


def make_policy(spec: dict, env):
    """The policy described by ``spec`` (``{"kind": ..., "mpc_options": {...}, "dir": ..., "estimator": bool}``, or
    ``"dirs": [...]`` for a bc/dagger ensemble) for ``env``; with ``estimator`` the policy, built for the env without
    its delay, acts behind :class:`~hsddp_gym.planners.policies.estimated_state.EstimatedStatePolicy` (the MPC's
    state filter and latency compensation)."""
    from hsddp_gym.planners.policies.base import EnvInterface

    kind = spec["kind"]
    interface = EnvInterface.from_env(env)
    if kind in ("bc", "dagger"):  # a network or a mean-action ensemble, behind the estimator if trained behind it
        from hsddp_gym.learning.ensemble import load_mlp_learner
        from hsddp_gym.planners.policies.estimated_state import EstimatedStatePolicy

        policy = load_mlp_learner(spec.get("dirs") or spec["dir"], interface)
        if not spec.get("estimator") or isinstance(policy, EstimatedStatePolicy):
            return policy
        return EstimatedStatePolicy.around(policy.with_interface, interface)
    if spec.get("estimator"):
        from hsddp_gym.planners.policies.estimated_state import EstimatedStatePolicy

        if kind in ("mpc", "mpc-options"):
            raise ValueError("estimator: the MPC filters and predicts itself (MPCOptions.state_filter, "
                             "latency_compensation); wrap other policies")
        return EstimatedStatePolicy.around(lambda i: _make_bare_policy(kind, spec, env, i), interface)
    return _make_bare_policy(kind, spec, env, interface)


def _make_bare_policy(kind: str, spec: dict, env, interface):
    if kind in ("mpc", "mpc-options"):
        from hsddp_gym.planners.policies.mpc import MPCOptions, MPCPolicy

        return MPCPolicy(interface, MPCOptions(**(spec.get("mpc_options") or {})))
    if kind == "heuristic":
        from hsddp_gym.planners.policies.heuristic import HeuristicPolicy

        return HeuristicPolicy(interface)
    if kind == "random":
        from hsddp_gym.planners.policies.random_policy import RandomPolicy

        return RandomPolicy(interface, seed=0)
    if kind in ("ppo", "sac"):
        from hsddp_gym.learning.sb3 import load_trained_policy

        policy = load_trained_policy(spec["dir"], env, checkpoint=spec.get("checkpoint", "final"))
        policy.interface = interface  # the model reads observations only; the interface says which env it acts for
        return policy
    raise ValueError(f"policy kind must be one of {BUILTIN + tuple(LEARNED)}, got {kind!r}")


def run_one(task: tuple) -> dict:
    """One episode: ``task = (label, policy spec, condition name, seed, max_steps or None, simulator)``."""
    from hsddp_gym.envs.perturbations import HardwareCondition, episode_perturbation, get_condition
    from hsddp_gym.rollout.episodes import run_episode

    label, spec, condition, seed, max_steps, simulator = task
    cond = get_condition(condition)
    env = cond.make(simulator=cond.simulator_for(simulator))
    try:
        policy = make_policy(spec, env)
        res = run_episode(env, policy, seed, max_steps=max_steps)
        stats = res.policy_stats or {}
        solve_ms = stats.get("solve_ms") or []
        run = {"seed": int(seed), "return": res.episode_return, "fell": bool(res.fell), "length": res.length,
               "fall_time_s": res.simulated_time if res.fell else None, "speed": res.forward_speed,
               "wall_time_s": res.wall_time, "simulated_time_s": res.simulated_time,
               "replans": int(stats.get("replans", 0)), "planner_failures": int(stats.get("planner_failures", 0)),
               "mean_replan_ms": float(np.mean(solve_ms)) if solve_ms else None,
               "target_speed": float(env.unwrapped.target_speed)}
        if isinstance(cond, HardwareCondition):  # the delay, bias or phase-timed push of this episode
            run["perturbation"] = episode_perturbation(env)
        if cond.SIMULATOR is not None:  # a contact condition: the simulator and the model of this episode
            run["simulator"] = cond.SIMULATOR
            run["contact_model"] = env.unwrapped.contact_model.as_dict()
        return run
    finally:
        env.close()


def summarize_cell(runs: list[dict]) -> dict:
    alive = [r for r in runs if not r["fell"]]
    target = runs[0]["target_speed"]
    speed = float(np.mean([r["speed"] for r in alive])) if alive else None
    ms = [r["mean_replan_ms"] for r in runs if r["mean_replan_ms"] is not None]
    return {"episodes": len(runs), "falls": sum(r["fell"] for r in runs),
            "fall_seeds": [r["seed"] for r in runs if r["fell"]],
            "mean_return": float(np.mean([r["return"] for r in runs])),
            "std_return": float(np.std([r["return"] for r in runs])),
            "mean_speed": speed, "target_speed": target,
            "speed_error": None if speed is None else (speed - target) / target,
            "real_time_factor": sum(r["simulated_time_s"] for r in runs) / max(sum(r["wall_time_s"] for r in runs),
                                                                              1e-12),
            "planner_failures": sum(r["planner_failures"] for r in runs),
            "mean_replan_ms": float(np.mean(ms)) if ms else None,
            "mean_fall_time_s": float(np.mean([r["fall_time_s"] for r in runs if r["fell"]]))
            if len(alive) < len(runs) else None}


def run_benchmark(policies: dict, conditions, seeds, max_steps=None, workers: int = 1, progress: bool = True,
                  backend: str = "local", address: str | None = None, simulator: str = "bounding") -> dict:
    """``{label: {condition: cell summary + "runs"}}`` for ``policies = {label: spec}``; the episodes run on
    :func:`hsddp_gym.util.parallel.run_parallel` (``backend`` "local" or "ray", ``address`` a Ray cluster) in
    ``simulator`` (a key of ``hsddp_gym.envs.perturbations.SIMULATORS``)."""
    from tqdm import tqdm

    tasks = [(label, spec, c, s, max_steps, simulator) for c in conditions for label, spec in policies.items()
             for s in seeds]
    with tqdm(total=len(tasks), desc="episodes", disable=not progress, smoothing=0.05) as bar:
        runs = run_parallel(run_one, tasks, workers=workers, backend=backend, address=address,
                            on_result=lambda i, r: bar.update(1))
    out: dict = {label: {} for label in policies}
    for task, run in zip(tasks, runs):
        out[task[0]].setdefault(task[2], []).append(run)
    return {label: {c: {**summarize_cell(r), "runs": r} for c, r in cells.items()} for label, cells in out.items()}


def markdown(results: dict, conditions) -> str:
    from hsddp_gym.envs.perturbations import get_condition

    labels = list(results)
    lines = ["Falls / episodes, mean return, mean speed of the episodes that did not fall (error to the target), "
             "real-time factor", "",
             "| condition | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
    for c in conditions:
        cells = []
        for label in labels:
            s = results[label][c]
            speed = "-" if s["mean_speed"] is None else f"{s['mean_speed']:.2f} m/s ({100 * s['speed_error']:+.0f} %)"
            cells.append(f"**{s['falls']}/{s['episodes']}**, {s['mean_return']:.0f}, {speed}, "
                         f"RTF {s['real_time_factor']:.1f}")
        lines.append(f"| {c}: {get_condition(c).description} | " + " | ".join(cells) + " |")
    totals = [f"{sum(results[lb][c]['falls'] for c in conditions)}/"
              f"{sum(results[lb][c]['episodes'] for c in conditions)}" for lb in labels]
    lines.append("| total falls | " + " | ".join(totals) + " |")
    contact = [c for c in conditions if get_condition(c).SIMULATOR is not None]
    if contact:
        lines += ["", "Contact models (MuJoCo twin): falls / episodes, mean time to fall of the episodes that fell [s]",
                  "", "| condition | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
        for c in contact:
            cells = []
            for label in labels:
                s = results[label][c]
                t = s.get("mean_fall_time_s")
                cells.append(f"**{s['falls']}/{s['episodes']}**" + ("" if t is None else f", {t:.2f} s"))
            lines.append(f"| {c} | " + " | ".join(cells) + " |")
        c_totals = [f"{sum(results[lb][c]['falls'] for c in contact)}/"
                    f"{sum(results[lb][c]['episodes'] for c in contact)}" for lb in labels]
        lines.append("| contact falls | " + " | ".join(c_totals) + " |")
    return "\n".join(lines) + "\n"


def combine(paths, out: Path) -> dict:
    """One table from several ``robustness.json`` files (e.g. a baseline, the current default, ablations): every
    policy of every file, labelled ``NAME`` or, when two files hold the same name, ``NAME@DIRNAME``; only the
    conditions common to all. Writes ``OUT/robustness.md``, ``.png`` and ``.json``."""
    loaded = [(Path(p), json.loads(Path(p).read_text())) for p in paths]
    names = [name for _, d in loaded for name in d["results"]]
    results, sources = {}, {}
    for path, d in loaded:
        for name, cells in d["results"].items():
            label = name if names.count(name) == 1 else f"{name}@{path.parent.name}"
            results[label] = cells
            sources[label] = {"file": str(path), "command": d.get("command"), "seeds": d.get("seeds")}
    common = [c for c in loaded[0][1]["conditions"] if all(c in cells for cells in results.values())]
    write_json(out / "robustness.json", {"command": " ".join(["python", *sys.argv]), "sources": sources,
                                         "conditions": loaded[0][1]["conditions"], "results": results})
    table = markdown(results, common)
    with atomic_path(out / "robustness.md") as tmp:
        tmp.write_text(table)
    plot_robustness(results, common, out / "robustness.png")
    print(table)
    return results


def main(argv: list[str] | None = None) -> int:
    from hsddp_gym.envs.perturbations import CONDITIONS, SIMULATORS, SUITE

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--out", default="runs/robustness", help="output directory (default: %(default)s)")
    p.add_argument("--policies", nargs="*", default=["mpc", "heuristic"], choices=BUILTIN,
                   help="built-in policies; '--policies' alone runs none (only --learned ones) (default: %(default)s)")
    p.add_argument("--mpc-options", default=None, metavar="JSON",
                   help="MPCOptions fields of the mpc-options policy as a JSON object (ablations)")
    p.add_argument("--label", default="mpc-options", help="name of the mpc-options policy (default: %(default)s)")
    p.add_argument("--learned", action="append", default=[], metavar="NAME=DIR",
                   help=f"a trained policy, NAME one of {list(LEARNED)}, or NAME@TAG to run several of a kind (e.g. "
                        "ppo@seed0=DIR0 ppo@seed1=DIR1); bc/dagger with comma-separated directories "
                        "(dagger@ens=DIR0,DIR1,DIR2) is the mean action of those learners (repeatable; skipped if "
                        "its files are missing)")
    p.add_argument("--rl-checkpoint", choices=("final", "best"), default="final",
                   help="ppo/sac: the final weights or the best training-time evaluation's (default: %(default)s)")
    p.add_argument("--estimated", nargs="+", default=[], metavar="LABEL",
                   help="policies (labels of --policies or --learned names, not the MPC) that also run behind the "
                        "MPC's state filter and latency compensation (EstimatedStatePolicy), labelled LABEL+est")
    p.add_argument("--conditions", nargs="+", default=list(SUITE), choices=list(CONDITIONS),
                   help="conditions (default: the benchmark suite, hsddp_gym.envs.perturbations.SUITE: every condition "
                        "but push_x3 and the contact ones). The contact-model conditions always run in the MuJoCo twin "
                        "(whatever --simulator says): contact_family draws a contact model per episode from the "
                        "episode seed (friction cone, solref, solimp, foot radius, impratio, time step, friction; "
                        "hsddp_gym.envs.mujoco_twin.ContactModel.sample), contact_<corner> runs one corner of "
                        "CONTACT_CORNERS (softest, stiffest, pyramidal, large_feet, low_friction, coarse_step); "
                        "the table then adds falls and mean time to fall per contact condition. The hardware "
                        "conditions (HARDWARE_CONDITIONS) test what a real robot has: a latency other than the one "
                        "announced to the policy (delay_<executed>_announced_<announced>, e.g. "
                        "delay_10ms_announced_5ms; delay_jitter: 10 ms announced, 5, 10 or 15 ms executed, drawn per "
                        "episode), a constant sensor bias (sensor_bias: +0.03 rad pitch, +0.05 m/s forward velocity, "
                        "-0.02 m height; sensor_bias_random: drawn per episode; sensor_bias_x2: sensor_bias twice "
                        "over), pushes timed by the contact phase (push_flight, push_stance: dv up to 1.0 m/s, "
                        "1.0 m/s, 7 rad/s at the first flight or stance step after t ~ U(1, 4) s) and several at once "
                        "(noise_bias_latency: obs_noise's noise, sensor_bias_random's bias, 10 ms of latency "
                        "announced as 5 ms); push_x3: three pushes")
    p.add_argument("--seeds", type=int, default=20, help="episodes per policy and condition (default: %(default)s)")
    p.add_argument("--first-seed", type=int, default=EVAL_FIRST_SEED,
                   help="first seed (default: %(default)s, the evaluation seeds; develop on others)")
    p.add_argument("--seed-list", type=int, nargs="+", default=None, metavar="SEED",
                   help="run exactly these seeds instead of --seeds/--first-seed (e.g. an earlier run's fall seeds)")
    p.add_argument("--max-steps", type=int, default=None,
                   help="stop episodes after this many control steps (default: the 1000-step limit; smoke tests)")
    p.add_argument("--workers", type=int, default=1,
                   help="parallel worker processes; results do not depend on it (default: %(default)s)")
    add_backend_arguments(p)
    p.add_argument("--simulator", default="bounding", choices=sorted(SIMULATORS),
                   help="the simulator every condition runs in (the contact ones: always mujoco): bounding "
                        "(hsddp_gym/Bounding-v0, exact LCP), mujoco "
                        "(its MuJoCo twin, soft contacts; needs the extra 'mujoco') or kkt (the planner's own model) "
                        "(default: %(default)s)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--combine", nargs="+", default=None, metavar="JSON",
                   help="run nothing: merge these robustness.json files into one table in --out")
    p.add_argument("--record", default=None, metavar="FILE.json",
                   help="also write the table's cells (no per-episode rows) as a record of the results store, e.g. "
                        "results/robustness/suite.json")
    args = p.parse_args(argv)
    if args.combine:
        missing = [f for f in args.combine if not Path(f).is_file()]
        if missing:
            p.error(f"--combine: no such file(s) {missing}")
        combine(args.combine, Path(args.out))
        return 0
    if args.seeds < 1:
        p.error(f"--seeds must be >= 1, got {args.seeds}")
    if args.first_seed < 0:
        p.error(f"--first-seed must be >= 0, got {args.first_seed}")
    if args.seed_list is not None:
        if min(args.seed_list) < 0:
            p.error(f"--seed-list: seeds must be >= 0, got {min(args.seed_list)}")
        if len(set(args.seed_list)) != len(args.seed_list):
            p.error("--seed-list: a seed is given twice")
    if args.workers < 1:
        p.error(f"--workers must be >= 1, got {args.workers}")
    try:
        check_backend(args.backend, args.address)
    except (ImportError, ValueError) as exc:
        p.error(f"--backend {args.backend}: {exc}")
    if args.max_steps is not None and args.max_steps < 1:
        p.error(f"--max-steps must be >= 1, got {args.max_steps}")
    policies: dict = {}
    for name in args.policies:
        if name == "mpc-options":
            if args.mpc_options is None:
                p.error("the mpc-options policy needs --mpc-options")
            from hsddp_gym.planners.policies.mpc import MPCOptions

            try:
                opts = json.loads(args.mpc_options)
                MPCOptions(**opts)
            except (ValueError, TypeError) as exc:
                p.error(f"--mpc-options must be a JSON object of MPCOptions fields: {exc}")
            policies[args.label] = {"kind": "mpc-options", "mpc_options": opts}
        else:
            policies[name] = {"kind": name}
    skipped = {}
    for item in args.learned:
        name, sep, path = item.partition("=")
        kind = name.split("@")[0]
        if not sep or kind not in LEARNED or name in policies or name in skipped:
            p.error(f"--learned must be NAME=DIR with NAME one of {list(LEARNED)}, optionally tagged NAME@TAG (e.g. "
                    f"ppo@seed1), each NAME once, got {item!r}")
        dirs = path.split(",")
        if len(dirs) > 1 and kind not in ("bc", "dagger"):
            p.error(f"--learned {item!r}: only bc and dagger learners form an ensemble of several directories")
        missing = [str(Path(d) / LEARNED[kind]) for d in dirs if not (Path(d) / LEARNED[kind]).exists()]
        if missing:
            skipped[name] = f"missing {', '.join(missing)}"
            print(f"skipping {name}: {skipped[name]}", flush=True)
            continue
        policies[name] = {"kind": kind, "dir": path} if len(dirs) == 1 else {"kind": kind, "dirs": dirs}
        if kind in ("ppo", "sac"):
            policies[name]["checkpoint"] = args.rl_checkpoint
    for label in args.estimated:
        if label in skipped:
            continue
        if label not in policies:
            p.error(f"--estimated: {label!r} is not one of the policies run ({sorted(policies)})")
        if policies[label]["kind"] in ("mpc", "mpc-options"):
            p.error(f"--estimated: {label!r} is an MPC, which filters and predicts itself")
        policies[f"{label}+est"] = {**policies[label], "estimator": True}
    if not policies:
        p.error("no policy to run: give --policies or a --learned policy whose files exist")
    seeds = list(args.seed_list) if args.seed_list is not None else list(range(args.first_seed,
                                                                                 args.first_seed + args.seeds))
    machine = machine_info()
    t0 = time.perf_counter()
    results = run_benchmark(policies, args.conditions, seeds, args.max_steps, args.workers, not args.quiet,
                            args.backend, args.address, args.simulator)
    out = Path(args.out)
    write_json(out / "robustness.json", {
        "command": " ".join(["python", *sys.argv]), "seeds": seeds, "max_steps": args.max_steps,
        "simulator": args.simulator,
        "policies": policies, "skipped": skipped, "wall_time_s": time.perf_counter() - t0,
        "conditions": {c: CONDITIONS[c].as_dict() for c in args.conditions}, "results": results})
    table = markdown(results, args.conditions)
    with atomic_path(out / "robustness.md") as tmp:
        tmp.write_text(table)
    plot_robustness(results, args.conditions, out / "robustness.png")
    print("\n" + table)
    if args.record:
        cells = {pol: {c: {k: v for k, v in cell.items() if k != "runs"} for c, cell in by_cond.items()}
                 for pol, by_cond in results.items()}
        write_record(args.record, {"seeds": seeds, "max_steps": args.max_steps, "simulator": args.simulator,
                                   "policies": policies, "conditions": {c: CONDITIONS[c].as_dict()
                                                                        for c in args.conditions},
                                   "results": cells},
                     f"Falls, returns and speeds of {', '.join(results)} under the perturbation conditions "
                     f"({len(seeds)} seeds each, {args.simulator})", machine=machine)
        print(f"wrote {args.record}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
