"""The iteration of the relative orientation (:mod:`.relative`): the pairs'
rows in padded blocks, one evaluation of their normal equations, the chord
check, the safeguarded Gauss-Newton iteration of many pairs at once, and the
robust flags of gross y-parallaxes.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._stats import sample_median
from .._typing import BoolArray, FloatArray, IntArray
from .relative_normals import _solve_damped, _solve_normals
from .relative_state import _Block, _Components, _State

MIN_POINTS_PER_PAIR = 5
_BLOCK_CELLS = 1 << 15  # cells (rows) per block: its temporaries stay in cache
# Corrections below this fraction of their standard deviation are negligible.
_PRECISION_FRACTION = 0.01
# Step control of the safeguarded Gauss-Newton iteration (_iterate): a step
# is accepted when Σ w q² does not grow by more than this fraction (rounding),
# or this absolute amount (noise-free pairs near 0) ...
_COST_RTOL = 1e-10
_COST_ATOL = 1e-28
# ... else Levenberg-Marquardt damping λ starts here, grows tenfold at each
# failed step and shrinks tenfold at each good one, back to Gauss-Newton
# below _DAMPING_MIN; beyond _DAMPING_MAX no step lowers the cost: the pair
# is at a minimum if the Gauss-Newton step would lower the cost by less than
# _STALL_RTOL of it.
_DAMPING_START = 1e-3
_DAMPING_MIN = 1e-7
_DAMPING_MAX = 1e8
_STALL_RTOL = 1e-6


class _Blocks:
    """The pairs' rows gathered into padded 2-D blocks (pairs × points).

    Element-wise work on a block needs no per-row gather of the pairs'
    unknowns (they broadcast as (pairs, 1) columns), and per-pair sums and
    medians are row operations.  Pairs are grouped by their number of rows so
    that padding stays small, and a block holds about ``_BLOCK_CELLS`` cells
    so that its temporaries stay in cache.  With ``stride > 1`` every
    stride-th row of a pair is taken (a spread subsample for the first
    iterations).
    """

    def __init__(
        self,
        left_t: FloatArray,
        right_t: FloatArray,
        starts: IntArray,
        counts: IntArray,
        pairs: IntArray,
        stride: IntArray | None = None,
        constant_z: tuple[float | None, float | None] = (None, None),
    ) -> None:
        # left_t, right_t: image vectors as contiguous (3, n) arrays, which
        # np.take gathers from 5x faster than fancy indexing of an (n, 3) view;
        # a z component that is one constant (-c, `constant_z`) is not gathered
        left_z, right_z = constant_z
        if stride is None:
            stride = np.ones_like(counts)
        width_of = -(-counts // stride)  # ceil
        order = pairs[np.argsort(width_of[pairs], kind="stable")]
        self.items: list[_Block] = []
        i = 0
        while i < order.size:
            # widths ascend within `order`: the last pair of a block is its widest
            cells = np.arange(1, order.size - i + 1) * width_of[order[i:]]
            j = i + max(1, int(np.searchsorted(cells, _BLOCK_CELLS, side="right")))
            idx = order[i:j]
            col = np.arange(int(width_of[idx].max()))
            n = counts[idx][:, None]
            step = stride[idx][:, None]
            taken = col * step
            valid = taken < n
            rows = starts[idx][:, None] + np.minimum(taken, n - 1)
            self.items.append(
                _Block(
                    idx,
                    rows,
                    valid,
                    valid.sum(axis=1),
                    _gather_components(left_t, left_z, rows),
                    _gather_components(right_t, right_z, rows),
                )
            )
            i = j
        self.pairs = np.sort(pairs)
        self.n_rows = int(sum(b.counts.sum() for b in self.items))


def _constant_or_none(values: FloatArray) -> float | None:
    """The value of an array whose elements are all equal, else None."""
    if values.size and bool((values == values[0]).all()):
        return float(values[0])
    return None


def _gather_components(vectors_t: FloatArray, z: float | None, rows: IntArray) -> _Components:
    """Components (x, y, z) of the rows (nb, width) of (3, n) vectors; z as
    the float ``z`` where given (one constant for all rows)."""
    if z is None:
        x, y, z_rows = np.take(vectors_t, rows, axis=1)
        return x, y, z_rows
    x, y = np.take(vectors_t[:2], rows, axis=1)
    return x, y, z


def _robust_scale(abs_q: FloatArray, block: _Block) -> FloatArray:
    """1.4826 × the median |q| of each pair of a block (upper median), (nb, 1)."""
    ranked = np.sort(np.where(block.valid, abs_q, np.inf), axis=1)
    median = ranked[np.arange(ranked.shape[0]), block.counts // 2]
    scale: FloatArray = np.maximum(1.4826 * median, 1e-6)[:, None]
    return scale


class _Evaluation:
    """One evaluation of the pairs of a blocking: per-pair normal equations and
    largest |y-parallax|, and per block the design rows, the y-parallaxes at
    image scale and the weights."""

    def __init__(self, n_pairs: int, blocks: _Blocks):
        self.blocks = blocks
        self.normal = np.zeros((n_pairs, 5, 5))
        self.gradient = np.zeros((n_pairs, 5))
        self.max_parallax_mm = np.zeros(n_pairs)
        self.sum_wqq = np.zeros(n_pairs)  # Σ w q² (model units)
        self.n_rows = np.zeros(n_pairs, dtype=np.intp)
        self.design: list[FloatArray] = []  # per block, rows scaled by sqrt(w)
        self.parallax_mm: list[FloatArray] = []


class _Record:
    """Final residual y-parallaxes (µm at image scale) and redundancy numbers
    ``1 − w aᵀ N⁻¹ a`` of each row, stored per pair from the evaluation at
    which the pair converged (pairs are independent: a converged pair does not
    move while others iterate)."""

    def __init__(self, n_rows: int, n_pairs: int):
        self.parallax_um = np.full(n_rows, np.nan)
        self.redundancy = np.full(n_rows, np.nan)
        self.stored = np.zeros(n_pairs, dtype=bool)

    def store(self, ev: _Evaluation, pairs: np.ndarray, n_inv: FloatArray) -> None:
        """Rows of the pairs in mask ``pairs``; ``n_inv`` (n_pairs, 5, 5) the
        inverse normal matrices of the evaluation."""
        for block, m, q_img in zip(ev.blocks.items, ev.design, ev.parallax_mm, strict=True):
            sel = pairs[block.pairs]
            if not sel.any():
                continue
            if sel.all():  # the usual case: every pair of the block converged together
                a, inv, valid, rows = m[:, :5], n_inv[block.pairs], block.valid, block.rows
            else:
                a, inv = m[sel, :5], n_inv[block.pairs[sel]]
                valid, rows, q_img = block.valid[sel], block.rows[sel], q_img[sel]
            # the design rows are stored scaled by sqrt(w): w aᵀ N⁻¹ a
            leverage = np.einsum("pik,pik->pk", a, inv @ a)
            rows = rows[valid]
            self.parallax_um[rows] = 1000.0 * q_img[valid]
            self.redundancy[rows] = np.clip(1.0 - leverage[valid], 0.0, 1.0)
        self.stored |= pairs

    def snapshot(self) -> tuple[FloatArray, FloatArray, BoolArray]:
        return self.parallax_um.copy(), self.redundancy.copy(), self.stored.copy()

    def restore(
        self,
        pairs: BoolArray,
        pair: IntArray,
        snapshot: tuple[FloatArray, FloatArray, BoolArray],
    ) -> None:
        """Rows of the pairs in mask ``pairs`` (``pair``: pair of each row) back
        to ``snapshot``."""
        rows = pairs[pair]
        self.parallax_um[rows] = snapshot[0][rows]
        self.redundancy[rows] = snapshot[1][rows]
        self.stored[pairs] = snapshot[2][pairs]

    def misfit(self, pair: IntArray, var: FloatArray, n_pairs: int) -> FloatArray:
        """RMS of the y-parallaxes in units of their a priori sigmas, per pair
        (inf where not stored): about 1 at the solution, far more at a wrong
        local minimum or with gross errors."""
        z2 = (self.parallax_um / 1000.0) ** 2 / var
        z2 = np.where(np.isfinite(z2), z2, np.inf)
        with np.errstate(invalid="ignore"):
            out = np.sqrt(
                np.bincount(pair, z2, minlength=n_pairs) / np.bincount(pair, minlength=n_pairs)
            )
        out[~self.stored] = np.inf
        return out


def _evaluate(
    state: _State, blocks: _Blocks, weight: FloatArray, robust: bool = False
) -> _Evaluation:
    """Design rows and y-parallaxes at the current state, reduced to per-pair
    normal equations ``N x = g`` of the weighted Gauss-Newton step.

    With ``robust`` the weights are multiplied by Cauchy weights of the
    current residuals, c = 2.385 robust sigmas of the pair (IRLS; start
    values only, the final solution is ordinary least squares).
    """
    ev = _Evaluation(state.n_pairs, blocks)

    for block in blocks.items:
        m = block.design
        q_img = state.terms(block.pairs, block, m)
        abs_q = np.abs(q_img)
        root_w = block.root_weight(weight)
        if robust:
            abs_q = np.where(np.isfinite(abs_q), abs_q, np.inf)
            cauchy = 1.0 + (abs_q / (2.385 * _robust_scale(abs_q, block))) ** 2
            root_w = root_w / np.sqrt(cauchy)
        m *= root_w[:, None, :]  # in place: the weighted rows serve N and the leverage
        normal = m @ m.transpose(0, 2, 1)
        ev.normal[block.pairs] = normal[:, :5, :5]
        ev.gradient[block.pairs] = -normal[:, :5, 5]
        ev.max_parallax_mm[block.pairs] = np.max(abs_q, axis=1)
        ev.sum_wqq[block.pairs] = normal[:, 5, 5]
        ev.n_rows[block.pairs] = block.counts
        ev.design.append(m)
        ev.parallax_mm.append(q_img)
    return ev


def _chord(
    state: _State, ev: _Evaluation, weight: FloatArray, n_inv: FloatArray
) -> tuple[_Evaluation, FloatArray]:
    """The y-parallaxes at the current state with the design rows of the
    previous evaluation ``ev`` (its blocks, rows scaled by sqrt(w)) and its
    inverse normal matrices ``n_inv`` (n_pairs, 5, 5): an evaluation whose
    parallaxes are current and design is the previous one, and the chord
    (simplified Newton) correction ``N⁻¹ Aᵀ W q`` of every pair, (n_pairs, 5).

    Near the solution the chord correction agrees with the Gauss-Newton one to
    first order in the last step, and it costs a third of a full evaluation
    (no design rows, no normal equations): a pair whose chord correction is
    negligible has converged at the current state.
    """
    chord = _Evaluation(state.n_pairs, ev.blocks)
    gradient = np.zeros((state.n_pairs, 5))
    for block, m in zip(ev.blocks.items, ev.design, strict=True):
        q, q_img = state.residuals(block.pairs, block)
        wq = block.root_weight(weight) * q
        gradient[block.pairs] = -(m[:, :5] @ wq[:, :, None])[:, :, 0]
        chord.sum_wqq[block.pairs] = np.einsum("pr,pr->p", wq, wq)
        chord.max_parallax_mm[block.pairs] = np.max(np.abs(q_img), axis=1)
        chord.n_rows[block.pairs] = block.counts
        chord.design.append(m)
        chord.parallax_mm.append(q_img)
    return chord, np.einsum("mij,mj->mi", n_inv, gradient)


def _negligible_limit(ev: _Evaluation, n_inv: FloatArray, tolerance: float) -> FloatArray:
    """Size below which a correction is negligible, (n_pairs, 5): the
    tolerance, or a small fraction of each unknown's own standard deviation
    (method.md §3: "negligible against image measuring accuracy"); exact data
    fall back on the tolerance."""
    sigma0_sq = ev.sum_wqq / np.maximum(ev.n_rows - MIN_POINTS_PER_PAIR, 1)
    with np.errstate(invalid="ignore"):
        limit: FloatArray = np.maximum(
            tolerance,
            _PRECISION_FRACTION * np.sqrt(sigma0_sq[:, None] * np.einsum("mii->mi", n_inv)),
        )
    return limit


def _iterate(
    state: _State,
    blocks_of: Callable[[BoolArray, IntArray | None], _Blocks],
    weight: FloatArray,
    max_iterations: int,
    tolerance: float,
    active: BoolArray,
    history: list[float],
    *,
    robust: bool = False,
    stride: IntArray | None = None,
    record: _Record | None = None,
    apply_last: bool = False,
) -> tuple[BoolArray, IntArray, BoolArray]:
    """Safeguarded Gauss-Newton steps for the active pairs until their
    corrections are negligible.

    Length: one loop whose step control (damping, the accepted normal
    equations, the chord check) carries over from step to step; most of its
    length is the description of that control below.

    ``blocks_of(mask, stride)`` gives the blocking of a set of pairs; after
    each step only the pairs still iterating are evaluated (the pairs are
    independent of each other).  A pair has converged when its next
    Gauss-Newton correction is negligible (below ``tolerance`` or 1 % of its
    own standard deviation); that correction is not applied (unless
    ``apply_last``), so the evaluation describes the final state, and its
    residuals and redundancy numbers go to ``record``.

    Every step must lower the pair's Σ w q²: a step that does not is taken
    back and replaced by a Levenberg-Marquardt step ``(N + λ diag N)⁻¹ g``
    from the normal equations kept from the accepted state, with λ ten times
    larger at each failure and ten times smaller at each success (pure
    Gauss-Newton again below 1e-7).  Gauss-Newton alone diverges or
    oscillates from a poor start and, with noisy short-base pairs, where the
    curvature of the y-parallax equation times the residuals matters,
    near the solution too; the safeguard makes every pair descend.  A pair
    whose cost no step can lower (λ beyond 1e8) has stopped at a minimum:
    converged when the Gauss-Newton step would lower its cost by less than
    1e-6 of it, failed otherwise.  A singular normal matrix is damped the
    same way.

    With ``record`` (least squares to the end), a step is followed by a
    chord check (``_chord``): the pairs whose chord correction is negligible
    (and whose cost fell) have converged, with their residuals at the final
    state and redundancy numbers from the design of the step; the others are
    evaluated in full.

    Returns (converged mask, evaluations per pair, singular mask at the last
    state of the pairs that did not converge).  ``history`` receives the
    largest |y-parallax| (µm at image scale) of the pairs evaluated, at each
    evaluation.
    """
    n_pairs = active.shape[0]
    done = np.zeros(n_pairs, dtype=bool)
    failed = np.zeros(n_pairs, dtype=bool)
    singular = np.zeros(n_pairs, dtype=bool)
    iterations = np.zeros(n_pairs, dtype=np.intp)
    todo = active.copy()
    damping = np.zeros(n_pairs)
    # the accepted state: its cost, normal equations and (for the pairs it
    # holds) the unknowns
    kept_cost = np.full(n_pairs, np.inf)
    kept_normal = np.zeros((n_pairs, 5, 5))
    kept_gradient = np.zeros((n_pairs, 5))
    kept = state.snapshot()
    blocks = blocks_of(todo, stride)
    # (evaluation, N⁻¹, pairs) of a step small enough for a chord check
    chord_from = None
    for it in range(1, max_iterations + 1):
        if chord_from is not None:
            ev, n_inv, near = chord_from
            ev, corr = _chord(state, ev, weight, n_inv)
            history.append(_largest_um(ev.max_parallax_mm[todo]))
            limit = _negligible_limit(ev, n_inv, tolerance)
            lower = ev.sum_wqq <= kept_cost * (1.0 + _COST_RTOL)
            small = todo & near & lower & (np.abs(corr) < limit).all(axis=1)
            iterations[small] = it - 1
            if small.any():
                assert record is not None  # the chord check serves the recorded solution
                record.store(ev, small, n_inv)
            done |= small
            todo &= ~small
            if not todo.any():
                break
            if todo.sum() < 0.8 * blocks.pairs.size:
                blocks = blocks_of(todo, stride)
        ev = _evaluate(state, blocks, weight, robust)
        history.append(_largest_um(ev.max_parallax_mm[todo]))
        cost = ev.sum_wqq
        with np.errstate(invalid="ignore"):
            worse = todo & ~(cost <= kept_cost * (1.0 + _COST_RTOL) + _COST_ATOL)
        better = todo & ~worse
        if worse.any():
            state.restore(worse, kept)
            damping[worse] = np.maximum(damping[worse] * 10.0, _DAMPING_START)
        damping[better] *= 0.1
        damping[damping < _DAMPING_MIN] = 0.0
        kept.save(better, state)
        kept_cost[better] = cost[better]
        kept_normal[better] = ev.normal[better]
        kept_gradient[better] = ev.gradient[better]
        corr = np.zeros((n_pairs, 5))
        singular = np.zeros(n_pairs, dtype=bool)
        n_inv = np.zeros((n_pairs, 5, 5))
        corr[todo], singular[todo], n_inv[todo] = _solve_normals(
            kept_normal[todo], kept_gradient[todo]
        )
        with np.errstate(invalid="ignore"):
            sigma0_sq = kept_cost / np.maximum(ev.n_rows - MIN_POINTS_PER_PAIR, 1)
            limit = np.maximum(
                tolerance,
                _PRECISION_FRACTION * np.sqrt(sigma0_sq[:, None] * np.einsum("mii->mi", n_inv)),
            )
        small = better & ~singular & (np.abs(corr) < limit).all(axis=1)
        # a pair no step can lower stops at its minimum when the Gauss-Newton
        # step would gain next to nothing
        stuck = todo & ~small & (damping > _DAMPING_MAX)
        if stuck.any():
            gain = np.einsum("mi,mi->m", corr, kept_gradient)
            at_minimum = stuck & better & ~singular & (gain <= _STALL_RTOL * kept_cost)
            small |= at_minimum
            failed |= stuck & ~at_minimum
        iterations[small] = it - 1
        if record is not None and small.any():
            record.store(ev, small, n_inv)
        done |= small
        todo &= ~(small | failed)
        damped = todo & ((damping > 0.0) | singular)
        if damped.any():
            damping[damped & (damping == 0.0)] = _DAMPING_START
            corr[damped] = _solve_damped(
                kept_normal[damped], kept_gradient[damped], damping[damped]
            )
        corr[~np.isfinite(corr).all(axis=1)] = 0.0
        step = todo | (small & apply_last)
        corr[~step] = 0.0
        if step.any():
            state.update(corr)
        if not todo.any():
            break
        # Chord checks only near the solution, where they succeed (else they are
        # lost work): an undamped step that reduces Σ w q² by less than half (the
        # residuals are mostly noise, not an orientation still to be found), and
        # the next correction, of the order of the step squared, is negligible.
        near = (
            step
            & (damping == 0.0)
            & (np.einsum("mi,mi->m", corr, kept_gradient) < 0.5 * kept_cost)
            & (np.max(np.abs(corr), axis=1) ** 2 < np.min(limit, axis=1))
        )
        chord_from = (ev, n_inv, near) if record is not None and not robust else None
        if chord_from is not None and not (todo & near).any():
            chord_from = None
        if todo.sum() < 0.8 * blocks.pairs.size:
            blocks = blocks_of(todo, stride)
    return done, iterations, active & ~done & singular


def _largest_um(max_parallax_mm: FloatArray) -> float:
    q = max_parallax_mm[np.isfinite(max_parallax_mm)]
    return float(np.max(q)) * 1000.0 if q.size else float("nan")


def _gross_rows(state: _State, blocks: _Blocks, n_rows: int) -> BoolArray:
    """Rows (flat mask) whose y-parallax exceeds 5 robust sigmas (1.4826 MAD) of their pair."""
    gross = np.zeros(n_rows, dtype=bool)
    for block in blocks.items:
        abs_q = np.abs(state.terms(block.pairs, block, block.design))
        abs_q = np.where(np.isfinite(abs_q), abs_q, np.inf)
        flag = ~(abs_q <= 5.0 * _robust_scale(abs_q, block)) & block.valid
        gross[block.rows[flag]] = True
    return gross


def _suspect_pairs(
    record: _Record, pair: IntArray, var: FloatArray, counts: IntArray
) -> BoolArray:
    """Pairs whose least-squares y-parallaxes suggest gross errors.

    The y-parallaxes are standardised by their a priori sigmas.  A pair is
    suspect if one of them exceeds 5 robust sigmas of the strip (1.4826 × the
    median over the strip, one O(n) pass), or if its RMS exceeds 3 a priori
    sigmas: many gross errors spread into the fit and inflate the median.  A
    pair that is only noisier than declared is just re-solved robustly; which
    of its rows are gross is decided within the pair (``_gross_rows``).
    """
    z = np.abs(record.parallax_um) / (1000.0 * np.sqrt(var))
    z = np.where(np.isfinite(z), z, np.inf)
    scale = max(1.4826 * sample_median(z), 1e-6)
    over = ~(z <= 5.0 * scale)
    n_pairs = counts.shape[0]
    rms = np.sqrt(np.bincount(pair, np.minimum(z, 1e150) ** 2, minlength=n_pairs) / counts)
    return (np.bincount(pair[over], minlength=n_pairs) > 0) | ~(rms <= 3.0)
