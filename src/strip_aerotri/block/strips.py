"""A block by independent strips (R4 3, ``block = "strips"``).

Every strip is formed as a strip of its own (dependent or independent
models, :mod:`strip_aerotri.strip`), in its own strip system.  Then all
strips are transformed at once, each by its own 3D similarity, onto the
control and onto each other on the points they share in their side overlap
(:func:`strip_aerotri.geometry.simultaneous.adjust_units`, the strips as its
units), in one least-squares adjustment in the ground stage's work frame.  A
strip with too little control of its own is carried by its neighbours: that
is what a block is for (R4: its field control can be sparser than a
strip's).

Each strip's points (and projection centres) enter with the precision the
strip shows: the RMS of its tie points' double determinations in plan and in
height, times the strip's scale.  Control enters with its own sigmas and is
tested by Baarda's w (the worst failing component rejected at a time, never
one the control cannot spare).  The strips' discrepancies on their common
points (R4 1.7.7.3 and 1.7.7.7) are the block's accuracy criteria.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..errors import FlightAxisError, GeometryError, PhotoOrderError
from ..geodesy import GroundCRS
from ..geometry.rotation import opk_from_matrix
from ..geometry.simultaneous import UnitObservations, UnitTransforms, adjust_units
from ..observations import (
    ControlPoints,
    GnssCentres,
    ImageObservations,
    ImuAttitudes,
    StripSpec,
)
from ..options import (
    DEFAULT_BLOCK_POLYNOMIAL,
    DEFAULT_MAX_ITERATIONS,
    BlunderOptions,
    Construction,
    Route,
    SelfCalibration,
    StripOptions,
)
from ..results import (
    AccuracyStatistics,
    BlockResult,
    PointWarning,
    Rejection,
    StripJoin,
    StripModel,
)
from ..strip.densify import form_strip_stepped
from .problem import _prepare, _Problem, control_rows
from .snooping import _band_order, _determined_terms, _snoop, _Solution

__all__ = ["adjust_block", "strip_observations"]


def strip_observations(
    observations: ImageObservations, photo_ids: Sequence[str]
) -> ImageObservations:
    """The observations of one strip's photos (in that strip's order), with the
    block's point ids kept so that a point index means one point block-wide."""
    lookup = {pid: i for i, pid in enumerate(observations.photo_ids)}
    index = np.array([lookup[p] for p in photo_ids], dtype=np.intp)
    position = np.full(len(observations.photo_ids), -1, dtype=np.intp)
    position[index] = np.arange(index.size)
    rows = np.flatnonzero(position[observations.photo] >= 0)
    photo = position[observations.photo[rows]]
    order = np.lexsort((observations.point[rows], photo))
    rows = rows[order]
    return ImageObservations(
        photo_ids=tuple(photo_ids),
        point_ids=observations.point_ids,
        photo=photo[order],
        point=observations.point[rows],
        xy=observations.xy[rows],
        sigma=observations.sigma[rows],
        principal_distance=observations.principal_distance,
        source_line=(
            observations.source_line[rows]
            if observations.source_line.shape[0] == observations.photo.shape[0]
            else np.zeros(0, dtype=np.intp)
        ),
    )


