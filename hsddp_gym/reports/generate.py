"""Regenerate, or check, the generated tables of every Markdown file of the repository."""

from __future__ import annotations

from pathlib import Path

from hsddp_gym.reports import markers
from hsddp_gym.reports.store import Store
from hsddp_gym.reports.tables.registry import render as render_table
from hsddp_gym.util.io import atomic_path


def rendered(root) -> dict[Path, tuple[str, str]]:
    """``{file: (current text, text with every generated table regenerated)}`` for README.md and docs/**/*.md."""
    root = Path(root)
    store = Store(root)
    cache: dict[str, str] = {}

    def render(table_id: str) -> str:
        if table_id not in cache:
            cache[table_id] = render_table(store, table_id)
        return cache[table_id]

    out = {}
    for path in markers.markdown_files(root):
        text = path.read_text()
        out[path] = (text, markers.render_text(text, render, where=str(path.relative_to(root))))
    return out


def check(root) -> list[str]:
    """``"FILE: TABLE_ID"`` for every generated table that differs from what the store gives (empty: all match)."""
    stale = []
    for path, (old, new) in rendered(root).items():
        if old == new:
            continue
        old_blocks = dict(zip(markers.block_ids(old), [m.group("body") for m in markers.BLOCK.finditer(old)]))
        new_blocks = dict(zip(markers.block_ids(new), [m.group("body") for m in markers.BLOCK.finditer(new)]))
        rel = path.relative_to(Path(root))
        stale += [f"{rel}: {tid}" for tid in new_blocks if old_blocks.get(tid) != new_blocks[tid]]
    return stale


def regenerate_tables(root) -> list[Path]:
    """Rewrite every file whose generated tables differ from the store (atomically); returns the files changed."""
    changed = []
    for path, (old, new) in rendered(root).items():
        if old != new:
            with atomic_path(path) as tmp:
                tmp.write_text(new)
            changed.append(path)
    return changed
