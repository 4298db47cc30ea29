"""Systematic errors are not blunders: control that fails at many points alike.

Uncorrected camera errors (lens distortion, film affinity) deform a strip or a
block everywhere; the control then fails the blunder tests at many points at
once, at similar test values, while a bad control point fails alone, or
drags a few neighbours over the limit at test values well below its own.
When more than ``max_fraction`` of the control fails, :func:`fails_alike`
tells the two apart (:func:`systematic_pattern`) on the first solution's test
values and on every test value met so far, and the stages (the construction
by models, by strips with polynomials, the block and the bundle) keep the
control and warn (:func:`systematic_message`) instead of stopping.  The test
values met so far matter: a bending the control follows fails a few points
at a time, a little over the critical value, and rejecting them one by one
makes the next ones fail, which the first solution alone does not show.

The rule: at least :data:`MIN_CONTROL_POINTS` control points; at least
:data:`MIN_FAILING_POINTS` of them, and at least :data:`MIN_FAILING_SHARE` of
them, failing; and no point dominating: the largest test value is at most
:data:`MAX_DOMINANCE` times the median of the failing points' largest values.

(A smooth surface over the plan does not tell them apart: in the construction
by models every model follows the control on its own, and a camera error leaves
a pattern that changes sign from model to model.)
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import replace

import numpy as np

from .._typing import FloatArray
from ..errors import StripAerotriWarning
from ..results import Rejection

__all__ = [
    "KEPT_EFFECT",
    "MAX_DOMINANCE",
    "MIN_CONTROL_POINTS",
    "MIN_FAILING_POINTS",
    "MIN_FAILING_SHARE",
    "kept_control",
    "kept_if_alike",
    "rejected_components",
    "fails_alike",
    "self_calibration_follows",
    "systematic_message",
    "systematic_pattern",
]

#: Fewest control points on which a pattern is judged (three failing alike
#: among four or five are no more likely blunders than bending: a weakly
#: controlled drone strip with 26 µm of camera error fails 4 of its 5 points
#: at |w| 12-43).
MIN_CONTROL_POINTS = 4
#: Fewest failing control points that make a pattern.
MIN_FAILING_POINTS = 3
#: Smallest share of the control points failing that makes a pattern.
MIN_FAILING_SHARE = 0.2
#: Largest ratio of the worst test value to the failing points' median.
MAX_DOMINANCE = 3.0


def systematic_pattern(w: FloatArray, critical: float) -> bool:
    """True when the control's test values ``w`` (n points, components; NaN
    where not tested) fail at many points alike (module notes)."""
    n = w.shape[0]
    worst = np.max(np.nan_to_num(np.abs(w)), axis=1, initial=0.0)
    failing = worst[worst > critical]
    if n < MIN_CONTROL_POINTS or failing.size < max(MIN_FAILING_POINTS, MIN_FAILING_SHARE * n):
        return False
    return bool(failing.max() <= MAX_DOMINANCE * float(np.median(failing)))


def fails_alike(
    first: FloatArray,
    critical: float,
    *,
    last: FloatArray | None = None,
    rejected: Sequence[tuple[int, int, float]] = (),
) -> FloatArray | None:
    """The stages' one judgement of control that fails beyond ``max_fraction``:
    the test values on which it fails at many points alike, or None (blunders).

    Parameters
    ----------
    first : ndarray, shape (n, 3)
        The first solution's test values of the n control points (components;
        NaN where not tested).
    critical : float
        The critical value they are judged against.
    last : ndarray, shape (n, 3), optional
        The last solution's, on the same rows (NaN where not tested, rejected
        components included).
    rejected : sequence of (row, column, w)
        The components rejected so far, each at the test value it was rejected
        with (row of ``first``, column 0-2).

    Returns
    -------
    ndarray or None
        ``first`` when its pattern is systematic; else every test value met so
        far (``last`` with each rejected component at its rejection's value)
        when that pattern is; else None.
    """
    if systematic_pattern(first, critical):
        return first
    if last is None:
        return None
    seen = np.abs(np.asarray(last, dtype=np.float64))
    for row, column, w in rejected:
        seen[row, column] = abs(w)
    return seen if systematic_pattern(seen, critical) else None


def kept_if_alike(
    stage: str,
    first: FloatArray,
    critical: float,
    *,
    last: FloatArray | None = None,
    rejected: Sequence[tuple[int, int, float]] = (),
    self_calibrating: bool = False,
) -> bool:
    """:func:`fails_alike`, and when it does, the stage's warning
    (:func:`systematic_message`, attributed to the stage's caller): True when
    the stage keeps its control."""
    judged = fails_alike(first, critical, last=last, rejected=rejected)
    if judged is None:
        return False
    warnings.warn(
        systematic_message(stage, judged, critical, self_calibrating=self_calibrating),
        StripAerotriWarning,
        stacklevel=5,
    )
    return True


def rejected_components(
    rejections: Sequence[Rejection], row_of: Mapping[str, int]
) -> list[tuple[int, int, float]]:
    """The control components rejected so far as :func:`fails_alike` takes
    them: (row, column, w) of every applied control rejection whose point has
    a row in ``row_of`` (a height's column 2, a plan's 0)."""
    return [
        (row_of[r.point], 2 if r.component in ("height", "H") else 0, r.w)
        for r in rejections
        if r.stage == "control" and r.applied and r.point in row_of
    ]


#: True while a stage runs whose result the bundle refinement then
#: self-calibrates (:func:`self_calibration_follows`): the remedy it names is
#: already under way.
_SELF_CALIBRATION_FOLLOWS: ContextVar[bool] = ContextVar("self_calibration_follows", default=False)


@contextmanager
def self_calibration_follows(follows: bool = True) -> Iterator[None]:
    """Within: the stages' warnings know that a self-calibrating bundle follows."""
    token = _SELF_CALIBRATION_FOLLOWS.set(follows)
    try:
        yield
    finally:
        _SELF_CALIBRATION_FOLLOWS.reset(token)


def systematic_message(
    stage: str, w: FloatArray, critical: float, *, self_calibrating: bool = False
) -> str:
    """The warning of a stage that keeps control failing at many points alike.

    The remedy named depends on what the run already does: ``self_calibrating``
    (the stage is a self-calibrating bundle) or a self-calibrating bundle
    following the stage (:func:`self_calibration_follows`) do not suggest
    self-calibration again.
    """
    worst = np.max(np.nan_to_num(np.abs(w)), axis=1, initial=0.0)
    failing = worst[worst > critical]
    head = (
        f"{stage}: {failing.size} of {w.shape[0]} control points fail the blunder test alike "
        f"(|w| {failing.min():.1f} to {failing.max():.1f}, critical {critical:.2f}): "
    )
    if self_calibrating:
        return head + (
            "the camera is self-calibrated, so camera errors beyond its parameters (another "
            'set: self_calibration = "ebner12" for film, or a list) or image coordinates '
            "noisier than their sigma are likely rather than bad control, so the control is "
            'kept; or follow the bending with block = "strips" and a polynomial'
        )
    if _SELF_CALIBRATION_FOLLOWS.get():
        return head + (
            "uncorrected camera errors (lens distortion, film or sensor affinity), or image "
            "coordinates noisier than their sigma, are likely rather than bad control, so the "
            "control is kept; the bundle refinement's self-calibration estimates the camera "
            "from these photos next"
        )
    return head + (
        "uncorrected camera errors (lens distortion, film or sensor affinity), or image "
        "coordinates noisier than their sigma, are likely rather than bad control, so the "
        "control is kept; calibrate the camera with "
        '[adjustment] refine = "bundle" and self_calibration = "auto", or follow the '
        'bending with block = "strips" and a polynomial'
    )


#: The effect written on a control rejection undone by :func:`kept_control`.
KEPT_EFFECT = "kept: the control fails at many points alike"


def kept_control(rejections: Sequence[Rejection]) -> list[Rejection]:
    """The rejections with those of the control turned into kept ones."""
    return [
        replace(r, applied=False, effect=KEPT_EFFECT) if r.stage == "control" else r
        for r in rejections
    ]
