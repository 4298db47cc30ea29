"""Interior orientation: from measured image coordinates to the method's image system.

The method (method.md section 2) wants image coordinates in millimetres,
reduced to the principal point, corrected for lens distortion, with x along
the flight and y to its left.  Measurements rarely come that way.  This module
takes them there, one vectorised step at a time, in this order:

1. :func:`mm_from_pixel` -- pixel column/row to millimetres (rows grow
   downwards, y is turned to grow upwards);
2. :func:`fit_fiducial_transform` -- comparator (or scanner) coordinates to
   the calibrated fiducial system of the camera, per photo, by a similarity or
   affine transformation with R4 §1.7.7.1's check of the deformation
   coefficients;
3. subtraction of the principal point (``[camera] principal_point_mm``);
4. :func:`correct_distortion` -- Brown's radial and decentring distortion;
5. :func:`flight_from_sensor` -- the sensor axes turned so that x runs along
   the flight.

Steps 1-4 work in the *sensor axes*: x to the right, y up, looking at the
image as it lies in the camera with the scene in front (the usual
photogrammetric "x right, y up" of a positive).  Step 5 is a proper rotation
in the image plane (det +1), so z stays up and the image vector stays
``(x, y, -c)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._typing import ArrayLike, FloatArray, IntArray
from .options import (
    DEFAULT_DIFFERENCE_TOLERANCE,
    DEFAULT_SCALE_TOLERANCE,
    DistortionModel,
    DistortionUnits,
    FiducialTransform,
    FlightDirection,
    ImageUnits,
)

__all__ = [
    "DEFAULT_DIFFERENCE_TOLERANCE",
    "DEFAULT_SCALE_TOLERANCE",
    "BrownDistortion",
    "DistortionModel",
    "DistortionUnits",
    "FiducialFit",
    "FiducialTransform",
    "FlightDirection",
    "ImageUnits",
    "apply_fiducial_transforms",
    "correct_distortion",
    "corrected_flight_direction",
    "distortion_shift",
    "fit_fiducial_transform",
    "fit_fiducial_transforms",
    "flight_from_sensor",
    "flight_matrix",
    "mm_from_pixel",
    "reduce_image_coordinates",
    "sensor_from_flight",
]

# --------------------------------------------------------------------------- helpers


def _as_xy(xy: ArrayLike, name: str = "xy") -> FloatArray:
    arr = np.asarray(xy, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"Expected `{name}` to have shape (K, 2), got {arr.shape}")
    return arr


# --------------------------------------------------------------------------- pixels


def mm_from_pixel(
    colrow: ArrayLike, pixel_size_mm: float, principal_point_px: ArrayLike
) -> FloatArray:
    """Pixel column/row to image millimetres, x right and y up.

    Parameters
    ----------
    colrow : array_like, shape (K, 2)
        Column and row of each measurement in pixels; columns grow to the
        right, rows grow *downwards* (the raster convention).
    pixel_size_mm : float
        Side of a (square) pixel in millimetres.
    principal_point_px : array_like, shape (2,)
        Column c0 and row r0 of the origin (the principal point, or the image
        centre) in the same pixel coordinates.

    Returns
    -------
    ndarray, shape (K, 2)
        ``x = (col - c0) * s``, ``y = -(row - r0) * s`` in mm: x to the right,
        y up.

    Examples
    --------
    >>> mm_from_pixel([[2010.0, 1490.0]], 0.002, [2000.0, 1500.0])
    array([[0.02, 0.02]])
    """
    cr = _as_xy(colrow, "colrow")
    s = float(pixel_size_mm)
    if not (np.isfinite(s) and s > 0):
        raise ValueError(f"Expected `pixel_size_mm` > 0, got {pixel_size_mm!r}")
    pp = np.asarray(principal_point_px, dtype=np.float64).reshape(-1)
    if pp.shape != (2,) or not np.isfinite(pp).all():
        raise ValueError(f"Expected `principal_point_px` to be 2 finite numbers, got {pp!r}")
    out = np.empty_like(cr)
    out[:, 0] = (cr[:, 0] - pp[0]) * s
    out[:, 1] = -(cr[:, 1] - pp[1]) * s
    return out


# --------------------------------------------------------------------------- flight axes

# Rows: image (x', y') of the method as combinations of sensor (x, y).
_FLIGHT_MATRICES: dict[FlightDirection, FloatArray] = {
    FlightDirection.PLUS_X: np.array([[1.0, 0.0], [0.0, 1.0]]),
    FlightDirection.MINUS_X: np.array([[-1.0, 0.0], [0.0, -1.0]]),
    FlightDirection.PLUS_Y: np.array([[0.0, 1.0], [-1.0, 0.0]]),
    FlightDirection.MINUS_Y: np.array([[0.0, -1.0], [1.0, 0.0]]),
}


def flight_matrix(flight_direction: FlightDirection | str) -> FloatArray:
    """The 3 x 3 matrix taking sensor-axis image vectors to the flight axes
    (a turn about the image z axis, z kept): the rotation of
    :func:`flight_from_sensor`, ``"+y"`` giving x' = y, y' = -x.

    Examples
    --------
    >>> flight_matrix("+y") @ [1.0, 2.0, -3.0]
    array([ 2., -1., -3.])
    """
    out = np.eye(3)
    out[:2, :2] = _FLIGHT_MATRICES[FlightDirection(flight_direction)]
    return out


def flight_from_sensor(xy: ArrayLike, flight_direction: FlightDirection | str) -> FloatArray:
    """Turn sensor coordinates so that x runs along the flight and y to its left.

    Parameters
    ----------
    xy : array_like, shape (K, 2)
        Image coordinates in the sensor axes (x right, y up), any unit.
    flight_direction : {"+x", "-x", "+y", "-y"}
        The sensor axis that points along the flight.

    Returns
    -------
    ndarray, shape (K, 2)
        ``(x', y')`` of method.md section 2: ``"+x"``: unchanged; ``"-x"``:
        ``(-x, -y)``; ``"+y"``: ``(y, -x)``; ``"-y"``: ``(-y, x)``.  A proper
        rotation about the image z axis (90° steps), so the image system stays
        right-handed with z up.

    Examples
    --------
    >>> flight_from_sensor([[1.0, 2.0]], "+y")
    array([[ 2., -1.]])
    """
    arr = _as_xy(xy)
    matrix = _FLIGHT_MATRICES[FlightDirection(flight_direction)]
    return arr @ matrix.T


def sensor_from_flight(xy: ArrayLike, flight_direction: FlightDirection | str) -> FloatArray:
    """Inverse of :func:`flight_from_sensor` (method's axes back to sensor axes)."""
    arr = _as_xy(xy)
    matrix = _FLIGHT_MATRICES[FlightDirection(flight_direction)]
    return arr @ matrix


def corrected_flight_direction(
    flight_direction: FlightDirection | str, along: str
) -> FlightDirection:
    """The flight direction to set when the photos move along another axis.

    Parameters
    ----------
    flight_direction : {"+x", "-x", "+y", "-y"}
        The flight direction the image coordinates were turned with.
    along : {"+x", "-x", "+y", "-y"}
        The axis of the turned coordinates (the method's x, y) that the
        photos actually move along.

    Returns
    -------
    FlightDirection
        The sensor axis that points along the flight.

    Examples
    --------
    >>> corrected_flight_direction("+y", "-x").value
    '-y'
    >>> corrected_flight_direction("+x", "+y").value
    '+y'
    """
    unit = {"+x": (1.0, 0.0), "-x": (-1.0, 0.0), "+y": (0.0, 1.0), "-y": (0.0, -1.0)}
    if along not in unit:
        raise ValueError(f"Expected `along` in {tuple(unit)}, got {along!r}")
    sx, sy = sensor_from_flight([unit[along]], flight_direction)[0]
    axis = "x" if abs(sx) > abs(sy) else "y"
    sign = "+" if (sx if axis == "x" else sy) > 0 else "-"
    return FlightDirection(sign + axis)


# --------------------------------------------------------------------------- distortion


@dataclass(frozen=True)
class BrownDistortion:
    """Radial and decentring lens distortion, Brown's polynomials.

    With ``(x, y)`` reduced to the principal point in the sensor axes (x
    right, y up, mm), ``r² = x² + y²`` (``u = x/c``, ``v = y/c`` in place of x,
    y for ``units = "normalized"``), the shift is

    ``Δx = x (k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2 x²) + 2 p2 x y + b1 x + b2 y``

    ``Δy = y (k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2 y²)``

    (``b1`` affinity and ``b2`` shear of the sensor or film, Fraser 1997; a
    self-calibration's ``camera.toml`` may carry them.)

    (radial: Brown 1971; decentring: Brown 1966, with his pairing of P1 with
    ``r² + 2x²``.  OpenCV names the same terms the other way round: OpenCV's
    p1 is this p2 and its p2 this p1.)

    ``model = "correction"`` (Brown 1971, classical photogrammetry, also the
    MATLAB ``STRIP.m`` of the FC300X data): the polynomials are evaluated at
    the *measured* point and ``corrected = measured + Δ(measured)``.
    ``model = "projection"`` (OpenCV, Agisoft): they map the *ideal* point to
    the distorted one, ``measured = ideal + Δ(ideal)``; the correction inverts
    this by fixed-point iteration.

    Coefficients from a y-down system (OpenCV, Agisoft pixel frames) keep k1,
    k2, k3 and p1 and change the sign of p2 in these y-up axes.

    Attributes
    ----------
    k1, k2, k3 : float
        Radial coefficients (mm^-2, mm^-4, mm^-6 for units "mm").
    p1, p2 : float
        Decentring coefficients (mm^-1 for units "mm").
    b1, b2 : float
        Affinity and shear (dimensionless).
    units : DistortionUnits
    model : DistortionModel

    References
    ----------
    Brown, D. C. (1966). Decentering distortion of lenses. Photogrammetric
    Engineering 32(3), 444-462.
    Brown, D. C. (1971). Close-range camera calibration. Photogrammetric
    Engineering 37(8), 855-866.
    """

    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    b1: float = 0.0
    b2: float = 0.0
    units: DistortionUnits = DistortionUnits.MM
    model: DistortionModel = DistortionModel.CORRECTION

    def __post_init__(self) -> None:
        object.__setattr__(self, "units", DistortionUnits(self.units))
        object.__setattr__(self, "model", DistortionModel(self.model))
        for name in ("k1", "k2", "k3", "p1", "p2", "b1", "b2"):
            value = float(getattr(self, name))
            if not np.isfinite(value):
                raise ValueError(f"Expected `{name}` to be finite, got {value!r}")
            object.__setattr__(self, name, value)

    @property
    def is_zero(self) -> bool:
        """True when every coefficient is zero (no correction)."""
        return not any((self.k1, self.k2, self.k3, self.p1, self.p2, self.b1, self.b2))


def distortion_shift(
    xy: ArrayLike, distortion: BrownDistortion, principal_distance_mm: float
) -> FloatArray:
    """Brown's polynomials Δ evaluated at ``xy`` (see :class:`BrownDistortion`).

    Parameters
    ----------
    xy : array_like, shape (K, 2)
        Image coordinates in mm reduced to the principal point, sensor axes
        (x right, y up).
    distortion : BrownDistortion
    principal_distance_mm : float
        c, for ``units = "normalized"``.

    Returns
    -------
    ndarray, shape (K, 2)
        Δx, Δy in mm.
    """
    arr = _as_xy(xy)
    d = distortion
    norm = float(principal_distance_mm) if d.units is DistortionUnits.NORMALIZED else 1.0
    if not (np.isfinite(norm) and norm > 0):
        raise ValueError(f"Expected `principal_distance_mm` > 0, got {principal_distance_mm!r}")
    x = arr[:, 0] / norm
    y = arr[:, 1] / norm
    r2 = x * x + y * y
    radial = r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3))
    out = np.empty_like(arr)
    out[:, 0] = x * radial + d.p1 * (r2 + 2.0 * x * x) + 2.0 * d.p2 * x * y
    if d.b1 or d.b2:  # affinity and shear (kept out of the sum when zero: same bits)
        out[:, 0] += d.b1 * x + d.b2 * y
    out[:, 1] = y * radial + 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * y * y)
    return out * norm


