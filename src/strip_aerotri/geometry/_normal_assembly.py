"""The kernels of :mod:`strip_aerotri.geometry.normals`: forming the normal
blocks, the Schur complement on the points, the band's factor and solve with
the border eliminated after it, and the selected inverse with the redundancy
numbers.  Shapes: n units of d parameters, p points, k border parameters;
the band in the structure's order (position J holds unit ``order[J]``)."""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Concatenate, NamedTuple, ParamSpec, TypeVar

import numpy as np

from .._threads import compute_workers, split_map
from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ._blockband import BandFactor, NotPositiveDefinite, factor_band, selected_inverse
from ._normal_entries import (
    PairBlocks,
    PointFactor,
    entry_major,
    lower_t_times,
    lower_times,
    pair_blocks,
    point_factor,
    run_sums,
    shift_pair_blocks,
    spans,
    take,
    times_lower,
    times_lower_t,
)
from ._normal_pattern import Chunk
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
_P = ParamSpec("_P")
_R = TypeVar("_R")


def _in_workers(
    kernel: Callable[Concatenate[NormalStructure, _P], _R],
) -> Callable[Concatenate[NormalStructure, _P], _R]:
    """Run a kernel of structure `st` inside ``_threads.compute_workers``: the
    bundle has it open already (its threads are used); elsewhere (the ground
    stage, the block) the kernel opens its own for the call, by the same
    rule, sized by the structure's unit-point rows."""

    @functools.wraps(kernel)
    def wrapped(st: NormalStructure, /, *args: _P.args, **kwargs: _P.kwargs) -> _R:
        with compute_workers(st.pattern.row_unit.size):
            return kernel(st, *args, **kwargs)

    return wrapped


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


@_in_workers
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
    unit_border = np.zeros((n, d, k))
    point_border = np.zeros((p, 3, k))
    border = np.zeros((k, k))
    g_border = np.zeros(k)
    cost = 0.0
    diag_block = pat.position * w1  # band block of each unit's diagonal
    whitened = [rows.whitened(k, d) for rows in unit_point_rows]
    fast = _pair_blocks(st, unit_point_rows, whitened)
    w_entries: FloatArray | None = None
    if fast is not None:
        band.reshape(n * w1, d, d)[diag_block] += fast.u  # one block per unit
        w_entries, v, g_unit, g_point = fast.w, fast.v, fast.g_unit, fast.g_point
        unit_border, point_border, border, g_border = (
            fast.unit_border, fast.point_border, fast.border, fast.g_border
        )
        cost = fast.cost
    # the general rows' W, pair-major (the entry-major path has its own)
    w = np.zeros((0 if fast is not None else n_pairs, d, 3))
    general = zip(unit_point_rows, whitened) if fast is None else ()
    offset = 0
    for rows, (au, ap, f, ab) in general:
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
        band.reshape(n, w1, d, d), g_unit, v, g_point,
        entry_major(w) if w_entries is None else w_entries,
        unit_border, point_border, border, g_border, cost,
    )


def _joined(arrays: list[_A]) -> _A:
    """One array of the groups' rows (no copy for one group)."""
    return arrays[0] if len(arrays) == 1 else np.concatenate(arrays)


def _pair_blocks(
    st: NormalStructure,
    unit_point_rows: Sequence[UnitPointRows],
    whitened: list[tuple[FloatArray, FloatArray, FloatArray, FloatArray]],
) -> PairBlocks | None:
    """The unit-point rows' blocks by the entry-major kernels when they are the
    structure's own rows with one row group per (unit, point) pair and the
    same r (the common case); None otherwise."""
    pat = st.pattern
    if pat.pair_row is None or not whitened or len({a[0].shape[1] for a in whitened}) != 1:
        return None
    unit = _joined([np.asarray(r.unit, np.intp) for r in unit_point_rows])
    point = _joined([np.asarray(r.point, np.intp) for r in unit_point_rows])
    if not (np.array_equal(unit, pat.row_unit) and np.array_equal(point, pat.row_point)):
        return None
    au, ap, f, ab = (_joined([a[i] for a in whitened]) for i in range(4))
    d = st.unit_size
    if st.n_border == 0 and d >= 3 and all(r.unit_shift for r in unit_point_rows):
        _check_unit_shift(au, ap)
        rows = None if pat.rows_in_pair_order else pat.pair_row
        return shift_pair_blocks(pat, rows, st.n_units, d, st.n_points, au, ap, f)
    return pair_blocks(pat, pat.pair_row, st.n_units, d, st.n_points, st.n_border,
                       au, ap, f, ab)


