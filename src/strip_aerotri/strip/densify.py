"""Strips with very high forward overlap: models on every k-th photo.

Drone strips are flown with 80-95 % forward overlap.  Consecutive photos then
have bases of a few metres at 100 m and more of height: a model of such a
pair is as weak in depth as its base-to-height ratio is small, and the
partially dependent chain (method.md §5) carries the weakness along the
strip.  The remedy of this module:

1. :func:`choose_photo_step` picks a step k from a first relative orientation
   of consecutive pairs: the smallest k whose base-to-height ratio reaches a
   minimum (:data:`~strip_aerotri.options.DEFAULT_MIN_BASE_TO_HEIGHT` by default);
2. the strip is formed by the method on the *model photos* only
   (:func:`model_photo_index`: every k-th photo, spread so that the first and
   the last photo are model photos) with
   ``chaining.form_strip(observations, options, photo_index=seq)``; tie points
   still come from the triple overlap of three consecutive model photos;
3. :func:`complete_strip` orients every other photo by space resection on the
   triangulated points (:func:`resect`, one batched Gauss-Newton over all of
   them) and intersects the points seen on non-model photos only by multi-ray
   least squares (:func:`intersect_rays`).

:func:`form_strip_stepped` does the three steps in one call.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ..errors import ConvergenceError, GeometryError, StripAerotriWarning
from ..geometry.collinearity import image_vectors
from ..geometry.intersection import intersect
from ..geometry.rotation import matrix_from_rotvec, skew
from ..observations import ImageObservations
from ..options import (
    DEFAULT_IMAGE_SIGMA_MM,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_MIN_BASE_TO_HEIGHT,
    DEFAULT_PHOTO_STEP,
    BlunderOptions,
    ModelFormation,
    StripOptions,
)
from ..results import StripModel
from .chaining import form_strip, pair_rows, tie_rows
from .independent import form_strip_independent
from .relative import relative_orientation

__all__ = [
    "DEFAULT_MIN_BASE_TO_HEIGHT",
    "RayIntersection",
    "Resection",
    "StepChoice",
    "choose_photo_step",
    "complete_strip",
    "form_strip_stepped",
    "intersect_rays",
    "model_photo_index",
    "photo_step_table",
    "resect",
]

_MIN_PAIR_POINTS = 8
_MIN_TIE_POINTS = 3


# --------------------------------------------------------------------------- model photos


def first_model_step(photo_step: int | str) -> int:
    """The photo step of a strip's first models: ``photo_step`` itself, or 1
    for ``"auto"``, whose first relative orientation is of all consecutive
    pairs (:func:`choose_photo_step`)."""
    return photo_step if isinstance(photo_step, int) else 1


def model_photo_index(n_photos: int, photo_step: int) -> IntArray:
    """The model photos for a step: every k-th photo, first and last included.

    Parameters
    ----------
    n_photos : int
        Photos of the strip (>= 2).
    photo_step : int
        k >= 1.

    Returns
    -------
    ndarray of int, shape (n_models + 1,)
        ``round(linspace(0, n - 1, n_models + 1))`` with ``n_models =
        ceil((n - 1) / k)``: exactly every k-th photo when k divides n - 1,
        otherwise steps of k and k - 1 spread evenly.

    Examples
    --------
    >>> model_photo_index(13, 3)
    array([ 0,  3,  6,  9, 12])
    >>> model_photo_index(12, 3)
    array([ 0,  3,  6,  8, 11])
    """
    n = int(n_photos)
    k = int(photo_step)
    if n < 2:
        raise ValueError(f"Expected `n_photos` >= 2, got {n_photos!r}")
    if k < 1:
        raise ValueError(f"Expected `photo_step` >= 1, got {photo_step!r}")
    n_models = max(1, math.ceil((n - 1) / k))
    return np.unique(np.round(np.linspace(0.0, n - 1, n_models + 1)).astype(np.intp))


def _overlap_counts(observations: ImageObservations, seq: IntArray) -> tuple[IntArray, IntArray]:
    """Points common to each model's two photos and tie points of each model."""
    model, _, row_l, row_r = pair_rows(observations, seq)
    n_models = seq.shape[0] - 1
    pair_count = np.bincount(model, minlength=n_models)
    i_now, _ = tie_rows(row_l, row_r, observations.photo.shape[0])
    tie_count = np.bincount(np.take(model, i_now), minlength=n_models)
    return pair_count, tie_count


