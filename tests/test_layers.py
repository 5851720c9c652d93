"""The package's import graph, built from the source with ``ast``: no cycles, and imports only point down the layers
(docs/architecture.md): util <- core <- {optimizer, viz, registry}; registry <- envs (the perturbation conditions
read the tasks); optimizer <- policies <- tasks;
everything <- rollout <- datasets <- learning <- workflows <- cli; learning <- reports <- benchmarks."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    tomllib = pytest.importorskip("tomli")

ROOT = Path(__file__).resolve().parents[1]

ROOMS = {  # module-name prefix -> room (the longest matching prefix wins)
    "hsddp_gym": "root",
    "hsddp_gym.util": "util",
    "hsddp_gym.core": "core",
    "hsddp_gym.viz": "viz",
    "hsddp_gym.planners": "planners",
    "hsddp_gym.planners.optimizer": "optimizer",
    "hsddp_gym.planners.policies": "policies",
    "hsddp_gym.planners.tasks": "tasks",
    "hsddp_gym.planners.motions": "tasks",  # planning tasks beside the paper's
    "hsddp_gym.envs": "envs",
    "hsddp_gym.datasets": "datasets",
    "hsddp_gym.learning": "learning",
    "hsddp_gym.workflows": "workflows",
    "hsddp_gym.cli": "cli",
    "hsddp_gym.reports": "reports",
    "hsddp_gym.registry": "registry",
    "hsddp_gym.rollout": "rollout",
    "hsddp_gym.benchmarks": "benchmarks",
}
_BELOW = {
    "root": {"registry", "core"},  # registers the registry's envs (the registry and core's task constants: pure Python)
    "planners": set(),
    "util": set(),
    "core": {"util"},
    "registry": {"core"},
    "viz": {"util", "core"},
    "optimizer": {"util", "core"},
    "envs": {"util", "core", "viz", "registry"},  # the perturbation conditions build any task's env
    "policies": {"util", "core", "optimizer"},
    "tasks": {"util", "core", "optimizer", "policies"},
    "rollout": {"util", "core", "viz", "optimizer", "policies", "tasks", "envs", "registry"},
}
_BELOW["datasets"] = _BELOW["rollout"] | {"rollout"}
_BELOW["learning"] = _BELOW["datasets"] | {"datasets"}
_BELOW["workflows"] = _BELOW["learning"] | {"learning"}
_BELOW["cli"] = _BELOW["workflows"] | {"workflows"}
_BELOW["reports"] = _BELOW["learning"] | {"learning"}  # tables and figures from the results store
_BELOW["benchmarks"] = _BELOW["reports"] | {"reports"}  # the experiments' shared evaluations
ALLOWED = {room: below | {room, "root"} for room, below in _BELOW.items()}
"""Rooms each room may import (``root``, the registering ``hsddp_gym/__init__``, imports nothing and may be
imported by anyone)."""


def source_modules(root: Path = ROOT) -> dict[str, Path]:
    """``{module name: file}`` of the installed package, from pyproject's ``package-dir`` mapping."""
    cfg = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]
    modules = {}
    for package, folder in cfg["package-dir"].items():
        base = root / folder
        for f in sorted(base.rglob("*.py")):
            rel = f.relative_to(base).with_suffix("").parts
            name = ".".join((package, *rel[:-1])) if rel[-1] == "__init__" else ".".join((package, *rel))
            if name.split(".")[1:2] in (["planners"], ["envs"]) and package == "hsddp_gym":
                continue  # never: the folders are not inside hsddp_gym/
            modules[name] = f
    return modules


def import_edges(modules: dict[str, Path]) -> dict[str, set[str]]:
    """``{module: {imported modules of the package}}``, every import statement counted (also inside functions)."""
    edges = {}
    for name, path in modules.items():
        is_pkg = path.name == "__init__.py"
        out = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = name.split(".") if is_pkg else name.split(".")[:-1]
                    parts = parts[: len(parts) - node.level + 1]
                    base = ".".join([*parts, base] if base else parts)
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
            for t in targets:
                while t and t not in modules:  # `import a.b.c` imports a.b.c (and its packages)
                    t = t.rpartition(".")[0]
                if t and t != name:
                    out.add(t)
        edges[name] = out
    return edges


