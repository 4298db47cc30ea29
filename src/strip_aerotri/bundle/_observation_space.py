"""The self-calibration's image observation equation in the observations' space.

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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._typing import FloatArray
from ..geometry.camera_model import CameraModel

__all__ = ["TOLERANCE_MM", "ObservationSpace", "observation_space", "premultiply"]

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
    model: CameraModel, values: FloatArray, computed: FloatArray, observed: FloatArray
) -> ObservationSpace:
    """The true positions, residuals and mappings of rays whose projections are
    ``computed`` (K, 2) and observations ``observed`` (K, 2), camera ``model``
    at ``values``, by Newton's sweeps from ``observed``."""
    xhat, last = observed, np.inf
    for sweep in range(1, MAX_SWEEPS + 1):
        delta, d_xy = model.correction_and_xy_partials(xhat, values)
        mapping = inverse_2x2(d_xy)
        m00, m01, m10, m11 = (mapping[:, i, j] for i in (0, 1) for j in (0, 1))
        fx, fy = (xhat + delta - computed).T
        step = np.column_stack([m00 * fx + m01 * fy, m10 * fx + m11 * fy])
        xhat = xhat - step
        size = float(np.max(np.abs(step), initial=0.0))
        if not np.isfinite(size):
            break
        if size <= TOLERANCE_MM or (sweep > 1 and size * (size / last) <= TOLERANCE_MM):
            mapping = inverse_2x2(model.xy_partials(xhat, values))  # at x̂ itself
            return ObservationSpace(xhat, xhat - observed, mapping, sweep, True)
        last = size
    nan = np.full_like(observed, np.nan)
    return ObservationSpace(nan, nan, np.full((observed.shape[0], 2, 2), np.nan), sweep, False)


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
