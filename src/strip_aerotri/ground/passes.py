"""J's construction: the passes of similarity and deformation polynomials.

One solution of the ground stage for the construction ``"strips"``
(method.md §6): the similarity on the control in a work frame along the
strip, the deformation polynomials of J(16) with the straight-line
condition J(18), and the passes that turn the work frame onto the strip's
axis and give plan control its height and height control its plan position
from the adjusted strip (the work frame's coordinates of such points need
them through the earth's curvature), until nothing changes.

A long strip bent by its chain leaves the similarity a roll set by the bend;
the roll is turned back into the similarity when its effect on the relief
matters (:func:`_fit_with_roll`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal, NamedTuple

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray
from ..frames import WorkFrame, make_work_frame
from ..geodesy import GroundCRS
from ..geometry.deformation import DeformationResult, StraightLine, fit_deformation
from ..geometry.deformation_auto import KindSelection, select_kind_auto
from ..geometry.similarity import (
    SimilarityResult,
    SimilarityTransform,
    fit_similarity,
    similarity_from_points,
)
from ..observations import LineSpec
from ..options import Route
from ..results import StripModel
from .common import deformation_slopes

__all__ = ["Solution", "StripProblem", "solve_passes"]

_MAX_PASSES = 8
_PASS_TOLERANCE_M = 1e-5
_ROLL_TOLERANCE = 0.1  # of the expected plan sigma, over the relief's spread
_MAX_TURNS = 4  # of the roll in one pass (a large turn settles in one or two)
_ROLL_SAMPLE_STEP = 4  # of the served sample: 2048 points for the roll's mean and relief
# Probe points (m) that carry a similarity from one work frame to the next.
_FRAME_PROBE_M = np.array(
    [[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0], [0.0, 1000.0, 0.0], [0.0, 0.0, 1000.0]]
)


@dataclass(frozen=True, eq=False)
class StripProblem:
    """What every pass of one ground stage needs, fixed for the stage.

    Control arrays are per usable control row (C); work-frame quantities in
    metres.

    Attributes
    ----------
    strip : StripModel
    crs : GroundCRS
    route : Route
    lines : sequence of LineSpec
    line_index : list of ndarray of int
        The strip's index of each line's points.
    ids : tuple of str
        Control point ids.
    given, guess : ndarray, shape (C, 3)
        The control as given, and with start values for what is not given
        (plan points at the mean known height, height points at the centroid
        of the known plan positions).
    check : ndarray of bool, shape (C,)
    strip_xyz : ndarray, shape (C, 3)
        The control points in the strip model.
    exp_xy, exp_z : ndarray, shape (C,)
        Expected errors: the control's own with the photogrammetric ones.
    control_sigma_xy : ndarray, shape (C,)
    metres_per_mm, sigma_plan, sigma_height : float
        Image scale and the expected photogrammetric errors of a point.
    served : ndarray, shape (S, 3)
        A sample of the strip's points the similarity serves (its test of
        height control nearly in one vertical plane, the roll's relief).
    sections, max_iterations : int
    pass_tolerance_m : float
        The passes end when the guessed control coordinates move by less.
    """

    strip: StripModel
    crs: GroundCRS
    route: Route
    lines: tuple[LineSpec, ...]
    line_index: list[IntArray]
    ids: tuple[str, ...]
    given: FloatArray
    guess: FloatArray
    check: BoolArray
    strip_xyz: FloatArray
    exp_xy: FloatArray
    exp_z: FloatArray
    control_sigma_xy: FloatArray
    metres_per_mm: float
    sigma_plan: float
    sigma_height: float
    served: FloatArray
    sections: int
    max_iterations: int
    pass_tolerance_m: float = _PASS_TOLERANCE_M


class Solution(NamedTuple):
    """One solution of the passes, for the tests and the products."""

    work: WorkFrame
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
    active: BoolArray
    control_sigma_xy: FloatArray
    roll: float


def solve_passes(
    problem: StripProblem,
    use_xy: BoolArray,
    use_z: BoolArray,
    line_keep: list[BoolArray],
    previous: Solution | None,
    polynomial: int | Literal["auto"],
) -> Solution:
    """Similarity and polynomial with the plan/height iteration (passes).

    ``use_xy``, ``use_z`` (C,) say which control coordinates are used,
    ``line_keep`` which line points.  A re-solve after a rejection starts
    from the ``previous`` solution's azimuth and similarity; each fit starts
    from the last one carried into the current frame (fewer iterations, the
    same solution).
    """
    p = problem
    active = use_xy | use_z
    act_ids = [pid for pid, a in zip(p.ids, active, strict=True) if a]
    guess = p.guess.copy()
    azimuth = 0.0 if previous is None else previous.azimuth
    last_fit = None if previous is None else (previous.sim.transform, previous.work)
    roll = 0.0 if previous is None else previous.roll
    ends = p.strip.centres[[0, -1]]
    work = make_work_frame(p.route, p.crs, guess[active], azimuth)
    converged, n_pass = False, 0
    for n_pass in range(1, _MAX_PASSES + 1):
        target = work.to_work(guess)
        sim = fit_similarity(
            p.strip_xyz[active],
            target[active],
            use_xy=use_xy[active],
            use_z=use_z[active],
            sigma_xy=p.exp_xy[active],
            sigma_z=p.exp_z[active],
            point_ids=act_ids,
            start=None if last_fit is None else _carried(*last_fit, work),
            served=p.served,
            max_iterations=p.max_iterations,
        )
        last_fit = (sim.transform, work)
        axis = sim.transform.apply(ends)
        step = _azimuth_step(axis[1] - axis[0])
        # Along the strip: to 1e-9 rad, or to 1 % of the azimuth's own
        # standard deviation in the fit (a long strip bent by its chain: the
        # similarity stops at negligible steps, and the remaining turn,
        # halving from pass to pass, is noise, not a frame to turn).
        sigma_azimuth = float(np.sqrt(sim.covariance[6, 6]))
        along = abs(step) <= max(1e-9, 0.01 * sigma_azimuth)
        if not along and n_pass < _MAX_PASSES:
            # Re-express in a frame whose X runs along the strip and start
            # over (the last pass fits the polynomials in the frame it has,
            # and the passes are reported as not converged).
            azimuth += step
            work = make_work_frame(p.route, p.crs, guess[active], azimuth)
            continue
        sim, deformation, selection, roll, model_xyz = _fit_with_roll(
            p, sim, roll, target, use_xy, use_z, line_keep, polynomial, act_ids
        )
        corrected = model_xyz if deformation is None else deformation.correct(model_xyz)
        new_guess = p.given.copy()
        fill_h, fill_xy = ~use_z & ~p.check, ~use_xy & ~p.check
        # only the rows filled are converted (point by point; most rows of a
        # strip are full check points)
        adjusted = np.full(corrected.shape, np.nan)
        filled = fill_h | fill_xy
        if filled.any():
            adjusted[filled] = work.from_work(corrected[filled])
        new_guess[fill_h, 2] = adjusted[fill_h, 2]
        new_guess[fill_xy, :2] = adjusted[fill_xy, :2]
        # The pass's input guess came back unchanged (always so when every
        # control point is full): another pass would repeat this one.
        change = float(np.nanmax(np.abs(new_guess - guess)))
        guess = new_guess
        if change < p.pass_tolerance_m:
            converged = along
            break
        work = make_work_frame(p.route, p.crs, guess[active], azimuth)
    return Solution(
        work,
        guess,
        sim,
        deformation,
        selection,
        converged,
        n_pass,
        azimuth,
        p.metres_per_mm,
        p.sigma_plan,
        p.sigma_height,
        active,
        p.control_sigma_xy,
        roll,
    )


def _fit_with_roll(
    p: StripProblem,
    fitted: SimilarityResult,
    roll: float,
    target: FloatArray,
    use_xy: BoolArray,
    use_z: BoolArray,
    line_keep: list[BoolArray],
    polynomial: int | Literal["auto"],
    act_ids: list[str],
) -> tuple[SimilarityResult, DeformationResult | None, KindSelection | None, float, FloatArray]:
    """The polynomials on the similarity turned by ``roll`` about the strip's
    axis, the roll updated until its effect on the relief is negligible.

    Returns the similarity as turned, the deformation (None for the
    similarity alone), the "auto" selection, the roll and the control
    points after the similarity (C, 3)."""
    active = use_xy | use_z
    axis_point = target[active].mean(axis=0)
    sim = fitted
    deformation, selection = None, None
    for turns in range(_MAX_TURNS + 1):
        if roll:
            sim = replace(fitted, transform=_turned_about_x(fitted.transform, roll, axis_point))
        model_xyz = sim.transform.apply(p.strip_xyz)
        line_objs = [
            StraightLine(
                point_ids=tuple(np.asarray(line.point_ids)[keep]),
                xyz=sim.transform.apply(p.strip.points[li[keep]]),
                weight=line.weight,
                name=line.name,
            )
            for line, li, keep in zip(p.lines, p.line_index, line_keep, strict=True)
        ]
        deformation, selection = _fit_polynomial(
            polynomial,
            p.sections,
            model_xyz[active],
            target[active],
            use_xy[active],
            use_z[active],
            p.exp_xy[active],
            p.exp_z[active],
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
        # A long strip bent by its chain leaves the similarity a roll set by
        # the bend, not by the cross-section; the polynomial takes the roll as
        # a shear of Z across the strip, which cannot move the points' Y with
        # their height.  Turn it back into the similarity (and fit the
        # polynomial again) when its effect on the relief matters.
        served_work = sim.transform.apply(p.served[::_ROLL_SAMPLE_STEP])
        turn = _cross_slope(deformation, served_work)
        relief = float(np.std(deformation.correct(served_work)[:, 2]))
        if abs(turn) * relief <= _ROLL_TOLERANCE * p.sigma_plan:
            break
        roll -= float(np.arctan(turn))
    return sim, deformation, selection, roll, model_xyz


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


def _carried(
    sim: SimilarityTransform, work_from: WorkFrame, work_to: WorkFrame
) -> SimilarityTransform | None:
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
    (dw_dy,) = deformation_slopes(deformation, xyz, (1,))
    return float(np.mean(dw_dy[:, 2]))


def _azimuth_step(vector_work: FloatArray) -> float:
    """Angle to add to A0 so that X points along a work-frame vector (Y is left,
    i.e. counter-clockwise, while azimuth is clockwise)."""
    return -float(np.arctan2(vector_work[1], vector_work[0]))


def _fit_polynomial(
    kind: int | Literal["auto"],
    sections: int,
    xyz: FloatArray,
    target: FloatArray,
    use_xy: BoolArray,
    use_z: BoolArray,
    exp_xy: FloatArray,
    exp_z: FloatArray,
    lines: list[StraightLine],
    ids: list[str],
) -> tuple[DeformationResult | None, KindSelection | None]:
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