def adjust_block(
    observations: ImageObservations,
    control: ControlPoints,
    crs: GroundCRS | str,
    strips: Sequence[StripSpec],
    *,
    strip_options: StripOptions | None = None,
    construction: Construction | str = Construction.MODELS,
    route: Route | str | None = None,
    blunders: BlunderOptions | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    refine: bool = False,
    gnss: GnssCentres | None = None,
    imu: ImuAttitudes | None = None,
    polynomial: int | None = None,
    self_calibration: SelfCalibration | None = None,
    variance_components: bool = False,
    control_name: str = "control",
) -> BlockResult:
    """Form every strip, then transform all strips at once to the control.

    Parameters
    ----------
    observations : ImageObservations
        Every photo of the block (a point id is one point block-wide).
    control : ControlPoints
        In ``crs``; check points are compared, never used.
    crs : GroundCRS or str
    strips : sequence of StripSpec
        At least two; a photo in one strip only.
    strip_options : StripOptions, optional
        How each strip is formed.
    construction : Construction
        ``"strips"`` (R4 3: every strip its own 3D similarity) or
        ``"models"`` (every model of every strip its own, PAT-M; the default).
    route : Route, optional
        The work frame (default geocentric, projected for ``"local"``).
    blunders : BlunderOptions, optional
    refine : bool
        Refine the block's solution by a rigorous bundle adjustment of every
        photo and point in the work frame (control as weighted observations,
        with data snooping); the joins stay those of the block's
        transformation.
    gnss, imu : GnssCentres, ImuAttitudes, optional
        Observed projection centres and attitudes of the refinement (with
        ``refine`` only).
    polynomial : int, optional
        With ``"strips"``: J(16)'s type (1, 2, 3) of every strip's own
        deformation polynomial, adjusted with its similarity
        (:class:`~strip_aerotri.geometry.simultaneous.UnitPolynomial`); 0
        for similarities only; default
        :data:`~strip_aerotri.options.DEFAULT_BLOCK_POLYNOMIAL` (2).  Not
        used with ``"models"``.
    self_calibration : SelfCalibration, optional
        The refinement calibrates the camera (:mod:`strip_aerotri.bundle.selfcal`).
    variance_components : bool
        The refinement estimates its observation groups' weights
        (:mod:`strip_aerotri.bundle.variance`).
    control_name : str
        The control in messages (its file, for one).

    Raises
    ------
    GeometryError
        A strip that shares fewer than three points with the rest of the
        block and has too little control of its own; too little control for
        the block; a strip that cannot be formed.
    HeightUnitError
        The control heights in another unit than its plan
        (:mod:`strip_aerotri.ground.height_units`), the message naming the
        control ``control_name``.
    """
    t0 = time.perf_counter()
    if not isinstance(crs, GroundCRS):
        crs = GroundCRS.from_user_input(crs)
    blunders = blunders or BlunderOptions()
    route = (
        Route.create(route)
        if route is not None
        else (Route.PROJECTED if crs.is_local else Route.GEOCENTRIC)
    )
    formed = tuple(_form(observations, spec, strip_options, blunders) for spec in strips)
    t_strips = time.perf_counter() - t0
    problem = _prepare(
        observations,
        control,
        crs,
        tuple(strips),
        formed,
        route,
        Construction.create(construction),
        max_iterations,
        DEFAULT_BLOCK_POLYNOMIAL if polynomial is None else polynomial,
        control_name=control_name,
    )
    problem, dropped = _determined_terms(problem)
    solution, used_xy, used_z, keep_rows, rejections = _snoop(problem, blunders)
    result = _products(problem, solution, used_xy, used_z, keep_rows, rejections)
    result = replace(
        result, warnings=_formation_notes(problem, result) + tuple(dropped) + result.warnings
    )
    timings = {"strips": t_strips, "block": time.perf_counter() - t0 - t_strips}
    if refine:
        t1 = time.perf_counter()
        result = _refine(
            problem,
            solution,
            result,
            blunders,
            max_iterations,
            gnss,
            imu,
            self_calibration,
            variance_components,
        )
        timings["bundle"] = time.perf_counter() - t1
    return _with_timings(result, timings)


def _form(
    observations: ImageObservations,
    spec: StripSpec,
    options: StripOptions | None,
    blunders: BlunderOptions,
) -> StripModel:
    sub = strip_observations(observations, spec.photo_ids)
    try:
        return form_strip_stepped(sub, options, blunders=blunders)
    except PhotoOrderError as exc:
        raise PhotoOrderError(
            f"strip '{spec.name}': {exc}",
            n_wrong=exc.n_wrong,
            n_pairs=exc.n_pairs,
            strip=spec.name,
        ) from None
    except FlightAxisError as exc:
        raise FlightAxisError(
            f"strip '{spec.name}': {exc}", pair=exc.pair, along=exc.along, strip=spec.name
        ) from None
    except GeometryError as exc:
        raise GeometryError(f"strip '{spec.name}': {exc}") from None


def _strip_sums(
    p: _Problem, t: UnitTransforms, keep_rows: BoolArray
) -> tuple[FloatArray, IntArray]:
    """Per strip and point, the sum of its units' transformed determinations
    (S, P, 3, work frame) and their count (S, P)."""
    n_points = p.observations.n_points
    r = p.rows
    is_point = (r.point < n_points) & keep_rows
    placed = t.apply(r.unit[is_point], r.xyz[is_point])
    n_strips = len(p.strips)
    key = p.unit_strip[r.unit[is_point]] * n_points + r.point[is_point]
    counts = np.bincount(key, minlength=n_strips * n_points).reshape(n_strips, n_points)
    sums: FloatArray = np.stack(
        [np.bincount(key, placed[:, c], minlength=n_strips * n_points) for c in range(3)],
        axis=-1,
    ).reshape(n_strips, n_points, 3)  # type: ignore[assignment]  # weighted: float64
    return sums, counts


