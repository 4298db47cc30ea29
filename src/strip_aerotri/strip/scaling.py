"""Scale transfer from one model to the next on tie points (method.md §5).

Each model is formed with a unit base; its scale relative to the previous
model follows from the tie points (points in the triple overlap, determined
in both models), measured from the projection centre the two models share.
The functions take the tie points of all models at once.
"""

from __future__ import annotations

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ..options import ScaleTransfer

__all__ = ["ScaleTransfer", "scale_ratios", "scale_ratios_distance", "scale_ratios_z"]


def _prepare(
    previous: ArrayLike, new: ArrayLike, model: ArrayLike
) -> tuple[FloatArray, FloatArray, IntArray]:
    previous = np.asarray(previous, dtype=np.float64)
    new = np.asarray(new, dtype=np.float64)
    model = np.asarray(model, dtype=np.intp)
    if previous.ndim != 2 or previous.shape[1] != 3 or new.shape != previous.shape:
        raise ValueError(
            f"Expected previous and new to have shape (t, 3), got {previous.shape} and {new.shape}"
        )
    if model.shape != (previous.shape[0],):
        raise ValueError(f"Expected model to have shape ({previous.shape[0]},), got {model.shape}")
    return previous, new, model


def scale_ratios_z(
    previous: ArrayLike, new: ArrayLike, model: ArrayLike, n_models: int
) -> FloatArray:
    """Scale of each model relative to the previous one from Z components, J(13)-(15).

    With ``u = k̃ l_z`` (the Z component of the tie point in the new model
    formed with the unit base, measured from the shared projection centre) and
    ``d`` the Z component of the same point in the previous model, measured
    from the same centre, the least-squares scale is ``Σ u d / Σ u²`` (J(15);
    the fixed J(13) has ``−λ`` in ``Δr_z = r'_z − s_lz − λ k̃ l_z``).

    Parameters
    ----------
    previous, new : array_like, shape (t, 3)
        Tie points relative to the shared projection centre, in the previous
        and in the new model's (unit-base) units.
    model : array_like of int, shape (t,)
        Index of the new model of each tie point.
    n_models : int

    Returns
    -------
    ndarray, shape (n_models,)
        Ratio new-model scale / previous-model scale; NaN for models without
        tie points.
    """
    previous, new, model = _prepare(previous, new, model)
    u = new[:, 2]
    num = np.bincount(model, u * previous[:, 2], minlength=n_models)
    den = np.bincount(model, u * u, minlength=n_models)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio: FloatArray = np.where(den > 0, num / np.where(den > 0, den, 1.0), np.nan)
        return ratio


def scale_ratios_distance(
    previous: ArrayLike, new: ArrayLike, model: ArrayLike, n_models: int
) -> FloatArray:
    """Scale ratio from distances to the shared projection centre, B(139)-(140).

    ``k = D / D'`` per tie point, D and D' its distances from the shared
    centre in the previous and the new model; the mean is taken over the tie
    points of the model.  Arguments and result as :func:`scale_ratios_z`.
    """
    previous, new, model = _prepare(previous, new, model)
    ratio = np.linalg.norm(previous, axis=1) / np.linalg.norm(new, axis=1)
    total = np.bincount(model, ratio, minlength=n_models)
    count = np.bincount(model, minlength=n_models)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean: FloatArray = np.where(count > 0, total / np.maximum(count, 1), np.nan)
        return mean


def scale_ratios(
    previous: ArrayLike,
    new: ArrayLike,
    model: ArrayLike,
    n_models: int,
    *,
    method: ScaleTransfer | str = ScaleTransfer.Z,
) -> FloatArray:
    """Dispatch to :func:`scale_ratios_z` or :func:`scale_ratios_distance`."""
    if ScaleTransfer(method) is ScaleTransfer.Z:
        return scale_ratios_z(previous, new, model, n_models)
    return scale_ratios_distance(previous, new, model, n_models)
