"""Check points that their own rays fix too loosely to check anything.

A check point's discrepancy (given minus adjusted) is the adjustment's error
there plus the error of the point's own determination from its rays.  When
its rays meet at a small angle the second part dominates: on the real FC300X
block, check point '14' is seen on two consecutive photos 5.3 m apart at
50-55 m (its rays meet at 2.5°), and with the photos held its two rays fix
it to 0.2-0.5 m along them where every other check point is fixed to
millimetres; the rigorous bundle gives it standard deviations of 0.11 /
0.21 / 0.10 m (E / N / H) with the photos' own uncertainty.  Its
discrepancy, 0.13 m in plan from the bundle and 0.01 m from the strip
constructions, then says nothing about which is better, and as one of 15 it
decided their comparison.

The rule (in the spirit of the ASPRS accuracy standard's: a check must be
at least three times more accurate than what it checks): with the standard
deviation of a check point's forward intersection from its own rays
(:mod:`strip_aerotri.geometry.intersection_precision`; the photos as
adjusted, the image coordinates' a priori sigma), the point is *weakly
determined* when, in plan or in height, that sigma exceeds
:data:`WEAK_CHECK_FACTOR` times its control sigma (it cannot check at the
level the control states) and :data:`WEAK_CHECK_FACTOR` times the median of
the check points' own (it is an outlier of the geometry, so a design whose
check points are all alike is never emptied), or when its rays do not fix
it at all.  The rule looks at the geometry only, never at the discrepancy.
Such points stay in the outputs with their discrepancies; the check
statistics leave them out and a warning names them.

On the FC300X block point 14 is 42 (plan) and 23 (height) times the median
check point and point 78 13 times in height; the next, 17, 3.3 times in plan
but within 3 times its control sigma.  On the simulated examples (film strip,
drone corridor) no check point is beyond 1.9 times the median.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..frames import TangentWorkFrame
from ..geodesy import GroundCRS
from ..geometry.intersection_precision import intersection_angles, intersection_covariances
from ..geometry.rotation import matrix_from_opk
from ..observations import ControlPoints, ImageObservations
from ..results import AccuracyStatistics

__all__ = [
    "WEAK_CHECK_FACTOR",
    "Adjusted",
    "CheckPrecision",
    "WeakCheck",
    "check_point_precision",
    "check_statistics_without",
    "strong_checks",
    "weak_check_message",
    "weak_check_points",
    "weak_checks_of",
]

#: A check point whose own intersection's sigma exceeds this many times its
#: control sigma and the check points' median (plan or height) is weakly
#: determined.
WEAK_CHECK_FACTOR = 3.0


@dataclass(frozen=True)
class WeakCheck:
    """A weakly determined check point: its rays, their largest angle
    (degrees), and its intersection's sigmas in plan and height (m) against
    its control sigmas (m)."""

    point: str
    n_rays: int
    angle_deg: float
    sigma_plan_m: float
    sigma_height_m: float
    control_sigma_xy_m: float
    control_sigma_h_m: float


class CheckPrecision(NamedTuple):
    """How well their own rays fix check points: the rows of the control,
    their rays, the rays' largest angle (degrees) and the intersection's
    sigmas in plan and height (m; NaN where the rays do not fix the point)."""

    rows: IntArray
    n_rays: IntArray
    angle_deg: FloatArray
    sigma_plan_m: FloatArray
    sigma_height_m: FloatArray


def check_point_precision(
    observations: ImageObservations,
    control: ControlPoints,
    crs: GroundCRS,
    check_rows: IntArray,
    points: FloatArray,
    photo_centres: FloatArray,
    photo_opk: FloatArray,
) -> CheckPrecision:
    """The forward intersection's precision of the check points among
    ``check_rows`` that the result determines (module notes).

    Parameters
    ----------
    observations : ImageObservations
        The image observations of the result (points and photos indexed as
        ``points`` and ``photo_centres``).
    control : ControlPoints
    crs : GroundCRS
    check_rows : ndarray of int
        Rows of ``control`` that are check points.
    points : ndarray, shape (P, 3)
        Adjusted points in the CRS (NaN where not determined).
    photo_centres, photo_opk : ndarray, shape (M, 3)
        Adjusted centres in the CRS and omega, phi, kappa (radians, image ->
        east-north-up at each centre).

    Notes
    -----
    The rays are intersected in the site system (``crs = "local"``) or in a
    tangent frame at the check points' centroid, Z along its normal: plan
    and height are those of that frame.
    """
    ids = np.asarray(observations.point_ids, dtype=object)
    sorter = np.argsort(ids)
    rows = np.asarray(check_rows, dtype=np.intp)
    names = np.asarray(control.point_ids, dtype=object)[rows]
    at = np.clip(np.searchsorted(ids, names, sorter=sorter), 0, max(ids.size - 1, 0))
    seen = ids.size > 0 and ids[sorter[at]] == names
    rows, index = rows[seen], sorter[at][seen]
    if rows.size:
        given = np.all(np.isfinite(points[index]), axis=1)
        rows, index = rows[given], index[given]
    if rows.size == 0:
        empty = np.zeros(0)
        return CheckPrecision(rows, np.zeros(0, dtype=np.intp), empty, empty, empty)
    if crs.is_local:
        frame = TangentWorkFrame(crs, None)
    else:
        frame = TangentWorkFrame.at_control(crs, points[index], 0.0)
    compact = np.full(observations.n_points, -1, dtype=np.intp)
    compact[index] = np.arange(index.size)
    sel = np.flatnonzero(compact[observations.point] >= 0)
    photo, point = observations.photo[sel], compact[observations.point[sel]]
    centres = frame.to_work(photo_centres)
    rotations = frame.work_from_enu(photo_centres) @ matrix_from_opk(photo_opk)
    pts = frame.to_work(points[index])
    cov = intersection_covariances(
        centres, rotations, pts, photo, point, observations.principal_distance,
        observations.sigma[sel],
    )  # fmt: skip
    return CheckPrecision(
        rows,
        np.bincount(point, minlength=index.size),
        intersection_angles(centres, pts, photo, point),
        np.sqrt(cov[:, 0, 0] + cov[:, 1, 1]),
        np.sqrt(cov[:, 2, 2]),
    )


def weak_check_points(
    observations: ImageObservations,
    control: ControlPoints,
    crs: GroundCRS,
    check_rows: IntArray,
    points: FloatArray,
    photo_centres: FloatArray,
    photo_opk: FloatArray,
) -> tuple[WeakCheck, ...]:
    """The weakly determined check points among ``check_rows`` (module notes;
    arguments as :func:`check_point_precision`)."""
    prec = check_point_precision(
        observations, control, crs, check_rows, points, photo_centres, photo_opk
    )
    rows = prec.rows
    sxy, sh = control.sigma_xy[rows], control.sigma_h[rows]
    weak = _beyond(prec.sigma_plan_m, sxy) | _beyond(prec.sigma_height_m, sh)
    return tuple(
        WeakCheck(
            control.point_ids[rows[i]],
            int(prec.n_rays[i]),
            float(prec.angle_deg[i]),
            float(prec.sigma_plan_m[i]),
            float(prec.sigma_height_m[i]),
            float(sxy[i]),
            float(sh[i]),
        )
        for i in np.flatnonzero(weak)
    )


def _beyond(sigma: FloatArray, control_sigma: FloatArray) -> BoolArray:
    """Weak by one component: beyond both bounds of the module notes, or not
    determined by the rays at all (NaN: one ray, parallel rays)."""
    finite = np.isfinite(sigma)
    typical = float(np.median(sigma[finite])) if finite.any() else np.inf
    with np.errstate(invalid="ignore"):
        beyond = (sigma > WEAK_CHECK_FACTOR * control_sigma) & (
            sigma > WEAK_CHECK_FACTOR * typical
        )
    out: BoolArray = beyond | ~finite
    return out


class Adjusted(Protocol):
    """What a strip's ground stage, its bundle refinement and a block result
    share: the control rows' residuals and the adjusted points and photos."""

    @property
    def control_index(self) -> IntArray: ...
    @property
    def is_check(self) -> BoolArray: ...
    @property
    def control_residuals(self) -> FloatArray: ...
    @property
    def points(self) -> FloatArray: ...
    @property
    def photo_centres(self) -> FloatArray: ...
    @property
    def photo_opk(self) -> FloatArray: ...