def _unit_means(p: _Problem, t: UnitTransforms, keep_rows: BoolArray) -> FloatArray:
    """Every point's mean over the units' determinations of it, work frame
    (P, 3; NaN for points no kept row determines)."""
    sums, counts = _strip_sums(p, t, keep_rows)
    with np.errstate(invalid="ignore", divide="ignore"):
        means: FloatArray = sums.sum(axis=0) / counts.sum(axis=0)[:, None]
    return means


def _terms_kept(p: _Problem) -> tuple[int, ...]:
    """The polynomial terms each strip kept (a unit is a strip with "strips")."""
    poly = p.polynomial
    if poly is None:
        return ()
    n_fixed = (
        np.zeros(p.unit_strip.shape[0], dtype=np.intp)
        if poly.fixed is None
        else poly.fixed.sum(axis=1)
    )
    return tuple(int(poly.n_terms - n) for n in n_fixed)


def _formation_notes(p: _Problem, result: BlockResult) -> tuple[str, ...]:
    """The warnings of forming the strips, as one strip's run gives them: every
    rejection of its blunder tests (tie residuals in metres), and the control
    points on two photos or more that the block does not determine (not on
    both photos of a pair, or every determination of them rejected)."""
    notes = [
        f"strip '{spec.name}': {text}"
        for spec, strip in zip(result.specs, result.strips, strict=True)
        for text in strip.break_warnings
    ]
    notes += [r.describe() for strip in result.strips for r in strip.rejections]
    determined = {int(r) for r in p.control_rows}
    obs = p.observations
    # points on one photo only: the loader has said so, once for all of them
    n_photos = np.bincount(obs.point, minlength=obs.n_points)
    on_pairs = {pid for pid, n in zip(obs.point_ids, n_photos, strict=True) if n >= 2}
    failed: dict[str, str] = {}
    for strip in p.strips:
        failed.update(strip.lost_to_blunder_tests())
    for row, pid in enumerate(p.control.point_ids):
        if row in determined or pid not in on_pairs:
            continue
        why = failed.get(pid, "not measured on both photos of any pair")
        notes.append(PointWarning.not_triangulated(pid, why, check=bool(p.control.is_check[row])))
    return tuple(notes)


def _in_work_frame(p: _Problem, sol: _Solution) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Points (P, 3), projection centres (M, 3) and image -> work rotations
    (M, 3, 3) of the block's solution; a photo's attitude is the mean of its
    units' transforms of its strip rotation."""
    res = sol.result
    n_points = p.observations.n_points
    t = res.transforms
    rot_work = np.empty((p.observations.n_photos, 3, 3))
    for k, strip in enumerate(p.strips):
        photos = np.flatnonzero(p.photo_strip == k)
        r_strip = strip.rotations[p.photo_in_strip[photos]]
        at = strip.centres[p.photo_in_strip[photos]]  # unit coordinates ("strips")
        ra = t.apply_to_rotation(p.photo_units[photos, 0], r_strip, at)
        rb = t.apply_to_rotation(p.photo_units[photos, 1], r_strip, at)
        rot_work[photos] = _mean_rotation(ra, rb)
    return res.points[:n_points], res.points[n_points:], rot_work


def _keep_given(resid: FloatArray, p: _Problem) -> None:
    """Blank the residuals (in place) of the coordinates the control does not
    give (a plan point's dH, a height point's dE, dN); a rejected control
    component keeps its residual, as a strip's does (``used_xy``, ``used_h``
    say what was used)."""
    given_xy = p.check | p.control.uses_xy[p.control_rows]
    given_h = p.check | p.control.uses_h[p.control_rows]
    resid[~given_xy, :2] = np.nan
    resid[~given_h, 2] = np.nan
    resid[np.isnan(p.given)] = np.nan