def correct_distortion(
    xy: ArrayLike,
    distortion: BrownDistortion,
    principal_distance_mm: float,
    *,
    max_iterations: int = 20,
    tolerance_mm: float = 1e-9,
) -> FloatArray:
    """Measured image coordinates corrected for lens distortion.

    Parameters
    ----------
    xy : array_like, shape (K, 2)
        Measured coordinates in mm reduced to the principal point, sensor axes.
    distortion : BrownDistortion
        Coefficients, units and model (see there for the exact formulas).
    principal_distance_mm : float
        c in mm (used by ``units = "normalized"``).
    max_iterations, tolerance_mm
        Of the fixed-point inversion for ``model = "projection"``:
        ``ideal ← measured − Δ(ideal)`` until no coordinate moves by more than
        ``tolerance_mm``.

    Returns
    -------
    ndarray, shape (K, 2)
        ``measured + Δ(measured)`` for ``"correction"``; the ideal point with
        ``ideal + Δ(ideal) = measured`` for ``"projection"``.

    Raises
    ------
    ConvergenceError
        If the inversion of a "projection" model does not converge (the
        distortion is not invertible over the measured area).
    """
    measured = _as_xy(xy)
    if distortion.is_zero:
        return measured.copy()
    if distortion.model is DistortionModel.CORRECTION:
        return measured + distortion_shift(measured, distortion, principal_distance_mm)
    from .errors import ConvergenceError

    ideal = measured.copy()
    step = float("nan")
    for _ in range(max_iterations):
        with np.errstate(over="ignore", invalid="ignore"):
            new = measured - distortion_shift(ideal, distortion, principal_distance_mm)
            step = float(np.max(np.abs(new - ideal), initial=0.0))
        if not np.isfinite(step):
            break
        ideal = new
        if step <= tolerance_mm:
            return ideal
    raise ConvergenceError(
        f"lens distortion: the inversion of the projection model did not converge in "
        f"{max_iterations} iterations (last step {step:.3g} mm); check the coefficients "
        "and their units"
    )


