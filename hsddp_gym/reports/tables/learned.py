"""The tables of the learned policies: every policy under one evaluation protocol, and each learner's falls per
condition of the suite."""

from __future__ import annotations

from hsddp_gym.reports.store import Store
from hsddp_gym.reports.tables.markdown import NA, markdown_table, source_line
from hsddp_gym.reports.tables.robustness import ENSEMBLES


def _suite_total(cells: dict) -> int:
    """Falls over the suite's conditions (a record may hold more conditions, e.g. ``push_x3``)."""
    from hsddp_gym.envs.perturbations.conditions import SUITE

    return sum(cells[c]["falls"] for c in SUITE if c in cells)


def _learner_suite(learners: dict, policy: str) -> str:
    """The suite falls of each training seed of a protocol row (``bc``, ``sac``, ``ppo@sde``, ...)."""
    prefix = {"dagger@speed_est": "dagger@speed_est@"}.get(policy, f"{policy}@")
    totals = [str(_suite_total(v)) for k, v in learners.items() if k.startswith(prefix) and "ensemble" not in k
              and k[len(prefix):].startswith("seed")]
    text = ", ".join(totals) if totals else NA
    if policy == "dagger@speed_est":
        ens = ", ".join(str(_suite_total(learners[e])) for e in ENSEMBLES if e in learners)
        text += f"; three acting together: {ens}"
    return text


ROW_NAMES = {"mpc": "HS-DDP MPC (the expert)", "expert": "plan-tracking expert (5-cycle plan)",
             "heuristic": "contact-event heuristic", "random": "random", "bc": "BC, 24 DART demonstrations",
             "dagger@speed_est": "DAgger (speed input, perturbed rollouts, behind the estimator)",
             "sac": "SAC `--hidden 128,128`, 1 h", "ppo@push_x3": "PPO `parallel`, trained under `push_x3`, 1 h",
             "ppo@sde": "PPO `parallel --sde` (gSDE), 1 h"}
READING = {"best": "best checkpoint", "final": "final weights", "stochastic": "own draws (final weights)"}


def policies_protocol(store: Store) -> str:
    """Every policy under one protocol, with its suite falls."""
    model = store.data("policies/model_based")
    learned = store.data("policies/learned")
    learners = store.data("robustness/learners")["learners"]
    suite = store.data("robustness/suite")["results"]
    mpc = next(r for r in model["rows"] if r["policy"] == "mpc")["mean_return"]
    header = ["policy", "reading", "training seeds", "return", "of the MPC's", "falls", "speed [m/s]",
              "learned from (per seed)", "training wall time (per seed)", "suite: falls of 260 (per seed)"]
    rows = []
    for r in model["rows"]:
        cells = suite.get(r["policy"])
        rows.append([ROW_NAMES.get(r["policy"], r["policy"]), NA, NA,
                     f"{r['mean_return']:.1f} ± {r['std_return']:.1f} (std)", f"{100 * r['mean_return'] / mpc:.0f} %",
                     f"{r['falls']}/{r['episodes']}", f"{r['mean_forward_speed']:.2f}", NA, NA,
                     str(_suite_total(cells)) if cells else NA])
    order = ["bc", "dagger@speed_est", "sac", "ppo@push_x3", "ppo@sde"]
    for policy in order:
        for reading in ("best", "final", "stochastic"):
            r = next((x for x in learned["readings"][reading] if x["policy"] == policy), None)
            if r is None or (reading != "best" and policy in ("bc", "dagger@speed_est")):
                continue
            first = reading == "best"
            tt = NA if r.get("train_time_s") is None else f"{r['train_time_s']:.0f} s"
            rows.append([ROW_NAMES[policy] if first else "", READING[reading] if policy.startswith(("sac", "ppo"))
                         else NA, r["training_seeds"], f"{r['mean_return']:.1f} ± {r['ci95']:.1f}",
                         f"{100 * r['mean_return'] / mpc:.0f} %", f"{r['falls']}/{r['episodes']}",
                         f"{r['mean_forward_speed']:.2f}", r["samples"] if first else "", tt if first else "",
                         _learner_suite(learners, policy) if first else ""])
    p = learned["protocol"]
    note = (f"{p['episodes']} episodes, seeds {p['seeds']}, the default env, the mean action of learned policies "
            "unless the reading says otherwise. Learned rows: the mean over training seeds of each seed's mean "
            "return ± the 95 % Student-t interval of that mean, falls summed over seeds; model-based rows: mean ± "
            f"std over the episodes. The learned policies were trained and evaluated with version "
            f"{store['policies/learned'].version}, their demonstrations and labels from that version's MPC "
            f"(return {learned['mpc_return_at_evaluation']:.1f} then). Suite: the perturbation suite's 13 "
            "conditions × 20 evaluation seeds.")
    return "\n".join([markdown_table(header, rows), "", note,
                      source_line(store, "policies/model_based", "policies/learned", "robustness/suite",
                                  "robustness/learners")])


SHORT = {"default": "default", "reset_noise_x4": "reset ×4", "obs_noise": "obs. noise", "delay_5ms": "5 ms",
         "delay_10ms": "10 ms", "push": "push", "friction_0.4": "μ 0.4", "mass_+15": "mass +15 %",
         "mass_-15": "mass −15 %", "speed_0.5": "0.5 m/s", "speed_1.25": "1.25 m/s", "speed_1.5": "1.5 m/s",
         "speed_2.0": "2 m/s"}


def learning_imitation(store: Store) -> str:
    """Every learned policy under the suite: falls of 20 per condition."""
    d = store.data("robustness/learners")
    conds = d["suite_conditions"]
    rows = []
    for label, cells in d["learners"].items():
        rows.append([f"`{label}`"] + [str(cells[c]["falls"]) if c in cells else NA for c in conds]
                    + [f"**{_suite_total({c: cells[c] for c in conds if c in cells})}**"])
    table = markdown_table(["policy"] + [SHORT.get(c, c) for c in conds] + ["total of 260"], rows,
                           ["l"] + ["r"] * (len(conds) + 1))
    ens = "; ".join(f"`{k}`: {v}" for k, v in d["ensembles"].items())
    return "\n".join([table, "", f"Falls of 20 per condition (evaluation seeds {d['seeds']}). {ens}. Recorded with "
                      f"version {store['robustness/learners'].version}.", source_line(store, "robustness/learners")])
