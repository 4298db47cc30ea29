"""Entry-major kernels of the structured normal equations (method.md 6B).

The small blocks of the problem (a pair's r x d Jacobian, its d x 3 coupling
W, a point's 3 x 3 V) are held one array per entry, the pairs or points last
and contiguous: shape ``(*block, m)``.  A product of blocks is then an
``einsum`` over long vectors and a sum per unit or point an
``np.add.reduceat`` over its run, where the same products as batches of
(m, r, d) matrices spend most of their time per tiny matrix (a 2 x 6 times
2 x 3 product per image ray).

Used by :mod:`strip_aerotri.geometry._normal_assembly` for the common case:
unit-point rows that are the structure's own rows, one group of r rows per
(unit, point) pair.  Shapes: g pairs (in the pattern's order: by point, and
within a point by the unit's place along the band), p points, n units of d
parameters, k border parameters.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from .._threads import split_map
from .._typing import FloatArray, IntArray
from ._normal_pattern import Pattern

__all__ = [
    "PairBlocks",
    "PointFactor",
    "entry_major",
    "pair_blocks",
    "point_factor",
    "run_sums",
    "shift_pair_blocks",
    "spans",
    "take",
]


def entry_major(a: FloatArray) -> FloatArray:
    """``(m, *block) -> (*block, m)``, C-contiguous (no copy when the memory of
    `a` is already laid out so, as
    :func:`~strip_aerotri.geometry.collinearity.collinearity_jacobians` lays
    out its Jacobians)."""
    t = np.moveaxis(a, 0, -1)
    return t if t.flags.c_contiguous else np.ascontiguousarray(t)


def take(values: FloatArray, index: IntArray) -> FloatArray:
    """``values[..., index]`` of entry-major values, entry-major (C order;
    numpy's own ``values[..., index]`` puts the indexed axis first in memory)."""
    out: FloatArray = np.take(values, index, axis=-1)
    return out


def run_sums(values: FloatArray, runs: tuple[IntArray | None, IntArray, IntArray],
             n: int) -> FloatArray:
    """Sums of entry-major `values` (*block, m) over the runs of an index:
    ``runs`` = (the order that makes the index's equal values contiguous, or
    None when it already is; the start of each run in that order; the value of
    each run).  Returns (n, *block), zero where the index has no entry."""
    out = np.zeros((n, *values.shape[:-1]))

    def block(span: slice, places: slice | IntArray, first: IntArray, which: IntArray) -> None:
        # a block of whole runs (blocks_of): each run summed as in one call
        part = values[..., span] if isinstance(places, slice) else take(values, places)
        out[which] = np.moveaxis(np.add.reduceat(part, first, axis=-1), -1, 0)

    split_map(_star(block), blocks_of(runs, values.shape[-1]))
    return out


def _star(function: Callable[..., None]) -> Callable[[tuple[object, ...]], None]:
    """``function(*args)`` of one tuple ``args`` (for :func:`split_map`)."""
    return lambda args: function(*args)


class PairBlocks(NamedTuple):
    """The normal blocks of the pairs' rows: ``u`` (n, d, d) per unit, ``w``
    (d, 3, g) per pair (entry-major), ``v`` (p, 3, 3) per point, the
    gradients ``g_unit`` (n, d) and ``g_point`` (p, 3), the border's blocks
    ``unit_border`` (n, d, k), ``point_border`` (p, 3, k), ``border`` (k, k),
    ``g_border`` (k,), and the cost ``Σ‖T f‖²``."""

    u: FloatArray
    w: FloatArray
    v: FloatArray
    g_unit: FloatArray
    g_point: FloatArray
    unit_border: FloatArray
    point_border: FloatArray
    border: FloatArray
    g_border: FloatArray
    cost: float


#: Places (rows or pairs) per block of the blocked products: a block's
#: products stay in the processor's cache until they are summed, where the
#: products of all rows at once (30 MB for the 6 x 6 blocks of 100 000 rows)
#: would go through memory.
BLOCK = 16384


def spans(size: int) -> list[slice]:
    """Consecutive slices of :data:`BLOCK` places covering ``range(size)``."""
    return [slice(lo, lo + BLOCK) for lo in range(0, size, BLOCK)]


def blocks_of(runs: tuple[IntArray | None, IntArray, IntArray],
              size: int) -> list[tuple[slice, slice | IntArray, IntArray, IntArray]]:
    """Blocks of about :data:`BLOCK` places of an index of `size` places, cut
    between its runs (``runs`` as :func:`run_sums` takes them).  Per block:
    its span in the runs' order, the index's places there (the span itself
    when the runs need no order), the starts of its runs within the block
    and their values."""
    order, starts, seen = runs
    if starts.size == 0:
        return []
    first = np.unique(np.searchsorted(starts, np.arange(0, size, BLOCK), side="right") - 1)
    ends = np.r_[first[1:], starts.size]
    out: list[tuple[slice, slice | IntArray, IntArray, IntArray]] = []
    for i0, i1 in zip(first.tolist(), ends.tolist(), strict=True):
        lo = int(starts[i0])
        hi = int(starts[i1]) if i1 < starts.size else size
        span = slice(lo, hi)
        out.append((span, span if order is None else order[span], starts[i0:i1] - lo,
                    seen[i0:i1]))
    return out


def pair_blocks(
    pat: Pattern, rows: IntArray, n: int, d: int, p: int, k: int,
    au: FloatArray, ap: FloatArray, f: FloatArray, ab: FloatArray,
) -> PairBlocks:
    """The normal blocks of whitened rows given in the structure's row order:
    ``au`` (G, r, d), ``ap`` (G, r, 3), ``f`` (G, r), ``ab`` (G, r, k), in
    any memory layout; ``rows`` (G,) the row of each pair (``pat.pair_row``).

    The rows' entries are put side by side, one record a row, and read back
    block by block (:func:`blocks_of`), each block entry-major while in cache:
    per unit the rows in their own order, per pair and per point the rows in
    the pairs' order (gathering records moves whole rows, six times faster
    than gathering each entry's array).  Besides the blocks, one copy of the
    rows is held at a time."""
    g, r = f.shape
    parts = [au, ap, f[:, :, None]] + ([ab] if k else [])
    bounds = list(itertools.pairwise(np.cumsum([0] + [r * x.shape[2] for x in parts]).tolist()))
    records = np.empty((g, bounds[-1][1]))

    def fill(span: slice) -> None:
        for x, (lo, _) in zip(parts, bounds, strict=True):
            m = x.shape[2]
            for i in range(r):
                records[span, lo + i * m : lo + (i + 1) * m] = x[span, i]

    split_map(fill, spans(g))

    def entries(block: FloatArray) -> list[FloatArray]:
        # a block of records (b, width) -> entry-major pieces (r, m, b)
        em = np.ascontiguousarray(block.T)
        return [em[lo:hi].reshape(r, -1, em.shape[1]) for lo, hi in bounds]

    u, g_unit = np.zeros((n, d, d)), np.zeros((n, d))
    unit_border, point_border = np.zeros((n, d, k)), np.zeros((p, 3, k))
    w = np.empty((d, 3, rows.size))
    v, g_point = np.zeros((p, 3, 3)), np.zeros((p, 3))

    def unit_block(places: slice | IntArray, starts: IntArray, seen: IntArray) -> None:
        bu, _, bf, *bb = entries(records[places])
        u[seen] = _gram_summed(bu, starts)
        g_unit[seen] = _summed(np.einsum("rak,rk->ak", bu, bf[:, 0]), starts)
        if bb:
            unit_border[seen] = _summed(np.einsum("rak,rbk->abk", bu, bb[0]), starts)

    def point_block(span: slice, places: slice | IntArray, starts: IntArray,
                    seen: IntArray) -> None:
        pu, pp, pf, *pb = entries(np.take(records, rows[places], axis=0))
        np.einsum("rak,rbk->abk", pu, pp, out=w[..., span])
        v[seen] = _gram_summed(pp, starts)
        g_point[seen] = _summed(np.einsum("rak,rk->ak", pp, pf[:, 0]), starts)
        if pb:
            point_border[seen] = _summed(np.einsum("rak,rbk->abk", pp, pb[0]), starts)

    # each block writes its own units' and points' blocks: the blocks run on
    # the threads of _threads.compute_workers, the results as in one thread
    tasks: list[Callable[[], None]] = []
    tasks += [functools.partial(point_block, *b) for b in blocks_of(pat.point_runs, rows.size)]
    tasks += [functools.partial(unit_block, *b[1:]) for b in blocks_of(pat.row_unit_runs, g)]
    split_map(_call, tasks)
    cost = float(np.einsum("gr,gr->", f, f))
    if not k:
        return PairBlocks(u, w, v, g_unit, g_point, unit_border, point_border,
                          np.zeros((0, 0)), np.zeros(0), cost)
    return PairBlocks(
        u, w, v, g_unit, g_point, unit_border, point_border,
        np.einsum("gra,grb->ab", ab, ab), np.einsum("gra,gr->a", ab, f), cost,
    )


def shift_pair_blocks(
    pat: Pattern, rows: IntArray | None, n: int, d: int, p: int,
    au: FloatArray, ap: FloatArray, f: FloatArray,
) -> PairBlocks:
    """:func:`pair_blocks` without a border for rows whose unit's first three
    parameters move them as the opposite shift of their point does,
    ``au[..., :3] == -ap`` (a photo's projection centre against its image
    points); ``rows`` as there, None when the rows are in the pairs' order.
    With ``ar = au[..., 3:]`` the blocks need only ``apᵀ ap``, ``arᵀ ap``,
    ``arᵀ ar``, ``apᵀ f`` and ``arᵀ f`` per row (27 of the 54 products for
    d = 6): ``W = [-apᵀ ap; arᵀ ap]``, per point ``V = Σ apᵀ ap``,
    ``g_point = Σ apᵀ f``, per unit ``U = [[Σ apᵀ ap, -Σ (arᵀ ap)ᵀ],
    [-Σ arᵀ ap, Σ arᵀ ar]]``, ``g_unit = [-Σ apᵀ f, Σ arᵀ f]``.

    The products are formed once per row in the rows' own order from the
    entry-major Jacobians (no copy when they are laid out so, as
    :func:`~strip_aerotri.geometry.collinearity.collinearity_jacobians`
    lays them out); the pairs' share is read in place when the rows are in
    the pairs' order (else gathered), the units' summed by their runs (or,
    rows not sorted by unit, by ``np.bincount``).  Equal to
    :func:`pair_blocks` of the same rows up to the rounding of the sums'
    order (the products are the same)."""
    g = f.shape[0]
    e = d - 3
    a_u, a_p, f_e = entry_major(au), entry_major(ap), entry_major(f)
    a_r = a_u[:, 3:]
    # rows of `prod`: W of each row (d, 3) in C order, then apᵀ f (3), arᵀ f
    # (e) and arᵀ ar (lower); W's top -apᵀ ap, its bottom arᵀ ap
    at_gp = 3 * d
    at_gr, at_rr = at_gp + 3, at_gp + 3 + e
    prod = np.empty((at_rr + e * (e + 1) // 2, g))
    w_rows = prod[:at_gp].reshape(d, 3, g)
    lower = [3 * i + j for i in range(3) for j in range(i + 1)]  # -apᵀ ap's own entries

    def products(span: slice) -> None:
        xp, xr, xf = a_p[..., span], a_r[..., span], f_e[:, span]
        for i in range(3):  # W[i, :i + 1] = -Σ_r ap[r, i] ap[r, :i + 1]
            row = w_rows[i, : i + 1, span]
            np.einsum("rk,rbk->bk", xp[:, i], xp[:, : i + 1], out=row)
            np.negative(row, out=row)
            w_rows[: i, i, span] = w_rows[i, : i, span]
        np.einsum("rak,rbk->abk", xr, xp, out=w_rows[3:, :, span])
        np.einsum("rak,rk->ak", xp, xf, out=prod[at_gp:at_gr, span])
        np.einsum("rak,rk->ak", xr, xf, out=prod[at_gr:at_rr, span])
        _lower_gram(xr, prod[at_rr:, span])

    split_map(products, spans(g))
    # W: the rows' own in the pairs' order, else gathered
    w = w_rows if rows is None else take(w_rows, rows)
    v, g_point = np.zeros((p, 3, 3)), np.zeros((p, 3))

    def point_block(span: slice, places: slice | IntArray, starts: IntArray,
                    seen: IntArray) -> None:
        top = w[:3, :, span].reshape(9, -1)
        gp = prod[at_gp:at_gr, places] if rows is None else take(
            prod[at_gp:at_gr], rows[places]
        )
        v[seen] = -np.add.reduceat(top, starts, axis=-1).T.reshape(-1, 3, 3)
        g_point[seen] = np.add.reduceat(gp, starts, axis=-1).T

    split_map(_star(point_block), blocks_of(pat.point_runs, w.shape[-1]))
    own = np.r_[lower, 9 : at_gp, at_gp:at_rr, at_rr : prod.shape[0]]
    sums = _unit_sums(prod, own, pat, n)  # (n, entries of `own`)
    ip, jp = np.tril_indices(3)
    n_rp = 3 * e
    u = np.empty((n, d, d))
    u[:, ip, jp] = u[:, jp, ip] = -sums[:, :6]
    rp = sums[:, 6 : 6 + n_rp].reshape(n, e, 3)
    np.negative(rp, out=u[:, 3:, :3])
    np.negative(np.swapaxes(rp, 1, 2), out=u[:, :3, 3:])
    ir, jr = np.tril_indices(e)
    at = 6 + n_rp
    u[:, 3 + ir, 3 + jr] = u[:, 3 + jr, 3 + ir] = sums[:, at + 3 + e :]
    g_unit = np.concatenate([-sums[:, at : at + 3], sums[:, at + 3 : at + 3 + e]], axis=1)
    cost = float(np.einsum("rk,rk->", f_e, f_e))
    return PairBlocks(u, w, v, g_unit, g_point, np.zeros((n, d, 0)), np.zeros((p, 3, 0)),
                      np.zeros((0, 0)), np.zeros(0), cost)


def _unit_sums(values: FloatArray, entries: IntArray, pat: Pattern, n: int) -> FloatArray:
    """Sums (n, len(entries)) of the `entries` of entry-major per-row values
    (E, G) over each unit's rows: by the runs of rows sorted by unit, else
    one ``np.bincount`` per entry (a gather of the rows by unit would read
    them at random)."""
    if pat.row_unit_runs[0] is None:
        return run_sums(values[entries], pat.row_unit_runs, n)
    out = np.empty((entries.size, n))

    def entry(i: int) -> None:
        out[i] = np.bincount(pat.row_unit, values[entries[i]], minlength=n)

    split_map(entry, range(entries.size))
    return out.T


def _lower_gram(x: FloatArray, out: FloatArray) -> None:
    """``Σ_r x[r, a] x[r, b]`` of entry-major x (r, m, g) for a >= b, row by
    row of the lower triangle (``np.tril_indices(m)``'s order), into out
    (m (m + 1) / 2, g)."""
    for a in range(x.shape[1]):
        lo = a * (a + 1) // 2
        np.einsum("rk,rbk->bk", x[:, a], x[:, : a + 1], out=out[lo : lo + a + 1])


def _call(task: Callable[[], None]) -> None:
    task()


def _summed(products: FloatArray, starts: IntArray) -> FloatArray:
    """Sums over the runs starting at `starts` of entry-major products (…, m):
    (runs, …)."""
    out: FloatArray = np.moveaxis(np.add.reduceat(products, starts, axis=-1), -1, 0)
    return out


def _gram_summed(x: FloatArray, starts: IntArray) -> FloatArray:
    """``Σ_r x[r, a] x[r, b]`` of entry-major x (r, d, m) summed over the runs
    starting at `starts`: (runs, d, d), as ``_summed(einsum("rak,rbk->abk"))``
    to the bit (a product commutes exactly) from its lower triangle alone,
    d (d + 1) / 2 of the d² entries."""
    d = x.shape[1]
    lower = np.empty((d * (d + 1) // 2, x.shape[2]))
    for a in range(d):  # row a of the lower triangle: entries (a, 0..a)
        lo = a * (a + 1) // 2
        np.einsum("rk,rbk->bk", x[:, a], x[:, : a + 1], out=lower[lo : lo + a + 1])
    sums = np.add.reduceat(lower, starts, axis=-1).T  # (runs, d (d + 1) / 2)
    ia, ib = np.tril_indices(d)
    out = np.empty((sums.shape[0], d, d))
    out[:, ia, ib] = sums
    out[:, ib, ia] = sums
    return out


class PointFactor(NamedTuple):
    """Per point ``V = L Lᵀ`` and ``M = L⁻¹`` (lower), entry-major: ``m`` (6, p)
    the entries m00, m10, m11, m20, m21, m22 of M (NaN where V is not
    positive definite); ``v_inv`` (p, 3, 3) ``V⁻¹ = Mᵀ M``; ``bound`` (p,)
    ``1 / (trace V⁻¹ trace V)``, a lower bound of ``λmin / λmax``."""

    m: FloatArray
    v_inv: FloatArray
    bound: FloatArray


def lower_factor(v: FloatArray) -> FloatArray:
    """``V = L Lᵀ`` of 3 x 3 blocks V (p, 3, 3) in closed form: the entries
    l00, l10, l11, l20, l21, l22 of L (6, p), NaN (or a zero pivot) where V
    is not positive definite; ten times as fast as ``np.linalg.cholesky``
    on a stack of 3 x 3 matrices."""
    with np.errstate(invalid="ignore", divide="ignore"):
        l00 = np.sqrt(v[:, 0, 0])
        l10 = v[:, 1, 0] / l00
        l20 = v[:, 2, 0] / l00
        l11 = np.sqrt(v[:, 1, 1] - l10 * l10)
        l21 = (v[:, 2, 1] - l20 * l10) / l11
        l22 = np.sqrt(v[:, 2, 2] - l20 * l20 - l21 * l21)
    return np.stack([l00, l10, l11, l20, l21, l22])


def point_factor(v: FloatArray) -> PointFactor:
    """Cholesky factors of the points' 3 x 3 blocks V (p, 3, 3), in closed form."""
    l00, l10, l11, l20, l21, l22 = lower_factor(v)
    with np.errstate(invalid="ignore", divide="ignore"):
        m00, m11, m22 = 1.0 / l00, 1.0 / l11, 1.0 / l22
        m10 = -l10 * m00 * m11
        m21 = -l21 * m11 * m22
        m20 = -(l20 * m00 + l21 * m10) * m22
        m = np.stack([m00, m10, m11, m20, m21, m22])
        v_inv = lower_gram(m)
        trace = v[:, 0, 0] + v[:, 1, 1] + v[:, 2, 2]
        bound = 1.0 / ((v_inv[:, 0, 0] + v_inv[:, 1, 1] + v_inv[:, 2, 2]) * trace)
    return PointFactor(m, v_inv, bound)


def lower_gram(m: FloatArray) -> FloatArray:
    """``Mᵀ M`` (p, 3, 3) of lower-triangular M given as its six entries (6, p)."""
    m00, m10, m11, m20, m21, m22 = m
    out = np.empty((m.shape[1], 3, 3))
    out[:, 0, 0] = m00 * m00 + m10 * m10 + m20 * m20
    out[:, 1, 1] = m11 * m11 + m21 * m21
    out[:, 2, 2] = m22 * m22
    out[:, 0, 1] = out[:, 1, 0] = m10 * m11 + m20 * m21
    out[:, 0, 2] = out[:, 2, 0] = m20 * m22
    out[:, 1, 2] = out[:, 2, 1] = m21 * m22
    return out


def times_lower_t(x: FloatArray, m: FloatArray) -> FloatArray:
    """``X Mᵀ`` for entry-major X (a, 3, g) and lower M (6, g) per entry:
    (a, 3, g); with ``M = L⁻¹`` of V, ``(X Mᵀ)(X Mᵀ)ᵀ = X V⁻¹ Xᵀ``."""
    m00, m10, m11, m20, m21, m22 = m
    x0, x1, x2 = x[:, 0], x[:, 1], x[:, 2]
    out = np.empty_like(x)
    np.multiply(x0, m00, out=out[:, 0])
    np.multiply(x0, m10, out=out[:, 1])
    out[:, 1] += x1 * m11
    np.multiply(x0, m20, out=out[:, 2])
    out[:, 2] += x1 * m21
    out[:, 2] += x2 * m22
    return out


def times_lower(x: FloatArray, m: FloatArray) -> FloatArray:
    """``X M`` for entry-major X (a, 3, g) and lower M (6, g): (a, 3, g)."""
    m00, m10, m11, m20, m21, m22 = m
    x0, x1, x2 = x[:, 0], x[:, 1], x[:, 2]
    out = np.empty_like(x)
    np.multiply(x0, m00, out=out[:, 0])
    out[:, 0] += x1 * m10
    out[:, 0] += x2 * m20
    np.multiply(x1, m11, out=out[:, 1])
    out[:, 1] += x2 * m21
    np.multiply(x2, m22, out=out[:, 2])
    return out


def lower_times(m: FloatArray, x: FloatArray) -> FloatArray:
    """``M x`` for lower M (6, g) and entry-major x (3, ..., g): (3, ..., g),
    the leading axis of x the one M acts on."""
    m00, m10, m11, m20, m21, m22 = m
    return np.stack([m00 * x[0], m10 * x[0] + m11 * x[1], m20 * x[0] + m21 * x[1] + m22 * x[2]])


def lower_t_times(m: FloatArray, x: FloatArray) -> FloatArray:
    """``Mᵀ x`` for lower M (6, g) and entry-major x (3, ..., g): (3, ..., g)."""
    m00, m10, m11, m20, m21, m22 = m
    return np.stack([m00 * x[0] + m10 * x[1] + m20 * x[2], m11 * x[1] + m21 * x[2], m22 * x[2]])
