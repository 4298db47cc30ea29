"""Control heights in another unit than the plan control (feet, US survey
feet or decimetres with X, Y in metres, or the other way round).

The span of the heights on a photo
(:func:`strip_aerotri.plausibility.control_relief_problems`) sees a factor
of 1000, not one of 3.3.  Once the strip model is formed and scaled to the
plan control (the ground stage's first look at the control), a height unit
differing from the plan unit shows as a height scale: the control heights
against the model's heights have a slope near the unit's factor instead of 1.
"""

from __future__ import annotations

import numpy as np

from .._typing import ArrayLike

__all__ = ["height_slope", "height_unit_problems"]


#: Heights in another unit than the plan coordinates: the control heights
#: against the strip model's heights (in plan units after the similarity in
#: plan) have this slope.  Feet international (0.3048 m) and US survey
#: (1200/3937 m) differ by 2e-6: one factor.  X, Y in feet with H in metres
#: (a slope of 0.3048) is not stopped here: a real block's strips reach 0.57
#: (below), where a strip's own height deformation, not its units, lowers
#: the slope, and 0.35 would be too near to refuse a project on; the other
#: rules weighed for it, and why none is safe: docs/project-file.md.
_HEIGHT_UNIT_SLOPES = (
    (1.0 / 0.3048, "H in feet (heights are metres, whatever the unit of X, Y)"),
    (10.0, "H in decimetres (heights are metres, whatever the unit of X, Y)"),
    (0.1, "X, Y in decimetres with H in metres"),
)
#: The slope is told (enough height spread) when its standard deviation is at
#: most this share of it: the window around a unit factor is then 3 of them
#: wide, and 1 is 14 of them from 3.28 (0.3048: 46).
_SLOPE_PRECISION = 0.05
#: A slope within this share of a unit factor names that unit.  Real projects
#: keep it between 0.57 and 1.26: simulated strips 0.95-1.02, the examples
#: 0.996 and 1.006, the external strips 0.97 and 1.26 (neither told), the
#: FC300X block's strips 0.57-0.66 (their models' heights stretched 1.5-1.7
#: times against their plan).
_SLOPE_WINDOW = 0.15


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


def height_unit_problems(
    model_xyz: ArrayLike, height: ArrayLike, sigma: ArrayLike, file: str = "control"
) -> list[str]:
    """Control heights in another unit than the plan control (feet, US survey
    feet, decimetres): once the strip model is scaled to the plan control, the
    control heights against the model's heights have a slope (see
    :func:`height_slope`) near the unit factor (3.28, 0.3048, 10 or 0.1)
    instead of 1.

    The slope decides when its standard deviation is at most
    :data:`_SLOPE_PRECISION` of it: the height control's RMS spread about
    the plane of its tilt must reach about sigma / (0.05 sqrt(n)) (sigma the
    heights' expected error, n the points: 1.8 m for 0.2 m at 5 points); a
    project with less relief passes.  It stops when the
    slope lies within :data:`_SLOPE_WINDOW` of a unit factor.

    Returns
    -------
    list of str
        One message when the units disagree (empty otherwise).
    """
    fit = height_slope(model_xyz, height, sigma)
    if fit is None:
        return []
    s, sigma_s = fit
    if not (np.isfinite(s) and np.isfinite(sigma_s)) or s <= 0.0:
        return []
    if sigma_s > _SLOPE_PRECISION * s:
        return []
    for factor, cause in _HEIGHT_UNIT_SLOPES:
        if abs(np.log(s / factor)) <= np.log1p(_SLOPE_WINDOW):
            return [
                f"{file}: the control heights change {s:.4g} times as fast as the strip's "
                f"heights (± {sigma_s:.2g}; the strip scaled to the plan control, over "
                f"{np.asarray(height).size} height points) where the units agree at 1: "
                f"{cause}?"
            ]
    return []
