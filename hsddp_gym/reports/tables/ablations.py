"""The table of what each rule of the MPC buys: the default beside the MPC without one rule at a time, on the same
episodes (records ``robustness/rule_ablations*`` of ``experiments/rule_ablations.py``)."""

from __future__ import annotations

from hsddp_gym.reports.store import Store
from hsddp_gym.reports.tables.markdown import machine_note, markdown_table, source_line


def _where(cells: dict) -> str:
    return ", ".join(f"`{c}` {len(s)}" for c, s in cells.items()) or "–"


def rule_ablation_table(store: Store, rid: str) -> str:
    """Per arm of record ``rid``: the rule it takes away, falls / episodes, the episodes it fell in where the default
    did not and the reverse, and the conditions of its falls."""
    d = store.data(rid)
    arms, seeds = d["arms"], d["seeds"]
    if "default" not in arms:
        raise ValueError(f"{rid}: the record needs the arm 'default'")
    header = ["MPC", "falls", "more than the default", "fewer than the default", "where it fell"]
    rows = []
    for name, arm in arms.items():
        label = "**default** (every rule)" if name == "default" else f"without: {arm['rule']}"
        rows.append([label, f"{arm['falls']}/{arm['episodes']}", len(arm["extra"]) if name != "default" else "–",
                     len(arm["fewer"]) if name != "default" else "–", _where(arm["fall_cells"])])
    conditions = d["conditions"]
    note = (f"Every arm plays the same episodes: {len(conditions)} conditions x seeds {seeds[0]}-{seeds[-1]}, one "
            f"1000-step episode (5 s) each; \"more than the default\" counts the episodes the arm fell in and the "
            f"default did not. Two episodes at a time on {machine_note(store, rid)}.")
    return "\n".join([markdown_table(header, rows), "", note, source_line(store, rid)])


def robustness_rule_ablations(store: Store) -> str:
    """The rules on every condition of the generality table (``robustness/rule_ablations``)."""
    return rule_ablation_table(store, "robustness/rule_ablations")


def robustness_rule_ablations_pushes(store: Store) -> str:
    """The rules that cost no fall there, on many more seeds of the pushes and sensor biases
    (``robustness/rule_ablations_pushes``)."""
    return rule_ablation_table(store, "robustness/rule_ablations_pushes")


def robustness_rule_ablations_push_laws(store: Store) -> str:
    """The three rules that cost at most one fall in both runs above, on 100 seeds of each push law
    (``robustness/rule_ablations_push_laws``)."""
    return rule_ablation_table(store, "robustness/rule_ablations_push_laws")
