"""The ``[camera]`` and ``[distortion]`` tables judged on their own and on
the image points.

:func:`principal_distance_problems` refuses a c outside every camera's
range (in metres, pixels or micrometres).  The plausibility of the image coordinates
(:func:`~strip_aerotri.plausibility.image_coordinate_problems`) is judged
on the coordinates reduced to the principal point and corrected for the
distortion.  When those are implausible but the measurements as given are
not, the cause is the camera, not the coordinates: a principal point in
pixels or outside the format, or distortion coefficients in another unit or
of the wrong size.  :func:`camera_problems` names the table and the key;
it also refuses a correction that moves a point by more than its distance
from the principal point, or whose radial terms fold the image over the
measured radii (the corrected radius shrinking as the measured one grows):
no lens does either, and the coordinates' own checks may not see them; and
an affinity or shear beyond 1 %.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from .._typing import FloatArray
from ..interior import BrownDistortion, flight_from_sensor
from ..options import DistortionModel, DistortionUnits, FlightDirection
from ..plausibility import MIN_SPAN_OVER_C, image_coordinate_problems

__all__ = ["camera_problems", "measured_problems", "principal_distance_problems"]

#: Image points spanning at least this are on a real format (a phone's
#: sensor spans 5 mm); in metres no format does (230 mm film: 0.23).
_MIN_FORMAT_MM = 1.0
#: Fewer image points than this may all lie near the image's centre.
_MIN_POINTS = 20

#: No camera's principal distance is shorter (a phone's is 4 mm); in metres
#: every camera's is (the longest mapping lens, 610 mm on film: 0.61).
MIN_PRINCIPAL_DISTANCE_MM = 1.0
#: Nor longer (mapping lenses reach 610 mm, reconnaissance ones 1676 mm); in
#: pixels or micrometres almost every camera's is (the FC300X: 2320 px).
MAX_PRINCIPAL_DISTANCE_MM = 2000.0

#: Largest affinity b1 or shear b2 of a film or sensor: film's differential
#: shrinkage and a scanner's affinity are 1e-4 to 1e-3 (R4 §1.7.7.1: the
#: fiducials' scales agree to a few units of the 4th decimal); the FC300X
#: block's self-calibration gives b1 = 7.5e-4.
MAX_AFFINITY = 0.01
_SKEW = {"b1": "an affinity", "b2": "a shear"}

#: Coordinates from the measurements to the photo system: ``reduce(lens,
#: principal_point)`` with or without the distortion and the principal point.
Reduce = Callable[[BrownDistortion | None, tuple[float, float]], FloatArray]


def _lens(distortion: BrownDistortion) -> str:
    """The distortion's non-zero coefficients, units and model, for a message."""
    names = ("k1", "k2", "k3", "p1", "p2", "b1", "b2")
    given = [f"{n} = {getattr(distortion, n):.6g}" for n in names if getattr(distortion, n)]
    units = f'units = "{distortion.units.value}", model = "{distortion.model.value}"'
    return ", ".join([*given, units])


def principal_distance_problems(toml_path: Path, principal_distance: float) -> list[str]:
    """``[camera] principal_distance_mm`` outside every camera's range (in
    metres, pixels or micrometres), named before the image points it would
    make implausible are."""
    c = float(principal_distance)
    if MIN_PRINCIPAL_DISTANCE_MM <= c <= MAX_PRINCIPAL_DISTANCE_MM:
        return []
    key = f"{toml_path}: [camera] principal_distance_mm = {c:g}"
    if c < MIN_PRINCIPAL_DISTANCE_MM:
        return [
            f"{key} is shorter than any camera's ({MIN_PRINCIPAL_DISTANCE_MM:g} mm; a phone's is "
            "4 mm): is it in metres instead of millimetres?"
        ]
    return [
        f"{key} is longer than any aerial camera's ({MAX_PRINCIPAL_DISTANCE_MM:g} mm; mapping "
        "lenses reach 610 mm): is it in pixels (c divided by the pixel size) or micrometres "
        "instead of millimetres?"
    ]


def measured_problems(
    toml_path: Path,
    measured: FloatArray,
    principal_point: tuple[float, float],
    flight_direction: FlightDirection,
    principal_distance: float,
) -> list[str]:
    """The camera against the image points as measured: a principal point
    farther from their origin than every point along an axis (outside the
    image, whatever the points cover: a true one lies within a few hundredths
    of the format of its centre), and a c the points' span, a real format,
    makes a field of view under 2.3 deg (c in pixels or micrometres).

    Parameters
    ----------
    toml_path : Path
    measured : ndarray, shape (n, 2)
        The image points in mm before the principal point and the distortion
        (x along the flight).
    principal_point : (float, float)
        ``[camera] principal_point_mm``, sensor axes.
    flight_direction : FlightDirection
    principal_distance : float
        c in mm.

    Returns
    -------
    list of str
        At most one message naming ``[camera]`` and the key.
    """
    if measured.shape[0] < 3:  # as the coordinates' own span rule
        return []
    c = float(principal_distance)
    span = float(np.max(np.ptp(measured, axis=0)))
    if _MIN_FORMAT_MM <= span < MIN_SPAN_OVER_C * c:
        return [
            f"{toml_path}: [camera] principal_distance_mm = {c:g}: the image points span "
            f"{span:.3g} mm, a real format, but less than {MIN_SPAN_OVER_C:g} c (a field of view "
            "under 2.3 deg): is c in pixels (c divided by the pixel size) or micrometres "
            "instead of millimetres?"
        ]
    along = flight_from_sensor(np.asarray([principal_point], dtype=np.float64), flight_direction)
    reach = np.max(np.abs(measured), axis=0)
    if measured.shape[0] < _MIN_POINTS or not np.any(np.abs(along[0]) > reach):
        return []
    x0, y0 = principal_point
    return [
        f"{toml_path}: [camera] principal_point_mm = [{x0:.6g}, {y0:.6g}] lies outside the image "
        f"points (measured: up to {reach[0]:.4g} mm from their origin along the flight, "
        f"{reach[1]:.4g} mm across it): in pixels, or from another origin? It is in mm in the "
        'measurements\' axes (pixels: [images] units = "pixel" with principal_point_px)'
    ]