def _with_restored_control(
    p: _Problem,
    sol: _Solution,
    block: BlockResult,
    restored: BoolArray,
    points_work: FloatArray,
) -> tuple[_Problem, _Solution, BlockResult]:
    """The control rows of the points the block left out and the refinement
    restored (``restored`` (P,), start values ``points_work``), appended to
    the problem, to its solution's guesses (a missing component from the
    start value, as the block's own rows take the block's) and to the block's
    tables, where their residuals are NaN: the block had none.  A control
    point the block left out after the strips determined it (its rows all
    rejected) keeps the one row it has."""
    has_row = np.zeros(restored.shape[0], dtype=bool)
    has_row[p.idx] = True
    new = control_rows(p.observations, p.control, restored & ~has_row)
    if not new.rows.size:
        return p, sol, block
    p = replace(
        p,
        control_rows=np.concatenate([p.control_rows, new.rows]),
        idx=np.concatenate([p.idx, new.idx]),
        given=np.vstack([p.given, new.given]),
        sigma=np.vstack([p.sigma, new.sigma]),
        use_xy=np.concatenate([p.use_xy, new.use_xy]),
        use_z=np.concatenate([p.use_z, new.use_z]),
        check=np.concatenate([p.check, new.check]),
    )
    guess = np.where(np.isnan(new.given), p.work.from_work(points_work[new.idx]), new.given)
    sol = replace(sol, guess=np.vstack([sol.guess, guess]))
    block = replace(
        block,
        control_index=p.control_rows,
        is_check=p.check,
        control_residuals=np.vstack(
            [block.control_residuals, np.full((new.rows.size, 3), np.nan)]
        ),
    )
    return p, sol, block


def _refine(
    p: _Problem,
    sol: _Solution,
    block: BlockResult,
    blunders: BlunderOptions,
    max_iterations: int,
    gnss: GnssCentres | None = None,
    imu: ImuAttitudes | None = None,
    self_calibration: SelfCalibration | None = None,
    variance_components: bool = False,
) -> BlockResult:
    """The bundle adjustment of the whole block from its solution, in the work
    frame (plan-only and height-only control keep the block's value of their
    other coordinate).  It starts from all the control, as a strip's
    refinement does, and tests it itself: what the block's similarities
    rejected may be a camera error the self-calibration takes out
    (docs/block.md), and a true blunder fails its tests again."""
    from ..bundle.refine import gnss_imu_in_frame, gnss_imu_outcomes, lost_points_note
    from ..bundle.start_points import restore_points, restored_ids, restored_points_note
    from ..bundle.variance import refine_frame_weighted

    block_points, centres0, rot0 = _in_work_frame(p, sol)
    # points the block left out, intersected from its photos (bundle/start_points.py);
    # a control or check point among them takes its control row again
    restored = restore_points(p.observations, centres0, rot0, block_points, blunders=blunders)
    points0 = restored.points
    p, sol, block = _with_restored_control(p, sol, block, restored.restored, points0)
    use_xy, use_z = p.use_xy, p.use_z
    n_points = p.observations.n_points
    target = p.work.to_work(sol.guess)
    control_xyz = np.full((n_points, 3), np.nan)
    control_sigma = np.full((n_points, 3), np.inf)
    use = np.column_stack([use_xy, use_xy, use_z])
    control_xyz[p.idx] = np.where(use, target, np.nan)
    control_sigma[p.idx] = np.where(use, p.sigma, np.inf)
    aux = gnss_imu_in_frame(p.observations.photo_ids, block.photo_centres, p.work, gnss, imu)
    fr = refine_frame_weighted(
        p.observations,
        centres0,
        rot0,
        points0,
        control_xyz=control_xyz,
        control_sigma=control_sigma,
        gnss_centres=aux.gnss_xyz,
        gnss_sigma=aux.gnss_sig,
        imu_rotations=aux.imu_rot,
        imu_sigma=aux.imu_sig,
        gnss_axes=aux.gnss_axes,
        blunders=blunders,
        max_iterations=max_iterations,
        compute_precision=False,
        self_calibration=self_calibration,
        variance_components=variance_components,
    )
    work = p.work
    points_work = np.where(fr.point_used[:, None], fr.points, np.nan)
    centres = work.from_work(fr.centres)
    rot_enu = work.rotations_to_enu(fr.rotations, centres)
    # what the GNSS centres and IMU attitudes did, as for one strip
    gnss_out, imu_out = gnss_imu_outcomes(
        aux,
        gnss,
        imu,
        fr,
        work.work_from_enu(centres),
        opk_from_matrix(rot_enu),
        p.observations.photo_ids,
        blunders or BlunderOptions(),
    )
    given_work = work.to_work(np.where(np.isnan(p.given), sol.guess, p.given))
    resid = work.enu_from_work(given_work - points_work[p.idx])
    used_xy = use_xy & fr.control_used[p.idx, 0]
    used_z = use_z & fr.control_used[p.idx, 2]
    _keep_given(resid, p)
    used = resid.copy()
    used[~used_xy, :2] = np.nan
    used[~used_z, 2] = np.nan
    notes = tuple(r.describe() for r in fr.rejections)
    notes += _used_again_note(p, block, used_xy, used_z)
    notes += tuple(lost_points_note(p.observations.point_ids, block_points, fr.point_used))
    notes += tuple(
        restored_points_note(p.observations.point_ids, restored.restored, fr.point_used)
    )
    if fr.self_calibration is not None:
        notes = fr.self_calibration.notes + notes
    return replace(
        block,
        points=work.from_work(points_work),
        photo_centres=centres,
        photo_opk=opk_from_matrix(rot_enu),
        control_residuals=resid,
        used_xy=used_xy,
        used_h=used_z,
        control_statistics=AccuracyStatistics.from_residuals(used[~p.check]),
        check_statistics=AccuracyStatistics.from_residuals(resid[p.check]),
        rejections=block.rejections + tuple(fr.rejections),
        warnings=block.warnings + notes,
        refined=True,
        refined_sigma0=float(fr.bundle.sigma0),
        block_check_statistics=block.check_statistics,
        block_control_residuals=block.control_residuals,
        gnss=gnss_out,
        imu=imu_out,
        self_calibration=fr.self_calibration,
        variance_components=fr.variance_components,
        restored_points=restored_ids(p.observations.point_ids, restored.restored, fr.point_used),
    )


