"""Start values of the relative orientation (:mod:`.relative`): the image
similarity, the homography over flat ground and the essential matrix of
every pair at once, for pairs that the iteration cannot start from the
vertical case (short bases, drone swings; docs/strip-formation.md).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
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


class _PairTable(NamedTuple):
    """Rows of every pair side by side in a padded (n_pairs, width) table.

    ``take(values)`` lays the flat (pair-sorted) values out in it, ``fill``
    in the cells beyond a pair's count.  Per-pair sums become products of
    (n_pairs, width, k) arrays: a few small tables instead of (n, k) arrays
    as long as the rows (their page faults cost more than the arithmetic).
    """

    pair: IntArray
    rank: IntArray
    counts: IntArray
    valid: BoolArray

    @classmethod
    def of(cls, pair: IntArray, starts: IntArray) -> _PairTable:
        counts = np.diff(np.append(starts, pair.shape[0]))
        rank = np.arange(pair.shape[0]) - np.repeat(starts, counts)
        valid = np.arange(int(counts.max(initial=0)))[None, :] < counts[:, None]
        return cls(pair, rank, counts, valid)

    def take(self, values: FloatArray, fill: float = 0.0) -> FloatArray:
        table = np.full(self.valid.shape, fill)
        table[self.pair, self.rank] = values
        return table

    def medians(self, table: FloatArray) -> FloatArray:
        """Median of each pair's cells, (n_pairs,): ``table`` holds no NaN and
        +inf beyond each count (a padding equal to a value, +inf, changes no
        rank below the count), so one sort along the rows does it."""
        ordered = np.sort(table, axis=1)
        rows = np.arange(ordered.shape[0])
        counts = self.counts
        medians: FloatArray = 0.5 * (ordered[rows, (counts - 1) // 2] + ordered[rows, counts // 2])
        return medians


def _homography_normals(moments: FloatArray, factors: FloatArray) -> FloatArray:
    """The 9 × 9 normal matrix of every pair's DLT of the homography.

    With ``l = (u, v, -1)`` and ``p = (x, y, -1)`` the two rows of a point in
    the entries of H (row-major) are ``[0, l, y l]`` and ``[-l, 0, -x l]``,
    so the normal matrix is made of 3 × 3 blocks ``S_f = Σ w f l lᵀ`` for
    ``f`` in ``1, x, y, x² + y²``::

        [[S_1, 0,   S_x], [0, S_1, S_y], [S_x, S_y, S_xx+yy]]

    ``moments`` (n_pairs, width, 6): ``u², uv, u, v², v, 1`` of each cell;
    ``factors`` (n_pairs, width, 4): ``w, w x, w y, w (x² + y²)``, zero in
    the padding.
    """
    m = np.matmul(np.swapaxes(factors, 1, 2), moments)  # (n_pairs, 4, 6) sums
    blocks = np.empty((m.shape[0], 4, 3, 3))
    blocks[:, :, 0, 0], blocks[:, :, 1, 1], blocks[:, :, 2, 2] = m[..., 0], m[..., 3], m[..., 5]
    blocks[:, :, 0, 1] = blocks[:, :, 1, 0] = m[..., 1]
    blocks[:, :, 0, 2] = blocks[:, :, 2, 0] = -m[..., 2]
    blocks[:, :, 1, 2] = blocks[:, :, 2, 1] = -m[..., 4]
    normal = np.zeros((m.shape[0], 9, 9))
    normal[:, 0:3, 0:3] = normal[:, 3:6, 3:6] = blocks[:, 0]
    normal[:, 0:3, 6:9] = blocks[:, 1]
    normal[:, 6:9, 0:3] = blocks[:, 1]
    normal[:, 3:6, 6:9] = blocks[:, 2]
    normal[:, 6:9, 3:6] = blocks[:, 2]
    normal[:, 6:9, 6:9] = blocks[:, 3]
    return normal


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
    normalised image coordinates, formed from its 3 × 3 blocks:
    :func:`_homography_normals`), and its decomposition (Malis & Vargas,
    "Deeper understanding of the homography decomposition for vision-based
    control", INRIA RR-6303, 2007, §3.1) gives two candidates with the
    points in front of both photos; the one whose plane normal is nearest
    the left photo's axis (ground below a near-vertical camera) is kept.
    Unlike the image similarity it includes the relative tilts, and unlike
    the essential matrix it is not degenerate over flat ground; relief makes
    it approximate, which is all a start needs.  The fit is iteratively
    reweighted (Cauchy weights of the points' transfer errors, three
    rounds), so that a few gross errors do not turn it.

    The pairs' rows are laid out side by side in padded tables
    (:class:`_PairTable`); pairs of very unequal sizes are taken in groups
    of like size (:func:`_size_groups`), so that the tables stay within
    twice the rows whatever the largest pair.

    Parameters and returns as :func:`essential_start`.
    """
    l = np.asarray(left, dtype=np.float64)
    p = np.asarray(right, dtype=np.float64)
    pair = np.asarray(pair, dtype=np.intp)
    if starts is None:
        starts = _segment_starts(pair, n_pairs)
    counts = np.diff(np.append(starts, pair.shape[0]))
    groups = _size_groups(counts)
    if len(groups) == 1:
        return _homography_start(l, p, pair, n_pairs, starts)
    relative, base = np.empty((n_pairs, 3, 3)), np.empty((n_pairs, 3))
    for group in groups:  # a few groups (sizes within a factor of two), not pairs
        rows = np.flatnonzero(np.isin(pair, group))  # pair-sorted, as pair is
        local = np.searchsorted(group, pair[rows])
        own = np.concatenate([[0], np.cumsum(counts[group])[:-1]]).astype(np.intp)
        relative[group], base[group] = _homography_start(l[rows], p[rows], local, group.size, own)
    return relative, base


