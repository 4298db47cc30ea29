"""Strip formation: relative orientation, model formation, scale transfer and
chaining of the models into one strip model (method.md §1-5).

The strip system is defined as in J (first photo at the origin with the
identity rotation, first base ``b_x = 1``) or by a given first exterior
orientation and base length as in B.  Every step works on the points of all
pairs at once; only the chain of 3 × 3 rotations and the cumulative scale and
position run along the strip.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._stats import sample_median
from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..blunders import robust_variance_factor
from ..errors import GeometryError
from ..geometry.intersection import (
    Intersection,
    intersect_normal,
    midpoint_along_y_components,
)
from ..observations import ImageObservations
from ..options import BlunderOptions, IntersectionMethod, StripOptions
from ..plausibility import ray_direction_problems
from ..results import Rejection, RelativeOrientation, StripModel
from ..results.strip import BASE_UNITS
from .relative import COLLINEAR_RATIO, collinear_ratio, relative_orientation
from .scaling import scale_ratios

__all__ = ["StripModel", "StripOptions", "form_strip"]


def pair_rows(
    observations: ImageObservations, photo_index: IntArray
) -> tuple[IntArray, IntArray, IntArray, IntArray]:
    """Observations of the points measured on both photos of each model.

    Returns
    -------
    model, point, left_row, right_row : ndarray of int, shape (n,)
        Sorted by model, then point; ``left_row`` and ``right_row`` index the
        observations on the model's left and right photo.
    """
    n_seq = photo_index.shape[0]
    position = np.full(observations.n_photos, -1, dtype=np.int64)
    position[photo_index] = np.arange(n_seq)
    t = position[observations.photo]
    n_pts = np.int64(max(observations.n_points, 1))
    # Keys (position in the strip, point), negative on photos not in the
    # sequence; sorted already when the sequence runs in photo order
    # (observations are sorted by photo, then point).
    key = t * n_pts + observations.point
    order = None
    if key.size > 1 and not bool((key[1:] > key[:-1]).all()):
        order = np.argsort(key, kind="stable")
        key = key[order]
    # The row of (t + 1, p) for every (t, p), by binary search over the
    # window of keys that a chunk of the (sorted) queries can reach: the
    # search does not depend on how point ids are numbered (a sort by point,
    # the other way, takes 4x longer when the ids do not follow the flight).
    wanted = key + n_pts
    n = key.shape[0]
    found = np.empty(n, dtype=np.intp)
    for lo in range(0, n, _CHUNK_ROWS):
        hi = min(lo + _CHUNK_ROWS, n)
        first = int(np.searchsorted(key, wanted[lo]))
        last = int(np.searchsorted(key, wanted[hi - 1], side="right"))
        found[lo:hi] = np.searchsorted(key[first:last], wanted[lo:hi])
        found[lo:hi] += first
    np.minimum(found, n - 1, out=found)
    # a model of the sequence: t in 0 .. n_seq - 2, and (t + 1, p) observed
    hit = np.flatnonzero(
        (np.take(key, found) == wanted) & (key >= 0) & (key < (n_seq - 1) * n_pts)
    )
    right = np.take(found, hit)
    model = np.take(t if order is None else t[order], hit)
    point = np.take(observations.point if order is None else observations.point[order], hit)
    if order is not None:
        hit, right = order[hit], order[right]
    return (
        model.astype(np.intp, copy=False),
        point.astype(np.intp, copy=False),
        hit.astype(np.intp, copy=False),
        right.astype(np.intp, copy=False),
    )


def tie_rows(
    left_row: IntArray, right_row: IntArray, n_observations: int
) -> tuple[IntArray, IntArray]:
    """The tie points of a chain of models: for the model rows of
    :func:`pair_rows` (``left_row``, ``right_row`` index the observations),
    the rows ``i_now`` of points that the model before has too and those
    rows ``i_prev`` in the model before, ``i_now`` ascending.

    Model m - 1's observation of a point on its right photo (photo m) is
    model m's observation on its left photo: one inverse lookup, linear in
    the rows (a sorted intersection of (model, point) keys costs 5x more).
    In pair_rows an observation is the left one of at most one model and
    the right one of at most the model before it.
    """
    row_of_right = np.full(n_observations, -1, dtype=np.intp)
    row_of_right[right_row] = np.arange(right_row.shape[0])
    previous_row = np.take(row_of_right, left_row)
    i_now = np.flatnonzero(previous_row >= 0)
    return i_now, np.take(previous_row, i_now)


def model_sequence(
    observations: ImageObservations, photo_index: ArrayLike | None
) -> tuple[IntArray, list[str]]:
    """The photos that form the models, in strip order (all by default), and
    the name of each pair ("pair <left>-<right>")."""
    seq = (
        np.arange(observations.n_photos, dtype=np.intp)
        if photo_index is None
        else np.asarray(photo_index, dtype=np.intp)
    )
    if seq.shape[0] < 2:
        raise GeometryError(f"a strip needs at least two photos, got {seq.shape[0]}")
    ids = observations.photo_ids
    return seq, [f"pair {ids[seq[m]]}-{ids[seq[m + 1]]}" for m in range(seq.shape[0] - 1)]


def _check_photos_spread(
    left: FloatArray,
    right: FloatArray,
    model: IntArray,
    n_models: int,
    photos: list[str],
    labels: list[str],
) -> None:
    """Refuse a photo whose points of a pair lie nearly on one line: its
    orientation cannot be determined from them (the rotation about their
    line stays free), whatever an iteration then returns.  Each photo of a
    pair is looked at, the left one first (``photos`` in model order)."""
    counts = np.bincount(model, minlength=n_models)
    for side, image in ((0, left), (1, right)):
        ratio = collinear_ratio(image, model, n_models)
        bad = np.flatnonzero((counts >= 2) & ~(ratio >= COLLINEAR_RATIO))
        if bad.size:
            m = int(bad[0])
            raise GeometryError(
                f"photo {photos[m + side]}: its {int(counts[m])} points of {labels[m]} lie "
                f"nearly on one line in the image (spread across that line {ratio[m]:.1e} of "
                "the spread along it): the points do not determine the relative orientation "
                "nor the photo's; measure points spread over the whole overlap (or correct "
                "the photo's image coordinates)"
            )


def form_strip(
    observations: ImageObservations,
    options: StripOptions | None = None,
    *,
    photo_index: ArrayLike | None = None,
    blunders: BlunderOptions | None = None,
) -> StripModel:
    """Form one strip model from the image observations of a strip.

    Parameters
    ----------
    observations : ImageObservations
        Image coordinates (mm, reduced to the principal point) of the strip.
    options : StripOptions, optional
    photo_index : array_like of int, optional
        The photos that form the models, in strip order (indices into
        ``observations.photo_ids``); all photos by default.
    blunders : BlunderOptions, optional
        Gross-error tests of the y-parallaxes and the tie points (default:
        test and reject, see :mod:`strip_aerotri.blunders`).

    Returns
    -------
    StripModel

    Raises
    ------
    GeometryError
        Fewer than two photos, a pair with fewer than five common points, a
        model with no tie point to the previous model, or a degenerate pair.
    ConvergenceError
        A relative orientation that does not converge.
    """
    options = options or StripOptions()
    seq, labels = model_sequence(observations, photo_index)
    n_models = seq.shape[0] - 1
    blunders = blunders or BlunderOptions()
    rejections: list[Rejection] = []
    pairs = _orient_pairs(observations, options, blunders, seq, labels, rejections)
    rel, model, point = pairs.rel, pairs.model, pairs.point
    unit = _form_models(observations, options, pairs, n_models, labels)
    ties = _transfer_scale(observations, options, blunders, pairs, unit, seq, labels, rejections)
    centres, rotations, scale = _chain(options, rel, ties.ratio)
    model_points, model_parallax, points, counts = _strip_points(
        observations, model, point, unit, centres, scale, ties.rejected_rows
    )
    i_now, i_prev, tie_model, tie_count = ties.i_now, ties.i_prev, ties.tie_model, ties.tie_count
    tie_difference, tie_rms = tie_differences(model_points, i_now, i_prev, tie_model, tie_count)
    row_l, row_r, ratio = pairs.row_l, pairs.row_r, ties.ratio
    rejected_point_index, missing = ties.rejected_point_index, ties.missing

    return StripModel(
        observations=observations,
        options=options,
        photo_index=seq,
        centres=centres,
        rotations=rotations,
        relative=rel,
        scale=scale,
        scale_ratio=ratio,
        points=points,
        n_determinations=counts.astype(np.intp),
        model=model,
        model_point=point,
        model_points=model_points,
        model_parallax=model_parallax,
        tie_model=tie_model,
        tie_point=point[i_now],
        tie_difference=tie_difference,
        tie_count=tie_count,
        tie_rms=tie_rms,
        model_labels=tuple(labels),
        rejections=tuple(rejections),
        rejected_points=tuple(observations.point_ids[i] for i in rejected_point_index),
        rejected_determinations=ties.rejected_rows,
        model_rows=np.column_stack([row_l, row_r]),
        breaks=missing.astype(np.intp),
    )


class _Pairs(NamedTuple):
    """The oriented pairs: the relative orientation, and per point row of a
    pair its model, point and observation rows and its image vectors as
    contiguous components (3, n)."""

    rel: RelativeOrientation
    model: IntArray
    point: IntArray
    row_l: IntArray
    row_r: IntArray
    left_t: FloatArray
    right_t: FloatArray


def _orient_pairs(
    observations: ImageObservations,
    options: StripOptions,
    blunders: BlunderOptions,
    seq: IntArray,
    labels: list[str],
    rejections: list[Rejection],
) -> _Pairs:
    """Relative orientation of every pair, with data snooping of the y-parallaxes
    (rejections appended to ``rejections``)."""
    n_models = seq.shape[0] - 1
    ids = observations.photo_ids
    model, point, row_l, row_r = pair_rows(observations, seq)
    keep = _excluded_rows(observations, blunders, row_l, row_r)
    model, point, row_l, row_r = model[keep], point[keep], row_l[keep], row_r[keep]
    # Image vectors as contiguous components (3, n): the relative orientation
    # gathers its blocks from them and the midpoint intersection works on
    # them; the (n, 3) arrays passed on are their transposes (views).
    left_t = _image_components(observations, row_l)
    right_t = _image_components(observations, row_r)
    left, right = left_t.T, right_t.T
    n_rows = model.shape[0]
    _check_photos_spread(left, right, model, n_models, [ids[i] for i in seq], labels)
    rel = None
    while True:
        # after a rejection the pairs start from their previous solution: only
        # the pairs that lost an observation take steps
        rel = relative_orientation(
            left,
            right,
            model,
            n_models,
            method=options.relative_orientation,
            rotation_first=options.first_rotation,
            sigma_left=observations.sigma[row_l],
            sigma_right=observations.sigma[row_r],
            max_iterations=options.max_iterations,
            tolerance=options.tolerance,
            labels=labels,
            robust=blunders.rejecting,
            start=rel,
        )
        if not blunders.testing:
            break
        worst = _worst_parallaxes(rel, blunders)
        if worst.size == 0:
            break
        for row in worst:
            m, pid = int(model[row]), observations.point_ids[point[row]]
            rejections.append(
                Rejection(
                    stage="relative_orientation",
                    point=pid,
                    photos=(ids[seq[m]], ids[seq[m + 1]]),
                    component="y-parallax",
                    residual=float(rel.parallax_um[row]),
                    unit="µm",
                    w=float(_w_statistic(rel)[row] / np.sqrt(_factor(rel))),
                    critical=blunders.critical("relative_orientation", n_rows),
                    applied=blunders.rejecting,
                    effect=f"left out of the pair; its sigma0 {rel.sigma0_um[m]:.2f} µm",
                )
            )
        if not blunders.rejecting:
            break
        kept = np.ones(model.shape[0], dtype=bool)
        kept[worst] = False
        model, point, row_l, row_r = model[kept], point[kept], row_l[kept], row_r[kept]
        # rows of (n, 3) arrays by np.compress / np.take throughout: several
        # times faster than fancy indexing of 2-D arrays with numpy 2
        left_t, right_t = np.compress(kept, left_t, axis=1), np.compress(kept, right_t, axis=1)
        left, right = left_t.T, right_t.T
        if n_rows - model.shape[0] > blunders.max_fraction * n_rows:
            raise GeometryError(
                f"relative orientation: more than {blunders.max_fraction:.0%} of the "
                f"y-parallaxes fail the blunder test ({n_rows - model.shape[0]} of {n_rows}); "
                "the image coordinates or point ids cannot be trusted"
            )

    return _Pairs(rel, model, point, row_l, row_r, left_t, right_t)


def _form_models(
    observations: ImageObservations,
    options: StripOptions,
    pairs: _Pairs,
    n_models: int,
    labels: list[str],
) -> Intersection:
    """Every model with the unit base (b_x = 1), relative to its left centre;
    refuses a pair whose rays meet behind the photos."""
    rel, model = pairs.rel, pairs.model
    left_t, right_t = pairs.left_t, pairs.right_t
    left, right = left_t.T, right_t.T
    ray_direction_problems(
        rel.rotation_left, rel.rotation_right, rel.base, left, right, model, labels, strict=True
    )

    if IntersectionMethod(options.intersection) is IntersectionMethod.MIDPOINT:
        unit = _intersect_in_left_frames(rel, model, left_t, right_t)
    else:
        per_model = np.bincount(model, minlength=n_models)
        unit = intersect_normal(
            np.repeat(rel.base, per_model, axis=0),
            _rotate_rows(rel.rotation_left, model, left),
            _rotate_rows(rel.rotation_right, model, right),
            observations.principal_distance,
        )

    return unit


class _Ties(NamedTuple):
    """Scale transfer: the ratio of each model's scale to the previous one's
    (1 for the first and across breaks), the tie rows kept (``i_now`` in
    model m, ``i_prev`` in model m - 1), their models and counts, the models
    with no tie (breaks), the points all of whose determinations the tie
    test rejected and the determinations it rejected (rows)."""

    ratio: FloatArray
    i_now: IntArray
    i_prev: IntArray
    tie_model: IntArray
    tie_count: IntArray
    missing: IntArray
    rejected_point_index: IntArray
    rejected_rows: BoolArray


def _transfer_scale(
    observations: ImageObservations,
    options: StripOptions,
    blunders: BlunderOptions,
    pairs: _Pairs,
    unit: Intersection,
    seq: IntArray,
    labels: list[str],
    rejections: list[Rejection],
) -> _Ties:
    """Scale ratios from the tie points, with data snooping of the tie points."""
    rel, model, point = pairs.rel, pairs.model, pairs.point
    row_l, row_r = pairs.row_l, pairs.row_r
    n_models = seq.shape[0] - 1
    ids = observations.photo_ids
    # Tie points: determined in model m and in model m - 1.
    i_now, i_prev = tie_rows(row_l, row_r, observations.photo.shape[0])
    tie_ok = np.ones(i_now.shape[0], dtype=bool)
    while True:
        tie_model = model[i_now[tie_ok]]
        # Same point seen from the shared centre: previous model minus its base.
        previous = np.take(unit.points, i_prev[tie_ok], axis=0) - np.take(
            rel.base, model[i_prev[tie_ok]], axis=0
        )
        new_pts = np.take(unit.points, i_now[tie_ok], axis=0)
        ratio = scale_ratios(previous, new_pts, tie_model, n_models, method=options.scale_transfer)
        if not blunders.testing or tie_model.size < 8:
            break
        failing, crit = _worst_ties(previous, new_pts, tie_model, ratio, blunders)
        if failing.size == 0:
            break
        index_ok = np.flatnonzero(tie_ok)
        components = np.array(["X", "Y", "Z"])[failing["component"]]
        for k, comp, w, resid in zip(
            failing["index"], components, failing["w"], failing["residual"], strict=True
        ):
            row = i_now[index_ok[k]]
            m = int(model[row])
            rejections.append(
                Rejection(
                    stage="tie_points",
                    point=observations.point_ids[point[row]],
                    photos=(ids[seq[m - 1]], ids[seq[m]], ids[seq[m + 1]]),
                    component=comp,
                    residual=float(resid),
                    unit=BASE_UNITS,
                    w=float(w),
                    critical=float(crit),
                    applied=blunders.rejecting,
                    effect=(
                        "tie left out of the scale transfer; the point's determinations in "
                        "the models of the photo its failed ties share left out of the strip "
                        "model"
                    ),
                )
            )
        if not blunders.rejecting:
            break
        tie_ok[index_ok[failing["index"]]] = False
        if (~tie_ok).sum() > blunders.max_fraction * tie_ok.size:
            raise GeometryError(
                f"scale transfer: more than {blunders.max_fraction:.0%} of the tie points fail "
                "the blunder test; the strip cannot be formed reliably"
            )
    rejected_rows, rejected_point_index = rejected_determinations(
        point, model, i_now, i_prev, tie_ok, observations.n_points
    )
    i_now, i_prev = i_now[tie_ok], i_prev[tie_ok]
    tie_model = model[i_now]
    tie_count = np.bincount(tie_model, minlength=n_models).astype(np.intp)
    missing = np.flatnonzero(tie_count[1:] == 0) + 1
    if missing.size and not options.allow_breaks:
        m = int(missing[0])
        raise GeometryError(
            f"{labels[m]} shares no tie point with {labels[m - 1]} (no point is measured on "
            f"all three photos {ids[seq[m - 1]]}, {ids[seq[m]]}, {ids[seq[m + 1]]}"
            + (", after rejecting blunders" if rejected_point_index.size else "")
            + "): the scale cannot be transferred"
        )
    # A break (allowed): the scale goes on unchanged (equal bases), and the
    # ground stage takes the models after it from their own control.
    ratio[missing] = 1.0
    bad = np.flatnonzero(~np.isfinite(ratio[1:]) | (ratio[1:] <= 0)) + 1
    if bad.size:
        m = int(bad[0])
        raise GeometryError(f"{labels[m]}: the tie points give no valid scale (ratio {ratio[m]})")
    ratio[0] = 1.0
    return _Ties(
        ratio, i_now, i_prev, tie_model, tie_count, missing, rejected_point_index, rejected_rows
    )


def rejected_determinations(
    point: IntArray,
    model: IntArray,
    i_now: IntArray,
    i_prev: IntArray,
    tie_ok: BoolArray,
    n_points: int,
) -> tuple[BoolArray, IntArray]:
    """The determinations (rows of the models' points) that failed tie tests
    leave out, and the points left with none.

    A blunder in one image coordinate spoils the point in the two models
    that share that photo.  The tie at model m compares models m − 1 and m,
    photos m − 1, m, m + 1 (model m is photos m and m + 1); when a point's
    failed ties have photos in common, those photos are the suspects and
    only the point's determinations in the models holding them are left
    out (a check point seen on six photos with an error on the middle one
    keeps three of its five); otherwise both models of every failed tie.
    """
    rows = np.zeros(point.shape[0], dtype=bool)
    failed = ~tie_ok
    if not failed.any():
        return rows, np.zeros(0, dtype=np.intp)
    f_point = point[i_now[failed]]
    f_model = model[i_now[failed]]
    # the photos common to all of a point's failed ties: m - 1 .. m + 1 of the
    # latest tie to those of the earliest
    low = np.full(n_points, np.iinfo(np.intp).min, dtype=np.intp)
    high = np.full(n_points, np.iinfo(np.intp).max, dtype=np.intp)
    np.maximum.at(low, f_point, f_model - 1)
    np.minimum.at(high, f_point, f_model + 1)
    has_failed = np.zeros(n_points, dtype=bool)
    has_failed[f_point] = True
    shared = has_failed & (low <= high)
    # with a suspect photo: the point's models holding one (model m: photos m, m + 1)
    mine = shared[point]
    rows[mine] = (model[mine] + 1 >= low[point[mine]]) & (model[mine] <= high[point[mine]])
    # without one: both models of every failed tie
    apart = ~shared[f_point]
    rows[i_now[failed][apart]] = True
    rows[i_prev[failed][apart]] = True
    kept = np.bincount(point[~rows], minlength=n_points)
    touched = np.unique(point[rows])
    return rows, touched[kept[touched] == 0].astype(np.intp)


def _chain(
    options: StripOptions, rel: RelativeOrientation, ratio: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Projection centres (M, 3), rotations image -> strip (M, 3, 3) and the
    scale of every model, chained from the first photo."""
    first_scale = (
        1.0
        if options.first_base_length is None
        else options.first_base_length / float(np.linalg.norm(rel.base[0]))
    )
    scale = first_scale * np.cumprod(ratio)

    first_position = (
        np.zeros(3)
        if options.first_position is None
        else np.asarray(options.first_position, float)
    )
    steps = scale[:, None] * rel.base
    centres = np.vstack([first_position, first_position + np.cumsum(steps, axis=0)])
    rotations: FloatArray = np.concatenate([rel.rotation_left[:1], rel.rotation_right], axis=0)
    return np.asarray(centres, dtype=np.float64), rotations, np.asarray(scale, dtype=np.float64)


def _strip_points(
    observations: ImageObservations,
    model: IntArray,
    point: IntArray,
    unit: Intersection,
    centres: FloatArray,
    scale: FloatArray,
    rejected_rows: BoolArray,
) -> tuple[FloatArray, FloatArray, FloatArray, IntArray]:
    """Every model's points in the strip system, and each point's mean over the
    models that determine it (determinations the tie test rejected left
    out): ``model_points``, ``model_parallax``, ``points`` (NaN where none),
    ``counts``."""
    # Column by column: an (n, 1) factor broadcast over (n, 3) rows runs
    # numpy's inner loop over three elements.
    model_scale = np.take(scale, model)
    model_points = np.empty_like(unit.points)
    for k in range(3):
        model_points[:, k] = np.take(centres[:, k], model) + model_scale * unit.points[:, k]
    model_parallax = model_scale * unit.parallax
    if rejected_rows.any():
        usable = ~rejected_rows
        usable_point, usable_xyz = point[usable], np.compress(usable, model_points, axis=0)
    else:
        usable_point, usable_xyz = point, model_points
    counts = np.bincount(usable_point, minlength=observations.n_points)
    points = np.empty((observations.n_points, 3))
    with np.errstate(invalid="ignore", divide="ignore"):
        for k in range(3):
            sums = np.bincount(usable_point, usable_xyz[:, k], minlength=observations.n_points)
            points[:, k] = sums / counts
    points[counts == 0] = np.nan

    return model_points, model_parallax, points, counts


def tie_differences(
    model_points: FloatArray,
    i_now: IntArray,
    i_prev: IntArray,
    tie_model: IntArray,
    tie_count: IntArray,
) -> tuple[FloatArray, FloatArray]:
    """The tie points' double determinations: model m minus model m - 1 (n, 3),
    and their RMS per model and axis (NaN for a model with no tie)."""
    n_models = tie_count.shape[0]
    tie_difference = np.take(model_points, i_now, axis=0) - np.take(model_points, i_prev, axis=0)
    sq = np.stack(
        [np.bincount(tie_model, tie_difference[:, k] ** 2, minlength=n_models) for k in range(3)],
        axis=1,
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        tie_rms = np.sqrt(sq / tie_count[:, None])
    tie_rms[tie_count == 0] = np.nan

    return tie_difference, tie_rms


_CHUNK_ROWS = 1 << 15  # rows per chunk (rotations, intersection): temporaries stay in cache


def _image_components(observations: ImageObservations, rows: IntArray) -> FloatArray:
    """Image vectors ``(x, y, -c)`` (mm) of the observations ``rows`` as
    contiguous components, shape (3, n)."""
    out = np.empty((3, rows.shape[0]))
    out[:2] = np.take(observations.xy, rows, axis=0).T
    out[2] = -observations.principal_distance
    return out


def _intersect_in_left_frames(
    rel: RelativeOrientation, model: IntArray, left_t: FloatArray, right_t: FloatArray
) -> Intersection:
    """J(11)-(12) for every row, the y-parallax along the left photo's image y
    axis as in the relative orientation; points relative to the left centre
    in the strip system, (n, 3), in base units.

    The formulas do not change under a common rotation, so each pair is
    intersected in its left photo's image frame (the left rays as measured,
    ``j = (0, 1, 0)``, the right rays turned by the relative rotation Q,
    the base ``R_lᵀ b``) and the points are turned to the strip by ``R_l``,
    in chunks of rows whose temporaries stay in cache, on the (3, n)
    components of the image vectors.
    """
    base_left = np.einsum("mji,mj->mi", rel.rotation_left, rel.base)  # R_lᵀ b
    base_t = np.ascontiguousarray(base_left.T)  # (3, M)
    q_entries = np.ascontiguousarray(rel.relative_rotation.reshape(-1, 9).T)  # (9, M)
    r_entries = np.ascontiguousarray(rel.rotation_left.reshape(-1, 9).T)
    points = np.empty((model.shape[0], 3))
    parallax = np.empty(model.shape[0])
    for start in range(0, model.shape[0], _CHUNK_ROWS):
        rows = slice(start, start + _CHUNK_ROWS)
        m = model[rows]
        q = np.take(q_entries, m, axis=1)
        x, y, z = right_t[:, rows]
        p = [q[3 * i] * x + q[3 * i + 1] * y + q[3 * i + 2] * z for i in range(3)]
        u, parallax[rows] = midpoint_along_y_components(
            np.take(base_t, m, axis=1), left_t[:, rows], p
        )
        r = np.take(r_entries, m, axis=1)
        for i in range(3):
            points[rows, i] = r[3 * i] * u[0] + r[3 * i + 1] * u[1] + r[3 * i + 2] * u[2]
    return Intersection(points, parallax)


def _rotate_rows(matrices: FloatArray, index: IntArray, vectors: FloatArray) -> FloatArray:
    """``matrices[index[i]] @ vectors[i]`` for every row i: (n, 3).

    In chunks of rows whose temporaries stay in cache (a whole-array (9, n)
    stack of entries would be fresh memory, paid in page faults), on
    contiguous components: about 4x faster than an (n, 3, 3) stack.
    """
    entries = np.ascontiguousarray(matrices.reshape(-1, 9).T)
    components = np.ascontiguousarray(vectors.T)
    out = np.empty_like(vectors)
    for start in range(0, vectors.shape[0], _CHUNK_ROWS):
        rows = slice(start, start + _CHUNK_ROWS)
        e = np.take(entries, index[rows], axis=1)
        x, y, z = components[:, rows]
        for i in range(3):
            out[rows, i] = e[3 * i] * x + e[3 * i + 1] * y + e[3 * i + 2] * z
    return out


def _excluded_rows(
    observations: ImageObservations, blunders: BlunderOptions, row_l: IntArray, row_r: IntArray
) -> BoolArray:
    """Mask of pair rows kept after the user's exclusions (points, observations)."""
    _, drop_obs = blunders.excluded(observations)
    kept: BoolArray = ~(drop_obs[row_l] | drop_obs[row_r])
    return kept


def _w_statistic(rel: RelativeOrientation) -> FloatArray:
    """The y-parallaxes' w-tests (relative_orientation always computes them)."""
    assert rel.w_statistic is not None
    return rel.w_statistic


def _factor(rel: RelativeOrientation) -> float:
    return robust_variance_factor(_w_statistic(rel))


def _worst_parallaxes(rel: RelativeOrientation, blunders: BlunderOptions) -> IntArray:
    """Rows to reject: per pair the largest |w| above the critical value (all
    failing rows when only reporting)."""
    w = np.abs(_w_statistic(rel)) / np.sqrt(_factor(rel))
    crit = blunders.critical("relative_orientation", int(np.isfinite(w).sum()))
    failing = np.isfinite(w) & (w > crit)
    if not failing.any():
        return np.zeros(0, dtype=np.intp)
    if not blunders.rejecting:
        return np.flatnonzero(failing)
    # the largest per pair: sort by (pair, w) and take the last of each failing pair
    order = np.lexsort((np.where(failing, w, -1.0), rel.pair))
    last = np.r_[rel.pair[order][1:] != rel.pair[order][:-1], True]
    pick = order[last]
    worst: IntArray = pick[failing[pick]]
    return worst


_TIE_DTYPE = [("index", np.intp), ("component", np.intp), ("w", float), ("residual", float)]


def _worst_ties(
    previous: FloatArray,
    new_pts: FloatArray,
    tie_model: IntArray,
    ratio: FloatArray,
    blunders: BlunderOptions,
) -> tuple[np.ndarray, float]:
    """Tie points whose two height determinations disagree beyond the critical value.

    As J tested after each scaling, the Z differences of the tie points are
    tested (X and Y differences of a point are dominated by the ray of the
    photo both models share, far from normally distributed; y-parallaxes are
    tested in the relative orientation).  The Z difference, in the previous
    model's unit-base units, is standardised by a robust scale (1.4826 × MAD
    over all tie points of the strip); per model the worst one above the
    critical value is returned (all failing ones when only reporting).
    """
    diff = ratio[tie_model] * new_pts[:, 2] - previous[:, 2]
    centre = sample_median(diff)
    mad = 1.4826 * sample_median(np.abs(diff - centre))
    # floor: exact data leave differences at the level of the relative orientation's
    # convergence (its tolerance, 1e-11 by default), which are not blunders
    mad = max(mad, 1e-10 * max(float(np.abs(previous).max()), 1.0))
    w = np.abs(diff - centre) / mad
    crit = blunders.critical("tie_points", w.size)
    failing = w > crit
    if not failing.any():
        return np.zeros(0, dtype=_TIE_DTYPE), crit
    if blunders.rejecting:
        order = np.lexsort((np.where(failing, w, -1.0), tie_model))
        last = np.r_[tie_model[order][1:] != tie_model[order][:-1], True]
        pick = order[last]
        pick = pick[failing[pick]]
    else:
        pick = np.flatnonzero(failing)
    out = np.zeros(pick.size, dtype=_TIE_DTYPE)
    out["index"] = pick
    out["component"] = 2
    out["w"] = w[pick]
    out["residual"] = diff[pick] - centre
    return out, crit
