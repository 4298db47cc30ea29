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

from collections.abc import Sequence
from typing import NamedTuple, NoReturn

import numpy as np

from .._stats import exact_median
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
from .relative_iterate import (
    MIN_POINTS_PER_PAIR,
    _Blocks,
    _constant_or_none,
    _gross_rows,
    _iterate,
    _Record,
    _suspect_pairs,
)
from .relative_starts import (
    SimilarityStart,
    _similarity_start,
    _vertical_start,
    essential_start,
    homography_start,
    similarity_start,
)
from .relative_state import (
    _BaseState,
    _DependentState,
    _segment_starts,
    _State,
    chain_rotations,
)

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

_ROBUST_STEPS = 10  # IRLS steps of the robust start
# RMS y-parallax (in a priori sigmas) above which a converged pair is tried
# from the other starts too (a wrong local minimum, or gross errors)
_DOUBTFUL_MISFIT = 3.0
# Points whose spread across their best-fitting image line is below this
# fraction of the spread along it are collinear (_check_not_collinear).
COLLINEAR_RATIO = 1e-2
_SUBSAMPLE_POINTS = 40  # points per pair in the first iterations


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

    The strategy reads in order: the first start (or ``start``), least
    squares, the other starts for the pairs that fail or fit badly, the
    robust recovery of pairs that do not converge, and with ``robust`` the
    robust re-solution of suspect pairs; each is a pass of ``_Run`` over
    one state, the iteration itself is in :mod:`.relative_iterate`.

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
    rows = _Rows.of(left, right, pair, n_pairs, labels, (sigma_left, sigma_right))
    method = RelativeOrientationMethod(method)
    first = np.eye(3) if rotation_first is None else np.asarray(rotation_first, np.float64)
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
    run = _Run(rows, state, max_iterations, tolerance, _Record(rows.pair.shape[0], n_pairs))
    first_start = None if start is not None else run.first_pass()
    converged, iterations, always_singular = run.iterate(np.ones(n_pairs, dtype=bool), record=True)
    run.other_starts(converged, iterations, always_singular)
    robust_done = ~converged
    if robust_done.any():
        converged |= run.recover(robust_done, first_start, iterations, always_singular)
    if not converged.all():
        run.fail(~converged, always_singular)
    if robust:
        run.resolve_suspects(iterations, robust_done)
    return run.orientation(method, iterations)


class _Rows(NamedTuple):
    """The checked observations of :func:`relative_orientation`: image
    vectors, pair of each row, its rows per pair and where they start, the
    variance of each y-parallax (mm²) and its weight (1 at the median)."""

    left: FloatArray
    right: FloatArray
    pair: IntArray
    counts: IntArray
    starts: IntArray
    var: FloatArray
    weight: FloatArray
    labels: list[str] | None

    @classmethod
    def of(
        cls,
        left: ArrayLike,
        right: ArrayLike,
        pair: ArrayLike,
        n_pairs: int,
        labels: list[str] | None,
        sigmas: tuple[ArrayLike | float, ArrayLike | float],
    ) -> _Rows:
        left = np.asarray(left, dtype=np.float64)
        right = np.asarray(right, dtype=np.float64)
        pair = np.asarray(pair, dtype=np.intp)
        if left.ndim != 2 or left.shape[1] != 3 or right.shape != left.shape:
            raise ValueError(
                f"Expected left and right to have shape (n, 3), got {left.shape} and "
                f"{right.shape}"
            )
        if pair.shape != (left.shape[0],):
            raise ValueError(f"Expected pair to have shape ({left.shape[0]},), got {pair.shape}")
        if pair.size and np.any(np.diff(pair) < 0):
            raise ValueError("Expected pair indices to be sorted (non-decreasing)")
        counts = _check_pairs(pair, n_pairs, labels)
        starts = _segment_starts(pair, n_pairs)
        _check_not_collinear(left, pair, counts, labels)
        var = (
            np.broadcast_to(np.asarray(sigmas[0], np.float64), pair.shape) ** 2
            + np.broadcast_to(np.asarray(sigmas[1], np.float64), pair.shape) ** 2
        )
        weight = 2.0 * (exact_median(var) / 2.0) / var
        return cls(left, right, pair, counts, starts, var, weight, labels)