#: Pairs are grouped by size when padding them all to the largest would
#: need more than twice their rows and more than this many cells.
_PADDING_CELLS = 1 << 16


def _size_groups(counts: IntArray) -> list[IntArray]:
    """The pairs (indices, ascending) to take together in one padded table:
    all of them when the padding is cheap, else pairs whose row counts
    (each at least one) have the same bit length, within a factor of two."""
    n_cells = counts.size * int(counts.max(initial=0))
    if n_cells <= max(2 * int(counts.sum()), _PADDING_CELLS):
        return [np.arange(counts.size, dtype=np.intp)]
    size = np.frexp(counts.astype(np.float64))[1]  # the bit length of each count
    return [np.flatnonzero(size == k) for k in np.unique(size)]


def _homography_start(
    l: FloatArray, p: FloatArray, pair: IntArray, n_pairs: int, starts: IntArray
) -> tuple[FloatArray, FloatArray]:
    """:func:`homography_start` of pairs in one padded table."""
    table = _PairTable.of(pair, starts)
    # image vectors scaled to z = -1, (u, v, -1) and (x, y, -1), per pair
    lu, lv = (table.take(l[:, k] / -l[:, 2]) for k in (0, 1))
    px, py = (table.take(p[:, k] / -p[:, 2]) for k in (0, 1))
    moments = np.stack([lu * lu, lu * lv, lu, lv * lv, lv, table.valid.astype(np.float64)], axis=2)
    basis = np.stack([np.ones_like(px), px, py, px * px + py * py], axis=2)
    weight = table.valid.astype(np.float64)
    for _ in range(_HOMOGRAPHY_IRLS + 1):
        _, vec = np.linalg.eigh(_homography_normals(moments, basis * weight[:, :, None]))
        h = vec[:, :, 0].reshape(-1, 3, 3)
        # Transfer errors of the points (normalised image units) and Cauchy
        # weights at 2.385 robust sigmas of the pair: a few gross errors (a
        # swapped id) must not turn the start, nor the flight-direction check
        # that uses it.
        hu, hv, hw = (h[:, :, k, None] for k in range(3))
        mapped = hu * lu[:, None] + hv * lv[:, None] - hw  # (n_pairs, 3, width)
        with np.errstate(invalid="ignore", divide="ignore"):
            error = np.hypot(mapped[:, 0] / -mapped[:, 2] - px, mapped[:, 1] / -mapped[:, 2] - py)
        error = np.where(np.isfinite(error) & table.valid, error, np.inf)
        scale = np.maximum(1.4826 * table.medians(error), 1e-12)
        weight = 1.0 / (1.0 + (error / (2.385 * scale[:, None])) ** 2)
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
    counts = table.counts
    for rot, t, n in candidates:
        facing = n[:, 0, None] * lu + n[:, 1, None] * lv - n[:, 2, None]  # nᵀ l, (n_pairs, width)
        in_front = np.count_nonzero((facing > 0) & table.valid, axis=1)
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
