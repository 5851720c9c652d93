"""The README's and the documentation site's code blocks, and the site itself.

* Every ```python block runs as written, every command line of a ```bash block parses with its program's own
  argument parser, and the two set-up commands install every extra a command can ask for.
* A walkthrough (Getting started's Quickstart sections, the tutorials' Step sections) runs top to bottom as written:
  its python blocks and its ``hsddp-gym`` commands, in the page's order, in one fresh folder; a tutorial at its
  smoke size (:data:`SMOKE_SIZES`: the same steps with smaller sizes).
* The site builds with ``mkdocs build --strict`` (broken links and anchors fail it), renders every documented
  module, loads no script, stylesheet or font from another host, and shows its formulas rendered in a browser.

The other pages' Python blocks read files that the CLI writes (a dataset, a BC run, a SAC run); the test writes them
with the same commands at tiny settings into a scratch working directory, then runs each block unchanged in a fresh
interpreter there.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import http.server
import io
import os
import re
import runpy
import shlex
import shutil
import subprocess
import sys
import threading
from html.parser import HTMLParser
from pathlib import Path

import pytest
import tomllib

from hsddp_gym.reports.markers import markdown_files

ROOT = Path(__file__).resolve().parents[1]
PAGES = {str(p.relative_to(ROOT)): p.read_text() for p in markdown_files(ROOT)}
README = PAGES["README.md"]


FENCE = re.compile(r"^```(\w+)\n(.*?)^```", re.S | re.M)
SECTION = re.compile(r"^## (.*)$", re.M)


def sections_and_blocks(text: str) -> list[tuple[str, str, str]]:
    """``(section, language, body)`` of each fenced block of a Markdown text, in the page's order; ``section`` is the
    heading of the ``## `` section the block is in ("" before the first)."""
    headings = [(m.start(), m.group(1).strip()) for m in SECTION.finditer(text)]
    return [(next((h for pos, h in reversed(headings) if pos < m.start()), ""), m.group(1), m.group(2))
            for m in FENCE.finditer(text)]


def fenced_blocks(text: str, language: str) -> list[str]:
    """The bodies of the ```language blocks of a Markdown text."""
    return [body for _, lang, body in sections_and_blocks(text) if lang == language]


WALKTHROUGHS = {"docs/getting-started.md": "Quickstart", "docs/tutorials/train-from-demonstrations.md": "Step",
                "docs/tutorials/mpc-on-your-task.md": "Step"}
"""Pages whose sections with a heading that starts with the given word run top to bottom as one walkthrough."""

SMOKE_SIZES = {
    "docs/tutorials/train-from-demonstrations.md": {
        "--episodes 24 --seed 1000": "--episodes 2 --max-episode-steps 60 --seed 1000",
        "--rounds 2 --episodes-per-round 8": "--rounds 1 --episodes-per-round 1 --max-episode-steps 60",
        "seeds = range(9500, 9520)": "seeds = range(9500, 9502)",
    },
    "docs/tutorials/mpc-on-your-task.md": {
        "STEPS = 1000": "STEPS = 60",
        "--episodes 5 --out runs/mpc_fast": "--episodes 1 --max-episode-steps 60 --out runs/mpc_fast",
        "SEEDS = range(5)": "SEEDS = range(1)",
    },
}
"""A walkthrough's smoke size: ``{page: {text as written: text the test runs instead}}``. The page gives the full
size a reader runs (minutes); the test runs every step at the smoke size (seconds). Every text must occur in its
page, so a substitution cannot silently stop applying."""


def smoke_size(page: str, text: str) -> str:
    """``text`` (the page ``page``) with its :data:`SMOKE_SIZES` substitutions made.

    Raises:
        AssertionError: a substitution whose text is not in the page.
    """
    for written, smoke in SMOKE_SIZES.get(page, {}).items():
        assert written in text, f"{page}: the smoke-size substitution {written!r} no longer occurs in the page"
        text = text.replace(written, smoke)
    return text


def in_walkthrough(page: str, section: str) -> bool:
    return page in WALKTHROUGHS and section.startswith(WALKTHROUGHS[page])


