"""What both ground constructions share: the route, the control and line
points found in the strip, the precision of the control's tests, the
deformation's local rotation, and the points no model determined."""

from __future__ import annotations

from bisect import bisect_left
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._stats import MEDIAN_SAMPLE, sample_median
from .._typing import BoolArray, FloatArray, IntArray
from ..errors import GeometryError
from ..geodesy import GroundCRS
from ..geometry.deformation import DeformationResult
from ..geometry.rotation import matrix_from_rotvec
from ..observations import ControlPoints, ImageObservations, LineSpec
from ..options import BlunderOptions, Route
from ..results import StripModel

__all__ = [
    "ControlRows",
    "control_detectability",
    "control_rows",
    "control_rows_of",
    "index_of",
    "intersect_unmodelled",
    "line_indices",
    "resolve_route",
]


def resolve_route(route: Route | str | None, crs: GroundCRS) -> Route:
    """The route asked for, or the default for the CRS (geocentric; projected
    for ``"local"``); GeometryError for a route the CRS cannot take."""
    resolved = (
        (Route.PROJECTED if crs.is_local else Route.GEOCENTRIC)
        if route is None
        else Route.create(route)
    )
    if crs.is_local and resolved is Route.GEOCENTRIC:
        raise GeometryError(
            'the geocentric route needs a real CRS; with crs = "local" use route = "projected"'
        )
    if resolved is Route.PROJECTED and crs.is_geographic:
        raise GeometryError(
            "the projected route needs a projected CRS (or local); "
            f"{crs.name} is geographic: use the geocentric route"
        )
    return resolved


def index_of(ids: Sequence[str], names: Sequence[str]) -> IntArray:
    """Index of each name in ids (-1 where absent).

    `names` (control, line points) are few, `ids` (every point of the strip)
    many.  Each name is first found by binary search: point ids built by
    :meth:`ImageObservations.from_ids` or from a project are sorted
    (``np.unique``), and a hit is confirmed by equality, so unsorted ids give
    no wrong index.  The names it misses (absent, or ids not sorted) are
    looked up by one pass of set membership over `ids` (C-level ``map``);
    sorting or hashing all of `ids` would cost 3× more than that pass, and
    the pass 50× more than the binary searches.
    """
    n = len(ids)
    out = np.full(len(names), -1, dtype=np.intp)
    missed = []
    for k, name in enumerate(names):
        i = bisect_left(ids, name)
        if i < n and ids[i] == name:
            out[k] = i
        else:
            missed.append(k)
    if missed:
        wanted = frozenset(names[k] for k in missed)
        hits = np.flatnonzero(np.fromiter(map(wanted.__contains__, ids), bool, n))
        found = {ids[int(i)]: int(i) for i in hits}
        out[missed] = [found.get(names[k], -1) for k in missed]
    return out


@dataclass(frozen=True)
class ControlRows:
    """The control points the strip triangulated, in control-file order.

    Attributes
    ----------
    rows : ndarray of int, shape (C,)
        Rows of the control table.
    index : ndarray of int, shape (C,)
        Index of each among the strip's points.
    ids : tuple of str
    given : ndarray, shape (C, 3)
        Coordinates in the control CRS (NaN where not given).
    use_xy, use_z, check : ndarray of bool, shape (C,)
        Plan and height control, check points.
    sigma_xy, sigma_h : ndarray, shape (C,)
        The control's own standard deviations, metres.
    left_out : tuple of str
        Control points not triangulated (named in the warnings).
    """

    rows: IntArray
    index: IntArray
    ids: tuple[str, ...]
    given: FloatArray
    use_xy: BoolArray
    use_z: BoolArray
    check: BoolArray
    sigma_xy: FloatArray
    sigma_h: FloatArray
    left_out: tuple[str, ...]


def control_rows(strip: StripModel, control: ControlPoints) -> ControlRows:
    """The control rows that can be used: observed and triangulated.

    Raises
    ------
    GeometryError
        If no control point is triangulated.
    """
    picked = control_rows_of(strip.observations, control, strip.triangulated)
    if not (picked.use_xy | picked.use_z).any():
        raise GeometryError(_no_control_message(control))
    return picked


