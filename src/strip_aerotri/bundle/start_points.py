"""Start values for the points the strip method left out.

The strip method drops a point whose determinations fail its tie test: one
wrong ray on the middle photo of a point spoils both models that photo
belongs to, and the point goes with all its good rays.  The bundle
refinement can test each ray on its own, so before it starts,
:func:`restore_points` intersects every such point from the strip method's
photos and gives it a start value when three or more of its rays agree;
the bundle's data snooping then finds the wrong ray itself.  Points seen
on two photos are not restored: they have no check of a ray of their own
(a rejection leaves one ray), and on real blocks they are the automatic
matches least to be trusted (on the FC300X block 294 such points took the
check RMSE up by 0.1-0.3 mm in plan on every one of six splits).

Agreement is judged at the start photos.  A ray agrees with an intersection
when both image residuals (mm), divided by the ray's sigma and by the
robust scale ``s`` of the same residuals of the points the strip method did
determine on the same photos (the start photos' own error, 1.4826 times the
median absolute value, at least 1), stay within the critical value of the
image tests.  Each point's rays are intersected all together and leaving
each one out in turn; the point is restored when one of these
intersections makes three or more rays agree: all rays if they do;
otherwise the ray whose leaving out makes the others fit their own
intersection best is given up, one at a time, while four or more are left.
(The ray that fits the others' intersection worst is not a safe choice: a
wrong ray pulls that intersection, and a good ray at the end of a long base
can then fit it worse than the wrong one.)  Intersections minimise the
rays' distances weighted by the inverse square of their length (image-scale
residuals), as in :func:`strip_aerotri.strip.densify.intersect_rays`, and
their normal equations are summed and solved by its functions (the same
test of parallel rays: a determinant, two rays or more).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .._text import named
from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..geometry.collinearity import project
from ..observations import ImageObservations
from ..options import BlunderOptions
from ..strip.densify import intersect_rays, ray_normal_sums, solve_ray_normals
from .snooping import IMAGE_STAGE

__all__ = ["RestoredPoints", "restore_points", "restored_ids", "restored_points_note"]

#: Fewer rays of determined points than this: the start photos' scale is taken as 1.
_MIN_RAYS_FOR_SCALE = 20


class RestoredPoints(NamedTuple):
    """Start values with the restored points filled in.

    Attributes
    ----------
    points : ndarray, shape (P, 3)
        The start points (frame, m); NaN where still none.
    restored : ndarray of bool, shape (P,)
        The points that had no start value and now have one.
    scale : float
        Robust scale of the determined points' normalised residuals at the
        start photos (1 when too few).
    """

    points: FloatArray
    restored: BoolArray
    scale: float


def restore_points(
    observations: ImageObservations,
    centres: ArrayLike,
    rotations: ArrayLike,
    points: ArrayLike,
    *,
    blunders: BlunderOptions | None = None,
) -> RestoredPoints:
    """Start values for points without one whose rays agree (module notes).

    Parameters
    ----------
    observations : ImageObservations
        Reduced image coordinates (mm), their sigmas, photo and point of
        each ray.
    centres : array_like, shape (M, 3)
        Projection centres (frame, m).
    rotations : array_like, shape (M, 3, 3)
        Image -> frame rotations (``l = R @ (x, y, -c)``).
    points : array_like, shape (P, 3)
        Start points (frame, m), NaN where the strip method gave none.
    blunders : BlunderOptions, optional
        Nothing is restored unless it rejects (the default does): without
        rejections a wrong ray would stay in.  Its excluded points and
        observations are left out, and its ``alpha`` sets the critical value.

    Returns
    -------
    RestoredPoints
    """
    blunders = blunders or BlunderOptions()
    obs = observations
    pts = np.array(points, dtype=np.float64, copy=True)
    c = np.asarray(centres, dtype=np.float64)
    rot = np.asarray(rotations, dtype=np.float64)
    p = obs.n_points
    have = np.all(np.isfinite(pts), axis=1)
    restored = np.zeros(p, dtype=bool)
    if have.all() or not blunders.rejecting:
        return RestoredPoints(pts, restored, 1.0)
    photo_ok = np.all(np.isfinite(c), axis=1) & np.all(np.isfinite(rot), axis=(1, 2))
    excluded_points, excluded_obs = blunders.excluded(obs)
    ray_ok = photo_ok[obs.photo] & ~excluded_obs
    wanted = ~have & ~excluded_points
    rows = np.flatnonzero(wanted[obs.point] & ray_ok)
    n_rays = np.bincount(obs.point[rows], minlength=p)
    rows = rows[n_rays[obs.point[rows]] >= 3]
    if not rows.size:
        return RestoredPoints(pts, restored, 1.0)
    # the start photos' own error, on the photos that see the points to restore
    near = np.zeros(c.shape[0], dtype=bool)
    near[obs.photo[rows]] = True
    scale = _start_scale(
        obs, c, rot, pts, np.flatnonzero(have[obs.point] & ray_ok & near[obs.photo])
    )
    tolerance = blunders.critical(IMAGE_STAGE, 2 * obs.photo.shape[0]) * scale
    fill, chosen = _agreeing_intersections(obs, c, rot, rows, tolerance)
    pts[fill] = chosen
    restored[fill] = True
    return RestoredPoints(pts, restored, scale)


def _normalised_residuals(
    obs: ImageObservations, c: FloatArray, rot: FloatArray, rows: IntArray, xyz: FloatArray
) -> FloatArray:
    """|image residual| / sigma of rays ``rows`` at points ``xyz`` (len(rows), 3):
    the larger of x and y; inf for a point not in front of the photo."""
    with np.errstate(divide="ignore", invalid="ignore"):
        xy, v = project(c, rot, xyz, obs.photo[rows], np.arange(rows.size), obs.principal_distance)
        w = np.max(np.abs(xy - obs.xy[rows]), axis=1) / obs.sigma[rows]
    out: FloatArray = np.where((v[:, 2] < 0) & np.isfinite(w), w, np.inf)
    return out


def _start_scale(
    obs: ImageObservations, c: FloatArray, rot: FloatArray, pts: FloatArray, rows: IntArray
) -> float:
    """1.4826 median |v / sigma| of the rays ``rows`` (of determined points)
    at the start, not below 1; 1 with fewer than :data:`_MIN_RAYS_FOR_SCALE`."""
    if rows.size < _MIN_RAYS_FOR_SCALE:
        return 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        xy = project(c, rot, pts, obs.photo[rows], obs.point[rows], obs.principal_distance)[0]
        v = (xy - obs.xy[rows]) / obs.sigma[rows, None]
    v = v[np.all(np.isfinite(v), axis=1)]
    if v.size < _MIN_RAYS_FOR_SCALE:
        return 1.0
    return max(1.0, 1.4826 * float(np.median(np.abs(v))))


class _Rays(NamedTuple):
    """The rays of the points to restore, sorted by point: ``rows`` into the
    observations, ``group`` (R,) the point's rank among ``labels``, each
    ray's share of the normal equations, ``a = w (I - d dᵀ)`` (R, 3, 3) and
    ``b = a @ centre`` (R, 3)."""

    rows: IntArray
    group: IntArray
    labels: IntArray
    a: FloatArray
    b: FloatArray


def _rays(obs: ImageObservations, c: FloatArray, rot: FloatArray, rows: IntArray) -> _Rays:
    """Each ray's share of its point's intersection: ``(I - d dᵀ) / t²`` with
    ``t`` its length to the unweighted intersection of all the point's rays."""
    rows = rows[np.argsort(obs.point[rows], kind="stable")]
    labels, group = np.unique(obs.point[rows], return_inverse=True)
    ph = obs.photo[rows]
    image = np.column_stack([obs.xy[rows], np.full(rows.size, -obs.principal_distance)])
    d = np.einsum("kij,kj->ki", rot[ph], image)
    d /= np.linalg.norm(d, axis=1)[:, None]
    proj = np.eye(3) - d[:, :, None] * d[:, None, :]
    first = intersect_rays(c[ph], d, group, labels.size, image_weights=False).points
    t = np.einsum("ki,ki->k", first[group] - c[ph], d)
    with np.errstate(divide="ignore", invalid="ignore"):
        weight = np.where(np.isfinite(t) & (t > 0), 1.0 / t**2, 0.0)
    a = proj * weight[:, None, None]
    return _Rays(rows, group.astype(np.intp), labels, a, np.einsum("kij,kj->ki", a, c[ph]))


