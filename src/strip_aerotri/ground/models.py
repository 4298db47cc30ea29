"""The strip to the ground model by model: every model its own similarity.

R4 §3's construction for one strip (method.md §6A, "block by independent
models"; PAT-M): the models of the chain are transformed at once, each by
its own 3D similarity, onto the control and onto each other on the points
they share (the tie points of the triple overlaps, every point seen in two
or more models) and on the projection centres (each shared by two
consecutive models).  The chain's accumulated errors of scale and rotation,
which J's polynomials can follow only as far as a cubic bends, are taken out
model by model, with the weight the tie points give them.

Every determination of a point in a model is weighted by its information
from its two rays (:func:`strip_aerotri.geometry.precision.ray_information`, photos
held fixed: a model point is weak along the rays, above all in height at a
short base), every projection centre by its information from a space
resection on the model's points (:func:`strip_aerotri.geometry.precision.centre_information`).
The control enters with its own sigmas, straight lines (J(18)) as
conditions on the adjusted points.  The solution is
:func:`strip_aerotri.geometry.simultaneous.adjust_units` in the ground stage's work
frame (docs/ground.md); J's similarity (:func:`strip_aerotri.ground.polynomials.adjust_to_ground`
with polynomial 0) gives the frame, the start values and the checks of the
control's geometry.

Gross errors are tested here too: the control by Baarda's w with exact
redundancy numbers (one rejection at a time, never one that would leave the
control unable to carry the strip: such a point is kept and flagged), the
determinations of a point in a model by their 3-D residual (stage
``models``), and the line points.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from itertools import pairwise
from typing import NamedTuple

import numpy as np

from .._stats import leading_failures
from .._typing import BoolArray, FloatArray, IntArray
from ..errors import ConvergenceError, GeometryError, StripAerotriWarning
from ..frames import WorkFrame, make_work_frame
from ..geodesy import GroundCRS
from ..geometry.grouped_start import grouped_start, groups_along
from ..geometry.precision import rays_information
from ..geometry.rotation import opk_from_matrix
from ..geometry.similarity import SimilarityTransform, _validate_control_geometry
from ..geometry.simultaneous import (
    LineCondition,
    SimultaneousResult,
    UnitObservations,
    UnitTransforms,
    adjust_units,
)
from ..observations import ControlPoints, LineSpec
from ..options import BlunderOptions, GroundOptions
from ..results import GroundResult, ModelAdjustment, Rejection, StripModel
from .common import control_detectability, index_of, intersect_unmodelled
from .control_passes import ControlPasses
from .polynomials import similarity_start
from .systematic import kept_control, kept_if_alike, rejected_components

__all__ = ["ModelAdjustment", "adjust_models_to_ground", "model_weights"]

_MAX_PASSES = 8
_CHI2_3_MEDIAN = 2.365973884375338  # median of chi-square with 3 degrees of freedom
#: Models taken together for the start of a long strip (the chain's drift
#: over so many models is far below what Gauss-Newton takes in one step).
_GROUP_MODELS = 16
#: A strip of at least so many groups starts from the groups' adjustment;
#: a shorter one from J's similarity.
_GROUPS_FROM = 4


def model_weights(
    strip: StripModel, start_transform: SimilarityTransform, sigma_fallback: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Work-frame information matrices of the determinations (n, 3, 3) and of
    the left and right centre of each model (M, 3, 3) each."""
    obs = strip.observations
    c = obs.principal_distance
    pos = strip.model_photo_positions
    m = strip.model
    left, right = pos[m], pos[m + 1]
    rot = start_transform.apply_to_rotation(strip.rotations)
    centres = start_transform.apply(strip.centres)
    points = start_transform.apply(strip.model_points)
    if strip.model_rows is not None:
        sig_l = obs.sigma[strip.model_rows[:, 0]]
        sig_r = obs.sigma[strip.model_rows[:, 1]]
    else:
        sig_l = sig_r = np.full(m.shape[0], sigma_fallback)
    n_models = strip.n_models
    info, c_left = rays_information(points, left, centres, rot, c, sig_l, m, n_models)
    info_right, c_right = rays_information(points, right, centres, rot, c, sig_r, m, n_models)
    info += info_right
    # A model whose points cannot fix a centre (too few, degenerate): the
    # centre gets the weight of one of the model's points, isotropic.
    typical = np.median(np.einsum("nii->n", info)) / 3.0
    for block in (c_left, c_right):
        bad = ~np.isfinite(block).all(axis=(1, 2))
        block[bad] = typical * np.eye(3)
    return info, c_left, c_right


