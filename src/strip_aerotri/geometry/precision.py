"""Precision of points and projection centres from the collinearity geometry.

Information matrices (inverse covariances) in a Cartesian frame, from the
image rays with the image coordinates' standard deviations:

* :func:`ray_information` — of a point from one ray with the photo held
  fixed (a forward intersection adds those of its rays);
* :func:`centre_information` — of a projection centre from the rays of one
  photo to fixed points (a space resection: the 6 × 6 information of centre
  and attitude, the attitude eliminated).

Both use the collinearity equations of docs/bundle.md: with
``v = Rᵀ (X − S)``, ``x = −c v_x / v_z``, ``y = −c v_y / v_z`` (image
vectors ``(x, y, −c)`` in mm, ``R`` image -> frame).  The frame's unit is
whatever ``X`` and ``S`` are in (model units or metres); the information is
in 1 / unit².
"""

from __future__ import annotations

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ._normal_assembly import sum_into
from .collinearity import image_jacobian, image_vectors

__all__ = ["centre_information", "ray_information"]


def _image_jacobian(
    points: FloatArray, centres: FloatArray, rotations: FloatArray, principal_distance: float
) -> tuple[FloatArray, FloatArray]:
    """d(x, y)/d(frame coordinates of the point) of each ray, (n, 2, 3), and
    the image-system vectors v (n, 3)."""
    v = image_vectors(centres, rotations, points)
    return image_jacobian(v, principal_distance), v


def ray_information(
    points: ArrayLike,
    centres: ArrayLike,
    rotations: ArrayLike,
    principal_distance: float,
    sigma_mm: ArrayLike,
) -> FloatArray:
    """Information of each point from one ray, the photo held fixed.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Points in the frame.
    centres : array_like, shape (n, 3)
        Projection centre of each ray's photo.
    rotations : array_like, shape (n, 3, 3)
        Image -> frame rotation of each ray's photo.
    principal_distance : float
        c in mm.
    sigma_mm : float or array_like, shape (n,)
        Standard deviation of each image coordinate, mm.

    Returns
    -------
    ndarray, shape (n, 3, 3)
        ``Jᵀ J / σ²`` with ``J = d(x, y) / dX``: rank 2 (nothing along the
        ray); two rays of a model give a full-rank sum.
    """
    points = np.asarray(points, dtype=np.float64)
    rotations = np.asarray(rotations, dtype=np.float64)
    jac, _ = _image_jacobian(
        points, np.asarray(centres, dtype=np.float64), rotations, principal_distance
    )
    jac = jac @ np.swapaxes(rotations, 1, 2)
    sigma = np.broadcast_to(np.asarray(sigma_mm, dtype=np.float64), points.shape[:1])
    information: FloatArray = np.swapaxes(jac, 1, 2) @ jac / (sigma**2)[:, None, None]
    return information


def _resection_normals(
    points: ArrayLike,
    centres: ArrayLike,
    rotations: ArrayLike,
    principal_distance: float,
    sigma_mm: ArrayLike,
    group: ArrayLike,
    n_groups: int,
) -> tuple[FloatArray, IntArray]:
    """6 x 6 normal matrices (centre, attitude about the image axes) of space
    resections on fixed points, one per group, and the rays per group."""
    points = np.asarray(points, dtype=np.float64)
    rotations = np.asarray(rotations, dtype=np.float64)
    group = np.asarray(group, dtype=np.intp)
    jac, v = _image_jacobian(
        points, np.asarray(centres, dtype=np.float64), rotations, principal_distance
    )
    # d image / d S = −J Rᵀ; rotation about the image axes (R ← R exp([δ]×)):
    # v ← v − δ × v, d image / d δ = J [v]×.
    d_centre = -(jac @ np.swapaxes(rotations, 1, 2))
    vx = np.zeros((v.shape[0], 3, 3))
    vx[:, 0, 1], vx[:, 0, 2], vx[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    vx -= np.swapaxes(vx, 1, 2)
    d_attitude = jac @ vx
    sigma = np.broadcast_to(np.asarray(sigma_mm, dtype=np.float64), points.shape[:1])
    full = np.concatenate([d_centre, d_attitude], axis=2) / sigma[:, None, None]
    normal = sum_into(group, np.swapaxes(full, 1, 2) @ full, n_groups)
    return normal, np.bincount(group, minlength=n_groups)


def _resection_covariance(normal: FloatArray, counts: IntArray) -> FloatArray:
    """Inverse 6 x 6 normal matrices, NaN where fewer than three rays or
    ill-conditioned."""
    out = np.full(normal.shape, np.nan)
    ok = counts >= 3
    if ok.any():
        cond = np.linalg.cond(normal[ok])
        good = np.flatnonzero(ok)[cond < 1e12]
        if good.size:
            out[good] = np.linalg.inv(normal[good])
    return out


def centre_information(
    points: ArrayLike,
    centres: ArrayLike,
    rotations: ArrayLike,
    principal_distance: float,
    sigma_mm: ArrayLike,
    group: ArrayLike,
    n_groups: int,
) -> FloatArray:
    """Information of projection centres from their rays to fixed points.

    The rays of a group (one photo in one model) determine the photo's
    centre and attitude by space resection; the attitude is eliminated
    (the centre block of the inverse 6 × 6 normal matrix, inverted).

    Parameters
    ----------
    points, centres, rotations, principal_distance, sigma_mm
        As :func:`ray_information`, one row per ray.
    group : array_like of int, shape (n,)
        The group (photo in a model) of each ray, 0 .. n_groups − 1.
    n_groups : int

    Returns
    -------
    ndarray, shape (n_groups, 3, 3)
        NaN for a group whose rays do not determine the centre (fewer than
        three, or singular).
    """
    normal, counts = _resection_normals(
        points, centres, rotations, principal_distance, sigma_mm, group, n_groups
    )
    cov = _resection_covariance(normal, counts)[:, :3, :3]
    out = np.full(cov.shape, np.nan)
    ok = np.isfinite(cov).all(axis=(1, 2))
    out[ok] = np.linalg.inv(cov[ok])
    return out
