"""A symmetric block-banded matrix: LAPACK's banded Cholesky and the band of its inverse.

The matrix has ``n`` diagonal blocks of size ``d`` and nonzero blocks only
within ``w`` blocks of the diagonal.  It is held as its lower block band
``band[J, o] = S[J + o, J]`` (shape (n, w + 1, d, d), blocks beyond the last
row are zero), converted to LAPACK's lower band storage (``ab[i - j, j] =
S[i, j]``, ``u = (w + 1) d - 1`` sub-diagonals) for
:func:`scipy.linalg.cholesky_banded`, equilibrated to unit diagonal first.

:func:`selected_inverse` gives the same block band of ``Z = S⁻¹`` by
Takahashi's recursion (Takahashi, Fagan & Chin 1973; Erisman & Tinney 1975)
from the last block column backwards:

    Z_>J,J = -Z_>J,>J L_>J,J L_JJ⁻¹
    Z_JJ   = L_JJ⁻ᵀ (L_JJ⁻¹ - L_>J,Jᵀ Z_>J,J)

where ``>J`` are the ``w`` block rows below J: each step needs only the part
of Z within the band, kept in a dense window of (w + 1) blocks that slides up
the diagonal.  A loop over the n block columns (sequential by nature), each
step a few products of a (w d) x (w d) window with a (w d) x d panel.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .._threads import interruptible
from .._typing import FloatArray, IntArray

__all__ = ["BandFactor", "band_to_lapack", "factor_band", "selected_inverse"]


#: Units moved at a time between the block band and LAPACK's storage: the
#: reordered copy of a few hundred units, not of the whole band.
_MOVE_UNITS = 256


def band_to_lapack(band: FloatArray) -> FloatArray:
    """LAPACK lower band storage ((w+1) d, n d) of a block band (n, w+1, d, d).

    Entry (a, b) of block [J, o] is S[(J + o) d + a, J d + b], row
    ``o d + a - b`` of column ``J d + b``: for each b the rows ``o d + a``
    of the blocks' column b, shifted up by b (the rows above the diagonal
    of the diagonal blocks fall off)."""
    n, w1, d, _ = band.shape
    ab = np.zeros((w1 * d, n, d))  # column J d + b as (J, b)
    for j0 in range(0, n, _MOVE_UNITS):
        part = band[j0 : j0 + _MOVE_UNITS]
        by_row = part.transpose(1, 2, 0, 3).reshape(w1 * d, part.shape[0], d)  # [o d + a, J, b]
        for b in range(d):
            ab[: w1 * d - b, j0 : j0 + part.shape[0], b] = by_row[b:, :, b]
    return ab.reshape(w1 * d, n * d)


def lapack_to_band(ab: FloatArray, n: int, d: int) -> FloatArray:
    """The inverse of :func:`band_to_lapack` (upper triangles of diagonal blocks 0)."""
    w1 = ab.shape[0] // d
    view = ab.reshape(w1 * d, n, d)
    band = np.empty((n, w1, d, d))
    for j0 in range(0, n, _MOVE_UNITS):
        j1 = min(n, j0 + _MOVE_UNITS)
        by_row = np.zeros((w1 * d, j1 - j0, d))
        for b in range(d):
            by_row[b:, :, b] = view[: w1 * d - b, j0:j1, b]
        band[j0:j1] = by_row.reshape(w1, d, j1 - j0, d).transpose(2, 0, 1, 3)
    # entries past the last row (J + o >= n) are not the matrix's
    for off in range(1, w1):
        band[max(n - off, 0) :, off] = 0.0
    return band


@dataclass(frozen=True)
class BandFactor:
    """``D S D = L Lᵀ`` of an equilibrated block band.

    ``factor`` LAPACK's lower band storage of L, ``scale`` the diagonal of D
    (n d,), ``min_pivot`` the smallest ``L_ii²`` (the relative pivot of the
    equilibrated matrix, whose diagonal is 1) and ``min_pivot_index`` its
    scalar index in the band's order."""

    factor: FloatArray
    scale: FloatArray
    n: int
    d: int
    min_pivot: float
    min_pivot_index: int

    def solve(self, rhs: FloatArray) -> FloatArray:
        """``S⁻¹ rhs`` for rhs (n d,) or (n d, k), in the band's order."""
        from scipy.linalg import cho_solve_banded

        s = self.scale if rhs.ndim == 1 else self.scale[:, None]
        x: FloatArray = cho_solve_banded((self.factor, True), s * rhs, check_finite=False)
        return s * x


#: N b² (flops of the factor, about 0.4 ns each) above which the factor runs
#: through _threads.interruptible: from about 20 ms on, so that Ctrl-C does not
#: wait for the seconds a wide block's factor takes (docs/scaling.md).
_LONG_FACTOR = 5e7


class NotPositiveDefinite(Exception):
    """The band is not positive definite; ``index`` the scalar row (band order)
    at which the factorisation stopped, or the first non-positive diagonal."""

    def __init__(self, index: int):
        super().__init__(f"not positive definite at row {index}")
        self.index = index