@dataclass(frozen=True, eq=False)
class _ModelsProblem:
    """What every solution of the simultaneous transformation needs, fixed
    for the stage.  Control arrays per usable control row (C); the rows of
    the adjustment are the determinations of the points in the models (n_det
    of them), then the left and the right projection centre of each model."""

    strip: StripModel
    start: GroundResult  # J's similarity: frame, start values, checks
    work: WorkFrame
    ids: tuple[str, ...]
    idx: IntArray  # strip point of each control row
    given: FloatArray  # (C, 3) as given, NaN where not
    guess: FloatArray  # (C, 3) with the similarity's values where not given
    use_xy: BoolArray
    use_z: BoolArray
    sigma: FloatArray  # (C, 3) the control's own sigmas
    lines: tuple[LineSpec, ...]
    line_index: list[IntArray]
    plan_sigma: float  # control and photogrammetric plan error: the lines' unit
    rows: UnitObservations  # every row of the adjustment
    n_det: int
    start_units: UnitTransforms
    points0: FloatArray  # start values of the points and the centres
    max_iterations: int

    @property
    def n_unknown_points(self) -> int:
        n_centres: int = self.strip.centres.shape[0]
        return self.strip.observations.n_points + n_centres


class _ModelsSolution(NamedTuple):
    result: SimultaneousResult
    guess: FloatArray
    converged: bool
    n_pass: int
    active: BoolArray


def adjust_models_to_ground(
    strip: StripModel,
    control: ControlPoints,
    crs: GroundCRS | str,
    *,
    lines: Sequence[LineSpec] = (),
    options: GroundOptions | None = None,
    blunders: BlunderOptions | None = None,
    control_name: str = "control",
) -> GroundResult:
    """Transform every model of the strip at once onto the control.

    Parameters and result as :func:`strip_aerotri.ground.polynomials.adjust_to_ground`;
    the result's ``similarity`` is J's similarity of the whole strip (the
    start values), ``deformation`` is None and ``models`` holds the
    simultaneous transformation.

    Raises
    ------
    GeometryError
        Insufficient or degenerate control (J's rules for the similarity),
        line points not triangulated, a model not tied to the others.
    """
    options = options or GroundOptions()
    blunders = blunders or BlunderOptions()
    if not isinstance(crs, GroundCRS):
        crs = GroundCRS.from_user_input(crs)
    problem = _prepare(strip, control, crs, tuple(lines), options, control_name)
    sol, keep_rows, use_xy, use_z, line_keep, rejections, rejected_rows = _snoop(problem, blunders)
    if not sol.converged:
        warnings.warn(
            f"ground stage: the passes did not settle in {sol.n_pass} (the estimated "
            "coordinates of plan and height control still changed); the results are those "
            "of the last pass",
            StripAerotriWarning,
            stacklevel=2,
        )
    return _products(
        problem, sol, keep_rows, use_xy, use_z, line_keep, rejections, rejected_rows, blunders
    )


