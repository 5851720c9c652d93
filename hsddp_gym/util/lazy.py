"""Lazy re-exports for package ``__init__`` modules: ``from pkg import Name`` without importing every module."""

from __future__ import annotations

import importlib


def lazy_exports(package: str, exports: dict[str, tuple[str, ...]]):
    """``(__getattr__, __dir__)`` for package ``package`` whose submodule ``package.module`` defines the public
    names ``exports[module]``.

    The defining module is imported on first access, so importing the package stays cheap and package
    ``__init__`` files import nothing (the layer test sees every real import edge)."""

    where = {name: module for module, names in exports.items() for name in names}

    def __getattr__(name: str):
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{module}"), name)

    def __dir__() -> list[str]:
        return sorted(where)

    return __getattr__, __dir__
