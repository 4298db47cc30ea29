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
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..errors import FlightAxisError, GeometryError, PhotoOrderError, StripAerotriWarning
from ..frames import WorkFrame, make_work_frame
from ..geodesy import GroundCRS
from ..geometry.rotation import opk_from_matrix
from ..geometry.similarity import SimilarityTransform, similarity_from_points
from ..geometry.simultaneous import (
    SimultaneousResult,
    UnitObservations,
    UnitPolynomial,
    UnitTransforms,
    adjust_units,
)
from ..ground.models import model_weights
from ..ground.polynomials import adjust_to_ground
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
    BlunderAction,
    BlunderOptions,
    Construction,
    GroundOptions,
    Route,
    StripOptions,
)
from ..results import AccuracyStatistics, BlockResult, Rejection, StripJoin, StripModel
from ..strip.densify import form_strip_stepped

__all__ = ["adjust_block", "strip_observations"]

#: Common points a strip needs with the placed strips when its own control
#: cannot place it (a 3D similarity needs three).
MIN_COMMON_POINTS = 3

_MAX_PASSES = 6
_CHI2_3_MEDIAN = 2.365973884375338  # median of chi-square with 3 degrees of freedom
_NO_TESTS = BlunderOptions(action=BlunderAction.OFF)
_PASS_TOLERANCE_M = 1e-5


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

    Raises
    ------
    GeometryError
        A strip that shares fewer than three points with the rest of the
        block and has too little control of its own; too little control for
        the block; a strip that cannot be formed.
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
            problem, solution, used_xy, used_z, result, blunders, max_iterations, gnss, imu
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


@dataclass
class _Problem:
    """What every solution of the block's transformation needs."""

    observations: ImageObservations
    control: ControlPoints
    crs: GroundCRS
    specs: tuple[StripSpec, ...]
    strips: tuple[StripModel, ...]
    work: WorkFrame
    photo_strip: IntArray  # (M,)
    photo_in_strip: IntArray  # (M,) position of each photo in its strip
    photo_units: IntArray  # (M, 2) the units whose transforms carry each photo's attitude
    unit_strip: IntArray  # (U,) the strip of each unit
    rows: UnitObservations  # points, then centres (point index n_points + photo)
    start: UnitTransforms
    points0: FloatArray
    control_rows: IntArray  # control rows the block determined
    idx: IntArray  # their points
    given: FloatArray
    sigma: FloatArray  # (C, 3)
    use_xy: BoolArray
    use_z: BoolArray
    check: BoolArray
    max_iterations: int
    construction: Construction = Construction.MODELS
    polynomial: UnitPolynomial | None = None  # the strips' deformation ("strips")
    tie_rejected: BoolArray | None = None  # rows the strips' tie tests left out
    unit_sigma: FloatArray | None = None  # (U, 3) a strip point's sigma ("strips")


def _prepare(
    observations: ImageObservations,
    control: ControlPoints,
    crs: GroundCRS,
    specs: tuple[StripSpec, ...],
    strips: tuple[StripModel, ...],
    route: Route,
    construction: Construction,
    max_iterations: int,
    polynomial: int = 0,
) -> _Problem:
    """Start values (each strip to the ground), the work frame, and the rows
    (``polynomial``: J(16)'s type of every strip's own deformation with
    ``"strips"``, 0 for none)."""
    n_points = observations.n_points
    lookup = {pid: i for i, pid in enumerate(observations.point_ids)}
    point_of = np.array([lookup.get(p, -1) for p in control.point_ids], dtype=np.intp)
    determined = np.zeros(n_points, dtype=bool)
    for strip in strips:
        determined |= np.isfinite(strip.points).all(axis=1)
    rows = np.flatnonzero((point_of >= 0) & determined[np.maximum(point_of, 0)])
    idx = point_of[rows]
    given = control.xyz[rows]
    check = control.is_check[rows]
    use_xy = control.uses_xy[rows] & ~check
    use_z = control.uses_h[rows] & ~check
    placed_crs, azimuth = _start_in_crs(observations, control, crs, specs, strips)
    active = use_xy | use_z
    guess = np.where(np.isnan(given), placed_crs[idx], given)
    work = make_work_frame(route, crs, guess[active], azimuth)
    start_work = work.to_work(np.where(np.isfinite(placed_crs), placed_crs, 0.0))
    units = _units(observations, strips, start_work, construction)
    sig_xy, sig_h = control.sigma_xy[rows], control.sigma_h[rows]
    deformation = (
        UnitPolynomial.fit(units.rows.unit, units.rows.xyz, units.unit_strip.shape[0], polynomial)
        if polynomial and construction is Construction.STRIPS
        else None
    )
    return _Problem(
        observations=observations,
        control=control,
        crs=crs,
        specs=specs,
        strips=strips,
        work=work,
        photo_strip=units.photo_strip,
        photo_in_strip=units.photo_in_strip,
        photo_units=units.photo_units,
        unit_strip=units.unit_strip,
        rows=units.rows,
        start=units.start,
        points0=np.vstack([start_work, units.centres0]),
        control_rows=rows,
        idx=idx,
        given=given,
        sigma=np.column_stack([sig_xy, sig_xy, sig_h]),
        use_xy=use_xy,
        use_z=use_z,
        check=check,
        max_iterations=max_iterations,
        construction=construction,
        polynomial=deformation,
        tie_rejected=units.tie_rejected,
        unit_sigma=units.unit_sigma,
    )