def _prepare(
    strip: StripModel,
    control: ControlPoints,
    crs: GroundCRS,
    lines: tuple[LineSpec, ...],
    options: GroundOptions,
    control_name: str = "control",
) -> _ModelsProblem:
    """J's similarity of the whole strip, then the rows and weights of the
    simultaneous transformation and its start values."""
    obs = strip.observations
    # J's similarity of the whole strip: the work frame along the strip, the
    # start values, and the checks of the control's geometry (its own misfit
    # warnings concern the similarity alone, which the models replace).
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        start = similarity_start(
            strip,
            control,
            crs,
            route=options.route,
            max_iterations=options.max_iterations,
            control_name=control_name,
        )
    rows = start.control_index
    check = start.is_check
    ids = tuple(control.point_ids[r] for r in rows)
    idx = index_of(obs.point_ids, ids)
    given = control.xyz[rows]
    use_xy = control.uses_xy[rows] & ~check
    use_z = control.uses_h[rows] & ~check
    guess = np.where(np.isnan(given), start.points[idx], given)
    active = use_xy | use_z
    work = make_work_frame(start.route, crs, guess[active], start.azimuth)
    transform = start.similarity.transform
    _check_breaks(strip, idx, use_xy, use_z, ids, work.to_work(guess))
    info, c_left, c_right = model_weights(strip, transform, float(np.median(obs.sigma)))

    pos = strip.model_photo_positions
    n_models, n_points = strip.n_models, obs.n_points
    model_ids = np.arange(n_models)
    all_rows = UnitObservations(
        np.concatenate([strip.model, model_ids, model_ids]),
        np.concatenate([strip.model_point, n_points + pos[:-1], n_points + pos[1:]]),
        np.vstack([strip.model_points, strip.centres[pos[:-1]], strip.centres[pos[1:]]]),
        np.concatenate([info, c_left, c_right]),
    )
    sig_xy, sig_h = control.sigma_xy[rows], control.sigma_h[rows]
    return _ModelsProblem(
        strip=strip,
        start=start,
        work=work,
        ids=ids,
        idx=idx,
        given=given,
        guess=guess,
        use_xy=use_xy,
        use_z=use_z,
        sigma=np.column_stack([sig_xy, sig_xy, sig_h]),
        lines=lines,
        line_index=[index_of(obs.point_ids, line.point_ids) for line in lines],
        plan_sigma=float(np.hypot(np.median(sig_xy[active]), start.expected_sigma_plan)),
        rows=all_rows,
        n_det=strip.model.shape[0],
        start_units=UnitTransforms(
            np.full(n_models, transform.scale),
            np.broadcast_to(transform.rotation, (n_models, 3, 3)).copy(),
            np.broadcast_to(transform.translation, (n_models, 3)).copy(),
            np.zeros((n_models, 3)),
        ),
        points0=np.vstack(
            [
                np.where(np.isfinite(start.points_work), start.points_work, 0.0),
                start.photo_centres_work,
            ]
        ),
        max_iterations=options.max_iterations,
    )


def _adjust(
    p: _ModelsProblem,
    keep_rows: BoolArray,
    use_xy: BoolArray,
    use_z: BoolArray,
    conditions: list[LineCondition],
    passes: ControlPasses,
    starts: UnitTransforms,
    points0: FloatArray,
) -> SimultaneousResult:
    """:func:`adjust_units` on the rows ``keep_rows`` with the control used."""
    active = use_xy | use_z
    r = p.rows
    rows = UnitObservations(
        r.unit[keep_rows], r.point[keep_rows], r.xyz[keep_rows], r.weight[keep_rows]
    )
    return adjust_units(
        rows,
        p.strip.n_models,
        p.n_unknown_points,
        start=starts,
        points0=points0,
        control_point=p.idx[active],
        control_xyz=passes.target(),
        control_sigma=p.sigma[active],
        lines=conditions,
        statistics=True,
        max_iterations=p.max_iterations,
        order="given",  # the models are numbered along the strip
        # each model's weights are its points' information in the model,
        # given at the start's rotation: they turn with the model
        weight_rotation=p.start_units.rotation,
        control_update=passes.update if passes.guessed else None,
        project_points=True,
    )


def _grouped_start(
    p: _ModelsProblem,
    keep_rows: BoolArray,
    use_xy: BoolArray,
    use_z: BoolArray,
    conditions: list[LineCondition],
) -> tuple[FloatArray, UnitTransforms, FloatArray]:
    """The control's guess, the models' start and the points' start of the
    first solution: J's similarity for every model on a strip of fewer than
    :data:`_GROUPS_FROM` groups of :data:`_GROUP_MODELS` models, else each
    model at its group's similarity from the adjustment of the groups
    (:func:`~strip_aerotri.geometry.grouped_start.grouped_start`; J's
    similarity where that fails or does not converge: it is only a start)."""
    strip = p.strip
    group = groups_along(strip.n_models, _GROUP_MODELS, strip.breaks)
    if int(group.max(initial=0)) + 1 < _GROUPS_FROM:
        return p.guess.copy(), p.start_units, p.points0
    active = use_xy | use_z
    passes = ControlPasses(p.work, p.idx, p.given, p.guess.copy(), use_xy, use_z, _MAX_PASSES)
    r = p.rows
    try:
        grouped = grouped_start(
            UnitObservations(
                r.unit[keep_rows], r.point[keep_rows], r.xyz[keep_rows], r.weight[keep_rows]
            ),
            group,
            p.n_unknown_points,
            start=p.start_units,
            points0=p.points0,
            control_point=p.idx[active],
            control_xyz=passes.target(),
            control_sigma=p.sigma[active],
            lines=conditions,
            weight_rotation=p.start_units.rotation,
            control_update=passes.update if passes.guessed else None,
            max_iterations=p.max_iterations,
        )
    except (GeometryError, ConvergenceError, np.linalg.LinAlgError):
        return p.guess.copy(), p.start_units, p.points0
    if not grouped.converged:  # groups that did not settle are no start
        return p.guess.copy(), p.start_units, p.points0
    return passes.guess, grouped.transforms, grouped.points


