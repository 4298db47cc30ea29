"""The fixed pattern of a structured normal system (method.md 6B): which units
each point is tied to, the units' order along the band, and the index arrays
that scatter the Schur complement's blocks into the band and gather the band
of the inverse back per point.

Built once per problem (the pattern does not change between iterations) by
:class:`strip_aerotri.geometry.normals.NormalStructure`.

Pairs (unit, point) are the distinct couplings ``W_ip``; they are held sorted
by point, and within a point by the unit's position along the band, with the
points themselves grouped by their number q of units and, within that, by
their unit set (the *signature*): points with the same units are summed into
the band together.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np

from .._typing import BoolArray, IntArray

#: Largest number of float64 entries of one chunk of per-point products.
CHUNK_ENTRIES = 2_000_000


@dataclass(frozen=True)
class Chunk:
    """Groups of points with the same q units each and the same number of
    points per group (``size``), processed at once.

    The points of one group share their units (their *signature*); ``points``
    (G * size,) lists them group by group, and their pairs are the contiguous
    ``pair_start .. pair_start + G * size * q`` (per point, its q units by
    position).  ``scatter`` (G, q(q+1)/2) is the band block index
    ``J (w + 1) + o`` of each lower pair (a >= b) of a group's units,
    ``gather`` (G, q, q) that of every pair (a, b) and ``upper`` (q, q) where
    that block is the transpose of the stored one (a < b).

    The lower blocks ``(lower_a, lower_b)`` of the groups' Schur products go
    into the band at ``scatter``; where several of a chunk's blocks add into
    one band block, ``scatter_unique`` are the distinct targets and
    ``scatter_inverse`` (G q(q+1)/2,) the place of each block among them
    (None when every target is distinct)."""

    q: int
    size: int
    points: IntArray
    pair_start: int
    scatter: IntArray
    gather: IntArray
    upper: BoolArray
    lower_a: IntArray
    lower_b: IntArray
    scatter_unique: IntArray | None
    scatter_inverse: IntArray | None

    @property
    def groups(self) -> int:
        return self.points.size // self.size


@dataclass(frozen=True)
class Pattern:
    n_units: int
    unit_size: int
    n_points: int
    position: IntArray  # (n,) place of each unit along the band
    order: IntArray  # (n,) unit at each place
    width: int  # half-bandwidth in units
    pair_unit: IntArray  # (n_pairs,)
    pair_point: IntArray  # (n_pairs,)
    row_pair: IntArray  # (G,) pair of each unit-point row
    chunks: tuple[Chunk, ...]
    pair_keys: IntArray  # sorted keys point * n + position of the pairs
    row_unit: IntArray  # (G,) the unit-point rows' units, as given
    row_point: IntArray  # (G,) and points
    pair_row: IntArray | None  # (n_pairs,) the row of each pair when there is one each
    #: runs of the pairs by point (contiguous: no order), of the pairs by
    #: unit and of the rows by unit (None: the rows are sorted by unit), each
    #: (order, first of each run, its point or unit), for entry_major.run_sums
    point_runs: tuple[IntArray | None, IntArray, IntArray]
    pair_unit_runs: tuple[IntArray | None, IntArray, IntArray]
    row_unit_runs: tuple[IntArray | None, IntArray, IntArray]
    pair_by_key: IntArray  # the pair of each sorted key
    #: the unit-point rows are the pairs themselves, in their order (row i is
    #: pair i's: :meth:`in_pair_order`)
    rows_in_pair_order: bool = False

    def in_pair_order(self) -> Pattern | None:
        """The same pattern for its unit-point rows given in the pairs' order
        (``row_unit[pair_row]``, ``row_point[pair_row]``), so that the pairs'
        blocks are read in place; None when a pair has more than one row."""
        if self.pair_row is None:
            return None
        if self.rows_in_pair_order:
            return self
        rows = np.arange(self.pair_row.size, dtype=np.intp)
        # the runs by unit of the rows as given, renumbered (no new sort)
        by_unit, starts, units = self.row_unit_runs
        new_row = self.row_pair  # the new place of each row as given
        return dataclasses.replace(
            self, row_unit=self.row_unit[self.pair_row], row_point=self.row_point[self.pair_row],
            row_pair=rows, pair_row=rows, rows_in_pair_order=True,
            row_unit_runs=(new_row if by_unit is None else new_row[by_unit], starts, units),
        )

    def pair_of(self, unit: IntArray, point: IntArray) -> IntArray:
        """Pair index of (unit, point) couplings; ValueError if not in the pattern."""
        key = point * self.n_units + self.position[unit]
        at = np.searchsorted(self.pair_keys, key)
        at = np.minimum(at, max(self.pair_keys.size - 1, 0))
        if key.size and (self.pair_keys.size == 0 or np.any(self.pair_keys[at] != key)):
            raise ValueError("rows tie a unit to a point that the pattern does not couple")
        return self.pair_by_key[at]

    def block_index(self, unit_a: IntArray, unit_b: IntArray) -> tuple[IntArray, BoolArray]:
        """Band block index and 'transposed' flag of the blocks (a, b) of units."""
        pa, pb = self.position[unit_a], self.position[unit_b]
        upper = pa < pb
        lo, hi = np.minimum(pa, pb), np.maximum(pa, pb)
        off = hi - lo
        if np.any(off > self.width):
            raise ValueError("units outside the band of the pattern")
        return lo * (self.width + 1) + off, upper


def bandwidth(position: IntArray, point_pairs: tuple[IntArray, IntArray],
              unit_sets: list[IntArray]) -> int:
    """Half-bandwidth (in units) of the reduced matrix for the units' positions."""
    pair_point, pair_unit = point_pairs
    width = 0
    if pair_point.size:
        p = position[pair_unit]
        n_points = int(pair_point.max()) + 1
        hi = np.full(n_points, -1)
        lo = np.full(n_points, np.iinfo(np.intp).max)
        np.maximum.at(hi, pair_point, p)
        np.minimum.at(lo, pair_point, p)
        seen = hi >= 0
        width = int(np.max(hi[seen] - lo[seen], initial=0))
    for units in unit_sets:
        if units.size:
            p = position[units]
            width = max(width, int(np.max(p.max(axis=1) - p.min(axis=1), initial=0)))
    return width


