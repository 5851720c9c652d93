"""MkDocs hook of the documentation site: let mkdocstrings find ``hsddp_gym.envs`` and ``hsddp_gym.planners``.

``pyproject.toml`` installs the folders ``envs/`` and ``planners/`` as ``hsddp_gym.envs`` and ``hsddp_gym.planners``
(``[tool.setuptools] package-dir``). Python imports them through that mapping, but griffe (the static analysis
behind mkdocstrings) looks for the submodules of ``hsddp_gym`` only inside the folder ``hsddp_gym/``. This hook
adds the mapped folders to the submodules griffe finds for ``hsddp_gym``, read from ``pyproject.toml``, so the API
pages can document ``hsddp_gym.envs.bounding`` and ``hsddp_gym.planners.policies.mpc`` under their import names.
"""

from __future__ import annotations

from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: the backport
    import tomli as tomllib

ROOT = Path(__file__).resolve().parent


def _mapped_packages() -> dict[tuple[str, ...], Path]:
    """``{("envs",): ROOT/envs, ("planners",): ROOT/planners}``: the subpackages of ``hsddp_gym`` that live outside
    its folder, from ``pyproject.toml``'s ``package-dir``."""
    setup = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    mapped = {}
    for name, folder in setup.get("package-dir", {}).items():
        parts = tuple(name.split("."))
        if len(parts) == 2 and parts[0] == "hsddp_gym":
            mapped[parts[1:]] = ROOT / folder
    return mapped


def _patch_griffe() -> None:
    from griffe._internal import finder

    if getattr(finder.ModuleFinder, "_hsddp_gym_package_dir", False):
        return
    mapped = _mapped_packages()
    submodules = finder.ModuleFinder.submodules

    def submodules_with_package_dir(self, module):
        found = list(submodules(self, module))
        if module.path == "hsddp_gym":
            for parts, folder in mapped.items():
                found.append((parts, folder / "__init__.py"))
                found += [(parts + sub, path) for sub, path in self.iter_submodules(folder / "__init__.py")]
            found.sort(key=lambda item: len(item[0]))
        return found

    finder.ModuleFinder.submodules = submodules_with_package_dir
    finder.ModuleFinder._hsddp_gym_package_dir = True


def on_startup(command, dirty):  # noqa: ARG001  (the MkDocs hook signature)
    """Patch griffe once, before mkdocstrings loads any module."""
    _patch_griffe()


_patch_griffe()