def control_rows_of(
    observations: ImageObservations, control: ControlPoints, determined: BoolArray
) -> ControlRows:
    """The control rows whose point is among the observations' and
    ``determined`` (P,) bool, the control's ids found by binary search
    (:func:`index_of`); the others are ``left_out``."""
    row_point = index_of(observations.point_ids, control.point_ids)
    found = row_point >= 0
    kept = found & determined[np.where(found, row_point, 0)]
    rows = np.flatnonzero(kept)
    return ControlRows(
        rows=rows,
        index=row_point[rows],
        ids=tuple(control.point_ids[r] for r in rows),
        given=control.xyz[rows],
        use_xy=control.uses_xy[rows],
        use_z=control.uses_h[rows],
        check=control.is_check[rows],
        sigma_xy=control.sigma_xy[rows],
        sigma_h=control.sigma_h[rows],
        left_out=tuple(p for p, ok in zip(control.point_ids, kept, strict=True) if not ok),
    )


def _no_control_message(control: ControlPoints) -> str:
    """Why no control point takes part: none is given, or none is triangulated."""
    if (control.uses_xy | control.uses_h).any():
        return "no control point is observed on two photos of a model"
    return (
        f"no full, plan or height control point is given ({int(control.is_check.sum())} check "
        "point(s) only): the strip needs at least two plan and three height control points; "
        "give some points the type full, plan or height"
    )


def line_indices(strip: StripModel, lines: Sequence[LineSpec]) -> list[IntArray]:
    """The strip's index of every line point, line by line.

    Raises
    ------
    GeometryError
        If a line point is not triangulated (the line and points named).
    """
    obs = strip.observations
    out = []
    for line in lines:
        li = index_of(obs.point_ids, line.point_ids)
        missing = [
            p
            for p, i in zip(line.point_ids, li, strict=True)
            if i < 0 or not strip.triangulated[i]
        ]
        if missing:
            raise GeometryError(
                f"straight line {line.name!r}: point(s) {', '.join(map(repr, missing[:5]))} "
                "are not triangulated (not measured on both photos of a model)"
            )
        out.append(li)
    return out