def python_blocks(page: str, text: str) -> list[tuple[str, int, str]]:
    """``(page, index, code)`` of the page's python blocks that run on their own (not in a walkthrough)."""
    blocks = [(section, body) for section, lang, body in sections_and_blocks(text) if lang == "python"]
    return [(page, i, body) for i, (section, body) in enumerate(blocks) if not in_walkthrough(page, section)]


PYTHON_BLOCKS = [block for name, text in PAGES.items() for block in python_blocks(name, text)]


def command_lines(block: str) -> list[str]:
    """The ``hsddp-gym ...``, ``python experiments/...`` and ``python -m hsddp_gym...`` commands of a shell block
    (continuation lines joined, comments dropped, split at ``&&``, ``;`` and ``|``; loop variables read as 0)."""
    text = re.sub(r"\\\n", " ", block)
    text = re.sub(r"\$\([^)]*\)", "", text)              # command substitutions
    text = re.sub(r"\$\{?[A-Za-z_][A-Za-z_0-9]*\}?", "0", text)  # shell variables
    out = []
    for line in text.splitlines():
        try:
            tokens = shlex.split(line, comments=True)
        except ValueError as exc:
            raise AssertionError(f"unparsable shell line: {line!r} ({exc})") from None
        cmd: list[str] = []
        for tok in [*tokens, ";"]:
            if tok in ("&&", ";", "|", "||", "&", "do", "done", "then", "fi"):
                if cmd:
                    out.append(cmd)
                cmd = []
            else:
                cmd.append(tok)
    return [c for c in out if c and (c[0] == "hsddp-gym" or (c[0] in ("python", "python3") and len(c) > 1 and (
        c[1].startswith("experiments/") or (c[1] == "-m" and len(c) > 2 and c[2].startswith("hsddp_gym")))))]


COMMANDS = [(name, " ".join(cmd), cmd) for name, text in PAGES.items() for block in fenced_blocks(text, "bash")
            for cmd in command_lines(block)]


class _Parsed(Exception):
    """Raised by the patched ``parse_args`` once the arguments have parsed."""


@contextlib.contextmanager
def _parse_only():
    original = argparse.ArgumentParser.parse_args

    def parse_args(self, args=None, namespace=None):
        original(self, args, namespace)
        raise _Parsed

    argparse.ArgumentParser.parse_args = parse_args
    try:
        yield
    finally:
        argparse.ArgumentParser.parse_args = original


def parse(cmd: list[str]) -> str | None:
    """None if ``cmd`` parses with its program's parser, else the parser's message."""
    err = io.StringIO()
    if cmd[0] == "hsddp-gym":
        from hsddp_gym.cli import main as run
        argv = cmd[1:]
    elif cmd[1] == "-m":
        module = runpy.run_module(cmd[2] + ("" if cmd[2].endswith("__main__") else ".__main__"), run_name="docs")
        run, argv = module["main"], cmd[3:]
    else:
        script = ROOT / cmd[1]
        if not script.is_file():
            return f"no such script {cmd[1]}"
        module = runpy.run_path(str(script), run_name="docs")
        run, argv = module["main"], cmd[2:]
    with _parse_only(), contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            run(argv)
        except _Parsed:
            return None
        except SystemExit as exc:
            if exc.code in (0, None):
                return None  # --help
            return err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else f"exit {exc.code}"
    return "the program finished without parsing its arguments"


def test_the_pages_have_the_blocks_users_need():
    joined = "\n".join(code for text in PAGES.values() for code in fenced_blocks(text, "python"))
    readme = "\n".join(fenced_blocks(README, "python"))
    for needle in ('gym.make("hsddp_gym/Bounding-v0"', "minari.load_dataset(", "MPCPolicy"):
        assert needle in readme, f"README quickstart lacks {needle}"
    for needle in ("load_minari(", "load_policy(", "sol.control("):
        assert needle in joined, needle
    assert len(COMMANDS) >= 20


@pytest.mark.parametrize("page,line,cmd", COMMANDS, ids=[f"{n}:{c[:60]}" for n, c, _ in COMMANDS])
def test_every_documented_command_parses(page, line, cmd):
    problem = parse(cmd)
    assert problem is None, f"{page}: `{line}`: {problem}"