# --------------------------------------------------------------------------- fiducials


@dataclass(frozen=True)
class FiducialFit:
    """Interior orientation of one photo from its fiducial marks.

    The transformation maps comparator coordinates ``(x, y)`` to calibrated
    coordinates ``(x', y')``::

        x' = a0 + a1 x + a2 y
        y' = b0 + b1 x + b2 y

    (similarity: ``b2 = a1``, ``b1 = -a2``).  The deformation (scale)
    coefficients are the lengths of the images of the comparator axes,
    ``scale_x = hypot(a1, b1)``, ``scale_y = hypot(a2, b2)``; R4 §1.7.7.1 asks
    that each differ from 1 by at most a few units of the 4th decimal and that
    their difference be at most a few units of the 5th.

    Attributes
    ----------
    photo_id : str
    transform : FiducialTransform
    marks : tuple of str
        The marks used, in the order of ``residuals``.
    parameters : ndarray, shape (2, 3)
        ``[[a0, a1, a2], [b0, b1, b2]]``.
    residuals : ndarray, shape (n_marks, 2)
        Calibrated minus transformed comparator coordinates, mm.
    rms_mm : float
        RMS of the residual coordinates (NaN without redundancy).
    scale_x, scale_y : float
    rotation : float
        Angle of the comparator x axis in the calibrated system, radians.
    scale_ok, difference_ok : bool
        Verdicts of R4 §1.7.7.1 with the tolerances used.
    """

    photo_id: str
    transform: FiducialTransform
    marks: tuple[str, ...]
    parameters: FloatArray
    residuals: FloatArray
    rms_mm: float
    scale_x: float
    scale_y: float
    rotation: float
    scale_ok: bool
    difference_ok: bool

    @property
    def passed(self) -> bool:
        """Both R4 §1.7.7.1 checks passed."""
        return self.scale_ok and self.difference_ok

    def apply(self, xy: ArrayLike) -> FloatArray:
        """Comparator ``(K, 2)`` -> calibrated fiducial system ``(K, 2)``."""
        arr = _as_xy(xy)
        return self.parameters[:, 0] + arr @ self.parameters[:, 1:].T

    def message(self) -> str:
        """One line describing a failed check (empty when both passed)."""
        if self.passed:
            return ""
        return (
            f"photo '{self.photo_id}': interior orientation ({self.transform.value}) scale "
            f"coefficients {self.scale_x:.6f}, {self.scale_y:.6f} (difference "
            f"{self.scale_x - self.scale_y:+.6f}) fail R4 1.7.7.1 (|s - 1| within a few units "
            "of the 4th decimal, |sx - sy| within a few units of the 5th)"
        )


