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

from .._typing import FloatArray, IntArray

__all__ = ["collinearity_jacobians", "image_jacobian", "image_vectors", "project"]


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
    """
    v = image_vectors(centres[photo], rotations[photo], points[point])
    xy = -principal_distance * v[:, :2] / v[:, 2:3]
    return xy, v


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
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The collinearity equations and their Jacobians (arguments as :func:`project`).

    Returns
    -------
    xy, v : ndarray, shapes (K, 2), (K, 3)
        As :func:`project`.
    jac_photo : ndarray, shape (K, 2, 6)
        d(x, y) / d(dS, δ), mm per unit and mm per rad, for the update
        ``S <- S + dS``, ``R <- R @ exp([δ]×)`` (δ about the image axes).
    jac_point : ndarray, shape (K, 2, 3)
        d(x, y) / dX, mm per unit.
    """
    xy, v = project(centres, rotations, points, photo, point, principal_distance)
    # d(x, y)/dv = f [[1, 0, -v_x/v_z], [0, 1, -v_y/v_z]] with f = -c / v_z;
    # dv/dX = Rᵀ, dv/dS = −Rᵀ, dv/dδ = [v]×  (Rᵀ <- (I − [δ]×) Rᵀ), written
    # out term by term (the 2 x 3 factor has four nonzeros)
    f = -principal_distance / v[:, 2]
    ux, uy = v[:, 0] / v[:, 2], v[:, 1] / v[:, 2]
    rot = rotations[photo]  # (K, 3, 3); row a of Rᵀ is column a of R
    jac_point = np.empty((v.shape[0], 2, 3))
    jac_point[:, 0] = f[:, None] * (rot[:, :, 0] - ux[:, None] * rot[:, :, 2])
    jac_point[:, 1] = f[:, None] * (rot[:, :, 1] - uy[:, None] * rot[:, :, 2])
    vx, vy, vz = v[:, 0], v[:, 1], v[:, 2]
    jac_photo = np.empty((v.shape[0], 2, 6))
    jac_photo[:, :, :3] = -jac_point
    # rows of d_v times [v]× = [[0, -vz, vy], [vz, 0, -vx], [-vy, vx, 0]]
    jac_photo[:, 0, 3] = f * ux * vy
    jac_photo[:, 0, 4] = -f * (vz + ux * vx)
    jac_photo[:, 0, 5] = f * vy
    jac_photo[:, 1, 3] = f * (vz + uy * vy)
    jac_photo[:, 1, 4] = -f * uy * vx
    jac_photo[:, 1, 5] = -f * vx
    return xy, v, jac_photo, jac_point
