"""The camera's own systematic errors as additional parameters (method.md 6C).

Two families of corrections to image coordinates, both vectorised, with
their partial derivatives with respect to every parameter and to the image
coordinates:

* **Brown/Fraser** (Fraser 1997), ten parameters in this order::

      c, x0, y0, k1, k2, k3, p1, p2, b1, b2

  All are *increments* from the start camera (``[camera]`` and the
  ``[distortion]`` already applied to the coordinates): ``c`` the change of
  the principal distance (mm), ``x0, y0`` the change of the principal point
  (mm, sensor axes), ``k1, k2, k3`` radial (mm^-2, mm^-4, mm^-6), ``p1, p2``
  decentring (mm^-1), ``b1`` affinity and ``b2`` shear (dimensionless).  With
  ``x̄ = x - x0``, ``ȳ = y - y0``, ``r² = x̄² + ȳ²`` and ``c`` the start
  principal distance, the correction added to the measured coordinates is::

      Δx = -x0 - (x̄/c) dc + x̄ (k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2x̄²) + 2 p2 x̄ȳ + b1 x̄ + b2 ȳ
      Δy = -y0 - (ȳ/c) dc + ȳ (k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x̄ȳ + p2 (r² + 2ȳ²)

  which is method.md 6C's formula with its ``Δx0`` written as the principal
  point's own change (``x̄ = x - x0``: a principal point moved by ``+x0``
  shifts the reduced coordinates by ``-x0``).  The corrected coordinates
  ``x + Δx`` are what the collinearity equations with the start ``c`` see
  (the bundle takes its residual at the true position ``x̂``, ``x̂ + Δ(x̂) =
  x(S, R, X)``, in the observations' space: :mod:`strip_aerotri.bundle._observation_space`);
  the adjusted camera is ``c + dc``, ``x0 + dx0``, the distortion
  coefficients added to the start ones (:mod:`strip_aerotri.interior`'s
  ``model = "correction"``, ``units = "mm"``).

* **Ebner's 12** orthogonal parameters for film (Ebner 1976, the set of
  PAT-B), over the 3 x 3 grid of the standard overlap with spacing ``b``
  (the base at image scale, mm); ``m = 2b²/3`` is the mean of ``x²`` over
  the grid points ``{-b, 0, b}``::

      Δx =  e1 x + e2 y - 2 e3 (x² - m) + e4 xy + e5 (y² - m)
            + e7 x (y² - m) + e9 y (x² - m) + e11 (x² - m)(y² - m)
      Δy = -e1 y + e2 x + e3 xy - 2 e4 (y² - m) + e6 (x² - m)
            + e8 y (x² - m) + e10 x (y² - m) + e12 (x² - m)(y² - m)

  (``2(x² - m) = 2x² - 4b²/3`` as Ebner writes it).  Over the nine grid
  points the twelve correction fields are mutually orthogonal, which is the
  defining property of the set (tested).  The parameters are dimensionless
  (e1, e2), mm^-1 (e3-e6), mm^-2 (e7-e10) and mm^-3 (e11, e12).

* **Rolling shutter** (:class:`ShutterMotion`; Vautherin et al. 2016): a
  rolling-shutter sensor reads its rows one after the other, and the row read
  at the fraction ``t`` of the readout (0 the first row, 1 the last) sees the
  projection centre moved by ``d (t - 1/2)`` from where it is at the middle
  row, ``d`` (metres, frame axes) the centre's displacement over the whole
  readout (speed times readout time).  Vautherin et al. model it per photo
  with a translation and a small rotation; here one ``d`` per group of
  photos (a strip, flown at a steady speed and heading), translation only.
  The collinearity equation of an observation on photo ``j`` of group ``g``
  is ``x(S_j + s d_g, R_j, X)`` with ``s = t - 1/2`` of the row the ray
  lands on, its true position's (:meth:`ShutterMotion.row_gradient`,
  :meth:`ShutterMotion.image_velocity`;
  :mod:`strip_aerotri.bundle._observation_space`), so ``dx/dd_g = s
  dx/dS_j``: the centre's columns of the collinearity Jacobian times ``s``,
  three columns per group in the dense border of the normal equations
  (method.md 6B).  Rows are read along the sensor's y axis from the top (y
  up, so ``s = -ȳ / h``, ``ȳ`` the image y from the principal point and
  ``h`` the extent of the rows read, mm).  Over flat ground a motion along
  the rows (forward, when the flight runs along image y) acts on the image
  as an affinity, which b1 also takes; lateral and vertical motion, and
  speeds that differ per strip, do not.

Coordinates are in the sensor axes (x right, y up, mm, reduced to the start
principal point); :class:`CameraModel` takes and returns the method's
flight axes and turns them into the sensor's and back.

References
----------
Fraser, C. S. (1997). Digital camera self-calibration. ISPRS Journal of
Photogrammetry and Remote Sensing 52(4), 149-159.
Ebner, H. (1976). Self calibrating block adjustment. Bildmessung und
Luftbildwesen 44, 128-139.
Vautherin, J., Rutishauser, S., Schneider-Zapp, K., Choi, H. F.,
Chovancova, V., Glass, A., Strecha, C. (2016). Photogrammetric accuracy and
modeling of rolling shutter cameras. ISPRS Annals III-3, 139-146.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray

__all__ = [
    "BROWN_PARAMETERS",
    "EBNER_PARAMETERS",
    "PARAMETER_UNITS",
    "CameraModel",
    "ShutterMotion",
    "brown_correction",
    "brown_partials",
    "brown_xy_partials",
    "ebner_correction",
    "ebner_partials",
    "ebner_xy_partials",
]

#: The Brown/Fraser parameters in their fixed order.
BROWN_PARAMETERS = ("c", "x0", "y0", "k1", "k2", "k3", "p1", "p2", "b1", "b2")
#: Ebner's twelve parameters.
EBNER_PARAMETERS = tuple(f"e{i}" for i in range(1, 13))
#: Unit of each parameter.
PARAMETER_UNITS: dict[str, str] = {
    "c": "mm",
    "x0": "mm",
    "y0": "mm",
    "k1": "mm^-2",
    "k2": "mm^-4",
    "k3": "mm^-6",
    "p1": "mm^-1",
    "p2": "mm^-1",
    "b1": "1",
    "b2": "1",
    **dict.fromkeys(("e1", "e2"), "1"),
    **dict.fromkeys(("e3", "e4", "e5", "e6"), "mm^-1"),
    **dict.fromkeys(("e7", "e8", "e9", "e10"), "mm^-2"),
    **dict.fromkeys(("e11", "e12"), "mm^-3"),
}


def _xy(xy: ArrayLike) -> FloatArray:
    arr = np.asarray(xy, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"Expected `xy` to have shape (K, 2), got {arr.shape}")
    return arr


def _times_2x2(a: FloatArray, m: FloatArray) -> FloatArray:
    """``a @ m`` for rows ``a`` (..., 2) and a 2 x 2 ``m``, as two scaled
    columns: numpy's matmul of a (K, 2) by a (2, 2) matrix is ten times slower
    than this (0.22 s against 0.025 s at K = 419 000)."""
    out: FloatArray = a[..., :1] * m[0] + a[..., 1:] * m[1]
    return out


def _brown_values(values: ArrayLike) -> FloatArray:
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    if v.shape != (10,):
        raise ValueError(f"Expected 10 Brown/Fraser values {BROWN_PARAMETERS}, got {v.shape}")
    return v


def _brown_terms(
    xy: FloatArray, v: FloatArray, c: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """x̄, ȳ, r², the radial factor R(r²) and its derivative dR/d(r²)."""
    xb = xy[:, 0] - v[1]
    yb = xy[:, 1] - v[2]
    r2 = xb * xb + yb * yb
    radial = r2 * (v[3] + r2 * (v[4] + r2 * v[5]))
    d_radial = v[3] + r2 * (2.0 * v[4] + 3.0 * r2 * v[5])
    return xb, yb, r2, radial, d_radial


def brown_correction(xy: ArrayLike, values: ArrayLike, c: float) -> FloatArray:
    """Brown/Fraser correction Δ (K, 2) in mm at measured ``xy`` (K, 2), mm.

    ``values`` are the ten increments of :data:`BROWN_PARAMETERS`; ``c`` is
    the start principal distance (mm).
    """
    arr, v = _xy(xy), _brown_values(values)
    return _brown_delta(arr, v, c, _brown_terms(arr, v, c))


def _brown_delta(
    arr: FloatArray,
    v: FloatArray,
    c: float,
    terms: tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray],
) -> FloatArray:
    xb, yb, r2, radial, _ = terms
    out = np.empty_like(arr)
    out[:, 0] = (
        -v[1]
        - xb / c * v[0]
        + xb * radial
        + v[6] * (r2 + 2.0 * xb * xb)
        + 2.0 * v[7] * xb * yb
        + v[8] * xb
        + v[9] * yb
    )
    out[:, 1] = (
        -v[2] - yb / c * v[0] + yb * radial + 2.0 * v[6] * xb * yb + v[7] * (r2 + 2.0 * yb * yb)
    )
    return out


def _brown_dd(
    xy: FloatArray,
    v: FloatArray,
    c: float,
    terms: tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray] | None = None,
) -> FloatArray:
    """Derivative (K, 2, 2) of the correction's non-shift part with respect to
    (x̄, ȳ) (``terms``: :func:`_brown_terms` of the same arguments, if at hand)."""
    xb, yb, _, radial, d_radial = _brown_terms(xy, v, c) if terms is None else terms
    jac = np.empty((xy.shape[0], 2, 2))
    common = -v[0] / c + radial
    cross = 2.0 * xb * yb * d_radial
    jac[:, 0, 0] = common + 2.0 * xb * xb * d_radial + 6.0 * v[6] * xb + 2.0 * v[7] * yb + v[8]
    jac[:, 0, 1] = cross + 2.0 * v[6] * yb + 2.0 * v[7] * xb + v[9]
    jac[:, 1, 0] = cross + 2.0 * v[6] * yb + 2.0 * v[7] * xb
    jac[:, 1, 1] = common + 2.0 * yb * yb * d_radial + 2.0 * v[6] * xb + 6.0 * v[7] * yb
    return jac


def brown_xy_partials(xy: ArrayLike, values: ArrayLike, c: float) -> FloatArray:
    """∂Δ/∂(x, y), shape (K, 2, 2): row the component of Δ, column x or y."""
    return _brown_dd(_xy(xy), _brown_values(values), c)


def brown_partials(xy: ArrayLike, values: ArrayLike, c: float) -> FloatArray:
    """∂Δ/∂(values), shape (K, 2, 10), columns in the order of :data:`BROWN_PARAMETERS`."""
    arr, v = _xy(xy), _brown_values(values)
    xb, yb, r2, _, _ = _brown_terms(arr, v, c)
    k = arr.shape[0]
    jac = np.zeros((k, 2, 10))
    jac[:, 0, 0], jac[:, 1, 0] = -xb / c, -yb / c
    # x0, y0 enter through x̄ = x - x0 and the shift -x0: ∂Δ/∂x0 = -e_x - ∂D/∂x̄.
    dd = _brown_dd(arr, v, c)
    jac[:, :, 1:3] = -dd
    jac[:, 0, 1] -= 1.0
    jac[:, 1, 2] -= 1.0
    r4 = r2 * r2
    for col, power in ((3, r2), (4, r4), (5, r4 * r2)):
        jac[:, 0, col], jac[:, 1, col] = xb * power, yb * power
    jac[:, 0, 6], jac[:, 1, 6] = r2 + 2.0 * xb * xb, 2.0 * xb * yb
    jac[:, 0, 7], jac[:, 1, 7] = 2.0 * xb * yb, r2 + 2.0 * yb * yb
    jac[:, 0, 8] = xb
    jac[:, 0, 9] = yb
    return jac


def ebner_partials(xy: ArrayLike, base_mm: float) -> FloatArray:
    """∂Δ/∂(e1..e12), shape (K, 2, 12): Ebner's twelve correction fields."""
    arr = _xy(xy)
    b = float(base_mm)
    if not (np.isfinite(b) and b > 0.0):
        raise ValueError(f"Expected a positive grid spacing `base_mm`, got {base_mm!r}")
    x, y = arr[:, 0], arr[:, 1]
    m = 2.0 * b * b / 3.0
    xm, ym = x * x - m, y * y - m
    jac = np.zeros((arr.shape[0], 2, 12))
    jac[:, 0, 0], jac[:, 1, 0] = x, -y
    jac[:, 0, 1], jac[:, 1, 1] = y, x
    jac[:, 0, 2], jac[:, 1, 2] = -2.0 * xm, x * y
    jac[:, 0, 3], jac[:, 1, 3] = x * y, -2.0 * ym
    jac[:, 0, 4] = ym
    jac[:, 1, 5] = xm
    jac[:, 0, 6] = x * ym
    jac[:, 1, 7] = y * xm
    jac[:, 0, 8] = y * xm
    jac[:, 1, 9] = x * ym
    jac[:, 0, 10] = xm * ym
    jac[:, 1, 11] = xm * ym
    return jac


