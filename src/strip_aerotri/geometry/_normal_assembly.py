"""The kernels of :mod:`strip_aerotri.geometry.normals`: forming the normal
blocks, the Schur complement on the points, the band's factor and solve with
the border eliminated after it, and the selected inverse with the redundancy
numbers.  Shapes: n units of d parameters, p points, k border parameters;
the band in the structure's order (position J holds unit ``order[J]``)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ._blockband import BandFactor, NotPositiveDefinite, factor_band, selected_inverse
from ._normal_rows import (
    POINT_RANK_TOL,
    BorderRows,
    PointRows,
    Rows,
    SingularNormalsError,
    UnitPointRows,
    UnitRows,
    _Normals,
)
from ._normal_rows import StructureLike as NormalStructure


_A = TypeVar("_A", FloatArray, IntArray)


def sum_into(index: IntArray, values: FloatArray, n: int) -> FloatArray:
    """``out[index[i]] += values[i]`` for values (m, *shape) -> (n, *shape)."""
    shape = values.shape[1:]
    size = int(np.prod(shape, dtype=np.intp))
    if size == 0 or index.size == 0:
        return np.zeros((n, *shape))
    flat = (index[:, None] * size + np.arange(size)[None, :]).reshape(-1)
    out: FloatArray = np.bincount(  # type: ignore[assignment]
        flat, values.reshape(-1), minlength=n * size
    )
    return out.reshape(n, *shape)


def _add_blocks(
    blocks: FloatArray, index: IntArray, values: FloatArray,
    compressed: tuple[IntArray, IntArray] | None = None,
) -> None:
    """``blocks[index[i]] += values[i]`` in place (blocks (N, d, d), values
    (m, d, d)), summed over the distinct indices only (the band is large, the
    blocks touched may be few); `compressed` the precomputed
    ``np.unique(index, return_inverse=True)``."""
    if index.size == 0:
        return
    uniq, inverse = compressed if compressed is not None else np.unique(index, return_inverse=True)
    blocks[uniq] += sum_into(inverse, values, uniq.size)


def assemble(
    st: NormalStructure,
    unit_point_rows: Sequence[UnitPointRows],
    unit_rows: Sequence[UnitRows],
    point_rows: Sequence[PointRows],
    border_rows: Sequence[BorderRows],
) -> _Normals:
    """The normal blocks (U in the band, V, W per pair, the border's) and
    the gradients ``Aᵀ P f`` of all rows.

    Length: one accumulation per kind of row, in one place so that the four
    kinds add into the same arrays in the same way."""

    pat = st.pattern
    n, d, p, k = st.n_units, st.unit_size, st.n_points, st.n_border
    w1 = pat.width + 1
    n_pairs = pat.pair_unit.size
    band = np.zeros(n * w1 * d * d)
    g_unit = np.zeros((n, d))
    v = np.zeros((p, 3, 3))
    g_point = np.zeros((p, 3))
    w = np.zeros((n_pairs, d, 3))
    unit_border = np.zeros((n, d, k))
    point_border = np.zeros((p, 3, k))
    border = np.zeros((k, k))
    g_border = np.zeros(k)
    cost = 0.0
    diag_block = pat.position * w1  # band block of each unit's diagonal
    whitened = [rows.whitened(k, d) for rows in unit_point_rows]
    fast = _fast_unit_point(st, unit_point_rows, whitened)
    if fast is not None:
        u_blocks, w, v, g_unit, g_point, unit_border, point_border, border, g_border, cost = fast
        band.reshape(n * w1, d, d)[diag_block] += u_blocks  # one block per unit
    offset = 0
    for rows, (au, ap, f, ab) in zip(unit_point_rows, whitened):
        if fast is not None:
            break
        unit = np.asarray(rows.unit, np.intp)
        point = np.asarray(rows.point, np.intp)
        g = unit.size
        pair = pat.row_pair[offset : offset + g]
        if pair.size != g or np.any(pat.pair_unit[pair] != unit) or np.any(
            pat.pair_point[pair] != point
        ):
            pair = pat.pair_of(unit, point)
        offset += g
        _add_blocks(band.reshape(n * w1, d, d), diag_block[unit], np.einsum("gra,grb->gab", au, au))
        w += sum_into(pair, np.einsum("gra,grb->gab", au, ap), n_pairs)
        v += sum_into(point, np.einsum("gra,grb->gab", ap, ap), p)
        g_unit += sum_into(unit, np.einsum("gra,gr->ga", au, f), n)
        g_point += sum_into(point, np.einsum("gra,gr->ga", ap, f), p)
        cost += float(np.sum(f * f))
        if k:
            unit_border += sum_into(unit, np.einsum("gra,grb->gab", au, ab), n)
            point_border += sum_into(point, np.einsum("gra,grb->gab", ap, ab), p)
            border += np.einsum("gra,grb->ab", ab, ab)
            g_border += np.einsum("gra,gr->a", ab, f)
    for urows in unit_rows:
        a, f, ab = urows.whitened(k, d)
        units = np.asarray(urows.units, np.intp)
        q = units.shape[1]
        blocks = np.einsum("grai,grbj->gabij", a, a)  # (g, q, q, d, d)
        ia, ib = np.meshgrid(np.arange(q), np.arange(q), indexing="ij")
        ua, ub = units[:, ia.ravel()], units[:, ib.ravel()]  # (g, q*q)
        idx, upper = pat.block_index(ua, ub)
        keep = ~upper
        _add_blocks(
            band.reshape(n * w1, d, d), idx[keep], blocks.reshape(units.shape[0], q * q, d, d)[keep]
        )
        g_unit += sum_into(units.reshape(-1), np.einsum("grai,gr->gai", a, f).reshape(-1, d), n)
        cost += float(np.sum(f * f))
        if k:
            ub_blocks = np.einsum("grai,grb->gaib", a, ab).reshape(-1, d, k)
            unit_border += sum_into(units.reshape(-1), ub_blocks, n)
            border += np.einsum("gra,grb->ab", ab, ab)
            g_border += np.einsum("gra,gr->a", ab, f)
    for prows in point_rows:
        a, f, ab = prows.whitened(k)
        point = np.asarray(prows.point, np.intp)
        v += sum_into(point, np.einsum("gra,grb->gab", a, a), p)
        g_point += sum_into(point, np.einsum("gra,gr->ga", a, f), p)
        cost += float(np.sum(f * f))
        if k:
            point_border += sum_into(point, np.einsum("gra,grb->gab", a, ab), p)
            border += np.einsum("gra,grb->ab", ab, ab)
            g_border += np.einsum("gra,gr->a", ab, f)
    for brows in border_rows:
        a, f = brows.whitened(k)
        border += np.einsum("gra,grb->ab", a, a)
        g_border += np.einsum("gra,gr->a", a, f)
        cost += float(np.sum(f * f))
    return _Normals(
        band.reshape(n, w1, d, d), g_unit, v, g_point, w, unit_border, point_border, border,
        g_border, cost,
    )


def _by_group(blocks: FloatArray, groups: int, n_g: int, q: int, d: int) -> FloatArray:
    """Pair blocks (G n_g q, d, c) of a chunk as (G, q d, c n_g): per group,
    the blocks of its points side by side, a row per unit parameter."""
    c = blocks.shape[-1]
    out: FloatArray = (
        blocks.reshape(groups, n_g, q, d, c).transpose(0, 2, 3, 1, 4).reshape(groups, q * d, n_g * c)
    )
    return out


def _by_point(blocks: FloatArray, groups: int, n_g: int, q: int, d: int) -> FloatArray:
    """The inverse of :func:`_by_group`: (G, q d, c n_g) -> (G n_g q, d, c)."""
    c = blocks.shape[-1] // n_g
    out: FloatArray = (
        blocks.reshape(groups, q, d, n_g, c).transpose(0, 3, 1, 2, 4).reshape(-1, d, c)
    )
    return out


_Blocks = tuple[
    FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray,
    FloatArray, FloatArray, float,
]


def _joined(arrays: list[_A]) -> _A:
    """One array of the groups' rows (no copy for one group)."""
    return arrays[0] if len(arrays) == 1 else np.concatenate(arrays)


def _fast_unit_point(
    st: NormalStructure,
    unit_point_rows: Sequence[UnitPointRows],
    whitened: list[tuple[FloatArray, FloatArray, FloatArray, FloatArray]],
) -> _Blocks | None:
    """The unit-point rows' blocks when they are the structure's own rows with
    one row group per (unit, point) pair and the same r (the common case):
    U (and U_b) per unit as one product of its rows stacked (zero-padded to
    the most rows of a unit), W per pair, V per point.  None otherwise."""
    pat = st.pattern
    if pat.pair_row is None or not whitened or len({a[0].shape[1] for a in whitened}) != 1:
        return None
    unit = _joined([np.asarray(r.unit, np.intp) for r in unit_point_rows])
    point = _joined([np.asarray(r.point, np.intp) for r in unit_point_rows])
    if not (np.array_equal(unit, pat.row_unit) and np.array_equal(point, pat.row_point)):
        return None
    n, d, p, k = st.n_units, st.unit_size, st.n_points, st.n_border
    au, ap, f, ab = (_joined([a[i] for a in whitened]) for i in range(4))
    g, r = f.shape
    padded = np.zeros((n, pat.rows_per_unit, r, d + k))
    padded[unit, pat.unit_slot, :, :d] = au
    if k:
        padded[unit, pat.unit_slot, :, d:] = ab
    stacked = padded.reshape(n, -1, d + k)
    uu = np.swapaxes(stacked, 1, 2) @ stacked  # (n, d + k, d + k)
    rows = pat.pair_row
    ap_pairs = ap[rows]
    w = np.swapaxes(au[rows], 1, 2) @ ap_pairs  # (n_pairs, d, 3)
    # V, V_b and the points' gradients: the pairs of a point are contiguous
    apb = np.concatenate([ap_pairs, ab[rows]], axis=2) if k else ap_pairs
    starts, seen = pat.point_runs
    vv = np.zeros((p, 3, 3 + k))
    g_point = np.zeros((p, 3))
    if starts.size:
        vv[seen] = np.add.reduceat(np.swapaxes(ap_pairs, 1, 2) @ apb, starts, axis=0)
        g_point[seen] = np.add.reduceat(np.einsum("gra,gr->ga", ap_pairs, f[rows]), starts, axis=0)
    g_unit = sum_into(unit, np.einsum("gra,gr->ga", au, f), n)
    border = uu[:, d:, d:].sum(axis=0)
    g_border = np.einsum("gra,gr->a", ab, f) if k else np.zeros(0)
    return (
        uu[:, :d, :d], w, vv[:, :, :3].copy(), g_unit, g_point, uu[:, :d, d:].copy(),
        vv[:, :, 3:].copy(), border, g_border, float(np.sum(f * f)),
    )


@dataclass
class Reduced:
    """The reduced system's factor and what the step and the cofactors need."""

    factor: BandFactor
    unit_step: FloatArray
    point_step: FloatArray
    border_step: FloatArray
    v_inv: FloatArray  # (p, 3, 3), undamped when damping == 0
    y: FloatArray  # (n_pairs, d, 3) W V⁻¹
    y_border: FloatArray  # (p, k, 3) Vbᵀ V⁻¹
    x: FloatArray  # (n d, k) S⁻¹ Sb, position order
    t_inv: FloatArray  # (k, k) (Sbb - Sbᵀ S⁻¹ Sb)⁻¹
    border_min_pivot: float
    normals: _Normals


def _damped(normals: _Normals, damping: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    band, v, border = normals.band, normals.v, normals.border
    if damping > 0.0:
        band = band.copy()
        v = v.copy()
        border = border.copy()
        i = np.arange(band.shape[-1])
        band[:, 0, i, i] *= 1.0 + damping
        i3 = np.arange(3)
        v[:, i3, i3] *= 1.0 + damping
        ik = np.arange(border.shape[0])
        border[ik, ik] *= 1.0 + damping
    return band, v, border


def undetermined_points(v: FloatArray, tol: float) -> tuple[IntArray, FloatArray | None]:
    """Points whose 3 x 3 block has ``λmin <= tol λmax`` and ``V⁻¹`` (None when
    a block is exactly singular).  ``λmin / λmax >= 1 / (trace V⁻¹ trace V)``:
    eigenvalues are computed only for the blocks below that bound."""
    v_inv: FloatArray | None
    try:
        with np.errstate(all="ignore"):
            inv: FloatArray = np.linalg.inv(v)  # type: ignore[assignment]
        bound = 1.0 / (np.trace(inv, axis1=1, axis2=2) * np.trace(v, axis1=1, axis2=2))
        near = np.flatnonzero(~(bound > tol))
        v_inv = inv
    except np.linalg.LinAlgError:  # an exactly singular block
        v_inv = None
        near = np.arange(v.shape[0])
    if near.size == 0:
        return near, v_inv
    ev = np.linalg.eigvalsh(v[near])
    return near[~(ev[:, 0] > tol * ev[:, 2])], v_inv


def _point_inverse(st: NormalStructure, v: FloatArray) -> FloatArray:
    """V⁻¹ of every point; SingularNormalsError naming the first undetermined one."""

    if v.shape[0] == 0:
        return v.copy()
    bad, v_inv = undetermined_points(v, POINT_RANK_TOL)
    if bad.size or v_inv is None:
        i = int(bad[0]) if bad.size else 0
        raise SingularNormalsError(
            f"{bad.size} point(s) not determined, the first {st.point_name(i)}: "
            "its 3 x 3 normal block is singular (a point needs rays from two units, or "
            "control that fixes it)",
            "point",
            i,
        )
    return v_inv


def reduce_points(st: NormalStructure, normals: _Normals, damping: float) -> Reduced:
    """Schur complement on the points, the banded factor, the border after
    the band, the step (units, points, border) and its predicted cost.

    Length: the four stages of method.md 6B 1-2 for one step, which share
    their intermediate products."""

    pat = st.pattern
    n, d, k = st.n_units, st.unit_size, st.n_border
    w1 = pat.width + 1
    band, v, border = _damped(normals, damping)
    v_inv = _point_inverse(st, v)
    y = normals.w @ v_inv[pat.pair_point]  # (n_pairs, d, 3)
    flat = band.reshape(-1).copy()
    dd = d * d
    flat_blocks = flat.reshape(n * w1, dd)
    for c in pat.chunks:
        q, n_g, groups = c.q, c.size, c.groups
        span = slice(c.pair_start, c.pair_start + groups * n_g * q)
        # per group: [Y of its points side by side] (qd, 3 n_g) times the same of W
        yc = _by_group(y[span], groups, n_g, q, d)
        wc = _by_group(normals.w[span], groups, n_g, q, d)
        sums = yc @ np.swapaxes(wc, 1, 2)  # (G, qd, qd)
        blocks = sums.reshape(-1, q, d, q, d).transpose(0, 1, 3, 2, 4)[:, c.lower_a, c.lower_b]
        # summed over the distinct blocks of the chunk (several groups add
        # into one block of the band)
        flat_blocks[c.scatter_unique] -= sum_into(
            c.scatter_inverse, blocks.reshape(-1, dd), c.scatter_unique.size
        )
    s_band = flat.reshape(n, w1, d, d)
    b_point = -normals.g_point
    rhs_unit = -normals.g_unit - sum_into(
        pat.pair_unit, np.einsum("pij,pj->pi", y, b_point[pat.pair_point]), n
    )
    try:
        factor = factor_band(s_band)
    except NotPositiveDefinite as exc:
        unit = int(pat.order[exc.index // d])
        raise SingularNormalsError(
            f"the reduced normal matrix is singular at the {st.parameter_name(exc.index % d)} "
            f"of {st.unit_name(unit)}: the datum or that unit is not determined by the "
            "observations",
            "unit",
            unit,
            exc.index % d,
        ) from None
    order = pat.order
    rhs_pos = rhs_unit[order].reshape(-1)
    y_border = np.zeros((st.n_points, k, 3))
    x = np.zeros((n * d, k))
    t_inv = np.zeros((k, k))
    border_step = np.zeros(k)
    border_min_pivot = np.inf
    if k:
        # Sb = Ub - Σ Y Vb ; Sbb = C - Σ Vbᵀ V⁻¹ Vb ; rb = b_b - Σ Vbᵀ V⁻¹ b_p
        vb = normals.point_border
        s_b = normals.unit_border - sum_into(pat.pair_unit, y @ vb[pat.pair_point], n)
        y_border = np.swapaxes(vb, 1, 2) @ v_inv  # (p, k, 3)
        s_bb = border - np.einsum("pki,pil->kl", y_border, vb)
        r_b = -normals.g_border - np.einsum("pki,pi->k", y_border, b_point)
        x = factor.solve(s_b[order].reshape(n * d, k))
        t = s_bb - s_b[order].reshape(n * d, k).T @ x
        t_inv, border_min_pivot = _border_inverse(st, t)
        u0 = factor.solve(rhs_pos)
        border_step = t_inv @ (r_b - s_b[order].reshape(n * d, k).T @ u0)
        x_pos = u0 - x @ border_step
    else:
        x_pos = factor.solve(rhs_pos)
    unit_step = np.empty((n, d))
    unit_step[order] = x_pos.reshape(n, d)
    # points: V⁻¹ (b_p - Σ Wᵀ δu - Vb δb)
    t_p = b_point - sum_into(
        pat.pair_point,
        np.einsum("pij,pi->pj", normals.w, unit_step[pat.pair_unit]),
        st.n_points,
    )
    if k:
        t_p -= normals.point_border @ border_step
    point_step = np.einsum("pij,pj->pi", v_inv, t_p)
    return Reduced(
        factor, unit_step, point_step, border_step, v_inv, y, y_border, x, t_inv,
        border_min_pivot, normals,
    )


def _border_inverse(st: NormalStructure, t: FloatArray) -> tuple[FloatArray, float]:

    diag = np.diag(t).copy()
    if np.any(~(diag > 0.0)):
        j = int(np.flatnonzero(~(diag > 0.0))[0])
        raise SingularNormalsError(
            f"border parameter {j} is not determined by the observations", "border", j
        )
    s = 1.0 / np.sqrt(diag)
    ts = t * s[:, None] * s[None, :]
    try:
        chol = np.linalg.cholesky(ts)
    except np.linalg.LinAlgError:
        ev, vec = np.linalg.eigh(ts)
        j = int(np.argmax(np.abs(vec[:, 0])))
        raise SingularNormalsError(
            f"border parameter {j} is not determined by the observations (it moves with "
            "the others or with the units)",
            "border",
            j,
        ) from None
    piv = float(np.min(np.diag(chol) ** 2))
    inv = np.linalg.inv(ts) * s[:, None] * s[None, :]
    return 0.5 * (inv + inv.T), piv


def predicted_cost(st: NormalStructure, red: Reduced) -> float:
    """``‖T (f + A δ)‖² = cost + 2 gᵀ δ + δᵀ N δ`` with the undamped N."""
    normals, du, dp, db = red.normals, red.unit_step, red.point_step, red.border_step
    pat = st.pattern
    order = pat.order
    n, d = du.shape
    band = normals.band  # U alone (before the Schur complement), position order
    x = du[order]  # (n, d) by position
    quad = 0.0
    w1 = band.shape[1]
    for o in range(w1):
        # blocks S[J + o, J]: x[J+o]ᵀ B x[J], counted twice off the diagonal
        if o >= n:
            break
        val = float(np.einsum("ja,jab,jb->", x[o:], band[: n - o, o], x[: n - o]))
        quad += val if o == 0 else 2.0 * val
    quad += float(np.einsum("pa,pab,pb->", dp, normals.v, dp))
    quad += 2.0 * float(np.einsum("pa,pab,pb->", du[pat.pair_unit], normals.w, dp[pat.pair_point]))
    if db.size:
        quad += float(db @ normals.border @ db)
        quad += 2.0 * float(np.einsum("na,nab,b->", du, normals.unit_border, db))
        quad += 2.0 * float(np.einsum("pa,pab,b->", dp, normals.point_border, db))
    lin = float(np.sum(normals.g_unit * du) + np.sum(normals.g_point * dp)
                + normals.g_border @ db)
    return normals.cost + 2.0 * lin + quad


def cofactors(st: NormalStructure, red: Reduced) -> Cofactors:
    """The selected inverse: the band of the units' block (with the border's
    share ``X T⁻¹ Xᵀ``), the border's blocks and per point
    ``Q_pp = V⁻¹ + Yᵀ Q_RR Y``, ``Q_Rp = -Q_RR Y`` over its units and the
    border R (``Y = N_Rp V⁻¹``), one chunk of points with the same number of
    units at a time."""

    pat = st.pattern
    n, d, k, p = st.n_units, st.unit_size, st.n_border, st.n_points
    z = selected_inverse(red.factor)  # (n, w+1, d, d), position order
    w1 = z.shape[1]
    q_ub = np.zeros((n, d, k))  # position order
    if k:
        xb = red.x.reshape(n, d, k)
        xt = xb @ red.t_inv
        for o in range(min(w1, n)):
            z[: n - o, o] += xt[o:] @ np.swapaxes(xb[: n - o], 1, 2)
        q_ub = -xt
    q_bb = red.t_inv
    v_inv, y, y_border = red.v_inv, red.y, red.y_border
    point = v_inv.copy()
    pair = np.zeros((pat.pair_unit.size, d, 3))
    point_border = np.zeros((p, 3, k))
    zflat = z.reshape(-1, d, d)
    for c in pat.chunks:
        q, n_g, groups = c.q, c.size, c.groups
        qd = q * d
        span = slice(c.pair_start, c.pair_start + groups * n_g * q)
        blocks = zflat[c.gather]  # (G, q, q, d, d): the same for all points of a group
        blocks = np.where(c.upper[None, :, :, None, None], np.swapaxes(blocks, -1, -2), blocks)
        q_rr = blocks.transpose(0, 1, 3, 2, 4).reshape(groups, qd, qd)
        y_r = _by_group(y[span], groups, n_g, q, d)  # (G, qd, 3 n_g)
        if k:
            units = pat.pair_unit[span].reshape(groups, n_g, q)[:, 0]  # (G, q)
            ub = q_ub[pat.position[units]].reshape(groups, qd, k)
            top = np.concatenate([q_rr, ub], axis=2)
            bottom = np.concatenate(
                [np.swapaxes(ub, 1, 2), np.broadcast_to(q_bb, (groups, k, k))], axis=2
            )
            q_rr = np.concatenate([top, bottom], axis=1)
            yb = y_border[c.points].reshape(groups, n_g, k, 3).transpose(0, 2, 1, 3)
            y_r = np.concatenate([y_r, yb.reshape(groups, k, n_g * 3)], axis=1)
        t = q_rr @ y_r  # (G, qd + k, 3 n_g)
        # Q_pp = V⁻¹ + Yᵀ Q_RR Y per point: the 3 x 3 diagonal blocks of y_rᵀ t
        yt = np.einsum("gmpi,gmpj->gpij", y_r.reshape(groups, -1, n_g, 3),
                       t.reshape(groups, -1, n_g, 3))
        point[c.points] += yt.reshape(-1, 3, 3)
        pair[span] = -_by_point(t[:, :qd], groups, n_g, q, d)
        if k:
            tb = t[:, qd:].reshape(groups, k, n_g, 3).transpose(0, 2, 3, 1)  # (G, n_g, 3, k)
            point_border[c.points] = -tb.reshape(-1, 3, k)
    if k:
        alone = np.bincount(pat.pair_point, minlength=p) == 0
        t = q_bb @ y_border[alone]  # (a, k, 3)
        point[alone] += np.swapaxes(y_border[alone], 1, 2) @ t
        point_border[alone] = -np.swapaxes(t, 1, 2)
    return Cofactors(
        structure=st,
        unit=z[pat.position, 0],
        point=point,
        border=q_bb,
        unit_border=q_ub[pat.position],
        point_border=point_border,
        band=z,
        pair=pair,
    )


def _joint(blocks: list[list[FloatArray]]) -> FloatArray:
    """A batch of block matrices (g, m, m) from a grid of (g, a, b) blocks."""
    return np.concatenate([np.concatenate(row, axis=2) for row in blocks], axis=1)


def _quadratic(a: FloatArray, c: FloatArray) -> FloatArray:
    """Diagonal of ``a C aᵀ`` per group: a (g, r, m), C (g, m, m) -> (g, r)."""
    out: FloatArray = np.einsum("gri,gij,grj->gr", a, c, a)
    return out


def leverage(cof: Cofactors, rows: Rows) -> FloatArray:
    """``diag(T A Q Aᵀ Tᵀ)`` (g, r) of rows of any kind."""

    st = cof.structure
    k = st.n_border
    if isinstance(rows, UnitPointRows):
        au, ap, _, ab = rows.whitened(k, st.unit_size)
        unit = np.asarray(rows.unit, np.intp)
        point = np.asarray(rows.point, np.intp)
        q_up = cof.unit_point(unit, point)

        def form(a: FloatArray, q: FloatArray, b: FloatArray) -> FloatArray:
            out: FloatArray = np.sum((a @ q) * b, axis=2)
            return out

        h = form(au, cof.unit[unit], au) + 2.0 * form(au, q_up, ap)
        h += form(ap, cof.point[point], ap)
        if k:
            h += 2.0 * form(au, cof.unit_border[unit], ab)
            h += 2.0 * form(ap, cof.point_border[point], ab)
            h += np.sum((ab @ cof.border) * ab, axis=2)
        return h
    if isinstance(rows, UnitRows):
        a, _, ab = rows.whitened(k, st.unit_size)
        units = np.asarray(rows.units, np.intp)
        g, q = units.shape
        d = st.unit_size
        ia, ib = np.meshgrid(np.arange(q), np.arange(q), indexing="ij")
        blocks = cof.unit_blocks(units[:, ia], units[:, ib])  # (g, q, q, d, d)
        q_uu = blocks.transpose(0, 1, 3, 2, 4).reshape(g, q * d, q * d)
        q_ub = cof.unit_border[units].reshape(g, q * d, k)
        q_bb = np.broadcast_to(cof.border, (g, k, k))
        c = _joint([[q_uu, q_ub], [np.swapaxes(q_ub, 1, 2), q_bb]])
        return _quadratic(np.concatenate([a.reshape(g, a.shape[1], q * d), ab], axis=2), c)
    if isinstance(rows, PointRows):
        a, _, ab = rows.whitened(k)
        point = np.asarray(rows.point, np.intp)
        q_pb = cof.point_border[point]
        q_bb = np.broadcast_to(cof.border, (point.size, k, k))
        c = _joint([[cof.point[point], q_pb], [np.swapaxes(q_pb, 1, 2), q_bb]])
        return _quadratic(np.concatenate([a, ab], axis=2), c)
    if isinstance(rows, BorderRows):
        a, _ = rows.whitened(k)
        return _quadratic(a, np.broadcast_to(cof.border, (a.shape[0], k, k)))
    raise TypeError(f"Expected rows of the four kinds, got {type(rows).__name__}")


@dataclass(frozen=True)
class Cofactors:
    """Blocks of ``Q = N⁻¹`` on the pattern (the selected inverse).

    ``unit`` (n, d, d), ``point`` (p, 3, 3), ``border`` (k, k),
    ``unit_border`` (n, d, k), ``point_border`` (p, 3, k); ``band`` (n, w+1,
    d, d) the band in the structure's order (``band[J, o] = Q[order[J + o],
    order[J]]``), ``pair`` (n_pairs, d, 3) the unit-point blocks of the
    pattern's pairs."""

    structure: NormalStructure  # the structure the blocks follow
    unit: FloatArray
    point: FloatArray
    border: FloatArray
    unit_border: FloatArray
    point_border: FloatArray
    band: FloatArray
    pair: FloatArray

    def unit_blocks(self, unit_a: ArrayLike, unit_b: ArrayLike) -> FloatArray:
        """Blocks ``Q[a, b]`` (m, d, d) of units within the band of each other."""
        a = np.asarray(unit_a, dtype=np.intp)
        b = np.asarray(unit_b, dtype=np.intp)
        d = self.structure.unit_size
        idx, upper = self.structure.pattern.block_index(a, b)
        blocks = self.band.reshape(-1, d, d)[idx]
        return np.where(upper[..., None, None], np.swapaxes(blocks, -1, -2), blocks)

    def unit_point(self, unit: ArrayLike, point: ArrayLike) -> FloatArray:
        """Blocks ``Q[unit, point]`` (m, d, 3) of coupled unit-point pairs."""
        pairs = self.structure.pattern.pair_of(
            np.asarray(unit, dtype=np.intp), np.asarray(point, dtype=np.intp)
        )
        return self.pair[pairs]

    def redundancy(self, rows: Rows) -> FloatArray:
        """Redundancy numbers ``1 - (T A Q Aᵀ Tᵀ)ᵢᵢ`` (g, r) of rows (with the
        weights of `rows`; for diagonal weights ``1 - (A Q Aᵀ P)ᵢᵢ``)."""
        h = leverage(self, rows)
        return 1.0 - h