def _used_again_note(
    p: _Problem, block: BlockResult, used_xy: BoolArray, used_z: BoolArray
) -> tuple[str, ...]:
    """The control points the block's tests rejected and the refinement's
    kept (``used_xy``, ``used_z``: the refinement's), named in a note: their
    rejection above is the block's, not the result's."""
    n = block.used_xy.size  # the block's rows; restored control comes after
    again = (~block.used_xy & used_xy[:n]) | (~block.used_h & used_z[:n])
    if not again.any():
        return ()
    names = [p.control.point_ids[r] for r in p.control_rows[:n][again]]
    return (
        f"bundle: {len(names)} control point(s) the block's tests rejected pass the "
        f"refinement's and are used in it: {', '.join(repr(n) for n in names)}",
    )


def _products(
    p: _Problem,
    sol: _Solution,
    use_xy: BoolArray,
    use_z: BoolArray,
    keep_rows: BoolArray,
    rejections: tuple[Rejection, ...],
) -> BlockResult:
    """Points and photos to the CRS, the control's residuals and the joins."""
    res, work = sol.result, p.work
    points_work, centres_work, rot_work = _in_work_frame(p, sol)
    t = res.transforms
    centres = work.from_work(centres_work)
    rot_enu = work.rotations_to_enu(rot_work, centres)
    given_work = work.to_work(np.where(np.isnan(p.given), sol.guess, p.given))
    resid = work.enu_from_work(given_work - points_work[p.idx])
    _keep_given(resid, p)
    used = resid.copy()
    used[~use_xy, :2] = np.nan
    used[~use_z, 2] = np.nan
    # how well the units themselves meet the control: given minus the mean of
    # their determinations of the point (the adjusted point also leans on the
    # control, the more the less the units weigh)
    own = work.enu_from_work(given_work - _unit_means(p, t, keep_rows)[p.idx])
    own[np.isnan(used)] = np.nan
    return BlockResult(
        specs=p.specs,
        strips=tuple(  # the tie test's residuals in metres
            strip.with_rejections_in_metres(float(np.mean(t.scale[p.unit_strip == k])))
            for k, strip in enumerate(p.strips)
        ),
        observations=p.observations,
        photo_strip=p.photo_strip,
        scale=np.array([float(np.mean(t.scale[p.unit_strip == k])) for k in range(len(p.strips))]),
        points=work.from_work(points_work),
        photo_centres=centres,
        photo_opk=opk_from_matrix(rot_enu),
        control=p.control,
        control_index=p.control_rows,
        control_residuals=resid,
        is_check=p.check,
        used_xy=use_xy,
        used_h=use_z,
        control_statistics=AccuracyStatistics.from_residuals(used[~p.check]),
        check_statistics=AccuracyStatistics.from_residuals(resid[p.check]),
        control_fit_statistics=AccuracyStatistics.from_residuals(own[~p.check]),
        joins=_with_transfer(
            _joins(p, t, keep_rows),
            _joins(p, _free_block(p, sol, use_xy | use_z, keep_rows), keep_rows),
            _photo_scale_m_per_mm(p, points_work, centres_work),
        ),
        sigma0=float(res.sigma0),
        polynomial=0 if p.polynomial is None else p.polynomial.degree,
        polynomial_terms=_terms_kept(p),
        redundancy=int(res.redundancy),
        iterations=int(res.iterations),
        rejections=rejections,
        warnings=tuple(r.describe() for r in rejections),
    )


