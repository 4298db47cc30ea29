"""The result of a block of strips."""

from __future__ import annotations

from dataclasses import dataclass, field

from .._typing import BoolArray, FloatArray, IntArray
from ..observations import ControlPoints, ImageObservations, StripSpec
from ..options import AdjustmentOptions
from .bundle import GnssResiduals, ImuResiduals, SelfCalibrationOutcome, VarianceComponents
from .common import AccuracyStatistics, Rejection
from .strip import StripModel

__all__ = ["BlockResult", "StripJoin"]


@dataclass(frozen=True)
class StripJoin:
    """Two strips of a block on the points they share (R4 1.7.7.3, 1.7.7.7).

    The points are transformed to the ground by each strip's own similarity
    and compared: the differences show how well the strips fit together.

    Attributes
    ----------
    strips : (int, int)
        The two strips, indices into ``BlockResult.strips``.
    n_points : int
        Points determined in both.
    mean_plan_m, max_plan_m : float
        Mean and largest plan discrepancy, metres.
    mean_height_m, max_height_m : float
        Mean and largest absolute height discrepancy, metres.
    mean_transfer_um, max_transfer_um : float
        Mean and largest plan discrepancy of the same points in the *free*
        block (transformed onto each other, the control holding the datum
        only), in micrometres at the photo scale: the transfer error of the
        common points from strip to strip (R4 1.7.7.3: at most 40 um on
        average with digital identification, 60 um otherwise).  NaN where
        not computed.
    """

    strips: tuple[int, int]
    n_points: int
    mean_plan_m: float
    max_plan_m: float
    mean_height_m: float
    max_height_m: float
    mean_transfer_um: float = float("nan")
    max_transfer_um: float = float("nan")


@dataclass(frozen=True)
class BlockResult:
    """A block of strips transformed at once onto the control.

    Points and photos are in the control CRS (X, Y as given, H ellipsoidal)
    in ``observations.point_ids`` / ``observations.photo_ids`` order; each
    strip keeps its own strip model.

    Attributes
    ----------
    specs : tuple of StripSpec
        The strips as the project names them.
    strips : tuple of StripModel
        Each strip formed on its own (its own strip system).
    observations : ImageObservations
        Every photo of the block.
    photo_strip : ndarray of int, shape (M,)
        The strip of each photo.
    scale : ndarray, shape (S,)
        Each strip's similarity scale (metres per strip unit).
    points : ndarray, shape (P, 3)
        X, Y, H in the control CRS (NaN where no strip triangulated the point).
    photo_centres : ndarray, shape (M, 3)
    photo_opk : ndarray, shape (M, 3)
        omega, phi, kappa in radians of ``R = Rx Ry Rz``, image -> local
        east-north-up at the centre (image -> X, Y, H for ``"local"``).
    control : ControlPoints
    control_index : ndarray of int, shape (C,)
        Rows of ``control`` whose point the block determined.
    control_residuals : ndarray, shape (C, 3)
        Given minus adjusted, E, N, H metres (NaN for components not given
        or, except at check points, not used).
    is_check, used_xy, used_h : ndarray of bool, shape (C,)
    control_statistics, check_statistics : AccuracyStatistics
    joins : tuple of StripJoin
        Every pair of strips that share points.
    sigma0 : float
        A posteriori sigma of unit weight of the transformation.
    redundancy, iterations : int
    rejections : tuple of Rejection
    warnings : tuple of str
        Doubtful but valid findings; those about one point are
        :class:`~strip_aerotri.results.PointWarning`.
    timings : dict
        Seconds per stage.
    refined : bool
        The points, photos and control residuals are those of the bundle
        refinement of the whole block (``refine = "bundle"``); the joins
        stay the block transformation's.
    refined_sigma0 : float
        A posteriori sigma of unit weight of the refinement (NaN without).
    gnss, imu : GnssResiduals, ImuResiduals or None
        The refinement's GNSS centres and IMU attitudes: residuals and tests
        (None without them).
    self_calibration : SelfCalibrationOutcome or None
        The refinement's self-calibrated camera (None without).
    polynomial : int
        J(16)'s type of every strip's own deformation polynomial (block of
        independent strips), 0 for none.
    control_fit_statistics : AccuracyStatistics or None
        Given minus the mean of the units' own determinations at the control
        used: how well the strips (or models) themselves meet the control,
        where ``control_statistics`` compares with the adjusted points,
        which lean on the control too.
    polynomial_terms : tuple of int
        The polynomial terms each strip kept (those the control and the
        common points determine); empty without a polynomial.
    block_check_statistics : AccuracyStatistics or None
        After a bundle refinement: the check points of the block's own
        transformation, for comparison, without the weakly determined ones
        as ``check_statistics`` (None without a refinement).
    block_control_residuals : ndarray, shape (N, 3), or None
        After a bundle refinement: the block transformation's own
        ``control_residuals`` (the same rows), metres east, north, up (None
        without a refinement).
    options : AdjustmentOptions or None
        The options the block ran with
        (:func:`strip_aerotri.pipeline.triangulate_block` sets them).
    weak_checks : tuple of str
        The check points weakly determined by their own rays, left out of
        ``check_statistics`` (:mod:`strip_aerotri.ground.check_precision`).
    variance_components : VarianceComponents or None
        The refinement's observation weights estimated from its residuals
        (None unless asked for).
    restored_points : tuple of str
        The points the block left out that the bundle refinement restored
        and determined (:mod:`strip_aerotri.bundle.start_points`), in point
        order; empty without a refinement.
    """

    specs: tuple[StripSpec, ...]
    strips: tuple[StripModel, ...]
    observations: ImageObservations
    photo_strip: IntArray
    scale: FloatArray
    points: FloatArray
    photo_centres: FloatArray
    photo_opk: FloatArray
    control: ControlPoints
    control_index: IntArray
    control_residuals: FloatArray
    is_check: BoolArray
    used_xy: BoolArray
    used_h: BoolArray
    control_statistics: AccuracyStatistics
    check_statistics: AccuracyStatistics
    joins: tuple[StripJoin, ...]
    sigma0: float
    redundancy: int
    iterations: int
    rejections: tuple[Rejection, ...] = ()
    warnings: tuple[str, ...] = ()
    timings: dict[str, float] = field(default_factory=dict)
    refined: bool = False
    refined_sigma0: float = float("nan")
    polynomial: int = 0
    polynomial_terms: tuple[int, ...] = ()
    control_fit_statistics: AccuracyStatistics | None = None
    block_check_statistics: AccuracyStatistics | None = None
    block_control_residuals: FloatArray | None = None
    gnss: GnssResiduals | None = None
    imu: ImuResiduals | None = None
    self_calibration: SelfCalibrationOutcome | None = None
    options: AdjustmentOptions | None = None
    weak_checks: tuple[str, ...] = ()
    variance_components: VarianceComponents | None = None
    restored_points: tuple[str, ...] = ()

    @property
    def photo_ids(self) -> tuple[str, ...]:
        return self.observations.photo_ids

    @property
    def point_ids(self) -> tuple[str, ...]:
        return self.observations.point_ids