def _start_in_crs(
    observations: ImageObservations,
    control: ControlPoints,
    crs: GroundCRS,
    specs: tuple[StripSpec, ...],
    strips: tuple[StripModel, ...],
) -> tuple[FloatArray, float]:
    """Every point in the CRS from the strips placed so far, and the azimuth of
    the first placed strip's work frame.

    A strip whose own control carries J's similarity is placed by it; the
    others, in turn, by a similarity on the points they share with the strips
    placed (the strip sharing most first).  A strip placed neither way is an
    error naming it.
    """
    n_points = observations.n_points
    placed = np.full((n_points, 3), np.nan)
    done = np.zeros(len(strips), dtype=bool)
    azimuth = None
    start_options = GroundOptions(polynomial=0, construction=Construction.STRIPS)
    for k, strip in enumerate(strips):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", StripAerotriWarning)
                ground = adjust_to_ground(
                    strip,
                    control,
                    crs,
                    options=start_options,
                    blunders=_NO_TESTS,
                )
        except GeometryError:
            continue
        fill = np.isnan(placed).any(axis=1) & np.isfinite(ground.points).all(axis=1)
        placed[fill] = ground.points[fill]
        done[k] = True
        azimuth = ground.azimuth if azimuth is None else azimuth
    if azimuth is None:
        raise GeometryError(
            "block: no strip has the control for its own similarity (two plan and three "
            "height points, not in one vertical plane): the block cannot be placed"
        )
    while not done.all():
        shared: list[tuple[int, int, BoolArray]] = []
        for j in np.flatnonzero(~done):
            ok = np.isfinite(strips[j].points).all(axis=1) & np.isfinite(placed).all(axis=1)
            shared.append((int(ok.sum()), int(j), np.asarray(ok, dtype=bool)))
        count, k, ok = max(shared)
        if count < MIN_COMMON_POINTS:
            names = ", ".join(f"'{specs[j].name}'" for j in np.flatnonzero(~done))
            raise GeometryError(
                f"block: strip {names} shares {count} point(s) with the rest of the block and "
                "has too little control of its own (a similarity needs two plan and three "
                f"height control points, or {MIN_COMMON_POINTS} points common with a "
                "neighbouring strip): measure common points in the side overlap or add control"
            )
        local = _local_frame(crs, placed[ok])
        fit = similarity_from_points(strips[k].points[ok], local.to_local(placed[ok]))
        here = np.isfinite(strips[k].points).all(axis=1) & np.isnan(placed).any(axis=1)
        placed[here] = local.from_local(fit.apply(strips[k].points[here]))
        done[k] = True
    return placed, float(azimuth)


@dataclass(frozen=True)
class _LocalFrame:
    """A Cartesian frame for closed-form similarities: ECEF minus an origin,
    or the CRS coordinates themselves for ``"local"`` (metres either way)."""

    crs: GroundCRS
    origin: FloatArray

    def to_local(self, xyh: FloatArray) -> FloatArray:
        if self.crs.is_local:
            return xyh - self.origin
        ecef: FloatArray = self.crs.to_ecef(xyh) - self.origin
        return ecef

    def from_local(self, xyz: FloatArray) -> FloatArray:
        if self.crs.is_local:
            return xyz + self.origin
        back: FloatArray = self.crs.from_ecef(xyz + self.origin)
        return back


