"""The results store and what is generated from it: every published table is what the store gives, every record backs
a table or a figure, the store and the docs stay small, and the project speaks of the software only."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from hsddp_gym.reports import figures, markers
from hsddp_gym.reports.generate import check
from hsddp_gym.reports.store import Store, read_record, record_id, write_record
from hsddp_gym.reports.tables.registry import TABLES, render
from hsddp_gym.reports.tables.robustness import robustness_pushes, wilson_interval

ROOT = Path(__file__).resolve().parents[1]


def test_every_published_table_is_what_the_store_gives():
    stale = check(ROOT)
    assert not stale, f"tables out of date (run `python -m hsddp_gym.reports`): {stale}"


def test_the_check_fails_on_a_table_edited_by_hand(tmp_path):
    (tmp_path / "results" / "paper").mkdir(parents=True)
    (tmp_path / "results" / "paper" / "task1.json").write_text((ROOT / "results/paper/task1.json").read_text())
    page = "# page\n\n<!-- results: paper/task1 -->\n<!-- /results -->\n"
    (tmp_path / "README.md").write_text(page)
    assert check(tmp_path) == ["README.md: paper/task1"]
    res = subprocess.run([sys.executable, "-m", "hsddp_gym.reports", "--root", str(tmp_path)], capture_output=True,
                         text=True)
    assert res.returncode == 0, res.stderr
    assert check(tmp_path) == []
    text = (tmp_path / "README.md").read_text()
    edited = text.replace("| al-reb | 4 |", "| al-reb | 3 |")
    assert edited != text
    (tmp_path / "README.md").write_text(edited)
    assert check(tmp_path) == ["README.md: paper/task1"]
    res = subprocess.run([sys.executable, "-m", "hsddp_gym.reports", "--root", str(tmp_path), "--check"],
                         capture_output=True, text=True)
    assert res.returncode == 1 and "paper/task1" in res.stdout


def test_every_table_id_in_the_pages_is_known_and_every_table_is_published():
    used = set()
    for path in markers.markdown_files(ROOT):
        for tid in markers.block_ids(path.read_text()):
            assert tid in TABLES, f"{path.relative_to(ROOT)}: unknown results table {tid!r}"
            used.add(tid)
    assert set(TABLES) <= used, f"tables published nowhere: {sorted(set(TABLES) - used)}"


class _LoggingStore(Store):
    """A store that remembers which records were read."""

    def __init__(self, root) -> None:
        super().__init__(root)
        self.read: set[str] = set()

    def __getitem__(self, rid):
        self.read.add(rid)
        return super().__getitem__(rid)


def _records_read_by_tables_and_figures() -> set[str]:
    store = _LoggingStore(ROOT)
    for tid in TABLES:
        render(store, tid)
    return store.read | set(figures.FIGURES)


def test_every_record_backs_a_published_table_or_figure_and_names_its_command():
    store = Store(ROOT)
    used = _records_read_by_tables_and_figures()
    for rid in store.ids():
        rec = store[rid]
        assert rid in used, f"results/{rid}.json backs no table or figure: delete it or publish it"
        assert rec.description.strip() and rec.commands, rid
        for cmd in rec.commands:
            assert re.match(r"(python |hsddp-gym )", cmd), f"{rid}: a command should be runnable as written: {cmd}"


def test_docs_and_results_fit_in_two_megabytes():
    files = subprocess.run(["git", "ls-files", "docs", "results"], cwd=ROOT, capture_output=True, text=True)
    names = files.stdout.split() if files.returncode == 0 and files.stdout.strip() else [
        str(p.relative_to(ROOT)) for d in ("docs", "results") for p in (ROOT / d).rglob("*") if p.is_file()]
    total = sum((ROOT / n).stat().st_size for n in names if (ROOT / n).is_file())
    assert total <= 2 * 1024 * 1024, f"docs/ and results/ hold {total / 1e6:.2f} MB (at most 2 MiB)"


def test_every_figure_is_drawn_from_the_store(tmp_path):
    pytest.importorskip("matplotlib")
    store = Store(ROOT)
    written = []
    for rid, draw in figures.FIGURES.items():
        written += draw(store.data(rid), tmp_path)
    for draw in figures.STORE_FIGURES:
        written += draw(store, tmp_path)
    assert written and all(p.is_file() and p.stat().st_size > 5_000 for p in written)  # palette PNGs: 8-45 kB
    published = {p.name for p in (ROOT / figures.FIGURE_DIR).glob("*.png")}
    assert {p.name for p in written} <= published, "a drawn figure is not published in docs/figures"


PROCESS_WORDS = re.compile(r"stop ?[0-9]+|issue ?[0-9]+", re.I)


def test_the_project_speaks_of_the_software_only():
    """No development-process vocabulary ("stop N", "issue N") in the user-facing tree, file names included."""
    hits = []
    for folder in ("README.md", "CHANGELOG.md", "docs", "results", "hsddp_gym", "planners", "envs", "experiments",
                   "tests", "mkdocs.yml", "pyproject.toml"):
        base = ROOT / folder
        paths = [base] if base.is_file() else [p for p in base.rglob("*") if p.is_file()] if base.exists() else []
        for path in paths:
            rel = str(path.relative_to(ROOT))
            if "__pycache__" in rel or path.suffix in (".png", ".gif", ".npz", ".pyc"):
                if PROCESS_WORDS.search(path.name):
                    hits.append(rel)
                continue
            if PROCESS_WORDS.search(rel):
                hits.append(rel)
            for n, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                if PROCESS_WORDS.search(line):
                    hits.append(f"{rel}:{n}: {line.strip()[:100]}")
    assert not hits, "\n".join(hits[:30])


# -- the store's own rules -------------------------------------------------------------------------------------------

def test_a_record_round_trips_and_names_its_id(tmp_path):
    path = tmp_path / "results" / "speed" / "thing.json"
    write_record(path, {"x": [1.5, 2.0], "n": 3}, "a test record", command="python experiments/x.py --record y")
    rec = read_record(path)
    assert rec.id == "speed/thing" == record_id(path)
    assert rec.data == {"x": [1.5, 2.0], "n": 3} and rec.commands == ["python experiments/x.py --record y"]
    assert rec.machine["cpus"] >= 1 and "load_average_after" in rec.machine
    assert Store(tmp_path).ids() == ["speed/thing"]


def test_bad_records_are_refused_with_the_file_named(tmp_path):
    with pytest.raises(ValueError, match="end in .json"):
        write_record(tmp_path / "results/x/y.txt", {}, "d")
    with pytest.raises(ValueError, match="description"):
        write_record(tmp_path / "results/x/y.json", {}, "  ")
    with pytest.raises(TypeError, match="data must be a dict"):
        write_record(tmp_path / "results/x/y.json", [1], "d")
    path = tmp_path / "results" / "x" / "y.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"record": "x/z", "description": "d", "command": "python a.py", "version": "0",
                                "machine": {}, "data": {}}))
    with pytest.raises(ValueError, match="does not match its path"):
        read_record(path)
    path.write_text(json.dumps({"record": "x/y", "description": "d"}))
    with pytest.raises(ValueError, match="misses"):
        read_record(path)
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        read_record(path)
    with pytest.raises(KeyError, match="no record 'x/none'"):
        Store(tmp_path)["x/none"]


def test_an_unclosed_marker_is_an_error_naming_the_line():
    with pytest.raises(ValueError, match="page.md:3"):
        markers.render_text("a\n\n<!-- results: paper/task1 -->\nb\n", lambda tid: "", where="page.md")
    text = "x\n<!-- results: a/b -->\nold\n<!-- /results -->\ny\n"
    expected = "x\n<!-- results: a/b -->\nnew a/b\n<!-- /results -->\ny\n"
    assert markers.render_text(text, lambda tid: f"new {tid}") == expected
    with pytest.raises(KeyError, match="unknown results table"):
        render(Store(ROOT), "no/such")


def test_without_option_drops_the_option_and_its_values():
    from hsddp_gym.reports.store import without_option

    argv = ["--bc", "a", "b", "--made-with", "cmd 1", "cmd 2", "--record", "r.json"]
    assert without_option(argv, "--made-with") == ["--bc", "a", "b", "--record", "r.json"]
    assert without_option(["--made-with", "x"], "--made-with") == []
    assert without_option(argv, "--absent") == argv


def test_the_wilson_interval_matches_known_values_and_refuses_bad_counts():
    lo, hi = wilson_interval(0, 100)
    assert lo == 0.0 and hi == pytest.approx(0.0370, abs=1e-4)
    lo, hi = wilson_interval(5, 100)
    assert (lo, hi) == (pytest.approx(0.0215, abs=1e-4), pytest.approx(0.1118, abs=1e-4))
    assert wilson_interval(20, 20)[1] == 1.0
    for k, n in ((1, 0), (-1, 10), (11, 10)):
        with pytest.raises(ValueError, match="k <= n"):
            wilson_interval(k, n)


def test_the_pushes_table_counts_blocks_where_the_mpc_fell_more(tmp_path):
    seeds = list(range(100, 140))  # two blocks of 20

    def cell(fall_seeds):
        return {"episodes": len(seeds), "falls": len(fall_seeds), "fall_seeds": fall_seeds}

    data = {"seeds": seeds, "conditions": ["push", "push_x3"],
            "results": {"mpc": {"push": cell([101]), "push_x3": cell([])},
                        "heuristic": {"push": cell([125, 130]), "push_x3": cell([139])}}}
    write_record(tmp_path / "results" / "robustness" / "pushes.json", data, "a test record",
                 command="python experiments/robustness.py --record results/robustness/pushes.json")
    text = robustness_pushes(Store(tmp_path))
    rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
            for line in text.splitlines() if line.startswith("| ")}
    # push: the first block has the MPC's one fall and none of the heuristic's; the second, the heuristic's two
    assert rows["`push`"][0] == "1/40" and rows["`push`"][-1] == "1 of 2"
    assert rows["`push_x3`"][-1] == "0 of 2"
    assert rows["**all pushes**"][0] == "**1/80**" and rows["**all pushes**"][-1] == "1 of 4"
    assert "`push` 101" in text and "2.5 % (" in text
    del data["results"]["heuristic"]
    write_record(tmp_path / "results" / "robustness" / "pushes.json", data, "a test record",
                 command="python experiments/robustness.py --record results/robustness/pushes.json")
    with pytest.raises(ValueError, match="missing \\['heuristic'\\]"):
        robustness_pushes(Store(tmp_path))


def test_records_keep_eight_significant_digits(tmp_path):
    """Floats (also in NumPy arrays and scalars) are written to 8 significant digits; ints and strings as they are."""
    import numpy as np

    raw = {"t": 0.5650000000000001, "a": np.array([1 / 3, 2e-9 / 3]), "s": np.float64(16287.792324226368),
           "n": 12345678901, "w": "1.23456789"}
    path = write_record(tmp_path / "x" / "y.json", raw, "d", command="python a.py", machine={})
    data = read_record(path).data
    assert data == {"t": 0.565, "a": [0.33333333, 6.6666667e-10], "s": 16287.792, "n": 12345678901, "w": "1.23456789"}


def test_a_record_puts_one_episode_and_one_row_of_numbers_per_line(tmp_path):
    """An object of scalars and a list of numbers take one line each, and so does any short list or object; a list of
    strings takes one line per string; longer nesting keeps one key per line; the data read back are the data
    written."""
    episodes = [{"seed": s, "fell": s % 2 == 0, "x": None, "return": 100.0 + s} for s in range(4)]
    data = {"rows": [{"label": "mpc", "per_episode": episodes}], "seeds": [1, 2], "conditions": ["push", "obs_noise"],
            "empty": {}, "nested": [[1, 2], [3]], "long": [[float(i) for i in range(60)], [1.0]]}
    path = write_record(tmp_path / "x" / "y.json", data, "d", command=["a", "b"], machine={})
    lines = path.read_text().splitlines()
    assert '     {"seed": 1, "fell": false, "x": null, "return": 101.0},' in lines  # one episode, one line
    assert '  "seeds": [1, 2],' in lines and '  "empty": {},' in lines and '  "nested": [[1, 2], [3]],' in lines
    assert '   [1.0]' in lines  # a long list of lists: one row per line
    assert '   "push",' in lines and ' "command": [' in lines and '  "a",' in lines
    assert read_record(path).data == data
