"""From the strip model to the ground (method.md §6): similarity transformation
on the control, deformation polynomials with the straight-line condition, and
the two routes to the user's CRS.

Both routes work in a Cartesian *work frame* whose X axis runs along the
strip, Y to its left and Z up, so that the polynomials of J(16) have their
meaning:

* ``geocentric`` (B(142)-(152)): the local tangent system at the geocentric
  centroid of the control, X at the azimuth A0 of the strip axis; the earth's
  curvature is in the geometry and needs no correction.
* ``projected`` (J, with B(153)): the map grid itself, rotated by the grid
  azimuth of the strip axis, with heights reduced to the tangent plane at the
  centre of the net, ``Z = H − D²/(2R)``.  With ``crs = "local"`` there is
  no earth curvature correction (a site system is taken as Cartesian).

Plan control has no height and height control no plan position; the work
frame coordinates of such points need them (through the earth's curvature),
so they are taken from the adjusted model and the solution is iterated until
nothing changes (a few passes).
"""

from __future__ import annotations

import warnings
from bisect import bisect_left
from collections.abc import Sequence
from dataclasses import replace
from typing import Any, NamedTuple

import numpy as np

from .._stats import MEDIAN_SAMPLE, exact_median, sample_median
from .._typing import FloatArray, IntArray
from ..blunders import robust_variance_factor
from ..errors import GeometryError, StripAerotriWarning
from ..frames import make_work_frame
from ..geodesy import GroundCRS
from ..geometry.deformation import (
    DeformationResult,
    KindSelection,
    StraightLine,
    fit_deformation,
    select_kind_auto,
)
from ..geometry.rotation import matrix_from_rotvec, opk_from_matrix
from ..geometry.similarity import (
    SimilarityResult,
    SimilarityTransform,
    fit_similarity,
    similarity_from_points,
)
from ..observations import ControlPoints, LineSpec
from ..options import BlunderOptions, Construction, GroundOptions, Route
from ..results import GroundResult, Rejection, StripModel

__all__ = [
    "Construction",
    "GroundOptions",
    "GroundResult",
    "LineSpec",
    "Route",
    "adjust_to_ground",
    "control_detectability",
    "intersect_unmodelled",
]

_MAX_PASSES = 8
#: sigma0 of the last ground fit above which its misfit is warned about (the
#: test suite's strips reach 26 with blunders left in; one cubic over 300
#: photos of bench_strip's strip 40, over 1000 photos 65-490).
_MISFIT_SIGMA0 = 30.0
_ROLL_TOLERANCE = 0.1  # of the expected plan sigma, over the relief's spread
_MAX_TURNS = 4  # of the roll in one pass (a large turn settles in one or two)
_ROLL_SAMPLE_STEP = 4  # of the served sample: 2048 points for the roll's mean and relief
_SERVED_SAMPLE = 8192  # strip points for the similarity's test of the cross tilt
_PASS_TOLERANCE_M = 1e-5
#: A control observation whose rejection the polynomial cannot afford goes
#: only when its |w| is at least this many times the critical value.
_CERTAIN = 3.0
# Probe points (m) that carry a similarity from one work frame to the next.
_FRAME_PROBE_M = np.array(
    [[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0], [0.0, 1000.0, 0.0], [0.0, 0.0, 1000.0]]
)


# --------------------------------------------------------------------------- helpers