def _local_frame(crs: GroundCRS, xyh: FloatArray) -> _LocalFrame:
    origin = xyh.mean(axis=0) if crs.is_local else crs.to_ecef(xyh).mean(axis=0)
    return _LocalFrame(crs, origin)


@dataclass
class _Units:
    """The units of the transformation and how photos and strips map to them."""

    rows: UnitObservations
    start: UnitTransforms
    unit_strip: IntArray
    photo_strip: IntArray
    photo_in_strip: IntArray
    photo_units: IntArray
    centres0: FloatArray
    tie_rejected: BoolArray  # rows the strips' tie tests left out
    unit_sigma: FloatArray  # (U, 3) a strip point's sigma, m ("strips"; NaN for models)


def _strip_point_weights(
    strip: StripModel, fit: SimilarityTransform, pts: IntArray, iso: FloatArray
) -> FloatArray:
    """Weights (n, 3, 3) of a strip's points in the block of independent
    strips: the shape of each point's information from its rays (the sum
    over its determinations the tie test kept, as the ground stage weighs
    one model's points), scaled so that their median trace is that of the
    strip's own precision ``iso`` (the RMS of its tie points' double
    determinations: the chained strip is less precise than its rays say).

    Rays rather than one sigma for all: a point seen on two photos at the
    image edge and one seen on five in the middle differ several times in
    precision, in height most (on simulated drone blocks the check points'
    height error fell by a fifth to a quarter; on the real FC300X block from
    0.125 / 0.045 to 0.030 / 0.025 m)."""
    info, _, _ = model_weights(strip, fit, float(np.median(strip.observations.sigma)))
    keep = strip.kept_determinations
    n = strip.points.shape[0]
    total = np.zeros((n, 3, 3))
    np.add.at(total, strip.model_point[keep], info[keep])
    out = total[pts]
    good = np.all(np.linalg.eigvalsh(out) > 0, axis=1)
    if not good.any():
        flat: FloatArray = np.broadcast_to(iso, (pts.size, 3, 3)).copy()
        return flat
    factor = float(np.trace(iso)) / float(np.median(np.einsum("nii->n", out[good])))
    shaped: FloatArray = out * factor
    shaped[~good] = iso  # a point its kept rays do not fix: the strip's precision
    return shaped