class StepChoice(NamedTuple):
    """Base-to-height ratios behind :func:`choose_photo_step`.

    Attributes
    ----------
    ratio_consecutive : ndarray, shape (n_photos - 1,)
        Base-to-height ratio of each pair of consecutive photos: base length
        over the median depth of its model points (depth along the left
        photo's optical axis).
    ratio : float
        Median of ``ratio_consecutive``.
    wanted : int
        ``ceil(min_base_to_height / ratio)``: the step that reaches the
        minimum (the bases of consecutive photos add up).
    feasible : int
        The largest step whose models still have enough common points and
        tie points.
    step : int
        ``min(wanted, feasible)``.
    source : str
        ``"relative orientation"``, or ``"x-parallax"`` when the relative
        orientation of the consecutive pairs failed (short noisy bases) and
        the normal-case estimate ``B / H = median(x_left - x_right) / c`` was
        used instead.
    """

    ratio_consecutive: FloatArray
    ratio: float
    wanted: int
    feasible: int
    step: int
    source: str


def photo_step_table(
    observations: ImageObservations,
    min_base_to_height: float = DEFAULT_MIN_BASE_TO_HEIGHT,
    *,
    options: StripOptions | None = None,
    min_pair_points: int = _MIN_PAIR_POINTS,
    min_tie_points: int = _MIN_TIE_POINTS,
) -> StepChoice:
    """The figures of :func:`choose_photo_step` (see there)."""
    if not (np.isfinite(min_base_to_height) and min_base_to_height > 0):
        raise ValueError(f"Expected `min_base_to_height` > 0, got {min_base_to_height!r}")
    options = options or StripOptions()
    n = observations.n_photos
    seq = np.arange(n, dtype=np.intp)
    model, _, row_l, row_r = pair_rows(observations, seq)
    if np.unique(model).shape[0] < n - 1:
        raise GeometryError("photo step: two consecutive photos share no point")
    order = np.argsort(model, kind="stable")
    starts = np.searchsorted(model[order], np.arange(n))

    def median_per_pair(values: FloatArray) -> FloatArray:
        v = values[order]
        return np.array([np.median(v[starts[m] : starts[m + 1]]) for m in range(n - 1)])

    vectors = observations.image_vectors()
    try:
        rel = relative_orientation(
            vectors[row_l],
            vectors[row_r],
            model,
            n - 1,
            method=options.relative_orientation,
            sigma_left=observations.sigma[row_l],
            sigma_right=observations.sigma[row_r],
            max_iterations=options.max_iterations,
            tolerance=options.tolerance,
        )
    except (ConvergenceError, GeometryError):
        # Short noisy bases can defeat the relative orientation: fall back to
        # the x-parallax of normal-case photos, p = c B / H.
        parallax = observations.xy[row_l, 0] - observations.xy[row_r, 0]
        ratio_consecutive = np.abs(median_per_pair(parallax)) / observations.principal_distance
        source = "x-parallax"
    else:
        left = np.einsum("nij,nj->ni", rel.rotation_left[model], vectors[row_l])
        right = np.einsum("nij,nj->ni", rel.rotation_right[model], vectors[row_r])
        unit = intersect(rel.base[model], left, right)
        axis = rel.rotation_left[model][:, :, 2]  # optical axis (image z) in the strip frame
        depth = np.abs(median_per_pair(-np.einsum("ni,ni->n", unit.points, axis)))
        ratio_consecutive = np.linalg.norm(rel.base, axis=1) / depth
        source = "relative orientation"
    ratio = float(np.median(ratio_consecutive))
    wanted = max(1, math.ceil(min_base_to_height / ratio - 1e-9))
    feasible = 1
    for k in range(2, n):  # a handful of candidate steps
        pair_count, tie_count = _overlap_counts(observations, model_photo_index(n, k))
        if pair_count.min() < min_pair_points or (
            tie_count.shape[0] > 1 and tie_count[1:].min() < min_tie_points
        ):
            break
        feasible = k
    return StepChoice(ratio_consecutive, ratio, wanted, feasible, min(wanted, feasible), source)


