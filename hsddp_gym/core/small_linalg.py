"""Compiled (numba) linear algebra for the small symmetric positive definite systems of the planner: the 4x4
``Q_uu`` of the backward pass and the 7x7 mass matrix and <= 4x4 Delassus matrix of the contact dynamics."""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, fastmath=False)
def cholesky_solve(A, B, L, out):
    """Solve ``A X = B`` for the SPD ``A`` (m, m) through its Cholesky factor, written into ``L`` (m, m; lower
    triangle), the solution into ``out`` (m, ncol) for ``B`` (m, ncol). Returns False (``out`` undefined) when ``A``
    is not positive definite: a pivot at or below 1e-12, or not finite (a NaN or inf matrix is not PD)."""
    m = A.shape[0]
    for i in range(m):
        for j in range(i + 1):
            s = A[i, j]
            for p in range(j):
                s -= L[i, p] * L[j, p]
            if i == j:
                if not 1e-12 < s < np.inf:
                    return False
                L[i, i] = np.sqrt(s)
            else:
                L[i, j] = s / L[j, j]
    ncol = B.shape[1]
    for c in range(ncol):
        for i in range(m):  # forward: L y = b
            s = B[i, c]
            for p in range(i):
                s -= L[i, p] * out[p, c]
            out[i, c] = s / L[i, i]
        for i in range(m - 1, -1, -1):  # backward: L^T x = y
            s = out[i, c]
            for p in range(i + 1, m):
                s -= L[p, i] * out[p, c]
            out[i, c] = s / L[i, i]
    return True