def ebner_correction(xy: ArrayLike, values: ArrayLike, base_mm: float) -> FloatArray:
    """Ebner's correction Δ (K, 2) in mm (linear in the twelve ``values``)."""
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    if v.shape != (12,):
        raise ValueError(f"Expected 12 Ebner values, got {v.shape}")
    out: FloatArray = ebner_partials(xy, base_mm) @ v
    return out


def ebner_xy_partials(xy: ArrayLike, values: ArrayLike, base_mm: float) -> FloatArray:
    """∂Δ/∂(x, y) of Ebner's correction, shape (K, 2, 2)."""
    arr = _xy(xy)
    e = np.asarray(values, dtype=np.float64).reshape(12)
    b = float(base_mm)
    x, y = arr[:, 0], arr[:, 1]
    m = 2.0 * b * b / 3.0
    xm, ym = x * x - m, y * y - m
    jac = np.empty((arr.shape[0], 2, 2))
    jac[:, 0, 0] = e[0] - 4.0 * e[2] * x + e[3] * y + e[6] * ym + 2.0 * e[8] * x * y
    jac[:, 0, 0] += 2.0 * e[10] * x * ym
    jac[:, 0, 1] = e[1] + e[3] * x + 2.0 * e[4] * y + 2.0 * e[6] * x * y + e[8] * xm
    jac[:, 0, 1] += 2.0 * e[10] * y * xm
    jac[:, 1, 0] = e[1] + e[2] * y + 2.0 * e[5] * x + 2.0 * e[7] * x * y + e[9] * ym
    jac[:, 1, 0] += 2.0 * e[11] * x * ym
    jac[:, 1, 1] = -e[0] + e[2] * x - 4.0 * e[3] * y + e[7] * xm + 2.0 * e[9] * x * y
    jac[:, 1, 1] += 2.0 * e[11] * y * xm
    return jac