def _agreeing_intersections(
    obs: ImageObservations, c: FloatArray, rot: FloatArray, rows: IntArray, tolerance: float
) -> tuple[IntArray, FloatArray]:
    """The points of ``rows`` (rays of points without a start, three or more
    each) whose rays agree within ``tolerance`` (module notes), and their
    intersections.

    Each round intersects every point from its active rays; a point whose
    rays do not all agree and that has four or more left gives up the ray
    whose leaving out makes the others fit best.  A point is restored when its
    active rays agree, three or more."""
    rays = _rays(obs, c, rot, rows)
    g_count = rays.labels.size
    active = np.ones(rays.rows.size, dtype=bool)
    while True:  # at most (largest number of rays - 3) rounds
        xyz, agree, drop = _round(obs, c, rot, rays, active, tolerance)
        left = np.bincount(rays.group[active], minlength=g_count)
        drop = drop[~agree & (left >= 4) & (drop >= 0)]
        if not drop.size:
            break
        active[drop] = False
    left = np.bincount(rays.group[active], minlength=g_count)
    ok = agree & (left >= 3) & np.all(np.isfinite(xyz), axis=1)
    return rays.labels[ok].astype(np.intp), xyz[ok]


def _round(
    obs: ImageObservations,
    c: FloatArray,
    rot: FloatArray,
    rays: _Rays,
    active: BoolArray,
    tolerance: float,
) -> tuple[FloatArray, BoolArray, IntArray]:
    """One round over the active rays: each point's intersection (G, 3),
    whether all its active rays agree with it (G,), and the ray (index into
    ``rays``) whose leaving out makes the point's other rays fit their own
    intersection best (the largest of their residuals the smallest), -1 for
    a point with fewer than three.

    Length: the table of the leave-one-out intersections and the rays each
    is judged on is built in one vectorised pass."""
    g_count = rays.labels.size
    on = np.flatnonzero(active)
    group = rays.group[on]
    sizes = np.bincount(group, minlength=g_count)
    a_all, b_all = ray_normal_sums(group, g_count, rays.a[on], rays.b[on])
    xyz = solve_ray_normals(a_all, b_all, sizes)
    w = _normalised_residuals(obs, c, rot, rays.rows[on], xyz[group])
    score = np.zeros(g_count)
    np.maximum.at(score, group, w)
    agree = (score <= tolerance) & np.all(np.isfinite(xyz), axis=1)
    drop = np.full(g_count, -1, dtype=np.intp)
    loo = np.flatnonzero(sizes[group] >= 3)  # positions in ``on``
    if not loo.size:
        return xyz, agree, drop
    g = group[loo]
    others = solve_ray_normals(  # each point of three or more rays less one of them
        a_all[g] - rays.a[on[loo]], b_all[g] - rays.b[on[loo]], sizes[g] - 1
    )
    # pairs (leave-one-out candidate, another active ray of its point); the
    # active rays are sorted by point, so a point's rays are contiguous in ``on``
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    counts = sizes[g]
    pair_cand = np.repeat(np.arange(loo.size), counts)
    within = np.arange(pair_cand.size) - np.repeat(np.cumsum(counts) - counts, counts)
    pair_ray = starts[g[pair_cand]] + within
    keep = pair_ray != loo[pair_cand]
    pair_cand, pair_ray = pair_cand[keep], pair_ray[keep]
    fit = np.zeros(loo.size)
    np.maximum.at(
        fit,
        pair_cand,
        _normalised_residuals(obs, c, rot, rays.rows[on[pair_ray]], others[pair_cand]),
    )
    fit[~np.all(np.isfinite(others), axis=1)] = np.inf
    order = np.lexsort((fit, g))
    first = order[np.unique(g[order], return_index=True)[1]]
    first = first[np.isfinite(fit[first])]
    drop[g[first]] = on[loo[first]]
    return xyz, agree, drop


def restored_ids(
    point_ids: Sequence[str], restored: ArrayLike, used: ArrayLike
) -> tuple[str, ...]:
    """The points the strip method left out that the refinement restored
    (``restored`` (P,) bool) and determined (``used`` (P,) bool), in point order."""
    back = np.flatnonzero(np.asarray(restored, dtype=bool) & np.asarray(used, dtype=bool))
    return tuple(point_ids[i] for i in back.tolist())


def restored_points_note(
    point_ids: Sequence[str], restored: ArrayLike, used: ArrayLike
) -> list[str]:
    """The note naming the points the strip method left out that the
    refinement restored and determined (``restored``, ``used``: (P,) bool)."""
    back = restored_ids(point_ids, restored, used)
    if not back:
        return []
    return [
        f"bundle: {len(back)} point(s) left out before the refinement were intersected from "
        f"the photos and determined, their rays tested one by one: {named(back)}"
    ]