def fit_fiducial_transform(
    comparator: ArrayLike,
    calibrated: ArrayLike,
    transform: FiducialTransform | str = FiducialTransform.AFFINE,
    *,
    photo_id: str = "",
    marks: tuple[str, ...] = (),
    scale_tolerance: float = DEFAULT_SCALE_TOLERANCE,
    difference_tolerance: float = DEFAULT_DIFFERENCE_TOLERANCE,
) -> FiducialFit:
    """Least-squares transformation of one photo's fiducial marks.

    Parameters
    ----------
    comparator : array_like, shape (n, 2)
        Measured coordinates of the marks (mm, any origin and rotation).
    calibrated : array_like, shape (n, 2)
        Their calibrated coordinates from the camera certificate, mm.
    transform : {"similarity", "affine"}
        4 parameters (n >= 2) or 6 parameters (n >= 3).
    photo_id, marks
        Labels carried into the result.
    scale_tolerance, difference_tolerance : float
        R4 §1.7.7.1 limits: ``|s - 1| <= scale_tolerance`` for both
        coefficients and ``|sx - sy| <= difference_tolerance`` (defaults 5e-4
        and 5e-5: "a few units" of the 4th and 5th decimal read as 5).

    Returns
    -------
    FiducialFit

    Raises
    ------
    GeometryError
        Too few marks for the transformation, or marks on one line.
    """
    from .errors import GeometryError

    src = _as_xy(comparator, "comparator")
    dst = _as_xy(calibrated, "calibrated")
    if src.shape != dst.shape:
        raise ValueError(
            f"Expected `comparator` and `calibrated` of equal shape, got {src.shape}, {dst.shape}"
        )
    kind = FiducialTransform(transform)
    n = src.shape[0]
    need = 2 if kind is FiducialTransform.SIMILARITY else 3
    label = f"photo '{photo_id}': " if photo_id else ""
    if n < need:
        raise GeometryError(
            f"{label}interior orientation: a {kind.value} transformation needs at least "
            f"{need} fiducial marks, got {n}"
        )
    # Centre both sets for a well-conditioned solution.
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    s, d = src - cs, dst - cd
    if kind is FiducialTransform.SIMILARITY:
        # x' = a x - b y, y' = b x + a y
        design = np.zeros((2 * n, 2))
        design[0::2, 0], design[0::2, 1] = s[:, 0], -s[:, 1]
        design[1::2, 0], design[1::2, 1] = s[:, 1], s[:, 0]
        sol, _, rank, _ = np.linalg.lstsq(design, d.reshape(-1), rcond=None)
        if rank < 2:
            raise GeometryError(f"{label}interior orientation: the fiducial marks coincide")
        a, b = sol
        linear = np.array([[a, -b], [b, a]])
        dof = 2 * n - 4
    else:
        sol, _, rank, _ = np.linalg.lstsq(s, d, rcond=None)
        if rank < 2:
            raise GeometryError(f"{label}interior orientation: the fiducial marks lie on one line")
        linear = sol.T
        dof = 2 * n - 6
    shift = cd - linear @ cs
    parameters = np.column_stack([shift, linear])
    residuals = dst - (shift + src @ linear.T)
    rms = float(np.sqrt(np.sum(residuals**2) / dof)) if dof > 0 else float("nan")
    scale_x = float(np.hypot(linear[0, 0], linear[1, 0]))
    scale_y = float(np.hypot(linear[0, 1], linear[1, 1]))
    scale_ok = abs(scale_x - 1.0) <= scale_tolerance and abs(scale_y - 1.0) <= scale_tolerance
    difference_ok = abs(scale_x - scale_y) <= difference_tolerance
    return FiducialFit(
        photo_id=photo_id,
        transform=kind,
        marks=tuple(marks),
        parameters=parameters,
        residuals=residuals,
        rms_mm=rms,
        scale_x=scale_x,
        scale_y=scale_y,
        rotation=float(np.arctan2(linear[1, 0], linear[0, 0])),
        scale_ok=bool(scale_ok),
        difference_ok=bool(difference_ok),
    )