def _group_major(x: FloatArray, c: Chunk, d: int, start: int | None = None) -> FloatArray:
    """A chunk's pairs of entry-major X (d, e, g) as (G, q d, n_g e): per group
    of points, the points' blocks side by side, a row per unit parameter;
    the chunk's pairs from `start` in X (default: the chunk's own place)."""
    e = x.shape[1]
    lo = c.pair_start if start is None else start
    span = x[:, :, lo : lo + c.groups * c.size * c.q]
    out: FloatArray = (
        span.reshape(d, e, c.groups, c.size, c.q).transpose(2, 4, 0, 3, 1)
        .reshape(c.groups, c.q * d, c.size * e)
    )
    return out


def _pair_major(blocks: FloatArray, c: Chunk, d: int) -> FloatArray:
    """The inverse of :func:`_group_major`: (G, q d, n_g e) -> (d, e, G n_g q)."""
    e = blocks.shape[-1] // c.size
    out: FloatArray = (
        blocks.reshape(c.groups, c.q, d, c.size, e).transpose(2, 4, 0, 3, 1).reshape(d, e, -1)
    )
    return out


@dataclass
class Reduced:
    """The reduced system's factor and what the step and the cofactors need."""

    factor: BandFactor
    unit_step: FloatArray
    point_step: FloatArray
    border_step: FloatArray
    v_inv: FloatArray  # (p, 3, 3), undamped when damping == 0
    z: FloatArray  # (d, 3, n_pairs) W Mᵀ, entry-major (M = L⁻¹, V = L Lᵀ)
    m_point: FloatArray  # (6, p) M of each point
    m_pair: FloatArray  # (6, n_pairs) M of each pair's point
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


def undetermined_points(v: FloatArray, tol: float) -> tuple[IntArray, PointFactor]:
    """Points whose 3 x 3 block has ``λmin <= tol λmax``, and the blocks'
    Cholesky factors.  ``λmin / λmax >= 1 / (trace V⁻¹ trace V)``:
    eigenvalues are computed only for the blocks below that bound (and those
    whose factor failed)."""
    pf = point_factor(v)
    near = np.flatnonzero(~(pf.bound > tol))
    if near.size == 0:
        return near, pf
    ev = np.linalg.eigvalsh(v[near])
    return near[~(ev[:, 0] > tol * ev[:, 2])], pf


def _point_factor(st: NormalStructure, v: FloatArray) -> PointFactor:
    """V = L Lᵀ of every point; SingularNormalsError naming the first undetermined one."""

    bad, pf = undetermined_points(v, POINT_RANK_TOL)
    if bad.size or not np.all(np.isfinite(pf.m)):
        i = int(bad[0]) if bad.size else int(np.flatnonzero(~np.isfinite(pf.m).all(axis=0))[0])
        raise SingularNormalsError(
            f"{max(bad.size, 1)} point(s) not determined, the first {st.point_name(i)}: "
            "its 3 x 3 normal block is singular (a point needs rays from two units, or "
            "control that fixes it)",
            "point",
            i,
        )
    return pf


