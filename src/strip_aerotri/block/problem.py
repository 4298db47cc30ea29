"""What a block's transformation needs, fixed for the block: the start
values (each strip placed on the ground), the work frame, the units' order
along the normal equations' band, and the rows of the two constructions
(``block = "strips"``: every strip one unit, its points weighted by their
rays at the strip's own precision; ``"models"``: every model of every strip
one unit, its determinations and centres weighted by their rays)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..errors import GeometryError, HeightUnitError, StripAerotriWarning
from ..frames import WorkFrame, make_work_frame
from ..geodesy import GroundCRS
from ..geometry.similarity import SimilarityTransform, similarity_from_points
from ..geometry.simultaneous import UnitObservations, UnitPolynomial, UnitTransforms
from ..ground.common import control_rows_of
from ..ground.models import model_weights
from ..ground.polynomials import adjust_to_ground
from ..observations import ControlPoints, ImageObservations, StripSpec
from ..options import BlunderAction, BlunderOptions, Construction, GroundOptions, Route
from ..results import StripModel

#: Common points a strip needs with the placed strips when its own control
#: cannot place it (a 3D similarity needs three).
MIN_COMMON_POINTS = 3

_NO_TESTS = BlunderOptions(action=BlunderAction.OFF)

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
    unit_order: IntArray | None = None  # the units along the normal equations' band


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
    *,
    control_name: str = "control",
) -> _Problem:
    """Start values (each strip to the ground), the work frame, and the rows
    (``polynomial``: J(16)'s type of every strip's own deformation with
    ``"strips"``, 0 for none; ``control_name`` the control in messages)."""
    determined = np.zeros(observations.n_points, dtype=bool)
    for strip in strips:
        determined |= np.isfinite(strip.points).all(axis=1)
    c = control_rows(observations, control, determined)
    rows, idx, given, use_xy, use_z = c.rows, c.idx, c.given, c.use_xy, c.use_z
    placed_crs, azimuth = _start_in_crs(
        observations, control, crs, specs, strips, control_name=control_name
    )
    active = use_xy | use_z
    guess = np.where(np.isnan(given), placed_crs[idx], given)
    work = make_work_frame(route, crs, guess[active], azimuth)
    start_work = work.to_work(np.where(np.isfinite(placed_crs), placed_crs, 0.0))
    units = _units(observations, strips, start_work, construction)
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
        sigma=c.sigma,
        use_xy=use_xy,
        use_z=use_z,
        check=c.check,
        max_iterations=max_iterations,
        construction=construction,
        polynomial=deformation,
        tie_rejected=units.tie_rejected,
        unit_sigma=units.unit_sigma,
        unit_order=_across_strips(units.rows, units.start, units.unit_strip.shape[0]),
    )


class ControlRowTable(NamedTuple):
    """Rows of the control table and what the block takes from each.

    Attributes
    ----------
    rows : ndarray of int, shape (C,)
        Rows of the control table, in its order.
    idx : ndarray of int, shape (C,)
        Their points (index into the observations' points).
    given : ndarray, shape (C, 3)
        Their coordinates in the CRS (NaN where not given).
    sigma : ndarray, shape (C, 3)
        Their sigmas (plan, plan, height; CRS units).
    use_xy, use_z : ndarray of bool, shape (C,)
        Plan and height used as control (never for a check point).
    check : ndarray of bool, shape (C,)
    """

    rows: IntArray
    idx: IntArray
    given: FloatArray
    sigma: FloatArray
    use_xy: BoolArray
    use_z: BoolArray
    check: BoolArray


def control_rows(
    observations: ImageObservations, control: ControlPoints, points: BoolArray
) -> ControlRowTable:
    """The control rows of the points ``points`` (P,) bool, as the strip's
    (:func:`~strip_aerotri.ground.common.control_rows_of`), their sigmas as
    one (C, 3) table."""
    picked = control_rows_of(observations, control, points)
    return ControlRowTable(
        rows=picked.rows,
        idx=picked.index,
        given=picked.given,
        sigma=np.column_stack([picked.sigma_xy, picked.sigma_xy, picked.sigma_h]),
        use_xy=picked.use_xy,
        use_z=picked.use_z,
        check=picked.check,
    )


def _across_strips(rows: UnitObservations, start: UnitTransforms, n_units: int) -> IntArray:
    """The units in the order of their centres along the flight (the work
    frame's X), the classical numbering across the strips: the reduced
    normal equations then couple a unit only with those of about one overlap
    window in every strip (method.md 6B; a 10 x 100-photo drone block by
    models: a half-band of 53 models, against 111 by reverse Cuthill-McKee
    and 197 strip after strip)."""
    counts = np.bincount(rows.unit, minlength=n_units).astype(np.float64)
    centre = np.column_stack(
        [np.bincount(rows.unit, rows.xyz[:, k], minlength=n_units) / counts for k in range(3)]
    )
    along = start.apply(np.arange(n_units), centre)[:, 0]
    order: IntArray = np.argsort(along, kind="stable").astype(np.intp)
    return order


def _start_in_crs(
    observations: ImageObservations,
    control: ControlPoints,
    crs: GroundCRS,
    specs: tuple[StripSpec, ...],
    strips: tuple[StripModel, ...],
    *,
    control_name: str = "control",
) -> tuple[FloatArray, float]:
    """Every point in the CRS from the strips placed so far, and the azimuth of
    the first placed strip's work frame.

    A strip whose own control carries J's similarity is placed by it; the
    others, in turn, by a similarity on the points they share with the strips
    placed (the strip sharing most first).  A strip placed neither way is an
    error naming it; control heights in another unit than its plan raise
    :class:`~strip_aerotri.errors.HeightUnitError` naming the control
    ``control_name``.
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
                    control_name=control_name,
                )
        except HeightUnitError:
            raise  # the control's, not the strip's: no strip would do
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