def fit_fiducial_transforms(
    photo: ArrayLike,
    comparator: ArrayLike,
    calibrated: ArrayLike,
    photo_ids: tuple[str, ...],
    transform: FiducialTransform | str = FiducialTransform.AFFINE,
    *,
    marks: tuple[str, ...] | None = None,
    scale_tolerance: float = DEFAULT_SCALE_TOLERANCE,
    difference_tolerance: float = DEFAULT_DIFFERENCE_TOLERANCE,
) -> tuple[FiducialFit, ...]:
    """:func:`fit_fiducial_transform` for every photo.

    Parameters
    ----------
    photo : array_like of int, shape (n,)
        Photo index (into ``photo_ids``) of each mark measurement.
    comparator, calibrated : array_like, shape (n, 2)
        Measured and calibrated coordinates of each measurement, mm.
    photo_ids : tuple of str
    transform, scale_tolerance, difference_tolerance
        As for :func:`fit_fiducial_transform`.
    marks : tuple of str, length n, optional
        Mark id of each measurement.

    Returns
    -------
    tuple of FiducialFit, one per photo of ``photo_ids``.
    """
    index = np.asarray(photo, dtype=np.intp).reshape(-1)
    src = _as_xy(comparator, "comparator")
    dst = _as_xy(calibrated, "calibrated")
    names = tuple(marks) if marks is not None else tuple("" for _ in range(index.shape[0]))
    fits = []
    for i, pid in enumerate(photo_ids):  # one small solution per photo
        rows = np.flatnonzero(index == i)
        fits.append(
            fit_fiducial_transform(
                src[rows],
                dst[rows],
                transform,
                photo_id=pid,
                marks=tuple(names[r] for r in rows),
                scale_tolerance=scale_tolerance,
                difference_tolerance=difference_tolerance,
            )
        )
    return tuple(fits)


