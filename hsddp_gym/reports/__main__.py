"""``python -m hsddp_gym.reports``: regenerate the results tables (and figures) of the README and the docs site."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from hsddp_gym.reports.generate import check, regenerate_tables


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m hsddp_gym.reports",
        description="Regenerate every results table between '<!-- results: ID -->' and '<!-- /results -->' in "
                    "README.md and docs/**/*.md from the records in results/ (and, with --figures, every results "
                    "figure in docs/figures/).")
    parser.add_argument("--root", default=".", help="the repository's top folder (default: the current folder)")
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 and name every table that differs from what the store gives")
    parser.add_argument("--figures", action="store_true", help="also redraw every results figure from the store")
    args = parser.parse_args(argv)
    root = Path(args.root)
    if not (root / "results").is_dir():
        parser.error(f"--root: no results/ folder in {root.resolve()}")
    if args.check:
        stale = check(root)
        for item in stale:
            print(f"out of date: {item}")
        if stale:
            print("run `python -m hsddp_gym.reports` to regenerate them", file=sys.stderr)
            return 1
        print("every generated table matches the results store")
        return 0
    for path in regenerate_tables(root):
        print(f"updated {path}")
    if args.figures:
        from hsddp_gym.reports.figures import regenerate
        from hsddp_gym.reports.store import Store

        for path in regenerate(Store(root), root):
            print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
