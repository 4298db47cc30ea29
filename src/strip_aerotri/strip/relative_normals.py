"""The normal equations of the relative orientation, one small system per pair
solved at once: equilibrated to a unit diagonal, Cholesky with a pivot and
a trace test for singular pairs, and the damped (Levenberg-Marquardt) solve
(:mod:`.relative` iterates with them).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._typing import FloatArray

__all__: list[str] = []


# Singular normal matrices (after equilibration to a unit diagonal): a
# Cholesky pivot below _PIVOT_MIN or trace(N⁻¹) above _TRACE_MAX (condition
# number of order 1e10).
_PIVOT_MIN = 1e-13
_TRACE_MAX = 1e10


def _solve_normals(
    normal: FloatArray, gradient: FloatArray
) -> tuple[FloatArray, np.ndarray, FloatArray]:
    """Solve per-pair normal equations: (n_pairs, k, k), (n_pairs, k) ->
    corrections (n_pairs, k), a mask of pairs whose normal matrix is singular
    or not finite, and N⁻¹ (n_pairs, k, k).

    Cholesky of the equilibrated (unit-diagonal) matrices, written out over
    the k × k entries so that every operation runs on all pairs at once (a
    batched LAPACK call costs more per 5 × 5 matrix than the arithmetic).
    Singular: a pivot below 1e-13, or trace(N⁻¹) of the equilibrated matrix
    above 1e10, which bounds its condition number within a factor k.
    """
    k = normal.shape[-1]
    finite = np.asarray(
        np.isfinite(normal).all(axis=(1, 2)) & np.isfinite(gradient).all(axis=1), dtype=bool
    )
    diag = np.einsum("mii->mi", normal)
    scale = 1.0 / np.sqrt(np.where(finite[:, None] & (diag > 1e-300), diag, 1.0))
    a = (normal * scale[:, :, None] * scale[:, None, :]).transpose(1, 2, 0)  # (k, k, m)
    ok = finite.copy()
    low: list[list[Any]] = [[None] * k for _ in range(k)]  # L, entries (m,)
    for j in range(k):
        d = a[j, j].copy()
        for t in range(j):
            d -= low[j][t] * low[j][t]
        with np.errstate(invalid="ignore"):
            ok &= d > _PIVOT_MIN
        inv_pivot = 1.0 / np.sqrt(np.where(ok, d, 1.0))
        low[j][j] = 1.0 / inv_pivot
        for i in range(j + 1, k):
            s = a[i, j].copy()
            for t in range(j):
                s -= low[i][t] * low[j][t]
            low[i][j] = s * inv_pivot
    inv_low: list[list[Any]] = [[None] * k for _ in range(k)]  # L⁻¹ by forward substitution
    for j in range(k):
        inv_low[j][j] = 1.0 / low[j][j]
        for i in range(j + 1, k):
            s = low[i][j] * inv_low[j][j]
            for t in range(j + 1, i):
                s = s + low[i][t] * inv_low[t][j]
            inv_low[i][j] = -s / low[i][i]
    inverse = np.empty_like(a)  # N⁻¹ = L⁻ᵀ L⁻¹
    for r in range(k):
        for c in range(r, k):
            s = inv_low[c][r] * inv_low[c][c]
            for i in range(c + 1, k):
                s = s + inv_low[i][r] * inv_low[i][c]
            inverse[r, c] = s
            inverse[c, r] = s
    with np.errstate(invalid="ignore"):
        singular = ~ok | ~(np.einsum("iim->m", inverse) < _TRACE_MAX)
    g = np.where(finite[:, None], gradient, 0.0) * scale
    sol = np.einsum("ijm,mj->mi", inverse, g) * scale
    sol[singular] = 0.0
    return sol, singular, inverse.transpose(2, 0, 1) * scale[:, :, None] * scale[:, None, :]


def _solve_damped(normal: FloatArray, gradient: FloatArray, damping: FloatArray) -> FloatArray:
    """Levenberg-Marquardt corrections ``(N + λ diag N)⁻¹ g`` of a few pairs:
    (m, 5, 5), (m, 5), (m,) -> (m, 5); zero where the damped matrix is
    singular too."""
    diag = np.einsum("mii->mi", normal)
    scale = np.where(diag > 0.0, diag, np.maximum(diag.max(axis=1, keepdims=True), 1e-300))
    damped = normal + (damping[:, None] * scale)[:, :, None] * np.eye(normal.shape[-1])
    corr, singular, _ = _solve_normals(damped, gradient)
    corr[singular] = 0.0
    return corr
