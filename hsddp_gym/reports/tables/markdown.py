"""The pieces every results table is made of: number formatting, GitHub-flavoured Markdown tables, the provenance
line under a table and the note on the machine a record was measured on."""

from __future__ import annotations

from collections.abc import Iterable

from hsddp_gym.reports.store import Store

NA = "–"


def fmt(value, spec: str = ".3g", none: str = NA) -> str:
    """``value`` formatted with ``spec`` (``none`` for None or NaN)."""
    if value is None or (isinstance(value, float) and value != value):
        return none
    return format(value, spec)


def markdown_table(header: list[str], rows: Iterable[list], align: list[str] | None = None) -> str:
    """A GitHub-flavoured Markdown table (``align``: one of ``"l"``, ``"r"`` per column; default left)."""
    rows = [[str(c) for c in r] for r in rows]
    for r in rows:
        if len(r) != len(header):
            raise ValueError(f"row {r} has {len(r)} cells, the header {len(header)}")
    align = align or ["l"] * len(header)
    rule = ["---:" if a == "r" else "---" for a in align]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(rule) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def source_line(store: Store, *rids: str, commands: bool = True) -> str:
    """The provenance line under a table: the records and the commands that made them (``commands`` False: only how
    many, for a long command the page shows once elsewhere)."""
    parts = []
    for rid in rids:
        rec = store[rid]
        if len(rec.commands) > 2 or not commands:
            n = len(rec.commands)
            cmds = f"{n} commands, listed in the record" if n > 1 else "its command in the record"
        else:
            cmds = "; ".join(f"`{c}`" for c in rec.commands)
        parts.append(f"`results/{rid}.json` ({cmds})")
    return "Generated from " + ", ".join(parts) + " by `python -m hsddp_gym.reports`."


def load_average(machine: dict) -> str:
    """The load average of a record's ``machine`` (before and after the run, when both were recorded)."""
    before, after = machine.get("load_average_before"), machine.get("load_average_after")
    if not before:
        return "unknown"
    return f"{before[0]:.2f} before, {after[0]:.2f} after" if after else f"{before[0]:.2f}"


def machine_note(store: Store, rid: str) -> str:
    """``"N cores, load average ..."``: the machine record ``rid`` was measured on."""
    m = store[rid].machine
    return f"{m.get('cpus')} cores, load average {load_average(m)}"