def _units(
    observations: ImageObservations,
    strips: tuple[StripModel, ...],
    start_work: FloatArray,
    construction: Construction,
) -> _Units:
    """The rows of every unit: a strip's points and centres weighted by the
    strip's own precision (``"strips"``), or each model's determinations and
    its two centres weighted by their rays (``"models"``, as the ground stage
    weights one strip's models)."""
    n_points = observations.n_points
    photo_index = {pid: i for i, pid in enumerate(observations.photo_ids)}
    photo_strip = np.zeros(observations.n_photos, dtype=np.intp)
    photo_in_strip = np.zeros(observations.n_photos, dtype=np.intp)
    photo_units = np.zeros((observations.n_photos, 2), dtype=np.intp)
    centres0 = np.zeros((observations.n_photos, 3))
    units, points, xyz, weights, unit_strip, rejected = [], [], [], [], [], []
    unit_sigma: list[list[float]] = []
    scale, rotation, translation = [], [], []
    n_units = 0
    for k, strip in enumerate(strips):
        ok = np.isfinite(strip.points).all(axis=1)
        fit = similarity_from_points(strip.points[ok], start_work[ok])
        photos = np.array([photo_index[p] for p in strip.photo_ids], dtype=np.intp)
        photo_strip[photos] = k
        photo_in_strip[photos] = np.arange(photos.size)
        centres0[photos] = fit.apply(strip.centres)
        if construction is Construction.STRIPS:
            sigma_plan, sigma_height = _strip_sigmas(strip, fit.scale)
            w = np.diag([sigma_plan**-2, sigma_plan**-2, sigma_height**-2])
            pts = np.flatnonzero(ok)
            units.append(np.full(pts.size + photos.size, n_units, dtype=np.intp))
            points.append(np.concatenate([pts, n_points + photos]))
            xyz.append(np.vstack([strip.points[pts], strip.centres]))
            weights.append(
                np.concatenate(
                    [
                        _strip_point_weights(strip, fit, pts, w),
                        np.broadcast_to(w, (photos.size, 3, 3)),
                    ]
                )
            )
            unit_sigma.append([sigma_plan, sigma_plan, sigma_height])
            rejected.append(np.zeros(pts.size + photos.size, dtype=bool))
            photo_units[photos] = n_units
            n_here = 1
        else:
            info, c_left, c_right = model_weights(
                strip, fit, float(np.median(strip.observations.sigma))
            )
            pos = strip.model_photo_positions
            model = np.arange(strip.n_models)
            units.append(n_units + np.concatenate([strip.model, model, model]))
            points.append(
                np.concatenate(
                    [strip.model_point, n_points + photos[pos[:-1]], n_points + photos[pos[1:]]]
                )
            )
            xyz.append(
                np.vstack([strip.model_points, strip.centres[pos[:-1]], strip.centres[pos[1:]]])
            )
            weights.append(np.concatenate([info, c_left, c_right]))
            # the determinations the strip's tie test left out stay out, as
            # in one strip's ground stage (the centres are not tested there)
            rejected.append(
                np.concatenate(
                    [~strip.kept_determinations, np.zeros(2 * strip.n_models, dtype=bool)]
                )
            )
            unit_sigma += [[np.nan] * 3] * strip.n_models
            # a photo's attitude: the mean of the models it belongs to
            as_left = np.searchsorted(pos[:-1], np.arange(photos.size), side="right") - 1
            photo_units[photos, 0] = n_units + np.clip(as_left, 0, strip.n_models - 1)
            photo_units[photos, 1] = n_units + np.clip(
                as_left - (np.isin(np.arange(photos.size), pos[1:])), 0, strip.n_models - 1
            )
            n_here = strip.n_models
        unit_strip.append(np.full(n_here, k, dtype=np.intp))
        scale.append(np.full(n_here, fit.scale))
        rotation.append(np.broadcast_to(fit.rotation, (n_here, 3, 3)))
        translation.append(np.broadcast_to(fit.translation, (n_here, 3)))
        n_units += n_here
    rows = UnitObservations(
        np.concatenate(units), np.concatenate(points), np.vstack(xyz), np.concatenate(weights)
    )
    start = UnitTransforms(
        np.concatenate(scale),
        np.concatenate(rotation).copy(),
        np.concatenate(translation).copy(),
        np.zeros((n_units, 3)),
    )
    return _Units(
        rows,
        start,
        np.concatenate(unit_strip),
        photo_strip,
        photo_in_strip,
        photo_units,
        centres0,
        np.concatenate(rejected),
        np.asarray(unit_sigma, dtype=np.float64),
    )


def _strip_sigmas(strip: StripModel, scale: float) -> tuple[float, float]:
    """A strip point's standard deviation in plan and in height, metres: the
    RMS of its tie points' double determinations over √2 (each difference
    holds two determinations), times the strip's scale."""
    tie = np.asarray(strip.tie_difference, dtype=np.float64).reshape(-1, 3)
    if tie.shape[0] < 3:
        raise GeometryError(
            f"block: a strip of {strip.n_models} model(s) with {tie.shape[0]} tie point(s) "
            "gives no precision of its points; a strip of a block needs tie points"
        )
    plan = float(np.sqrt(np.mean(tie[:, 0] ** 2 + tie[:, 1] ** 2) / 2.0 / 2.0))
    height = float(np.sqrt(np.mean(tie[:, 2] ** 2) / 2.0))
    return max(plan * scale, 1e-6), max(height * scale, 1e-6)


@dataclass
class _Solution:
    result: SimultaneousResult
    guess: FloatArray


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
    failed = {pid for strip in p.strips for pid in strip.rejected_points}
    for row, pid in enumerate(p.control.point_ids):
        if row in determined or pid not in on_pairs:
            continue
        why = (
            "every determination of it failed the tie-point test"
            if pid in failed
            else "not measured on both photos of any pair"
        )
        kind = "check point" if p.control.is_check[row] else "control point"
        notes.append(f"{kind} {pid!r} is not triangulated ({why}): left out")
    return tuple(notes)