def _solve(
    p: _ModelsProblem,
    keep_rows: BoolArray,
    use_xy: BoolArray,
    use_z: BoolArray,
    line_keep: list[BoolArray],
    previous: _ModelsSolution | None,
) -> _ModelsSolution:
    """The adjustment for one set of observations, from the previous
    solution when there is one.

    Control given in full is met as given; plan and height points get their
    missing coordinate from the adjustment as it goes
    (:class:`~strip_aerotri.ground.control_passes.ControlPasses`), and the
    statistics come from the factor of its last step, once the coordinates
    have settled."""
    active = use_xy | use_z
    conditions = [
        LineCondition(point=li[keep], sigma=p.plan_sigma / np.sqrt(line.weight))
        for line, li, keep in zip(p.lines, p.line_index, line_keep, strict=True)
    ]
    if previous is None:
        guess, starts, points0 = _grouped_start(p, keep_rows, use_xy, use_z, conditions)
    else:
        guess, starts = previous.guess, previous.result.transforms
        points0 = np.where(np.isfinite(previous.result.points), previous.result.points, p.points0)
    passes = ControlPasses(p.work, p.idx, p.given, guess, use_xy, use_z, _MAX_PASSES)
    res = _adjust(p, keep_rows, use_xy, use_z, conditions, passes, starts, points0)
    converged = passes.settled or not passes.guessed
    return _ModelsSolution(res, passes.guess, converged, passes.n_pass, active)


def _snoop(
    p: _ModelsProblem, blunders: BlunderOptions
) -> tuple[
    _ModelsSolution,
    BoolArray,
    BoolArray,
    BoolArray,
    list[BoolArray],
    tuple[Rejection, ...],
    tuple[tuple[str, str], ...],
]:
    """The simultaneous transformation, then data snooping until nothing
    fails: the worst failing control component or line point out (they come
    first: their errors show in their points' determinations too), else
    every failing determination that is the largest of its point and of its
    model, all in one round; solve again.  A control point whose rejection
    would leave the control unable to carry the strip is kept and flagged.

    Returns the last solution, the rows, control coordinates and line points
    used, the rejections (the flagged ones last) and the (model, point) of
    each determination rejected."""
    strip = p.strip
    keep_rows = np.ones(p.rows.unit.shape[0], dtype=bool)
    # points whose determinations disagreed between consecutive models (the
    # strip's tie test) stay out, as they are out of the strip model
    keep_rows[: p.n_det] = strip.kept_determinations
    use_xy, use_z = p.use_xy.copy(), p.use_z.copy()
    line_keep = [np.ones(len(li), dtype=bool) for li in p.line_index]
    rejections: list[Rejection] = []
    flagged: list[Rejection] = []
    rejected_rows: list[tuple[str, str]] = []
    n_control_obs = int(2 * use_xy.sum() + use_z.sum())
    sol = start_sol = None
    control_kept = False
    while True:
        sol = _solve(p, keep_rows, use_xy, use_z, line_keep, sol)
        start_sol = start_sol or sol
        if not blunders.testing:
            break
        known = {(k.stage, k.point, k.component) for k in flagged}
        found = [
            f
            for f in _tests(p, sol.result, use_xy, use_z, keep_rows, line_keep, blunders)
            if (f[0].stage, f[0].point, f[0].component) not in known
            and not (control_kept and f[0].stage == "control")
        ]
        if not found:
            break
        if not blunders.rejecting:
            rejections.extend(f[0] for f in found)
            break
        # Control and line tests first: their errors show in the determinations
        # of their points too (the models give way to them), while an error of
        # a determination seldom makes a control or line test fail.
        first = [f for f in found if f[0].stage != "models"] or found
        worst, apply = max(first, key=lambda f: abs(f[0].w) / f[0].critical)
        if worst.stage == "control":
            trial_xy, trial_z = use_xy.copy(), use_z.copy()
            apply(trial_xy, trial_z)
            target = p.work.to_work(sol.guess)
            if not _feasible(strip, p.idx, target, trial_xy, trial_z, p.ids):
                # Rejection must never make the adjustment impossible: keep
                # the point, flagged with its test value.
                flagged.append(
                    replace(
                        worst,
                        applied=False,
                        effect="kept: without it the control could not carry the strip "
                        "(J's rules for the similarity); check this point",
                    )
                )
                continue
            use_xy, use_z = trial_xy, trial_z
            rejected_obs = n_control_obs - int(2 * use_xy.sum() + use_z.sum())
            if rejected_obs > blunders.max_fraction * max(n_control_obs, 1):
                if not _keep_systematic(
                    p, start_sol, blunders, use_xy, use_z, sol, [*rejections, worst]
                ):
                    raise GeometryError(
                        f"control: more than {blunders.max_fraction:.0%} of the control "
                        "observations fail the blunder test; the control cannot be trusted"
                    )
                # a smooth pattern: the camera, not the control; keep it all
                use_xy, use_z, control_kept = p.use_xy.copy(), p.use_z.copy(), True
                rejections = kept_control(rejections)
                continue
        elif worst.stage == "models":
            # every determination that leads its point and its model, at once
            for rejection, reject in found:
                reject(keep_rows)
                label = rejection.photos
                rejected_rows.append((label[0] if label else "", rejection.point))
                rejections.append(rejection)
            if (~keep_rows[: p.n_det]).sum() > blunders.max_fraction * p.n_det:
                raise GeometryError(
                    f"models: more than {blunders.max_fraction:.0%} of the determinations "
                    "fail the blunder test; the image coordinates cannot be trusted"
                )
            continue
        else:
            apply(line_keep)
        rejections.append(worst)
    return (
        sol,
        keep_rows,
        use_xy,
        use_z,
        line_keep,
        tuple(rejections + flagged),
        tuple(rejected_rows),
    )


