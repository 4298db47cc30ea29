"""The bundle's given observations: their values, weights and checks, and
the photos' order for a narrow reduced normal matrix."""

from __future__ import annotations

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray

__all__ = ["along_axis_order", "check_rotations", "given_weights", "observed_with_sigma"]


def along_axis_order(centres: FloatArray) -> IntArray:
    """The photos by their place along the main axis of their centres' plan:
    along a strip the strip's order, in a block across the strips (the
    classical numbering), so that the reduced normal matrix is narrow."""
    xy = centres[:, :2] - centres[:, :2].mean(axis=0)
    if xy.shape[0] < 2:
        return np.arange(xy.shape[0], dtype=np.intp)
    _, _, vt = np.linalg.svd(xy, full_matrices=False)
    return np.argsort(xy @ vt[0], kind="stable").astype(np.intp)


def observed_with_sigma(
    values: ArrayLike,
    sigma: ArrayLike | None,
    shape: tuple[int, ...],
    name: str,
    sigma_name: str,
) -> tuple[FloatArray, FloatArray]:
    """Observations of ``shape`` (NaN where absent) and their standard
    deviations, broadcast to (shape[0], 3): three per point or photo (the
    coordinates of a point or centre, the angles of an attitude); `name` and
    `sigma_name` are the arguments' names for the messages."""
    vals = np.asarray(values, dtype=np.float64)
    if vals.shape != shape:
        raise ValueError(f"Expected `{name}` to have shape {shape}, got {vals.shape}")
    if sigma is None:
        raise ValueError(f"`{name}` given without its standard deviations (`{sigma_name}`)")
    return vals, np.broadcast_to(np.asarray(sigma, dtype=np.float64), (shape[0], 3))


def given_weights(
    values: ArrayLike | None,
    sigma: ArrayLike | None,
    shape: tuple[int, ...],
    name: str,
    sigma_name: str,
) -> tuple[FloatArray, FloatArray]:
    """Given values with NaN where absent and their sigmas -> (values 0-filled, weights)."""
    if values is None:
        return np.zeros(shape), np.zeros(shape)
    vals, sig = observed_with_sigma(values, sigma, shape, name, sigma_name)
    used = np.isfinite(vals) & np.isfinite(sig)
    if np.any(sig[used] <= 0.0):
        raise ValueError(f"Expected positive standard deviations for `{name}`")
    weight = np.zeros(shape)
    weight[used] = 1.0 / sig[used] ** 2
    return np.where(used, vals, 0.0), weight


def check_rotations(rotations: FloatArray, name: str) -> None:
    err = np.abs(np.einsum("...ji,...jk->...ik", rotations, rotations) - np.eye(3))
    bad = ~np.all(err < 1e-6, axis=(-2, -1)) | ~(np.linalg.det(rotations) > 0.0)
    if np.any(bad):
        raise ValueError(
            f"Expected `{name}` to hold proper rotation matrices, "
            f"entry {int(np.flatnonzero(bad)[0])} is not"
        )
