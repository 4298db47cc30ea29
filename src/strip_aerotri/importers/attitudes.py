"""Photo attitudes from omega, phi, kappa on a map grid (PATB convention),
turned to local east-north-up with the meridian convergence
(:func:`strip_aerotri.geodesy.grid_convergence_deg`).
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray, StrArray
from ..errors import ConfigError
from ..geodesy import grid_convergence_deg
from ..geometry.rotation import matrix_from_opk
from .tables import PhotoAttitudes

__all__ = ["attitudes_from_opk"]


def attitudes_from_opk(
    photo: StrArray,
    opk_deg: FloatArray,
    xy: FloatArray,
    crs: str,
    where: str,
) -> PhotoAttitudes:
    """Attitudes from omega, phi, kappa of the PATB convention on a map grid.

    The source's angles give ``R_grid = Rx(omega) Ry(phi) Rz(kappa)`` mapping
    camera vectors in the PATB axes (x right, y up, z back; the camera looks
    along -z) to the map grid (grid east, grid north, up).  The local
    east-north-up matrix is ``Rz(-gamma) @ R_grid`` with the meridian
    convergence gamma at the photo (:func:`grid_convergence_deg`).

    Raises
    ------
    ConfigError
        When most cameras would look *up* with this reading (a source in
        another camera convention): converting them would be wrong.
    """
    grid = matrix_from_opk(opk_deg, degrees=True)
    # the camera looks along its -z axis, whose up component is -r33: down when r33 > 0
    if np.median(grid[:, 2, 2]) <= 0.0:
        raise ConfigError(
            f"{where}: read as PATB omega, phi, kappa (camera x right, y up, looking along -z) "
            "most cameras would look up; the file uses another camera convention, so the "
            "attitudes are not converted (leave out the attitudes or export PATB angles)"
        )
    gamma = grid_convergence_deg(crs, xy)
    enu = matrix_from_opk(np.column_stack([0.0 * gamma, 0.0 * gamma, -gamma]), degrees=True) @ grid
    return PhotoAttitudes(photo, enu)