class _Run:
    """One orientation of the pairs: the passes of :func:`relative_orientation`
    over one state, each an :func:`_iterate` of some pairs."""

    def __init__(
        self, rows: _Rows, state: _State, max_iterations: int, tolerance: float, record: _Record
    ) -> None:
        self.rows, self.state, self.record = rows, state, record
        self.max_iterations, self.tolerance = max_iterations, tolerance
        self.weight = rows.weight
        self.history: list[float] = []
        self.n_pairs = rows.counts.shape[0]
        self._left_t = np.ascontiguousarray(rows.left.T)
        self._right_t = np.ascontiguousarray(rows.right.T)
        self._constant_z = (
            _constant_or_none(self._left_t[2]),
            _constant_or_none(self._right_t[2]),
        )

    def blocks_of(self, mask: BoolArray, stride: IntArray | None = None) -> _Blocks:
        return _Blocks(
            self._left_t,
            self._right_t,
            self.rows.starts,
            self.rows.counts,
            np.flatnonzero(mask),
            stride,
            self._constant_z,
        )

    def iterate(
        self,
        active: BoolArray,
        *,
        record: bool = False,
        robust: bool = False,
        max_iterations: int | None = None,
        tolerance: float | None = None,
    ) -> tuple[BoolArray, IntArray, BoolArray]:
        """:func:`_iterate` of the ``active`` pairs (``record``: least
        squares to the end, residuals kept)."""
        return _iterate(
            self.state,
            self.blocks_of,
            self.weight,
            self.max_iterations if max_iterations is None else max_iterations,
            self.tolerance if tolerance is None else tolerance,
            active,
            self.history,
            robust=robust,
            record=self.record if record else None,
        )

    def first_pass(self) -> tuple[FloatArray, FloatArray]:
        """The first start for every pair, and the first steps on a subsample.

        The relative rotation and the base from the homography of the two
        images: J's near-vertical start (Q = I, b = (1, 0, 0)) is far off for
        the swings and tilts of drone photos (relative kappa of 10-15 deg,
        tilts of 5-8 deg against a base of 0.15 of the height).  The first
        steps only have to reach the region of quadratic convergence: they
        are taken on a spread subsample of every large pair, then finished on
        all points.
        """
        r = self.rows
        everything = np.ones(self.n_pairs, dtype=bool)
        first_start = homography_start(r.left, r.right, r.pair, self.n_pairs, r.starts)
        self.state.restart(everything, *first_start)
        stride = np.maximum(r.counts // _SUBSAMPLE_POINTS, 1)
        if (stride > 1).any():
            ok, *_ = _iterate(
                self.state,
                self.blocks_of,
                self.weight,
                self.max_iterations,
                1e-6,
                everything,
                self.history,
                stride=stride,
                apply_last=True,
            )
            if not ok.all():
                self.state.restart(~ok, first_start[0][~ok], first_start[1][~ok])
        return first_start

    def other_starts(
        self, converged: BoolArray, iterations: IntArray, always_singular: BoolArray
    ) -> None:
        """Pairs that did not converge, or converged to y-parallaxes far above
        their a priori sigmas (a wrong local minimum, or gross errors), start
        again from the other linear starts: J's near-vertical one, and the
        essential matrix (large relative rotations, oblique photos; degenerate
        over flat ground).  A converged pair keeps the solution of least
        misfit.  Updates the three arrays in place."""
        r, record = self.rows, self.record
        misfit = record.misfit(r.pair, r.var, self.n_pairs)
        for make_start in (_similarity_start, _vertical_start, essential_start):
            retry = ~converged | (misfit > _DOUBTFUL_MISFIT)
            if not retry.any():
                break
            before = self.state.snapshot(), record.snapshot()
            rotation, base_dir = make_start(r.left, r.right, r.pair, self.n_pairs, r.starts)
            self.state.restart(retry, rotation[retry], base_dir[retry])
            ok, more, singular = self.iterate(retry, record=True)
            new_misfit = record.misfit(r.pair, r.var, self.n_pairs)
            better = ok & (~converged | (new_misfit < misfit))
            back = retry & converged & ~better
            self.state.restore(back, before[0])
            record.restore(back, r.pair, before[1])
            iterations[better] = more[better]
            misfit = np.where(better, new_misfit, misfit)
            converged |= ok
            always_singular &= singular | ~retry

    def recover(
        self,
        retry: BoolArray,
        first_start: tuple[FloatArray, FloatArray] | None,
        iterations: IntArray,
        always_singular: BoolArray,
    ) -> BoolArray:
        """Gross errors (swapped ids, mm-size blunders) can keep least squares
        from converging at all: start values for the pairs ``retry`` by robust
        IRLS from the first start, then ordinary least squares to the end, in
        which the observations beyond 5 robust sigmas of the robust fit take
        no part (their w-tests then fail and the caller's data snooping
        reports and rejects them).  Returns the pairs that converged."""
        r = self.rows
        rotation, base_dir = first_start or homography_start(
            r.left, r.right, r.pair, self.n_pairs, r.starts
        )
        self.state.restart(retry, rotation[retry], base_dir[retry])
        self.iterate(retry, robust=True, tolerance=1e-6)
        gross = _gross_rows(self.state, self.blocks_of(retry), r.pair.shape[0])
        self.weight = np.where(gross, 0.0, self.weight)
        ok, more, singular = self.iterate(retry, record=True)
        iterations[retry] = more[retry]
        always_singular &= singular | ~retry
        return ok

    def resolve_suspects(self, iterations: IntArray, robust_done: BoolArray) -> None:
        """Gross errors that least squares converged through show as
        residuals beyond 5 robust sigmas of their pair: those pairs are
        solved again from a robust (IRLS, Cauchy) fit with no weight for such
        observations, so that they cannot distort the orientation; the
        caller's tests then find and name them."""
        r = self.rows
        suspect = _suspect_pairs(self.record, r.pair, r.var, r.counts) & ~robust_done
        if not suspect.any():
            return
        self.iterate(suspect, robust=True, max_iterations=_ROBUST_STEPS, tolerance=1e-6)
        gross = _gross_rows(self.state, self.blocks_of(suspect), r.pair.shape[0])
        self.weight = np.where(gross, 0.0, self.weight)
        ok, more, singular = self.iterate(suspect, record=True)
        if not ok[suspect].all():
            self.fail(suspect & ~ok, singular)
        iterations[suspect] += more[suspect]

    def fail(self, failed: BoolArray, singular: BoolArray) -> None:
        r = self.rows
        _raise_not_oriented(
            failed,
            singular,
            r.left,
            r.right,
            r.pair,
            r.starts,
            r.counts,
            r.labels,
            self.max_iterations,
        )

    def orientation(
        self, method: RelativeOrientationMethod, iterations: IntArray
    ) -> RelativeOrientation:
        """The result: the rotations and bases, and each pair's statistics."""
        r, state = self.rows, self.state
        rot_left, rot_right, relative = state.rotations()
        base = state.base_strip(rot_left)
        # With the base's image-x component 1, 1/|b| is the cosine between the
        # base and the left photo's image x axis.
        cos_along = 1.0 / np.linalg.norm(base, axis=1)
        weak = np.flatnonzero(~np.isfinite(cos_along) | (cos_along < 0.2))
        if weak.size:
            _raise_across(int(weak[0]), r.left, r.right, r.pair, r.labels)
        parallax_um, redundancy = self.record.parallax_um, self.record.redundancy
        dof = np.maximum(r.counts - MIN_POINTS_PER_PAIR, 1)
        sum_wq2 = np.add.reduceat(self.weight * parallax_um**2, r.starts)
        sigma0 = np.sqrt(sum_wq2 / dof / 2.0)
        sigma0[r.counts <= MIN_POINTS_PER_PAIR] = np.nan
        with np.errstate(invalid="ignore", divide="ignore"):
            w_stat = parallax_um / (1000.0 * np.sqrt(r.var * redundancy))
        w_stat[redundancy < 1e-6] = np.nan
        return RelativeOrientation(
            method=method,
            base=base,
            rotation_left=rot_left,
            rotation_right=rot_right,
            relative_rotation=relative,
            elements=state.elements(),
            iterations=iterations,
            n_points=r.counts.astype(np.intp),
            sigma0_um=sigma0,
            rms_parallax_um=np.sqrt(np.add.reduceat(parallax_um**2, r.starts) / r.counts),
            max_parallax_um=np.maximum.reduceat(np.abs(parallax_um), r.starts),
            pair=r.pair,
            parallax_um=parallax_um,
            history=np.asarray(self.history),
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