@dataclass(frozen=True)
class CameraModel:
    """Which additional parameters are estimated, and how they act.

    Attributes
    ----------
    family : {"brown", "ebner"}
    estimated : tuple of str
        The estimated parameters (a subset of :data:`BROWN_PARAMETERS` or
        :data:`EBNER_PARAMETERS`, in that order).
    principal_distance_mm : float
        The start c (mm).
    base_mm : float
        Ebner's grid spacing (mm, the base at image scale); unused by Brown.
    flight_matrix : ndarray, shape (2, 2)
        Rows: the coordinates the methods take and return (the method's
        flight axes) as combinations of the sensor axes the corrections are
        defined in (a rotation by 90° steps,
        :func:`strip_aerotri.interior.flight_from_sensor`); identity by
        default (the coordinates are the sensor's).
    """

    family: str
    estimated: tuple[str, ...]
    principal_distance_mm: float
    base_mm: float = 0.0
    flight_matrix: FloatArray = field(default_factory=lambda: np.eye(2))
    #: the flight axes are the sensor's (no turn to apply)
    _unturned: bool = field(init=False, repr=False, compare=False, default=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_unturned", bool(np.array_equal(self.flight_matrix, np.eye(2))))
        names = self.all_names
        if self.family not in ("brown", "ebner"):
            raise ValueError(f"Expected family 'brown' or 'ebner', got {self.family!r}")
        unknown = [n for n in self.estimated if n not in names]
        if unknown:
            raise ValueError(f"Unknown {self.family} parameter(s) {unknown}; expected {names}")
        ordered = tuple(n for n in names if n in self.estimated)
        object.__setattr__(self, "estimated", ordered)
        if self.family == "ebner" and not self.base_mm > 0.0:
            raise ValueError(f"Expected a positive Ebner grid spacing, got {self.base_mm!r}")

    @property
    def all_names(self) -> tuple[str, ...]:
        """Every parameter of the family, in its fixed order."""
        return BROWN_PARAMETERS if self.family == "brown" else EBNER_PARAMETERS

    @property
    def columns(self) -> FloatArray:
        """Index of each estimated parameter in :attr:`all_names` (int array)."""
        names = self.all_names
        return np.array([names.index(n) for n in self.estimated], dtype=np.intp)

    def full(self, values: ArrayLike) -> FloatArray:
        """The estimated ``values`` placed into the family's full vector (0 elsewhere)."""
        out = np.zeros(len(self.all_names))
        out[self.columns] = np.asarray(values, dtype=np.float64).reshape(-1)
        return out

    def _sensor(self, xy: ArrayLike) -> FloatArray:
        if self._unturned:
            return _xy(xy)
        out: FloatArray = _times_2x2(_xy(xy), self.flight_matrix)  # rows f = M s: s = Mᵀ f
        return out

    def _flight(self, delta: FloatArray) -> FloatArray:
        """Vectors (K, 2) in the sensor axes turned to the flight axes."""
        if self._unturned:
            return delta
        out: FloatArray = _times_2x2(delta, self.flight_matrix.T)
        return out

    def correction(self, xy: ArrayLike, values: ArrayLike) -> FloatArray:
        """Δ (K, 2), mm, at coordinates ``xy`` (flight axes) for the estimated ``values``."""
        full, s = self.full(values), self._sensor(xy)
        if self.family == "brown":
            delta = brown_correction(s, full, self.principal_distance_mm)
        else:
            delta = ebner_correction(s, full, self.base_mm)
        return self._flight(delta)

    def partials(self, xy: ArrayLike, values: ArrayLike) -> FloatArray:
        """∂Δ/∂(estimated values), shape (K, 2, len(estimated)), flight axes."""
        full, s = self.full(values), self._sensor(xy)
        if self.family == "brown":
            jac = brown_partials(s, full, self.principal_distance_mm)
        else:
            jac = ebner_partials(s, self.base_mm)
        picked = jac[:, :, self.columns]  # (K, 2, k): M @ each column pair
        if self._unturned:
            return picked
        m = self.flight_matrix
        out: FloatArray = np.stack(
            [m[i, 0] * picked[:, 0] + m[i, 1] * picked[:, 1] for i in range(2)], axis=1
        )
        return out

    def xy_partials(self, xy: ArrayLike, values: ArrayLike) -> FloatArray:
        """∂Δ/∂(x, y), shape (K, 2, 2), flight axes."""
        full, s = self.full(values), self._sensor(xy)
        if self.family == "brown":
            jac = brown_xy_partials(s, full, self.principal_distance_mm)
        else:
            jac = ebner_xy_partials(s, full, self.base_mm)
        return self._flight_2x2(jac)

    def correction_and_xy_partials(
        self, xy: ArrayLike, values: ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """:meth:`correction` and :meth:`xy_partials` at once (Brown/Fraser
        shares their terms: the same values, at the cost of about one)."""
        if self.family != "brown":
            return self.correction(xy, values), self.xy_partials(xy, values)
        full, s = self.full(values), self._sensor(xy)
        c = self.principal_distance_mm
        terms = _brown_terms(s, full, c)
        delta = self._flight(_brown_delta(s, full, c, terms))
        return delta, self._flight_2x2(_brown_dd(s, full, c, terms))

    def _flight_2x2(self, jac: FloatArray) -> FloatArray:
        """``M jac Mᵀ`` (K, 2, 2) of a derivative in the sensor axes."""
        if self._unturned:
            return jac
        m = self.flight_matrix  # M jac Mᵀ per row, entry by entry (a batched matmul is slower)
        right = [_times_2x2(jac[:, i, :], m.T) for i in range(2)]  # rows of jac Mᵀ
        out = np.empty_like(jac)
        for i in range(2):
            out[:, i, :] = m[i, 0] * right[0] + m[i, 1] * right[1]
        return out


@dataclass(frozen=True)
class ShutterMotion:
    """Which photos share a readout motion, and how the rows are read.

    Attributes
    ----------
    group : ndarray of int, shape (M,)
        The group (strip) of each photo, ``0 .. len(group_names) - 1``.
    group_names : tuple of str
        A name per group (the strips' names).
    readout_mm : float
        The extent of the rows read (mm along the sensor's y axis: the
        format's height).
    flight_matrix : ndarray, shape (2, 2)
        The image coordinates the bundle takes (flight axes) as combinations
        of the sensor's (as :class:`strip_aerotri.geometry.camera_model.CameraModel`).
    """

    group: IntArray
    group_names: tuple[str, ...]
    readout_mm: float
    flight_matrix: FloatArray = field(default_factory=lambda: np.eye(2))

    def __post_init__(self) -> None:
        group = np.asarray(self.group, dtype=np.intp)
        n = len(self.group_names)
        if group.ndim != 1 or (group.size and (group.min() < 0 or group.max() >= n)):
            raise ValueError(f"Expected photo groups in 0..{n - 1}, got {group!r}")
        if not (np.isfinite(self.readout_mm) and self.readout_mm > 0.0):
            raise ValueError(f"Expected a positive readout extent, got {self.readout_mm!r}")
        object.__setattr__(self, "group", group)

    @property
    def n_groups(self) -> int:
        """The number of groups."""
        return len(self.group_names)

    @property
    def n_unknowns(self) -> int:
        """Three per group."""
        return 3 * self.n_groups

    def fractions(self, xy: FloatArray) -> FloatArray:
        """``s = t - 1/2`` (K,) of image observations ``xy`` (K, 2; flight
        axes, mm from the principal point): -1/2 at the first row, +1/2 at the
        last."""
        xy = np.asarray(xy, dtype=np.float64)
        a = self.row_gradient
        out: FloatArray = xy[:, 0] * a[0] + xy[:, 1] * a[1]
        return out

    @property
    def row_gradient(self) -> FloatArray:
        """``a = ∂s/∂x`` (2,), mm⁻¹: :meth:`fractions` is ``aᵀ x``."""
        out: FloatArray = -np.asarray(self.flight_matrix, dtype=np.float64)[:, 1] / self.readout_mm
        return out

    def image_velocity(
        self,
        motion: FloatArray,
        rotations: FloatArray,
        photo: IntArray,
        vectors: FloatArray,
        c: float,
    ) -> FloatArray:
        """``u = ∂x/∂s`` (K, 2), mm: how each projection ``x = -c v_xy / v_z``
        moves with the fraction ``s`` as its centre moves by ``s d_g``.  With
        ``v = Rᵀ(X - S - s d)`` (``vectors`` (K, 3), at the ray's fraction)
        and ``w = Rᵀ d`` (``rotations`` (M, 3, 3) of the photos, ``motion``
        (G, 3), m), ``u = c (w_xy v_z - v_xy w_z) / v_z²``."""
        d = np.asarray(motion, dtype=np.float64)[self.group]  # (M, 3) per photo
        w = np.einsum("mji,mj->mi", rotations, d)[photo]  # Rᵀ d per ray
        vz = vectors[:, 2:3]
        out: FloatArray = c * (w[:, :2] * vz - vectors[:, :2] * w[:, 2:3]) / vz**2
        return out

    def centre_shift(self, motion: FloatArray, photo: IntArray, s: FloatArray) -> FloatArray:
        """The centre's displacement ``s d_g`` (K, 3), m, at each observation
        (``motion`` (G, 3), ``photo`` (K,) its photo, ``s`` its fraction)."""
        out: FloatArray = s[:, None] * np.asarray(motion, dtype=np.float64)[self.group[photo]]
        return out

    def border(self, jac_centre: FloatArray, photo: IntArray, s: FloatArray) -> FloatArray:
        """The design columns (K, 2, 3 G) of the motions: ``s dx/dS`` in the
        three columns of the observation's group, zero elsewhere
        (``jac_centre`` (K, 2, 3) the collinearity Jacobian by the centre)."""
        k = photo.size
        out = np.zeros((k, 2, self.n_groups, 3))
        out[np.arange(k), :, self.group[photo], :] = jac_centre * s[:, None, None]
        return out.reshape(k, 2, self.n_unknowns)
