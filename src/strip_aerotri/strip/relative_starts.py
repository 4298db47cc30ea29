"""Start values of the relative orientation (:mod:`.relative`): the image
similarity, the homography over flat ground and the essential matrix of
every pair at once, for pairs that the iteration cannot start from the
vertical case (short bases, drone swings; docs/strip-formation.md).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from .relative_state import _EX, _segment_starts

__all__ = ["SimilarityStart", "essential_start", "homography_start", "similarity_start"]


_HOMOGRAPHY_IRLS = 3  # reweighted rounds of the homography start


def _similarity_start(
    left: FloatArray, right: FloatArray, pair: IntArray, n_pairs: int, starts: IntArray
) -> tuple[FloatArray, FloatArray]:
    """The rotation and base direction of :func:`similarity_start`."""
    start = similarity_start(left, right, pair, n_pairs, starts)
    return start.relative, start.base


def _vertical_start(
    left: FloatArray, right: FloatArray, pair: IntArray, n_pairs: int, starts: IntArray
) -> tuple[FloatArray, FloatArray]:
    """J's near-vertical start: ``Q = I`` and the base along image x."""
    return np.broadcast_to(np.eye(3), (n_pairs, 3, 3)), np.tile(_EX, (n_pairs, 1))


class SimilarityStart(NamedTuple):
    """Start values of the pairs from a 2D similarity between their images.

    Attributes
    ----------
    relative : ndarray, shape (n_pairs, 3, 3)
        Right image -> left image rotation: the relative kappa about image z.
    base : ndarray, shape (n_pairs, 3)
        Base direction in the left image (not normalised): the image shift
        (x, y) of the similarity and the change of scale as z.
    shift : ndarray, shape (n_pairs, 2)
        The similarity's shift ``t`` of ``left ≈ a · right + t`` in
        normalised image units (x / -z, y / -z): about base / height along
        the base's image direction; its x is positive when the pair's right
        photo follows the left one along image x.
    kappa : ndarray, shape (n_pairs,)
        Relative kappa ``arg a`` in radians.
    scale : ndarray, shape (n_pairs,)
        ``|a|``: the ratio of the photos' distances to the ground (right over
        left).
    """

    relative: FloatArray
    base: FloatArray
    shift: FloatArray
    kappa: FloatArray
    scale: FloatArray


def similarity_start(
    left: ArrayLike,
    right: ArrayLike,
    pair: ArrayLike,
    n_pairs: int,
    starts: IntArray | None = None,
) -> SimilarityStart:
    """Linear start values of every pair from a 2D similarity of its images.

    For near-vertical photos the image of a point on the right photo,
    turned by the relative kappa, is the left one shifted by the base over
    the height (times c) and scaled by the ratio of the flying heights:
    ``z_l ≈ a z_r + t`` in complex normalised image coordinates
    ``z = (x + i y) / (-z_image)``, solved in closed form per pair (least
    squares over its points).  The start is ``Q = R_z(arg a)`` and the base
    direction ``(t_x, t_y, |a| - 1)``; the tilts start at zero.  Unlike the
    essential matrix it is not degenerate over flat ground, and unlike J's
    start (``Q = I``) it is not far off for the swings of drone photos.

    Parameters
    ----------
    left, right : array_like, shape (n, 3)
        Image vectors of each point on the left and the right photo.
    pair : array_like of int, shape (n,)
        Sorted pair index of each row; every pair has at least one row.
    n_pairs : int

    Returns
    -------
    SimilarityStart
    """
    l = np.asarray(left, dtype=np.float64)
    r = np.asarray(right, dtype=np.float64)
    pair = np.asarray(pair, dtype=np.intp)
    if starts is None:
        starts = _segment_starts(pair, n_pairs)
    zl = (l[:, 0] + 1j * l[:, 1]) / -l[:, 2]
    zr = (r[:, 0] + 1j * r[:, 1]) / -r[:, 2]
    counts = np.bincount(pair, minlength=n_pairs)
    ml = np.add.reduceat(zl, starts) / counts
    mr = np.add.reduceat(zr, starts) / counts
    dl, dr = zl - ml[pair], zr - mr[pair]
    with np.errstate(invalid="ignore", divide="ignore"):
        a = np.add.reduceat(np.conj(dr) * dl, starts) / np.add.reduceat(np.abs(dr) ** 2, starts)
    a = np.where(np.isfinite(a), a, 1.0)
    t = ml - a * mr
    kappa = np.angle(a)
    c, s = np.cos(kappa), np.sin(kappa)
    relative = np.zeros((n_pairs, 3, 3))
    relative[:, 0, 0], relative[:, 0, 1] = c, -s
    relative[:, 1, 0], relative[:, 1, 1] = s, c
    relative[:, 2, 2] = 1.0
    base = np.column_stack([t.real, t.imag, np.abs(a) - 1.0])
    # No usable direction from a shift of zero length (identical images) or
    # across image x (the dependent pair fixes b_x = 1): start along x; the
    # flight-direction checks name such strips before they get here.
    base[~(np.abs(t.real) > 0.1 * np.abs(t))] = _EX
    return SimilarityStart(relative, base, np.column_stack([t.real, t.imag]), kappa, np.abs(a))


