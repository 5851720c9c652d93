"""MkDocs hook of the documentation site: the two build inputs that do not live in ``docs/``.

* **The package as it is imported, for the API pages.** ``pyproject.toml`` installs the folders ``envs/`` and
  ``planners/`` as ``hsddp_gym.envs`` and ``hsddp_gym.planners`` (``[tool.setuptools] package-dir``). mkdocstrings
  reads modules from the folders in its python handler's ``paths`` (mkdocs.yml); this hook lays ``hsddp_gym`` out
  there as Python imports it: a folder ``hsddp_gym/`` of symbolic links to the entries of ``hsddp_gym/`` and to each
  mapped folder under its import name.
* **MathJax's files, for the formulas.** The pages load MathJax from the site itself (no other host): the files of
  MathJax 3 that the ``docs`` extra installs (the package ``django-static-mathjax``: MathJax's own distribution,
  Apache-2.0, no dependencies) are added to the site under ``javascripts/mathjax/``.
"""

from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

from mkdocs.plugins import event_priority
from mkdocs.structure.files import File

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the backport
    import tomli as tomllib

ROOT = Path(__file__).resolve().parent
PACKAGE = "hsddp_gym"
MATHJAX_URI = "javascripts/mathjax"
# MathJax's combined TeX-to-HTML component, its fonts, and what it may load on demand (TeX extensions that an
# autoloaded macro asks for; the context menu's accessibility options and their speech rules); paths in its es5/.
MATHJAX_FILES = ("tex-chtml.js", "output/chtml/fonts/woff-v2", "input/tex/extensions", "ui", "a11y", "sre")


def mapped_packages(pyproject: Path = ROOT / "pyproject.toml") -> dict[str, Path]:
    """``{"envs": ROOT/envs, "planners": ROOT/planners}``: the subpackages of ``hsddp_gym`` that live outside its
    folder, from ``pyproject.toml``'s ``package-dir``."""
    package_dir = tomllib.loads(pyproject.read_text())["tool"]["setuptools"].get("package-dir", {})
    mapped = {}
    for name, folder in package_dir.items():
        top, _, sub = name.partition(".")
        if top != PACKAGE or not sub:
            continue
        if "." in sub:
            raise ValueError(f"package-dir: expected {PACKAGE}.NAME mapped to a folder, got {name!r}")
        mapped[sub] = pyproject.parent / folder
    return mapped


def lay_out_package(folder: Path) -> Path:
    """Write ``folder/hsddp_gym``: links to every entry of ``hsddp_gym/`` and to each mapped subpackage; returns it."""
    target = folder / PACKAGE
    if target.is_symlink() or target.is_file():
        target.unlink()
    elif target.exists():
        shutil.rmtree(target)
    target.mkdir(parents=True)
    entries = {p.name: p for p in (ROOT / PACKAGE).iterdir() if p.name != "__pycache__"}
    entries.update(mapped_packages())
    for name, path in entries.items():
        (target / name).symlink_to(path, target_is_directory=path.is_dir())
    return target


def _api_source_folder(config) -> Path:
    handler = config.plugins["mkdocstrings"].config.handlers["python"]
    paths = handler.get("paths", [])
    if len(paths) != 1:
        raise ValueError(f"mkdocstrings' python handler: expected one entry in paths (the folder this hook writes "
                         f"{PACKAGE}/ into), got {paths!r}")
    return Path(config.config_file_path).parent / paths[0]


def mathjax_folder() -> Path:
    """The folder of MathJax's ``es5`` distribution that the ``docs`` extra installs."""
    spec = importlib.util.find_spec("mathjax")
    if spec is None or not spec.submodule_search_locations:
        raise ModuleNotFoundError('MathJax\'s files are missing: pip install -e ".[docs]" (django-static-mathjax)')
    root = Path(next(iter(spec.submodule_search_locations))) / "static" / "mathjax"
    if not (root / "es5" / "tex-chtml.js").is_file():
        raise FileNotFoundError(f"no MathJax 3 distribution in {root}")
    return root


def mathjax_files(config) -> list[File]:
    """The site's files ``javascripts/mathjax/...``: :data:`MATHJAX_FILES` and MathJax's license."""
    root = mathjax_folder()
    es5 = root / "es5"
    sources = {"LICENSE": root / "LICENSE"}
    for name in MATHJAX_FILES:
        path = es5 / name
        for src in [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file()):
            sources[src.relative_to(es5).as_posix()] = src
    return [File.generated(config, f"{MATHJAX_URI}/{uri}", abs_src_path=str(src)) for uri, src in sources.items()]


@event_priority(100)  # before mkdocstrings reads its paths (it keeps only folders that exist)
def on_config(config):
    """Lay the package out where mkdocstrings looks for it."""
    lay_out_package(_api_source_folder(config))
    return config


def on_files(files, config):
    """Add MathJax's files to the site."""
    for file in mathjax_files(config):
        files.append(file)
    return files