def apply_fiducial_transforms(
    xy: ArrayLike, photo: ArrayLike, fits: tuple[FiducialFit, ...]
) -> FloatArray:
    """Comparator coordinates of observations to the calibrated system, per photo.

    Parameters
    ----------
    xy : array_like, shape (K, 2)
        Comparator coordinates, mm.
    photo : array_like of int, shape (K,)
        Index into ``fits`` of each observation's photo.
    fits : tuple of FiducialFit

    Returns
    -------
    ndarray, shape (K, 2)
    """
    arr = _as_xy(xy)
    index: IntArray = np.asarray(photo, dtype=np.intp).reshape(-1)
    params = np.stack([f.parameters for f in fits])[index]  # (K, 2, 3)
    corrected: FloatArray = params[:, :, 0] + np.einsum("kij,kj->ki", params[:, :, 1:], arr)
    return corrected


def reduce_image_coordinates(
    xy: ArrayLike,
    photo: ArrayLike,
    principal_distance_mm: float,
    *,
    units: ImageUnits | str = ImageUnits.MM,
    pixel_size_mm: float | None = None,
    principal_point_px: ArrayLike | None = None,
    fiducials: tuple[FiducialFit, ...] | None = None,
    principal_point_mm: ArrayLike = (0.0, 0.0),
    distortion: BrownDistortion | None = None,
    flight_direction: FlightDirection | str = FlightDirection.PLUS_X,
) -> FloatArray:
    """All interior-orientation steps, in the order of the module notes.

    Parameters
    ----------
    xy : array_like, shape (K, 2)
        Measured coordinates: mm (x right, y up) or pixel column/row.
    photo : array_like of int, shape (K,)
        Photo index of each observation (into ``fiducials``).
    principal_distance_mm : float
        c in mm.
    units : {"mm", "pixel"}
    pixel_size_mm, principal_point_px
        For ``units = "pixel"`` (see :func:`mm_from_pixel`).
    fiducials : tuple of FiducialFit, optional
        Per-photo comparator -> calibrated transformations (applied after the
        pixel conversion).
    principal_point_mm : array_like, shape (2,)
        x0, y0 in the (calibrated) sensor axes, subtracted.
    distortion : BrownDistortion, optional
    flight_direction : {"+x", "-x", "+y", "-y"}

    Returns
    -------
    ndarray, shape (K, 2)
        x along the flight, y to its left, mm, reduced to the principal point
        and corrected for distortion.  With the defaults (mm, no fiducials,
        principal point 0, no distortion, "+x") a copy of ``xy``.
    """
    out = _as_xy(xy).copy()
    if ImageUnits(units) is ImageUnits.PIXEL:
        if pixel_size_mm is None or principal_point_px is None:
            raise ValueError(
                "Expected `pixel_size_mm` and `principal_point_px` for units = 'pixel'"
            )
        out = mm_from_pixel(out, pixel_size_mm, principal_point_px)
    if fiducials:
        out = apply_fiducial_transforms(out, photo, fiducials)
    out -= np.asarray(principal_point_mm, dtype=np.float64).reshape(2)
    if distortion is not None and not distortion.is_zero:
        out = correct_distortion(out, distortion, principal_distance_mm)
    if FlightDirection(flight_direction) is not FlightDirection.PLUS_X:
        out = flight_from_sensor(out, flight_direction)
    return out