def _keep_systematic(
    p: _ModelsProblem,
    first: _ModelsSolution,
    blunders: BlunderOptions,
    use_xy: BoolArray,
    use_z: BoolArray,
    last: _ModelsSolution,
    rejections: Sequence[Rejection],
) -> bool:
    """True (and a warning) when the control fails at many points alike
    (:mod:`strip_aerotri.ground.systematic`): camera errors, not blunders.

    Judged on the first solution's test values, and on the test values met so
    far: each rejected component at the value it was rejected with, the others
    at the last solution's.  A bending the control follows fails a few points
    at a time, a little over the critical value: rejecting them one by one
    makes the next ones fail, which the first solution alone does not show."""
    rows = np.flatnonzero(p.use_xy | p.use_z)
    w = np.array(first.result.control_w, dtype=np.float64)
    w[~p.use_xy[rows], :2] = np.nan
    w[~p.use_z[rows], 2] = np.nan
    critical = blunders.critical("control", max(int(np.isfinite(w).sum()), 1))
    now = np.full((p.use_xy.size, 3), np.nan)
    now[np.flatnonzero(last.active)] = np.array(last.result.control_w, dtype=np.float64)
    now[~use_xy, :2] = np.nan
    now[~use_z, 2] = np.nan
    row_of = {pid: int(np.searchsorted(rows, k)) for k, pid in enumerate(p.ids)}
    rejected = rejected_components(rejections, row_of)
    return kept_if_alike("control", w, critical, last=now[rows], rejected=rejected)


def _check_breaks(
    strip: StripModel,
    idx: IntArray,
    use_xy: BoolArray,
    use_z: BoolArray,
    ids: tuple[str, ...],
    target: FloatArray,
) -> None:
    """Each run of models between breaks (a model sharing no tie point with
    the one before: its scale was not transferred) must carry itself on its
    own control, J's rules for a similarity (two plan and three height
    points, not degenerate); the shared projection centre holds only the
    position across a break."""
    breaks = np.asarray(strip.breaks, dtype=np.intp)
    if breaks.size == 0:
        return
    edges = [0, *breaks.tolist(), strip.n_models]
    labels = strip.model_labels or tuple(f"model {m}" for m in range(strip.n_models))
    for lo, hi in pairwise(edges):
        in_run = np.zeros(strip.observations.n_points, dtype=bool)
        in_run[strip.model_point[(strip.model >= lo) & (strip.model < hi)]] = True
        here = in_run[idx]
        xy, z = use_xy & here, use_z & here
        if _feasible(strip, idx, target, xy, z, ids):
            continue
        m = int(breaks[0]) if lo == 0 else lo
        ids_ = strip.observations.photo_ids
        seq = strip.photo_index[strip.model_photo_positions]
        raise GeometryError(
            f"{labels[m]} shares no tie point with {labels[m - 1]} (no point is measured on all "
            f"three photos {ids_[seq[m - 1]]}, {ids_[seq[m]]}, {ids_[seq[m + 1]]}): the scale "
            f"cannot be transferred across it, and the models {labels[lo]} to {labels[hi - 1]} "
            f"have too little control of their own ({int(xy.sum())} plan and {int(z.sum())} "
            "height points; a similarity needs two and three, not in one vertical plane): "
            "measure tie points in that triple overlap or add control there"
        )


