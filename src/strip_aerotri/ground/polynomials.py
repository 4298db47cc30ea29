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
from collections.abc import Sequence
from dataclasses import replace
from typing import Literal, NamedTuple, TypedDict

import numpy as np

from .._stats import exact_median
from .._threads import limit_blas_threads
from .._typing import BoolArray, FloatArray, IntArray
from ..blunders import robust_variance_factor
from ..errors import GeometryError, HeightUnitError, StripAerotriWarning
from ..frames import WorkFrame, make_work_frame
from ..geodesy import GroundCRS
from ..geometry.deformation import DeformationResult
from ..geometry.rotation import opk_from_matrix
from ..geometry.similarity import SimilarityResult
from ..observations import ControlPoints, LineSpec
from ..options import BlunderAction, BlunderOptions, Construction, GroundOptions, Route
from ..results import GroundResult, Rejection, StripModel
from .common import (
    ControlRows,
    control_detectability,
    control_rows,
    deformation_rotation,
    image_scale,
    intersect_unmodelled,
    line_indices,
    line_residuals,
    resolve_route,
)
from .height_units import height_unit_problems
from .passes import _PASS_TOLERANCE_M, Solution, StripProblem, _plan_scale, solve_passes
from .systematic import kept_control, kept_if_alike, rejected_components

__all__ = [
    "Construction",
    "GroundOptions",
    "GroundResult",
    "LineSpec",
    "Route",
    "adjust_to_ground",
    "control_detectability",
    "height_unit_check",
    "intersect_unmodelled",
    "similarity_start",
]

#: sigma0 of the last ground fit above which its misfit is warned about (the
#: test suite's strips reach 26 with blunders left in; one cubic over 300
#: photos of bench_strip's strip 40, over 1000 photos 65-490).
_MISFIT_SIGMA0 = 30.0
_SERVED_SAMPLE = 8192  # strip points for the similarity's test of the cross tilt
#: A control observation whose rejection the polynomial cannot afford goes
#: only when its |w| is at least this many times the critical value.
_CERTAIN = 3.0
#: Metres the guessed control coordinates of :func:`similarity_start` may
#: still move when its passes end: it is only the start of the models,
#: whose own passes carry the guesses on and whose first step moves the
#: models by up to a metre.  A 1000-photo strip: 4 passes instead of the 8
#: of 1e-5 m (the passes converge linearly, by a seventh each), 28-31 ->
#: 17-18 ms, the models' solution the same to 1e-9 m.
_START_PASS_TOLERANCE_M = 1e-2


