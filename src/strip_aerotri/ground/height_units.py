"""Control heights in another unit than the plan control (feet, US survey
feet or decimetres with X, Y in metres, or the other way round).

The span of the heights on a photo
(:func:`strip_aerotri.plausibility.control_relief_problems`) sees a factor
of 1000, not one of 3.3.  Once the strip model is formed and scaled to the
plan control (the ground stage's first look at the control), a height unit
differing from the plan unit shows as a height scale.  Two measures of it:

* :func:`gradient_ratio`, the norm of the control heights' gradient over
  the model coordinates against that of the plan coordinates' gradients:
  the model is a similarity of the ground, so the three are equal when the
  units agree, whatever the model's rotation (the oblique FC300X strips:
  0.986-1.002 over six control splits); 3.28 for H in feet, 0.3048 for X, Y in feet with H in
  metres.  It needs four plan and four height points spanning the model in
  three dimensions;
* :func:`height_slope`, the slope of the control heights on the model's
  heights with the model's tilt taken out: the gradient's component on the
  model's z, which needs three height points and no plan fit, but shrinks
  with the cosine of the model's tilt (0.57-0.66 on the FC300X strips, their
  photos 44 degrees from the vertical).

The ratio decides where its relief tells it; the slope only where the ratio
cannot be told (fewer than four plan or height points, points on one plane
of the model, too little relief: docs/project-file.md gives the
measurements, ``benchmarks/bench_height_units.py`` makes them).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._typing import ArrayLike, FloatArray

__all__ = ["GradientRatio", "gradient_ratio", "height_slope", "height_unit_problems"]


#: Heights in another unit than the plan coordinates: the ratio of the
#: control heights' gradient over the strip model to the plan coordinates'.
#: Feet international (0.3048 m) and US survey (1200/3937 m) differ by 2e-6:
#: one factor.
_GRADIENT_FACTORS = (
    (1.0 / 0.3048, "H in feet (heights are metres, whatever the unit of X, Y)"),
    (0.3048, "X, Y in feet with H in metres"),
    (10.0, "H in decimetres (heights are metres, whatever the unit of X, Y)"),
    (0.1, "X, Y in decimetres with H in metres"),
)
#: The factors the slope of :func:`height_slope` may name, where the ratio
#: cannot be told: not 0.3048, which the cosine of a model's tilt and its
#: plan scale's error reach on oblique strips (the FC300X strips' slopes
#: 0.57-0.66, 1.9-2.2 times from it).
_HEIGHT_UNIT_SLOPES = tuple(f for f in _GRADIENT_FACTORS if f[0] != 0.3048)
#: A ratio or slope is told (enough height spread) when its standard
#: deviation is at most this share of it: the window around a unit factor is
#: then 3 of them wide, and 1 is 14 of them from 3.28 (0.3048: 46).
_SLOPE_PRECISION = 0.05
#: A ratio or slope within this share of a unit factor names that unit.
#: Real projects keep the ratio between 0.94 and 1.07 where told (the
#: examples, the external strips, the FC300X block's strips over six
#: control splits, simulated strips and blocks) and the slope between 0.57
#: and 1.26 (the FC300X strips' models are not stretched but turned: their
#: z axes 44 degrees from the vertical); the nearest window edges are 0.35
#: and 2.85 (docs/project-file.md).
_SLOPE_WINDOW = 0.15


def _told(value: float, sd: float) -> bool:
    """Whether a ratio or slope ``value`` is told by its standard deviation
    ``sd``: at most :data:`_SLOPE_PRECISION` of it (False for a NaN)."""
    return bool(sd <= _SLOPE_PRECISION * value)


class GradientRatio(NamedTuple):
    """The height's gradient over the strip model against the plan's
    (:func:`gradient_ratio`): ``ratio``, its standard deviation ``sd``, and
    the plan and height points of the fits ``n_plan``, ``n_height``."""

    ratio: float
    sd: float
    n_plan: int
    n_height: int

    @property
    def told(self) -> bool:
        """Whether the ratio is told: its standard deviation at most
        :data:`_SLOPE_PRECISION` of it (enough height spread)."""
        return _told(self.ratio, self.sd)


#: Points from which the fits are also tried with the strip's bending: terms
#: in the square and cube of the coordinate along the strip (two more
#: unknowns per coordinate, two observations to spare).  The strip method's
#: models bend as J's polynomials model them; an affine fit leaves the
#: bending in its scatter (the external strip one-inch-75pct: the ratio 1.25
#: +- 0.15 affine, 1.07 +- 0.04 with the bending), while on short strips the
#: two terms only take up relief (the FC300X strips, 10 photos: 0.063, 0.014,
#: 0.016 relative affine, 0.094, 0.032, 0.018 with them).  The ratio is the
#: one of the two with the smaller relative standard deviation.
_BENDING_POINTS = 8


def _gradients(
    model_xyz: FloatArray, values: FloatArray, sigma: FloatArray, bending: bool
) -> tuple[FloatArray, FloatArray] | None:
    """Gradients G (3, c) of ``values`` (n, c) = a + G' m (+ with ``bending``
    the strip's bending along its long axis) over the model
    points ``model_xyz`` (n, 3), weighted by 1 / ``sigma``² (n,), and the
    covariance (3, 3) each column's gradient has (the columns share it: the
    variance factor is pooled over them, at least 1, read once two or more
    observations are redundant).  None when the points lie on one plane of
    the model (nothing tells the gradient across it)."""
    w = 1.0 / sigma**2
    m = model_xyz - np.average(model_xyz, axis=0, weights=w)
    columns = [np.ones(m.shape[0]), m]
    if bending:
        # the strip's long axis: the first principal axis of the points
        along = m @ np.linalg.svd(m * np.sqrt(w)[:, None], full_matrices=False)[2][0]
        along = along / max(float(np.max(np.abs(along))), np.finfo(float).tiny)
        columns += [along**2, along**3]
    design = np.column_stack(columns)
    normal = (design * w[:, None]).T @ design
    scale = np.sqrt(np.diag(normal))
    if not (np.isfinite(scale).all() and (scale > 0.0).all()):
        return None
    eig = np.linalg.eigvalsh(normal / np.outer(scale, scale))
    if not eig[0] > 1e-12 * eig[-1]:
        return None
    cov = np.asarray(np.linalg.inv(normal), dtype=np.float64)
    coef = cov @ ((design * w[:, None]).T @ values)
    redundancy = values.size - design.shape[1] * values.shape[1]
    if redundancy >= 2:
        factor = float(np.sum(w[:, None] * (values - design @ coef) ** 2)) / redundancy
        cov = cov * max(factor, 1.0)
    return coef[1:4], cov[1:4, 1:4]


def gradient_ratio(
    plan_xyz: ArrayLike,
    plan_xy: ArrayLike,
    plan_sigma: ArrayLike,
    height_xyz: ArrayLike,
    height: ArrayLike,
    height_sigma: ArrayLike,
    model_sigma: ArrayLike = 0.0,
) -> GradientRatio | None:
    """How many times faster the control heights change over the strip model
    than its plan coordinates: 1 when H and X, Y are in one unit, whatever
    the model's rotation (3.28 for H in feet, 0.3048 for X, Y in feet).

    A strip model is a similarity of the ground, m -> s R m + t, so the
    gradient of each ground coordinate over the model coordinates is s times
    a row of R: all three of norm s, H's k s for heights in a unit k times
    smaller than the plan's.  Each is fitted as an affine function of the
    model coordinates (and with the strip's bending, :data:`_BENDING_POINTS`):
    X and Y over the plan control (``plan_xyz`` (n, 3) in the model, any
    unit; ``plan_xy`` (n, 2) given; ``plan_sigma`` (n,) their expected
    errors, plan units), H over the height control (``height_xyz`` (m, 3),
    ``height`` (m,) as given, ``height_sigma`` (m,) their own errors in H's
    unit, ``model_sigma`` the model heights' expected error in the model's
    unit, taken to H's unit by the ratio itself: a first fit at 1, a
    second at the ratio it gave).  The ratio is |grad H| over
    sqrt((|grad X|² + |grad Y|²) / 2).  The slope of :func:`height_slope` is
    the component of grad H on the model's z alone: k s cos t on a model
    whose z axis is t from the vertical.

    Returns the ratio and its standard deviation (linear propagation of both
    fits' covariances, each at least the expected errors' and, with two or
    more observations redundant, the fit's own scatter), or None with fewer
    than four points of either kind or either kind on one plane of the
    model.  Its relative standard deviation is about sigma / (sqrt(m) r),
    r the RMS spread of the height points about their plane in the model
    (ground units), sigma their expected error.
    """
    plan_m = np.asarray(plan_xyz, dtype=np.float64).reshape(-1, 3)
    height_m = np.asarray(height_xyz, dtype=np.float64).reshape(-1, 3)
    if plan_m.shape[0] < 4 or height_m.shape[0] < 4:
        return None
    xy = np.asarray(plan_xy, dtype=np.float64).reshape(-1, 2)
    h = np.asarray(height, dtype=np.float64).reshape(-1, 1)
    sigmas = (
        np.asarray(plan_sigma, dtype=np.float64).reshape(-1),
        np.asarray(height_sigma, dtype=np.float64).reshape(-1),
        np.asarray(model_sigma, dtype=np.float64),
    )
    found = [
        _ratio(plan_m, xy, height_m, h, sigmas, bending)
        for bending in (False, True)
        if not bending or min(plan_m.shape[0], height_m.shape[0]) >= _BENDING_POINTS
    ]
    told = [r for r in found if r is not None]
    if not told:
        return None
    k, sd = min(told, key=lambda r: r[1] / r[0])
    return GradientRatio(k, sd, plan_m.shape[0], height_m.shape[0])


def _ratio(
    plan_m: FloatArray,
    xy: FloatArray,
    height_m: FloatArray,
    h: FloatArray,
    sigmas: tuple[FloatArray, FloatArray, FloatArray],
    bending: bool,
) -> tuple[float, float] | None:
    """:func:`gradient_ratio`'s ratio and standard deviation from one kind of
    fit (``bending`` or not); ``sigmas`` the plan points', the heights' own
    and the model heights' expected errors."""
    plan = _gradients(plan_m, xy, sigmas[0], bending)
    if plan is None:
        return None
    g_plan, cov_plan = plan
    rho = float(np.sqrt(0.5 * np.sum(g_plan**2)))
    if not rho > 0.0:
        return None
    k = 1.0
    for _ in range(2):
        fit = _gradients(height_m, h, np.hypot(sigmas[1], k * sigmas[2]), bending)
        if fit is None:
            return None
        g_h, cov_h = fit
        norm_h = float(np.linalg.norm(g_h))
        if not (np.isfinite(norm_h) and norm_h > 0.0):
            return None
        k = norm_h / rho
    j_h = g_h[:, 0] / (norm_h * rho)  # d k / d grad H
    j_plan = -k * g_plan / (2.0 * rho**2)  # d k / d grad X, d grad Y (3, 2)
    var = float(j_h @ cov_h @ j_h) + float(np.einsum("ic,ij,jc->", j_plan, cov_plan, j_plan))
    return k, float(np.sqrt(var))


def height_slope(
    model_xyz: ArrayLike, height: ArrayLike, sigma: ArrayLike
) -> tuple[float, float] | None:
    """The slope s of H = a + bx x + by y + s z over the height control.

    ``model_xyz`` (n, 3) the control points in the strip model scaled to the
    plan control (plan units), ``height`` (n,) their control heights,
    ``sigma`` (n,) the heights' expected errors.  The tilt terms bx, by take
    up the model's tilt (a plan direction the points do not span is left
    out).  Returns s and its standard deviation (the larger of the expected
    and, with two or more redundant points, the fit's own scatter), or None
    with fewer than three points.
    """
    xyz = np.asarray(model_xyz, dtype=np.float64).reshape(-1, 3)
    h = np.asarray(height, dtype=np.float64)
    w = 1.0 / np.asarray(sigma, dtype=np.float64) ** 2
    if h.size < 3:
        return None
    plan = xyz[:, :2] - np.average(xyz[:, :2], axis=0, weights=w)
    _, sv, vt = np.linalg.svd(plan * np.sqrt(w)[:, None], full_matrices=False)
    spans = sv > 1e-6 * max(float(sv[0]), np.finfo(float).tiny)
    design = np.column_stack([np.ones_like(h), plan @ vt[spans].T, xyz[:, 2]])
    if h.size < design.shape[1]:
        design = design[:, [0, -1]]  # three points: the tilt is not told
    root_w = np.sqrt(w)[:, None]
    coef, *_ = np.linalg.lstsq(design * root_w, h * root_w[:, 0], rcond=None)
    normal = (design * w[:, None]).T @ design
    with np.errstate(all="ignore"):
        var_s = float(np.linalg.pinv(normal)[-1, -1])
    redundancy = h.size - design.shape[1]
    if redundancy >= 2:
        variance_factor = float(np.sum(w * (h - design @ coef) ** 2)) / redundancy
        var_s *= max(variance_factor, 1.0)
    return float(coef[-1]), float(np.sqrt(max(var_s, 0.0)))


def _near_factor(
    value: float, sd: float, factors: tuple[tuple[float, str], ...]
) -> str | None:
    """The cause of the unit factor ``value`` lies near, when ``sd`` tells it
    (:func:`_told`) and it lies within :data:`_SLOPE_WINDOW` of one; else
    None."""
    if not (np.isfinite(value) and np.isfinite(sd)) or value <= 0.0:
        return None
    if not _told(value, sd):
        return None
    for factor, cause in factors:
        if abs(np.log(value / factor)) <= np.log1p(_SLOPE_WINDOW):
            return cause
    return None


def height_unit_problems(
    model_xyz: ArrayLike,
    height: ArrayLike,
    sigma: ArrayLike,
    file: str = "control",
    *,
    plan: tuple[ArrayLike, ArrayLike, ArrayLike] | None = None,
    given: tuple[ArrayLike, ArrayLike, ArrayLike] | None = None,
) -> list[str]:
    """Control heights in another unit than the plan control (feet, US survey
    feet, decimetres, or X, Y in feet or decimetres with H in metres).

    ``model_xyz`` (n, 3) the height control in the strip model scaled to the
    plan control (plan units), ``height`` (n,) their control heights,
    ``sigma`` (n,) their expected errors (all for the slope); ``plan`` the
    plan control's (model points (p, 3), given X, Y (p, 2), expected errors
    (p,)) and ``given`` the height control's heights as given (n,), their
    own errors (n,) and the model heights' expected error (plan units), for
    the ratio.  The heights as given, not the work frame's: there the earth's
    curvature lowers a point by d² / 2R at d from the centre, d taken in the
    plan's unit, which for X, Y in feet bends the heights 3.28² times more
    than the model (the film example: the ratio 0.293 +- 0.039, untold, in
    the work frame; 0.310 +- 0.002 on the heights as given).

    With the plan control given, the ratio of the heights' gradient over the
    model to the plan's (:func:`gradient_ratio`) decides when it is told (its
    standard deviation at most :data:`_SLOPE_PRECISION` of it: the height
    control's RMS spread about its plane in the model must reach about sigma
    / (0.05 sqrt(n)), 1.8 m for 0.2 m at 5 points): it stops within
    :data:`_SLOPE_WINDOW` of 3.28, 0.3048, 10 or 0.1.  Otherwise the slope of
    the heights on the model's heights (:func:`height_slope`), told by the
    same rule, stops within that window of 3.28, 10 or 0.1.  A project with
    less relief passes.

    Returns
    -------
    list of str
        One message when the units disagree (empty otherwise).
    """
    ratio = (
        None
        if plan is None or given is None
        else gradient_ratio(*plan, model_xyz, *given)
    )
    if ratio is not None and ratio.told:
        cause = _near_factor(ratio.ratio, ratio.sd, _GRADIENT_FACTORS)
        if cause is None:
            return []
        return [
            f"{file}: the control heights change {ratio.ratio:.4g} times as fast as the "
            f"plan coordinates over the strip (± {ratio.sd:.2g}; the gradients over "
            f"{ratio.n_plan} plan and {ratio.n_height} height points, whatever the "
            f"strip's tilt) where the units agree at 1: {cause}?"
        ]
    n = np.asarray(height).size
    fit = height_slope(model_xyz, height, sigma)
    cause = None if fit is None else _near_factor(*fit, _HEIGHT_UNIT_SLOPES)
    if fit is None or cause is None:
        return []
    return [
        f"{file}: the control heights change {fit[0]:.4g} times as fast as the strip's "
        f"heights (± {fit[1]:.2g}; the strip scaled to the plan control, over {n} height "
        f"points) where the units agree at 1: {cause}?"
    ]
