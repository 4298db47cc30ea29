"""The collinearity equations, x = −c v_x / v_z, y = −c v_y / v_z with
v = Rᵀ (X − S), and their derivatives: one place for the resection, the
precision of rays and the bundle adjustment.

Conventions: R maps image vectors to the object frame (image -> object,
premultiplying column vectors); S the projection centre and X the point in
the same Cartesian frame (metres or model units); c the principal distance
in mm; image x, y in mm.  A point in front of the photo has ``v_z < 0``.
"""

from __future__ import annotations

import numpy as np

from .._threads import split_map
from .._typing import FloatArray, IntArray

__all__ = ["collinearity_jacobians", "image_jacobian", "image_vectors", "project"]

#: Observations per block of :func:`collinearity_jacobians` (the blocks run on
#: the threads of ``_threads.compute_workers`` where one is open).
_BLOCK = 16384


def image_vectors(centres: FloatArray, rotations: FloatArray, points: FloatArray) -> FloatArray:
    """``v = Rᵀ (X − S)`` of rays, each with its own photo: shapes (K, 3),
    (K, 3, 3), (K, 3) -> (K, 3)."""
    vectors: FloatArray = np.einsum("kji,kj->ki", rotations, points - centres)
    return vectors


def project(
    centres: FloatArray,
    rotations: FloatArray,
    points: FloatArray,
    photo: IntArray,
    point: IntArray,
    principal_distance: float,
) -> tuple[FloatArray, FloatArray]:
    """Image coordinates of observations by the collinearity equations.

    Parameters
    ----------
    centres : ndarray, shape (M, 3)
        Projection centres.
    rotations : ndarray, shape (M, 3, 3)
        Image -> frame rotations.
    points : ndarray, shape (P, 3)
        Object points.
    photo, point : ndarray of int, shape (K,)
        Photo and point index of each observation.
    principal_distance : float
        c in mm.

    Returns
    -------
    xy : ndarray, shape (K, 2)
        Computed image coordinates, mm.
    v : ndarray, shape (K, 3)
        ``Rᵀ (X − S)`` (``v_z < 0`` for a point in front of the photo).

    Both are views of arrays laid out coordinate by coordinate (the K
    observations contiguous), as the normal equations read them.
    """
    v = _vectors(centres, rotations, points, photo, point)[0]
    xy = np.empty((2, v.shape[1]))
    np.multiply(v[:2], -principal_distance / v[2], out=xy)
    return xy.T, v.T


def _vectors(
    centres: FloatArray,
    rotations: FloatArray,
    points: FloatArray,
    photo: IntArray,
    point: IntArray,
) -> tuple[FloatArray, FloatArray]:
    """``v = Rᵀ (X − S)`` (3, K) and the rays' rotations R (9, K) (entry
    ``3 j + a`` is ``R[j, a]``), coordinate-major."""
    rot = np.take(np.asarray(rotations, np.float64).reshape(-1, 9).T, photo, axis=1)
    diff = np.take(np.asarray(points, np.float64).T, point, axis=1)
    diff -= np.take(np.asarray(centres, np.float64).T, photo, axis=1)
    v = np.empty((3, diff.shape[1]))
    for a in range(3):  # v_a = Σ_j R[j, a] (X − S)_j
        np.multiply(rot[a], diff[0], out=v[a])
        v[a] += rot[3 + a] * diff[1]
        v[a] += rot[6 + a] * diff[2]
    return v, rot


def image_jacobian(v: FloatArray, principal_distance: float) -> FloatArray:
    """d(x, y) / dv of the collinearity equations at image vectors v (K, 3):
    shape (K, 2, 3), mm per unit of v."""
    f = -principal_distance / v[:, 2]
    jac = np.zeros((v.shape[0], 2, 3))
    jac[:, 0, 0] = f
    jac[:, 1, 1] = f
    jac[:, 0, 2] = -f * v[:, 0] / v[:, 2]
    jac[:, 1, 2] = -f * v[:, 1] / v[:, 2]
    return jac


def collinearity_jacobians(
    centres: FloatArray,
    rotations: FloatArray,
    points: FloatArray,
    photo: IntArray,
    point: IntArray,
    principal_distance: float,
    scale: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The collinearity equations and their Jacobians (arguments as :func:`project`;
    `scale` (K,), optional, multiplies each observation's two Jacobians, e.g.
    ``1 / sigma`` to whiten them).

    Returns
    -------
    xy, v : ndarray, shapes (K, 2), (K, 3)
        As :func:`project`.
    jac_photo : ndarray, shape (K, 2, 6)
        d(x, y) / d(dS, δ), mm per unit and mm per rad, for the update
        ``S <- S + dS``, ``R <- R @ exp([δ]×)`` (δ about the image axes).
    jac_point : ndarray, shape (K, 2, 3)
        d(x, y) / dX, mm per unit.

    Views of arrays laid out entry by entry, the K observations contiguous
    (``np.moveaxis(jac_photo, 0, -1)`` is C-contiguous), as
    :mod:`strip_aerotri.geometry.normals` reads them.
    """
    photo, point = np.asarray(photo, np.intp), np.asarray(point, np.intp)
    k = photo.size
    xy, v_all = np.empty((2, k)), np.empty((3, k))
    jac_point, jac_photo = np.empty((2, 3, k)), np.empty((2, 6, k))

    def block(at: slice) -> None:
        v, rot = _vectors(centres, rotations, points, photo[at], point[at])
        v_all[:, at] = v
        # d(x, y)/dv = f [[1, 0, -v_x/v_z], [0, 1, -v_y/v_z]] with f = -c / v_z;
        # dv/dX = Rᵀ, dv/dS = −Rᵀ, dv/dδ = [v]×  (Rᵀ <- (I − [δ]×) Rᵀ), written
        # out term by term (the 2 x 3 factor has four nonzeros), each entry an
        # array over the observations
        vx, vy, vz = v
        f = -principal_distance / vz
        ux, uy = vx / vz, vy / vz
        np.multiply(f, vx, out=xy[0, at])
        np.multiply(f, vy, out=xy[1, at])
        jp, jo = jac_point[..., at], jac_photo[..., at]
        for b in range(3):  # row b of Rᵀ ... column b of R: R[b, 0], R[b, 1], R[b, 2]
            np.multiply(f, rot[3 * b] - ux * rot[3 * b + 2], out=jp[0, b])
            np.multiply(f, rot[3 * b + 1] - uy * rot[3 * b + 2], out=jp[1, b])
        np.negative(jp, out=jo[:, :3])
        # rows of d_v times [v]× = [[0, -vz, vy], [vz, 0, -vx], [-vy, vx, 0]]
        fu, fv = f * ux, f * uy
        jo[0, 3] = fu * vy
        jo[0, 4] = -(f * vz + fu * vx)
        jo[0, 5] = f * vy
        jo[1, 3] = f * vz + fv * vy
        jo[1, 4] = -fv * vx
        jo[1, 5] = -f * vx
        if scale is not None:
            jp *= scale[at]
            jo *= scale[at]

    # blocks of observations on the threads of _threads.compute_workers
    split_map(block, [slice(lo, lo + _BLOCK) for lo in range(0, k, _BLOCK)])
    v = v_all
    return (
        xy.T, v.T, np.moveaxis(jac_photo, -1, 0), np.moveaxis(jac_point, -1, 0)
    )