def test_a_wrong_documented_command_is_caught():
    assert parse(["hsddp-gym", "rollout", "--no-such-option"]) is not None
    assert parse(["python", "experiments/robustness.py", "--conditions", "no_such_condition"]) is not None
    assert parse(["python", "experiments/no_such_script.py"]) == "no such script experiments/no_such_script.py"
    assert parse(["hsddp-gym", "rollout", "--policy", "mpc", "--episodes", "2"]) is None


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """A working directory with the files the snippets load, written by the CLI at tiny settings."""
    cwd = tmp_path_factory.mktemp("docs")
    exe = str(Path(sys.executable).with_name("hsddp-gym"))
    commands = [
        [exe, "dataset", "--policy", "mpc", "--episodes", "1", "--max-episode-steps", "10", "--quiet",
         "--out", "runs/demo_dataset"],
        [exe, "train", "--algo", "bc", "--dataset", "runs/demo_dataset", "--epochs", "2", "--eval-episodes", "0",
         "--quiet", "--out", "runs/bc"],
        [exe, "train", "--algo", "sac", "--steps", "64", "--learning-starts", "32", "--eval-freq", "0",
         "--eval-episodes", "0", "--max-episode-steps", "32", "--quiet", "--out", "runs/sac"],
    ]
    for cmd in commands:
        res = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=600)
        assert res.returncode == 0, res.stderr[-2000:]
    return cwd


def block_env() -> dict[str, str]:
    """The environment a page's code runs in: the user's, without a dataset folder of their own, figures off-screen."""
    env = {k: v for k, v in os.environ.items() if k != "MINARI_DATASETS_PATH"}
    env["MPLBACKEND"] = "Agg"
    return env


@pytest.mark.slow
@pytest.mark.parametrize("page,index,code", PYTHON_BLOCKS, ids=[f"{n}[{i}]" for n, i, _ in PYTHON_BLOCKS])
def test_every_python_block_runs_as_written(workdir, page, index, code):
    res = subprocess.run([sys.executable, "-c", code], cwd=workdir, capture_output=True, text=True, timeout=600,
                         env=block_env())
    assert res.returncode == 0, f"{page}, python block {index}:\n{code}\n--- stderr:\n{res.stderr[-3000:]}"


def walkthrough_steps(text: str, word: str) -> list[tuple[str, str]]:
    """The walkthrough of a page, in its order: ``("python", code)`` for each python block and ``("command", line)``
    for each command of a bash block, in the sections whose heading starts with ``word``."""
    steps = []
    for section, language, body in sections_and_blocks(text):
        if not section.startswith(word):
            continue
        if language == "python":
            steps.append(("python", body))
        elif language == "bash":
            steps += [("command", shlex.join(cmd)) for cmd in command_lines(body)]
    return steps


def step_argv(kind: str, step: str) -> list[str]:
    """The program and arguments of a walkthrough step, run with this interpreter's installation."""
    if kind == "python":
        return [sys.executable, "-c", step]
    cmd = shlex.split(step)
    if cmd[0] == "hsddp-gym":
        return [str(Path(sys.executable).with_name("hsddp-gym")), *cmd[1:]]
    if cmd[1] == "-m":
        return [sys.executable, *cmd[1:]]
    return [sys.executable, str(ROOT / cmd[1]), *cmd[2:]]  # python experiments/...: the repository's script


def run_walkthrough(steps: list[tuple[str, str]], cwd: Path) -> tuple[int, str] | None:
    """Run the steps in order in ``cwd``; None if every step succeeds, else the failing step's index and stderr."""
    for i, (kind, step) in enumerate(steps):
        res = subprocess.run(step_argv(kind, step), cwd=cwd, capture_output=True, text=True, timeout=600,
                             env=block_env())
        if res.returncode != 0:
            return i, res.stderr[-3000:]
    return None


def test_a_walkthrough_step_that_needs_a_later_one_fails(tmp_path):
    later = ("python", 'from pathlib import Path\nPath("made.txt").write_text("x")\n')
    needs_it = ("python", 'print(open("made.txt").read())\n')
    (tmp_path / "wrong").mkdir()
    (tmp_path / "right").mkdir()
    failed = run_walkthrough([needs_it, later], tmp_path / "wrong")
    assert failed is not None and failed[0] == 0 and "FileNotFoundError" in failed[1]
    assert run_walkthrough([later, needs_it], tmp_path / "right") is None


