"""How well a point's own rays fix it: the forward intersection's covariance.

With the photos' orientations held, a point seen on K photos is the
least-squares intersection of its K rays; linearising the collinearity
equations (:mod:`strip_aerotri.geometry.collinearity`) about the adjusted
point, its covariance is ``(Σ_k J_kᵀ J_k / σ_k²)⁻¹`` with ``J_k`` the 2 x 3
derivative of ray k's image coordinates by the point and ``σ_k`` their
standard deviation.  Two nearly parallel rays (a small base against the
distance) leave the point uncertain along them: in the normal case the depth
``Z`` of a two-ray point has ``σ_Z = Z² / (B c) · √2 σ`` (the parallax's
sigma), decimetres for a base of a twentieth of the distance where the
image sigma alone gives millimetres across the rays.

The orientations' own uncertainty is not included: the covariance is a
lower bound of the point's precision in a bundle, and the part that its
geometry alone fixes.
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, IntArray
from ._normal_assembly import sum_into
from .precision import ray_information

__all__ = ["intersection_angles", "intersection_covariances"]


def intersection_covariances(
    centres: FloatArray,
    rotations: FloatArray,
    points: FloatArray,
    photo: IntArray,
    point: IntArray,
    principal_distance: float,
    sigma_mm: FloatArray,
) -> FloatArray:
    """Covariance of each point's forward intersection from its rays (module notes).

    Parameters
    ----------
    centres, rotations, points, photo, point, principal_distance
        As :func:`strip_aerotri.geometry.collinearity.project` (a Cartesian
        frame in metres; rows of ``points`` with NaN are not computed).
    sigma_mm : ndarray, shape (K,)
        Standard deviation of each observation's x and y (mm).

    Returns
    -------
    ndarray, shape (P, 3, 3)
        Covariance (frame axes, m²); NaN for a point with fewer than two
        rays or rays that do not fix it (parallel).
    """
    n_points = points.shape[0]
    out = np.full((n_points, 3, 3), np.nan)
    ok = np.all(np.isfinite(points[point]), axis=1)
    if not ok.any():
        return out
    normal = sum_into(
        point[ok],
        ray_information(
            points[point[ok]],
            centres[photo[ok]],
            rotations[photo[ok]],
            principal_distance,
            np.asarray(sigma_mm, dtype=np.float64)[ok],
        ),
        n_points,
    )  # a forward intersection adds the information of its rays
    rays = np.bincount(point[ok], minlength=n_points)
    # a determinant far below the product of the diagonal: parallel rays
    scale = np.prod(np.diagonal(normal, axis1=1, axis2=2), axis=1)
    det = np.linalg.det(normal)
    good = (rays >= 2) & (scale > 0) & (det > 1e-12 * np.where(scale > 0, scale, 1.0))
    out[good] = np.linalg.inv(normal[good])
    return out


def intersection_angles(
    centres: FloatArray, points: FloatArray, photo: IntArray, point: IntArray
) -> FloatArray:
    """The largest angle (degrees) between two rays of each point: the
    intersection angle of its best pair (NaN with fewer than two rays).

    Every pair of rays of a point is formed (K² per point of K rays): pass
    the observations of the points wanted only, when they are many.
    """
    n_points = points.shape[0]
    out = np.full(n_points, np.nan)
    rows = np.flatnonzero(np.all(np.isfinite(points[point]), axis=1))
    rows = rows[np.argsort(point[rows], kind="stable")]
    if rows.size < 2:
        return out
    unit = points[point[rows]] - centres[photo[rows]]
    unit /= np.linalg.norm(unit, axis=1)[:, None]
    sorted_pts = point[rows]
    starts = np.flatnonzero(np.r_[True, sorted_pts[1:] != sorted_pts[:-1]])
    counts = np.diff(np.r_[starts, sorted_pts.size])
    total = counts * counts
    first = np.repeat(starts, total)
    size = np.repeat(counts, total)
    within = np.arange(int(total.sum())) - np.repeat(np.cumsum(total) - total, total)
    a = first + within // size
    b = first + within % size
    cos = np.einsum("ij,ij->i", unit[a], unit[b])
    smallest = np.full(n_points, np.inf)
    np.minimum.at(smallest, sorted_pts[a], cos)
    has_pair = np.bincount(sorted_pts, minlength=n_points) >= 2
    out[has_pair] = np.degrees(np.arccos(np.clip(smallest[has_pair], -1.0, 1.0)))
    return out