def served_points(strip: StripModel) -> FloatArray:
    """The points the similarity serves, for its rule on height control
    nearly in one vertical plane (the point farthest from that plane counts):
    an evenly spaced sample of the strip's triangulated points, which reaches
    the strip's edges in every few models (strip frame, shape (S, 3))."""
    served = strip.points[:: max(1, -(-strip.points.shape[0] // _SERVED_SAMPLE))]
    return served[np.isfinite(served).all(axis=1)]


@limit_blas_threads
def adjust_to_ground(
    strip: StripModel,
    control: ControlPoints,
    crs: GroundCRS | str,
    *,
    lines: Sequence[LineSpec] = (),
    options: GroundOptions | None = None,
    blunders: BlunderOptions | None = None,
    control_name: str = "control",
) -> GroundResult:
    """Orient the strip model on the control and deliver it in the control CRS.

    Parameters
    ----------
    strip : StripModel
        The strip model from :func:`strip_aerotri.strip.chaining.form_strip`.
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
    control_name : str
        How messages name the control (its file in a project).

    Returns
    -------
    GroundResult

    Raises
    ------
    GeometryError
        Insufficient or degenerate control (the rule and the points named),
        too few points for the polynomial type, line points not triangulated,
        control heights in another unit than the plan control
        (:func:`strip_aerotri.ground.height_units.height_unit_problems`).
    """
    return _adjusted(
        strip, control, crs, tuple(lines), options, blunders, all_points=True, name=control_name
    )


@limit_blas_threads
def similarity_start(
    strip: StripModel,
    control: ControlPoints,
    crs: GroundCRS,
    *,
    route: Route | None,
    max_iterations: int,
    control_name: str = "control",
) -> GroundResult:
    """J's similarity of the whole strip, untested, as the start of the
    models' ground stage (:mod:`strip_aerotri.ground.models`): the work
    frame, the start values and the checks of the control's geometry.

    :func:`adjust_to_ground` with ``polynomial=0`` and the blunder tests off,
    except that its ``points`` are taken to the CRS at the control points
    only (NaN elsewhere: the models' stage replaces them all; the inverse
    projection of every point of a 1000-photo strip costs 15-30 ms), and
    the points no model determined (seen only on photos between the model
    photos) are left NaN instead of intersected from their rays: the models'
    stage has no row on them (control and line points are triangulated
    points) and intersects them itself at the end; and its passes end at
    :data:`_START_PASS_TOLERANCE_M`.
    """
    options = GroundOptions(route=route, polynomial=0, max_iterations=max_iterations)
    blunders = BlunderOptions(action=BlunderAction.OFF)
    return _adjusted(
        strip, control, crs, (), options, blunders, all_points=False, name=control_name,
        pass_tolerance_m=_START_PASS_TOLERANCE_M,
    )  # fmt: skip


def _adjusted(
    strip: StripModel,
    control: ControlPoints,
    crs: GroundCRS | str,
    lines: tuple[LineSpec, ...],
    options: GroundOptions | None,
    blunders: BlunderOptions | None,
    *,
    all_points: bool,
    name: str = "control",
    pass_tolerance_m: float = _PASS_TOLERANCE_M,
) -> GroundResult:
    """:func:`adjust_to_ground`; with ``all_points`` False its ``points`` in
    the CRS at the control points only; ``name`` the control in messages;
    ``pass_tolerance_m`` (metres) that of the passes (default the stage's own)."""
    options = options or GroundOptions()
    blunders = blunders or BlunderOptions()
    if not isinstance(crs, GroundCRS):
        crs = GroundCRS.from_user_input(crs)
    route = resolve_route(options.route, crs)
    picked = control_rows(strip, control)
    problem = _prepare(strip, picked, crs, route, tuple(lines), options, name, pass_tolerance_m)
    sol, use_xy, use_z, line_keep, rejections = _snoop(problem, picked, blunders, options)
    if not sol.converged:
        warnings.warn(
            f"ground stage: the passes did not settle in {sol.n_pass} (the work frame's azimuth "
            "or the estimated coordinates of plan and height control still changed); the "
            "results are those of the last pass",
            StripAerotriWarning,
            stacklevel=2,
        )
    misfit = _misfit_message(sol.sim, sol.deformation, options.sections)
    if misfit:
        warnings.warn(misfit, StripAerotriWarning, stacklevel=2)
    return _products(
        problem, picked, sol, use_xy, use_z, line_keep, rejections, blunders, all_points
    )


def _prepare(
    strip: StripModel,
    picked: ControlRows,
    crs: GroundCRS,
    route: Route,
    lines: tuple[LineSpec, ...],
    options: GroundOptions,
    name: str = "control",
    pass_tolerance_m: float = _PASS_TOLERANCE_M,
) -> StripProblem:
    """The fixed data of the passes: start values of what the control does
    not give, and the expected errors that weight it.

    The strip scaled to the plan control meets the control heights here
    first: heights in another unit than the plan stop (``name`` the control
    in the message; :func:`strip_aerotri.ground.height_units.height_unit_problems`);
    the passes end when the guessed control coordinates move by less than
    ``pass_tolerance_m`` (metres).
    """
    line_index = line_indices(strip, lines)
    first = _first_look(strip, picked, crs, route)
    units = _unit_problems(first, picked, name)
    if units:
        raise HeightUnitError(name, units[0].removeprefix(f"{name}: "))
    given, guess, strip_xyz = picked.given, first.guess, first.strip_xyz
    metres_per_mm, sigma_plan = first.metres_per_mm, first.sigma_plan
    sigma_height, exp_z = first.sigma_height, first.exp_z

    served = served_points(strip)
    return StripProblem(
        strip=strip,
        crs=crs,
        route=route,
        lines=lines,
        line_index=line_index,
        ids=picked.ids,
        given=given,
        guess=guess,
        check=picked.check,
        strip_xyz=strip_xyz,
        exp_xy=first.exp_xy,
        exp_z=exp_z,
        control_sigma_xy=picked.sigma_xy,
        metres_per_mm=metres_per_mm,
        sigma_plan=sigma_plan,
        sigma_height=sigma_height,
        served=served,
        sections=options.sections,
        max_iterations=options.max_iterations,
        pass_tolerance_m=pass_tolerance_m,
    )


class _FirstLook(NamedTuple):
    """The strip scaled to the plan control, before any fit (per control row
    C: ``guess``, ``target`` work frame, ``strip_xyz``; ``exp_xy``,
    ``exp_z`` the expected errors of the control's plan coordinates and
    heights, their own and the photogrammetric ones, metres)."""

    guess: FloatArray
    target: FloatArray
    strip_xyz: FloatArray
    metres_per_model: float
    metres_per_mm: float
    sigma_plan: float
    sigma_height: float
    exp_xy: FloatArray
    exp_z: FloatArray


def _first_look(
    strip: StripModel, picked: ControlRows, crs: GroundCRS, route: Route
) -> _FirstLook:
    """Start values of what the control does not give, the image scale from
    the plan control and the expected errors of the passes."""
    given, use_xy, use_z = picked.given, picked.use_xy, picked.use_z
    active = use_xy | use_z
    strip_xyz = strip.points[picked.index]
    # Start values: plan points at the mean known height, height points at
    # the centroid of the known plan positions.
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
    guess[picked.check] = given[picked.check]

    model_per_mm, h_to_b = image_scale(strip)
    # The expected photogrammetric sigmas weight the control with one first
    # estimate of the image scale (control spread in plan, work frame over
    # strip), the same in every fit: a fit repeated in a frame turned only in
    # azimuth is then the same fit turned, so the azimuth pass is not repeated.
    target = make_work_frame(route, crs, guess[active], 0.0).to_work(guess)
    metres_per_model = _plan_scale(strip_xyz[use_xy], target[use_xy])
    metres_per_mm = model_per_mm * metres_per_model
    sigma_plan = exact_median(strip.observations.sigma) * metres_per_mm
    sigma_height = sigma_plan * h_to_b
    return _FirstLook(
        guess=guess,
        target=target,
        strip_xyz=strip_xyz,
        metres_per_model=metres_per_model,
        metres_per_mm=metres_per_mm,
        sigma_plan=sigma_plan,
        sigma_height=sigma_height,
        exp_xy=np.hypot(picked.sigma_xy, sigma_plan),
        exp_z=np.hypot(picked.sigma_h, sigma_height),
    )


class _UnitInputs(TypedDict):
    """The arguments of
    :func:`strip_aerotri.ground.height_units.height_unit_problems` but
    ``file``."""

    model_xyz: FloatArray
    height: FloatArray
    sigma: FloatArray
    plan: tuple[FloatArray, FloatArray, FloatArray]
    given: tuple[FloatArray, FloatArray, float]


def _unit_inputs(first: _FirstLook, picked: ControlRows) -> _UnitInputs:
    """What the test of the control heights' unit reads of the strip scaled
    to the plan control: the height control in it (``model_xyz`` (n, 3),
    the work frame's ``height`` (n,) and ``sigma`` (n,)), the plan control
    (``plan``: model points (p, 3), work frame X, Y (p, 2), expected errors
    (p,)) and the heights as given (``given``: (n,), their own errors (n,),
    the model heights' expected error)."""
    z, xy = picked.use_z, picked.use_xy
    scaled = first.strip_xyz * first.metres_per_model
    return _UnitInputs(
        model_xyz=scaled[z],
        height=first.target[z, 2],
        sigma=first.exp_z[z],
        plan=(scaled[xy], first.target[xy, :2], first.exp_xy[xy]),
        given=(picked.given[z, 2], picked.sigma_h[z], first.sigma_height),
    )


def _unit_problems(first: _FirstLook, picked: ControlRows, name: str) -> list[str]:
    """Control heights in another unit than the plan control: the gradients
    of the height and plan control over the strip, scaled to the plan
    control, or the heights against the strip's
    (:func:`strip_aerotri.ground.height_units.height_unit_problems`)."""
    return height_unit_problems(**_unit_inputs(first, picked), file=name)


def height_unit_check(
    strip: StripModel,
    control: ControlPoints,
    crs: GroundCRS | str,
    route: Route | None = None,
    control_name: str = "control",
) -> list[str]:
    """The ground stage's test of the control heights' unit on a formed
    strip, without the ground stage (``stripaero check``): one message when
    the heights are in another unit than the plan control, else none (also
    when the control is too scant for the similarity: its own rules say so).
    """
    if not isinstance(crs, GroundCRS):
        crs = GroundCRS.from_user_input(crs)
    picked = control_rows(strip, control)
    try:
        first = _first_look(strip, picked, crs, resolve_route(route, crs))
    except GeometryError:
        return []
    return _unit_problems(first, picked, control_name)


def _snoop(
    problem: StripProblem,
    picked: ControlRows,
    blunders: BlunderOptions,
    options: GroundOptions,
) -> tuple[Solution, BoolArray, BoolArray, list[BoolArray], list[Rejection]]:
    """The passes, then data snooping: the worst failing control or line
    observation out and solve again, until none fails.

    A rejection must never make the adjustment impossible.  When the control
    left cannot carry the polynomial, the point is kept and flagged: its test
    is not to be trusted (an observation the adjustment cannot do without has
    little redundancy, and the strip's deformation or another point's error
    shows in it), unless it fails by far (|w| at least ``_CERTAIN`` times the
    critical value): then it goes and the polynomial drops to a type the
    control left can carry.  Without even the similarity the point is kept.

    Returns the last solution, the control coordinates and line points used,
    and the rejections (the kept and flagged ones last).
    """
    lines, ids = problem.lines, problem.ids
    use_xy, use_z = picked.use_xy.copy(), picked.use_z.copy()
    line_keep = [np.ones(len(li), dtype=bool) for li in problem.line_index]
    rejections: list[Rejection] = []
    kept: list[Rejection] = []
    n_control_obs = int(2 * use_xy.sum() + use_z.sum())
    polynomial = options.polynomial
    assert polynomial is not None  # GroundOptions puts the default for None
    sol = solve_passes(problem, use_xy, use_z, line_keep, None, polynomial)
    first, control_kept = sol, False
    while blunders.testing:
        flagged = {(k.point, k.component) for k in kept}
        found = [
            r
            for r in _ground_tests(sol, ids, lines, line_keep, blunders)
            if (r.point, r.component) not in flagged
            and not (control_kept and r.stage == "control")
        ]
        if not found:
            break
        if not blunders.rejecting:
            rejections.extend(found)
            break
        worst = max(found, key=lambda r: abs(r.w) / r.critical)
        trial_xy, trial_z = use_xy.copy(), use_z.copy()
        trial_lines = [k.copy() for k in line_keep]
        if worst.stage == "control":
            row = ids.index(worst.point)
            (trial_z if worst.component == "height" else trial_xy)[row] = False
        else:
            k = [line.name for line in lines].index(worst.photos[0] if worst.photos else "")
            trial_lines[k][list(lines[k].point_ids).index(worst.point)] = False
        trial, lowered = None, polynomial
        kinds = _lower_kinds(polynomial)
        if abs(worst.w) < _CERTAIN * worst.critical:
            kinds = kinds[:1]
        for kind in kinds:
            try:
                trial = solve_passes(problem, trial_xy, trial_z, trial_lines, sol, kind)
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
        last = sol
        use_xy, use_z, line_keep, sol = trial_xy, trial_z, trial_lines, trial
        rejected_obs = n_control_obs - int(2 * use_xy.sum() + use_z.sum())
        if rejected_obs > blunders.max_fraction * max(n_control_obs, 1):
            if not _keep_systematic(ids, first, last, rejections, blunders):
                raise GeometryError(
                    f"control: more than {blunders.max_fraction:.0%} of the control "
                    "observations fail the blunder test; the control cannot be trusted"
                )
            # failing alike: the camera, not the control; all of it kept, untested
            use_xy, use_z, control_kept = picked.use_xy.copy(), picked.use_z.copy(), True
            rejections = kept_control(rejections)
            sol = solve_passes(problem, use_xy, use_z, line_keep, sol, polynomial)
    return sol, use_xy, use_z, line_keep, rejections + kept


def _keep_systematic(
    ids: Sequence[str],
    first: Solution,
    last: Solution,
    rejections: Sequence[Rejection],
    blunders: BlunderOptions,
) -> bool:
    """True (and a warning) when the control fails at many points alike
    (:func:`strip_aerotri.ground.systematic.fails_alike`): on the first
    solution's test values, or on every one met so far (``last``'s, each
    rejected component at the value it was rejected with)."""
    w_first, critical = _control_test_values(first, len(ids), blunders)
    w_last, _ = _control_test_values(last, len(ids), blunders)
    rows = np.flatnonzero(np.any(np.isfinite(w_first), axis=1))
    position = {ids[int(k)]: j for j, k in enumerate(rows)}
    rejected = rejected_components(rejections, position)
    return kept_if_alike("control", w_first[rows], critical, last=w_last[rows], rejected=rejected)


def _control_test_values(
    sol: Solution, n_ids: int, blunders: BlunderOptions
) -> tuple[FloatArray, float]:
    """The control's test values of a solution (n_ids, 3; NaN where not
    tested), as :func:`_ground_tests` computes them, and their critical value."""
    fit = sol.sim if sol.deformation is None else sol.deformation
    w, crit = _scaled_w(fit, blunders)
    out = np.full((n_ids, 3), np.nan)
    out[np.flatnonzero(sol.active)] = w
    return out, crit


def _scaled_w(
    fit: SimilarityResult | DeformationResult, blunders: BlunderOptions
) -> tuple[FloatArray, float]:
    """A fit's normalised control residuals scaled by their robust variance
    factor, and the critical value of their count."""
    w = np.asarray(fit.normalized_residuals, dtype=float)
    # The expected sigmas leave out the error the chain accumulates along
    # the strip; the robust variance factor scales them to the data
    # (blunders hardly move the median).
    w = w / np.sqrt(robust_variance_factor(w))
    return w, blunders.critical("control", int(np.isfinite(w).sum()))


def _products(
    problem: StripProblem,
    picked: ControlRows,
    sol: Solution,
    use_xy: BoolArray,
    use_z: BoolArray,
    line_keep: list[BoolArray],
    rejections: list[Rejection],
    blunders: BlunderOptions,
    all_points: bool = True,
) -> GroundResult:
    """Every point and photo through the last solution, to the CRS (the
    points at the control only, and those no model determined not
    intersected, unless ``all_points``), with the control's residuals and
    detectability."""
    strip, work, sim, deformation = problem.strip, sol.work, sol.sim, sol.deformation
    transform = sim.transform
    lines, line_index, check = problem.lines, problem.line_index, picked.check

    def to_work(xyz: FloatArray) -> FloatArray:
        out = transform.apply(xyz)
        return out if deformation is None else deformation.correct(out)

    # Every point at once: the points not triangulated are NaN rows, which the
    # similarity, the polynomials and the CRS route carry through as NaN, at
    # less cost than gathering the others and scattering them back.
    points_work = to_work(strip.points)
    points_work[~strip.triangulated] = np.nan
    centres_model = transform.apply(strip.centres)
    centres_work = to_work(strip.centres)
    rot_work = transform.apply_to_rotation(strip.rotations)
    if deformation is not None:
        rot_work = deformation_rotation(deformation, centres_model) @ rot_work
    if all_points:  # the models' stage starts from the triangulated points only
        points_work = intersect_unmodelled(strip, points_work, centres_work, rot_work)
    centres = work.from_work(centres_work)
    rot_enu = work.rotations_to_enu(rot_work, centres)

    # Residuals (given minus adjusted) along east, north, up; checks compared
    # in full; rejected control keeps its (large) residual, used_xy / used_h
    # say what was used.
    given = picked.given
    given_work = work.to_work(np.where(np.isnan(given), sol.guess, given))
    resid = work.enu_from_work(given_work - points_work[picked.index])
    resid[~(picked.use_xy | check), :2] = np.nan
    resid[~(picked.use_z | check), 2] = np.nan
    resid[np.isnan(given)] = np.nan

    if deformation is not None and lines:
        # Every line point (rejected ones too) against its fitted line.
        line_resid = tuple(
            points_work[li, 1] - (ab[0] + ab[1] * points_work[li, 0])
            for li, ab in zip(line_index, deformation.line_parameters, strict=True)
        )
    else:
        line_resid = tuple(line_residuals(points_work[li]) for li in line_index)

    final_fit = sim if deformation is None else deformation
    act = sol.active
    red_act = np.asarray(final_fit.redundancy_numbers, dtype=np.float64)
    sigma_act = np.column_stack([problem.exp_xy, problem.exp_xy, problem.exp_z])[act]
    red, mde = control_detectability(red_act, sigma_act, blunders, int(np.isfinite(red_act).sum()))
    control_red = np.full((picked.rows.shape[0], 3), np.nan)
    control_mde = np.full((picked.rows.shape[0], 3), np.nan)
    control_red[act], control_mde[act] = red, mde
    return GroundResult(
        route=problem.route,
        crs=problem.crs,
        azimuth=float(sol.azimuth),
        frame=work.frame,
        similarity=sim,
        deformation=deformation,
        kind_selection=sol.selection,
        points_work=points_work,
        points=_to_crs(work, points_work, None if all_points else picked.index),
        photo_centres_work=centres_work,
        photo_centres=centres,
        photo_rotations_work=rot_work,
        photo_rotations_enu=rot_enu,
        photo_opk=opk_from_matrix(rot_enu),
        control_index=picked.rows,
        control_residuals=resid,
        is_check=check,
        line_names=tuple(line.name for line in lines),
        line_point_index=tuple(line_index),
        line_residuals=line_resid,
        left_out=picked.left_out,
        passes=sol.n_pass,
        passes_converged=sol.converged,
        image_scale=sol.metres_per_mm,
        expected_sigma_plan=sol.sigma_plan,
        expected_sigma_height=sol.sigma_height,
        used_xy=use_xy & ~check,
        used_h=use_z & ~check,
        line_used=tuple(k.copy() for k in line_keep),
        rejections=tuple(rejections),
        control_redundancy=control_red,
        control_mde=control_mde,
    )


def _to_crs(work: WorkFrame, points_work: FloatArray, rows: IntArray | None) -> FloatArray:
    """``points_work`` in the CRS: all of them, or only ``rows`` (NaN elsewhere)."""
    if rows is None:
        return work.from_work(points_work)
    points = np.full(points_work.shape, np.nan)
    if rows.size:
        points[rows] = work.from_work(points_work[rows])
    return points


def _lower_kinds(kind: int | Literal["auto"]) -> list[int | Literal["auto"]]:
    """The polynomial type asked for, then every lower type down to the
    similarity alone ("auto" chooses by itself)."""
    if kind == "auto":
        return ["auto"]
    return list(range(int(kind), -1, -1))


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


def _ground_tests(
    sol: Solution,
    ids: tuple[str, ...],
    lines: Sequence[LineSpec],
    line_keep: list[BoolArray],
    blunders: BlunderOptions,
) -> list[Rejection]:
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
        w, crit = _scaled_w(fit, blunders)
        resid = np.asarray(fit.residuals, dtype=float)
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