def test_the_walkthrough_is_read_in_the_pages_order():
    text = "## Intro\n```python\nskipped\n```\n## Quickstart 1\n```python\na\n```\n```bash\n" \
           "hsddp-gym rollout --episodes 2  # run it\n```\n## Quickstart 2\n```python\nb\n```\n## Other\n" \
           "```bash\nhsddp-gym demo\n```\n"
    assert walkthrough_steps(text, "Quickstart") == [("python", "a\n"), ("command", "hsddp-gym rollout --episodes 2"),
                                                     ("python", "b\n")]


def test_smoke_sizes_apply_and_a_stale_one_is_caught():
    for page, substitutions in SMOKE_SIZES.items():
        assert page in WALKTHROUGHS
        smoke = smoke_size(page, PAGES[page])
        assert all(written not in smoke or written in substitutions.values() for written in substitutions)
    SMOKE_SIZES["<test page>"] = {"--episodes 24": "--episodes 2"}
    try:
        assert smoke_size("<test page>", "hsddp-gym dataset --episodes 24") == "hsddp-gym dataset --episodes 2"
        with pytest.raises(AssertionError, match="no longer occurs"):
            smoke_size("<test page>", "hsddp-gym dataset --episodes 48")
    finally:
        del SMOKE_SIZES["<test page>"]


@pytest.mark.slow
@pytest.mark.parametrize("page", sorted(WALKTHROUGHS))
def test_the_walkthrough_runs_top_to_bottom_in_a_fresh_folder(tmp_path, page):
    steps = walkthrough_steps(smoke_size(page, PAGES[page]), WALKTHROUGHS[page])
    assert sum(kind == "python" for kind, _ in steps) >= 3 and any(kind == "command" for kind, _ in steps)
    failed = run_walkthrough(steps, tmp_path)
    if failed is not None:
        index, stderr = failed
        pytest.fail(f"{page}: step {index} of the walkthrough fails in a fresh folder:\n{steps[index][1]}\n"
                    f"--- stderr:\n{stderr}")


def test_the_two_setup_commands_install_every_extra_a_command_asks_for():
    """`pip install "torch==2.13.0" && pip install -e ".[all]"` must cover every package that
    :mod:`hsddp_gym.util.extras` can ask for, so the README's commands stay the whole set-up."""
    from hsddp_gym.util.extras import _PIP_NAMES, EXTRAS

    setup = re.findall(r'^python3 -m venv .*pip install -e "\.\[all\]".*$', README, flags=re.M)
    assert len(setup) == 2 and all('pip install "torch==2.13.0" && pip install -e ".[all]"' in c for c in setup)
    assert setup[0].endswith("hsddp-gym demo") and setup[1].endswith("python -m pytest -q")
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    optional = project["optional-dependencies"]
    assert set(re.findall(r"\[(.*)\]", optional["all"][0])[0].split(",")) >= {"rl", "data", "viz"}

    def names(reqs):
        return {re.split(r"[\[<>=; ]", r, maxsplit=1)[0].lower() for r in reqs}

    for module, (extra, _) in EXTRAS.items():
        pip_name = _PIP_NAMES.get(module, module).lower()
        if extra == "torch":
            continue  # installed by the first half of the command
        listed = names(optional[extra])
        implied = {"h5py": "minari", "imageio": "imageio"}  # minari[hdf5] brings h5py
        assert pip_name in listed or implied.get(pip_name) in listed, (module, extra)


def test_the_cpu_wheel_advice_names_the_pinned_torch():
    """The README and Getting started tell a stock Linux machine how to get torch's CPU wheel, for the version that
    the set-up commands pin."""
    pinned = set(re.findall(r'pip install "torch==([^"]+)" &&', README))
    assert len(pinned) == 1
    for page in ("README.md", "docs/getting-started.md"):
        advice = re.findall(r'pip install "torch==([^"]+)" --index-url https://download\.pytorch\.org/whl/cpu$',
                            PAGES[page], flags=re.M)
        assert advice == list(pinned), (page, advice, pinned)


# --- the site --------------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site built once with ``mkdocs build --strict``."""
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings")
    out = tmp_path_factory.mktemp("site")
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(out)],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-4000:]
    return out