def camera_problems(
    toml_path: Path,
    corrected: FloatArray,
    measured: FloatArray,
    reduce: Reduce,
    principal_point: tuple[float, float],
    distortion: BrownDistortion | None,
    principal_distance: float,
) -> list[str]:
    """Problems of the camera tables seen on the image points.

    Parameters
    ----------
    toml_path : Path
        The project file, named in the messages.
    corrected : ndarray, shape (n, 2)
        The image points reduced with the principal point and the
        distortion (mm, x along the flight).
    measured : ndarray, shape (n, 2)
        The same before the principal point and the distortion.
    reduce : callable
        ``reduce(distortion, principal_point)``: the same points reduced with
        another distortion (None: none) and principal point.
    principal_point : (float, float)
        ``[camera] principal_point_mm``.
    distortion : BrownDistortion or None
        ``[distortion]``.
    principal_distance : float
        c in mm.

    Returns
    -------
    list of str
        At most one message naming ``[camera] principal_point_mm`` or
        ``[distortion]``; empty when the camera is not the cause (the
        measurements' own problems are then the coordinates' checks').
    """
    lens = distortion if distortion is not None and not distortion.is_zero else None
    shifted = any(principal_point)
    if lens is None and not shifted:
        return []
    c = float(principal_distance)
    centred = corrected if lens is None else reduce(None, principal_point)
    if lens is not None and (problem := _lens_problem(toml_path, centred, corrected, lens, c)):
        return [problem]
    if not image_coordinate_problems(corrected, c):
        return []
    if image_coordinate_problems(measured, c):
        return []  # the coordinates themselves: their own checks name them
    if lens is None or image_coordinate_problems(centred, c):
        low, high = measured.min(axis=0), measured.max(axis=0)
        x0, y0 = principal_point
        return [
            f"{toml_path}: [camera] principal_point_mm = [{x0:.6g}, {y0:.6g}] lies far off the "
            f"middle of the image points (measured: x from {low[0]:.4g} to "
            f"{high[0]:.4g}, y from {low[1]:.4g} to {high[1]:.4g} mm, x along the flight): in "
            "pixels, or from another origin? It is in mm in the measurements' axes (pixels: "
            '[images] units = "pixel" with principal_point_px)'
        ]
    return [
        f"{toml_path}: [distortion] ({_lens(lens)}) moves the image points where no camera has "
        'them, though they are plausible without it: another unit (units = "normalized" '
        "divides r by c), pixels, a wrong size?"
    ]


def _lens_problem(
    toml_path: Path,
    centred: FloatArray,
    corrected: FloatArray,
    distortion: BrownDistortion,
    principal_distance: float,
) -> str:
    """A correction larger than the point's distance from the principal point,
    or a radial correction that folds the image over the measured radii."""
    head = f"{toml_path}: [distortion] ({_lens(distortion)})"
    skew = max(("b1", "b2"), key=lambda n: abs(getattr(distortion, n)))
    if abs(getattr(distortion, skew)) > MAX_AFFINITY:
        return (
            f"{head}: {skew} is {getattr(distortion, skew):.3g}, {_SKEW[skew]} of more than "
            f"{MAX_AFFINITY:.0%}, where film and sensors differ by parts per thousand at most: a "
            "value in percent?"
        )
    shift = np.hypot(*(corrected - centred).T)
    radius = np.hypot(*centred.T)
    with np.errstate(invalid="ignore"):
        too_large = ~(shift <= radius)  # NaN too
    cause = 'another unit (units = "normalized" divides r by c), pixels, a wrong size or sign?'
    if too_large.any():
        k = int(np.flatnonzero(too_large)[np.argmax(shift[too_large])])
        return (
            f"{head} moves a point {radius[k]:.4g} mm from the principal point by "
            f"{shift[k]:.4g} mm, more than its distance ({int(too_large.sum())} of "
            f"{too_large.size} points): no lens does; {cause}"
        )
    # d(r + Δr)/dr of the radial terms at the radii where the polynomials are
    # evaluated: the measured point (correction) or the ideal one (projection)
    at = centred if distortion.model is DistortionModel.CORRECTION else corrected
    norm = principal_distance if distortion.units is DistortionUnits.NORMALIZED else 1.0
    r2 = np.einsum("ij,ij->i", at, at) / norm**2
    d = distortion
    slope = 1.0 + r2 * (3.0 * d.k1 + r2 * (5.0 * d.k2 + r2 * 7.0 * d.k3))
    folded = np.flatnonzero(slope <= 0.0)
    if not folded.size:
        return ""
    first = float(np.sqrt(r2[folded].min()) * norm)
    return (
        f"{head} folds the image beyond {first:.4g} mm from the principal point (the corrected "
        "radius shrinks as the measured grows: 1 + 3k1 r² + 5k2 r⁴ + 7k3 r⁶ ≤ 0 at "
        f"{folded.size} of {slope.size} points): no lens does; {cause}"
    )
