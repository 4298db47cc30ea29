"""The image observation equation with self-calibration or a rolling shutter,
in the observations' space.

With a camera model Δ(x; θ) (:class:`strip_aerotri.geometry.camera_model.CameraModel`)
the measured point's true position ``x̂`` is where the corrected coordinates
meet the projection::

    x̂ + Δ(x̂; θ) = x(S, R, X)

and the observation equation is ``v = x̂ - x_obs``, weighted with the sigma of
``x_obs``: the residual is the measurement's own error, whatever c or the
affinity do to the image's scale.  (Writing it ``x(S, R, X) - (x_obs +
Δ(x_obs))`` instead scales the residual by ``I + ∂Δ/∂x``, about ``1 - dc/c``
for c, and draws the least-squares c by ``Q_cc Ω / c``: docs/bundle.md.)

``x̂`` is found by Newton's sweeps from ``x_obs``: ``x̂ <- x̂ - M (x̂ + Δ(x̂)
- x)`` with ``M = (I + ∂Δ/∂x(x̂))⁻¹`` (2 x 2 per ray, closed form; Δ and
∂Δ/∂x from one evaluation of the camera's terms).  The plain fixed point
``x̂ <- x - Δ(x̂)`` contracts by ``|∂Δ/∂x|``, 1e-3 for a camera close to its
start but 0.03-0.1 at the format's corners for distortion an uncalibrated
camera leaves (five to eleven sweeps for 1e-11 mm); Newton's first step
leaves an error of the change of ``∂Δ/∂x`` over the residual (1e-6 of it and
less), the second one of that squared.  The sweeps stop when the last step,
times its ratio to the one before (the contraction seen), is below
:data:`TOLERANCE_MM`: two sweeps in general.  The derivatives follow by the
implicit function theorem, with ``M`` evaluated at ``x̂`` once more (the
last sweep's is a step away: a relative 1e-11 of M where the residuals are
of 0.01 mm)::

    ∂v/∂(photo, point, motion) = M ∂x/∂(photo, point, motion)
    ∂v/∂θ                      = -M ∂Δ/∂θ(x̂)

A rolling shutter (:class:`Readout`) reads the ray at the row where it
lands, the true position's: its fraction of the readout is ``s(x̂) = aᵀ x̂``
(``a`` the row's gradient, :meth:`ShutterMotion.row_gradient`), and the
projection is that of the centre moved by ``s(x̂) d``::

    x̂ + Δ(x̂; θ) = x(S + s(x̂) d, R, X)

The projections are computed at the fraction of coordinates ``x_r`` and
taken along ``s`` to first order, ``x(s) = x(s_r) + u (s - s_r)`` with ``u =
∂x/∂s`` (the image's velocity over the readout, mm): their second order
``x'' (s - s_r)² / 2``, with ``|x''| ≈ 2 |u| |(Rᵀd)_z / v_z|``, is below
:data:`TOLERANCE_MM` once ``x_r`` is a first solution's ``x̂`` (1e-13 mm
with residuals of 1-2 mm: :func:`moving_space`'s two passes; the bundle
takes the first's ``x̂`` and projects at its rows with the Jacobians).  The
sweeps' matrix becomes ``I + ∂Δ/∂x - u aᵀ``, M its inverse (``u aᵀ`` is
7e-4 for the FC300X, c 3.61 mm at 53 m, moving 5 cm over its readout of
4.686 mm), and the derivatives are as above with this M.  The rows'
fraction taken from ``x_obs`` instead puts the measurement's error into the
projection: the residual becomes ``(I - u aᵀ)``
times the error, a scale of the rows' axis that moves with ``d`` and pulls
the motion along the rows, as the scale ``I + ∂Δ/∂x`` pulled c
(docs/bundle.md).  Without a camera (``model`` None) Δ is zero: the first
sweep is exact, the second confirms it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray, IntArray
from ..geometry.camera_model import CameraModel, ShutterMotion
from ..geometry.collinearity import project

__all__ = [
    "TOLERANCE_MM",
    "ObservationSpace",
    "Readout",
    "moving_space",
    "observation_space",
    "premultiply",
    "readout_at",
]

#: The sweeps stop when the error they leave is estimated below this (mm).
TOLERANCE_MM = 1e-11
#: The sweeps give up after this many (I + ∂Δ/∂x near singular: no contraction).
MAX_SWEEPS = 20


@dataclass(frozen=True)
class ObservationSpace:
    """The rays' true positions and what the observation equations take of them.

    Attributes
    ----------
    true_xy : ndarray, shape (K, 2)
        ``x̂`` (mm, the coordinates' axes).
    residuals : ndarray, shape (K, 2)
        ``v = x̂ - x_obs`` (mm).
    mapping : ndarray, shape (K, 2, 2)
        ``M = (I + ∂Δ/∂x(x̂))⁻¹``.
    sweeps : int
        The sweeps taken.
    converged : bool
        Whether the sweeps reached :data:`TOLERANCE_MM` (False, and NaN
        everywhere, when they did not: I + ∂Δ/∂x singular, a computed
        coordinate not finite).
    """

    true_xy: FloatArray
    residuals: FloatArray
    mapping: FloatArray
    sweeps: int
    converged: bool


@dataclass(frozen=True)
class Readout:
    """A rolling shutter's share in the projections the sweeps meet.

    Attributes
    ----------
    velocity : ndarray, shape (K, 2)
        ``u = ∂x/∂s`` (mm per unit fraction of the readout) at the projections.
    row : ndarray, shape (2,)
        ``a = ∂s/∂x`` (mm⁻¹): the fraction's gradient in the coordinates.
    at : ndarray, shape (K, 2)
        ``x_r``: the coordinates (mm) at whose fraction the projections
        were computed; the sweeps start there.
    """

    velocity: FloatArray
    row: FloatArray
    at: FloatArray


def inverse_2x2(a: FloatArray) -> FloatArray:
    """``(I + a)⁻¹`` per row of ``a`` (K, 2, 2), in closed form."""
    p, q = 1.0 + a[:, 0, 0], 1.0 + a[:, 1, 1]
    det = p * q - a[:, 0, 1] * a[:, 1, 0]
    out = np.empty_like(a)
    out[:, 0, 0] = q / det
    out[:, 0, 1] = -a[:, 0, 1] / det
    out[:, 1, 0] = -a[:, 1, 0] / det
    out[:, 1, 1] = p / det
    return out


def observation_space(
    model: CameraModel | None,
    values: FloatArray,
    computed: FloatArray,
    observed: FloatArray,
    readout: Readout | None = None,
) -> ObservationSpace:
    """The true positions, residuals and mappings of rays whose projections are
    ``computed`` (K, 2) and observations ``observed`` (K, 2), camera ``model``
    at ``values`` (None: no camera, Δ = 0), by Newton's sweeps from
    ``observed``; with a rolling shutter's ``readout`` the projections move
    with the row the true position is read at (the module's notes), and the
    sweeps start from ``readout.at``."""
    start = observed if readout is None else readout.at
    xhat, last = start, np.inf
    for sweep in range(1, MAX_SWEEPS + 1):
        delta, d_xy = _correction(model, values, xhat, readout)
        mapping = inverse_2x2(d_xy)
        m00, m01, m10, m11 = (mapping[:, i, j] for i in (0, 1) for j in (0, 1))
        fx, fy = (xhat + delta - computed).T
        if readout is not None:  # x(s) = x(s_r) + u aᵀ (x̂ - x_r)
            moved = readout.velocity * ((xhat - readout.at) @ readout.row)[:, None]
            fx, fy = fx - moved[:, 0], fy - moved[:, 1]
        step = np.column_stack([m00 * fx + m01 * fy, m10 * fx + m11 * fy])
        xhat = xhat - step
        size = float(np.max(np.abs(step), initial=0.0))
        if not np.isfinite(size):
            break
        if size <= TOLERANCE_MM or (sweep > 1 and size * (size / last) <= TOLERANCE_MM):
            mapping = inverse_2x2(_correction(model, values, xhat, readout, partials_only=True)[1])
            return ObservationSpace(xhat, xhat - observed, mapping, sweep, True)
        last = size
    nan = np.full_like(observed, np.nan)
    return ObservationSpace(nan, nan, np.full((observed.shape[0], 2, 2), np.nan), sweep, False)


def readout_at(
    motion: ShutterMotion,
    shifts: FloatArray,
    rays: tuple[FloatArray, IntArray, FloatArray, float],
    at: FloatArray,
) -> Readout:
    """The readout of projections computed at the fractions of ``at`` (K,
    2): ``rays`` = (the photos' rotations (M, 3, 3), the rays' photos (K,),
    their image vectors (K, 3), c), the centres moving by ``shifts`` (G, 3)."""
    rotations, photo, vectors, c = rays
    velocity = motion.image_velocity(shifts, rotations, photo, vectors, c)
    return Readout(velocity, motion.row_gradient, at)


def moving_space(
    motion: ShutterMotion,
    shifts: FloatArray,
    rays: tuple[FloatArray, FloatArray, FloatArray, IntArray, float],
    model: CameraModel | None,
    values: FloatArray,
    observed: FloatArray,
    passes: int = 2,
) -> ObservationSpace | None:
    """The observation space of rays read by a rolling shutter whose centres
    move by ``shifts`` (G, 3), m, over the readout: ``rays`` = (centres (M,
    3), rotations (M, 3, 3), the rays' points (K, 3), their photos (K,), c).
    The first pass projects at the observations' rows, each further one at
    the rows of the last one's ``x̂`` (two leave an error of the fraction's
    second order below :data:`TOLERANCE_MM`: the module's notes).  None when
    a point is behind its photo."""
    centres, rotations, points, photo, c = rays
    index = np.arange(photo.size, dtype=np.intp)
    at, space = observed, None
    for _ in range(passes):
        moved = points - motion.centre_shift(shifts, photo, motion.fractions(at))
        xy, v = project(centres, rotations, moved, photo, index, c)
        if not (np.all(v[:, 2] < 0.0) and np.all(np.isfinite(xy))):
            return None
        readout = readout_at(motion, shifts, (rotations, photo, v, c), at)
        space = observation_space(model, values, xy, observed, readout)
        if not space.converged:
            return space
        at = space.true_xy
    return space


def _correction(
    model: CameraModel | None,
    values: FloatArray,
    xy: FloatArray,
    readout: Readout | None,
    partials_only: bool = False,
) -> tuple[FloatArray | float, FloatArray]:
    """Δ(x) (K, 2; 0.0 without a camera, or when only the partials are asked
    for) and ``∂Δ/∂x - u aᵀ`` (K, 2, 2), the sweeps' matrix less I."""
    delta: FloatArray | float = 0.0
    if model is None:
        d_xy = np.zeros((xy.shape[0], 2, 2))
    elif partials_only:
        d_xy = model.xy_partials(xy, values)
    else:
        delta, d_xy = model.correction_and_xy_partials(xy, values)
    if readout is not None:
        d_xy = d_xy - readout.velocity[:, :, None] * readout.row[None, None, :]
    return delta, d_xy


def premultiply(mapping: FloatArray, jac: FloatArray) -> None:
    """``jac <- M jac`` in place, per ray: ``mapping`` (K, 2, 2), ``jac`` (K, 2, n)
    (any strides, e.g. the collinearity's views laid out entry by entry)."""
    m00, m01 = mapping[:, 0, 0, None], mapping[:, 0, 1, None]
    m10, m11 = mapping[:, 1, 0, None], mapping[:, 1, 1, None]
    first = jac[:, 0].copy()
    jac[:, 0] *= m00
    jac[:, 0] += m01 * jac[:, 1]
    jac[:, 1] *= m11
    jac[:, 1] += m10 * first
