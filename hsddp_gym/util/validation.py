"""Argument checks that raise errors naming the argument, the expected and the received value."""

from __future__ import annotations

import numbers

import numpy as np


def check_vector(value, size: int, name: str) -> np.ndarray:
    """Return ``value`` as a finite float64 vector of length ``size`` or raise ``ValueError``/``TypeError``."""
    arr = _as_float_array(value, name, f"an array of {size} numbers")
    if arr.shape != (size,):
        raise ValueError(f"{name} must have shape ({size},), got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr}")
    return arr


def check_array(value, shape: tuple, name: str) -> np.ndarray:
    """Return ``value`` as a finite float64 array of ``shape`` (``None`` entries match any size)."""
    arr = _as_float_array(value, name, f"a numeric array of shape {shape}")
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (found NaN or inf)")
    return arr


def _as_float_array(value, name: str, what: str) -> np.ndarray:
    raw = np.asarray(value)
    if np.iscomplexobj(raw):
        raise TypeError(f"{name} must be real, got complex values")
    try:
        return np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name} must be {what}, got {type(value).__name__}") from exc


def real_array(value, name: str) -> np.ndarray:
    """``value`` as a real array (dtype kind ``f``, ``i`` or ``u``; shape unchecked), the one rule the single and
    vector envs apply to actions. An object array (e.g. of Python ints) becomes float64 entry by entry.

    Raises ``TypeError`` for what is not a real number (text, complex, bools in an object array) and
    ``ValueError`` ("must be finite") for entries too large for a float, e.g. ``10**400``."""
    if isinstance(value, np.ndarray) and value.dtype.kind in "fiu":
        return value
    try:
        a = np.asarray(value)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{name} must be an array of real numbers, got {value!r}") from exc
    kind = a.dtype.kind
    if kind in "fiu":
        return a
    if kind == "c":
        raise TypeError(f"{name} must be real, got the complex array {a!r}")
    if kind != "O":
        raise TypeError(f"{name} must be an array of real numbers, got dtype {a.dtype} ({value!r})")
    entries = a.ravel().tolist()
    for v in entries:
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
            raise TypeError(f"{name} must hold real numbers, got {v!r} of type {type(v).__name__}")
    try:
        return np.array([float(v) for v in entries], dtype=np.float64).reshape(a.shape)
    except OverflowError as exc:
        raise ValueError(f"{name} must be finite, got entries too large for a float: {value!r}") from exc


def check_positive(value, name: str, *, allow_zero: bool = False) -> float:
    """A finite real number > 0 (or >= 0 with ``allow_zero``)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    value = float(value)
    ok = value >= 0.0 if allow_zero else value > 0.0
    if not (np.isfinite(value) and ok):
        raise ValueError(f"{name} must be a finite number {'>=' if allow_zero else '>'} 0, got {value!r}")
    return value


def check_int(value, name: str, *, minimum: int = 0) -> int:
    """An integer >= ``minimum``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def check_in_range(value, lo: float, hi: float, name: str) -> float:
    """A finite real number in ``[lo, hi]``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__}")
    value = float(value)
    if not (np.isfinite(value) and lo <= value <= hi):
        raise ValueError(f"{name} must be in [{lo}, {hi}], got {value!r}")
    return value


def did_you_mean(value: str, candidates) -> str:
    """``"did you mean X?"`` with ``X`` the candidate closest to ``value`` (`difflib.get_close_matches`), or
    ``""`` when none is close: the one wording of the command line's suggestions."""
    import difflib

    close = difflib.get_close_matches(str(value), [str(c) for c in candidates], n=1)
    return f"did you mean {close[0]}?" if close else ""


def parenthesized(*parts: str) -> str:
    """``" (a; b)"`` of the non-empty ``parts``, ``""`` when all are empty."""
    kept = [p for p in parts if p]
    return f" ({'; '.join(kept)})" if kept else ""


class UsageError(ValueError):
    """A user's mistake in one option or argument, caught before any long work starts.

    ``str(err)`` is one line ``"<option>: <what is wrong> (allowed: <what is allowed>)"``; the ``hsddp-gym``
    CLI prints it as ``error: ...`` and exits with code 2 (no traceback). A ``ValueError``, so Python callers
    handle it as any other bad argument."""

    def __init__(self, option: str, problem: str, allowed: str) -> None:
        self.option, self.problem, self.allowed = option, problem, allowed
        super().__init__(f"{option}: {problem} (allowed: {allowed})")


def check_output_dir(path, name: str = "out"):
    """``path`` as a `Path` that can be a directory to write into: a directory that exists, or
    a new path whose nearest existing ancestor is a writable directory. Raises [`UsageError`][UsageError] naming
    ``name`` otherwise (an existing file, a path through a file, no write permission)."""
    import os
    from pathlib import Path

    if str(path).strip() == "":
        raise UsageError(name, "an empty path", "a directory to write into, existing or new")
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise UsageError(name, f"{str(path)!r} is an existing file",
                         "a directory to write into, existing or new")
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise UsageError(name, f"{str(path)!r} lies inside the file {str(probe)!r}",
                         "a directory to write into, existing or new")
    if probe.exists() and not os.access(probe, os.W_OK | os.X_OK):
        raise UsageError(name, f"{str(probe)!r} is not writable", "a directory you can write into")
    return path