def choose_photo_step(
    observations: ImageObservations,
    min_base_to_height: float = DEFAULT_MIN_BASE_TO_HEIGHT,
    *,
    options: StripOptions | None = None,
) -> int:
    """The smallest photo step k whose models reach a base-to-height ratio.

    A first relative orientation of all consecutive pairs (method.md §3)
    gives each pair's base (b_x = 1 units) and model; its base-to-height ratio
    is the base length over the median depth of the model points along the
    left photo's optical axis.  Bases of consecutive photos add up, so the
    models on every k-th photo have a ratio of about k times the median
    consecutive ratio; the step is ``ceil(min_base_to_height / median)``,
    (when the relative orientation of the consecutive pairs fails, as short
    noisy bases can make it, the normal-case x-parallax ``p = c B / H`` of
    the common points gives the ratios instead),
    but no larger than the largest step whose models still share at least 8
    points per pair and 3 tie points with the previous model.

    Parameters
    ----------
    observations : ImageObservations
        Image coordinates of the whole strip (mm, method's axes).
    min_base_to_height : float
        The minimum ratio (default :data:`DEFAULT_MIN_BASE_TO_HEIGHT`).
    options : StripOptions, optional
        Relative orientation choices (formulation, iterations).

    Returns
    -------
    int
        k >= 1 (1: every photo is a model photo, as in the classical method).

    Warns
    -----
    StripAerotriWarning
        When the overlap does not allow a step large enough to reach the
        minimum ratio.

    Raises
    ------
    GeometryError, ConvergenceError
        From the relative orientation of the consecutive pairs.
    """
    choice = photo_step_table(observations, min_base_to_height, options=options)
    if choice.wanted > choice.feasible:
        warnings.warn(
            f"photo step: base-to-height {min_base_to_height} needs a step of {choice.wanted} "
            f"photos (median consecutive ratio {choice.ratio:.3f}), but the overlap allows "
            f"only {choice.feasible}; using {choice.step} (ratio about "
            f"{choice.step * choice.ratio:.2f})",
            StripAerotriWarning,
            stacklevel=2,
        )
    return choice.step


# --------------------------------------------------------------------------- resection


@dataclass(frozen=True)
class Resection:
    """Exterior orientation of photos by space resection.

    Attributes
    ----------
    centres : ndarray, shape (M, 3)
        Projection centres, in the frame of the given points.
    rotations : ndarray, shape (M, 3, 3)
        Image -> point frame rotations (``l = R @ (x, y, -c)``).
    iterations : int
        Gauss-Newton iterations done (all photos iterate together).
    n_points : ndarray of int, shape (M,)
        Observations used per photo.
    rms_um : ndarray, shape (M,)
        RMS image residual per photo, µm (both coordinates).
    residuals : ndarray, shape (K, 2)
        Observed minus computed image coordinates, mm, per observation.
    """

    centres: FloatArray
    rotations: FloatArray
    iterations: int
    n_points: IntArray
    rms_um: FloatArray
    residuals: FloatArray