def factor_band(band: FloatArray) -> BandFactor:
    """Equilibrate and factor a block band (n, w+1, d, d); NotPositiveDefinite
    when a diagonal entry is not positive or LAPACK's factorisation stops."""
    from scipy.linalg import LinAlgError, cholesky_banded

    n, _, d, _ = band.shape
    ab = band_to_lapack(band)
    diag = ab[0].copy()
    bad = ~(diag > 0.0)
    if np.any(bad):
        raise NotPositiveDefinite(int(np.flatnonzero(bad)[0]))
    scale = 1.0 / np.sqrt(diag)
    for i in range(ab.shape[0]):  # row i of ab holds S[j + i, j]
        ab[i, : n * d - i] *= scale[i:] * scale[: n * d - i]
    try:
        if ab.size * ab.shape[0] > _LONG_FACTOR:  # seconds on a wide block: Ctrl-C acts
            factor = interruptible(
                cholesky_banded, ab, lower=True, overwrite_ab=True, check_finite=False
            )
        else:  # ab is this function's own: factorised in place
            factor = cholesky_banded(ab, lower=True, overwrite_ab=True, check_finite=False)
    except LinAlgError as exc:
        found = re.search(r"(\d+)", str(exc))
        raise NotPositiveDefinite(int(found.group(1)) - 1 if found else 0) from exc
    pivots = factor[0] ** 2
    j = int(np.argmin(pivots))
    return BandFactor(factor, scale, n, d, float(pivots[j]), j)


#: Units joined into one block of the recursion: about this many scalars a
#: block, so that a step is a few products of matrices of some size rather
#: than many of 6 x 6 blocks (the Python loop then runs n d / 36 times).
_RECURSION_BLOCK = 36


def selected_inverse(bf: BandFactor) -> FloatArray:
    """The block band of ``S⁻¹`` (n, w+1, d, d), ``[J, o] = (S⁻¹)[J + o, J]``,
    by Takahashi's recursion on the factor (see the module docstring).

    The recursion runs on blocks of ``m`` units at a time (``m d`` about
    :data:`_RECURSION_BLOCK`; the factor padded with identity rows to a
    whole number of blocks, which leaves Z's band unchanged), and the units'
    blocks are taken out of its band at the end."""
    n, d = bf.n, bf.d
    w1 = bf.factor.shape[0] // d
    m = max(1, min(w1, _RECURSION_BLOCK // d))
    big, wide = m * d, -(-(w1 - 1) // m) + 1  # block size and band blocks of the recursion
    n_big = -(-n // m)
    ab = np.zeros((wide * big, n_big * big))
    ab[: w1 * d, : n * d] = bf.factor
    ab[0, n * d :] = 1.0  # identity rows: Z is the identity there, decoupled
    lf = lapack_to_band(ab, n_big, big)
    del ab
    zb = _takahashi(lf).reshape(n_big, wide, m, d, m, d)  # (n_big, wide, big, big)
    del lf
    # unit block (J m + a, o) lies in zb[J, (a + o) // m] at rows (a + o) % m, column a
    out = np.empty((n_big, m, w1, d, d))
    for a in range(m):
        for o in range(w1):
            out[:, a, o] = zb[:, (a + o) // m, (a + o) % m, :, a, :]
    del zb
    z: FloatArray = out.reshape(n_big * m, w1, d, d)[:n]
    # undo the equilibration: S⁻¹ = D Z̃ D
    s = bf.scale.reshape(n, d)
    rows = np.arange(n)[:, None] + np.arange(w1)[None, :]
    s_rows = np.where((rows < n)[:, :, None], s[np.minimum(rows, n - 1)], 0.0)
    z *= s_rows[:, :, :, None]
    z *= s[:, None, None, :]
    return z


def _takahashi(lf: FloatArray) -> FloatArray:
    """Takahashi's recursion on the block band of L (n, w+1, d, d), ``[J, o] =
    L[J + o, J]``: the block band of ``(L Lᵀ)⁻¹``, unscaled."""
    n, w1, d, _ = lf.shape
    w = w1 - 1
    lf[:, 0] = np.tril(lf[:, 0])
    l_inv = np.linalg.inv(lf[:, 0])  # (n, d, d) lower
    # panel[J]: L[J+1 .. J+w, J] stacked (w d, d); zero beyond the last row
    panel = lf[:, 1:].reshape(n, w * d, d)
    z = np.zeros((n, w1, d, d))
    wd = w * d
    # The part of Z within the band near block J, in a buffer that the
    # recursion walks up the diagonal of: buf[top:top + wd, top:top + wd] is
    # Z over blocks J+1 .. J+w at step J (zero beyond the last block); each
    # step writes block row and column J just above and left of it.  When the
    # walk reaches the buffer's corner the window is copied back down (once
    # every w + 1 steps), so a step copies O(w d²), not the (w d)² window.
    home = w1 * d
    buf = np.zeros((home + wd, home + wd))
    top = home
    for j in range(n - 1, -1, -1):
        if top == 0:
            buf[home : home + wd, home : home + wd] = buf[:wd, :wd]
            top = home
        below = buf[top : top + wd, top : top + wd]  # Z over blocks J+1 .. J+w
        col = -(below @ panel[j]) @ l_inv[j]
        diag = l_inv[j].T @ (l_inv[j] - panel[j].T @ col)
        diag = 0.5 * (diag + diag.T)
        z[j, 0] = diag
        z[j, 1:] = col.reshape(w, d, d)
        top -= d
        buf[top : top + d, top : top + d] = diag
        buf[top + d : top + d + wd, top : top + d] = col
        buf[top : top + d, top + d : top + d + wd] = col.T
    return z
