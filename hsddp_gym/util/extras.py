"""Optional dependencies ("extras"): check that a job's imports are installed before the job starts.

``pip install -e ".[all]"`` installs every extra; with the core dependencies only (numpy, gymnasium, Pinocchio,
numba, tqdm) planning, the env and the policies work, and a job that needs more says which extra to install
before it starts ([`require`][require]), instead of failing on a raw import after minutes of work.
"""

from __future__ import annotations

import importlib.util

# import name -> (extra, what to install)
EXTRAS = {
    "minari": ("data", 'pip install "hsddp_gym[data]"  (from a clone: pip install -e ".[data]")'),
    "h5py": ("data", 'pip install "hsddp_gym[data]"  (from a clone: pip install -e ".[data]")'),
    "torch": ("torch", 'pip install "torch==2.13.0"  (the CPU build, see the README)'),
    "stable_baselines3": ("rl", 'pip install "torch==2.13.0" && pip install "hsddp_gym[rl]"  '
                                '(from a clone: pip install -e ".[rl]")'),
    "matplotlib": ("viz", 'pip install "hsddp_gym[viz]"  (from a clone: pip install -e ".[viz]")'),
    "PIL": ("viz", 'pip install "hsddp_gym[viz]"  (from a clone: pip install -e ".[viz]")'),
    "imageio": ("viz", 'pip install "hsddp_gym[viz]"  (from a clone: pip install -e ".[viz]")'),
    "ray": ("ray", 'pip install "hsddp_gym[ray]"  (from a clone: pip install -e ".[ray]")'),
    "mujoco": ("mujoco", 'pip install "hsddp_gym[mujoco]"  (from a clone: pip install -e ".[mujoco]")'),
}
_PIP_NAMES = {"PIL": "pillow", "stable_baselines3": "stable-baselines3"}


class MissingExtraError(ImportError):
    """A job needs optional packages that are not installed; the message names them and the extra to install.
    The ``hsddp-gym`` CLI prints it as one ``error: ...`` line and exits with code 2."""


def is_installed(module: str) -> bool:
    """Whether ``module`` (a top-level import name) can be imported, without importing it."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):  # a broken install, or a finder refusing the name
        return False


def missing(modules) -> list[str]:
    """The names of ``modules`` that are not installed."""
    return [m for m in modules if not is_installed(m)]


def require(modules, purpose: str) -> None:
    """Raise [`MissingExtraError`][MissingExtraError] if any of ``modules`` (import names, e.g. ``"minari"``) is
    missing.

    Args:
        purpose: what needs them, e.g. ``"hsddp-gym dataset"`` (starts the message).
    """
    absent = missing(modules)
    if not absent:
        return
    names = ", ".join(_PIP_NAMES.get(m, m) for m in absent)
    howto = []
    for m in absent:
        extra, cmd = EXTRAS.get(m, (None, f"pip install {_PIP_NAMES.get(m, m)}"))
        if cmd not in howto:
            howto.append(cmd)
    extras = sorted({EXTRAS[m][0] for m in absent if m in EXTRAS and EXTRAS[m][0] != "torch"})
    what = f"the {' and '.join(repr(e) for e in extras)} extra{'s' if len(extras) > 1 else ''}" if extras else ""
    if "torch" in absent:
        what = f"{what} and torch" if what else "torch"
    raise MissingExtraError(f"{purpose} needs {names} ({what}), which {'is' if len(absent) == 1 else 'are'} not "
                            f"installed; install with: {' ; '.join(howto)}")