def _collinearity(
    xy: FloatArray,
    points: FloatArray,
    photo: IntArray,
    c: float,
    centres: FloatArray,
    rotations: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Image vectors v = Rᵀ (X − S), their v_z, and observed minus computed xy."""
    v = image_vectors(centres[photo], rotations[photo], points)
    w = v[:, 2]
    computed = -c * v[:, :2] / w[:, None]
    return v, w, xy - computed


def resect(
    xy: ArrayLike,
    points: ArrayLike,
    photo: ArrayLike,
    n_photos: int,
    principal_distance: float,
    centres: ArrayLike,
    rotations: ArrayLike,
    *,
    sigma: ArrayLike | float = DEFAULT_IMAGE_SIGMA_MM,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    tolerance: float = 1e-12,
    labels: tuple[str, ...] | None = None,
) -> Resection:
    """Space resection of several photos at once by the collinearity equations.

    One Gauss-Newton iteration solves the 6 × 6 normal equations of every
    photo together (a batched solve): unknowns the projection centre and a
    small rotation vector φ applied in the image frame, ``R ← R · exp([φ]×)``.

    Parameters
    ----------
    xy : array_like, shape (K, 2)
        Image coordinates in mm (method's axes, reduced to the principal
        point, distortion-free).
    points : array_like, shape (K, 3)
        Object coordinates of the point of each observation (any Cartesian
        frame, e.g. the strip system).
    photo : array_like of int, shape (K,)
        Photo (0 .. n_photos - 1) of each observation.
    n_photos : int
    principal_distance : float
        c in mm; collinearity ``x = -c v_x / v_z``, ``y = -c v_y / v_z`` with
        ``v = Rᵀ (X - S)``.
    centres : array_like, shape (n_photos, 3)
        Start values of the projection centres.
    rotations : array_like, shape (n_photos, 3, 3)
        Start values of the image -> object rotations.
    sigma : float or array_like, shape (K,)
        Standard deviation of an image coordinate, mm (weights 1/σ²).
    max_iterations : int
    tolerance : float
        Stop when the largest rotation correction (radians) and the largest
        centre correction relative to the distance to the points fall below it.
    labels : tuple of str, optional
        Photo names for messages.

    Returns
    -------
    Resection

    Raises
    ------
    GeometryError
        A photo with fewer than 3 points, or a singular solution.
    ConvergenceError
        No convergence within ``max_iterations``.
    """
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    index = np.asarray(photo, dtype=np.intp).reshape(-1)
    k = xy.shape[0]
    if pts.shape[0] != k or index.shape[0] != k:
        raise ValueError(
            f"Expected xy, points and photo with K rows, got {xy.shape}, {pts.shape}, "
            f"{index.shape}"
        )
    m = int(n_photos)
    s = np.array(centres, dtype=np.float64).reshape(m, 3)
    r = np.array(rotations, dtype=np.float64).reshape(m, 3, 3)
    c = float(principal_distance)
    weight = 1.0 / np.broadcast_to(np.asarray(sigma, dtype=np.float64), (k,)) ** 2
    names = labels or tuple(str(i) for i in range(m))
    counts = np.bincount(index, minlength=m)
    few = np.flatnonzero(counts < 3)
    if few.size:
        i = int(few[0])
        raise GeometryError(
            f"photo {names[i]}: space resection needs at least 3 triangulated points, "
            f"got {counts[i]}"
        )
    scale = np.bincount(index, np.linalg.norm(pts - s[index], axis=1), minlength=m) / counts
    converged = False
    it = 0
    for it in range(1, max_iterations + 1):  # noqa: B007
        v, w, res = _collinearity(xy, pts, index, c, s, r)
        jv = np.zeros((k, 2, 3))
        jv[:, 0, 0] = -c / w
        jv[:, 1, 1] = -c / w
        jv[:, 0, 2] = c * v[:, 0] / w**2
        jv[:, 1, 2] = c * v[:, 1] / w**2
        design = np.empty((k, 2, 6))
        design[:, :, :3] = -np.einsum("kab,kcb->kac", jv, r[index])  # dv/dS = -R^T
        design[:, :, 3:] = np.einsum("kab,kbc->kac", jv, skew(v))  # dv/dphi = [v]x
        normal = np.zeros((m, 6, 6))
        rhs = np.zeros((m, 6))
        np.add.at(normal, index, weight[:, None, None] * np.einsum("kri,krj->kij", design, design))
        np.add.at(rhs, index, weight[:, None] * np.einsum("kri,kr->ki", design, res))
        try:
            delta = np.linalg.solve(normal, rhs[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            raise GeometryError(
                "space resection: singular normal equations (points on a line or all "
                "photos' points coincide)"
            ) from None
        s = s + delta[:, :3]
        r = r @ matrix_from_rotvec(delta[:, 3:])
        step = max(
            float(np.max(np.abs(delta[:, 3:]))),
            float(np.max(np.linalg.norm(delta[:, :3], axis=1) / scale)),
        )
        if not np.isfinite(step):
            raise GeometryError("space resection diverged (non-finite corrections)")
        if step < tolerance:
            converged = True
            break
    if not converged:
        raise ConvergenceError(
            f"space resection did not converge in {max_iterations} iterations "
            f"(last correction {step:.3g})"
        )
    _, w, res = _collinearity(xy, pts, index, c, s, r)
    if (w >= 0).any():
        bad = int(index[np.flatnonzero(w >= 0)[0]])
        raise GeometryError(f"photo {names[bad]}: space resection put points behind the photo")
    sq = np.bincount(index, np.sum(res**2, axis=1), minlength=m)
    return Resection(
        centres=s,
        rotations=r,
        iterations=it,
        n_points=counts.astype(np.intp),
        rms_um=1000.0 * np.sqrt(sq / (2 * counts)),
        residuals=res,
    )


# --------------------------------------------------------------------------- intersection


class RayIntersection(NamedTuple):
    """Points intersected from several rays.

    Attributes
    ----------
    points : ndarray, shape (P, 3)
        Least-squares intersection of each point's rays (NaN with fewer than
        two rays or parallel rays).
    n_rays : ndarray of int, shape (P,)
    rms_distance : ndarray, shape (P,)
        RMS distance of the point from its rays, in the rays' units.
    """

    points: FloatArray
    n_rays: IntArray
    rms_distance: FloatArray


def ray_normal_sums(
    point: IntArray, n_points: int, a: FloatArray, b: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The normal equations ``N X = n`` of each point's intersection, ``N``
    (P, 3, 3) and ``n`` (P, 3): the sums of its rays' shares ``a = w (I - d dᵀ)``
    (R, 3, 3) and ``b = a c`` (R, 3) (``d`` a ray's unit direction, ``c`` its
    origin, ``w`` its weight); ``point`` (R,) is each ray's point, 0 .. P - 1."""
    normal = np.zeros((n_points, 3, 3))
    rhs = np.zeros((n_points, 3))
    np.add.at(normal, point, a)
    np.add.at(rhs, point, b)
    return normal, rhs