def _joins(p: _Problem, t: UnitTransforms, keep_rows: BoolArray) -> tuple[StripJoin, ...]:
    """Every pair of strips on the points both determine: each strip's
    determination (the mean of its units' transformed rows) compared along
    east, north and up."""
    sums, counts = _strip_sums(p, t, keep_rows)
    n_strips = len(p.strips)
    out = []
    for i in range(n_strips):
        for j in range(i + 1, n_strips):
            both = np.flatnonzero((counts[i] > 0) & (counts[j] > 0))
            if both.size == 0:
                continue
            a = sums[i, both] / counts[i, both, None]
            b = sums[j, both] / counts[j, both, None]
            d = p.work.enu_from_work(a - b)
            plan = np.hypot(d[:, 0], d[:, 1])
            height = np.abs(d[:, 2])
            out.append(
                StripJoin(
                    (i, j),
                    int(both.size),
                    float(plan.mean()),
                    float(plan.max()),
                    float(height.mean()),
                    float(height.max()),
                )
            )
    return tuple(out)


#: Standard deviation of the control coordinates that only hold the datum of
#: the free block, as a fraction of the control's extent: far above any
#: discrepancy they could force (a pull of (σ_row / σ)² ≈ 1e-3 or less), yet
#: firm enough to hold the scale (with a sigma of a kilometre the block
#: shrinks towards a point, where its rows' noise costs nothing).
_FREE_DATUM_SIGMA = 1e-3


def _free_block(
    p: _Problem, sol: _Solution, active: BoolArray, keep_rows: BoolArray
) -> UnitTransforms:
    """The units transformed onto each other only: the block's solution
    again with its control held at the adjusted points, loosely, so that it
    fixes the datum and forces nothing (R4's "free block" of the transfer
    criterion)."""
    res = sol.result
    r = p.rows
    rows = UnitObservations(
        r.unit[keep_rows], r.point[keep_rows], r.xyz[keep_rows], r.weight[keep_rows]
    )
    idx = np.unique(p.idx[active])
    idx = idx[np.all(np.isfinite(res.points[idx]), axis=1)]  # a point may have lost its rows
    extent = float(np.max(np.ptp(res.points[idx], axis=0), initial=0.0))
    free = adjust_units(
        rows,
        p.unit_strip.shape[0],
        p.observations.n_points + p.observations.n_photos,
        start=res.transforms,
        points0=np.where(np.isfinite(res.points), res.points, p.points0),
        control_point=idx,
        control_xyz=res.points[idx],
        control_sigma=max(_FREE_DATUM_SIGMA * extent, 1e-3),
        max_iterations=p.max_iterations,
        statistics=False,
        polynomial=p.polynomial,
        order=_band_order(p),
    )
    return free.transforms


def _photo_scale_m_per_mm(p: _Problem, points: FloatArray, centres: FloatArray) -> float:
    """Metres on the ground per millimetre in the image: the median height
    of the projection centres above the median point over the principal
    distance (work frame heights; a block is flown at one height)."""
    up = p.work.enu_from_work(centres - np.nanmedian(points, axis=0))[:, 2]
    return float(np.nanmedian(up)) / p.observations.principal_distance


def _with_transfer(
    joins: tuple[StripJoin, ...], free: tuple[StripJoin, ...], m_per_mm: float
) -> tuple[StripJoin, ...]:
    """The joins with the free block's plan discrepancies at the photo scale."""
    um = 1e3 / m_per_mm if m_per_mm > 0 else float("nan")
    by_pair = {f.strips: f for f in free}
    out = []
    for join in joins:
        f = by_pair.get(join.strips)
        if f is None:
            out.append(join)
            continue
        out.append(
            replace(join, mean_transfer_um=f.mean_plan_m * um, max_transfer_um=f.max_plan_m * um)
        )
    return tuple(out)


def _mean_rotation(a: FloatArray, b: FloatArray) -> FloatArray:
    """The rotation nearest to the mean of two rotations, per row."""
    u, _, vt = np.linalg.svd(a + b)
    d = np.sign(np.linalg.det(u @ vt))
    u[:, :, 2] *= d[:, None]
    mean: FloatArray = u @ vt
    return mean


def _with_timings(result: BlockResult, timings: dict[str, float]) -> BlockResult:
    return replace(result, timings={**timings, "total": sum(timings.values())})