def unit_graph_order(n_units: int, point_pairs: tuple[IntArray, IntArray],
                     unit_sets: list[IntArray]) -> IntArray:
    """Reverse Cuthill-McKee order of the units' graph: two units linked when
    they share a point or a unit row (every pair of a point's units: the
    graph of the reduced matrix itself).  ``point_pairs`` (point, unit) sorted
    by point."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    pair_point, pair_unit = point_pairs
    rows, cols = [], []
    if pair_point.size:
        q_of = np.bincount(pair_point)
        first = np.concatenate([[0], np.cumsum(q_of)[:-1]])
        for q in np.unique(q_of[q_of > 1]):
            units = pair_unit[first[q_of == q][:, None] + np.arange(q)]  # (c, q)
            units = np.unique(units, axis=0)  # points with the same units: one clique
            ia, ib = np.triu_indices(int(q), 1)
            rows.append(units[:, ia].reshape(-1))
            cols.append(units[:, ib].reshape(-1))
    for units in unit_sets:
        if units.ndim == 2 and units.shape[1] > 1:
            ia, ib = np.triu_indices(units.shape[1], 1)
            rows.append(units[:, ia].reshape(-1))
            cols.append(units[:, ib].reshape(-1))
    r = np.concatenate(rows) if rows else np.zeros(0, np.intp)
    c = np.concatenate(cols) if cols else np.zeros(0, np.intp)
    graph = sp.csr_matrix((np.ones(r.size), (r, c)), shape=(n_units, n_units))
    graph = (graph + graph.T).tocsr()
    order: IntArray = np.asarray(reverse_cuthill_mckee(graph, symmetric_mode=True), np.intp)
    return order


def build_pattern(
    n_units: int,
    unit_size: int,
    n_points: int,
    row_unit: IntArray,
    row_point: IntArray,
    unit_sets: list[IntArray],
    order: IntArray,
) -> Pattern:
    """The pattern for unit-point rows (G,) and unit rows (each (g, q) units),
    with the units placed along the band in `order` (unit at each place)."""
    n = n_units
    position = np.empty(n, dtype=np.intp)
    position[order] = np.arange(n)
    key = row_point * n + position[row_unit]
    upair, row_pair = np.unique(key, return_inverse=True)
    pp = upair // n
    pu = order[upair % n]
    width = bandwidth(position, (pp, pu), unit_sets)
    q_of = np.bincount(pp, minlength=n_points)
    first = np.concatenate([[0], np.cumsum(q_of)[:-1]])
    # points by q, then by signature (their units' positions), then by index;
    # the groups of equal signature then by their size
    seen = np.flatnonzero(q_of > 0)
    chunks: list[Chunk] = []
    new_pairs: list[IntArray] = []
    for q in np.unique(q_of[seen]):
        pts = seen[q_of[seen] == q]
        pairs = first[pts][:, None] + np.arange(q)[None, :]
        sig = position[pu[pairs]]  # (c, q) ascending
        srt = np.lexsort((pts, *sig.T[::-1]))
        pts, pairs, sig = pts[srt], pairs[srt], sig[srt]
        new_group = np.r_[True, np.any(sig[1:] != sig[:-1], axis=1)]
        group = np.cumsum(new_group) - 1
        size = np.bincount(group)[group]  # points in each point's group
        srt = np.argsort(size, kind="stable")
        pts, pairs, sig, size = pts[srt], pairs[srt], sig[srt], size[srt]
        for n_g in np.unique(size):
            sel = size == n_g
            new_pairs.append(pairs[sel].reshape(-1))
            chunks.extend(_chunks(int(q), int(n_g), unit_size, width, pts[sel], pairs[sel],
                                  sig[sel]))
    # renumber the pairs in the chunks' order, so a chunk's pairs are contiguous
    old = np.concatenate(new_pairs) if new_pairs else np.zeros(0, np.intp)
    renum = np.empty_like(old)
    renum[old] = np.arange(old.size)
    chunks = [
        dataclasses.replace(c, pair_start=int(renum[c.pair_start])) for c in chunks
    ]
    # the pairs' keys point * n + position, sorted, are `upair` (the old
    # numbering); the new number of each is `renum`
    new_row_pair = renum[row_pair]
    pair_row: IntArray | None = None
    if row_pair.size == old.size:  # one row per pair
        pair_row = np.empty(old.size, dtype=np.intp)
        pair_row[new_row_pair] = np.arange(old.size)
    return Pattern(
        n_units=n,
        unit_size=unit_size,
        n_points=n_points,
        position=position,
        order=np.asarray(order, dtype=np.intp),
        width=width,
        pair_unit=pu[old],
        pair_point=pp[old],
        row_pair=new_row_pair,
        chunks=tuple(chunks),
        pair_keys=upair.astype(np.intp),
        pair_by_key=renum.astype(np.intp),
        row_unit=row_unit,
        row_point=row_point,
        pair_row=pair_row,
        point_runs=runs_of(pp[old]),
        pair_unit_runs=runs_of(pu[old]),
        row_unit_runs=runs_of(row_unit),
    )


def runs_of(index: IntArray) -> tuple[IntArray | None, IntArray, IntArray]:
    """The runs of equal values of `index`: (the stable order that makes each
    value's places contiguous, None when they already are; the first place of
    each run in that order; the value of each run)."""
    index = np.asarray(index, np.intp)
    if index.size == 0:
        return None, np.zeros(0, np.intp), np.zeros(0, np.intp)
    starts = np.flatnonzero(np.r_[True, index[1:] != index[:-1]]).astype(np.intp)
    values = index[starts]
    if np.all(values[1:] > values[:-1]) or np.bincount(values - values.min()).max() == 1:
        return None, starts, values
    order = np.argsort(index, kind="stable").astype(np.intp)
    return (order, *runs_of(index[order])[1:])


def sorted_unique(values: IntArray) -> IntArray:
    """``np.unique(values)`` by a sort (numpy's own hashes, which is slower on
    the index arrays here)."""
    flat = np.sort(np.asarray(values).reshape(-1))
    out: IntArray = flat[np.r_[True, flat[1:] != flat[:-1]]] if flat.size else flat
    return out


@functools.lru_cache(maxsize=64)
def _pair_tables(q: int) -> tuple[IntArray, IntArray, BoolArray, IntArray, IntArray]:
    """For q units of a group: the lower pairs (a >= b; positions ascending,
    so pos_a >= pos_b) as two index arrays, and for every pair (a, b) of the
    q x q grid whether it is above the diagonal and its smaller and larger
    index; read-only, shared by the chunks of every pattern."""
    a_idx, b_idx = np.tril_indices(q)
    aa, bb = np.meshgrid(np.arange(q), np.arange(q), indexing="ij")
    out = (a_idx.astype(np.intp), b_idx.astype(np.intp), aa < bb, np.minimum(aa, bb),
           np.maximum(aa, bb))
    for x in out:
        x.flags.writeable = False
    return out


def _chunks(q: int, n_g: int, d: int, width: int, pts: IntArray, pairs: IntArray,
            sig: IntArray) -> list[Chunk]:
    """Groups of n_g points with the same q units (consecutive runs of n_g in
    `pts`), in chunks of bounded size, with their index arrays; a chunk's
    ``pair_start`` is the old index of its first pair (renumbered by the caller)."""
    per_group = (q * d) ** 2 + n_g * q * d * 3
    groups = pts.size // n_g
    size = max(1, CHUNK_ENTRIES // per_group)
    w1 = width + 1
    a_idx, b_idx, upper, lo, hi = _pair_tables(q)
    gs_all = sig[::n_g]  # (groups, q)
    out = []
    for g0 in range(0, groups, size):
        g1 = min(groups, g0 + size)
        gs = gs_all[g0:g1]
        scatter = gs[:, b_idx] * w1 + (gs[:, a_idx] - gs[:, b_idx])
        gather = gs[:, lo] * w1 + (gs[:, hi] - gs[:, lo])
        flat = scatter.reshape(-1)
        uniq, inverse = np.unique(flat, return_inverse=True)
        distinct = uniq.size == flat.size
        out.append(
            Chunk(q, n_g, pts[g0 * n_g : g1 * n_g], int(pairs[g0 * n_g, 0]),
                  scatter.astype(np.intp), gather.astype(np.intp), upper, a_idx, b_idx,
                  None if distinct else uniq.astype(np.intp),
                  None if distinct else inverse.astype(np.intp).reshape(-1))
        )
    return out
