"""The relaxed barrier function of order k = 2 (paper eq. 27; Hauser & Saccon 2006).

For a constraint ``c >= 0`` with relaxation ``delta > 0``::

    B(c) = -log(c)                                              c >  delta
    B(c) = 1/2 [((c - 2 delta) / delta)^2 - 1] - log(delta)     c <= delta

It is C2 at ``c = delta``: value ``-log(delta)``, slope ``-1/delta`` and curvature ``1/delta^2`` from both
sides (the authors' MATLAB code used curvature 1 in the relaxed branch; the correct 1/delta^2 is used here).
"""

from __future__ import annotations

import numpy as np


def relaxed_barrier(c: np.ndarray, delta) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Value, first and second derivative of the relaxed barrier, elementwise.

    Args:
        c: constraint values (any shape). delta: relaxation (> 0), a scalar or broadcastable to ``c``.
    Returns:
        ``(B, dB/dc, d2B/dc2)`` with the shape of ``c``.
    """
    c = np.asarray(c, dtype=np.float64)
    delta = np.asarray(delta, dtype=np.float64)
    if np.any(delta <= 0) or not np.all(np.isfinite(delta)):
        raise ValueError(f"delta must be finite and > 0, got {delta}")
    delta = np.broadcast_to(delta, c.shape)
    inner = c > delta
    safe = np.where(inner, c, 1.0)
    t = (np.minimum(c, delta) - 2.0 * delta) / delta  # used in the relaxed branch only: no overflow for c >> delta
    value = np.where(inner, -np.log(safe), 0.5 * (t * t - 1.0) - np.log(delta))
    slope = np.where(inner, -1.0 / safe, t / delta)
    with np.errstate(over="ignore"):  # c > 1e154: safe * safe overflows to inf and the curvature is its limit, 0
        curvature = np.where(inner, 1.0 / (safe * safe), 1.0 / (delta * delta))
    return value, slope, curvature
