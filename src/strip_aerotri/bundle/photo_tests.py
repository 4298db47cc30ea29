"""Tests of the photos' direct observations (GNSS centres, IMU attitudes) in
the bundle: Baarda's w along chosen axes from the residuals' cofactors
(:func:`strip_aerotri.bundle.snooping.refine_frame`'s notes)."""

from __future__ import annotations

import numpy as np

from .._typing import ArrayLike, BoolArray, FloatArray

__all__: list[str] = []


def _photo_flags(values: ArrayLike | None, m: int, name: str) -> BoolArray:
    """Per-photo booleans (M,), all True when not given."""
    if values is None:
        return np.ones(m, bool)
    flags = np.array(values, dtype=bool)
    if flags.shape != (m,):
        raise ValueError(f"Expected `{name}` to have shape {(m,)}, got {flags.shape}")
    return flags


def _photo_tests(
    v: FloatArray, q_vv: FloatArray, sigma: FloatArray, axes: FloatArray, on: BoolArray
) -> tuple[FloatArray, FloatArray]:
    """w-tests and residuals along ``axes`` of the direct photo observations in use.

    ``v`` (M, 3) observed minus adjusted in the frame, ``q_vv`` (M, 3, 3)
    residual cofactors, ``sigma`` (M, 3), ``axes`` (M, 3, 3) or (3, 3)
    (columns: test directions in the frame), ``on`` (M,) the photos whose
    observation is in the adjustment.  Returns ``w`` and the residuals along
    the axes, both (M, 3), NaN for photos not in use.
    """
    m = v.shape[0]
    w = np.full((m, 3), np.nan)
    v_axes = np.full((m, 3), np.nan)
    rows = np.flatnonzero(on)
    if rows.size:
        a = np.broadcast_to(axes, (m, 3, 3))[rows]
        # unobserved components (weight 0) carry NaN: they take no part
        v_rows = np.nan_to_num(v[rows], nan=0.0)
        q_rows = np.nan_to_num(q_vv[rows], nan=0.0)  # all NaN without precision: w NaN
        _, w[rows] = _directional_tests(v_rows, q_rows, 1.0 / sigma[rows] ** 2, a)
        v_axes[rows] = np.einsum("gia,gi->ga", a, v_rows)
    return w, v_axes


def _directional_tests(
    v: FloatArray, q_vv: FloatArray, weight: FloatArray, axes: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Redundancy numbers and w-tests of direct observations along given axes.

    Parameters
    ----------
    v : ndarray, shape (G, 3)
        Observed minus adjusted, frame axes.
    q_vv : ndarray, shape (G, 3, 3)
        Cofactor matrices of the residuals, frame axes.
    weight : ndarray, shape (G, 3)
        Diagonal weights ``1 / sigma**2`` along the frame axes.
    axes : ndarray, shape (G, 3, 3)
        Columns: the test directions as unit vectors in the frame.

    Returns
    -------
    redundancy, w : ndarray, shape (G, 3)
        ``diag(Aᵀ Q_vv P A)`` and ``dᵀ P v / sqrt(dᵀ P Q_vv P d)`` per column
        ``d`` of ``A``; w is NaN where the component has no redundancy.
    """
    pa = weight[:, :, None] * axes  # P A
    redundancy = np.einsum("gia,gij,gja->ga", axes, q_vv, pa)
    denominator = np.einsum("gia,gij,gja->ga", pa, q_vv, pa)
    numerator = np.einsum("gia,gi->ga", pa, v)
    ok = denominator > 1e-12 * np.einsum("gia,gia->ga", pa, axes)
    w = np.where(ok, numerator / np.sqrt(np.where(ok, denominator, 1.0)), np.nan)
    return redundancy, w
