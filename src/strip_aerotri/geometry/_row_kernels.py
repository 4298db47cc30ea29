"""Row kernels of the simultaneous transformation of units
(:mod:`strip_aerotri.geometry.simultaneous`): work on every unit row (n,
3 × 3 blocks) split into blocks for the worker thread, the rows' whitening
``Lᵀ`` (the Cholesky factor of their weights) and its ``L Lᵀ``, each written
out in closed form."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._typing import FloatArray

__all__ = ["by_rows", "row_gram", "rows_whitening", "upper_entries", "upper_times"]

#: The entries (i, k) of an upper-triangular 3 x 3 matrix, in their order in
#: :func:`upper_entries`.
_UPPER = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def by_rows(n_rows: int, block: Callable[[slice], object]) -> None:
    """``block(rows)`` for consecutive blocks of the ``n_rows`` rows, shared
    with the worker thread of :func:`~strip_aerotri._threads.compute_workers`
    where one is open (:func:`~strip_aerotri.geometry.simultaneous.adjust_units`
    opens it): each block reads and writes its own rows only, so the result
    is that of one call on all rows, bit for bit."""
    from .._threads import split_map
    from ._normal_entries import spans

    split_map(block, spans(n_rows))


def rows_whitening(weight: FloatArray) -> FloatArray:
    """``Lᵀ`` of each row's weight ``W = L Lᵀ`` (n, 3, 3): ``‖Lᵀ v‖² = vᵀ W v``
    (the Cholesky factor in closed form)."""
    from ._normal_entries import lower_factor

    entries = lower_factor(weight)
    if not np.all(entries[[0, 2, 5]] > 0.0) or not np.all(np.isfinite(entries)):
        raise ValueError("Expected positive definite row weights")
    upper = np.zeros(weight.shape)
    for k, (i, j) in enumerate(((0, 0), (0, 1), (1, 1), (0, 2), (1, 2), (2, 2))):
        upper[:, i, j] = entries[k]  # Lᵀ[i, j] = L[j, i]
    return upper


def row_gram(lt: FloatArray) -> FloatArray:
    """``L Lᵀ`` of every row's whitening ``Lᵀ`` (n, 3, 3): its six distinct
    entries, each a sum of three products (a batched 3 x 3 product costs
    three times as much)."""
    out = np.empty(lt.shape)
    for i in range(3):
        for j in range(i + 1):
            value = lt[:, 0, i] * lt[:, 0, j]
            value += lt[:, 1, i] * lt[:, 1, j]
            value += lt[:, 2, i] * lt[:, 2, j]
            out[:, i, j] = value
            out[:, j, i] = value
    return out


def upper_entries(upper: FloatArray) -> FloatArray:
    """The six entries of upper-triangular 3 x 3 matrices (n, 3, 3) as
    (6, n), in the order of :data:`_UPPER`."""
    return np.stack([upper[:, i, k] for i, k in _UPPER])


def upper_times(entries: FloatArray, g: FloatArray) -> FloatArray:
    """``U G`` (b, 3, 3) of upper-triangular U given by its :func:`upper_entries`
    (6, b) and G entry-major (9, b), entry ``3 k + j`` its (k, j): 18 products
    over long vectors (a batched product of 3 x 3 matrices takes half as
    long again)."""
    place = {ik: m for m, ik in enumerate(_UPPER)}
    b = g.shape[1]
    out = np.empty((9, b))
    term = np.empty(b)
    for i in range(3):
        for j in range(3):
            target = out[3 * i + j]
            np.multiply(entries[place[(i, i)]], g[3 * i + j], out=target)
            for k in range(i + 1, 3):
                np.multiply(entries[place[(i, k)]], g[3 * k + j], out=term)
                target += term
    return out.T.reshape(b, 3, 3)
