"""Systematic errors are not blunders: control that fails in a smooth pattern.

Uncorrected camera errors (lens distortion, film affinity) bend a strip or a
block smoothly; the control then fails the blunder tests at many points at
once, in a pattern that varies slowly over the block, while a bad control
point fails alone (with, at most, its neighbours through the models).  When
more than ``max_fraction`` of the control fails, :func:`systematic_pattern`
tells the two apart on the first solution's test values, and the stages keep
the control and warn (:func:`systematic_message`) instead of stopping.

The rule: at least :data:`MIN_CONTROL_POINTS` control points, at least
:data:`MIN_FAILING_POINTS` of them failing, and a smooth surface of the plan
coordinates (a plane below 12 points, a quadratic from 12), fitted to each
component's w values, explains at least :data:`MIN_EXPLAINED` of their sum of
squares.  A single blunder leaves most of its square outside such a surface
(a quadratic over n points takes about 6/n of it).
"""

from __future__ import annotations

import numpy as np

from .._typing import FloatArray

__all__ = [
    "MIN_CONTROL_POINTS",
    "MIN_EXPLAINED",
    "MIN_FAILING_POINTS",
    "explained_share",
    "systematic_message",
    "systematic_pattern",
]

#: Fewest control points on which a pattern is judged.
MIN_CONTROL_POINTS = 8
#: Fewest failing control points that make a pattern.
MIN_FAILING_POINTS = 3
#: Share of the test values' sum of squares a smooth surface must explain.
MIN_EXPLAINED = 0.5


def explained_share(plan_xy: FloatArray, w: FloatArray) -> float:
    """Share (0-1) of the sum of squares of the test values ``w`` (n, 3; NaN
    where a component is not tested) that a smooth surface of the plan
    coordinates ``plan_xy`` (n, 2), fitted per component, explains."""
    n = plan_xy.shape[0]
    uv = plan_xy - plan_xy.mean(axis=0)
    uv = uv / max(float(np.max(np.abs(uv), initial=0.0)), 1e-12)
    u, v = uv[:, 0], uv[:, 1]
    columns = [np.ones(n), u, v] + ([u * u, u * v, v * v] if n >= 12 else [])
    design = np.column_stack(columns)
    total = rest = 0.0
    for comp in range(w.shape[1]):
        rows = np.isfinite(w[:, comp])
        if rows.sum() <= design.shape[1]:
            continue
        values = w[rows, comp]
        coef, *_ = np.linalg.lstsq(design[rows], values, rcond=None)
        total += float(values @ values)
        fit = values - design[rows] @ coef
        rest += float(fit @ fit)
    return 0.0 if total <= 0.0 else 1.0 - rest / total


def systematic_pattern(plan_xy: FloatArray, w: FloatArray, critical: float) -> bool:
    """True when the control's test values ``w`` (n, 3) fail in a smooth
    pattern over the plan positions ``plan_xy`` (n, 2) (module notes)."""
    if plan_xy.shape[0] < MIN_CONTROL_POINTS:
        return False
    failing = np.any(np.nan_to_num(np.abs(w)) > critical, axis=1)
    if int(failing.sum()) < MIN_FAILING_POINTS:
        return False
    return explained_share(plan_xy, w) >= MIN_EXPLAINED


def systematic_message(stage: str, n_failing: int, n_points: int, share: float) -> str:
    """The warning of a stage that keeps control failing in a smooth pattern."""
    return (
        f"{stage}: {n_failing} of {n_points} control points fail the blunder test in a smooth "
        f"pattern (a surface over the plan explains {share:.0%} of the test values): "
        "uncorrected camera errors (lens distortion, film or sensor affinity) are likely "
        "rather than bad control, so the control is kept; calibrate the camera with "
        '[adjustment] refine = "bundle" and self_calibration = "auto", or follow the '
        'bending with block = "strips" and a polynomial'
    )