#: A strip's polynomial term whose effect the block determines worse than
#: this many times a point of the strip is held at 0: it would add more
#: noise than the bending it removes (control at the block's corners only
#: leaves the bending of all strips together undetermined: a film block
#: missed its check points by 3.4 m).
_TERM_NOISE_RATIO = 2.0
_AXES = ("along", "across", "up")
_MONOMIALS = ("uv", "u²", "u³")


def _determined_terms(p: _Problem) -> tuple[_Problem, list[str]]:
    """The problem with every strip polynomial term that the control and the
    common points do not determine held at 0, and a warning per strip
    naming them."""
    if p.polynomial is None:
        return p, []
    res = _solve(p, p.use_xy, p.use_z, None, statistics=False).result
    if res.coefficient_variance is None:
        return p, []
    poly = p.polynomial
    assert p.unit_sigma is not None  # set with the strips' rows
    sigma = p.unit_sigma  # a strip point's sigma along its axes (m)
    effect = (
        res.transforms.scale[:, None]
        * poly.half_length[:, None]
        * np.sqrt(np.maximum(res.coefficient_variance, 0.0))
    )  # the term's standard deviation at the strip's end, metres
    weak = effect > _TERM_NOISE_RATIO * np.tile(sigma, poly.degree)
    if not weak.any():
        return p, []
    notes = []
    for u in np.flatnonzero(weak.any(axis=1)):
        terms = ", ".join(f"{_MONOMIALS[j // 3]} {_AXES[j % 3]}" for j in np.flatnonzero(weak[u]))
        notes.append(
            f"strip '{p.specs[int(p.unit_strip[u])].name}': polynomial term(s) {terms} left "
            "out: the control and the common points do not determine them (more control "
            "along the block's edges would)"
        )
    return replace(p, polynomial=poly.without(weak)), notes


def _solve(
    p: _Problem,
    use_xy: BoolArray,
    use_z: BoolArray,
    previous: _Solution | None,
    keep_rows: BoolArray | None = None,
    *,
    statistics: bool = True,
) -> _Solution:
    """The transformation, with passes for control given in plan or height only
    (their other coordinates from the adjusted point, as the ground stage);
    ``statistics``: the control's tests (cofactors) at the end."""
    active = use_xy | use_z
    guess = (
        np.where(np.isnan(p.given), p.work.from_work(p.points0[p.idx]), p.given)
        if previous is None
        else previous.guess
    )
    starts, points0 = (
        (p.start, p.points0)
        if previous is None
        else (
            previous.result.transforms,
            np.where(np.isfinite(previous.result.points), previous.result.points, p.points0),
        )
    )
    guessed = bool(np.isnan(p.given[active]).any())
    n_total = p.observations.n_points + p.observations.n_photos
    r = p.rows
    rows = (
        r
        if keep_rows is None
        else UnitObservations(
            r.unit[keep_rows], r.point[keep_rows], r.xyz[keep_rows], r.weight[keep_rows]
        )
    )
    result = None
    for n_pass in range(1, _MAX_PASSES + 1):
        target = p.work.to_work(guess)
        target[~use_xy, :2] = np.nan
        target[~use_z, 2] = np.nan

        def solve(
            start: UnitTransforms,
            points0: FloatArray,
            statistics: bool,
            target: FloatArray = target,
        ) -> SimultaneousResult:
            return adjust_units(
                rows,
                p.unit_strip.shape[0],
                n_total,
                start=start,
                points0=points0,
                control_point=p.idx[active],
                control_xyz=target[active],
                control_sigma=p.sigma[active],
                max_iterations=p.max_iterations,
                polynomial=p.polynomial,
                statistics=statistics,
            )

        # the control's cofactors (the costly part of a large block) only for
        # the pass that is the last
        last = not guessed or n_pass == _MAX_PASSES
        result = solve(starts, points0, statistics=last and statistics)
        if last:
            break
        adjusted = p.work.from_work(result.points[p.idx])
        new_guess = np.where(np.isnan(p.given), adjusted, p.given)
        change = float(np.nanmax(np.abs(new_guess - guess), initial=0.0))
        if change < _PASS_TOLERANCE_M:  # converged: once more from it, with the statistics
            if statistics:
                filled = np.where(np.isfinite(result.points), result.points, points0)
                result = solve(result.transforms, filled, statistics=True)
            guess = new_guess
            break
        guess = new_guess
        starts = result.transforms
        points0 = np.where(np.isfinite(result.points), result.points, points0)
    assert result is not None
    return _Solution(result, guess)