def solve_ray_normals(normal: FloatArray, rhs: FloatArray, n_rays: IntArray) -> FloatArray:
    """The intersections ``X = N⁻¹ n`` of points from their normal equations
    ``normal`` (P, 3, 3), ``rhs`` (P, 3) (:func:`ray_normal_sums`); NaN for a
    point of fewer than two rays (``n_rays`` (P,)) or whose rays are parallel
    (``|det N|`` at most 1e-12 of ``(trace N)³``)."""
    det = np.linalg.det(normal)
    scale = np.maximum(np.einsum("pii->p", normal), 1e-300) ** 3
    ok = (n_rays >= 2) & (np.abs(det) > 1e-12 * scale)
    out = np.full((normal.shape[0], 3), np.nan)
    if ok.any():
        out[ok] = np.linalg.solve(normal[ok], rhs[ok][:, :, None])[:, :, 0]
    return out


def _solve_rays(
    c: FloatArray, d: FloatArray, idx: IntArray, n_points: int, w: FloatArray
) -> tuple[FloatArray, IntArray]:
    proj = np.eye(3) - d[:, :, None] * d[:, None, :]  # I - d d^T
    normal, rhs = ray_normal_sums(
        idx, n_points, w[:, None, None] * proj, w[:, None] * np.einsum("kij,kj->ki", proj, c)
    )
    n_rays = np.bincount(idx, minlength=n_points)
    return solve_ray_normals(normal, rhs, n_rays), n_rays


