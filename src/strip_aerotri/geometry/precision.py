"""Precision of points and projection centres from the collinearity geometry.

Information matrices (inverse covariances) in a Cartesian frame, from the
image rays with the image coordinates' standard deviations:

* :func:`ray_information` — of a point from one ray with the photo held
  fixed (a forward intersection adds those of its rays);
* :func:`centre_information` — of a projection centre from the rays of one
  photo to fixed points (a space resection: the 6 × 6 information of centre
  and attitude, the attitude eliminated);
* :func:`rays_information` — both of the same rays at once (the rays of
  one photo of every model of a strip).

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

__all__ = ["centre_information", "ray_information", "rays_information"]


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


def _resection_rows(
    jac: FloatArray, v: FloatArray, rotations: FloatArray, sigma: FloatArray
) -> FloatArray:
    """The rows of the space resection of each ray, (n, 2, 6): d image /
    d(centre, attitude about the image axes) over σ, from the ray's
    :func:`_image_jacobian` (``jac``, ``v``)."""
    # d image / d S = −J Rᵀ; rotation about the image axes (R ← R exp([δ]×)):
    # v ← v − δ × v, d image / d δ = J [v]×.
    d_centre = -(jac @ np.swapaxes(rotations, 1, 2))
    vx = np.zeros((v.shape[0], 3, 3))
    vx[:, 0, 1], vx[:, 0, 2], vx[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    vx -= np.swapaxes(vx, 1, 2)
    d_attitude = jac @ vx
    full: FloatArray = np.concatenate([d_centre, d_attitude], axis=2) / sigma[:, None, None]
    return full


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
    sigma = np.broadcast_to(np.asarray(sigma_mm, dtype=np.float64), points.shape[:1])
    full = _resection_rows(jac, v, rotations, sigma)
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
    return _centre_from_normals(normal, counts)


def _centre_from_normals(normal: FloatArray, counts: IntArray) -> FloatArray:
    """The centre's information of each group from its 6 x 6 resection normals
    (NaN where the rays do not determine it)."""
    cov = _resection_covariance(normal, counts)[:, :3, :3]
    out = np.full(cov.shape, np.nan)
    ok = np.isfinite(cov).all(axis=(1, 2))
    out[ok] = np.linalg.inv(cov[ok])
    return out


def rays_information(
    points: ArrayLike,
    photo: ArrayLike,
    centres: ArrayLike,
    rotations: ArrayLike,
    principal_distance: float,
    sigma_mm: ArrayLike,
    group: ArrayLike,
    n_groups: int,
) -> tuple[FloatArray, FloatArray]:
    """:func:`ray_information` and :func:`centre_information` of the same
    rays, each ray's rows formed once (written out: :func:`_ray_rows`).

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Points in the frame, one per ray.
    photo : array_like of int, shape (n,)
        The photo of each ray: its row of ``centres`` and ``rotations``.
    centres : array_like, shape (M, 3)
    rotations : array_like, shape (M, 3, 3)
        Projection centres and image -> frame rotations of the photos.
    principal_distance, sigma_mm
        As :func:`ray_information` (``sigma_mm`` one per ray or one for all).
    group : array_like of int, shape (n,)
        The group (photo in a model) of each ray, 0 .. n_groups − 1.
    n_groups : int

    Returns
    -------
    points_information : ndarray, shape (n, 3, 3)
        As :func:`ray_information`.
    centres_information : ndarray, shape (n_groups, 3, 3)
        As :func:`centre_information`.
    """
    points = np.asarray(points, dtype=np.float64)
    photo = np.asarray(photo, dtype=np.intp)
    rot = np.asarray(rotations, dtype=np.float64)[photo]
    n = points.shape[0]
    sigma = np.broadcast_to(np.asarray(sigma_mm, dtype=np.float64), (n,))
    v = image_vectors(np.asarray(centres, dtype=np.float64)[photo], rot, points)
    (a_x, a_y), (b_x, b_y) = _ray_rows(rot, v, principal_distance, sigma)
    information = _outer_sum(a_x, a_y)
    # the resection's rows over σ: d / d centre = −a, d / d attitude = b
    rows = np.empty((n, 2, 6))
    rows[:, 0, :3], rows[:, 0, 3:], rows[:, 1, :3], rows[:, 1, 3:] = -a_x, b_x, -a_y, b_y
    normal, counts = _group_normals(rows, np.asarray(group, dtype=np.intp), n_groups)
    return information, _centre_from_normals(normal, counts)


def _outer_sum(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a aᵀ + b bᵀ`` of rows a, b (n, 3): (n, 3, 3), its six distinct
    entries computed once each (the same values as the broadcast products,
    in a tenth of the time: no (n, 3, 3) temporaries)."""
    out = np.empty((a.shape[0], 3, 3))
    for i in range(3):
        for j in range(i + 1):
            value = a[:, i] * a[:, j]
            value += b[:, i] * b[:, j]
            out[:, i, j] = value
            out[:, j, i] = value
    return out


def _group_normals(
    rows: FloatArray, group: IntArray, n_groups: int
) -> tuple[FloatArray, IntArray]:
    """``Σ rᵀ r`` of the rows ``r`` (n, k, d) of each group, (n_groups, d, d),
    and the rows per group: one product of each group's rows, stacked
    (k n_g, d), in a loop over the groups (a model's photo: loops over the
    models of a strip are sequential anyway); LAPACK's product of a tall
    block is several times faster than summing n products of k × d rows."""
    if not np.all(group[1:] >= group[:-1]):
        order = np.argsort(group, kind="stable")
        rows, group = rows[order], group[order]
    d = rows.shape[2]
    bounds = np.searchsorted(group, np.arange(n_groups + 1))
    normal = np.zeros((n_groups, d, d))
    flat = rows.reshape(-1, d)
    k = rows.shape[1]
    for g in np.flatnonzero(bounds[1:] > bounds[:-1]):
        block = flat[k * bounds[g] : k * bounds[g + 1]]
        normal[g] = block.T @ block
    return normal, np.diff(bounds)


def _ray_rows(
    rot: FloatArray, v: FloatArray, principal_distance: float, sigma: FloatArray
) -> tuple[tuple[FloatArray, FloatArray], tuple[FloatArray, FloatArray]]:
    """The two rows (x, y) of each ray's image coordinates over σ, (n, 3)
    each: ``a`` in the point's frame coordinates, ``J Rᵀ / σ``, and ``b`` in
    the photo's attitude about its image axes, ``J [v]× / σ``
    (:func:`_resection_rows` written out: ``J = f [[1, 0, −g_x], [0, 1, −g_y]]``
    with ``f = −c / v_z``, ``g = v / v_z``; a batched product of 2 × 3 by
    3 × 3 matrices costs several times as much)."""
    f = -principal_distance / v[:, 2] / sigma
    gx, gy = v[:, 0] / v[:, 2], v[:, 1] / v[:, 2]
    column_z = rot[:, :, 2]
    a_x = f[:, None] * (rot[:, :, 0] - gx[:, None] * column_z)
    a_y = f[:, None] * (rot[:, :, 1] - gy[:, None] * column_z)
    vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]
    b_x = f[:, None] * np.column_stack([gx * vy, -gx * vx - vz, vy])
    b_y = f[:, None] * np.column_stack([vz + gy * vy, -gy * vx, -vx])
    return (a_x, a_y), (b_x, b_y)