def _feasible(
    strip: StripModel,
    idx: IntArray,
    target: FloatArray,
    use_xy: BoolArray,
    use_z: BoolArray,
    ids: tuple[str, ...],
) -> bool:
    """True when the control left satisfies J's rules for the similarity."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", StripAerotriWarning)
        try:
            _validate_control_geometry(strip.points[idx], target, use_xy, use_z, ids)
        except GeometryError:
            return False
    return True


_Found = list[tuple[Rejection, Callable[..., None]]]


def _tests(
    p: _ModelsProblem,
    res: SimultaneousResult,
    use_xy: BoolArray,
    use_z: BoolArray,
    keep_rows: BoolArray,
    line_keep: list[BoolArray],
    blunders: BlunderOptions,
) -> _Found:
    """Every observation above its critical value, with the change that would
    reject it: (Rejection, apply) pairs."""
    return (
        _control_tests(p, res, use_xy | use_z, blunders)
        + _determination_tests(p, res, keep_rows, blunders)
        + _line_tests(p, res, line_keep, blunders)
    )


def _control_tests(
    p: _ModelsProblem, res: SimultaneousResult, active: BoolArray, blunders: BlunderOptions
) -> _Found:
    """Baarda's w of the control components, at their stated sigmas.

    No variance factor: a control error spreads through the models into the
    w of many other control points, and a factor from their median would
    hide it (a 5 m error gives a factor of 90)."""
    found: _Found = []
    act = np.flatnonzero(active)
    w = res.control_w  # (n_active, 3)
    crit = blunders.critical("control", int(np.isfinite(w).sum()))
    plan_w = np.fmax(np.abs(w[:, 0]), np.abs(w[:, 1]))
    height_w = np.abs(w[:, 2])
    resid = res.control_residuals
    with np.errstate(invalid="ignore", divide="ignore"):
        # Baarda's estimate of the error behind a failed test: v / r (the
        # models take most of a control error into the solution: r is small)
        estimate = np.nan_to_num(resid / res.control_redundancy)
    for k in np.flatnonzero((plan_w > crit) | (height_w > crit)):
        row = int(act[k])
        for comp, value, r, size in (
            (
                "plan",
                plan_w[k],
                float(np.hypot(np.nan_to_num(resid[k, 0]), np.nan_to_num(resid[k, 1]))),
                float(np.hypot(estimate[k, 0], estimate[k, 1])),
            ),
            ("height", height_w[k], float(resid[k, 2]), float(estimate[k, 2])),
        ):
            if not (np.isfinite(value) and value > crit):
                continue

            def apply(xy: BoolArray, z: BoolArray, row: int = row, comp: str = comp) -> None:
                (z if comp == "height" else xy)[row] = False

            rejection = Rejection(
                stage="control",
                point=p.ids[row],
                photos=(),
                component=comp,
                residual=r,
                unit="m",
                w=float(value),
                critical=crit,
                applied=blunders.rejecting,
                effect=f"estimated error {size:.3g} m; sigma0 {res.sigma0:.3g} before",
            )
            found.append((rejection, apply))
    return found


def _determination_tests(
    p: _ModelsProblem, res: SimultaneousResult, keep_rows: BoolArray, blunders: BlunderOptions
) -> _Found:
    """The 3-D residual of each determination against chi-square(3), as a
    "w" = sqrt(statistic) (row_statistic has mean 1 per row: times 3).
    Rejecting: every failing determination that is the largest of its point
    and of its model (they go out together, :func:`leading_failures`);
    flagging only: the five largest above the critical value.

    Data noisier than declared scale the statistic down by the rows' median
    over chi-square(3)'s, never up (the statistic's redundancy share is an
    estimate, and its tail is heavier than its median says)."""
    strip = p.strip
    found: _Found = []
    kept = np.flatnonzero(keep_rows[: p.n_det])
    stat = 3.0 * res.row_statistic[: kept.size]
    finite = stat[np.isfinite(stat)]
    if finite.size:
        stat = stat / max(1.0, float(np.median(finite)) / _CHI2_3_MEDIAN)
    crit = blunders.critical("models", int(np.isfinite(stat).sum()), dof=3)
    w_rows = np.sqrt(np.where(np.isfinite(stat), stat, 0.0))
    if blunders.rejecting:
        chosen = leading_failures(w_rows, crit, strip.model_point[kept], strip.model[kept])
    else:
        chosen = np.argsort(-w_rows)[:5]
        chosen = chosen[w_rows[chosen] > crit]
    for k in chosen:
        det = int(kept[k])
        m = int(strip.model[det])
        label = strip.model_labels[m] if strip.model_labels else f"model {m}"

        def apply(keep: BoolArray, det: int = det) -> None:
            keep[det] = False

        rejection = Rejection(
            stage="models",
            point=strip.observations.point_ids[strip.model_point[det]],
            photos=(label,),
            component="model point",
            residual=float(np.linalg.norm(res.residuals[k])),
            unit="m",
            w=float(w_rows[k]),
            critical=crit,
            applied=blunders.rejecting,
            effect="determination left out of the adjustment",
        )
        found.append((rejection, apply))
    return found


def _line_tests(
    p: _ModelsProblem,
    res: SimultaneousResult,
    line_keep: list[BoolArray],
    blunders: BlunderOptions,
) -> _Found:
    """Baarda's w of the line equations of the line points still used."""
    found: _Found = []
    if not p.lines:
        return found
    crit = blunders.critical("straight_line", int(sum(int(k.sum()) for k in line_keep)))
    for li_k, (line, keep, e, wl, rl) in enumerate(
        zip(p.lines, line_keep, res.line_residuals, res.line_w, res.line_redundancy, strict=True)
    ):
        kept_pos = np.flatnonzero(keep)
        for j in np.flatnonzero(np.abs(np.nan_to_num(wl)) > crit):
            pos = int(kept_pos[j])

            def apply(keeps: list[BoolArray], li_k: int = li_k, pos: int = pos) -> None:
                keeps[li_k][pos] = False

            rejection = Rejection(
                stage="straight_line",
                point=str(line.point_ids[pos]),
                photos=(line.name,),
                component="line",
                residual=float(e[j]),
                unit="m",
                w=float(abs(wl[j])),
                critical=crit,
                applied=blunders.rejecting,
                effect=f"line {line.name!r}; estimated distance from the line "
                f"{abs(e[j] / rl[j]):.3g} m",
            )
            found.append((rejection, apply))
    return found