def _snoop(
    p: _Problem, blunders: BlunderOptions
) -> tuple[_Solution, BoolArray, BoolArray, BoolArray, tuple[Rejection, ...]]:
    """Data snooping, one rejection at a time until nothing fails: the control
    by Baarda's w (never a component the block cannot spare: kept and
    flagged), then the determinations of the points in their units by their
    3-D residuals against chi-square(3), as the ground stage tests a strip's
    models."""
    use_xy, use_z = p.use_xy.copy(), p.use_z.copy()
    keep_rows = (
        np.ones(p.rows.unit.shape[0], dtype=bool) if p.tie_rejected is None else ~p.tie_rejected
    )
    n_det = int((p.rows.point < p.observations.n_points).sum())
    n_control = int(2 * use_xy.sum() + use_z.sum())
    rejections: list[Rejection] = []
    flagged: set[tuple[int, int]] = set()
    sol = _solve(p, use_xy, use_z, None, keep_rows)
    sigma0 = float(sol.result.sigma0)
    while blunders.testing:
        found = _control_test(p, sol, use_xy, use_z, blunders, flagged)
        if found is None:
            found = _determination_test(p, sol, keep_rows, blunders)
        if found is None:
            break
        rejection, apply = found
        rejections.append(rejection)
        if not (blunders.rejecting and rejection.applied):
            if not blunders.rejecting:
                break
            continue
        apply(use_xy, use_z, keep_rows)
        if n_control - int(2 * use_xy.sum() + use_z.sum()) > blunders.max_fraction * n_control:
            raise GeometryError(_too_much_control_fails(p, blunders, sigma0))
        if (~keep_rows).sum() > blunders.max_fraction * n_det:
            raise GeometryError(
                f"block: more than {blunders.max_fraction:.0%} of the points' determinations "
                "fail the blunder test; the image coordinates or point ids cannot be trusted"
            )
        sol = _solve(p, use_xy, use_z, sol, keep_rows)
    return sol, use_xy, use_z, keep_rows, tuple(rejections)


def _too_much_control_fails(p: _Problem, blunders: BlunderOptions, sigma0: float) -> str:
    """The message of a block whose control fails the tests beyond
    ``max_fraction`` (as the ground stage of one strip stops).  With one
    similarity per strip the usual cause is the strips' own bending, which a
    similarity cannot follow (long strips of dependent models drift in scale
    and azimuth): the good control then fails by the dozen."""
    head = (
        f"block: more than {blunders.max_fraction:.0%} of the control observations fail the "
        f"blunder test (sigma0 {sigma0:.3g} before the tests)"
    )
    if p.construction is Construction.STRIPS:
        return (
            f"{head}: one similarity per strip cannot follow the strips' bending, or the "
            'control has errors; use block = "models" (every model its own similarity), '
            "and check the control"
        )
    return f"{head}; the control cannot be trusted"


_Apply = Callable[[BoolArray, BoolArray, BoolArray], None]


def _control_test(
    p: _Problem,
    sol: _Solution,
    use_xy: BoolArray,
    use_z: BoolArray,
    blunders: BlunderOptions,
    flagged: set[tuple[int, int]],
) -> tuple[Rejection, _Apply] | None:
    """The control component with the largest |w| beyond the critical value."""
    active = use_xy | use_z
    w = np.full((p.idx.shape[0], 3), np.nan)
    w[active] = sol.result.control_w
    w[~use_xy, :2] = np.nan
    w[~use_z, 2] = np.nan
    n_tests = int(np.isfinite(w).sum())
    critical = blunders.critical("control", max(n_tests, 1))
    score = np.where(np.isfinite(w), np.abs(w), -np.inf)
    for row, comp in flagged:
        score[row, comp] = -np.inf
    row, comp = (int(v) for v in np.unravel_index(int(np.argmax(score)), score.shape))
    if not score[row, comp] > critical:
        return None
    plan = comp < 2
    spare = bool(use_xy.sum() > 2) if plan else bool(use_z.sum() > 3)
    if not spare:
        flagged.add((row, comp))
    resid = sol.result.control_residuals[int(active[: row + 1].sum()) - 1]

    def apply(xy: BoolArray, z: BoolArray, keep: BoolArray) -> None:
        if plan:
            xy[row] = False
        else:
            z[row] = False

    return (
        Rejection(
            stage="control",
            point=p.control.point_ids[p.control_rows[row]],
            photos=(),
            component="XY" if plan else "H",
            residual=float(np.hypot(resid[0], resid[1]) if plan else resid[2]),
            unit="m",
            w=float(w[row, comp]),
            critical=critical,
            applied=blunders.rejecting and spare,
            effect=(
                "left out of the block's transformation"
                if spare
                else "kept: the block cannot spare it (flagged); check this point"
            ),
        ),
        apply,
    )