def test_the_site_builds_strict_and_renders_every_documented_module(site):
    """``mkdocs build --strict``: no broken link or anchor, no missing page or reference, no docstring warning; every
    ``::: module`` of the API pages is on its page."""
    for page in sorted((ROOT / "docs" / "api").glob("*.md")):
        html = (site / "api" / ("" if page.stem == "index" else page.stem) / "index.html").read_text()
        for name in re.findall(r"^::: ([\w.]+)", page.read_text(), flags=re.M):
            assert f'id="{name}"' in html, f"{page.name}: {name} is not rendered"


def public_modules() -> set[str]:
    """Every public module of the package (no part starting with ``_``), the command line's aside (its reference is
    ``hsddp-gym --help``)."""
    import pkgutil

    import hsddp_gym
    import hsddp_gym.envs
    import hsddp_gym.planners

    found = {"hsddp_gym.envs", "hsddp_gym.planners"}
    for pkg in (hsddp_gym, hsddp_gym.planners, hsddp_gym.envs):
        for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."):
            if not any(part.startswith("_") for part in m.name.split(".")):
                found.add(m.name)
    return {m for m in found if not (m == "hsddp_gym.cli" or m.startswith("hsddp_gym.cli."))}


def test_every_public_module_has_an_api_page():
    documented = {name for page in (ROOT / "docs" / "api").glob("*.md")
                  for name in re.findall(r"^::: ([\w.]+)", page.read_text(), flags=re.M)}
    missing = sorted(public_modules() - documented)
    assert not missing, f"public modules without an API page: {missing}"
    assert "hsddp_gym.planners.policies.mpc.schedule" in documented and "hsddp_gym.registry" in documented


ROLE = re.compile(r":(?:class|func|meth|attr|data|mod|exc|obj):`")


def test_no_sphinx_role_reaches_the_site_or_the_docstrings(site):
    """The docstrings link with mkdocstrings' Markdown cross-references (``[`Name`][path]``); a Sphinx role would
    show as raw text."""
    shown = [str(p.relative_to(site)) for p in site.rglob("*.html") if ROLE.search(p.read_text())]
    assert not shown, f"raw Sphinx roles in {shown}"
    unlinked = [str(p.relative_to(site)) for p in site.rglob("*.html") if "][hsddp_gym." in p.read_text()]
    assert not unlinked, f"cross-references shown as raw text in {unlinked}"
    written = [str(p) for root in ("hsddp_gym", "planners", "envs") for p in (ROOT / root).rglob("*.py")
               if p.name != "_planar_terms.py" and "def generate" not in p.read_text() and ROLE.search(p.read_text())]
    assert not written, f"Sphinx roles in the docstrings of {written}"
    assert ROLE.search("see :class:`Terrain`") and not ROLE.search("see [`Terrain`][hsddp_gym.core.terrain.Terrain]")


def test_a_broken_anchor_fails_the_strict_build(tmp_path):
    """The repository's ``validation`` settings make a link to a missing heading fail ``mkdocs build --strict``."""
    yaml = pytest.importorskip("yaml")
    validation = yaml.safe_load((ROOT / "mkdocs.yml").read_text())["validation"]
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "index.md").write_text("# Home\n\n[there](other.md#no-such-heading)\n")
    (tmp_path / "docs" / "other.md").write_text("# Other\n\n## A heading\n")
    config = {"site_name": "t", "strict": True, "validation": validation, "nav": ["index.md", "other.md"]}
    (tmp_path / "mkdocs.yml").write_text(yaml.safe_dump(config))
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "-d", str(tmp_path / "site")], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode != 0 and "#no-such-heading" in res.stderr, res.stderr[-2000:]
    (tmp_path / "docs" / "index.md").write_text("# Home\n\n[there](other.md#a-heading)\n")
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "-d", str(tmp_path / "site")], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]


NAVIGATION_RELS = {"canonical", "alternate", "next", "prev", "author", "license", "help"}
"""``<link rel>`` values that name another page rather than load something into this one."""
CSS_URL = re.compile(r"""url\(\s*['"]?([^'")\s]+)|@import\s+['"]([^'"]+)""")


def is_foreign(url: str) -> bool:
    """Whether ``url`` points at another host (``http://``, ``https://`` or protocol-relative ``//``)."""
    return re.match(r"\s*(https?:)?//", url, flags=re.I) is not None


