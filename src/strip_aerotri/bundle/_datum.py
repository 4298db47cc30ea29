"""The datum test of the bundle adjustment: which of the seven similarity
motions of the whole net the control, GNSS and IMU observations leave free
(:func:`strip_aerotri.bundle.adjust.bundle_adjust` refuses to iterate then,
naming them)."""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray
from ..geometry.rotation import skew

__all__ = ["free_motions"]

#: Ratio of smallest to largest singular value of the datum matrix (unit
#: weights, coordinates reduced to the centroid and scaled by the net's size)
#: below which a similarity degree of freedom counts as free.
_DATUM_RANK_TOL = 1e-9

_MOTION_NAMES = (
    "shift along X",
    "shift along Y",
    "shift along Z",
    "rotation about X",
    "rotation about Y",
    "rotation about Z",
    "scale",
)


def free_motions(
    points: FloatArray,
    centres: FloatArray,
    rotations: FloatArray,
    control_weight: FloatArray,
    gnss_weight: FloatArray,
    imu_weight: FloatArray,
) -> list[str]:
    """Describe the similarity degrees of freedom left free by control, GNSS and IMU.

    Points (P, 3) and centres (M, 3) in metres, rotations (M, 3, 3) image ->
    frame; the weights (P, 3), (M, 3), (M, 3) of the control, GNSS and IMU
    components, 0 where none.

    The 7 infinitesimal similarity motions of the whole net (shifts, rotations
    about the frame axes through the centroid, scale; coordinates scaled by
    the net's size) are applied to the observed quantities; the rank of that
    n x 7 matrix (unit weights) tells which motions the observations fix.
    """
    ref = np.concatenate([points, centres])
    x0 = ref.mean(axis=0)
    size = float(np.sqrt(np.mean(np.sum((ref - x0) ** 2, axis=1)))) or 1.0

    def motion_rows(xyz: FloatArray) -> FloatArray:
        q = (xyz - x0) / size
        g = np.zeros((xyz.shape[0], 3, 7))
        g[:, :, :3] = np.eye(3)
        g[:, :, 3:6] = -skew(q)  # d(omega x q)/d(omega)
        g[:, :, 6] = q
        return g

    g_imu = np.zeros((centres.shape[0], 3, 7))
    g_imu[:, :, 3:6] = np.swapaxes(rotations, 1, 2)  # e -> e + R.T omega
    g = np.concatenate(
        [
            motion_rows(points)[control_weight > 0],
            motion_rows(centres)[gnss_weight > 0],
            g_imu[imu_weight > 0],
        ]
    )
    if g.shape[0] == 0:
        return list(_MOTION_NAMES)
    r_factor = np.zeros((7, 7))
    # same singular values, at most 7 x 7; mode "r" gives R alone (the stubs say QRResult)
    r_part: FloatArray = np.linalg.qr(g, mode="r")  # type: ignore[assignment]
    r_factor[: r_part.shape[0]] = r_part
    _, sv, vt = np.linalg.svd(r_factor)
    rank = int(np.count_nonzero(sv > _DATUM_RANK_TOL * sv[0]))
    null = vt[rank:]  # (7 - rank, 7) orthonormal basis of the free motions
    if null.shape[0] == 0:
        return []
    share = np.sum(null**2, axis=0)  # squared length of each motion in the null space
    whole = share > 1.0 - 1e-6
    free = [_MOTION_NAMES[i] for i in np.flatnonzero(whole)]
    rest = null.shape[0] - len(free)
    if rest > 0:
        parts = [_MOTION_NAMES[i] for i in np.flatnonzero(~whole & (share > 1e-3))]
        free.append(f"{rest} combination(s) of {', '.join(parts)}")
    return free
