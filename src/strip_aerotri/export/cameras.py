"""The photos as an omega-phi-kappa camera file (docs/export.md).

One line per photo, ``imageName X Y Z Omega Phi Kappa`` after a header line
of those names, separated by spaces: the layout of Pix4D's calibrated
external camera parameters, which Metashape imports as camera reference
(File > Import > Import Reference, columns label, X, Y, Z, omega, phi,
kappa; rotation angles "Omega, Phi, Kappa").

The angles are those of the PATB convention on the map grid:
``R = Rx(omega) Ry(phi) Rz(kappa)`` maps camera vectors in the sensor axes
(x right, y up, z back: the camera looks along -z) to grid east, grid
north, up, degrees.  This package's photos are in the flight axes (x along
the flight, ``[images] flight_direction``); they are turned back to the
sensor axes, and from local east-north-up to the grid by the meridian
convergence.  A geographic CRS has no grid: the file is refused.
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray
from ..geodesy import grid_convergence_deg
from ..geometry.rotation import matrix_from_opk, opk_from_matrix
from ..interior import flight_matrix
from ..options import FlightDirection

__all__ = ["camera_rotations_grid", "cameras_opk_text"]


def camera_rotations_grid(
    opk_enu_rad: FloatArray,
    centres_xy: FloatArray,
    crs: str,
    flight_direction: FlightDirection | str = FlightDirection.PLUS_X,
) -> FloatArray:
    """Sensor -> grid rotations (M, 3, 3) of photos given as this package's
    omega, phi, kappa (radians; flight axes -> local east-north-up)."""
    enu = matrix_from_opk(np.asarray(opk_enu_rad, dtype=np.float64)) @ flight_matrix(
        flight_direction
    )
    gamma = grid_convergence_deg(crs, np.asarray(centres_xy, dtype=np.float64))
    zeros = np.zeros_like(gamma)
    grid: FloatArray = matrix_from_opk(np.column_stack([zeros, zeros, gamma]), degrees=True) @ enu
    return grid


def cameras_opk_text(
    photo_ids: list[str] | tuple[str, ...],
    centres: FloatArray,
    opk_enu_rad: FloatArray,
    crs: str,
    flight_direction: FlightDirection | str = FlightDirection.PLUS_X,
) -> str:
    """The camera file's text (see the module notes); ``centres`` X, Y, Z in
    the project's CRS (projected or ``"local"``), metres."""
    centres = np.asarray(centres, dtype=np.float64)
    grid = camera_rotations_grid(opk_enu_rad, centres[:, :2], crs, flight_direction)
    opk = np.degrees(opk_from_matrix(grid))
    lines = ["imageName X Y Z Omega Phi Kappa"]
    lines += [
        f"{photo} {x:.4f} {y:.4f} {z:.4f} {o:.6f} {p:.6f} {k:.6f}"
        for photo, (x, y, z), (o, p, k) in zip(photo_ids, centres, opk, strict=True)
    ]
    return "\n".join(lines) + "\n"
