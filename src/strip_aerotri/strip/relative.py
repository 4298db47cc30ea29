"""Relative orientation of the pairs of a strip by the y-parallax equation.

Two formulations of the same coplanarity condition are offered:

* ``"dependent"`` — Janiszewski's dependent pair (J(5)-(10), method.md §3):
  the left photo's rotation is known (taken from the previous pair), the
  unknowns are the base components ``b_y, b_z`` (``b_x = 1`` in the strip
  system) and the right photo's rotation, corrected by Schut's algebraic
  rotation with the fixed J(7) and J(9).
* ``"base"`` — the Bulgarian textbook's base-system elements (B(125)-(136),
  method.md §3.1): the angles α'1, χ'1 of the left photo and α'2, ω'2, χ'2 of
  the right photo in a system whose x axis is the base.

All pairs of a strip are solved together, on padded (pairs × points) blocks
that hold the points of all pairs.  The y-parallax is taken along the left
photo's image y axis (J's strip y axis when the left rotation is the identity,
as for his first pair), so each pair is solved in its left photo's image frame
independently of the chain, whatever the heading; the strip's sequential
dependence (the right photo of pair m is the left photo of pair m + 1) enters
only through the chain of rotations formed from the pairs' relative rotations
at the end.  See docs/strip-formation.md.

Conventions: image vectors ``(x, y, -c)`` in mm; rotations map image vectors to
the strip system (``l = R @ l_image``); the residual y-parallax is reported at
image scale in micrometres.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import NoReturn

import numpy as np

from .._stats import exact_median, sample_median
from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..errors import ConvergenceError, FlightAxisError, GeometryError
from ..options import (
    DEFAULT_IMAGE_SIGMA_MM,
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_RO_TOLERANCE,
    RelativeOrientationMethod,
)
from ..plausibility import flight_axis_message
from ..results import RelativeOrientation
from .relative_state import (
    _BaseState,
    _Block,
    _Components,
    _DependentState,
    _State,
    _segment_starts,
    chain_rotations,
)
from .relative_starts import (
    SimilarityStart,
    _similarity_start,
    _vertical_start,
    essential_start,
    homography_start,
    similarity_start,
)
from .relative_normals import _solve_damped, _solve_normals


__all__ = [
    "COLLINEAR_RATIO",
    "MIN_POINTS_PER_PAIR",
    "RelativeOrientation",
    "RelativeOrientationMethod",
    "SimilarityStart",
    "chain_rotations",
    "collinear_ratio",
    "essential_start",
    "homography_start",
    "pair_count_problems",
    "relative_orientation",
    "similarity_start",
]

MIN_POINTS_PER_PAIR = 5
_ROBUST_STEPS = 10  # IRLS steps of the robust start
# RMS y-parallax (in a priori sigmas) above which a converged pair is tried
# from the other starts too (a wrong local minimum, or gross errors)
_DOUBTFUL_MISFIT = 3.0
# Points whose spread across their best-fitting image line is below this
# fraction of the spread along it are collinear (_check_not_collinear).
COLLINEAR_RATIO = 1e-2
_SUBSAMPLE_POINTS = 40  # points per pair in the first iterations
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


def pair_count_problems(counts: IntArray, labels: Sequence[str] | None = None) -> list[str]:
    """The pairs with too few common points for a relative orientation, one line each.

    ``counts[m]``: points measured on both photos of pair m; ``labels``: the
    pairs' names (default "pair m").  The rule of :func:`relative_orientation`
    (at least :data:`MIN_POINTS_PER_PAIR`), listed for ``stripaero check``.
    """
    return [
        f"{labels[int(m)] if labels else f'pair {m}'}: {counts[m]} point(s) measured on both "
        f"photos; relative orientation needs at least {MIN_POINTS_PER_PAIR}"
        for m in np.flatnonzero(np.asarray(counts) < MIN_POINTS_PER_PAIR)
    ]


def _check_pairs(pair: IntArray, n_pairs: int, labels: list[str] | None) -> IntArray:
    counts = np.bincount(pair, minlength=n_pairs)
    problems = pair_count_problems(counts, labels)
    if problems:
        raise GeometryError(problems[0])
    return counts


def collinear_ratio(image: ArrayLike, pair: IntArray, n_pairs: int) -> FloatArray:
    """Per pair, how far its points in one image are from lying on one line.

    Scale-free: the smaller singular value of the pair's centred normalised
    image coordinates (x / -z, y / -z) over the larger one (0: on one line;
    NaN for a pair without points).  Below ``COLLINEAR_RATIO`` (1 %) the points
    cannot determine the orientation whatever the start (the rotation about
    their line stays free).

    Parameters
    ----------
    image : array_like, shape (n, 3)
        Image vectors of the pairs' points, rows sorted by ``pair``.
    pair : ndarray of int, shape (n,)
        The pair of each row, non-decreasing.
    n_pairs : int
    """
    img = np.asarray(image, dtype=np.float64)
    counts = np.bincount(pair, minlength=n_pairs)
    ratio = np.full(n_pairs, np.nan)
    has = np.flatnonzero(counts)
    if not has.size:
        return ratio
    starts = _segment_starts(pair, n_pairs)[has]
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        uv = img[:, :2] / -img[:, 2:3]
        mean = np.add.reduceat(uv, starts, axis=0) / counts[has, None]
        d = uv - np.repeat(mean, counts[has], axis=0)
        sxx = np.add.reduceat(d[:, 0] ** 2, starts)
        syy = np.add.reduceat(d[:, 1] ** 2, starts)
        sxy = np.add.reduceat(d[:, 0] * d[:, 1], starts)
        # eigenvalues of the 2 x 2 scatter matrix
        half_trace = 0.5 * (sxx + syy)
        root = np.sqrt(np.maximum(half_trace**2 - (sxx * syy - sxy**2), 0.0))
        small, large = half_trace - root, half_trace + root
        ratio[has] = np.sqrt(np.maximum(small, 0.0) / large)
    return ratio


def _check_not_collinear(
    left: FloatArray,
    pair: IntArray,
    counts: IntArray,
    labels: list[str] | None,
) -> None:
    """Refuse pairs whose points lie nearly on one line in the left image
    (:func:`collinear_ratio`): the iteration may still stop somewhere, so the
    verdict comes from the data, not from it."""
    ratio = collinear_ratio(left, pair, counts.shape[0])
    bad = np.flatnonzero(~(ratio >= COLLINEAR_RATIO))
    if bad.size:
        m = int(bad[0])
        others = f" (and {bad.size - 1} more pair(s))" if bad.size > 1 else ""
        raise GeometryError(
            f"{_name(labels, m)}{others}: the points do not determine the relative "
            f"orientation: its {int(counts[m])} points lie nearly on one line in the "
            f"image (spread across that line {ratio[m]:.1e} of the spread along it); "
            "measure points spread over the whole overlap"
        )


def _name(labels: list[str] | None, m: int) -> str:
    return labels[m] if labels else f"pair {m}"


def _raise_across(
    m: int, left: FloatArray, right: FloatArray, pair: IntArray, labels: list[str] | None
) -> NoReturn:
    """Pair m's base runs across image x: name the image axis the photos move
    along (against the mean shift of the pair's points from the left photo to
    the right one, which the y-parallax equation cannot tell: b and -b are
    coplanar alike)."""
    rows = pair == m
    shift = np.mean(left[rows, :2] - right[rows, :2], axis=0) if rows.any() else np.zeros(2)
    k = int(np.argmax(np.abs(shift)))
    strong = np.isfinite(shift).all() and abs(shift[k]) > 2.0 * abs(shift[1 - k])
    along = ("+" if shift[k] > 0 else "-") + "xy"[k] if strong else ""
    name = _name(labels, m)
    raise FlightAxisError(
        flight_axis_message(name, "" if along == "+x" else along), pair=name, along=along
    )


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


def relative_orientation(
    left: ArrayLike,
    right: ArrayLike,
    pair: ArrayLike,
    n_pairs: int,
    *,
    method: RelativeOrientationMethod | str = RelativeOrientationMethod.DEPENDENT,
    rotation_first: ArrayLike | None = None,
    sigma_left: ArrayLike | float = DEFAULT_IMAGE_SIGMA_MM,
    sigma_right: ArrayLike | float = DEFAULT_IMAGE_SIGMA_MM,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    tolerance: float = DEFAULT_RO_TOLERANCE,
    labels: list[str] | None = None,
    robust: bool = False,
    start: RelativeOrientation | None = None,
) -> RelativeOrientation:
    """Orient a chain of pairs by the y-parallax equation.

    Length: the orientation strategy in one place (the first start, the
    retries from the other starts, the robust recovery of pairs that do not
    converge and the robust re-solution of suspect pairs), each a few lines
    over one shared state; the numerical work is in :func:`_iterate` and the
    state classes.

    Parameters
    ----------
    left, right : array_like, shape (n, 3)
        Image vectors ``(x, y, -c)`` in mm of each point on the left and the
        right photo of its pair.
    pair : array_like of int, shape (n,)
        Pair index of each row, non-decreasing, in ``0 .. n_pairs - 1``.
    n_pairs : int
        Number of pairs; pair m is formed by photos m and m + 1.
    method : {"dependent", "base"}
        J's dependent pair (J(5)-(10)) or B's base-system elements
        (B(125)-(136)).  Both solve the same coplanarity condition; on
        noise-free data they give the same orientation.
    rotation_first : array_like, shape (3, 3), optional
        Image -> strip rotation of the first photo; identity by default (J).
    sigma_left, sigma_right : float or array_like, shape (n,)
        Standard deviations of the image coordinates in mm; the weight of a
        y-parallax is proportional to ``1 / (sigma_left² + sigma_right²)``
        (J §3: weights per observation).
    max_iterations : int
    tolerance : float
        Convergence limit on the corrections (radians and base units); a
        correction below 1 % of its own standard deviation is negligible too.
    labels : list of str, optional
        Names of the pairs for messages, e.g. ``"pair 1201-1202"``.
    robust : bool
        Pairs whose least-squares y-parallaxes include some beyond 5 robust
        sigmas (1.4826 MAD) of the pair are solved again from an iteratively
        reweighted (Cauchy) start, and those y-parallaxes take no part in the
        final least squares, so that gross errors cannot distort it; their
        residuals and w-tests are still returned for the caller to report.
    start : RelativeOrientation, optional
        An earlier solution of the same pairs with the same method (e.g.
        before a rejected observation was left out), taken as start values:
        pairs it still solves take no step.

    Returns
    -------
    RelativeOrientation

    Raises
    ------
    GeometryError
        A pair with fewer than five points or with a degenerate point set.
    ConvergenceError
        The iteration did not converge.

    Notes
    -----
    The residual y-parallax of a point, J(5), is
    ``q = b·(l × p) / (j·(l × p))`` with ``l = R_l l_image``,
    ``p = R_p p_image`` and ``j = R_l (0, 1, 0)``, the left photo's image y
    axis (J's ``(0, 1, 0)`` for ``R_l = I``); its linearisation, the fixed
    J(7), is ``q = q0 + [(l × p0)/D]·db + [p0 × ((b0 − q0 j) × l)/D]·a``
    and the right rotation is updated by ``R_schut(a / 2)`` (fixed J(9)).
    """
    left = np.asarray(left, dtype=np.float64)
    right = np.asarray(right, dtype=np.float64)
    pair = np.asarray(pair, dtype=np.intp)
    method = RelativeOrientationMethod(method)
    if left.ndim != 2 or left.shape[1] != 3 or right.shape != left.shape:
        raise ValueError(
            f"Expected left and right to have shape (n, 3), got {left.shape} and {right.shape}"
        )
    if pair.shape != (left.shape[0],):
        raise ValueError(f"Expected pair to have shape ({left.shape[0]},), got {pair.shape}")
    if pair.size and np.any(np.diff(pair) < 0):
        raise ValueError("Expected pair indices to be sorted (non-decreasing)")
    first = np.eye(3) if rotation_first is None else np.asarray(rotation_first, np.float64)
    counts = _check_pairs(pair, n_pairs, labels)
    starts = _segment_starts(pair, n_pairs)
    _check_not_collinear(left, pair, counts, labels)
    var = (
        np.broadcast_to(np.asarray(sigma_left, np.float64), pair.shape) ** 2
        + np.broadcast_to(np.asarray(sigma_right, np.float64), pair.shape) ** 2
    )
    sigma_ref2 = exact_median(var) / 2.0
    weight = 2.0 * sigma_ref2 / var

    state: _State
    if method is RelativeOrientationMethod.DEPENDENT:
        state = _DependentState(n_pairs, first)
    else:
        state = _BaseState(n_pairs, first)

    if start is not None:
        if start.method is not method or start.n_pairs != n_pairs:
            raise ValueError(
                f"Expected a start of {n_pairs} pairs by the {method.value!r} method, got "
                f"{start.n_pairs} by {start.method.value!r}"
            )
        state.set_start(start.elements)

    left_t, right_t = np.ascontiguousarray(left.T), np.ascontiguousarray(right.T)

    constant_z = (_constant_or_none(left_t[2]), _constant_or_none(right_t[2]))

    def blocks_of(mask: BoolArray, stride: IntArray | None = None) -> _Blocks:
        return _Blocks(left_t, right_t, starts, counts, np.flatnonzero(mask), stride, constant_z)

    everything = np.ones(n_pairs, dtype=bool)
    record = _Record(pair.shape[0], n_pairs)
    history: list[float] = []
    first_start = None
    if start is None:
        # The relative rotation and the base from the homography of the two
        # images: J's near-vertical start (Q = I, b = (1, 0, 0)) is far off
        # for the swings and tilts of drone photos (relative kappa of 10-15
        # deg, tilts of 5-8 deg against a base of 0.15 of the height).
        first_start = homography_start(left, right, pair, n_pairs, starts)
        state.restart(everything, *first_start)
    stride = np.maximum(counts // _SUBSAMPLE_POINTS, 1)
    if start is None and (stride > 1).any():
        # The first steps only have to reach the region of quadratic
        # convergence: take them on a spread subsample of every large pair,
        # then finish on all points.
        ok, *_ = _iterate(
            state,
            blocks_of,
            weight,
            max_iterations,
            1e-6,
            everything,
            history,
            stride=stride,
            apply_last=True,
        )
        if not ok.all():
            assert first_start is not None  # set above: no start was given
            state.restart(~ok, first_start[0][~ok], first_start[1][~ok])
    converged, iterations, always_singular = _iterate(
        state, blocks_of, weight, max_iterations, tolerance, everything, history, record=record
    )
    # Pairs that did not converge, or converged to y-parallaxes far above
    # their a priori sigmas (a wrong local minimum, or gross errors), start
    # again from the other linear starts: J's near-vertical one, and the
    # essential matrix (large relative rotations, oblique photos; degenerate
    # over flat ground).  A converged pair keeps the solution of least misfit.
    misfit = record.misfit(pair, var, n_pairs)
    for make_start in (_similarity_start, _vertical_start, essential_start):
        retry = ~converged | (misfit > _DOUBTFUL_MISFIT)
        if not retry.any():
            break
        before = state.snapshot(), record.snapshot()
        rotation, base_dir = make_start(left, right, pair, n_pairs, starts)
        state.restart(retry, rotation[retry], base_dir[retry])
        ok, more, singular = _iterate(
            state, blocks_of, weight, max_iterations, tolerance, retry, history, record=record
        )
        new_misfit = record.misfit(pair, var, n_pairs)
        better = ok & (~converged | (new_misfit < misfit))
        back = retry & converged & ~better
        state.restore(back, before[0])
        record.restore(back, pair, before[1])
        iterations[better] = more[better]
        misfit = np.where(better, new_misfit, misfit)
        converged |= ok
        always_singular &= singular | ~retry
    robust_done = np.zeros(n_pairs, dtype=bool)
    if not converged.all():
        # Gross errors (swapped ids, mm-size blunders) can keep least squares from
        # converging at all: find start values by robust IRLS from the
        # near-vertical start, then finish with ordinary least squares.
        retry = ~converged
        rotation, base_dir = first_start or homography_start(left, right, pair, n_pairs, starts)
        state.restart(retry, rotation[retry], base_dir[retry])
        _iterate(state, blocks_of, weight, max_iterations, 1e-6, retry, history, robust=True)
        # Observations beyond 5 robust sigmas of the robust fit take no part in
        # the final least squares (their w-tests then fail and they are
        # reported and rejected by the caller's data snooping).
        weight = np.where(_gross_rows(state, blocks_of(retry), pair.shape[0]), 0.0, weight)
        ok, more, singular = _iterate(
            state, blocks_of, weight, max_iterations, tolerance, retry, history, record=record
        )
        iterations[retry] = more[retry]
        converged |= ok
        always_singular &= singular | ~retry
        robust_done = retry
    if not converged.all():
        _raise_not_oriented(
            ~converged, always_singular, left, right, pair, starts, counts, labels, max_iterations
        )
    if robust:
        # Gross errors that least squares converged through show as residuals
        # beyond 5 robust sigmas of their pair: re-solve those pairs from a
        # robust (IRLS, Cauchy) fit with no weight for such observations, so
        # that they cannot distort the orientation; the caller's tests then
        # find and name them.
        suspect = _suspect_pairs(record, pair, var, counts) & ~robust_done
        if suspect.any():
            _iterate(state, blocks_of, weight, _ROBUST_STEPS, 1e-6, suspect, history, robust=True)
            weight = np.where(_gross_rows(state, blocks_of(suspect), pair.shape[0]), 0.0, weight)
            ok, more, singular = _iterate(
                state,
                blocks_of,
                weight,
                max_iterations,
                tolerance,
                suspect,
                history,
                record=record,
            )
            if not ok[suspect].all():
                _raise_not_oriented(
                    suspect & ~ok,
                    singular,
                    left,
                    right,
                    pair,
                    starts,
                    counts,
                    labels,
                    max_iterations,
                )
            iterations[suspect] += more[suspect]
    rot_left, rot_right, relative = state.rotations()
    base = state.base_strip(rot_left)
    # With the base's image-x component 1, 1/|b| is the cosine between the base
    # and the left photo's image x axis.
    cos_along = 1.0 / np.linalg.norm(base, axis=1)
    weak = np.flatnonzero(~np.isfinite(cos_along) | (cos_along < 0.2))
    if weak.size:
        _raise_across(int(weak[0]), left, right, pair, labels)

    parallax_um, redundancy = record.parallax_um, record.redundancy
    dof = np.maximum(counts - MIN_POINTS_PER_PAIR, 1)
    sum_wq2 = np.add.reduceat(weight * parallax_um**2, starts)
    sigma0 = np.sqrt(sum_wq2 / dof / 2.0)
    sigma0[counts <= MIN_POINTS_PER_PAIR] = np.nan
    rms = np.sqrt(np.add.reduceat(parallax_um**2, starts) / counts)
    maxabs = np.maximum.reduceat(np.abs(parallax_um), starts)
    with np.errstate(invalid="ignore", divide="ignore"):
        w_stat = parallax_um / (1000.0 * np.sqrt(var * redundancy))
    w_stat[redundancy < 1e-6] = np.nan
    return RelativeOrientation(
        method=method,
        base=base,
        rotation_left=rot_left,
        rotation_right=rot_right,
        relative_rotation=relative,
        elements=state.elements(),
        iterations=iterations,
        n_points=counts.astype(np.intp),
        sigma0_um=sigma0,
        rms_parallax_um=rms,
        max_parallax_um=maxabs,
        pair=pair,
        parallax_um=parallax_um,
        history=np.asarray(history),
        redundancy_numbers=redundancy,
        w_statistic=w_stat,
    )


def _raise_not_oriented(
    failed: BoolArray,
    singular: BoolArray,
    left: FloatArray,
    right: FloatArray,
    pair: IntArray,
    starts: IntArray,
    counts: IntArray,
    labels: list[str] | None,
    max_iterations: int,
) -> None:
    """Say why the pairs in ``failed`` could not be oriented (first one named).

    Singular normal equations at the end of every attempt mean the points do
    not determine the orientation: the message gives the spread of the
    pair's points across and along the flight and how nearly they lie on a
    line.  Otherwise no start converged: the message gives the pair's RMS
    y-parallax at its best and points at gross errors.
    """
    bad = np.flatnonzero(failed)
    m = int(bad[0])
    rows = slice(int(starts[m]), int(starts[m]) + int(counts[m]))
    uv = left[rows, :2] * (left[rows, 2:3] / left[rows, 2:3].mean())
    extent = np.ptp(uv, axis=0)
    centred = uv - uv.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False) if centred.shape[0] >= 2 else np.zeros(2)
    others = f" (and {bad.size - 1} more pair(s))" if bad.size > 1 else ""
    layout = (
        f"its {int(counts[m])} points span {extent[1]:.2f} mm across the flight and "
        f"{extent[0]:.2f} mm along it on the left photo"
    )
    if singular[m]:
        line = " and lie nearly on one line" if sv[1] < 1e-2 * max(sv[0], 1e-300) else ""
        raise GeometryError(
            f"{_name(labels, m)}{others}: the points do not determine the relative "
            f"orientation (singular normal equations: {layout}{line}; points collinear, in "
            "one plane with the base, or too close together)"
        )
    raise ConvergenceError(
        f"relative orientation did not converge in {max_iterations} iterations for "
        f"{_name(labels, m)}{others} from any start ({layout}): check the point ids and "
        "image coordinates of this pair (a mismatched point, a wrong photo)"
    )


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