def intersect_rays(
    centres: ArrayLike,
    directions: ArrayLike,
    point: ArrayLike,
    n_points: int,
    *,
    image_weights: bool = True,
) -> RayIntersection:
    """Least-squares intersection of many rays per point (vectorised over points).

    Minimises, per point X, ``Σ w_r |(I - d_r d_rᵀ)(X - c_r)|²``: the squared
    distances of X from its rays.  With ``image_weights`` a second solution
    weights each ray by ``1 / t_r²`` (``t_r`` the distance along the ray from
    the first solution), which makes the distances image-scale residuals (as
    in the collinearity least squares) for rays of different lengths.

    Parameters
    ----------
    centres : array_like, shape (R, 3)
        Origin of each ray (projection centre).
    directions : array_like, shape (R, 3)
        Direction of each ray (any length; normalised here), e.g.
        ``R @ (x, y, -c)``.
    point : array_like of int, shape (R,)
        Point (0 .. n_points - 1) of each ray.
    n_points : int
    image_weights : bool

    Returns
    -------
    RayIntersection
    """
    c = np.asarray(centres, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    idx = np.asarray(point, dtype=np.intp).reshape(-1)
    if c.shape != d.shape or idx.shape[0] != c.shape[0]:
        raise ValueError(
            f"Expected centres, directions (R, 3) and point (R,), got {c.shape}, {d.shape}, "
            f"{idx.shape}"
        )
    norm = np.linalg.norm(d, axis=1)
    if (norm == 0).any():
        raise ValueError("Expected non-zero `directions`")
    d = d / norm[:, None]
    n = int(n_points)
    out, n_rays = _solve_rays(c, d, idx, n, np.ones(idx.shape[0]))
    if image_weights:
        t = np.einsum("ki,ki->k", out[idx] - c, d)
        with np.errstate(invalid="ignore", divide="ignore"):
            w = 1.0 / t**2
        w = np.where(np.isfinite(w), w, 0.0)
        out, _ = _solve_rays(c, d, idx, n, w)
        out[n_rays < 2] = np.nan
    gap = out[idx] - c
    perp = gap - np.einsum("ki,ki->k", gap, d)[:, None] * d
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(np.bincount(idx, np.sum(perp**2, axis=1), minlength=n) / n_rays)
    return RayIntersection(out, n_rays.astype(np.intp), rms)


# --------------------------------------------------------------------------- completion


def complete_strip(
    strip: StripModel,
    *,
    all_rays: bool = True,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
) -> StripModel:
    """Orient the photos between the model photos and intersect their points.

    Parameters
    ----------
    strip : StripModel
        Formed on the model photos (``form_strip(..., photo_index=seq)``).
    all_rays : bool
        True (default): every point seen on two or more photos is intersected
        from all its rays, the model photos' and the resected photos' (the
        rays of the photos between the model photos carry most of the
        redundancy of a high-overlap strip).  False: points determined in a
        model keep the models' mean (the method's value) and only the points
        no model determined are intersected.
    max_iterations : int
        Of the space resection.

    Returns
    -------
    StripModel
        ``dataclasses.replace(strip, ...)`` with:

        * ``photo_index``: every photo of ``observations`` in strip order;
        * ``centres``, ``rotations``: all photos, strip system (model photos
          unchanged, the others by space resection on the model points);
        * ``points``: multi-ray intersection (``all_rays``), or the models'
          mean for points determined in a model and the multi-ray
          intersection for the others;
        * ``n_determinations``: models that determined a point; a point added
          by the multi-ray intersection counts 1 (0: not triangulated).

        The model-level fields (``relative``, ``scale``, ``scale_ratio``,
        ``model``, ``model_point``, ``model_points``, ``model_parallax``,
        ``tie_*``, ``model_labels``) are kept: they describe the models of the
        model photos (``model_labels`` names each pair); model m is formed by
        model photos m and m + 1, not by photos m and m + 1 of the new
        ``photo_index``.  A strip already on every photo is returned as is.

    Raises
    ------
    GeometryError
        A photo sees fewer than 3 triangulated points.
    ConvergenceError
        A resection does not converge.
    """
    obs = strip.observations
    n = obs.n_photos
    seq = np.asarray(strip.photo_index, dtype=np.intp)
    if seq.shape[0] == n and np.array_equal(seq, np.arange(n)):
        return strip
    others = np.setdiff1d(np.arange(n), seq)
    centres = np.full((n, 3), np.nan)
    rotations = np.full((n, 3, 3), np.nan)
    centres[seq] = strip.centres
    rotations[seq] = strip.rotations

    # Start values: centres interpolated between the neighbouring model
    # photos, rotation of the nearer one.
    order = np.argsort(seq)
    sorted_seq = seq[order]
    hi = np.clip(np.searchsorted(sorted_seq, others), 1, sorted_seq.shape[0] - 1)
    lo = hi - 1
    p_lo, p_hi = sorted_seq[lo], sorted_seq[hi]
    t = (others - p_lo) / (p_hi - p_lo)
    start_centres = (1 - t)[:, None] * centres[p_lo] + t[:, None] * centres[p_hi]
    start_rotations = np.where((t <= 0.5)[:, None, None], rotations[p_lo], rotations[p_hi])

    slot = np.full(n, -1, dtype=np.intp)
    slot[others] = np.arange(others.shape[0])
    known = strip.n_determinations > 0
    rows = np.flatnonzero((slot[obs.photo] >= 0) & known[obs.point])
    result = resect(
        obs.xy[rows],
        strip.points[obs.point[rows]],
        slot[obs.photo[rows]],
        others.shape[0],
        obs.principal_distance,
        start_centres,
        start_rotations,
        sigma=obs.sigma[rows],
        max_iterations=max_iterations,
        labels=tuple(obs.photo_ids[i] for i in others),
    )
    centres[others] = result.centres
    rotations[others] = result.rotations

    directions = np.einsum("kij,kj->ki", rotations[obs.photo], obs.image_vectors())
    rays = intersect_rays(centres[obs.photo], directions, obs.point, obs.n_points)
    points = np.array(strip.points, dtype=np.float64)
    counts = np.array(strip.n_determinations, dtype=np.intp)
    new = ~known & np.isfinite(rays.points).all(axis=1)
    replace = new | (known if all_rays else np.zeros_like(known))
    points[replace] = rays.points[replace]
    counts[new] = 1
    return dataclasses.replace(
        strip,
        model_photos=np.asarray(strip.photo_index, dtype=np.intp)[strip.model_photo_positions],
        photo_index=np.arange(n, dtype=np.intp),
        centres=centres,
        rotations=rotations,
        points=points,
        n_determinations=counts,
    )


def form_strip_stepped(
    observations: ImageObservations,
    options: StripOptions | None = None,
    *,
    photo_step: int | Literal["auto"] = DEFAULT_PHOTO_STEP,
    min_base_to_height: float = DEFAULT_MIN_BASE_TO_HEIGHT,
    all_rays: bool = True,
    blunders: BlunderOptions | None = None,
) -> StripModel:
    """Form the strip on every k-th photo and complete it (module notes).

    Parameters
    ----------
    observations : ImageObservations
    options : StripOptions, optional
    photo_step : int or "auto"
        k (1: the classical strip on every photo, ``form_strip`` unchanged, or
        ``form_strip_independent`` with ``options.models = "independent"``) or
        ``"auto"`` (:func:`choose_photo_step` with ``min_base_to_height``).
    min_base_to_height : float
    all_rays : bool
        See :func:`complete_strip`.

    Returns
    -------
    StripModel
        On every photo (see :func:`complete_strip` for the fields).
    """
    if photo_step == "auto":
        k = choose_photo_step(observations, min_base_to_height, options=options)
    elif isinstance(photo_step, int | np.integer) and not isinstance(photo_step, bool):
        k = int(photo_step)
    else:
        raise ValueError(f'Expected `photo_step` a positive integer or "auto", got {photo_step!r}')
    if k < 1:
        raise ValueError(f"Expected `photo_step` >= 1, got {photo_step!r}")
    independent = options is not None and options.models is ModelFormation.INDEPENDENT
    form = form_strip_independent if independent else form_strip
    if k == 1:
        return form(observations, options, blunders=blunders)
    seq = model_photo_index(observations.n_photos, k)
    strip = form(observations, options, photo_index=seq, blunders=blunders)
    return dataclasses.replace(complete_strip(strip, all_rays=all_rays), photo_step=k)
