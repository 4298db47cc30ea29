"""Rigorous refinement of a strip-method result by bundle adjustment.

The strip method (partially dependent models, then similarity and
polynomials on the control) delivers every photo's exterior orientation and
every point's ground coordinates.  :func:`refine_bundle` takes them as
initial values of the simultaneous least-squares adjustment of all image
coordinates by the collinearity equations (:func:`strip_aerotri.bundle.bundle_adjust`),
with the ground control and, optionally, GNSS projection centres and IMU
attitudes as weighted observations; gross errors are searched for by data
snooping on the image, control, GNSS and IMU residuals, one rejection (or a
few well-separated image rays) at a time.

Frame
-----
The adjustment runs in a Cartesian frame in metres in which the collinearity
equations hold exactly:

* geocentric route: the ground stage's own local tangent frame
  (``result.ground.frame``, B(142)-(144), X along the strip); its
  work-frame arrays are the initial values;
* projected route with a real CRS: a local tangent frame built the same way,
  at the geocentric centroid of the control, X along the strip (the strip
  method's CRS results are converted to it through ECEF);
* ``crs = "local"``: the site system itself (X, Y, H taken as Cartesian, no
  earth curvature, as in the ground stage).

Plan-only and height-only control have no full position in the frame; their
missing components are taken from the adjusted points and the adjustment is
repeated (warm start, a pass or two) until the frame coordinates of the
control no longer change by more than 1 µm.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .._text import named
from .._threads import limit_blas_threads
from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..errors import StripAerotriWarning
from ..frames import LocalTangentFrame, TangentWorkFrame, WorkFrame, enu_residuals
from ..geometry.rotation import matrix_from_opk, opk_from_matrix, rotvec_from_matrix
from ..ground.common import index_of
from ..observations import ControlPoints, GnssCentres, ImuAttitudes
from ..options import DEFAULT_MAX_ITERATIONS, BlunderOptions, SelfCalibration
from ..results import (
    AccuracyStatistics,
    FrameRefinement,
    GnssResiduals,
    ImuResiduals,
    RefinedResult,
    Rejection,
    StripResult,
)
from ._structures import reusing_structures
from .photo_tests import _directional_tests
from .selfcal import carried_choice
from .snooping import GNSS_STAGE, IMU_STAGE, refine_frame
from .start_points import restore_points, restored_points_note
from .variance import refine_frame_weighted

__all__ = [
    "FrameRefinement",
    "GnssCentres",
    "GnssResiduals",
    "ImuAttitudes",
    "ImuResiduals",
    "RefinedResult",
    "gnss_imu_outcomes",
    "gnss_residuals",
    "imu_residuals",
    "refine_bundle",
    "refine_frame",
]

#: Passes for plan / height control in a curved frame stop below this change (m).
_PASS_TOLERANCE_M = 1e-6
_MAX_PASSES = 4


# --------------------------------------------------------------------------- frame


def _frame_for(
    result: StripResult, control_rows: IntArray, point_index: IntArray
) -> TangentWorkFrame:
    ground = result.ground
    crs = ground.crs
    if ground.frame is not None:
        return TangentWorkFrame(crs, ground.frame, "local tangent frame of the geocentric route")
    if crs.is_local:
        return TangentWorkFrame(crs, None, 'the site system of crs = "local" (X, Y, H Cartesian)')
    # Projected route with a real CRS: a tangent frame at the control centroid.
    pts = result.points[point_index[control_rows]]
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    ecef = crs.to_ecef(pts)
    frame0 = LocalTangentFrame.from_ecef_centroid(ecef, 0.0, crs=crs)
    ends = frame0.ecef2local(crs.to_ecef(result.photo_centres[[0, -1]]))
    azimuth = float(frame0.azimuth_of(ends[1] - ends[0]))
    return TangentWorkFrame(
        crs,
        frame0.with_azimuth(azimuth),
        "local tangent frame at the control centroid, X along the strip",
    )


# --------------------------------------------------------------------------- GNSS / IMU


def gnss_imu_outcomes(
    aux: _Auxiliary,
    gnss: GnssCentres | None,
    imu: ImuAttitudes | None,
    fr: FrameRefinement,
    enu2frame: FloatArray,
    opk_adjusted: FloatArray,
    photo_ids: Sequence[str],
    options: BlunderOptions,
) -> tuple[GnssResiduals | None, ImuResiduals | None]:
    """What the GNSS centres and the IMU attitudes of a refinement did
    (:func:`gnss_residuals`, :func:`imu_residuals`), None for those it did
    not have; ``aux`` from :func:`gnss_imu_in_frame`."""
    gnss_out = imu_out = None
    if aux.gnss_xyz is not None and aux.gnss_sig is not None and gnss is not None:
        gnss_out = gnss_residuals(
            gnss, aux.gnss_lookup, aux.gnss_xyz, aux.gnss_sig, fr, enu2frame, photo_ids, options
        )
    if aux.imu_rot is not None and aux.imu_sig is not None and imu is not None:
        imu_out = imu_residuals(
            imu, aux.imu_lookup, aux.imu_rot, aux.imu_sig, fr, opk_adjusted, photo_ids, options
        )
    return gnss_out, imu_out


def gnss_residuals(
    gnss: GnssCentres,
    lookup: IntArray,
    observed_frame: FloatArray,
    sigma: FloatArray,
    fr: FrameRefinement,
    enu2frame: FloatArray,
    strip_ids: Sequence[str],
    options: BlunderOptions,
) -> GnssResiduals:
    """Residuals and tests of the GNSS centres in the final adjustment.

    ``lookup`` (given rows -> strip photo or -1), ``observed_frame`` (M, 3)
    and ``sigma`` (M, 3) as passed to the bundle, ``enu2frame`` (M, 3, 3)
    at the adjusted centres.  Rejected centres (``fr.gnss_rejected``) keep
    their residual, observed minus adjusted; their redundancy and w are NaN
    (the bundle has no cofactor for them).
    """
    index = np.flatnonzero(np.all(np.isfinite(observed_frame), axis=1))
    v_frame = observed_frame[index] - fr.centres[index]  # observed - adjusted
    axes = enu2frame[index]
    weight = 1.0 / sigma[index] ** 2
    q_vv = fr.bundle.gnss_residual_cofactor[index]  # NaN for rejected centres
    redundancy, w = _directional_tests(v_frame, q_vv, weight, axes)
    rejected = fr.gnss_rejected[index] if fr.gnss_rejected.size else np.zeros(index.size, bool)
    return GnssResiduals(
        photo_ids=tuple(strip_ids[int(j)] for j in index),
        photo_index=index,
        n_given=len(gnss.photo_ids),
        unmatched=tuple(pid for pid, j in zip(gnss.photo_ids, lookup, strict=True) if j < 0),
        sigma_xy=sigma[index, 0],
        sigma_z=sigma[index, 2],
        residuals=np.einsum("gia,gi->ga", axes, v_frame),
        redundancy=redundancy,
        w=w,
        critical=options.critical(GNSS_STAGE, 3 * int(np.count_nonzero(~rejected))),
        rejected=rejected,
    )


def imu_residuals(
    imu: ImuAttitudes,
    lookup: IntArray,
    observed_frame: FloatArray,
    sigma: FloatArray,
    fr: FrameRefinement,
    opk_adjusted: FloatArray,
    strip_ids: Sequence[str],
    options: BlunderOptions,
) -> ImuResiduals:
    """Residuals and tests of the IMU attitudes in the final adjustment.

    ``lookup`` (given rows -> strip photo or -1), ``observed_frame``
    (M, 3, 3) and ``sigma`` (M, 3) as passed to the bundle;
    ``opk_adjusted`` (M, 3) the adjusted omega, phi, kappa (image -> ENU).
    Rejected attitudes as in :func:`gnss_residuals`.
    """
    m = observed_frame.shape[0]
    index = np.flatnonzero(np.all(np.isfinite(observed_frame), axis=(1, 2)))
    # log(R_adj.T R_imu): observed - adjusted, about the adjusted photo's axes
    v = rotvec_from_matrix(np.swapaxes(fr.rotations[index], 1, 2) @ observed_frame[index])
    ok = lookup >= 0
    opk_observed = np.full((m, 3), np.nan)
    opk_observed[lookup[ok]] = imu.opk[ok]
    d_opk = opk_observed[index] - opk_adjusted[index]
    d_opk = (d_opk + np.pi) % (2.0 * np.pi) - np.pi
    weight = 1.0 / sigma[index] ** 2
    axes = np.broadcast_to(np.eye(3), (index.size, 3, 3))
    q_vv = fr.bundle.imu_residual_cofactor[index]  # NaN for rejected attitudes
    redundancy, w = _directional_tests(v, q_vv, weight, axes)
    rejected = fr.imu_rejected[index] if fr.imu_rejected.size else np.zeros(index.size, bool)
    return ImuResiduals(
        photo_ids=tuple(strip_ids[int(j)] for j in index),
        photo_index=index,
        n_given=len(imu.photo_ids),
        unmatched=tuple(pid for pid, j in zip(imu.photo_ids, lookup, strict=True) if j < 0),
        sigma=sigma[index, 0],
        residuals=v,
        opk_differences=d_opk,
        redundancy=redundancy,
        w=w,
        critical=options.critical(IMU_STAGE, 3 * int(np.count_nonzero(~rejected))),
        rejected=rejected,
    )


# --------------------------------------------------------------------------- driver


def _photo_lookup(ids: Sequence[str], strip_ids: Sequence[str], what: str) -> IntArray:
    lookup = {pid: j for j, pid in enumerate(strip_ids)}
    index = np.array([lookup.get(pid, -1) for pid in ids], dtype=np.intp)
    unknown = [pid for pid, j in zip(ids, index, strict=True) if j < 0]
    if unknown:
        more = f" and {len(unknown) - 5} more" if len(unknown) > 5 else ""
        warnings.warn(
            f"{what}: photo(s) {', '.join(map(repr, unknown[:5]))}{more} are not in the strip; "
            "ignored",
            StripAerotriWarning,
            stacklevel=3,
        )
    return index


@limit_blas_threads
def refine_bundle(
    result: StripResult,
    *,
    control: ControlPoints | None = None,
    gnss: GnssCentres | None = None,
    imu: ImuAttitudes | None = None,
    blunders: BlunderOptions | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    compute_precision: bool = True,
    self_calibration: SelfCalibration | None = None,
    variance_components: bool = False,
) -> RefinedResult:
    """Refine a strip-method result by a rigorous bundle adjustment.

    Length: the documentation of its parameters and of what it returns; the
    code runs the bundle in the tangent frame and maps the result back.

    Parameters
    ----------
    result : StripResult
        From :func:`~strip_aerotri.pipeline.triangulate`; its photos and
        points are the initial values, its control the ground control
        (check points are compared, never used).
    control : ControlPoints, optional
        Control and check points (same CRS) to use instead of
        ``result.control``: e.g. fewer ground points once GNSS centres carry
        the datum; the strip result then only supplies initial values.
    gnss : GnssCentres, optional
        Observed projection centres in the control CRS.
    imu : ImuAttitudes, optional
        Observed attitudes (omega, phi, kappa, image -> local ENU).
    blunders : BlunderOptions, optional
        Data snooping of the image coordinates (stage ``"bundle"``), the
        control (stage ``"control"``), the GNSS centres (stage ``"gnss"``)
        and the IMU attitudes (stage ``"imu"``); default: test and reject.
        A rejected GNSS centre or IMU attitude leaves the adjustment as a
        whole (its three components); it stays listed in ``gnss`` / ``imu``
        with ``rejected`` True.
    max_iterations : int
        Largest number of bundle steps per adjustment.
    compute_precision : bool
        Standard deviations of points and centres and exact redundancy
        numbers of the image coordinates (the selected inverse of the normal
        matrix, about one more iteration; see
        :func:`~strip_aerotri.bundle.bundle_adjust`).
    self_calibration : SelfCalibration, optional
        Estimate the camera with the photos and points
        (:mod:`strip_aerotri.bundle.selfcal`).
    variance_components : bool
        Estimate the weights of the observation groups (image tie points,
        control points' marks, control plan and height, GNSS, IMU) from the
        residuals and adjust with them (:mod:`strip_aerotri.bundle.variance`).

    Returns
    -------
    RefinedResult

    Raises
    ------
    GeometryError
        The datum is not defined, a point or photo is not determined, or
        too many observations fail the blunder tests.
    ConvergenceError
        The adjustment diverges.

    Notes
    -----
    The frame is described in the module docstring.  Control rows enter as
    observations of their point's frame coordinates with the control's
    ``sigma_xy`` (X, Y) and ``sigma_h`` (Z); plan-only and height-only
    components are completed from the adjusted point and iterated (passes)
    in a curved frame.  Photo centres and attitudes observed by GNSS and IMU
    are converted into the frame (attitudes through east-north-up at the
    centre).  Points the strip method left out after its tie tests are
    intersected from its photos when three or more of their rays agree
    (:mod:`strip_aerotri.bundle.start_points`), so that the snooping tests
    each ray; points without agreeing rays stay out (NaN).

    Examples
    --------
    >>> from strip_aerotri.simulate import simulate_strip
    >>> from strip_aerotri.pipeline import triangulate
    >>> from strip_aerotri.options import GroundOptions
    >>> sim = simulate_strip(12, seed=1, crs="local")
    >>> strip = triangulate(sim.observations, sim.control, sim.crs,
    ...                     ground_options=GroundOptions(route="projected"))
    >>> refined = refine_bundle(strip)
    >>> bool(refined.converged), len(refined.rejections)
    (True, 0)
    >>> bool(refined.check_statistics.rmse_plan < strip.check_statistics.rmse_plan)
    True
    """
    t_start = time.perf_counter()
    obs = result.strip.observations
    control = result.control if control is None else control
    row_point = index_of(obs.point_ids, control.point_ids)
    seen = row_point >= 0
    has_point = np.zeros(len(control.point_ids), bool)
    has_point[seen] = np.all(np.isfinite(result.points[row_point[seen]]), axis=1)
    frame = _frame_for(result, np.flatnonzero(has_point), row_point)
    start = _start_values(result, frame)
    strip_points = start.points
    # points the strip method left out, intersected from its photos (start_points.py)
    restored = restore_points(obs, start.centres, start.rotations, start.points, blunders=blunders)
    start = start._replace(points=restored.points)
    has_point[seen] |= restored.restored[row_point[seen]]  # their control and checks too
    rows = np.flatnonzero(has_point)
    ctrl = _control_rows(control, rows, row_point[rows], obs.n_points)
    aux = gnss_imu_in_frame(obs.photo_ids, result.photo_centres, frame, gnss, imu)
    t_frame = time.perf_counter() - t_start

    with reusing_structures():  # the passes adjust the same rays again
        passes = _passes(
            result,
            frame,
            start,
            ctrl,
            aux,
            blunders=blunders,
            max_iterations=max_iterations,
            compute_precision=compute_precision,
            self_calibration=self_calibration,
            variance_components=variance_components,
        )
    fr, adjusted_crs, rejections, notes = (
        passes.last,
        passes.adjusted_crs,
        passes.rejections,
        passes.notes,
    )
    t_frame += passes.t_frame

    t0 = time.perf_counter()
    centres_crs = frame.from_work(fr.centres)
    enu2frame = frame.work_from_enu(centres_crs)
    rot_enu = np.swapaxes(enu2frame, 1, 2) @ fr.rotations
    opk = opk_from_matrix(rot_enu)

    # What the GNSS centres and IMU attitudes did (rejected ones included).
    rejections.extend(passes.reported)
    gnss_out, imu_out = gnss_imu_outcomes(
        aux, gnss, imu, fr, enu2frame, opk, obs.photo_ids, blunders or BlunderOptions()
    )
    res = _control_residuals(frame, ctrl, fr, adjusted_crs)
    t_frame += time.perf_counter() - t0
    keep_rows, check = res.keep_rows, ctrl.check
    if np.any(~keep_rows & ~check):
        dropped = [control.point_ids[r] for r in ctrl.rows[~keep_rows & ~check]]
        notes.append(f"control point(s) {', '.join(map(repr, dropped[:5]))} left out")
    notes += [r.describe() for r in rejections]
    notes += lost_points_note(obs.point_ids, strip_points, fr.point_used)
    notes += restored_points_note(obs.point_ids, restored.restored, fr.point_used)
    if fr.self_calibration is not None:
        notes += list(fr.self_calibration.notes)
    return RefinedResult(
        photo_ids=obs.photo_ids,
        point_ids=obs.point_ids,
        points=adjusted_crs,
        photo_centres=centres_crs,
        photo_opk=opk,
        frame=frame.frame,
        frame_description=frame.description,
        points_frame=fr.points,
        photo_centres_frame=fr.centres,
        photo_rotations_frame=fr.rotations,
        sigma0=fr.sigma0,
        redundancy=fr.redundancy,
        iterations=passes.iterations,
        converged=fr.converged,
        image_residuals_um=fr.image_residuals_mm * 1000.0,
        image_used=fr.observation_used,
        control_index=ctrl.rows[keep_rows],
        control_residuals=res.resid[keep_rows],
        is_check=check[keep_rows],
        used_xy=res.used_xy[keep_rows],
        used_h=res.used_h[keep_rows],
        control_statistics=AccuracyStatistics.from_residuals(res.used_resid[keep_rows & ~check]),
        check_statistics=AccuracyStatistics.from_residuals(res.resid[keep_rows & check]),
        point_std=fr.point_std,
        centre_std=fr.centre_std,
        rejections=tuple(rejections),
        warnings=tuple(notes),
        timings={
            "frame": t_frame,
            "bundle": passes.t_bundle,
            "total": time.perf_counter() - t_start,
        },
        n_observations=fr.bundle.n_observations,
        gnss=gnss_out,
        imu=imu_out,
        self_calibration=fr.self_calibration,
        variance_components=fr.variance_components,
    )


def lost_points_note(point_ids: Sequence[str], start: ArrayLike, used: ArrayLike) -> list[str]:
    """The warning naming the points that the refinement started from and
    did not determine (their rays rejected down to one): left out of
    points.csv.  ``start`` (P, 3) the start points, NaN where none; ``used``
    (P,) the points the refinement determined."""
    had = np.isfinite(np.asarray(start, dtype=np.float64)).all(axis=1)
    lost = np.flatnonzero(had & ~np.asarray(used, dtype=bool))
    if not lost.size:
        return []
    names = named([point_ids[i] for i in lost.tolist()])
    return [
        f"bundle: {lost.size} point(s) kept fewer than two rays after the rejections and are "
        f"no longer determined (left out of points.csv): {names}"
    ]


class _Start(NamedTuple):
    """Initial values in the frame: centres (M, 3), rotations image -> frame (M, 3, 3),
    points (P, 3; NaN where the strip method gave none)."""

    centres: FloatArray
    rotations: FloatArray
    points: FloatArray


def _start_values(result: StripResult, frame: TangentWorkFrame) -> _Start:
    """The strip method's photos and points in the refinement's frame."""
    ground = result.ground
    if ground.frame is not None or frame.frame is None:
        if ground.frame is not None:
            return _Start(
                np.array(ground.photo_centres_work),
                np.array(ground.photo_rotations_work),
                np.array(ground.points_work),
            )
        return _Start(
            np.array(result.photo_centres),
            np.array(ground.photo_rotations_enu),
            np.array(result.points),
        )
    ok = np.all(np.isfinite(result.points), axis=1)
    points0 = np.full((result.strip.observations.n_points, 3), np.nan)
    points0[ok] = frame.to_work(result.points[ok])
    centres0 = frame.to_work(result.photo_centres)
    rotations0 = frame.work_from_enu(result.photo_centres) @ ground.photo_rotations_enu
    return _Start(centres0, rotations0, points0)


class _ControlRows(NamedTuple):
    """The control rows whose point the strip method determined, as per-point arrays.

    ``rows`` index the control, ``idx`` the points; ``sig`` and ``mask``
    (P, 3) give each point's control sigmas (inf: not observed) and the
    components observed; check points are never used."""

    rows: IntArray
    idx: IntArray
    use_xy: BoolArray
    use_h: BoolArray
    check: BoolArray
    given_crs: FloatArray
    sig: FloatArray
    mask: BoolArray


def _control_rows(control: ControlPoints, rows: IntArray, idx: IntArray, p: int) -> _ControlRows:
    if np.unique(idx).size != idx.size:
        raise ValueError("a point occurs twice in the control")
    use_xy = control.uses_xy[rows]
    use_h = control.uses_h[rows]
    sig = np.full((p, 3), np.inf)
    sig[idx, 0] = sig[idx, 1] = np.where(use_xy, control.sigma_xy[rows], np.inf)
    sig[idx, 2] = np.where(use_h, control.sigma_h[rows], np.inf)
    mask = np.zeros((p, 3), bool)
    mask[idx, 0] = mask[idx, 1] = use_xy
    mask[idx, 2] = use_h
    return _ControlRows(
        rows, idx, use_xy, use_h, control.is_check[rows], control.xyz[rows], sig, mask
    )


class _Auxiliary(NamedTuple):
    """GNSS centres and IMU attitudes in the frame, one row per photo of the strip
    (NaN / inf sigma where a photo has none); the lookups map their rows to photos."""

    gnss_xyz: FloatArray | None
    gnss_sig: FloatArray | None
    gnss_lookup: IntArray
    gnss_axes: FloatArray | None
    imu_rot: FloatArray | None
    imu_sig: FloatArray | None
    imu_lookup: IntArray


def gnss_imu_in_frame(
    photo_ids: Sequence[str],
    photo_centres: FloatArray,
    frame: WorkFrame,
    gnss: GnssCentres | None,
    imu: ImuAttitudes | None,
) -> _Auxiliary:
    """GNSS centres and IMU attitudes in a work frame, one row per photo of
    ``photo_ids`` (NaN / inf sigma where a photo has none); the attitudes
    turned through east-north-up at the photos' centres ``photo_centres``
    (CRS, the current solution's)."""
    m = len(photo_ids)
    gnss_xyz = gnss_sig = imu_rot = imu_sig = None
    gnss_lookup = imu_lookup = np.zeros(0, dtype=np.intp)
    if gnss is not None:
        j = gnss_lookup = _photo_lookup(gnss.photo_ids, photo_ids, "GNSS centres")
        ok = j >= 0
        gnss_xyz = np.full((m, 3), np.nan)
        gnss_xyz[j[ok]] = frame.to_work(gnss.xyz[ok])
        gnss_sig = np.full((m, 3), np.inf)
        gnss_sig[j[ok], 0] = gnss_sig[j[ok], 1] = gnss.sigma_xy[ok]
        gnss_sig[j[ok], 2] = gnss.sigma_z[ok]
    if imu is not None:
        j = imu_lookup = _photo_lookup(imu.photo_ids, photo_ids, "IMU attitudes")
        ok = j >= 0
        imu_rot = np.full((m, 3, 3), np.nan)
        centres_for = photo_centres[j[ok]]
        imu_rot[j[ok]] = frame.work_from_enu(centres_for) @ matrix_from_opk(imu.opk[ok])
        imu_sig = np.full((m, 3), np.inf)
        imu_sig[j[ok]] = imu.sigma[ok, None]
    # GNSS test directions: east, north, up at the strip method's centres.
    gnss_axes = None if gnss is None else frame.work_from_enu(photo_centres)
    return _Auxiliary(gnss_xyz, gnss_sig, gnss_lookup, gnss_axes, imu_rot, imu_sig, imu_lookup)


class _Passes(NamedTuple):
    last: FrameRefinement
    adjusted_crs: FloatArray
    rejections: list[Rejection]
    reported: tuple[Rejection, ...]
    iterations: int
    notes: list[str]
    t_frame: float
    t_bundle: float


def _passes(
    result: StripResult,
    frame: TangentWorkFrame,
    start: _Start,
    ctrl: _ControlRows,
    aux: _Auxiliary,
    *,
    blunders: BlunderOptions | None,
    max_iterations: int,
    compute_precision: bool,
    self_calibration: SelfCalibration | None = None,
    variance_components: bool = False,
) -> _Passes:
    """Bundle adjustments in the frame until the control settles.

    A plan-only or height-only control point has its missing components
    taken from its adjusted position; in a curved frame those change the
    given components' frame coordinates, so the adjustment is repeated
    (at most :data:`_MAX_PASSES` times) until they move less than
    :data:`_PASS_TOLERANCE_M`.  Rejections of a pass stay rejected.
    """
    obs = result.strip.observations
    p = obs.n_points
    idx, given_crs = ctrl.idx, ctrl.given_crs
    t_frame = t_bundle = 0.0
    adjusted_crs = np.array(result.points)
    missing = ~np.all(np.isfinite(adjusted_crs), axis=1) & np.all(
        np.isfinite(start.points), axis=1
    )
    adjusted_crs[missing] = frame.from_work(start.points[missing])  # points restored
    state = (start.centres, start.rotations, start.points)
    obs_used: BoolArray | None = None
    ctrl_used: BoolArray | None = None
    gnss_used: BoolArray | None = None
    imu_used: BoolArray | None = None
    rejections: list[Rejection] = []
    reported: tuple[Rejection, ...] = ()
    iterations = 0
    control_frame_prev: FloatArray | None = None
    notes: list[str] = []
    spec, chosen = self_calibration, None
    control_tested = True
    for _ in range(_MAX_PASSES):
        t0 = time.perf_counter()
        filled = np.where(np.isnan(given_crs), adjusted_crs[idx], given_crs)
        control_frame = np.full((p, 3), np.nan)
        control_frame[idx] = frame.to_work(filled)
        control_xyz = np.where(ctrl.mask, control_frame, np.nan)
        t_frame += time.perf_counter() - t0
        if control_frame_prev is not None:
            change = float(np.nanmax(np.abs(control_xyz - control_frame_prev), initial=0.0))
            if change < _PASS_TOLERANCE_M:
                break
        control_frame_prev = control_xyz
        t0 = time.perf_counter()
        fr = refine_frame_weighted(
            obs,
            state[0],
            state[1],
            state[2],
            control_xyz=control_xyz,
            control_sigma=ctrl.sig,
            gnss_centres=aux.gnss_xyz,
            gnss_sigma=aux.gnss_sig,
            imu_rotations=aux.imu_rot,
            imu_sigma=aux.imu_sig,
            blunders=blunders,
            max_iterations=max_iterations,
            compute_precision=compute_precision,
            observation_used=obs_used,
            control_used=ctrl_used,
            gnss_axes=aux.gnss_axes,
            gnss_used=gnss_used,
            imu_used=imu_used,
            self_calibration=spec,
            control_tested=control_tested,
            variance_components=variance_components,
        )
        control_tested = fr.control_tested  # kept for failing alike: kept in later passes
        t_bundle += time.perf_counter() - t0
        if self_calibration is not None:
            # later passes estimate what the first kept; the outcome keeps its reasons
            fr, chosen, spec = carried_choice(self_calibration, chosen, fr)
        iterations += fr.iterations
        rejections.extend(r for r in fr.rejections if r.applied)
        # what would be rejected ("report"): as found in the last pass only
        reported = tuple(r for r in fr.rejections if not r.applied)
        # rejections of this pass stay rejected in the next
        # (a pass's record holds its own rejections: the earlier passes' stay out too)
        obs_used = ~fr.observation_rejected & (True if obs_used is None else obs_used)
        ctrl_used = ~fr.control_rejected & (True if ctrl_used is None else ctrl_used)
        gnss_used = ~fr.gnss_rejected
        imu_used = ~fr.imu_rejected
        state = (
            fr.centres,
            fr.rotations,
            np.where(fr.point_used[:, None], fr.points, start.points),
        )
        t0 = time.perf_counter()
        adjusted_crs = np.full((p, 3), np.nan)
        adjusted_crs[fr.point_used] = frame.from_work(fr.points[fr.point_used])
        t_frame += time.perf_counter() - t0
        if not frame.curved:
            break
    else:
        notes.append(
            f"plan/height control passes did not settle below {_PASS_TOLERANCE_M * 1e6:.0f} µm "
            f"in {_MAX_PASSES} passes"
        )
    return _Passes(fr, adjusted_crs, rejections, reported, iterations, notes, t_frame, t_bundle)


class _ControlResiduals(NamedTuple):
    resid: FloatArray
    used_resid: FloatArray
    used_xy: BoolArray
    used_h: BoolArray
    keep_rows: BoolArray


def _control_residuals(
    frame: TangentWorkFrame, ctrl: _ControlRows, fr: FrameRefinement, adjusted_crs: FloatArray
) -> _ControlResiduals:
    """Given minus adjusted along E, N, H at the control rows (NaN for components
    not given or not used; check points compared in full), and those of the
    control used in the end."""
    idx, given_crs, check = ctrl.idx, ctrl.given_crs, ctrl.check
    adj_rows = adjusted_crs[idx]
    filled = np.where(np.isnan(given_crs), adj_rows, given_crs)
    resid = enu_residuals(frame.crs, filled, adj_rows)
    used_xy = ctrl.use_xy & fr.control_used[idx, 0] & fr.point_used[idx]
    used_h = ctrl.use_h & fr.control_used[idx, 2] & fr.point_used[idx]
    resid[~(ctrl.use_xy | check), :2] = np.nan
    resid[~(ctrl.use_h | check), 2] = np.nan
    resid[np.isnan(given_crs)] = np.nan
    used_resid = resid.copy()
    used_resid[~used_xy, :2] = np.nan
    used_resid[~used_h, 2] = np.nan
    return _ControlResiduals(resid, used_resid, used_xy, used_h, fr.point_used[idx])
