"""Solving a block's transformation and its data snooping: the plan/height
passes of :func:`~strip_aerotri.geometry.simultaneous.adjust_units`, the
strips' polynomial terms the data do not determine, and the tests (the
control by Baarda's w one component at a time, then every failing point
determination that leads its point and its unit, in one round)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from .._stats import leading_failures
from .._typing import BoolArray, FloatArray, IntArray
from ..errors import GeometryError
from ..geometry.simultaneous import (
    SimultaneousResult,
    UnitObservations,
    adjust_units,
)
from ..ground.control_passes import ControlPasses
from ..ground.systematic import kept_control, kept_if_alike, rejected_components
from ..options import BlunderOptions, Construction
from ..results import Rejection
from .problem import _Problem

_MAX_PASSES = 6
_CHI2_3_MEDIAN = 2.365973884375338  # median of chi-square with 3 degrees of freedom


@dataclass
class _Solution:
    result: SimultaneousResult
    guess: FloatArray


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
    """The transformation, control given in plan or height only getting its
    other coordinates from the adjusted point as it goes (as the ground
    stage, :class:`~strip_aerotri.ground.control_passes.ControlPasses`);
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
    passes = ControlPasses(p.work, p.idx, p.given, guess, use_xy, use_z, _MAX_PASSES)
    result = adjust_units(
        rows,
        p.unit_strip.shape[0],
        n_total,
        start=starts,
        points0=points0,
        control_point=p.idx[active],
        control_xyz=passes.target(),
        control_sigma=p.sigma[active],
        max_iterations=p.max_iterations,
        polynomial=p.polynomial,
        statistics=statistics,
        order=_band_order(p),
        control_update=passes.update if guessed else None,
    )
    return _Solution(result, passes.guess)


def _snoop(
    p: _Problem, blunders: BlunderOptions
) -> tuple[_Solution, BoolArray, BoolArray, BoolArray, tuple[Rejection, ...]]:
    """Data snooping until nothing fails: the control by Baarda's w, one
    component at a time (never one the block cannot spare: kept and
    flagged), then the determinations of the points in their units by their
    3-D residuals against chi-square(3), as the ground stage tests a strip's
    models: every failing determination that is the largest of its point
    and of its unit, all in one round."""
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
    first, control_kept = sol, False
    while blunders.testing:
        control = (
            None if control_kept else _control_test(p, sol, use_xy, use_z, blunders, flagged)
        )
        found = (
            [control]
            if control is not None
            else _determination_test(p, sol, keep_rows, blunders)
        )
        if not found:
            break
        rejections.extend(rejection for rejection, _ in found)
        if not (blunders.rejecting and found[0][0].applied):
            if not blunders.rejecting:
                break
            continue
        last_w = _control_w(p, sol, use_xy, use_z)  # the test values met in this solution
        for _, apply in found:
            apply(use_xy, use_z, keep_rows)
        if n_control - int(2 * use_xy.sum() + use_z.sum()) > blunders.max_fraction * n_control:
            if not _keep_systematic(p, first, blunders, last_w, rejections):
                raise GeometryError(_too_much_control_fails(p, blunders, sigma0))
            # a pattern of many points failing alike: the camera, not the control; keep it all
            use_xy, use_z, control_kept = p.use_xy.copy(), p.use_z.copy(), True
            rejections = kept_control(rejections)
        if (~keep_rows).sum() > blunders.max_fraction * n_det:
            raise GeometryError(
                f"block: more than {blunders.max_fraction:.0%} of the points' determinations "
                "fail the blunder test; the image coordinates or point ids cannot be trusted"
            )
        sol = _solve(p, use_xy, use_z, sol, keep_rows)
    return sol, use_xy, use_z, keep_rows, tuple(rejections)


def _keep_systematic(
    p: _Problem,
    first: _Solution,
    blunders: BlunderOptions,
    last_w: FloatArray,
    rejections: Sequence[Rejection],
) -> bool:
    """True (and a warning) when the control fails at many points alike
    (:func:`strip_aerotri.ground.systematic.fails_alike`): camera errors, not
    blunders.  Judged on the first solution's test values and on every one
    met so far (``last_w``, the last solution's, with each rejected
    component at the value it was rejected with)."""
    active = p.use_xy | p.use_z
    w = _control_w(p, first, p.use_xy, p.use_z)
    critical = blunders.critical("control", max(int(np.isfinite(w).sum()), 1))
    rows = np.flatnonzero(active)
    position = {
        p.control.point_ids[p.control_rows[k]]: j for j, k in enumerate(rows.tolist())
    }
    rejected = rejected_components(rejections, position)
    return kept_if_alike("block", w[active], critical, last=last_w[active], rejected=rejected)


def _control_w(p: _Problem, sol: _Solution, use_xy: BoolArray, use_z: BoolArray) -> FloatArray:
    """The control's test values of a solution (control rows, components; NaN
    where not in use)."""
    w = np.full((p.idx.shape[0], 3), np.nan)
    w[use_xy | use_z] = sol.result.control_w
    w[~use_xy, :2] = np.nan
    w[~use_z, 2] = np.nan
    return w


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
    w = _control_w(p, sol, use_xy, use_z)
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
) -> list[tuple[Rejection, _Apply]]:
    """The point determinations whose 3-D residuals fail chi-square(3)
    (``row_statistic`` times 3, scaled down by its median over chi-square(3)'s
    when the data are noisier than declared, never up): rejecting, every one
    that is the largest of its point and of its unit (:func:`leading_failures`),
    largest first; only reporting, the largest."""
    n_points = p.observations.n_points
    kept = np.flatnonzero(keep_rows)
    stat = 3.0 * sol.result.row_statistic
    stat = np.where((p.rows.point[kept] < n_points) & np.isfinite(stat), stat, np.nan)
    finite = stat[np.isfinite(stat)]
    if finite.size == 0:
        return []
    stat = stat / max(1.0, float(np.median(finite)) / _CHI2_3_MEDIAN)
    critical = blunders.critical("models", int(finite.size), dof=3)
    w = np.sqrt(np.where(np.isfinite(stat), stat, 0.0))
    chosen = leading_failures(w, critical, p.rows.point[kept], p.rows.unit[kept])
    if not blunders.rejecting:
        chosen = chosen[:1]
    found: list[tuple[Rejection, _Apply]] = []
    for k in chosen:
        row = int(kept[k])
        strip = p.specs[int(p.unit_strip[int(p.rows.unit[row])])].name

        def apply(xy: BoolArray, z: BoolArray, keep: BoolArray, row: int = row) -> None:
            keep[row] = False

        rejection = Rejection(
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
        )
        found.append((rejection, apply))
    return found


def _band_order(p: _Problem) -> Literal["auto"] | IntArray:
    """The units' order for :func:`adjust_units` (across the strips)."""
    return "auto" if p.unit_order is None else p.unit_order
