"""Normal equations with a narrow band: factor, solve, selected inverse.

The normal matrix of a spline over many sections couples only neighbouring
unknowns: each observation row touches at most six of hundreds or thousands
of columns (the B-splines and hats of its section).  With the unknowns
ordered along the strip its nonzeros lie within a band of about 6 of the
diagonal, so in blocks of 64 unknowns it is block tridiagonal: the Cholesky
factor costs O(k B²), a solve O(k B), and the blocks of the inverse on the
three diagonals, which hold every entry the redundancy numbers need, come
from Takahashi's recursion in O(k B²), instead of O(k³) for a dense inverse
(1670 unknowns: a few ms instead of 250 ms).  numpy alone: importing
scipy.linalg would cost a run 0.25 s.

Like the dense path (similarity._normal_inverse) the matrix is equilibrated
to unit diagonal first, and its condition number is that of the
equilibrated matrix in the 1-norm, ``‖N⁻¹‖₁`` estimated by Hager's method
(Higham 1988) from a few solves, or by the largest diagonal entry of the
inverse when that is larger.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray

#: Unknowns per block (at least the band; a power of two).
BLOCK = 64
_SHIFT = BLOCK.bit_length() - 1
_MASK = BLOCK - 1
#: A band wider than this fraction 1/n of the unknowns is not worth it.
MAX_BAND_FRACTION = 8


class BandedNormals:
    """``N = Aᵀ A`` of whitened rows given by their nonzero entries.

    Build with :meth:`from_rows`; ``cond`` is the condition number estimate
    (inf when N is not positive definite), :meth:`solve` gives ``N⁻¹ b`` and
    :meth:`quadratic_forms` the ``aᵢᵀ N⁻¹ aᵢ`` of rows.
    """

    def __init__(
        self, order: IntArray, scale: FloatArray, diagonal: FloatArray, below: FloatArray
    ):
        self._order = order  # unknown at each position
        self._position = np.empty_like(order)
        self._position[order] = np.arange(order.size)
        self._scale = scale  # 1 / sqrt(diag N) by position (1 in the padding)
        k = order.size
        # 1-norm of the equilibrated matrix: column sums of the diagonal
        # blocks, of the blocks below and of those above (the transposes).
        colsum = np.abs(diagonal).sum(axis=1) + np.abs(below).sum(axis=1)
        colsum[1:] += np.abs(below[:-1]).sum(axis=2)
        self._norm = float(colsum.reshape(-1)[:k].max())
        self._inverse_diagonal, self._factor_below = _block_cholesky(diagonal, below)
        self._selected: tuple[FloatArray, FloatArray] | None = None

    @classmethod
    def from_rows(
        cls, index: IntArray, value: FloatArray, n_columns: int, order: IntArray
    ) -> BandedNormals | None:
        """From the rows' nonzero columns ``index`` (n, w) and values ``value``
        (n, w) (zero-padded, as similarity.RowSupport), with the unknowns taken
        in `order` (e.g. along the strip); None when the band in that order is
        wider than the block or than ``n_columns // MAX_BAND_FRACTION``."""
        k = n_columns
        position = np.empty(k, dtype=np.intp)
        position[order] = np.arange(k)
        p = position[index]
        nonzero = value != 0.0
        # the band: the widest spread of a row's nonzero positions
        spread = np.where(nonzero, p, -1).max(axis=1) - np.where(nonzero, p, k).min(axis=1)
        band = int(spread.max(initial=0))
        if band > BLOCK or band > k // MAX_BAND_FRACTION:
            return None
        n_blocks = -(-k // BLOCK)
        # Every product of two entries of a row (padding and zeros add 0); the
        # products of a block above the diagonal are those below it swapped,
        # which take the same slot: each counts once.
        size = n_blocks * 2 * BLOCK * BLOCK
        slots, lower = _slots(p[:, :, None], p[:, None, :])
        np.clip(slots, 0, size - 1, out=slots)  # padding paired afar: its product is 0
        product = value[:, :, None] * value[:, None, :]
        product *= lower
        # with weights bincount gives float64 (the stubs say intp throughout)
        blocks: FloatArray = np.bincount(  # type: ignore[assignment]
            slots.reshape(-1), product.reshape(-1), minlength=size
        ).reshape(n_blocks, 2, BLOCK, BLOCK)
        diagonal = blocks[:, 0].copy()
        below = blocks[:, 1].copy()  # below[J] = N[block J + 1, block J]; the last is 0
        diag = np.diagonal(diagonal, axis1=1, axis2=2).reshape(-1).copy()
        diag[k:] = 1.0  # padding of the last block: unit, uncoupled
        order = np.asarray(order, dtype=np.intp)
        if np.any(diag[:k] <= 0.0):
            return cls(order, np.ones(diag.size), _not_definite(diagonal), below * 0.0)
        scale = 1.0 / np.sqrt(diag)
        s = scale.reshape(n_blocks, BLOCK)
        diagonal *= s[:, :, None] * s[:, None, :]
        below[:-1] *= s[1:, :, None] * s[:-1, None, :]
        idx = np.arange(k, n_blocks * BLOCK)
        diagonal.reshape(n_blocks * BLOCK, BLOCK)[idx, idx % BLOCK] = 1.0
        return cls(order, scale, diagonal, below)

    @property
    def cond(self) -> float:
        """1-norm condition number (estimate) of the equilibrated matrix."""
        if self._inverse_diagonal is None:
            return np.inf
        inverse_norm = _inverse_norm_1(self._solve_padded, self._order.size, self._scale.size)
        z_diag = np.diagonal(self.selected_inverse()[0], axis1=1, axis2=2).reshape(-1)
        z_diag = z_diag[: self._order.size]
        if not np.isfinite(inverse_norm) or np.any(z_diag <= 0.0):
            return np.inf
        # Hager's estimate can miss a null vector orthogonal to its trial
        # vectors (two unknowns that only move together); the largest
        # diagonal entry of the inverse cannot, and bounds ‖N⁻¹‖₂ within k.
        return self._norm * max(inverse_norm, float(z_diag.max()))

    def _solve_padded(self, rhs: FloatArray) -> FloatArray:
        """Solve with the equilibrated matrix, rhs (k_padded,) by position."""
        inv, below = self._inverse_diagonal, self._factor_below
        assert inv is not None  # only a definite matrix is solved (cond is inf otherwise)
        n_blocks = inv.shape[0]
        b = rhs.reshape(n_blocks, BLOCK)
        y = np.empty_like(b)
        y[0] = inv[0] @ b[0]
        for j in range(1, n_blocks):  # forward: L y = b
            y[j] = inv[j] @ (b[j] - below[j - 1] @ y[j - 1])
        x = np.empty_like(b)
        x[-1] = inv[-1].T @ y[-1]
        for j in range(n_blocks - 2, -1, -1):  # backward: Lᵀ x = y
            x[j] = inv[j].T @ (y[j] - below[j].T @ x[j + 1])
        return x.reshape(-1)

    def solve(self, rhs: FloatArray) -> FloatArray:
        """``N⁻¹ rhs`` for rhs of shape (k,), in the unknowns' own order."""
        k = self._order.size
        padded = np.zeros(self._scale.size)
        padded[:k] = rhs[self._order] * self._scale[:k]
        y = self._solve_padded(padded)[:k] * self._scale[:k]
        out = np.empty(k)
        out[self._order] = y
        return out

    def selected_inverse(self) -> tuple[FloatArray, FloatArray]:
        """Blocks of the equilibrated matrix's inverse on the diagonal and
        below it (Takahashi's recursion, :func:`_block_takahashi`)."""
        if self._selected is None:
            assert self._inverse_diagonal is not None  # as _solve_padded
            self._selected = _block_takahashi(self._inverse_diagonal, self._factor_below)
        return self._selected

    def quadratic_forms(self, index: IntArray, value: FloatArray) -> FloatArray:
        """``aᵢᵀ N⁻¹ aᵢ`` for rows given by their nonzero entries (n, w)."""
        z_diagonal, z_below = self.selected_inverse()
        z = np.stack([z_diagonal, z_below], axis=1).reshape(-1)
        p = self._position[index]  # (n, w)
        w = value * self._scale[p]
        # padding has value 0: any slot it gets is multiplied by 0
        slots, _ = _slots(p[:, :, None], p[:, None, :])
        np.clip(slots, 0, z.size - 1, out=slots)
        forms: FloatArray = np.einsum("nij,ni,nj->n", np.take(z, slots), w, w)
        return forms


def _slots(p_a: IntArray, p_b: IntArray) -> tuple[IntArray, BoolArray]:
    """Flat index, in blocks (n_blocks, 2, BLOCK, BLOCK) of the diagonal and of
    the one below it, of the entry (p_a, p_b) of a symmetric matrix (taken
    from the lower triangle of blocks: the pair is swapped when p_a's block
    is above p_b's), and where p_a's block is not above p_b's (broadcast).
    Shifts and masks: BLOCK is a power of two, and numpy's integer division
    is several times slower."""
    block_a, block_b = p_a >> _SHIFT, p_b >> _SHIFT
    lower = block_a >= block_b
    row = np.where(lower, p_a, p_b)
    col = np.where(lower, p_b, p_a)
    block_col = np.minimum(block_a, block_b)
    which = np.abs(block_a - block_b)  # 0 diagonal, 1 below
    within = ((row & _MASK) << _SHIFT) + (col & _MASK)
    return (((block_col << 1) + which) << (2 * _SHIFT)) + within, lower


def _not_definite(diagonal: FloatArray) -> FloatArray:
    out = np.zeros_like(diagonal)
    out[0, 0, 0] = -1.0  # the factorisation refuses it: cond is inf
    return out


def _block_cholesky(
    diagonal: FloatArray, below: FloatArray
) -> tuple[FloatArray | None, FloatArray]:
    """Lower block Cholesky factor of a block tridiagonal matrix: the inverses
    of its diagonal blocks L_JJ⁻¹ and its blocks below, L_J+1,J = N_J+1,J L_JJ⁻ᵀ;
    (None, ...) when the matrix is not positive definite."""
    n_blocks = diagonal.shape[0]
    inverse = np.empty_like(diagonal)
    factor_below = np.empty_like(below)
    schur = diagonal[0]
    for j in range(n_blocks):
        try:
            lower = np.linalg.cholesky(schur)
        except np.linalg.LinAlgError:
            return None, factor_below
        inverse[j] = np.linalg.inv(lower)
        if j + 1 < n_blocks:
            factor_below[j] = below[j] @ inverse[j].T
            schur = diagonal[j + 1] - factor_below[j] @ factor_below[j].T
    return inverse, factor_below


def _block_takahashi(
    inverse: FloatArray, factor_below: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Blocks of ``Z = N⁻¹`` on the diagonal and below it, from the lower
    block factor (L_JJ⁻¹ and L_J+1,J).

    ``Lᵀ Z = L⁻¹`` with L⁻¹ lower triangular; block row J of it gives, from
    the last block up (Takahashi's recursion):

        Z_J+1,J = -Z_J+1,J+1 L_J+1,J L_JJ⁻¹
        Z_JJ    =  L_JJ⁻ᵀ (L_JJ⁻¹ - L_J+1,Jᵀ Z_J+1,J)

    (sequential over the blocks; each step a few products of blocks).
    """
    n_blocks = inverse.shape[0]
    z_diagonal = np.empty_like(inverse)
    z_below = np.zeros_like(inverse)
    z_diagonal[-1] = inverse[-1].T @ inverse[-1]
    for j in range(n_blocks - 2, -1, -1):
        z_below[j] = -(z_diagonal[j + 1] @ factor_below[j]) @ inverse[j]
        z_diagonal[j] = inverse[j].T @ (inverse[j] - factor_below[j].T @ z_below[j])
    return z_diagonal, z_below


def _inverse_norm_1(
    solve: Callable[[FloatArray], FloatArray], k: int, k_padded: int | None = None
) -> float:
    """Estimate of ``‖A⁻¹‖₁`` for a symmetric A from solves (Hager 1984, with
    Higham's 1988 alternating vector as a safeguard); a lower bound, as a rule
    within a factor 3 of the true value.  `solve` takes vectors of
    `k_padded` entries (default k), of which the first k are A's."""
    n = k if k_padded is None else k_padded

    def solve_k(x: FloatArray) -> FloatArray:
        padded = np.zeros(n)
        padded[:k] = x
        return solve(padded)[:k]

    x = np.full(k, 1.0 / k)
    estimate = 0.0
    for _ in range(5):
        y = solve_k(x)
        norm = float(np.abs(y).sum())
        if norm <= estimate:
            break
        estimate = norm
        sign = np.where(y >= 0.0, 1.0, -1.0)
        z = solve_k(sign)  # Aᵀ = A
        j = int(np.argmax(np.abs(z)))
        if abs(z[j]) <= float(z @ x):
            break
        x = np.zeros(k)
        x[j] = 1.0
    alternating = (-1.0) ** np.arange(k) * (1.0 + np.arange(k) / max(k - 1, 1))
    return max(estimate, 2.0 * float(np.abs(solve_k(alternating)).sum()) / (3.0 * k))