def _mean_rotation(a: FloatArray, b: FloatArray) -> FloatArray:
    """Chordal mean of pairs of rotations (n, 3, 3): the rotation nearest
    (a + b) / 2 (SVD projection)."""
    u, _, vt = np.linalg.svd(0.5 * (a + b))
    d = np.sign(np.linalg.det(u @ vt))
    u[:, :, 2] *= d[:, None]
    mean: FloatArray = u @ vt
    return mean


def _products(
    p: _ModelsProblem,
    sol: _ModelsSolution,
    keep_rows: BoolArray,
    use_xy: BoolArray,
    use_z: BoolArray,
    line_keep: list[BoolArray],
    rejections: tuple[Rejection, ...],
    rejected_rows: tuple[tuple[str, str], ...],
    blunders: BlunderOptions,
) -> GroundResult:
    """Every point and photo through the models' transforms, to the CRS, with
    the control's residuals and detectability and the models' discrepancies."""
    strip, res, work = p.strip, sol.result, p.work
    points_work, centres_work, rot_work = _photos_and_points(strip, res)
    points_work = intersect_unmodelled(strip, points_work, centres_work, rot_work)
    centres = work.from_work(centres_work)
    rot_enu = work.rotations_to_enu(rot_work, centres)

    given, check = p.given, p.start.is_check
    given_work = work.to_work(np.where(np.isnan(given), sol.guess, given))
    resid = work.enu_from_work(given_work - points_work[p.idx])
    # rejected control keeps its (large) residual; used_xy / used_h say what was used
    resid[~(p.use_xy | check), :2] = np.nan
    resid[~(p.use_z | check), 2] = np.nan
    resid[np.isnan(given)] = np.nan

    line_resid = tuple(
        points_work[li, 1] - (ab[0] + ab[1] * points_work[li, 0])
        for li, ab in zip(p.line_index, res.line_parameters, strict=True)
    )
    active = use_xy | use_z
    redundancy, mde = control_detectability(
        res.control_redundancy, p.sigma[active], blunders, int(np.isfinite(res.control_w).sum())
    )
    n_rows = p.start.control_index.shape[0]
    red_all = np.full((n_rows, 3), np.nan)
    mde_all = np.full((n_rows, 3), np.nan)
    red_all[active], mde_all[active] = redundancy, mde
    return replace(
        p.start,
        points_work=points_work,
        points=work.from_work(points_work),
        photo_centres_work=centres_work,
        photo_centres=centres,
        photo_rotations_work=rot_work,
        photo_rotations_enu=rot_enu,
        photo_opk=opk_from_matrix(rot_enu),
        control_residuals=resid,
        line_names=tuple(line.name for line in p.lines),
        line_point_index=tuple(p.line_index),
        line_residuals=line_resid,
        passes=sol.n_pass,
        passes_converged=sol.converged,
        used_xy=use_xy & ~check,
        used_h=use_z & ~check,
        line_used=tuple(k.copy() for k in line_keep),
        rejections=rejections,
        models=_model_adjustment(strip, res, keep_rows, p.n_det, rejected_rows),
        control_redundancy=red_all,
        control_mde=mde_all,
    )


