"""A strip of independent models (R4 2.2, ``[adjustment] models = "independent"``).

Each pair is oriented on its own in B's base system (both photos rotate, the
base is the model's x axis, B(125)-(136)), and its model is formed there
with the unit base.  The models are then joined to the strip one after the
other, each by a 3D similarity (seven parameters, Horn/Umeyama in closed
form) on its tie points (the points it shares with the previous model,
measured on the three photos of the triple overlap) and on the projection
centre the two models share: the previous model's right centre is the new
model's left one.  That centre is known exactly in both models (it defines
each model's origin or the end of its base), so it takes as much weight as
all the tie points together.

Every tie point is then determined twice, once in each model.  The two
determinations are compared (``tie_difference``, ``tie_rms``: the R4
accuracy criterion of the join) and a tie point whose height difference
exceeds the blunder test's critical value times a robust sigma over the
strip is left out of the joins and reported; finally every point is the mean of its
determinations, every projection centre the mean of its two and every
photo's rotation the mean rotation of its two.

The result is a :class:`~strip_aerotri.results.StripModel` like the
dependent chain's, so that the ground stage, the bundle refinement and the
report take it unchanged.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..errors import GeometryError
from ..geometry.intersection import Intersection, intersect
from ..geometry.rotation import matrix_from_cardan
from ..geometry.similarity import SimilarityTransform, similarity_from_points
from ..observations import ImageObservations
from ..options import BlunderOptions, RelativeOrientationMethod, StripOptions
from ..results import Rejection, RelativeOrientation, StripModel
from .chaining import (
    _orient_pairs,
    _Pairs,
    model_sequence,
    rejected_determinations,
    tie_differences,
    tie_rows,
)

__all__ = ["form_strip_independent"]

#: Ties a join needs besides the shared projection centre (3 points in all).
MIN_TIES = 2


def form_strip_independent(
    observations: ImageObservations,
    options: StripOptions | None = None,
    *,
    photo_index: ArrayLike | None = None,
    blunders: BlunderOptions | None = None,
) -> StripModel:
    """Form a strip from independent models (R4 2.2).

    Parameters and result as :func:`~strip_aerotri.strip.chaining.form_strip`;
    the relative orientation is B's base-system formulation whatever
    ``options.relative_orientation`` says (each pair on its own), and
    ``scale_ratio`` holds the ratio of the joins' scales.  ``tie_difference``
    (model m minus model m - 1, strip units) and ``tie_rms`` are the double
    determinations of the tie points.

    Raises
    ------
    GeometryError
        A pair that cannot be oriented, or a model that shares fewer than
        :data:`MIN_TIES` tie points with the previous one (the join needs
        them and the common projection centre: three points).
    """
    options = dataclasses.replace(
        options or StripOptions(), relative_orientation=RelativeOrientationMethod.BASE
    )
    blunders = blunders or BlunderOptions()
    seq, labels = model_sequence(observations, photo_index)
    rejections: list[Rejection] = []
    pairs = _orient_pairs(observations, options, blunders, seq, labels, rejections)
    left_base, right_base = _base_rotations(pairs.rel)
    unit = _models_in_base_systems(observations, options, pairs, left_base, right_base)
    i_now, i_prev = tie_rows(pairs.row_l, pairs.row_r, observations.photo.shape[0])
    joins = _join(observations, options, blunders, pairs, unit, i_now, i_prev, labels, seq)
    rejections += joins.rejections
    return _strip_model(
        observations, options, seq, pairs, unit, joins, left_base, right_base, labels, rejections
    )


def _base_rotations(rel: RelativeOrientation) -> tuple[FloatArray, FloatArray]:
    """Image -> base-system rotations of the left and the right photo of every
    pair, from B's elements (alpha'1, chi'1, alpha'2, omega'2, chi'2)."""
    e = np.asarray(rel.elements, dtype=np.float64)
    left = np.zeros((e.shape[0], 3))
    left[:, 0], left[:, 2] = e[:, 0], e[:, 1]
    return matrix_from_cardan(left), matrix_from_cardan(e[:, 2:])


def _models_in_base_systems(
    observations: ImageObservations,
    options: StripOptions,
    pairs: _Pairs,
    left_base: FloatArray,
    right_base: FloatArray,
) -> Intersection:
    """Every model in its own base system: left centre at the origin, the
    right one at (1, 0, 0)."""
    model = pairs.model
    left = np.einsum("nij,jn->ni", left_base[model], pairs.left_t)
    right = np.einsum("nij,jn->ni", right_base[model], pairs.right_t)
    return intersect(
        np.array([1.0, 0.0, 0.0]),
        left,
        right,
        method=options.intersection,
        principal_distance=observations.principal_distance,
    )


@dataclasses.dataclass
class _Joins:
    """The similarity of every model to the strip and the tie rows kept."""

    transforms: list[SimilarityTransform]
    tie_ok: BoolArray
    rejections: list[Rejection]


def _join(
    observations: ImageObservations,
    options: StripOptions,
    blunders: BlunderOptions,
    pairs: _Pairs,
    unit: Intersection,
    i_now: IntArray,
    i_prev: IntArray,
    labels: list[str],
    seq: IntArray,
) -> _Joins:
    """Every model joined to the strip, with data snooping of the tie points.

    The joins are fitted (:func:`_fit_joins`), the tie points' double
    determinations compared over the whole strip (:func:`_worst_ties`), the
    worst failing tie of each model left out (when rejecting), and the joins
    fitted again, until no tie fails: as J tested the tie points after each
    scaling of the dependent chain.
    """
    tie_ok = np.ones(i_now.shape[0], dtype=bool)
    rejections: list[Rejection] = []
    ids = observations.photo_ids
    while True:
        transforms = _fit_joins(
            observations, options, pairs, unit, i_now, i_prev, tie_ok, labels, seq
        )
        worst, w, critical = _worst_ties(transforms, pairs, unit, i_now, i_prev, tie_ok, blunders)
        if worst.size == 0:
            break
        for k in worst:
            m = int(pairs.model[i_now[k]])
            difference = _tie_differences(transforms, pairs, unit, i_now[[k]], i_prev[[k]])[0]
            rejections.append(
                Rejection(
                    stage="tie_points",
                    point=observations.point_ids[pairs.point[i_now[k]]],
                    photos=(ids[seq[m - 1]], ids[seq[m]], ids[seq[m + 1]]),
                    component="Z",
                    residual=float(difference[2]),
                    unit="strip units",
                    w=float(w[k]),
                    critical=critical,
                    applied=blunders.rejecting,
                    effect="left out of the join of the independent model and of the strip",
                )
            )
        if not blunders.rejecting:
            break
        tie_ok[worst] = False
        if (~tie_ok).sum() > blunders.max_fraction * tie_ok.size:
            raise GeometryError(
                f"joining the independent models: more than {blunders.max_fraction:.0%} of "
                "the tie points fail the blunder test; the strip cannot be formed reliably"
            )
    return _Joins(transforms, tie_ok, rejections)


def _fit_joins(
    observations: ImageObservations,
    options: StripOptions,
    pairs: _Pairs,
    unit: Intersection,
    i_now: IntArray,
    i_prev: IntArray,
    tie_ok: BoolArray,
    labels: list[str],
    seq: IntArray,
) -> list[SimilarityTransform]:
    """Model m to the strip through model m - 1, on its ties and the shared centre.

    The first model sets the strip system: its left photo turned to
    ``options.first_rotation`` (identity), its left centre at
    ``options.first_position`` (origin), its base ``options.first_base_length``
    long (1).
    """
    n_models = seq.shape[0] - 1
    left_base, _ = _base_rotations(pairs.rel)
    first = np.eye(3) if options.first_rotation is None else np.asarray(options.first_rotation)
    origin = np.zeros(3) if options.first_position is None else np.asarray(options.first_position)
    length = 1.0 if options.first_base_length is None else float(options.first_base_length)
    transforms = [SimilarityTransform(length, first @ left_base[0].T, origin.astype(float))]
    tie_model = pairs.model[i_now]
    ids = observations.photo_ids
    for m in range(1, n_models):
        rows = np.flatnonzero((tie_model == m) & tie_ok)
        if rows.size < MIN_TIES:
            raise GeometryError(
                f"{labels[m]} shares {rows.size} usable tie point(s) with {labels[m - 1]} "
                f"(points measured on all three photos {ids[seq[m - 1]]}, {ids[seq[m]]}, "
                f"{ids[seq[m + 1]]}); joining an independent model needs at least "
                f"{MIN_TIES} besides the common projection centre"
            )
        previous = transforms[m - 1]
        target = previous.apply(np.take(unit.points, i_prev[rows], axis=0))
        source = np.take(unit.points, i_now[rows], axis=0)
        centre = previous.apply(np.array([[1.0, 0.0, 0.0]]))
        transforms.append(
            similarity_from_points(
                np.vstack([source, np.zeros((1, 3))]),
                np.vstack([target, centre]),
                np.append(np.ones(rows.size), float(rows.size)),
            )
        )
    return transforms


def _tie_differences(
    transforms: list[SimilarityTransform],
    pairs: _Pairs,
    unit: Intersection,
    i_now: IntArray,
    i_prev: IntArray,
) -> FloatArray:
    """Each tie point in model m minus the same point in model m - 1, strip system."""
    scale = np.array([t.scale for t in transforms])
    rot = np.stack([t.rotation for t in transforms])
    shift = np.stack([t.translation for t in transforms])

    def to_strip(rows: IntArray) -> FloatArray:
        m = pairs.model[rows]
        xyz: FloatArray = shift[m] + scale[m, None] * np.einsum(
            "nij,nj->ni", rot[m], np.take(unit.points, rows, axis=0)
        )
        return xyz

    return to_strip(i_now) - to_strip(i_prev)


def _worst_ties(
    transforms: list[SimilarityTransform],
    pairs: _Pairs,
    unit: Intersection,
    i_now: IntArray,
    i_prev: IntArray,
    tie_ok: BoolArray,
    blunders: BlunderOptions,
) -> tuple[IntArray, FloatArray, float]:
    """Ties whose double determinations disagree beyond the critical value.

    As J tested the dependent chain, the height differences are tested,
    standardised by a robust sigma over all the strip's ties (1.4826 MAD).
    The plan differences are reported, not tested: along the base the shared
    projection centre holds them to a few per cent of the others, and across
    it they follow each join's geometry (tilts, kappa, the spread of its
    ties), so one sigma for the strip flags error-free ties (measured on
    simulated drone strips: up to 8 sigma); an image blunder large enough to
    matter shows in height, and across the flight in the y-parallax test of
    the relative orientation.  Returns the worst failing tie of
    each model (all failing ones when only reporting), every tie's w and the
    critical value.
    """
    w = np.zeros(i_now.shape[0])
    if not blunders.testing or tie_ok.sum() < 8:
        return np.zeros(0, dtype=np.intp), w, float("inf")
    diff = _tie_differences(transforms, pairs, unit, i_now, i_prev)
    kept = diff[tie_ok, 2]
    centre = float(np.median(kept))
    sigma = 1.4826 * float(np.median(np.abs(kept - centre)))
    # floor: exact data leave differences at the level of the orientation's convergence
    sigma = max(sigma, 1e-10 * max(float(np.abs(kept).max()), 1.0))
    w = np.where(tie_ok, np.abs(diff[:, 2] - centre) / sigma, 0.0)
    critical = blunders.critical("tie_points", int(tie_ok.sum()))
    failing = w > critical
    if not failing.any():
        return np.zeros(0, dtype=np.intp), w, critical
    if not blunders.rejecting:
        return np.flatnonzero(failing), w, critical
    tie_model = pairs.model[i_now]
    order = np.lexsort((np.where(failing, w, -1.0), tie_model))
    last = np.r_[tie_model[order][1:] != tie_model[order][:-1], True]
    pick = order[last]
    worst: IntArray = pick[failing[pick]]
    return worst, w, critical


def _strip_model(
    observations: ImageObservations,
    options: StripOptions,
    seq: IntArray,
    pairs: _Pairs,
    unit: Intersection,
    joins: _Joins,
    left_base: FloatArray,
    right_base: FloatArray,
    labels: list[str],
    rejections: list[Rejection],
) -> StripModel:
    """The joined models as one strip model: points, centres and rotations
    averaged over their determinations."""
    n_models = seq.shape[0] - 1
    model, point = pairs.model, pairs.point
    scale = np.array([t.scale for t in joins.transforms])
    rot = np.stack([t.rotation for t in joins.transforms])
    shift = np.stack([t.translation for t in joins.transforms])
    model_points = shift[model] + scale[model, None] * np.einsum(
        "nij,nj->ni", rot[model], unit.points
    )
    i_now, i_prev = tie_rows(pairs.row_l, pairs.row_r, observations.photo.shape[0])
    rejected_rows, rejected = rejected_determinations(
        point, model, i_now, i_prev, joins.tie_ok, observations.n_points
    )
    usable = ~rejected_rows
    counts = np.bincount(point[usable], minlength=observations.n_points)
    points = np.full((observations.n_points, 3), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        for k in range(3):
            sums = np.bincount(point[usable], model_points[usable, k], observations.n_points)
            points[:, k] = sums / counts
    points[counts == 0] = np.nan

    # the photos: left centre of model m and right centre of model m - 1
    left_centre = shift
    right_centre = shift + scale[:, None] * rot[:, :, 0]
    centres = np.empty((n_models + 1, 3))
    centres[0], centres[-1] = left_centre[0], right_centre[-1]
    centres[1:-1] = 0.5 * (left_centre[1:] + right_centre[:-1])
    as_left = rot @ left_base
    as_right = rot @ right_base
    rotations = np.empty((n_models + 1, 3, 3))
    rotations[0], rotations[-1] = as_left[0], as_right[-1]
    rotations[1:-1] = _mean_rotation(as_left[1:], as_right[:-1])

    i_now, i_prev = i_now[joins.tie_ok], i_prev[joins.tie_ok]
    tie_model = model[i_now]
    tie_count = np.bincount(tie_model, minlength=n_models).astype(np.intp)
    tie_difference, tie_rms = tie_differences(model_points, i_now, i_prev, tie_model, tie_count)
    ratio = np.ones(n_models)
    ratio[1:] = scale[1:] / scale[:-1]
    return StripModel(
        observations=observations,
        options=options,
        photo_index=seq,
        centres=centres,
        rotations=rotations,
        relative=pairs.rel,
        scale=scale,
        scale_ratio=ratio,
        points=points,
        n_determinations=counts.astype(np.intp),
        model=model,
        model_point=point,
        model_points=model_points,
        model_parallax=scale[model] * unit.parallax,
        tie_model=tie_model,
        tie_point=point[i_now],
        tie_difference=tie_difference,
        tie_count=tie_count,
        tie_rms=tie_rms,
        model_labels=tuple(labels),
        rejections=tuple(rejections),
        rejected_points=tuple(observations.point_ids[i] for i in rejected),
        rejected_determinations=rejected_rows,
        model_rows=np.column_stack([pairs.row_l, pairs.row_r]),
        breaks=np.zeros(0, dtype=np.intp),
    )


def _mean_rotation(a: FloatArray, b: FloatArray) -> FloatArray:
    """The rotation nearest (Frobenius) to the mean of two rotations, per row."""
    u, _, vt = np.linalg.svd(a + b)
    d = np.sign(np.linalg.det(u @ vt))
    u[:, :, 2] *= d[:, None]
    mean: FloatArray = u @ vt
    return mean
