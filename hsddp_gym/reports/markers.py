"""Generated blocks in Markdown files: the text between ``<!-- results: ID -->`` and ``<!-- /results -->``.

The block's content belongs to the generator ([`hsddp_gym.reports.tables`][hsddp_gym.reports.tables]); everything
outside the markers is the author's. `render_file` returns a file's text with every block regenerated, so a check is a
comparison. """

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

BLOCK = re.compile(r"^(?P<open><!-- results: (?P<id>[A-Za-z0-9_./-]+) -->\n)(?P<body>.*?)(?P<close>^<!-- /results -->)",
                   re.S | re.M)
OPEN = re.compile(r"^<!-- results:", re.M)
"""Markers count only at the start of a line (a page may quote them inside a sentence)."""


def block_ids(text: str) -> list[str]:
    """The ids of the generated blocks in ``text``, in order."""
    return [m.group("id") for m in BLOCK.finditer(text)]


def render_text(text: str, render: Callable[[str], str], where: str = "<text>") -> str:
    """``text`` with the body of every block replaced by ``render(id)`` (which ends without a newline).

    Raises:
        ValueError: an opening marker without its closing one (naming ``where`` and the line).
    """
    if len(OPEN.findall(text)) != len(block_ids(text)):
        matched = {m.start() for m in BLOCK.finditer(text)}
        for m in OPEN.finditer(text):
            if m.start() not in matched:
                line = text.count("\n", 0, m.start()) + 1
                raise ValueError(f"{where}:{line}: '<!-- results: ID -->' without a closing '<!-- /results -->'")

    def replace(m: re.Match) -> str:
        body = render(m.group("id")).rstrip("\n")
        return f"{m.group('open')}{body}\n{m.group('close')}"

    return BLOCK.sub(replace, text)


def markdown_files(root) -> list[Path]:
    """The files whose blocks are generated: ``README.md`` and every ``docs/**/*.md``."""
    root = Path(root)
    files = [root / "README.md"] if (root / "README.md").is_file() else []
    return files + sorted((root / "docs").rglob("*.md"))
