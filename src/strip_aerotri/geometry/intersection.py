"""Model formation: space intersection of the rays of a pair (method.md §4).

Both functions work on all points of all pairs at once and return model
points relative to the left projection centre, in the strip system and in the
units of the given base.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple, TypeAlias

import numpy as np

from .._typing import ArrayLike, FloatArray
from ..options import IntersectionMethod

#: Three component arrays x, y, z: the rows of a (3, n) array, or a sequence.
Components: TypeAlias = FloatArray | Sequence[FloatArray]

__all__ = [
    "Intersection",
    "IntersectionMethod",
    "intersect",
    "intersect_midpoint",
    "intersect_normal",
]


class Intersection(NamedTuple):
    """Model points and the remaining y-parallax of the rays.

    points : ndarray, shape (n, 3)
        Model point minus the left projection centre, strip system, base units.
    parallax : ndarray, shape (n,)
        Signed length of the shortest y-parallel vector between the rays
        (J(12)'s q'), base units; zero for rays that meet.
    """

    points: FloatArray
    parallax: FloatArray


def _rows(
    base: ArrayLike, left: ArrayLike, right: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    left = np.asarray(left, dtype=np.float64)
    right = np.asarray(right, dtype=np.float64)
    if left.ndim != 2 or left.shape[1] != 3 or right.shape != left.shape:
        raise ValueError(
            f"Expected left and right to have shape (n, 3), got {left.shape} and {right.shape}"
        )
    base = np.asarray(base, dtype=np.float64)
    if base.shape not in ((3,), left.shape):
        raise ValueError(f"Expected base to have shape (3,) or {left.shape}, got {base.shape}")
    return np.broadcast_to(base, left.shape), left, right


def intersect_midpoint(
    base: ArrayLike, left: ArrayLike, right: ArrayLike, *, across: ArrayLike | None = None
) -> Intersection:
    """Midpoint of the shortest y-parallel vector between two rays, J(11)-(12).

    Parameters
    ----------
    base : array_like, shape (3,) or (n, 3)
        Base vector from the left to the right projection centre (strip system).
    left, right : array_like, shape (n, 3)
        Ray directions ``R @ (x, y, -c)`` of the point on the left and right
        photo, in the strip system.
    across : array_like, shape (3,) or (n, 3), optional
        Unit direction j of the y-parallax: the strip y axis ``(0, 1, 0)``
        by default (J); :func:`~strip_aerotri.strip.chaining.form_strip` passes the
        left photo's image y axis, the direction of its relative orientation.

    Returns
    -------
    Intersection
        ``k_l = (b × p)·j / ((l × p)·j)``, ``q' = b·(l × p) / (j·(l × p))`` and
        the point ``k_l l + q'/2 j``.
    """
    b, l, p = _rows(base, left, right)
    if across is None:
        return _midpoint_along_y(b, l, p)
    j = np.asarray(across, dtype=np.float64)
    if j.shape not in ((3,), l.shape):
        raise ValueError(f"Expected across to have shape (3,) or {l.shape}, got {j.shape}")
    j0, j1, j2 = np.broadcast_to(j, l.shape).T
    b0, b1, b2 = b.T
    l0, l1, l2 = l.T
    p0, p1, p2 = p.T
    c0 = l1 * p2 - l2 * p1  # l × p, by components (np.cross is several times slower)
    c1 = l2 * p0 - l0 * p2
    c2 = l0 * p1 - l1 * p0
    inv_d = 1.0 / (j0 * c0 + j1 * c1 + j2 * c2)
    k = (j0 * (b1 * p2 - b2 * p1) + j1 * (b2 * p0 - b0 * p2) + j2 * (b0 * p1 - b1 * p0)) * inv_d
    half_q = 0.5 * (b0 * c0 + b1 * c1 + b2 * c2) * inv_d
    points = np.empty_like(l)
    points[:, 0] = k * l0 + half_q * j0
    points[:, 1] = k * l1 + half_q * j1
    points[:, 2] = k * l2 + half_q * j2
    return Intersection(points, 2.0 * half_q)


def _midpoint_along_y(b: FloatArray, l: FloatArray, p: FloatArray) -> Intersection:
    """J(12) with ``j = (0, 1, 0)`` for (n, 3) rows (see :func:`midpoint_along_y_components`)."""
    (u0, u1, u2), parallax = midpoint_along_y_components(b.T, l.T, p.T)
    points = np.empty_like(l)
    points[:, 0] = u0
    points[:, 1] = u1
    points[:, 2] = u2
    return Intersection(points, parallax)


def midpoint_along_y_components(
    b: Components, l: Components, p: Components
) -> tuple[tuple[FloatArray, FloatArray, FloatArray], FloatArray]:
    """J(12) with ``j = (0, 1, 0)`` written out: ``D = (l × p)_y``,
    ``k_l = (b × p)_y / D``, ``q' = b·(l × p) / D``.

    ``b``, ``l`` and ``p`` are each three component arrays (x, y, z) of the
    same shape (or broadcasting), e.g. the rows of (3, n) arrays; returns the
    point's components ``k_l l + q'/2 j`` and ``q'``.
    """
    b0, b1, b2 = b
    l0, l1, l2 = l
    p0, p1, p2 = p
    c1 = l2 * p0 - l0 * p2
    inv_d = 1.0 / c1
    k = (b2 * p0 - b0 * p2) * inv_d
    half_q = 0.5 * (b0 * (l1 * p2 - l2 * p1) + b1 * c1 + b2 * (l0 * p1 - l1 * p0)) * inv_d
    return (k * l0, k * l1 + half_q, k * l2), 2.0 * half_q


def intersect_normal(
    base: ArrayLike, left: ArrayLike, right: ArrayLike, principal_distance: float
) -> Intersection:
    """Normal-case intersection through rays reduced to horizontal photos, B(137)-(138).

    Each ray ``(X', Y', Z') = A (x, y, -c)`` is reduced to a horizontal photo,
    ``x0 = -c X'/Z'``, ``y0 = -c Y'/Z'`` (B(137), with the fixed ``y2_0``), and
    ``N = (B_X + (x2_0 / c) B_Z) / (x1_0 - x2_0)``, ``ΔX = N x1_0``,
    ``ΔY = N y1_0``, ``ΔZ = -N c`` (B(138)): the rays are intersected in the
    XZ plane and Y is taken from the left photo.  The returned parallax is
    the y-parallax at the point, ``(S2 + M p0_2 - S1 - N p0_1)_Y`` in base
    units.

    Parameters
    ----------
    base : array_like, shape (3,) or (n, 3)
    left, right : array_like, shape (n, 3)
        Ray directions in the strip system (any length).
    principal_distance : float
        c, in the units of the image vectors (mm).
    """
    b, l, p = _rows(base, left, right)
    c = float(principal_distance)
    x1 = -c * l[:, 0] / l[:, 2]
    y1 = -c * l[:, 1] / l[:, 2]
    x2 = -c * p[:, 0] / p[:, 2]
    y2 = -c * p[:, 1] / p[:, 2]
    n = (b[:, 0] + (x2 / c) * b[:, 2]) / (x1 - x2)
    points = np.column_stack([n * x1, n * y1, -n * c])
    m = n + b[:, 2] / c  # scale of the right ray: -M c = B_Z - N c
    parallax = b[:, 1] + m * y2 - n * y1
    return Intersection(points, parallax)


def intersect(
    base: ArrayLike,
    left: ArrayLike,
    right: ArrayLike,
    *,
    method: IntersectionMethod | str = IntersectionMethod.MIDPOINT,
    principal_distance: float | None = None,
    across: ArrayLike | None = None,
) -> Intersection:
    """Dispatch to :func:`intersect_midpoint` (with ``across``) or :func:`intersect_normal`."""
    method = IntersectionMethod(method)
    if method is IntersectionMethod.MIDPOINT:
        return intersect_midpoint(base, left, right, across=across)
    if principal_distance is None:
        raise ValueError("intersect(method='normal') needs principal_distance")
    return intersect_normal(base, left, right, principal_distance)