def _photos_and_points(
    strip: StripModel, res: SimultaneousResult
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Work-frame points (P, 3; NaN where not triangulated), projection
    centres (M, 3) and image -> work rotations (M, 3, 3) of the adjustment.

    A photo's attitude is the chordal mean of the (one or two) models'
    transforms applied to its strip rotation; a photo between the model
    photos (photo_step > 1) takes the transform of the model whose photos
    enclose it, and a point seen only by such photos that of the model whose
    centroid is nearest in plan."""
    n_points = strip.observations.n_points
    pos = strip.model_photo_positions
    n_photos = strip.centres.shape[0]
    points_work = res.points[:n_points].copy()
    points_work[~strip.triangulated] = np.nan
    centres_work = res.points[n_points:].copy()
    t = res.transforms
    rot_work = np.full((n_photos, 3, 3), np.nan)
    left_of = np.full(n_photos, -1)
    right_of = np.full(n_photos, -1)
    left_of[pos[:-1]] = np.arange(strip.n_models)  # photo is the left photo of model m
    right_of[pos[1:]] = np.arange(strip.n_models)
    m_a = np.where(left_of >= 0, left_of, right_of)
    m_b = np.where(right_of >= 0, right_of, left_of)
    in_model = m_a >= 0
    ra = t.apply_to_rotation(m_a[in_model], strip.rotations[in_model])
    rb = t.apply_to_rotation(m_b[in_model], strip.rotations[in_model])
    rot_work[in_model] = _mean_rotation(ra, rb)
    between = ~in_model
    if between.any():
        model_of = np.clip(
            np.searchsorted(pos, np.flatnonzero(between)) - 1, 0, strip.n_models - 1
        )
        rot_work[between] = t.apply_to_rotation(model_of, strip.rotations[between])
        centres_work[between] = t.apply(model_of, strip.centres[between])
        lonely = np.flatnonzero(strip.triangulated & ~np.isfinite(points_work).all(axis=1))
        if lonely.size:
            d = strip.points[lonely, None, :2] - t.centroid[None, :, :2]
            nearest = np.argmin(np.einsum("pmk,pmk->pm", d, d), axis=1)
            points_work[lonely] = t.apply(nearest, strip.points[lonely])
    return points_work, centres_work, rot_work


def _model_adjustment(
    strip: StripModel,
    res: SimultaneousResult,
    keep_rows: BoolArray,
    n_det: int,
    rejected_rows: tuple[tuple[str, str], ...],
) -> ModelAdjustment:
    """The discrepancies of the determinations and of the centres, with each
    model's RMS of its determinations."""
    kept = np.flatnonzero(keep_rows[:n_det])
    disc = res.residuals[: kept.size]
    det_model = strip.model[kept]
    counts = np.bincount(det_model, minlength=strip.n_models)
    with np.errstate(invalid="ignore", divide="ignore"):
        model_rms = np.sqrt(
            np.stack(
                [
                    np.bincount(det_model, disc[:, k] ** 2, minlength=strip.n_models)
                    for k in range(3)
                ],
                axis=1,
            )
            / counts[:, None]
        )
    centre_rows = np.flatnonzero(keep_rows[n_det:]) + kept.size
    centre_disc = res.residuals[centre_rows].reshape(2, strip.n_models, 3).transpose(1, 0, 2)
    return ModelAdjustment(
        result=res,
        model=det_model,
        point=strip.model_point[kept],
        discrepancy=disc,
        model_rms=model_rms,
        centre_discrepancy=centre_disc,
        rejected=rejected_rows,
    )