def room_of(module: str) -> str | None:
    best = None
    for prefix in ROOMS:
        if module == prefix or module.startswith(prefix + "."):
            if best is None or len(prefix) > len(best):
                best = prefix
    return ROOMS[best] if best is not None else None


def layer_violations(edges: dict[str, set[str]]) -> list[str]:
    bad = []
    for src, targets in edges.items():
        rs = room_of(src)
        if rs is None:
            bad.append(f"{src}: in no room (add it to ROOMS and docs/architecture.md)")
            continue
        for t in sorted(targets):
            rt = room_of(t)
            if rt not in ALLOWED[rs]:
                bad.append(f"{src} ({rs}) imports {t} ({rt})")
    return bad


def find_cycle(edges: dict[str, set[str]]) -> list[str] | None:
    """One import cycle ``[a, b, ..., a]``, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(u):
        state[u] = 1
        stack.append(u)
        for v in sorted(edges.get(u, ())):
            if state.get(v) == 1:
                return stack[stack.index(v):] + [v]
            if v not in state:
                found = visit(v)
                if found:
                    return found
        stack.pop()
        state[u] = 2
        return None

    for u in sorted(edges):
        if u not in state:
            found = visit(u)
            if found:
                return found
    return None


@pytest.fixture(scope="module")
def edges():
    return import_edges(source_modules())


def test_the_graph_covers_the_package(edges):
    assert "hsddp_gym.planners.optimizer.hsddp" in edges and "hsddp_gym.envs.bounding" in edges
    assert "hsddp_gym.planners.optimizer.problem" in edges["hsddp_gym.planners.optimizer.hsddp"]
    assert "hsddp_gym.core.dynamics" in edges["hsddp_gym.planners.optimizer.problem"]
    assert not [m for m in edges if m.startswith(("planners", "envs"))]


def test_no_import_cycles(edges):
    assert find_cycle(edges) is None, " -> ".join(find_cycle(edges))


def test_imports_point_down_the_layers(edges):
    assert layer_violations(edges) == []


def test_the_checks_fail_on_a_cycle_and_on_an_upward_import():
    bad = {"hsddp_gym.core.model": {"hsddp_gym.planners.policies.mpc"},
           "hsddp_gym.planners.policies.mpc": {"hsddp_gym.core.model"}, "elsewhere.module": set()}
    assert find_cycle(bad) is not None
    violations = layer_violations(bad)
    assert "hsddp_gym.core.model (core) imports hsddp_gym.planners.policies.mpc (policies)" in violations
    assert "elsewhere.module: in no room (add it to ROOMS and docs/architecture.md)" in violations
    assert not any(v.startswith("hsddp_gym.planners.policies.mpc") for v in violations)  # policies -> core is fine


def test_relative_and_function_level_imports_are_seen(tmp_path):
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "__init__.py").write_text("")
    (tmp_path / "pkg" / "a.py").write_text("def f():\n    from . import b\n    from .b import g\n")
    (tmp_path / "pkg" / "b.py").write_text("import pkg.a\n")
    mods = {"pkg": tmp_path / "pkg/__init__.py", "pkg.a": tmp_path / "pkg/a.py", "pkg.b": tmp_path / "pkg/b.py"}
    e = import_edges(mods)
    assert e["pkg.a"] == {"pkg.b"} and e["pkg.b"] == {"pkg.a"}
    assert find_cycle(e) is not None


@pytest.mark.parametrize("package", ["hsddp_gym.planners.policies", "hsddp_gym.datasets", "hsddp_gym.learning",
                                     "hsddp_gym.learning.sb3", "hsddp_gym.envs", "hsddp_gym.envs.perturbations"])
def test_lazy_reexports_resolve_to_their_defining_modules(package):
    import importlib

    pkg = importlib.import_module(package)
    for module, names in pkg._EXPORTS.items():
        defining = importlib.import_module(f"{package}.{module}")
        for name in names:
            assert getattr(pkg, name) is getattr(defining, name)
    with pytest.raises(AttributeError, match="no attribute 'nothing_here'"):
        pkg.nothing_here  # noqa: B018