def _schur_band(st: NormalStructure, band: FloatArray, z: FloatArray) -> FloatArray:
    """``U - Σ_points Z Zᵀ`` in the band (n, w+1, d, d), Z = W L⁻ᵀ per pair:
    per group of points with the same units one product (q d, 3 n_g) x
    (3 n_g, q d), its lower blocks summed into the band by their targets."""
    pat = st.pattern
    n, d = st.n_units, st.unit_size
    w1 = pat.width + 1
    dd = d * d
    flat_blocks = band.reshape(n * w1, dd).copy()

    def products(c: Chunk) -> tuple[IntArray, FloatArray]:
        zc = _group_major(z, c, d)
        sums = zc @ np.swapaxes(zc, 1, 2)  # (G, qd, qd)
        blocks = sums.reshape(-1, c.q, d, c.q, d).transpose(0, 1, 3, 2, 4)[:, c.lower_a, c.lower_b]
        if c.scatter_unique is None or c.scatter_inverse is None:  # every target once
            return c.scatter.reshape(-1), blocks.reshape(-1, dd)
        # summed over the chunk's blocks with the same target first
        return c.scatter_unique, sum_into(
            c.scatter_inverse, blocks.reshape(-1, dd), c.scatter_unique.size
        )

    def subtract(target_blocks: tuple[IntArray, FloatArray]) -> None:
        target, blocks = target_blocks
        flat_blocks[target] -= blocks

    # the chunks' products on the threads of _threads.compute_workers, their
    # sums into the band in the chunks' order (as in one thread)
    split_map(products, pat.chunks, subtract)
    return flat_blocks.reshape(n, w1, d, d)


@_in_workers
def reduce_points(st: NormalStructure, normals: _Normals, damping: float,
                  step: bool = True) -> Reduced:
    """Schur complement on the points, the banded factor, the border after
    the band, the step (units, points, border) and its predicted cost;
    without `step` what the cofactors need alone (the steps NaN).

    Length: the four stages of method.md 6B 1-2 for one step, which share
    their intermediate products."""

    pat = st.pattern
    n, d, k = st.n_units, st.unit_size, st.n_border
    band, v, border = _damped(normals, damping)
    pf = (
        _point_factor(st, v) if v.shape[0]
        else PointFactor(np.zeros((6, 0)), v.copy(), v[:, 0, 0])
    )
    b_point = -normals.g_point
    mb = lower_times(pf.m, b_point.T)  # (3, p): M b_p
    n_pairs = pat.pair_point.size
    m_pair = np.empty((6, n_pairs))
    z = np.empty((d, 3, n_pairs))  # W Mᵀ
    zmb = np.empty((d, n_pairs))  # Z (M b_p)

    def pairs_block(at: slice) -> None:
        m_pair[:, at] = take(pf.m, pat.pair_point[at])
        z[..., at] = times_lower_t(normals.w[..., at], m_pair[:, at])
        if step:
            np.einsum("ack,ck->ak", z[..., at], take(mb, pat.pair_point[at]), out=zmb[:, at])

    split_map(pairs_block, spans(n_pairs))
    s_band = _schur_band(st, band, z)
    # Σ_pairs W V⁻¹ b_p = Σ Z (M b_p), by unit
    rhs_unit = -normals.g_unit - run_sums(zmb, pat.pair_unit_runs, n) if step else None
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
    y_border = np.zeros((st.n_points, k, 3))
    x = np.zeros((n * d, k))
    t_inv = np.zeros((k, k))
    border_min_pivot = np.inf
    if k:
        # Sb = Ub - Σ W V⁻¹ Vb ; Sbb = C - Σ Vbᵀ V⁻¹ Vb ; rb = b_b - Σ Vbᵀ V⁻¹ b_p,
        # with V⁻¹ = Mᵀ M
        vb = normals.point_border
        mvb = lower_times(pf.m, np.moveaxis(vb, 0, -1))  # (3, k, p)
        s_b = normals.unit_border - run_sums(
            np.einsum("ack,cbk->abk", z, take(mvb, pat.pair_point)), pat.pair_unit_runs, n
        )
        y_border = np.moveaxis(lower_t_times(pf.m, mvb), -1, 0).transpose(0, 2, 1)  # (p, k, 3)
        s_bb = border - np.einsum("cap,cbp->ab", mvb, mvb)
        r_b = -normals.g_border - np.einsum("cap,cp->a", mvb, mb)
        s_b_pos = s_b[order].reshape(n * d, k)
        x = factor.solve(s_b_pos)
        t = s_bb - s_b_pos.T @ x
        t_inv, border_min_pivot = _border_inverse(st, t)
    if rhs_unit is None:  # the cofactors' share alone
        nan = np.full((n, d), np.nan), np.full((st.n_points, 3), np.nan), np.full(k, np.nan)
        return Reduced(factor, *nan, pf.v_inv, z, pf.m, m_pair, y_border, x, t_inv,
                       border_min_pivot, normals)
    with_border = _BorderTerms(x, t_inv, r_b, s_b_pos, normals.point_border) if k else None
    unit_step, point_step, border_step = _steps(
        st, factor, normals.w, pf.m, rhs_unit, b_point, with_border
    )
    return Reduced(
        factor, unit_step, point_step, border_step, pf.v_inv, z, pf.m, m_pair, y_border, x,
        t_inv, border_min_pivot, normals,
    )