def weak_checks_of(
    observations: ImageObservations,
    control: ControlPoints,
    crs: GroundCRS,
    rows: Adjusted,
    final: Adjusted,
) -> tuple[WeakCheck, ...]:
    """:func:`weak_check_points` of the check rows of ``rows`` with the
    points and photos of ``final``."""
    return weak_check_points(
        observations,
        control,
        crs,
        rows.control_index[rows.is_check],
        final.points,
        final.photo_centres,
        final.photo_opk,
    )


def check_statistics_without(
    adjusted: Adjusted, control: ControlPoints, weak: tuple[WeakCheck, ...]
) -> AccuracyStatistics:
    """The check statistics of ``adjusted``'s residuals (its rows of
    ``control``) without the weak points."""
    keep = strong_checks(adjusted, control, [w.point for w in weak])
    return AccuracyStatistics.from_residuals(np.asarray(adjusted.control_residuals)[keep])


def strong_checks(adjusted: Adjusted, control: ControlPoints, weak: Sequence[str]) -> BoolArray:
    """The rows of ``adjusted`` (its rows of ``control``) that are check
    points, and not among the weakly determined ``weak`` (point ids)."""
    index = np.asarray(adjusted.control_index, dtype=np.intp)
    names = np.array(control.point_ids, dtype=object)[index]
    return np.asarray(adjusted.is_check, dtype=bool) & ~np.isin(names, list(weak))


def weak_check_message(weak: WeakCheck) -> str:
    """The warning naming a weakly determined check point and why."""
    return (
        f"check point {weak.point!r} is weakly determined: its {weak.n_rays} ray(s) meet at "
        f"{weak.angle_deg:.1f} deg and fix it to {weak.sigma_plan_m:.3f} m in plan and "
        f"{weak.sigma_height_m:.3f} m in height at the image sigma (more than "
        f"{WEAK_CHECK_FACTOR:g} times its control sigma of {weak.control_sigma_xy_m:g} / "
        f"{weak.control_sigma_h_m:g} m and than the other check points' own), so its "
        "discrepancy measures its own intersection more than the adjustment: it is listed "
        "with the check points but left out of their statistics (measure it on more photos, "
        "farther apart)"
    )