def _pair_medians(values: FloatArray, pair: IntArray, starts: IntArray) -> FloatArray:
    """Median of each pair's values (rows sorted by pair, no NaN), (n_pairs,).

    Each pair's values are sorted in a row of their own, padded with +inf
    beyond its count (a padding equal to a value +inf changes no rank below
    the count): one sort along rows, not a lexsort of every value.
    """
    counts = np.diff(np.append(starts, values.shape[0]))
    rank = np.arange(values.shape[0]) - np.repeat(starts, counts)
    table = np.full((starts.shape[0], int(counts.max(initial=0))), np.inf)
    table[pair, rank] = values
    table.sort(axis=1)
    rows = np.arange(starts.shape[0])
    medians: FloatArray = 0.5 * (table[rows, (counts - 1) // 2] + table[rows, counts // 2])
    return medians


def homography_start(
    left: ArrayLike,
    right: ArrayLike,
    pair: ArrayLike,
    n_pairs: int,
    starts: IntArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Linear start values of every pair from the homography of its images.

    Over nearly flat ground the two bundles are related by the homography
    of the ground plane, ``p ~ H l`` with ``H = R + t nᵀ / d`` (``R = Qᵀ``
    and ``t = -Qᵀ b`` for the right photo, ``n`` the plane's normal and
    ``d`` its distance in the left image system).  H is the eigenvector of
    the smallest eigenvalue of each pair's 9 × 9 normal matrix (the DLT on
    normalised image coordinates), and its decomposition (Malis & Vargas,
    "Deeper understanding of the homography decomposition for vision-based
    control", INRIA RR-6303, 2007, §3.1) gives two candidates with the
    points in front of both photos; the one whose plane normal is nearest
    the left photo's axis (ground below a near-vertical camera) is kept.
    Unlike the image similarity it includes the relative tilts, and unlike
    the essential matrix it is not degenerate over flat ground; relief makes
    it approximate, which is all a start needs.  The fit is iteratively
    reweighted (Cauchy weights of the points' transfer errors, three
    rounds), so that a few gross errors do not turn it.

    Parameters and returns as :func:`essential_start`.
    """
    l = np.asarray(left, dtype=np.float64)
    p = np.asarray(right, dtype=np.float64)
    pair = np.asarray(pair, dtype=np.intp)
    if starts is None:
        starts = _segment_starts(pair, n_pairs)
    # image vectors scaled to z = -1: (u, v, -1)
    a = l / -l[:, 2:3]
    b = p / -p[:, 2:3]
    # p × (H l) = 0: two rows per point in the nine entries of H (row-major)
    zero = np.zeros_like(a)
    rows1 = np.concatenate([zero, -b[:, 2:3] * a, b[:, 1:2] * a], axis=1)
    rows2 = np.concatenate([b[:, 2:3] * a, zero, -b[:, 0:1] * a], axis=1)
    # the 45 entries on and above the diagonal of each row's product (the
    # normal matrix is symmetric: the same sums, half the work)
    upper, lower = np.triu_indices(9)
    products = rows1[:, upper] * rows1[:, lower] + rows2[:, upper] * rows2[:, lower]
    weight = np.ones(pair.shape[0])
    normal = np.empty((n_pairs, 9, 9))
    for _ in range(_HOMOGRAPHY_IRLS + 1):
        sums = np.add.reduceat(weight[:, None] * products, starts, axis=0)
        normal[:, upper, lower] = sums
        normal[:, lower, upper] = sums
        _, vec = np.linalg.eigh(normal)
        h = vec[:, :, 0].reshape(-1, 3, 3)
        # Transfer errors of the points (normalised image units) and Cauchy
        # weights at 2.385 robust sigmas of the pair: a few gross errors (a
        # swapped id) must not turn the start, nor the flight-direction check
        # that uses it.
        mapped = np.einsum("nij,nj->ni", h[pair], a)
        with np.errstate(invalid="ignore", divide="ignore"):
            error = np.hypot(*(mapped[:, :2] / -mapped[:, 2:3] - b[:, :2]).T)
        error = np.where(np.isfinite(error), error, np.inf)
        scale = np.maximum(1.4826 * _pair_medians(error, pair, starts), 1e-12)
        weight = 1.0 / (1.0 + (error / (2.385 * scale[pair])) ** 2)
    # Scale so that the middle singular value is 1 and det(H) > 0.
    sv = np.linalg.svd(h, compute_uv=False)
    h = h / (sv[:, 1] * np.sign(np.linalg.det(h)))[:, None, None]
    lam, v = np.linalg.eigh(np.swapaxes(h, 1, 2) @ h)  # ascending: λ3 <= 1 <= λ1
    v1, v2, v3 = v[:, :, 2], v[:, :, 1], v[:, :, 0]
    l1 = np.maximum(lam[:, 2], 1.0)
    l3 = np.minimum(lam[:, 0], 1.0)
    spread = np.sqrt(np.maximum(l1 - l3, 1e-300))[:, None]
    wa = np.sqrt(1.0 - l3)[:, None]
    wb = np.sqrt(l1 - 1.0)[:, None]
    candidates: list[tuple[FloatArray, FloatArray, FloatArray]] = []
    for sign in (1.0, -1.0):
        u = (wa * v1 + sign * wb * v3) / spread
        n = np.cross(v2, u)
        hv2 = np.einsum("mij,mj->mi", h, v2)
        hu = np.einsum("mij,mj->mi", h, u)
        frame_u = np.stack([v2, u, n], axis=2)
        frame_w = np.stack([hv2, hu, np.cross(hv2, hu)], axis=2)
        rot = frame_w @ np.swapaxes(frame_u, 1, 2)
        t = np.einsum("mij,mj->mi", h - rot, n)
        candidates.extend((rot, flip * t, flip * n) for flip in (1.0, -1.0))
    # In front of the left photo: nᵀ l > 0 for the points (the plane at
    # distance d > 0 along n); among those, the normal nearest -z (ground
    # below the camera).
    best_q = np.broadcast_to(np.eye(3), (n_pairs, 3, 3)).copy()
    best_b = np.tile(_EX, (n_pairs, 1))
    best_score = np.full(n_pairs, -np.inf)
    counts = np.bincount(pair, minlength=n_pairs)
    for rot, t, n in candidates:
        in_front = np.bincount(pair, np.einsum("ij,ij->i", n[pair], a) > 0, minlength=n_pairs)
        norm = np.linalg.norm(n, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            score = np.where(in_front == counts, -n[:, 2] / norm, -np.inf)
        better = score > best_score
        q = np.swapaxes(rot, 1, 2)
        base = -np.einsum("mij,mj->mi", q, t)
        best_q[better] = q[better]
        best_b[better] = base[better]
        best_score = np.where(better, score, best_score)
    ok = (
        np.isfinite(best_score)
        & np.isfinite(best_b).all(axis=1)
        & (np.linalg.norm(best_b, axis=1) > 0)
    )
    best_q[~ok] = np.eye(3)
    best_b[~ok] = _EX
    return best_q, best_b


_W = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


def essential_start(
    left: ArrayLike,
    right: ArrayLike,
    pair: ArrayLike,
    n_pairs: int,
    starts: IntArray | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Linear start for pairs with large relative rotations (essential matrix).

    The coplanarity ``l · (b × Q p) = 0`` is linear in ``E = [b]× Q``; E is
    the eigenvector of the smallest eigenvalue of each pair's 9 × 9 normal
    matrix (the eight-point solution on unit ray vectors), projected to an
    essential matrix and decomposed into the four ``(Q, ±b)`` candidates
    (Hartley & Zisserman, Multiple View Geometry, 2nd ed., §9.6); the
    candidate with most points in front of both photos is kept.

    Parameters
    ----------
    left, right : array_like, shape (n, 3)
        Image vectors of each point on the left and right photo.
    pair : array_like of int, shape (n,)
        Sorted pair index of each row.
    n_pairs : int

    Returns
    -------
    relative : ndarray, shape (n_pairs, 3, 3)
        Right image -> left image rotation Q.
    base : ndarray, shape (n_pairs, 3)
        Unit base direction in the left image system.

    Notes
    -----
    Degenerate for a planar scene; used only where the iteration from the
    near-vertical start fails.
    """
    l = np.asarray(left, dtype=np.float64)
    p = np.asarray(right, dtype=np.float64)
    pair = np.asarray(pair, dtype=np.intp)
    if starts is None:
        starts = _segment_starts(pair, n_pairs)
    l = l / np.linalg.norm(l, axis=1, keepdims=True)
    p = p / np.linalg.norm(p, axis=1, keepdims=True)
    rows = (l[:, :, None] * p[:, None, :]).reshape(-1, 9)
    normal = np.add.reduceat(rows[:, :, None] * rows[:, None, :], starts, axis=0)
    _, vec = np.linalg.eigh(normal)
    e = vec[:, :, 0].reshape(-1, 3, 3)
    u, _, vt = np.linalg.svd(e)
    u = u * np.sign(np.linalg.det(u))[:, None, None]
    vt = vt * np.sign(np.linalg.det(vt))[:, None, None]
    candidates_q = [u @ _W @ vt, u @ _W.T @ vt]
    t = u[:, :, 2]
    best_q = candidates_q[0].copy()
    best_b = t.copy()
    best_count = np.full(n_pairs, -1)
    for q_m in candidates_q:
        qp = np.einsum("nij,nj->ni", q_m[pair], p)
        lxqp = np.cross(l, qp)
        norm2 = np.einsum("ij,ij->i", lxqp, lxqp)
        for sign in (1.0, -1.0):
            b = sign * t[pair]
            k = np.einsum("ij,ij->i", np.cross(b, qp), lxqp) / norm2
            m = np.einsum("ij,ij->i", np.cross(b, l), lxqp) / norm2
            count = np.bincount(pair, (k > 0) & (m > 0), minlength=n_pairs)
            better = count > best_count
            best_q[better] = q_m[better]
            best_b[better] = sign * t[better]
            best_count = np.where(better, count, best_count)
    return best_q, best_b