def image_scale(strip: StripModel) -> tuple[float, float]:
    """Model units per mm on the image (times the similarity's scale: metres
    per mm), and the height-to-base ratio; medians over the strip's points."""
    c = strip.observations.principal_distance
    model_centres = strip.centres[strip.model_photo_positions]
    # the medians' evenly spaced sample (_stats.sample_median), taken before the rays
    step = -(-strip.model.size // MEDIAN_SAMPLE)
    ray = strip.model_points[::step] - np.take(model_centres, strip.model[::step], axis=0)
    model_per_mm = sample_median(np.sqrt(np.einsum("ij,ij->i", ray, ray))) / c
    base = float(np.median(np.linalg.norm(np.diff(model_centres, axis=0), axis=1)))
    height_to_base = sample_median(np.abs(ray[:, 2])) / base
    return model_per_mm, height_to_base


def deformation_slopes(
    deformation: DeformationResult, xyz: FloatArray, axes: Sequence[int]
) -> list[FloatArray]:
    """Central differences dw/dX, dw/dY (the `axes` 0, 1) of the deformation
    at points xyz, each (M, 3): all displaced copies in one evaluation (one
    set-up of the spline's pieces)."""
    h = 1e-3 * max(float(deformation.normalization.half_extent), 1.0)
    shifted = np.repeat(xyz[None], 2 * len(axes), axis=0)
    for k, axis in enumerate(axes):
        shifted[2 * k, :, axis] += h
        shifted[2 * k + 1, :, axis] -= h
    w = deformation.evaluate(shifted.reshape(-1, 3)).reshape(2 * len(axes), -1, 3)
    return [(w[2 * k] - w[2 * k + 1]) / (2 * h) for k in range(len(axes))]


def deformation_rotation(deformation: DeformationResult, xyz: FloatArray) -> FloatArray:
    """Local rotation (M, 3, 3) of the correction field -w(X, Y) at points xyz.

    The correction displaces the strip by u = -w(X, Y); a change of u_Z with
    X or Y tilts the model surface by that slope, and the antisymmetric part
    of the horizontal gradient turns it about Z.  Photo attitudes get the same
    small rotation (first order).
    """
    dw_dx, dw_dy = deformation_slopes(deformation, xyz, (0, 1))
    du_dx, du_dy = -dw_dx, -dw_dy
    rotvec = np.column_stack([du_dy[:, 2], -du_dx[:, 2], 0.5 * (du_dx[:, 1] - du_dy[:, 0])])
    return matrix_from_rotvec(rotvec)


def line_residuals(xyz: FloatArray) -> FloatArray:
    """Y residuals of points about their own best straight line Y = a + b X."""
    design = np.column_stack([np.ones(len(xyz)), xyz[:, 0]])
    coef, *_ = np.linalg.lstsq(design, xyz[:, 1], rcond=None)
    residuals: FloatArray = xyz[:, 1] - design @ coef
    return residuals


def intersect_unmodelled(
    strip: StripModel, points_work: FloatArray, centres_work: FloatArray, rot_work: FloatArray
) -> FloatArray:
    """Points no model determined but seen on two or more photos of the strip
    (e.g. on photos i and i + 2 only), intersected from all their rays with
    the photos' final orientations (work frame); the others unchanged, and
    so are the points the strip left out after a failed tie test.

    Parameters
    ----------
    strip : StripModel
    points_work : ndarray, shape (P, 3)
        Work-frame points, NaN where not triangulated.
    centres_work, rot_work : ndarray, shapes (M, 3) and (M, 3, 3)
        The strip's photos (``strip.photo_index``) in the work frame.

    Returns
    -------
    ndarray, shape (P, 3)
    """
    obs = strip.observations
    # with an axis, all() of a 2-D array is an array (the stubs add np.bool)
    missing: BoolArray = ~np.isfinite(points_work).all(axis=1)  # type: ignore[assignment]
    if strip.rejected_points:
        # a point whose determinations failed the tie test stays out
        missing &= ~np.isin(np.asarray(obs.point_ids), list(strip.rejected_points))
    if not missing.any():
        return points_work
    slot = np.full(obs.n_photos, -1, dtype=np.intp)
    slot[np.asarray(strip.photo_index, dtype=np.intp)] = np.arange(len(strip.photo_index))
    rows = np.flatnonzero(missing[obs.point] & (slot[obs.photo] >= 0))
    if rows.size < 2:
        return points_work
    from ..strip.densify import intersect_rays

    photos = slot[obs.photo[rows]]
    vectors = np.column_stack([obs.xy[rows], np.full(rows.size, -obs.principal_distance)])
    directions = np.einsum("kij,kj->ki", rot_work[photos], vectors)
    rays = intersect_rays(centres_work[photos], directions, obs.point[rows], obs.n_points)
    out = points_work.copy()
    fill = missing & np.isfinite(rays.points).all(axis=1)
    out[fill] = rays.points[fill]
    return out


def control_detectability(
    redundancy: FloatArray, sigma: FloatArray, blunders: BlunderOptions, n_tests: int
) -> tuple[FloatArray, FloatArray]:
    """Redundancy numbers (clipped to 0..1) and minimal detectable errors of
    control components, both (C, 3).

    The minimal detectable error (Baarda 1968) is ``σ δ0 / sqrt(r)``, with
    δ0 the critical value of the stage ``control`` for ``n_tests`` tests
    plus 0.84 (80 % power): an error that size is found with probability
    0.8; inf where r is below 1e-6 (the component has no redundancy: its
    error goes wholly into the solution and cannot show).
    """
    from ..geometry.simultaneous import baarda_delta

    r = np.clip(np.asarray(redundancy, dtype=np.float64), 0.0, 1.0)
    delta = baarda_delta(blunders.critical("control", max(n_tests, 1)))
    with np.errstate(invalid="ignore", divide="ignore"):
        mde = np.where(r > 1e-6, np.asarray(sigma, dtype=np.float64) * delta / np.sqrt(r), np.inf)
    mde[~np.isfinite(redundancy)] = np.nan
    return r, mde
