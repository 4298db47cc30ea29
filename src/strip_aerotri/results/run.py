"""The result of a whole run: every stage's result and the accuracy figures."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._typing import FloatArray
from ..observations import ControlPoints
from ..options import AdjustmentOptions
from .bundle import RefinedResult
from .common import AccuracyStatistics, Rejection
from .ground import GroundResult
from .strip import StripModel

__all__ = ["StripResult"]


@dataclass(frozen=True)
class StripResult:
    """Everything a run produced.

    Attributes
    ----------
    strip : StripModel
        The strip model in the strip system (per pair and per model figures).
    ground : GroundResult
        The strip on the ground (similarity, polynomials, points, photos).
    control : ControlPoints
    control_statistics, check_statistics : AccuracyStatistics
        At the control actually used and at the check points.
    warnings : tuple of str
        Doubtful but valid findings (control not triangulated, ...); those
        about one point are :class:`~strip_aerotri.results.PointWarning`
        (a str with the point's id and the cause as data).
    timings : dict
        Seconds per stage.
    refined : RefinedResult or None
        The bundle refinement (:mod:`strip_aerotri.bundle.refine`) when asked for;
        then ``points``, ``photo_centres`` and ``photo_opk`` are its values.
    options : AdjustmentOptions or None
        The options the run used (:func:`strip_aerotri.pipeline.triangulate`
        sets them): the route it took and ``photo_step = "auto"`` resolved to
        the step it chose.
    weak_checks : tuple of str
        The check points weakly determined by their own rays, left out of
        ``check_statistics`` (:mod:`strip_aerotri.ground.check_precision`).
    """

    strip: StripModel
    ground: GroundResult
    control: ControlPoints
    control_statistics: AccuracyStatistics
    check_statistics: AccuracyStatistics
    warnings: tuple[str, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)
    refined: RefinedResult | None = None
    options: AdjustmentOptions | None = None
    weak_checks: tuple[str, ...] = ()

    @property
    def photo_ids(self) -> tuple[str, ...]:
        return self.strip.photo_ids

    @property
    def rejections(self) -> tuple[Rejection, ...]:
        """Every observation that failed a blunder test, stage by stage."""
        return self.strip.rejections + self.ground.rejections

    @property
    def point_ids(self) -> tuple[str, ...]:
        return self.strip.observations.point_ids

    @property
    def points(self) -> FloatArray:
        """(P, 3) X, Y, H in the control CRS (NaN for points not triangulated);
        the bundle refinement's when it was run."""
        return self.ground.points if self.refined is None else self.refined.points

    @property
    def restored_points(self) -> tuple[str, ...]:
        """The points the strip method left out that the bundle refinement
        restored and determined (:mod:`strip_aerotri.bundle.start_points`),
        in point order; empty without a refinement."""
        if self.refined is None:
            return ()
        back = np.isfinite(self.refined.points).all(axis=1)
        back &= ~np.isfinite(self.ground.points).all(axis=1)
        return tuple(self.point_ids[i] for i in np.flatnonzero(back).tolist())

    @property
    def photo_centres(self) -> FloatArray:
        """(M, 3) projection centres X, Y, Z in the control CRS."""
        return self.ground.photo_centres if self.refined is None else self.refined.photo_centres

    @property
    def photo_opk(self) -> FloatArray:
        """(M, 3) omega, phi, kappa in radians (image -> local east-north-up)."""
        return self.ground.photo_opk if self.refined is None else self.refined.photo_opk

    @property
    def photo_opk_degrees(self) -> FloatArray:
        """(M, 3) omega, phi, kappa in degrees (image -> local east-north-up)."""
        return np.degrees(self.photo_opk)