class _LoadedURLs(HTMLParser):
    """The URLs a page loads: ``src`` of scripts, images and media, ``<link href>`` but navigation links, and the
    ``url(...)`` / ``@import`` of its ``<style>`` blocks and ``style`` attributes."""

    def __init__(self):
        super().__init__()
        self.urls: list[str] = []
        self._in_style = False

    def handle_starttag(self, tag, attrs):
        a = {k: v or "" for k, v in attrs}
        if tag in ("script", "img", "iframe", "source", "audio", "video", "embed", "track", "input") and a.get("src"):
            self.urls.append(a["src"])
        if tag == "link" and a.get("href") and not set(a.get("rel", "").lower().split()) <= NAVIGATION_RELS:
            self.urls.append(a["href"])
        if tag == "object" and a.get("data"):
            self.urls.append(a["data"])
        self.urls += css_urls(a.get("style", ""))
        self._in_style = tag == "style"

    def handle_endtag(self, tag):
        self._in_style = False

    def handle_data(self, data):
        if self._in_style:
            self.urls += css_urls(data)


def css_urls(css: str) -> list[str]:
    return [a or b for a, b in CSS_URL.findall(css)]


def foreign_resources(site: Path) -> list[str]:
    """``"file: url"`` for every script, stylesheet, font or image that a built site's HTML or CSS loads from another
    host."""
    found = []
    for path in sorted(site.rglob("*")):
        if path.suffix == ".html":
            parser = _LoadedURLs()
            parser.feed(path.read_text(errors="replace"))
            urls = parser.urls
        elif path.suffix == ".css":
            urls = css_urls(path.read_text(errors="replace"))
        else:
            continue
        found += [f"{path.relative_to(site)}: {url}" for url in urls if is_foreign(url)]
    return found


def test_foreign_resources_are_found_in_html_and_css(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "index.html").write_text(
        '<link rel="stylesheet" href="//fonts.example/css"><link rel="next" href="https://example.org/">'
        '<link rel="icon" href="../favicon.png"><script src="https://cdn.example/x.js"></script>'
        '<script src="local.js"></script><a href="https://example.org/">a page elsewhere</a>'
        '<style>@font-face { src: url("HTTPS://fonts.example/f.woff2") }</style><div style="background: url(b.png)">')
    (tmp_path / "site.css").write_text('@import "https://x.example/y.css"; .m { src: url(data:font/woff2;base64,AA) }'
                                       " .n { src: url('../fonts/a.woff') }")
    assert foreign_resources(tmp_path) == [
        "a/index.html: //fonts.example/css", "a/index.html: https://cdn.example/x.js",
        "a/index.html: HTTPS://fonts.example/f.woff2", "site.css: https://x.example/y.css"]


def test_the_site_loads_nothing_from_another_host(site):
    assert (site / "javascripts" / "mathjax" / "tex-chtml.js").is_file()
    assert foreign_resources(site) == []


# --- the site in a browser -------------------------------------------------------------------------------------------

CHROMIUM = shutil.which("chromium")
TEX_DELIMITERS = ("\\(", "\\)", "\\[", "\\]")


@contextlib.contextmanager
def serve(folder: Path):
    """Serve ``folder`` on 127.0.0.1 (Python's http.server); yields the base URL and the list of ``(path, status)``
    of the requests answered."""
    answered: list[tuple[str, int]] = []

    class Handler(http.server.SimpleHTTPRequestHandler):
        def log_request(self, code="-", size="-"):
            answered.append((self.path, int(getattr(code, "value", code))))

        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Handler, directory=str(folder)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}", answered
    finally:
        server.shutdown()
        server.server_close()


def chromium(args: list[str], profile: Path) -> str:
    """Run headless Chromium with no other host reachable than 127.0.0.1; returns its stdout."""
    res = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                          "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars",
                          f"--user-data-dir={profile}", "--host-resolver-rules=MAP * ~NOTFOUND , EXCLUDE 127.0.0.1",
                          "--virtual-time-budget=20000", *args],
                         capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, res.stderr[-3000:]
    return res.stdout