class _BorderTerms(NamedTuple):
    """What the border's step needs after the band: ``x = S⁻¹ Sb`` (n d, k,
    position order), ``T⁻¹`` (k, k), its right-hand side ``r_b`` (k,), ``Sb``
    (n d, k, position order) and the points' border blocks ``Vb`` (p, 3, k)."""

    x: FloatArray
    t_inv: FloatArray
    r_b: FloatArray
    s_b_pos: FloatArray
    point_border: FloatArray


def _steps(
    st: NormalStructure,
    factor: BandFactor,
    w: FloatArray,
    m: FloatArray,
    rhs_unit: FloatArray,
    b_point: FloatArray,
    border: _BorderTerms | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The steps of units (n, d), points (p, 3) and border (k,) from the
    reduced right-hand side ``rhs_unit`` (n, d) and the points' ``b_point``
    (p, 3): the band solved with `factor` (the border after it), then the
    points back-substituted, ``V⁻¹ (b_p - Σ Wᵀ δu - Vb δb)`` with
    ``V⁻¹ = Mᵀ M`` (`m` (6, p); `w` the pairs' W, entry-major)."""
    pat = st.pattern
    n, d = st.n_units, st.unit_size
    order = pat.order
    rhs_pos = rhs_unit[order].reshape(-1)
    border_step = np.zeros(0 if border is None else border.t_inv.shape[0])
    if border is not None:
        u0 = factor.solve(rhs_pos)
        border_step = border.t_inv @ (border.r_b - border.s_b_pos.T @ u0)
        x_pos = u0 - border.x @ border_step
    else:
        x_pos = factor.solve(rhs_pos)
    unit_step = np.empty((n, d))
    unit_step[order] = x_pos.reshape(n, d)
    wu = np.empty((3, pat.pair_unit.size))  # Wᵀ δu per pair

    def back_block(at: slice) -> None:
        np.einsum("abk,ak->bk", w[..., at], take(unit_step.T, pat.pair_unit[at]), out=wu[:, at])

    split_map(back_block, spans(pat.pair_unit.size))
    t_p = b_point - run_sums(wu, pat.point_runs, st.n_points)
    if border is not None:
        t_p -= border.point_border @ border_step
    point_step = np.ascontiguousarray(lower_t_times(m, lower_times(m, t_p.T)).T)
    return unit_step, point_step, border_step


def chord_step(
    st: NormalStructure, red: Reduced, g_unit: FloatArray, g_point: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The step (units (n, d), points (p, 3)) of other gradients ``g_unit``,
    ``g_point`` with the normal matrix of `red` (its banded factor, its
    points' ``V⁻¹`` and the pairs' ``W``): the elimination of
    :func:`reduce_points` for a new right-hand side, without forming or
    factoring again (a chord, or simplified Gauss-Newton, step).  Without a
    border only."""

    if st.n_border:
        raise ValueError("Expected a structure without a border for a chord step")
    pat = st.pattern
    b_point = -g_point
    mb = lower_times(red.m_pair, take(b_point.T, pat.pair_point))  # M b_p of each pair
    zmb = np.einsum("ack,ck->ak", red.z, mb)  # W V⁻¹ b_p of each pair
    rhs_unit = -g_unit - run_sums(zmb, pat.pair_unit_runs, st.n_units)
    unit_step, point_step, _ = _steps(
        st, red.factor, red.normals.w, red.m_point, rhs_unit, b_point
    )
    return unit_step, point_step


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
    quad += 2.0 * float(
        np.einsum("ak,abk,bk->", du[pat.pair_unit].T, normals.w, dp[pat.pair_point].T)
    )
    if db.size:
        quad += float(db @ normals.border @ db)
        quad += 2.0 * float(np.einsum("na,nab,b->", du, normals.unit_border, db))
        quad += 2.0 * float(np.einsum("pa,pab,b->", dp, normals.point_border, db))
    lin = float(np.sum(normals.g_unit * du) + np.sum(normals.g_point * dp)
                + normals.g_border @ db)
    return normals.cost + 2.0 * lin + quad


def _check_unit_shift(a_unit: FloatArray, a_point: FloatArray) -> None:
    """The contract of rows with ``unit_shift``: the first three columns of
    their (whitened) unit Jacobian (g, r, d) are minus their point Jacobian
    (g, r, 3), to the bit.  Compared as laid out (the entry-major copies of
    both cost five times as much on rows laid out row by row)."""
    if not np.array_equal(a_unit[..., :3], -a_point):
        raise ValueError(
            "Expected unit_jacobian[..., :3] == -point_jacobian of rows with unit_shift"
        )


@_in_workers
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
    y_border = red.y_border
    pair = np.zeros((d, 3, pat.pair_unit.size))
    point = red.v_inv.copy()
    point_border = np.zeros((p, 3, k))
    both = _both_sides(z)

    def chunk(c: Chunk) -> None:  # writes the chunk's own pairs and points
        q, n_g, groups = c.q, c.size, c.groups
        qd = q * d
        span = slice(c.pair_start, c.pair_start + groups * n_g * q)
        q_rr = _group_q(both, c.gather, c.upper)  # the same for all the group's points
        y = times_lower(red.z[..., span], red.m_pair[..., span])  # W V⁻¹ = Z M of the chunk
        y_r = _group_major(y, c, d, 0)  # (G, qd, 3 n_g)
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
        t = q_rr @ y_r  # (G, qd + k, 3 n_g): -Q_Rp
        pair[:, :, span] = -_pair_major(t[:, :qd], c, d)
        # Q_pp = V⁻¹ + Yᵀ Q_RR Y = V⁻¹ - Σ_pairs Yᵀ Q_up (the border's share below)
        yq = np.einsum("aik,ajk->ijk", y, pair[:, :, span])  # (3, 3, pairs of the chunk)
        point[c.points] -= np.moveaxis(yq.reshape(3, 3, -1, q).sum(axis=-1), -1, 0)
        if k:
            tb = t[:, qd:].reshape(groups, k, n_g, 3).transpose(0, 2, 3, 1)  # (G, n_g, 3, k)
            point_border[c.points] = -tb.reshape(-1, 3, k)

    split_map(chunk, pat.chunks)
    if k:  # and - Y_bᵀ Q_pbᵀ
        alone = np.bincount(pat.pair_point, minlength=p) == 0
        point_border[alone] = -np.swapaxes(q_bb @ y_border[alone], 1, 2)
        point -= np.einsum("pki,pjk->pij", y_border, point_border)
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


def point_cofactors(
    st: NormalStructure, red: Reduced, band_inverse: FloatArray, points: IntArray
) -> FloatArray:
    """``Q_pp`` (m, 3, 3) of the points `points` (m,) alone, without a border:
    ``V⁻¹ + Σ_ab Y_aᵀ Q_ab Y_b`` over the point's units a, b (``Y = W V⁻¹`` of
    its pairs, ``Q_ab`` from `band_inverse`, the selected inverse of the
    band), as :func:`cofactors` forms them for every point; the points
    grouped by their number of units q."""
    if st.n_border:
        raise ValueError("Expected a structure without a border for the points' cofactors")
    pat = st.pattern
    d = st.unit_size
    points = np.asarray(points, np.intp).reshape(-1)
    out: FloatArray = red.v_inv[points].copy()
    order, starts, values = pat.point_runs
    assert order is None  # a point's pairs are contiguous (build_pattern)
    run = np.full(st.n_points, -1, dtype=np.intp)
    run[values] = np.arange(values.size)
    count = np.diff(np.r_[starts, pat.pair_point.size])
    r = run[points]
    q_of = np.where(r >= 0, count[r], 0)
    for q in np.unique(q_of[q_of > 0]).tolist():
        sel = np.flatnonzero(q_of == q)
        pairs = (starts[r[sel]][:, None] + np.arange(q)).reshape(-1)  # (m q,)
        y = times_lower(take(red.z, pairs), take(red.m_pair, pairs))  # W V⁻¹, (d, 3, m q)
        y = np.moveaxis(y, -1, 0).reshape(sel.size, q * d, 3)  # the point's Y_a stacked
        units = pat.pair_unit[pairs].reshape(sel.size, q)
        idx, upper = pat.block_index(units[:, :, None], units[:, None, :])  # (m, q, q)
        q_rr = _group_q_one_sided(band_inverse, idx, upper)
        out[sel] += np.swapaxes(y, 1, 2) @ (q_rr @ y)
    return out


def _both_sides(band: FloatArray) -> FloatArray:
    """The band of a symmetric block matrix, ``band[J, o] = Q[J + o, J]`` (n,
    w+1, d, d), on both sides of the diagonal: (n, 2w+1, d, d) with
    ``Q[J, J + o]`` at ``[J, w + o]`` for ``|o| <= w`` (zero past the ends),
    so that any block within the band is read as it stands."""
    n, w1, d, _ = band.shape
    w = w1 - 1
    out = np.zeros((n, 2 * w + 1, d, d))
    for o in range(min(w1, n)):
        out[: n - o, w + o] = np.swapaxes(band[: n - o, o], 1, 2)  # Q[J, J + o]
        out[o:, w - o] = band[: n - o, o]  # Q[J + o, J]
    return out


def _group_q(both: FloatArray, gather: IntArray, upper: BoolArray) -> FloatArray:
    """``Q[a, b]`` of each group's units (G, q d, q d) from the band laid out
    on both sides (:func:`_both_sides`, (n, 2w+1, d, d)): the pairs (a, b)
    given by their band block ``gather`` (G, q, q), ``lo (w+1) + off``
    (:meth:`~strip_aerotri.geometry._normal_pattern.Pattern.block_index`),
    and ``upper`` where a < b (broadcast to ``gather``); the band's block
    (lo + off, lo) is read at (lo + off, w - off) of ``both``, its transpose
    at (lo, w + off) where a < b: no transposing of gathered blocks."""
    w2, d = both.shape[1], both.shape[2]
    w = w2 // 2
    lo, off = np.divmod(gather, w + 1)
    at = np.where(upper, lo * w2 + w + off, (lo + off) * w2 + w - off)
    g, q = gather.shape[0], gather.shape[1]
    blocks = both.reshape(-1, d, d)[at]  # (G, q, q, d, d)
    out: FloatArray = blocks.transpose(0, 1, 3, 2, 4).reshape(g, q * d, q * d)
    return out


def _group_q_one_sided(band: FloatArray, gather: IntArray, upper: BoolArray) -> FloatArray:
    """:func:`_group_q` from the band as the selected inverse gives it, (n,
    w+1, d, d), each block read where it stands and transposed where a < b:
    for a few points, where :func:`_both_sides`' copy, twice the band, would
    raise the peak memory (by 0.2 GB on a 20 x 500-photo block)."""
    d = band.shape[2]
    g, q = gather.shape[0], gather.shape[1]
    blocks = band.reshape(-1, d, d)[gather]  # (G, q, q, d, d): band[lo, off] = Q[lo + off, lo]
    blocks = np.where(upper[..., None, None], np.swapaxes(blocks, -1, -2), blocks)
    out: FloatArray = blocks.transpose(0, 1, 3, 2, 4).reshape(g, q * d, q * d)
    return out


def _joint(blocks: list[list[FloatArray]]) -> FloatArray:
    """A batch of block matrices (g, m, m) from a grid of (g, a, b) blocks."""
    return np.concatenate([np.concatenate(row, axis=2) for row in blocks], axis=1)


def _quadratic(a: FloatArray, c: FloatArray) -> FloatArray:
    """Diagonal of ``a C aᵀ`` per group: a (g, r, m), C (g, m, m) -> (g, r)."""
    out: FloatArray = np.einsum("gri,gij,grj->gr", a, c, a)
    return out


def _pair_leverage(cof: Cofactors, rows: UnitPointRows) -> FloatArray:
    """``diag(T A Q Aᵀ Tᵀ)`` (g, r) of unit-point rows, entry-major: per row
    ``a_u Q_uu a_uᵀ + 2 a_u Q_up a_pᵀ + a_p Q_pp a_pᵀ`` (and the border's terms),
    each block gathered per row as (…, g)."""
    st = cof.structure
    pat = st.pattern
    k = st.n_border
    au, ap, _, ab = rows.whitened(k, st.unit_size)
    unit = np.asarray(rows.unit, np.intp)
    point = np.asarray(rows.point, np.intp)
    same = np.array_equal(unit, pat.row_unit) and np.array_equal(point, pat.row_point)
    pairs = pat.row_pair if same else pat.pair_of(unit, point)
    a_u, a_p = entry_major(au), entry_major(ap)
    a_b = entry_major(ab) if k else None
    q_unit, q_point = entry_major(cof.unit), entry_major(cof.point)
    q_ub, q_pb = entry_major(cof.unit_border), entry_major(cof.point_border)

    def form(a: FloatArray, q: FloatArray, b: FloatArray) -> FloatArray:
        # Σ_ij a[r, i] q[i, j] b[r, j] per row: (r, m)
        out: FloatArray = np.einsum("rik,rik->rk", a, np.einsum("ijk,rjk->rik", q, b))
        return out

    h = np.empty((a_u.shape[0], a_u.shape[2]))  # (r, g)
    in_order = same and pat.rows_in_pair_order  # row i is pair i

    def q_pair(at: slice) -> FloatArray:
        return cof.pair[..., at] if in_order else take(cof.pair, pairs[at])

    def shift_block(at: slice) -> None:
        # a_u = [-a_p, a_r]: a_p (Q11 + Q_pp - Q_up1 - Q_up1ᵀ) a_pᵀ
        # + 2 a_r (Q_up2 - Q21) a_pᵀ + a_r Q22 a_rᵀ, with Q11 Q21 Q22 the
        # unit's block split after its first three parameters, Q_up1 Q_up2 the
        # unit-point block's rows so split
        x, y = a_p[..., at], a_u[:, 3:, at]
        q_uu, q_up = take(q_unit, unit[at]), q_pair(at)
        c = take(q_point, point[at]) + q_uu[:3, :3]
        c -= q_up[:3]
        c -= q_up[:3].transpose(1, 0, 2)
        h[:, at] = form(x, c, x) + 2.0 * form(y, q_up[3:] - q_uu[3:, :3], x)
        h[:, at] += form(y, q_uu[3:, 3:], y)

    if rows.unit_shift and k == 0 and st.unit_size >= 3:
        _check_unit_shift(au, ap)
        split_map(shift_block, spans(h.shape[1]))
        return h.T

    def rows_block(at: slice) -> None:  # blocks of rows: the gathered blocks stay small
        u, pt = unit[at], point[at]
        bu, bp = a_u[..., at], a_p[..., at]
        part = form(bu, take(q_unit, u), bu) + 2.0 * form(bu, q_pair(at), bp)
        part += form(bp, take(q_point, pt), bp)
        if a_b is not None:
            bb = a_b[..., at]
            part += 2.0 * form(bu, take(q_ub, u), bb) + 2.0 * form(bp, take(q_pb, pt), bb)
            part += np.einsum("rik,ij,rjk->rk", bb, cof.border, bb)
        h[:, at] = part

    split_map(rows_block, spans(h.shape[1]))
    return h.T


def leverage(cof: Cofactors, rows: Rows) -> FloatArray:
    """``diag(T A Q Aᵀ Tᵀ)`` (g, r) of rows of any kind."""

    st = cof.structure
    k = st.n_border
    if isinstance(rows, UnitPointRows):
        with compute_workers(st.pattern.row_unit.size):
            return _pair_leverage(cof, rows)
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
    order[J]]``), ``pair`` (d, 3, n_pairs) the unit-point blocks of the
    pattern's pairs, entry-major."""

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
        out: FloatArray = np.moveaxis(self.pair[..., pairs], -1, 0)
        return out

    def redundancy(self, rows: Rows) -> FloatArray:
        """Redundancy numbers ``1 - (T A Q Aᵀ Tᵀ)ᵢᵢ`` (g, r) of rows (with the
        weights of `rows`; for diagonal weights ``1 - (A Q Aᵀ P)ᵢᵢ``)."""
        h = leverage(self, rows)
        return 1.0 - h
