"""Check a loaded project without adjusting it: :func:`check_project`.

Loading (files, columns, ids, options) stops at the first problem, as
:func:`strip_aerotri.project.load_project` does.  The geometric checks that
follow list every problem, each by the rule of the stage that applies it
(one rule, one place):

* each consecutive pair has at least five points measured on both photos
  (:func:`strip_aerotri.strip.relative.pair_count_problems`, J(5)-(10));
* each model after the first shares at least one tie point with the previous
  model (a point measured on all three photos; scale transfer, J(15)); with
  ``block = "models"`` a model without one is the break the run takes, and
  each run of models between breaks carries itself on its own control;
* enough control for the similarity
  (:func:`strip_aerotri.geometry.similarity.control_count_problems`, J(14)),
  the plan points not coinciding and the height points not all in one
  vertical plane;
* enough control for the chosen deformation polynomial
  (:func:`strip_aerotri.geometry.deformation.polynomial_count_problems`, J(16));
* control not mirrored against the photos
  (:func:`strip_aerotri.plausibility.control_problems`);
* on the formed strip, control heights in the plan control's unit
  (:func:`strip_aerotri.ground.polynomials.height_unit_check`, the ground
  stage's rule);
* every straight-line point is measured on both photos of a pair (J(18));
* the output folder may be written.

When the counts allow it, the strip is then formed as the run forms it
(relative orientation of every pair, the photos' order, scale transfer), so
that a pair that cannot be oriented or photos listed against the flight are
found here too, and a block's strips are placed on the control as the run
places them; the ground stage is not run.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..errors import StripAerotriError
from ..geometry.deformation import n_terms, polynomial_count_problems
from ..geometry.similarity import (
    COINCIDENT_RTOL,
    COLLINEAR_MAGNIFICATION,
    COLLINEAR_RTOL,
    control_count_problems,
    cross_tilt,
)
from ..plausibility import (
    control_coverage_problems,
    control_problems,
    image_sigma_problems,
    photo_order_hint,
)
from ..strip.chaining import pair_rows
from ..strip.densify import first_model_step, model_photo_index
from ..strip.relative import MIN_POINTS_PER_PAIR, pair_count_problems
from .output import output_folder

if TYPE_CHECKING:
    from .._typing import BoolArray, FloatArray, IntArray
    from ..observations import ImageObservations
    from ..results import StripModel
    from .model import Project

__all__ = ["CheckReport", "check_project"]


@dataclass
class CheckReport:
    """Findings of :func:`check_project`.

    Attributes
    ----------
    problems : list of str
        Rules broken (each one line naming the file and the pair, model or points).
    warnings : list of str
        Valid but doubtful findings.
    summary : list of str
        Lines describing the project.
    details : list of str
        Per-pair figures (shown with ``-v``).
    """

    problems: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    summary: list[str] = field(default_factory=list)
    details: list[str] = field(default_factory=list)


def _quote(ids: Iterable[str], limit: int = 8) -> str:
    ids = list(ids)
    text = ", ".join(f"'{i}'" for i in ids[:limit])
    return text + (f" and {len(ids) - limit} more" if len(ids) > limit else "")


def _plan_metres(xy: np.ndarray, geographic: bool) -> np.ndarray:
    """Plan coordinates scaled to comparable units (degrees of longitude shrunk by cos φ)."""
    if not geographic or xy.shape[0] == 0:
        return xy
    lat = np.deg2rad(np.mean(xy[:, 1]))
    return np.column_stack([xy[:, 0] * np.cos(lat), xy[:, 1]])


#: When a strip cannot be formed (other problems), the check estimates how far
#: the strip reaches from the control and check points widened by a photo's
#: footprint, which exceeds the run's reach by up to this factor: it then
#: refuses height control in nearly one plane only when it is magnified more
#: than this times COLLINEAR_MAGNIFICATION, and warns between 1 and this times.
#: A formed strip is judged by the run's own rule instead
#: (:func:`_check_height_plane`), and a block by the run's placement of its
#: strips (:func:`_check_placement`).
_CHECK_MARGIN = 3.0


def _footprint_radius(
    obs: ImageObservations,
    control_point: IntArray,
    has_plan: BoolArray,
    control_xy: FloatArray,
) -> float | None:
    """Median ground radius of a photo's footprint, in the unit of `control_xy`.

    A photo's scale is the spread of the plan control measured on it over the
    spread of their image coordinates (two or more such points; tilt and
    relief ignored), its radius that scale times the farthest image point
    measured on it.  `control_point`: each control row's point index in `obs`
    (-1 if absent); `control_xy`: plan coordinates of the rows `has_plan`.
    None when no photo shows two plan control points apart.
    """
    xy_rows = np.full((has_plan.size, 2), np.nan)
    xy_rows[has_plan] = control_xy - control_xy.mean(axis=0)  # small numbers to square
    which = np.full(obs.n_points, -1, dtype=np.intp)
    rows = np.flatnonzero((control_point >= 0) & has_plan)
    which[control_point[rows]] = rows
    k = which[obs.point]
    on = k >= 0
    photo = obs.photo[on]

    def spread(xy: FloatArray) -> tuple[IntArray, FloatArray]:
        # sum of squared distances from each photo's centroid
        n = np.bincount(photo, minlength=obs.n_photos)
        sums = [np.bincount(photo, xy[:, c], minlength=obs.n_photos) for c in (0, 1)]
        squares = np.bincount(photo, np.einsum("ij,ij->i", xy, xy), minlength=obs.n_photos)
        with np.errstate(invalid="ignore", divide="ignore"):
            return n, squares - (sums[0] ** 2 + sums[1] ** 2) / n

    n, image = spread(obs.xy[on])
    _, ground = spread(xy_rows[k[on]])
    ok = (n >= 2) & (image > 1e-6 * np.maximum(n, 1)) & (ground > 0.0)  # apart by > 1 µm
    if not ok.any():
        return None
    farthest = np.zeros(obs.n_photos)
    np.maximum.at(farthest, obs.photo, np.hypot(obs.xy[:, 0], obs.xy[:, 1]))
    return float(np.median(np.sqrt(ground[ok] / image[ok]) * farthest[ok]))


def check_project(project: Project, out: Path | None = None) -> CheckReport:
    """Check the geometry of a loaded project without adjusting it.

    Parameters
    ----------
    project : Project
        A project from :func:`~strip_aerotri.project.load_project`.
    out : Path, optional
        The ``--out`` folder a run would use.

    Returns
    -------
    CheckReport
    """
    rep = CheckReport()
    if project.is_block:
        return _check_block(rep, project, out)
    facts = _check_pairs(rep, project)
    # Control not mirrored against the photos: the run's own check
    # (strip_aerotri.plausibility).
    rep.problems += control_problems(
        project.observations, project.control, project.crs, str(project.control_file)
    )
    plan_ids, height_ids, plane = _check_control(rep, project, facts.triangulable)
    formed = _check_formation(rep, project)
    if formed is not None and len(height_ids) >= 3:
        _check_height_plane(rep, project, formed, height_ids)  # as the run judges it
    else:
        _add_plane(rep, plane)
    if formed is not None:
        _check_breaks(rep, project, formed)
        _check_height_units(rep, project, formed)
    _doubts(rep, project, formed)
    _check_lines(rep, project, facts.triangulable)
    _check_polynomial(rep, project, plan_ids, height_ids)
    # Output folder.
    try:
        target = output_folder(project, out)
    except StripAerotriError as exc:
        rep.problems.append(str(exc))
        target = None

    _summarize(rep, project, facts, plan_ids, height_ids, target)
    return rep


def _doubts(rep: CheckReport, project: Project, formed: StripModel | None) -> None:
    """The run's warnings about a strip's input that need no adjustment: its
    ends beyond the control, an image sigma far from the pairs' scatter
    (:mod:`strip_aerotri.plausibility`)."""
    rep.warnings += control_coverage_problems(
        project.observations, project.control, str(project.control_file)
    )
    rep.warnings += _sigma_doubt(project, () if formed is None else (formed,))


def _sigma_doubt(project: Project, formed: Sequence[StripModel]) -> list[str]:
    """The run's warning of an image sigma far from the scatter of the formed
    strips' pairs (a block's over all its strips, as its run judges it)."""
    if not formed:
        return []
    pairs = np.concatenate([strip.relative.sigma0_um for strip in formed])
    return image_sigma_problems(pairs, project.observations.sigma)


def _check_block(rep: CheckReport, project: Project, out: Path | None) -> CheckReport:
    """A block: every strip's pairs, tie points and formation as a strip of its
    own (problems prefixed with the strip's name); the control over the whole
    block (a strip may lean on its neighbours); the image sigma against the
    pairs of every strip formed."""
    from ..block.strips import strip_observations

    triangulable = np.zeros(project.observations.n_points, dtype=bool)
    per_strip: list[str] = []
    seen_by = []
    formed: list[StripModel | None] = []
    for spec in project.strips:
        sub = dataclasses.replace(
            project,
            observations=strip_observations(project.observations, spec.photo_ids),
            photo_ids=spec.photo_ids,
            strips=(),
        )
        own = CheckReport()
        seen_by.append(np.unique(sub.observations.point))
        facts = _check_pairs(own, sub)
        if not own.problems:
            formed.append(_check_formation(own, sub, spec.name))
        triangulable |= facts.triangulable
        if facts.n_models:
            ties = (
                f", tie points per model {int(facts.ties[1:].min())}..{int(facts.ties[1:].max())}"
                if facts.n_models > 1
                else ""
            )
            per_strip.append(
                f"strip '{spec.name}': {len(spec.photo_ids)} photos, {facts.n_models} pairs, "
                f"{int(facts.counts.min())}..{int(facts.counts.max())} common points{ties}"
            )
        rep.problems += [_in_strip(p, spec.name, project) for p in own.problems]
        rep.warnings += [_in_strip(w, spec.name, project) for w in own.warnings]
        rep.details += [_in_strip(d, spec.name, project) for d in own.details]
    rep.problems += control_problems(
        project.observations, project.control, project.crs, str(project.control_file)
    )
    plan_ids, height_ids, _ = _check_control(rep, project, triangulable)
    strips = tuple(s for s in formed if s is not None)
    if not rep.problems and len(strips) == len(project.strips):
        _check_placement(rep, project, strips)  # the run's own rule
    rep.warnings += _sigma_doubt(project, strips)
    _check_lines(rep, project, triangulable)
    try:
        target = output_folder(project, out)
    except StripAerotriError as exc:
        rep.problems.append(str(exc))
        target = None
    kinds = [k.value for k in project.control.kind]
    by_kind = ", ".join(f"{kinds.count(k)} {k}" for k in ("full", "plan", "height", "check"))
    rep.summary += [
        f"project '{project.name}': {project.path}",
        f"block: {len(project.strips)} strips, {len(project.photo_ids)} photos "
        f"({', '.join(f'{s.name}: {len(s.photo_ids)}' for s in project.strips)})",
        *per_strip,
        *_common_points(project, seen_by),
        f"image points: {project.observations.n_points} on {len(project.observations.photo)} "
        f"observations, {int(triangulable.sum())} measured on a pair",
        f"control: {by_kind}; usable {len(plan_ids)} plan, {len(height_ids)} height",
        f"straight lines: {len(project.straight_lines)}",
        f"crs: {project.crs}; route {project.adjustment.route.value}; "
        f"block = {project.adjustment.block.value}",
    ]
    if target is not None:
        rep.summary.append(f"output folder: {target}")
    return rep


def _common_points(project: Project, seen_by: list[IntArray]) -> list[str]:
    """A line per two strips that share measured points (the side overlap
    that ties them), and the strips that share none with any other."""
    lines = []
    tied: set[int] = set()
    names = [s.name for s in project.strips]
    for i in range(len(seen_by)):
        for j in range(i + 1, len(seen_by)):
            n = int(np.intersect1d(seen_by[i], seen_by[j], assume_unique=True).size)
            if n:
                lines.append(f"strips '{names[i]}' / '{names[j]}': {n} common points")
                tied.update((i, j))
    alone = [names[k] for k in range(len(names)) if k not in tied]
    if alone:
        lines.append(f"strips without a point in common with another: {', '.join(alone)}")
    return lines


class _PairFacts(NamedTuple):
    step: int
    n_models: int
    counts: np.ndarray
    ties: np.ndarray
    triangulable: np.ndarray


def _check_pairs(rep: CheckReport, project: Project) -> _PairFacts:
    """Pairs (points on both photos, as strip formation takes them) and tie points."""
    obs = project.observations
    images = project.images_file
    all_ids = obs.photo_ids
    n_photos = obs.n_photos
    # Models on every k-th photo with [adjustment] photo_step = k (densify); "auto"
    # chooses k from a first relative orientation, so it is checked as k = 1.
    step = first_model_step(project.adjustment.photo_step)  # the run's own rule
    seq = model_photo_index(n_photos, step)
    ids = [all_ids[i] for i in seq]
    n_models = len(seq) - 1
    labels = [f"pair {ids[m]}-{ids[m + 1]}" for m in range(n_models)]

    # Pairs: points on both photos (same rows as strip formation).
    model, point, _, _ = pair_rows(obs, seq)
    counts = np.bincount(model, minlength=n_models)
    rep.problems += [f"{images}: {p}" for p in pair_count_problems(counts, labels)]

    # Tie points: a point determined in model m and in model m - 1.
    n_pts = max(obs.n_points, 1)
    key_now = model.astype(np.int64) * n_pts + point
    key_prev = (model.astype(np.int64) + 1) * n_pts + point
    _, i_now, _ = np.intersect1d(key_now, key_prev, assume_unique=True, return_indices=True)
    ties = np.bincount(model[i_now], minlength=n_models)
    # With every model transformed on its own (block = "models") a model
    # without ties is a break the run takes, each side on its own control
    # (_check_breaks); J's chain cannot transfer the scale across it.
    breaks = project.adjustment.allow_breaks
    (rep.warnings if breaks else rep.problems).extend(
        f"{images}: {labels[m]} shares no tie point with {labels[m - 1]} (no point is "
        f"measured on all three photos {ids[m - 1]}, {ids[m]}, {ids[m + 1]}): the scale "
        + (
            'is not carried across it: with block = "models" the models after it take '
            "theirs from the control (in a block, also from the neighbouring strips)"
            if breaks
            else "cannot be transferred"
        )
        for m in np.flatnonzero(ties[1:] == 0) + 1
    )
    failing = np.flatnonzero(counts < MIN_POINTS_PER_PAIR)
    if not breaks:  # a model without ties: its pair and the one before it
        untied = np.flatnonzero(ties[1:] == 0) + 1
        failing = np.concatenate([failing, untied, untied - 1])
    _, order = photo_order_hint(obs, seq, failing, MIN_POINTS_PER_PAIR)
    if order:
        rep.problems.append(f"{images}: {order}")
    rep.details += [
        f"{labels[m]}: {int(counts[m])} common points, "
        + ("first model" if m == 0 else f"{ties[m]} tie points with the previous model")
        for m in range(n_models)
    ]

    triangulable = np.zeros(obs.n_points, dtype=bool)
    if step == 1:
        triangulable[point] = True
    else:  # the other photos are resected and every point intersected from all its rays
        triangulable = np.bincount(obs.point, minlength=obs.n_points) >= 2
    return _PairFacts(step, n_models, counts, ties, triangulable)


class _Plane(NamedTuple):
    """Height control in one vertical plane, as judged before the strip is
    formed: a problem or a warning (``problem``) and its line."""

    problem: bool
    text: str


def _check_control(
    rep: CheckReport, project: Project, triangulable: np.ndarray
) -> tuple[list[str], list[str], _Plane | None]:
    """Enough control for the similarity, not degenerate; returns the ids of the
    usable plan and height control, and the finding on height control in one
    vertical plane (left to the caller: the formed strip judges it as the run
    does)."""
    obs = project.observations
    control_file = project.control_file
    # Control.
    ctrl = project.control
    lookup = {pid: i for i, pid in enumerate(obs.point_ids)}
    row_point = np.array([lookup.get(p, -1) for p in ctrl.point_ids], dtype=np.intp)
    ok = np.zeros(len(ctrl.point_ids), dtype=bool)
    ok[row_point >= 0] = triangulable[row_point[row_point >= 0]]
    lost = [p for p, good in zip(ctrl.point_ids, ok, strict=True) if not good]
    if lost:
        rep.warnings.append(
            f"{control_file}: {len(lost)} control or check point(s) not measured on both photos "
            f"of any pair cannot be triangulated and will be left out: {_quote(lost)}"
        )
    uses_xy = ctrl.uses_xy & ok
    uses_h = ctrl.uses_h & ok
    plan_ids = [ctrl.point_ids[i] for i in np.flatnonzero(uses_xy)]
    height_ids = [ctrl.point_ids[i] for i in np.flatnonzero(uses_h)]
    n_plan, n_height = len(plan_ids), len(height_ids)
    plane: _Plane | None = None
    geographic = False
    if not project.is_local:
        import pyproj

        geographic = pyproj.CRS.from_user_input(project.crs).is_geographic

    count_problems = control_count_problems(plan_ids, height_ids)
    rep.problems += [f"{control_file}: the {p}" for p in count_problems]
    if n_plan >= 2:
        xy = _plan_metres(ctrl.xyz[uses_xy, :2], geographic)
        spread = float(np.max(np.ptp(xy, axis=0)))
        every = _plan_metres(ctrl.xyz[:, :2][np.isfinite(ctrl.xyz[:, :2]).all(axis=1)], geographic)
        extent = float(np.max(np.ptp(every, axis=0)))
        if spread == 0.0 or spread <= COINCIDENT_RTOL * extent:
            rep.problems.append(
                f"{control_file}: the plan control points coincide (scale and azimuth are "
                f"undetermined): {_quote(plan_ids)}"
            )
    if n_height >= 3:
        hxy = ctrl.xyz[uses_h, :2]
        if np.isfinite(hxy).all():
            plan_all = np.asarray(np.isfinite(ctrl.xyz[:, :2]).all(axis=1), dtype=bool)
            known_xy = _plan_metres(ctrl.xyz[plan_all, :2], geographic)
            hxy = _plan_metres(hxy, geographic)
            ratio, _ = cross_tilt(hxy)
            if ratio < COLLINEAR_RTOL:
                # The run judges by the strip's points (similarity.cross_tilt);
                # here they are the control and check points widened by one
                # photo's footprint, which overstates r up to about 2.5 times.
                radius = _footprint_radius(obs, row_point, plan_all, known_xy)
                _, tilt_magnified = cross_tilt(hxy, known_xy, radius or 0.0)
                magnified = np.inf if tilt_magnified is None else tilt_magnified
                text = (
                    f"{control_file}: the height control points all lie in one vertical plane "
                    f"(collinear in plan, singular value ratio {ratio:.1e}"
                )
                if radius is None:
                    if magnified > COLLINEAR_MAGNIFICATION:
                        plane = _Plane(
                            True,
                            f"{text}); the tilt across it is undetermined: {_quote(height_ids)}",
                        )
                    else:
                        plane = _Plane(
                            False,
                            f"{text}); no photo shows two plan control points to size the strip, "
                            "so whether the tilt across it is determined is decided by the run: "
                            f"{_quote(height_ids)}",
                        )
                elif magnified > _CHECK_MARGIN * COLLINEAR_MAGNIFICATION:
                    plane = _Plane(
                        True,
                        f"{text}; an error of their heights reaches the strip's edge about "
                        f"{magnified:.0f} times magnified); the tilt across it is undetermined: "
                        f"{_quote(height_ids)}",
                    )
                elif magnified > COLLINEAR_MAGNIFICATION:
                    plane = _Plane(
                        False,
                        f"{text}; an error of their heights may reach the strip's edge up to "
                        f"{magnified:.0f} times magnified); the run refuses the tilt above "
                        f"{COLLINEAR_MAGNIFICATION:.0f}: {_quote(height_ids)}",
                    )
    return plan_ids, height_ids, plane


def _add_plane(rep: CheckReport, plane: _Plane | None) -> None:
    """The finding of :func:`_check_control` on height control in one plane."""
    if plane is not None:
        (rep.problems if plane.problem else rep.warnings).append(plane.text)


def _check_height_plane(
    rep: CheckReport, project: Project, strip: StripModel, height_ids: list[str]
) -> None:
    """Height control in one vertical plane judged on the formed strip by the
    run's own rule (:func:`~strip_aerotri.geometry.similarity.height_plane_verdict`
    over the points the similarity serves, in the strip's frame)."""
    from ..geometry.similarity import height_plane_verdict
    from ..ground.polynomials import served_points

    lookup = {pid: i for i, pid in enumerate(project.observations.point_ids)}
    rows = np.array([lookup[p] for p in height_ids], dtype=np.intp)
    xy = strip.points[rows, :2]
    known = np.asarray(np.isfinite(xy).all(axis=1), dtype=bool)
    ids = [height_ids[i] for i in np.flatnonzero(known)]
    if len(ids) < 3:
        return
    error, warning = height_plane_verdict(xy[known], served_points(strip)[:, :2], ids)
    if error is not None:
        rep.problems.append(f"{project.control_file}: the {error}")
    elif warning is not None:
        rep.warnings.append(f"{project.control_file}: the {warning}")


def _check_height_units(rep: CheckReport, project: Project, strip: StripModel) -> None:
    """Control heights in another unit than the plan control, judged on the
    formed strip by the ground stage's own rule
    (:func:`~strip_aerotri.ground.polynomials.height_unit_check`)."""
    if rep.problems:
        return  # the control's count or geometry is already wrong
    from ..ground.polynomials import height_unit_check

    rep.problems += height_unit_check(
        strip,
        project.control,
        project.crs,
        project.adjustment.route,
        control_name=str(project.control_file),
    )


def _check_formation(
    rep: CheckReport, project: Project, strip: str | None = None
) -> StripModel | None:
    """The strip formed as the run forms it, when the counts allow it
    (``strip``: the strip of a block that ``project`` stands for); None
    when it was not formed."""
    images = project.images_file
    obs = project.observations
    # Strip formation as the run does it (relative orientation of every pair,
    # photos in flight order, scale transfer), when the counts allow it.
    if not rep.problems:
        from ..errors import FlightAxisError, PhotoOrderError
        from ..pipeline import form_strip_of
        from .run import explain

        try:
            return form_strip_of(obs, project.adjustment, blunders=project.blunders)
        except PhotoOrderError as exc:
            # the order is the project file's ([strip] or [[strips]] photos)
            rep.problems.append(f"{project.path}: {_strip_free(explain(project, exc, strip))}")
        except FlightAxisError as exc:
            rep.problems.append(f"{images}: {_strip_free(explain(project, exc, strip))}")
        except StripAerotriError as exc:
            rep.problems.append(f"{images}: {exc}")
    return None


def _check_placement(rep: CheckReport, project: Project, strips: tuple[StripModel, ...]) -> None:
    """A block's strips placed on the control as the run places them
    (:mod:`strip_aerotri.block.problem`): a strip by its own similarity
    (J's rules for its control, height points in one vertical plane judged
    over the strip's points), the others by their common points with the
    strips placed."""
    from ..block.problem import _start_in_crs
    from ..errors import GeometryError, HeightUnitError
    from ..geodesy import GroundCRS

    try:
        _start_in_crs(
            project.observations,
            project.control,
            GroundCRS.from_user_input(project.crs),
            project.strips,
            strips,
            control_name=str(project.control_file),
        )
    except HeightUnitError as exc:
        rep.problems.append(str(exc))  # it names the control file
    except GeometryError as exc:
        rep.problems.append(f"{project.control_file}: {exc}")


def _check_breaks(rep: CheckReport, project: Project, strip: StripModel) -> None:
    """Each run of models between breaks (a model sharing no tie point with
    the one before, which ``block = "models"`` takes) carries itself on its
    own control, by J's rules for a similarity as the run applies them
    (:func:`~strip_aerotri.geometry.control_geometry._validate_control_geometry`
    on the run's control, in the strip and in the control's frames)."""
    from ..errors import GeometryError, StripAerotriWarning
    from ..geometry.control_geometry import _validate_control_geometry

    breaks = np.asarray(strip.breaks, dtype=np.intp)
    if breaks.size == 0:
        return
    ctrl = project.control
    lookup = {pid: i for i, pid in enumerate(project.observations.point_ids)}
    point = np.array([lookup.get(p, -1) for p in ctrl.point_ids], dtype=np.intp)
    src = np.where((point >= 0)[:, None], strip.points[np.maximum(point, 0)], np.nan)
    known = np.isfinite(src).all(axis=1)
    geographic = not project.is_local and _is_geographic(project.crs)
    target = np.column_stack([_plan_metres(ctrl.xyz[:, :2], geographic), ctrl.xyz[:, 2]])
    labels = strip.model_labels or tuple(f"model {m + 1}" for m in range(strip.n_models))
    edges = [0, *breaks.tolist(), strip.n_models]
    for lo, hi in pairwise(edges):
        in_run = np.zeros(project.observations.n_points, dtype=bool)
        in_run[strip.model_point[(strip.model >= lo) & (strip.model < hi)]] = True
        here = known & in_run[np.maximum(point, 0)] & (point >= 0) & ~ctrl.is_check
        ids = tuple(np.asarray(ctrl.point_ids)[here].tolist())
        try:
            with warnings.catch_warnings():  # the run's warnings are the ground stage's
                warnings.simplefilter("ignore", StripAerotriWarning)
                _validate_control_geometry(
                    src[here], target[here], ctrl.uses_xy[here], ctrl.uses_h[here], ids
                )
        except GeometryError as exc:
            rep.problems.append(
                f"{project.control_file}: the models {labels[lo]} to {labels[hi - 1]}, between "
                f"breaks (no tie point to carry the scale across), have too little control "
                f"of their own: {exc}"
            )


def _is_geographic(crs: str) -> bool:
    import pyproj

    return bool(pyproj.CRS.from_user_input(crs).is_geographic)


def _in_strip(message: str, strip: str, project: Project) -> str:
    """``message`` of one strip of a block with ``strip 'name': `` after the
    input file it begins with, if any (as ``run`` and every message: file first)."""
    for name in map(str, project.input_files):
        if message.startswith(f"{name}: "):
            return f"{name}: strip '{strip}': {message[len(name) + 2 :]}"
    return f"strip '{strip}': {message}"


def _strip_free(exc: Exception) -> str:
    """The message without its "strip 'name': " prefix (a block's check adds it)."""
    strip = getattr(exc, "strip", None)
    text = str(exc)
    prefix = f"strip '{strip}': "
    return text[len(prefix) :] if strip is not None and text.startswith(prefix) else text


def _check_lines(rep: CheckReport, project: Project, triangulable: np.ndarray) -> None:
    lookup = {pid: i for i, pid in enumerate(project.observations.point_ids)}
    # Straight lines.
    for i, line in enumerate(project.straight_lines, start=1):
        missing = [p for p in line.point_ids if not triangulable[lookup[p]]]
        if missing:
            rep.problems.append(
                f"{project.path}: [[straight_line]] #{i} ('{line.name}'): point(s) "
                f"{_quote(missing)} are not measured on both photos of any pair"
            )


def _check_polynomial(
    rep: CheckReport, project: Project, plan_ids: list[str], height_ids: list[str]
) -> None:
    control_file = project.control_file
    n_plan, n_height = len(plan_ids), len(height_ids)
    # Polynomial (J's construction only; with block = "models" every model has
    # its own similarity).
    kind = project.adjustment.polynomial
    sections = project.adjustment.sections
    strips = project.adjustment.block.value
    if strips == "strips" and kind != "auto" and n_plan >= 2 and n_height >= 3:
        where = (
            f" ([adjustment] polynomial{' and sections' if sections > 1 else ''} in "
            f"{project.path})"
        )
        rep.problems += [
            f"{control_file}: {p}{where}"
            for p in polynomial_count_problems(
                (int(kind),) * 3, sections, plan_ids, height_ids, project.straight_lines
            )
        ]


def _summarize(
    rep: CheckReport,
    project: Project,
    facts: _PairFacts,
    plan_ids: list[str],
    height_ids: list[str],
    target: Path | None,
) -> None:
    obs = project.observations
    ctrl = project.control
    all_ids, n_photos = obs.photo_ids, obs.n_photos
    step, n_models, counts, ties = facts.step, facts.n_models, facts.counts, facts.ties
    triangulable = facts.triangulable
    n_plan, n_height = len(plan_ids), len(height_ids)
    kind = project.adjustment.polynomial
    sections = project.adjustment.sections
    in_sections = f" in {sections} sections" if sections > 1 else ""
    strips = project.adjustment.block.value
    kinds = [k.value for k in ctrl.kind]
    by_kind = ", ".join(f"{kinds.count(k)} {k}" for k in ("full", "plan", "height", "check"))
    tie_text = (
        f"; tie points per model {int(ties[1:].min())}..{int(ties[1:].max())}"
        if n_models > 1
        else ""
    )
    poly = (
        f"auto{in_sections}"
        if kind == "auto"
        else f"{kind}{in_sections} (needs {n_terms(int(kind), sections)} per coordinate)"
    )
    rep.summary += [
        f"project '{project.name}': {project.path}",
        f"photos: {n_photos} ({all_ids[0]} ... {all_ids[-1]}), {n_models} pairs"
        + (f" (models on every {_ordinal(step)} photo)" if step > 1 else ""),
        f"image points: {obs.n_points} on {len(obs.photo)} observations, "
        f"{int(triangulable.sum())} measured on a pair",
        f"pairs: {int(counts.min())}..{int(counts.max())} common points{tie_text}",
        f"control: {by_kind}; usable {n_plan} plan, {n_height} height",
        f"straight lines: {len(project.straight_lines)}",
    ]
    for what, observed, source in (
        ("GNSS centres", project.gnss, project.gnss_file),
        ("IMU attitudes", project.imu, project.imu_file),
    ):
        if observed is not None:
            rep.summary.append(
                f"{what}: {len(observed.photo_ids)} of {n_photos} photos ({source})"
            )
    construction = (
        f"polynomial {poly}" if strips == "strips" else "every model at once (block = models)"
    )
    rep.summary += [
        f"crs: {project.crs}; route {project.adjustment.route.value}; {construction}",
    ]
    if target is not None:
        rep.summary.append(f"output folder: {target}")


def _ordinal(n: int) -> str:
    """English ordinal: 2nd, 3rd, 4th, 11th, 21st."""
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"