class _RenderedMath(HTMLParser):
    """In a page's DOM: the formulas (``arithmatex`` elements) with and without MathJax's output inside, MathJax's
    error marks, and text outside scripts and code that still holds a TeX delimiter."""

    SKIPPED = {"script", "style", "code", "pre", "textarea"}
    VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source", "track", "wbr"}

    def __init__(self):
        super().__init__()
        self.stack: list[tuple[str, bool]] = []  # (tag, is a formula)
        self.formulas = self.rendered = self.errors = 0
        self.raw_tex: list[str] = []
        self._formula_done = False

    def handle_starttag(self, tag, attrs):
        a = {k: v or "" for k, v in attrs}
        formula = "arithmatex" in a.get("class", "").split()
        if tag == "mjx-merror" or "data-mjx-error" in a:
            self.errors += 1
        if tag == "mjx-container" and any(f for _, f in self.stack) and not self._formula_done:
            self.rendered += 1
            self._formula_done = True
        if formula:
            self.formulas += 1
            self._formula_done = False
        if tag not in self.VOID:
            self.stack.append((tag, formula))

    def handle_endtag(self, tag):
        while self.stack:
            if self.stack.pop()[0] == tag:
                break

    def handle_data(self, data):
        if not any(t in self.SKIPPED for t, _ in self.stack) and any(d in data for d in TEX_DELIMITERS):
            self.raw_tex.append(" ".join(data.split())[:120])


def math_problems(dom: str) -> list[str]:
    """What is wrong with the formulas of a page's DOM after MathJax ran: formulas without MathJax's output, MathJax's
    error marks, TeX delimiters left in the text."""
    math = _RenderedMath()
    math.feed(dom)
    problems = [f"{math.formulas - math.rendered} of {math.formulas} formulas not rendered"] * (
        math.rendered != math.formulas)
    problems += [f"{math.errors} formulas MathJax could not typeset"] * (math.errors > 0)
    return problems + [f"TeX left in the text: {text}" for text in math.raw_tex]


@pytest.mark.skipif(CHROMIUM is None, reason="no chromium on PATH (Debian's package `chromium`): the browser test of "
                                             "the rendered formulas needs it")
def test_every_formula_renders_in_a_browser(site, tmp_path):
    """Each page with formulas in headless Chromium, served from the built site with no other host reachable: every
    formula is MathJax's output, no TeX delimiter is left in the text, MathJax's files all came from the site; and a
    screenshot of the HS-DDP page."""
    pages = sorted(str(p.parent.relative_to(site)) for p in site.rglob("index.html")
                   if 'class="arithmatex"' in p.read_text())
    assert "planner/hsddp" in pages, pages
    problems = []
    with serve(site) as (base, answered):
        for page in pages:
            dom = chromium(["--dump-dom", f"{base}/{page}/"], tmp_path / "profile")
            problems += [f"{page}: {problem}" for problem in math_problems(dom)]
            if page == "planner/hsddp":
                assert dom.count('class="arithmatex"') >= 30, "the HS-DDP page lost its formulas"
        shot = tmp_path / "hsddp.png"
        chromium([f"--screenshot={shot}", "--window-size=1280,2400", f"{base}/planner/hsddp/"], tmp_path / "profile")
    assert problems == []
    paths = {path for path, _ in answered}
    assert "/javascripts/mathjax/tex-chtml.js" in paths and any(p.endswith(".woff") for p in paths), sorted(paths)
    assert all(status < 400 for _, status in answered), [a for a in answered if a[1] >= 400]  # 304: cached
    png = shot.read_bytes()  # a blank page is about 8 kB, the page with its formulas over 200 kB
    assert png.startswith(b"\x89PNG") and len(png) > 50_000, len(png)


def test_math_problems_are_found_in_a_dom():
    rendered = '<p><span class="arithmatex"><mjx-container class="MathJax">x</mjx-container></span></p>'
    assert math_problems(rendered) == []
    assert math_problems('<p><span class="arithmatex">\\(x\\)</span></p>') == [
        "1 of 1 formulas not rendered", "TeX left in the text: \\(x\\)"]
    assert math_problems('<span class="arithmatex"><mjx-container><mjx-merror>\\foo</mjx-merror></mjx-container>'
                         '</span>') == ["1 formulas MathJax could not typeset"]
    assert math_problems('<nav><a><span class="md-ellipsis">Maps \\(P_i\\)</span></a></nav><code>\\(kept\\)</code>'
                         ) == ["TeX left in the text: Maps \\(P_i\\)"]