def _deformation_slopes(
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


def _deformation_rotation(deformation: DeformationResult, xyz: FloatArray) -> FloatArray:
    """Local rotation (M, 3, 3) of the correction field -w(X, Y) at points xyz.

    The correction displaces the strip by u = -w(X, Y); a change of u_Z with
    X or Y tilts the model surface by that slope, and the antisymmetric part
    of the horizontal gradient turns it about Z.  Photo attitudes get the same
    small rotation (first order).
    """
    dw_dx, dw_dy = _deformation_slopes(deformation, xyz, (0, 1))
    du_dx, du_dy = -dw_dx, -dw_dy
    rotvec = np.column_stack([du_dy[:, 2], -du_dx[:, 2], 0.5 * (du_dx[:, 1] - du_dy[:, 0])])
    return matrix_from_rotvec(rotvec)


def _index_of(ids: Sequence[str], names: Sequence[str]) -> IntArray:
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
        found = {ids[i]: int(i) for i in hits}
        out[missed] = [found.get(names[k], -1) for k in missed]
    return out


def _plan_scale(model_xyz: FloatArray, work_xyz: FloatArray) -> float:
    """Scale estimate (work metres per model unit): RMS plan spread of the
    control about its centroid, work frame over model; 1 where undefined (the
    similarity then names the degenerate control)."""
    if model_xyz.shape[0] < 2:
        return 1.0
    model = model_xyz[:, :2] - model_xyz[:, :2].mean(axis=0)
    work = work_xyz[:, :2] - work_xyz[:, :2].mean(axis=0)
    spread_model = float(np.sum(model**2))
    spread_work = float(np.sum(work**2))
    if not (spread_model > 0.0 and np.isfinite(spread_work)):
        return 1.0
    return float(np.sqrt(spread_work / spread_model))


def _carried(sim: SimilarityTransform, work_from, work_to) -> SimilarityTransform | None:
    """A strip -> work similarity carried from one work frame to another (the
    map between the frames from four probe points); None if it cannot be."""
    if work_to is work_from:
        return sim
    mapped = work_to.to_work(work_from.from_work(_FRAME_PROBE_M))
    if not np.all(np.isfinite(mapped)):
        return None
    return similarity_from_points(_FRAME_PROBE_M, mapped).compose(sim)


def _turned_about_x(
    transform: SimilarityTransform, angle: float, axis_point: FloatArray
) -> SimilarityTransform:
    """``transform`` followed by a turn of `angle` radians (counter-clockwise
    seen from +X) about the work frame's X axis through `axis_point`."""
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return SimilarityTransform(
        scale=transform.scale,
        rotation=turn @ transform.rotation,
        translation=axis_point + turn @ (transform.translation - axis_point),
    )


def _cross_slope(deformation: DeformationResult, xyz: FloatArray) -> float:
    """Mean slope dw_Z/dY of the deformation across the strip at points xyz
    (work frame): the tilt about the strip's axis left to the polynomial."""
    (dw_dy,) = _deformation_slopes(deformation, xyz, (1,))
    return float(np.mean(dw_dy[:, 2]))


def _azimuth_step(vector_work: FloatArray) -> float:
    """Angle to add to A0 so that X points along a work-frame vector (Y is left,
    i.e. counter-clockwise, while azimuth is clockwise)."""
    return -float(np.arctan2(vector_work[1], vector_work[0]))


def _image_scale(strip: StripModel) -> tuple[float, float]:
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


# --------------------------------------------------------------------------- main


def adjust_to_ground(
    strip: StripModel,
    control: ControlPoints,
    crs: GroundCRS | str,
    *,
    lines: Sequence[LineSpec] = (),
    options: GroundOptions | None = None,
    blunders: BlunderOptions | None = None,
) -> GroundResult:
    """Orient the strip model on the control and deliver it in the control CRS.

    Parameters
    ----------
    strip : StripModel
        The strip model from :func:`strip_aerotri.chaining.form_strip`.
    control : ControlPoints
        Control (full, plan, height) and check points; coordinates in `crs`.
    crs : GroundCRS or str
        The control CRS (``"local"`` for a site system).
    lines : sequence of LineSpec
        Straight-line conditions (J(18)).
    options : GroundOptions
    blunders : BlunderOptions, optional
        Tests of the control deviations and line points (data snooping, one
        rejection at a time; see :mod:`strip_aerotri.blunders`).

    Returns
    -------
    GroundResult

    Raises
    ------
    GeometryError
        Insufficient or degenerate control (the rule and the points named),
        too few points for the polynomial type, line points not triangulated.
    """
    options = options or GroundOptions()
    if not isinstance(crs, GroundCRS):
        crs = GroundCRS.from_user_input(crs)
    route = options.route
    if route is None:
        route = Route.PROJECTED if crs.is_local else Route.GEOCENTRIC
    if crs.is_local and route is Route.GEOCENTRIC:
        raise GeometryError(
            'the geocentric route needs a real CRS; with crs = "local" use route = "projected"'
        )
    if route is Route.PROJECTED and crs.is_geographic:
        raise GeometryError(
            "the projected route needs a projected CRS (or local); "
            f"{crs.name} is geographic: use the geocentric route"
        )
    obs = strip.observations

    # Control rows that can be used: observed and triangulated.
    row_point = _index_of(obs.point_ids, control.point_ids)
    triangulated = np.zeros(len(control.point_ids), dtype=bool)
    seen = row_point >= 0
    triangulated[seen] = strip.triangulated[row_point[seen]]
    left_out = tuple(p for p, ok in zip(control.point_ids, triangulated, strict=True) if not ok)
    rows = np.flatnonzero(triangulated)
    idx = row_point[rows]
    given = control.xyz[rows]
    use_xy = control.uses_xy[rows]
    use_z = control.uses_h[rows]
    check = control.is_check[rows]
    ids = tuple(control.point_ids[r] for r in rows)
    active = use_xy | use_z
    if not active.any():
        raise GeometryError("no control point is observed on two photos of a model")
    strip_xyz = strip.points[idx]

    # Lines: model points of the line points.
    line_index = []
    for line in lines:
        li = _index_of(obs.point_ids, line.point_ids)
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
        line_index.append(li)

    # Initial guesses: plan points at the mean known height, height points at the
    # centroid of the known plan positions.
    guess = given.copy()
    h_known = given[use_z, 2]
    xy_known = given[use_xy, :2]
    if h_known.size == 0 or xy_known.size == 0:
        raise GeometryError(
            "the similarity transformation needs at least two full or plan control points "
            "and three full or height control points"
        )
    guess[~use_z, 2] = np.mean(h_known)
    guess[~use_xy, :2] = np.mean(xy_known, axis=0)
    guess[check] = given[check]

    sig_xy_ctrl = control.sigma_xy[rows]
    sig_h_ctrl = control.sigma_h[rows]
    first, last = strip.centres[0], strip.centres[-1]
    model_per_mm, h_to_b = _image_scale(strip)
    # The expected photogrammetric sigmas weight the control with one first
    # estimate of the image scale (control spread in plan, work frame over
    # strip), the same in every fit: a fit repeated in a frame turned only in
    # azimuth is then the same fit turned, so the azimuth pass is not repeated.
    target0 = make_work_frame(route, crs, guess[active], 0.0).to_work(guess)
    metres_per_mm = model_per_mm * _plan_scale(strip_xyz[use_xy], target0[use_xy])
    sigma_plan = exact_median(obs.sigma) * metres_per_mm
    sigma_height = sigma_plan * h_to_b
    exp_xy = np.hypot(sig_xy_ctrl, sigma_plan)
    exp_z = np.hypot(sig_h_ctrl, sigma_height)

    # The points the similarity serves, for its warning about height control
    # nearly in one vertical plane (the point farthest from that plane
    # counts): an evenly spaced sample of the strip's points, which reaches
    # the strip's edges in every few models.
    served = strip.points[:: max(1, -(-strip.points.shape[0] // _SERVED_SAMPLE))]
    served = served[np.isfinite(served).all(axis=1)]

    def solve(
        use_xy: np.ndarray,
        use_z: np.ndarray,
        line_keep: list[np.ndarray],
        previous: _Solution | None = None,
        polynomial: int | str = options.polynomial,
    ):
        """Similarity and polynomial with the plan/height iteration (passes).

        A re-solve after a rejection starts from the ``previous`` solution's
        azimuth and similarity; each fit starts from the last one carried
        into the current frame (fewer iterations, the same solution)."""
        active = use_xy | use_z
        act_ids = [p for p, a in zip(ids, active, strict=True) if a]
        guess_ = guess.copy()
        azimuth = 0.0 if previous is None else previous.azimuth
        last_fit = None if previous is None else (previous.sim.transform, previous.work)
        work = make_work_frame(route, crs, guess_[active], azimuth)
        converged, n_pass = False, 0
        roll = 0.0 if previous is None else previous.roll
        for n_pass in range(1, _MAX_PASSES + 1):
            target = work.to_work(guess_)
            axis_point = target[active].mean(axis=0)
            sim = fit_similarity(
                strip_xyz[active],
                target[active],
                use_xy=use_xy[active],
                use_z=use_z[active],
                sigma_xy=exp_xy[active],
                sigma_z=exp_z[active],
                point_ids=act_ids,
                start=None if last_fit is None else _carried(*last_fit, work),
                served=served,
                max_iterations=options.max_iterations,
            )
            last_fit = (sim.transform, work)
            axis = sim.transform.apply(np.vstack([first, last]))
            step = _azimuth_step(axis[1] - axis[0])
            # Along the strip: to 1e-9 rad, or to 1 % of the azimuth's own
            # standard deviation in the fit (a long strip bent by its chain:
            # the similarity stops at negligible steps, and the remaining
            # turn, halving from pass to pass, is noise, not a frame to turn).
            sigma_azimuth = float(np.sqrt(sim.covariance[6, 6]))
            along = abs(step) <= max(1e-9, 0.01 * sigma_azimuth)
            if not along and n_pass < _MAX_PASSES:
                # Re-express in a frame whose X runs along the strip and start over
                # (the last pass fits the polynomials in the frame it has, and
                # the passes are reported as not converged).
                azimuth += step
                work = make_work_frame(route, crs, guess_[active], azimuth)
                continue
            fitted = sim
            for turns in range(_MAX_TURNS + 1):
                if roll:
                    turned = _turned_about_x(fitted.transform, roll, axis_point)
                    sim = replace(fitted, transform=turned)
                model_xyz = sim.transform.apply(strip_xyz)
                line_objs = [
                    StraightLine(
                        point_ids=tuple(np.asarray(line.point_ids)[keep]),
                        xyz=sim.transform.apply(strip.points[li[keep]]),
                        weight=line.weight,
                        name=line.name,
                    )
                    for line, li, keep in zip(lines, line_index, line_keep, strict=True)
                ]
                deformation, selection = _fit_polynomial(
                    polynomial,
                    options.sections,
                    model_xyz[active],
                    target[active],
                    use_xy[active],
                    use_z[active],
                    exp_xy[active],
                    exp_z[active],
                    line_objs,
                    act_ids,
                )
                if deformation is None:
                    if not roll:
                        break
                    roll, sim = 0.0, fitted  # "auto" chose the similarity alone: its own roll
                    continue
                if turns == _MAX_TURNS:
                    break
                # A long strip bent by its chain leaves the similarity a roll
                # set by the bend, not by the cross-section; the polynomial
                # takes the roll as a shear of Z across the strip, which
                # cannot move the points' Y with their height.  Turn it back
                # into the similarity (and fit the polynomial again) when its
                # effect on the relief matters.
                served_work = sim.transform.apply(served[::_ROLL_SAMPLE_STEP])
                turn = _cross_slope(deformation, served_work)
                relief = float(np.std(deformation.correct(served_work)[:, 2]))
                if abs(turn) * relief <= _ROLL_TOLERANCE * sigma_plan:
                    break
                roll -= float(np.arctan(turn))
            corrected = model_xyz if deformation is None else deformation.correct(model_xyz)
            adjusted = work.from_work(corrected)
            new_guess = given.copy()
            new_guess[~use_z & ~check, 2] = adjusted[~use_z & ~check, 2]
            new_guess[~use_xy & ~check, :2] = adjusted[~use_xy & ~check, :2]
            # The pass's input guess came back unchanged (always so when every
            # control point is full): another pass would repeat this one.
            change = float(np.nanmax(np.abs(new_guess - guess_)))
            guess_ = new_guess
            if change < _PASS_TOLERANCE_M:
                converged = along
                break
            work = make_work_frame(route, crs, guess_[active], azimuth)
        return _Solution(
            work,
            guess_,
            sim,
            deformation,
            selection,
            converged,
            n_pass,
            azimuth,
            metres_per_mm,
            sigma_plan,
            sigma_height,
            active,
            sig_xy_ctrl,
            roll,
        )

    blunders = blunders or BlunderOptions()
    use_xy_now, use_z_now = use_xy.copy(), use_z.copy()
    line_keep = [np.ones(len(li), dtype=bool) for li in line_index]
    rejections: list[Rejection] = []
    kept: list[Rejection] = []
    n_control_obs = int(2 * use_xy.sum() + use_z.sum())
    polynomial = options.polynomial
    sol = solve(use_xy_now, use_z_now, line_keep, None, polynomial)
    while blunders.testing:
        found = [
            r
            for r in _ground_tests(sol, ids, lines, line_keep, blunders)
            if (r.point, r.component) not in {(k.point, k.component) for k in kept}
        ]
        if not found:
            break
        if not blunders.rejecting:
            rejections.extend(found)
            break
        worst = max(found, key=lambda r: abs(r.w) / r.critical)
        trial_xy, trial_z = use_xy_now.copy(), use_z_now.copy()
        trial_lines = [k.copy() for k in line_keep]
        if worst.stage == "control":
            row = ids.index(worst.point)
            (trial_z if worst.component == "height" else trial_xy)[row] = False
        else:
            k = [line.name for line in lines].index(worst.photos[0] if worst.photos else "")
            trial_lines[k][list(lines[k].point_ids).index(worst.point)] = False
        # A rejection must never make the adjustment impossible.  When the
        # control left cannot carry the polynomial, the point is kept and
        # flagged: its test is not to be trusted (an observation the
        # adjustment cannot do without has little redundancy, and the
        # strip's deformation or another point's error shows in it), unless
        # it fails by far (|w| at least _CERTAIN times the critical value):
        # then it goes and the polynomial drops to a type the control left
        # can carry.  Without even the similarity the point is kept.
        trial, lowered = None, polynomial
        kinds = _lower_kinds(polynomial)
        if abs(worst.w) < _CERTAIN * worst.critical:
            kinds = kinds[:1]
        for kind in kinds:
            try:
                trial = solve(trial_xy, trial_z, trial_lines, sol, kind)
            except GeometryError:
                continue
            lowered = kind
            break
        if trial is None:
            what = "polynomial type " + str(polynomial) if polynomial != 0 else "similarity"
            kept.append(
                replace(
                    worst,
                    applied=False,
                    effect=f"kept: without it the control cannot carry the {what}; its error "
                    "cannot be told from the strip's deformation or another point's error: "
                    "check this point",
                )
            )
            continue
        if lowered != polynomial:
            worst = replace(
                worst,
                effect=f"{worst.effect}; polynomial type lowered from {polynomial} to "
                f"{lowered}: the control left cannot carry more",
            )
            polynomial = lowered
        rejections.append(worst)
        use_xy_now, use_z_now, line_keep, sol = trial_xy, trial_z, trial_lines, trial
        rejected_obs = n_control_obs - int(2 * use_xy_now.sum() + use_z_now.sum())
        if rejected_obs > blunders.max_fraction * max(n_control_obs, 1):
            raise GeometryError(
                f"control: more than {blunders.max_fraction:.0%} of the control observations "
                "fail the blunder test; the control cannot be trusted"
            )
    rejections.extend(kept)
    work, guess, sim, deformation, selection = (
        sol.work,
        sol.guess,
        sol.sim,
        sol.deformation,
        sol.selection,
    )
    converged, n_pass, azimuth = sol.converged, sol.n_pass, sol.azimuth
    if not converged:
        warnings.warn(
            f"ground stage: the passes did not settle in {n_pass} (the work frame's azimuth "
            "or the estimated coordinates of plan and height control still changed); the "
            "results are those of the last pass",
            StripAerotriWarning,
            stacklevel=2,
        )
    metres_per_mm, sigma_plan, sigma_height = sol.metres_per_mm, sol.sigma_plan, sol.sigma_height
    misfit = _misfit_message(sim, deformation, options.sections)
    if misfit:
        warnings.warn(misfit, StripAerotriWarning, stacklevel=2)
    use_xy_final, use_z_final = use_xy_now, use_z_now

    # Final products with the last frame and fits.
    transform = sim.transform

    def to_work(xyz: FloatArray) -> FloatArray:
        out = transform.apply(xyz)
        return out if deformation is None else deformation.correct(out)

    # Every point at once: the points not triangulated are NaN rows, which the
    # similarity, the polynomials and the CRS route carry through as NaN, at
    # less cost than gathering the others and scattering them back.
    points_work = to_work(strip.points)
    not_triangulated = ~strip.triangulated
    if not_triangulated.any():
        points_work[not_triangulated] = np.nan

    centres_model = transform.apply(strip.centres)
    centres_work = to_work(strip.centres)
    rot_work = transform.apply_to_rotation(strip.rotations)
    if deformation is not None:
        rot_work = _deformation_rotation(deformation, centres_model) @ rot_work
    points_work = intersect_unmodelled(strip, points_work, centres_work, rot_work)
    points = work.from_work(points_work)
    centres = work.from_work(centres_work)
    rot_enu = work.rotations_to_enu(rot_work, centres)
    opk = opk_from_matrix(rot_enu)

    # Residuals (given minus adjusted) along east, north, up; checks compared in full.
    given_work = work.to_work(np.where(np.isnan(given), guess, given))
    diff = work.enu_from_work(given_work - points_work[idx])
    resid = diff.copy()
    resid[~(use_xy | check), :2] = np.nan
    resid[~(use_z | check), 2] = np.nan
    resid[np.isnan(given)] = np.nan
    # Rejected control keeps its (large) residual; used_xy/used_h say what was used.

    if deformation is not None and lines:
        # Every line point (rejected ones too) against its fitted line.
        line_resid = tuple(
            points_work[li, 1] - (ab[0] + ab[1] * points_work[li, 0])
            for li, ab in zip(line_index, deformation.line_parameters, strict=True)
        )
    else:
        line_resid = tuple(_line_residuals(points_work[li]) for li in line_index)

    final_fit = sim if deformation is None else deformation
    act = sol.active
    red_act = np.asarray(final_fit.redundancy_numbers, dtype=np.float64)
    sigma_act = np.column_stack([exp_xy, exp_xy, exp_z])[act]
    red, mde = control_detectability(red_act, sigma_act, blunders, int(np.isfinite(red_act).sum()))
    control_red = np.full((rows.shape[0], 3), np.nan)
    control_mde = np.full((rows.shape[0], 3), np.nan)
    control_red[act], control_mde[act] = red, mde
    return GroundResult(
        route=route,
        crs=crs,
        azimuth=float(azimuth),
        frame=work.frame,
        similarity=sim,
        deformation=deformation,
        kind_selection=selection,
        points_work=points_work,
        points=points,
        photo_centres_work=centres_work,
        photo_centres=centres,
        photo_rotations_work=rot_work,
        photo_rotations_enu=rot_enu,
        photo_opk=opk,
        control_index=rows,
        control_residuals=resid,
        is_check=check,
        line_names=tuple(line.name for line in lines),
        line_point_index=tuple(line_index),
        line_residuals=line_resid,
        left_out=left_out,
        passes=n_pass,
        passes_converged=converged,
        image_scale=metres_per_mm,
        expected_sigma_plan=sigma_plan,
        expected_sigma_height=sigma_height,
        used_xy=use_xy_final & ~check,
        used_h=use_z_final & ~check,
        line_used=tuple(k.copy() for k in line_keep),
        rejections=tuple(rejections),
        control_redundancy=control_red,
        control_mde=control_mde,
    )


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
    missing = ~np.isfinite(points_work).all(axis=1)
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


def _lower_kinds(kind: int | str) -> list[int | str]:
    """The polynomial type asked for, then every lower type down to the
    similarity alone ("auto" chooses by itself)."""
    if kind == "auto":
        return ["auto"]
    return list(range(int(kind), -1, -1))


def _line_residuals(xyz: FloatArray) -> FloatArray:
    """Y residuals of points about their own best straight line Y = a + b X."""
    design = np.column_stack([np.ones(len(xyz)), xyz[:, 0]])
    coef, *_ = np.linalg.lstsq(design, xyz[:, 1], rcond=None)
    return xyz[:, 1] - design @ coef


def _misfit_message(
    sim: SimilarityResult, deformation: DeformationResult | None, sections: int
) -> str | None:
    """The warning when the last ground fit leaves the control more than
    ``_MISFIT_SIGMA0`` times its expected error, else None."""
    fit = sim if deformation is None else deformation
    if not (np.isfinite(fit.sigma0) and fit.sigma0 > _MISFIT_SIGMA0):
        return None
    if deformation is None:
        what = "the similarity transformation alone"
        advice = (
            "use a deformation polynomial ([adjustment] polynomial), over sections for a "
            "long strip"
        )
    elif sections == 1:
        what = f"polynomial type {deformation.kind}"
        advice = (
            "use [adjustment] sections (about one per 6-20 models, two control stations "
            "each; docs/ground.md, Long strips)"
        )
    else:
        what = f"polynomial type {deformation.kind} over {sections} sections"
        advice = "use more sections"
    return (
        f"ground stage: {what} leaves the control {fit.sigma0:.0f} times its expected "
        "error (sigma0): the strip bends more than it can follow, or the control has "
        f"errors; {advice}, and check the control"
    )


def _fit_polynomial(kind, sections, xyz, target, use_xy, use_z, exp_xy, exp_z, lines, ids):
    if kind == "auto":
        selection = select_kind_auto(
            xyz,
            target,
            use_xy=use_xy,
            use_z=use_z,
            expected_sigma_xy=exp_xy,
            expected_sigma_z=exp_z,
            lines=lines,
            point_ids=ids,
            sections=sections,
        )
        kind = selection.kind
    else:
        selection = None
    if kind == 0 and not lines:
        return None, selection
    return (
        fit_deformation(
            xyz,
            target,
            use_xy=use_xy,
            use_z=use_z,
            kind=kind,
            sigma_xy=exp_xy,
            sigma_z=exp_z,
            lines=lines,
            point_ids=ids,
            sections=sections if kind > 0 else 1,
        ),
        selection,
    )


class _Solution(NamedTuple):
    work: Any
    guess: FloatArray
    sim: SimilarityResult
    deformation: DeformationResult | None
    selection: KindSelection | None
    converged: bool
    n_pass: int
    azimuth: float
    metres_per_mm: float
    sigma_plan: float
    sigma_height: float
    active: np.ndarray
    control_sigma_xy: FloatArray
    roll: float


def _ground_tests(sol: _Solution, ids, lines, line_keep, blunders) -> list[Rejection]:
    """w-tests of the control deviations and line points of a solution.

    The normalised residuals of the last fit (polynomial if any, else the
    similarity) are tested; sigmas combine the control's and the expected
    photogrammetric error.  Returns every observation above its critical value.
    """
    act_ids = [p for p, a in zip(ids, sol.active, strict=True) if a]
    found: list[Rejection] = []
    # J tested twice: the control deviations after the similarity transformation
    # (high redundancy; the strip's deformation is part of the residuals and
    # is absorbed by the robust variance factor) and the residual deviations
    # after the polynomial fit.
    # With a polynomial only its residuals are tested: the similarity's
    # residuals contain the strip's bend, which is not a blunder.
    fits = (
        [("similarity", sol.sim)] if sol.deformation is None else [("polynomial", sol.deformation)]
    )
    seen: set[tuple[str, str]] = set()
    for label, fit in fits:
        w = np.asarray(fit.normalized_residuals, dtype=float)
        # The expected sigmas leave out the error the chain accumulates along
        # the strip; the robust variance factor scales them to the data
        # (blunders hardly move the median).
        w = w / np.sqrt(robust_variance_factor(w))
        resid = np.asarray(fit.residuals, dtype=float)
        crit = blunders.critical("control", int(np.isfinite(w).sum()))
        plan_w = np.fmax(np.abs(w[:, 0]), np.abs(w[:, 1]))
        plan_r = np.hypot(np.nan_to_num(resid[:, 0]), np.nan_to_num(resid[:, 1]))
        height_w = np.abs(w[:, 2])
        with np.errstate(invalid="ignore"):
            failing = np.flatnonzero((plan_w > crit) | (height_w > crit))  # NaN: not tested
        for k in failing:
            pid = act_ids[k]
            for comp, value, res in (
                ("plan", plan_w[k], float(plan_r[k])),
                ("height", height_w[k], float(resid[k, 2])),
            ):
                if np.isfinite(value) and value > crit and (pid, comp) not in seen:
                    seen.add((pid, comp))
                    found.append(
                        Rejection(
                            stage="control",
                            point=pid,
                            photos=(),
                            component=comp,
                            residual=res,
                            unit="m",
                            w=float(value),
                            critical=crit,
                            applied=blunders.rejecting,
                            effect=f"after the {label}, sigma0 {fit.sigma0:.3g} before",
                        )
                    )
    if sol.deformation is not None and lines:
        # The fit gives a line equation the sigma of plan control / sqrt(weight): a
        # device that makes the condition effective, not a precision.  A line
        # point's real cross-strip error is photogrammetric, so its w-test is
        # rescaled to that sigma.
        plan_sig = np.hypot(np.median(sol.control_sigma_xy[sol.active]), sol.sigma_plan)
        line_w = tuple(
            np.asarray(wk) * (plan_sig / np.sqrt(line.weight)) / sol.sigma_plan
            for wk, line in zip(sol.deformation.line_normalized_residuals, lines, strict=True)
        )
        line_r = sol.deformation.line_residuals
        n_line = int(sum(np.isfinite(np.asarray(x)).sum() for x in line_w))
        crit_l = blunders.critical("straight_line", n_line)
        for line, keep, wk, rk in zip(lines, line_keep, line_w, line_r, strict=True):
            kept_ids = np.asarray(line.point_ids)[keep]
            for pid, value, res in zip(kept_ids, np.abs(np.asarray(wk)), rk, strict=True):
                if np.isfinite(value) and value > crit_l:
                    found.append(
                        Rejection(
                            stage="straight_line",
                            point=str(pid),
                            photos=(line.name,),
                            component="line",
                            residual=float(res),
                            unit="m",
                            w=float(value),
                            critical=crit_l,
                            applied=blunders.rejecting,
                            effect=f"line {line.name!r}",
                        )
                    )
    return found