def _determination_test(
    p: _Problem, sol: _Solution, keep_rows: BoolArray, blunders: BlunderOptions
) -> tuple[Rejection, _Apply] | None:
    """The point determination whose 3-D residual fails chi-square(3) most
    (``row_statistic`` times 3, scaled down by its median over chi-square(3)'s
    when the data are noisier than declared, never up)."""
    n_points = p.observations.n_points
    kept = np.flatnonzero(keep_rows)
    stat = 3.0 * sol.result.row_statistic
    stat = np.where((p.rows.point[kept] < n_points) & np.isfinite(stat), stat, np.nan)
    finite = stat[np.isfinite(stat)]
    if finite.size == 0:
        return None
    stat = stat / max(1.0, float(np.median(finite)) / _CHI2_3_MEDIAN)
    critical = blunders.critical("models", int(finite.size), dof=3)
    w = np.sqrt(np.where(np.isfinite(stat), stat, 0.0))
    k = int(np.argmax(w))
    if not w[k] > critical:
        return None
    row = int(kept[k])
    unit = int(p.rows.unit[row])
    strip = p.specs[int(p.unit_strip[unit])].name

    def apply(xy: BoolArray, z: BoolArray, keep: BoolArray, row: int = row) -> None:
        keep[row] = False

    return (
        Rejection(
            stage="models",
            point=p.observations.point_ids[int(p.rows.point[row])],
            photos=(f"strip {strip}",),
            component="point",
            residual=float(np.linalg.norm(sol.result.residuals[k])),
            unit="m",
            w=float(w[k]),
            critical=critical,
            applied=blunders.rejecting,
            effect="determination left out of the block's transformation",
        ),
        apply,
    )


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


def _refine(
    p: _Problem,
    sol: _Solution,
    use_xy: BoolArray,
    use_z: BoolArray,
    block: BlockResult,
    blunders: BlunderOptions,
    max_iterations: int,
    gnss: GnssCentres | None = None,
    imu: ImuAttitudes | None = None,
) -> BlockResult:
    """The bundle adjustment of the whole block from its solution, in the work
    frame (plan-only and height-only control keep the block's value of their
    other coordinate)."""
    from ..bundle.refine import gnss_imu_in_frame, gnss_imu_outcomes
    from ..bundle.snooping import refine_frame

    points0, centres0, rot0 = _in_work_frame(p, sol)
    n_points = p.observations.n_points
    target = p.work.to_work(sol.guess)
    control_xyz = np.full((n_points, 3), np.nan)
    control_sigma = np.full((n_points, 3), np.inf)
    use = np.column_stack([use_xy, use_xy, use_z])
    control_xyz[p.idx] = np.where(use, target, np.nan)
    control_sigma[p.idx] = np.where(use, p.sigma, np.inf)
    aux = gnss_imu_in_frame(p.observations.photo_ids, block.photo_centres, p.work, gnss, imu)
    fr = refine_frame(
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
    resid[~(use_xy | p.check), :2] = np.nan
    resid[~(use_z | p.check), 2] = np.nan
    resid[np.isnan(p.given)] = np.nan
    used = resid.copy()
    used[~used_xy, :2] = np.nan
    used[~used_z, 2] = np.nan
    notes = tuple(r.describe() for r in fr.rejections)
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
        gnss=gnss_out,
        imu=imu_out,
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
    resid[~(use_xy | p.check), :2] = np.nan
    resid[~(use_z | p.check), 2] = np.nan
    resid[np.isnan(p.given)] = np.nan
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
