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

All pairs of a strip are solved together, one Gauss-Newton step for every pair
per iteration, on arrays that hold the points of all pairs; the strip's
sequential dependence (the right photo of pair m is the left photo of pair
m + 1) enters through the chain of rotations, recomputed at each iteration
from the pairs' relative rotations.  At convergence every pair satisfies its
own normal equations with the left rotation taken from the previous pair,
which is exactly the sequential solution of J, obtained without a Python loop
over the pairs' points.

Conventions: image vectors ``(x, y, -c)`` in mm; rotations map image vectors to
the strip system (``l = R @ l_image``); the residual y-parallax is reported at
image scale in micrometres.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np

from ._typing import ArrayLike, FloatArray, IntArray
from .errors import ConvergenceError, GeometryError
from .rotation import (
    cardan_from_matrix,
    matrix_from_cardan,
    matrix_from_schut,
    schut_from_matrix,
)

__all__ = [
    "MIN_POINTS_PER_PAIR",
    "RelativeOrientation",
    "RelativeOrientationMethod",
    "chain_rotations",
    "essential_start",
    "relative_orientation",
]

MIN_POINTS_PER_PAIR = 5
_J = np.array([0.0, 1.0, 0.0])
_EX = np.array([1.0, 0.0, 0.0])
_EY = np.array([0.0, 1.0, 0.0])
_EZ = np.array([0.0, 0.0, 1.0])
# J(9) fixed: the Schut parameters of the correcting rotation are half of the
# rotation vector a (phi = 2 (a, b, c)); the printed factor 1 converges only
# linearly (tests patch this to show it).
_SCHUT_FACTOR = 0.5
_ROBUST_STEPS = 10  # IRLS steps of the robust start


class RelativeOrientationMethod(str, Enum):
    """Formulation of the relative orientation (method.md §3 and §3.1)."""

    DEPENDENT = "dependent"
    BASE = "base"


@dataclass(frozen=True)
class RelativeOrientation:
    """Relative orientation of a chain of pairs.

    Pair m is formed by photos m and m + 1 of the chain.  Arrays with a
    leading ``n_pairs`` axis hold one row per pair; arrays with a leading
    ``n`` axis hold one row per point measured on both photos of a pair (all
    pairs concatenated, sorted by pair).

    Attributes
    ----------
    method : RelativeOrientationMethod
    base : ndarray, shape (n_pairs, 3)
        Base vector in the strip system, normalised so that its component
        along the left photo's image x axis is 1 (J(5)'s ``b_x = 1`` for
        near-vertical photos of a strip along x; valid for any heading).
    rotation_left, rotation_right : ndarray, shape (n_pairs, 3, 3)
        Image -> strip rotations of the two photos; ``rotation_left[m + 1]``
        equals ``rotation_right[m]``.
    relative_rotation : ndarray, shape (n_pairs, 3, 3)
        ``rotation_left.T @ rotation_right``: right image -> left image.
    elements : ndarray, shape (n_pairs, 5)
        The five elements of the formulation: ``(b_y, b_z, a, b, c)`` with
        the base components along the left photo's image y and z axes and the
        Schut parameters of the relative rotation for ``"dependent"``;
        ``(alpha1, chi1, alpha2, omega2, chi2)`` in radians, the base-system
        angles of B(125)-(135), for ``"base"``.
    iterations : ndarray of int, shape (n_pairs,)
        Gauss-Newton iterations until the pair's corrections fell below the
        tolerance.
    n_points : ndarray of int, shape (n_pairs,)
    sigma0_um : ndarray, shape (n_pairs,)
        A posteriori standard deviation of one image coordinate, from the
        residual y-parallaxes, in µm at image scale (a y-parallax combines two
        image coordinates, hence the factor 1/√2 against ``rms_parallax_um``).
    rms_parallax_um, max_parallax_um : ndarray, shape (n_pairs,)
        RMS and largest absolute residual y-parallax at image scale, µm.
    pair : ndarray of int, shape (n,)
        Pair index of each point row.
    parallax_um : ndarray, shape (n,)
        Residual y-parallax of each point at the left photo's image scale, µm.
    history : ndarray, shape (iterations + 1,)
        Largest absolute y-parallax over all pairs (µm) at the start and after
        each iteration; shows the convergence rate.
    redundancy_numbers : ndarray, shape (n,)
        Diagonal of ``I − A (AᵀPA)⁻¹ AᵀP`` for each y-parallax (0..1; they
        sum to n − 5 per pair): the share of a blunder that shows in its own
        residual.
    w_statistic : ndarray, shape (n,)
        Baarda's w-test of each y-parallax with the a priori sigmas:
        ``q / sqrt((sigma_left² + sigma_right²) · r)`` at image scale (NaN
        where r ≈ 0).
    """

    method: RelativeOrientationMethod
    base: FloatArray
    rotation_left: FloatArray
    rotation_right: FloatArray
    relative_rotation: FloatArray
    elements: FloatArray
    iterations: IntArray
    n_points: IntArray
    sigma0_um: FloatArray
    rms_parallax_um: FloatArray
    max_parallax_um: FloatArray
    pair: IntArray
    parallax_um: FloatArray
    history: FloatArray
    redundancy_numbers: FloatArray | None = None
    w_statistic: FloatArray | None = None

    @property
    def n_pairs(self) -> int:
        return self.base.shape[0]


def chain_rotations(first: ArrayLike, relative: ArrayLike) -> FloatArray:
    """Rotations of the photos of a chain from the pairs' relative rotations.

    Parameters
    ----------
    first : array_like, shape (3, 3)
        Image -> strip rotation of the first photo.
    relative : array_like, shape (n_pairs, 3, 3)
        Right image -> left image rotation of each pair.

    Returns
    -------
    ndarray, shape (n_pairs + 1, 3, 3)
        ``R[0] = first``, ``R[m + 1] = R[m] @ relative[m]``.
    """
    first = np.asarray(first, dtype=np.float64)
    relative = np.asarray(relative, dtype=np.float64)
    out = np.empty((relative.shape[0] + 1, 3, 3))
    out[0] = first
    # Sequential by nature; 3x3 products only, cheap even for thousands of photos.
    for m in range(relative.shape[0]):
        out[m + 1] = out[m] @ relative[m]
    return out


def _segment_starts(pair: IntArray, n_pairs: int) -> IntArray:
    return np.searchsorted(pair, np.arange(n_pairs)).astype(np.intp)


def _check_pairs(pair: IntArray, n_pairs: int, labels: list[str] | None) -> IntArray:
    counts = np.bincount(pair, minlength=n_pairs)
    few = np.flatnonzero(counts < MIN_POINTS_PER_PAIR)
    if few.size:
        m = int(few[0])
        name = labels[m] if labels else f"pair {m}"
        raise GeometryError(
            f"{name}: {counts[m]} point(s) measured on both photos; relative orientation "
            f"needs at least {MIN_POINTS_PER_PAIR}"
        )
    return counts


def _solve_normals(
    rows: FloatArray, rhs: FloatArray, weight: FloatArray, starts: IntArray
) -> tuple[FloatArray, np.ndarray]:
    """Solve the per-pair normal equations of stacked design rows.

    rows (n, u), rhs (n,), weight (n,) -> corrections (n_pairs, u) and a mask
    of pairs whose (equilibrated) normal matrix is singular or not finite.
    """
    wa = rows * weight[:, None]
    normal = np.add.reduceat(wa[:, :, None] * rows[:, None, :], starts, axis=0)
    gradient = np.add.reduceat(wa * rhs[:, None], starts, axis=0)
    finite = np.isfinite(normal).all(axis=(1, 2)) & np.isfinite(gradient).all(axis=1)
    normal[~finite] = np.eye(normal.shape[1])
    gradient[~finite] = 0.0
    scale = 1.0 / np.sqrt(np.maximum(np.einsum("mii->mi", normal), 1e-300))
    scaled = normal * scale[:, :, None] * scale[:, None, :]
    eig = np.linalg.eigvalsh(scaled)
    singular = ~finite | (eig[:, 0] < 1e-10 * eig[:, -1])
    scaled[singular] = np.eye(normal.shape[1])
    sol = np.linalg.solve(scaled, (gradient * scale)[:, :, None])[:, :, 0] * scale
    sol[singular] = 0.0
    return sol, singular


def _name(labels: list[str] | None, m: int) -> str:
    return labels[m] if labels else f"pair {m}"


def _segment_median(values: FloatArray, pair: IntArray, starts: IntArray) -> FloatArray:
    """Median of ``values`` within each pair (rows sorted by pair)."""
    counts = np.diff(np.r_[starts, pair.shape[0]])
    order = np.lexsort((values, pair))
    return values[order[starts + counts // 2]]


def _cauchy_weights(state, pair, starts) -> FloatArray:
    """Iteratively reweighted least squares (Cauchy, c = 2.385 robust sigmas per pair).

    Used only to find start values when a pair with gross errors does not
    converge; the final solution and its tests are ordinary least squares.
    """
    q = np.abs(state.parallax_image_mm())
    q = np.where(np.isfinite(q), q, np.inf)
    scale = 1.4826 * _segment_median(q, pair, starts)
    scale = np.maximum(scale, 1e-6)[pair]
    return 1.0 / (1.0 + (q / (2.385 * scale)) ** 2)


def _gross(state, pair, starts) -> np.ndarray:
    """Rows whose y-parallax exceeds 5 robust sigmas (1.4826 MAD) of their pair."""
    q = np.abs(state.parallax_image_mm())
    q = np.where(np.isfinite(q), q, np.inf)
    scale = 1.4826 * _segment_median(q, pair, starts)
    return ~(q <= 5.0 * np.maximum(scale, 1e-6)[pair])


def _iterate(state, weight, starts, max_iterations, tolerance, active, history, robust=False):
    """Gauss-Newton steps for the active pairs until their corrections vanish.

    Returns (converged mask, iterations per pair, singular-at-start mask).
    Pairs that diverge (non-finite or huge corrections) are frozen and
    reported as not converged.  With ``robust`` the weights are multiplied by
    Cauchy weights of the current residuals at every step (IRLS).
    """
    n_pairs = active.shape[0]
    done = ~active
    failed = np.zeros(n_pairs, dtype=bool)
    iterations = np.zeros(n_pairs, dtype=np.intp)
    singular_start = np.zeros(n_pairs, dtype=bool)
    for it in range(1, max_iterations + 1):
        rows, q = state.design()
        w = weight * _cauchy_weights(state, state.pair, starts) if robust else weight
        corr, singular = _solve_normals(rows, -q, w, starts)
        if it == 1:
            singular_start = singular & active
        size = np.max(np.abs(corr), axis=1)
        failed |= active & (singular | ~np.isfinite(size) | (size > 1.0))
        corr[done | failed] = 0.0
        state.update(corr)
        history.append(state.max_parallax_um(~failed))
        newly = ~done & ~failed & (size < tolerance)
        iterations[newly] = it
        done |= newly
        if (done | failed).all():
            break
    return done & ~failed, iterations, singular_start


def relative_orientation(
    left: ArrayLike,
    right: ArrayLike,
    pair: ArrayLike,
    n_pairs: int,
    *,
    method: RelativeOrientationMethod | str = RelativeOrientationMethod.DEPENDENT,
    rotation_first: ArrayLike | None = None,
    sigma_left: ArrayLike | float = 0.005,
    sigma_right: ArrayLike | float = 0.005,
    max_iterations: int = 30,
    tolerance: float = 1e-11,
    labels: list[str] | None = None,
    robust: bool = False,
) -> RelativeOrientation:
    """Orient a chain of pairs by the y-parallax equation.

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
        Convergence limit on the corrections (radians and base units).
    labels : list of str, optional
        Names of the pairs for messages, e.g. ``"pair 1201-1202"``.
    robust : bool
        Start with an iteratively reweighted (Cauchy) solution and give y-
        parallaxes beyond 5 robust sigmas of their pair no weight in the final
        least squares, so that gross errors cannot distort it; their residuals
        and w-tests are still returned for the caller to report.

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
    ``p = R_p p_image`` and ``j = (0, 1, 0)``; its linearisation, the fixed
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
    var = (
        np.broadcast_to(np.asarray(sigma_left, np.float64), pair.shape) ** 2
        + np.broadcast_to(np.asarray(sigma_right, np.float64), pair.shape) ** 2
    )
    sigma_ref2 = float(np.median(var)) / 2.0
    weight = 2.0 * sigma_ref2 / var

    if method is RelativeOrientationMethod.DEPENDENT:
        state = _DependentState(left, right, pair, n_pairs, first)
    else:
        state = _BaseState(left, right, pair, n_pairs, first)

    history = [state.max_parallax_um()]
    active = np.ones(n_pairs, dtype=bool)
    if robust:
        # Robust start (IRLS, Cauchy) and no weight for gross errors beyond 5
        # robust sigmas; the tests of the caller then find and name them.
        # Start values only: a few steps at a loose tolerance (IRLS weights keep
        # moving at the noise level and would never meet the final tolerance).
        _iterate(state, weight, starts, _ROBUST_STEPS, 1e-6, active, history, robust=True)
        weight = np.where(_gross(state, pair, starts), 0.0, weight)
    converged, iterations, singular_first = _iterate(
        state, weight, starts, max_iterations, tolerance, active, history
    )
    if not converged.all():
        # Large relative rotations (drone pairs, oblique photos): restart the
        # pairs that failed from the linear (essential-matrix) solution.
        retry = ~converged
        rotation, base_dir = essential_start(left, right, pair, n_pairs, starts)
        state.restart(retry, rotation[retry], base_dir[retry])
        ok, more, singular = _iterate(
            state, weight, starts, max_iterations, tolerance, retry, history
        )
        degenerate = singular | (singular_first & ~ok)
        if degenerate.any():
            m = int(np.flatnonzero(degenerate)[0])
            raise GeometryError(
                f"{_name(labels, m)}: the points do not determine the relative orientation "
                "(singular normal equations: points collinear, in one plane with the base, "
                "or too close together)"
            )
        iterations[retry] = more[retry]
        converged |= ok
    if not converged.all():
        # Gross errors (swapped ids, mm-size blunders) can keep least squares from
        # converging at all: find start values by robust IRLS from the
        # near-vertical start, then finish with ordinary least squares.
        retry = ~converged
        identity = np.broadcast_to(np.eye(3), (int(retry.sum()), 3, 3))
        state.restart(retry, identity, np.tile(_EX, (int(retry.sum()), 1)))
        _iterate(state, weight, starts, max_iterations, 1e-6, retry, history, robust=True)
        # Observations beyond 5 robust sigmas of the robust fit take no part in
        # the final least squares (their w-tests then fail and they are
        # reported and rejected by the caller's data snooping).
        weight = np.where(retry[pair] & _gross(state, pair, starts), 0.0, weight)
        ok, more, _ = _iterate(state, weight, starts, max_iterations, tolerance, retry, history)
        iterations[retry] = more[retry]
        converged |= ok
    if not converged.all():
        bad = np.flatnonzero(~converged)
        names = ", ".join(_name(labels, int(m)) for m in bad[:5])
        raise ConvergenceError(
            f"relative orientation did not converge in {max_iterations} iterations for {names}"
            " (check point ids and image coordinates of these pairs)"
        )
    base = state.base_strip()
    # With the base's image-x component 1, 1/|b| is the cosine between the base
    # and the left photo's image x axis.
    cos_along = 1.0 / np.linalg.norm(base, axis=1)
    weak = np.flatnonzero(~np.isfinite(cos_along) | (cos_along < 0.2))
    if weak.size:
        m = int(weak[0])
        raise GeometryError(
            f"{_name(labels, m)}: the base runs across the image x axis (b = "
            f"{np.array2string(base[m], precision=3)}); image x must point "
            "along the flight (turn the image axes)"
        )

    parallax_um = state.parallax_image_mm() * 1000.0
    dof = np.maximum(counts - MIN_POINTS_PER_PAIR, 1)
    sum_wq2 = np.add.reduceat(weight * parallax_um**2, starts)
    sigma0 = np.sqrt(sum_wq2 / dof / 2.0)
    sigma0[counts <= MIN_POINTS_PER_PAIR] = np.nan
    rms = np.sqrt(np.add.reduceat(parallax_um**2, starts) / counts)
    maxabs = np.maximum.reduceat(np.abs(parallax_um), starts)
    rot_left, rot_right, relative = state.rotations()
    rows, _ = state.design()
    wa = rows * weight[:, None]
    normal = np.add.reduceat(wa[:, :, None] * rows[:, None, :], starts, axis=0)
    n_inv = np.linalg.inv(normal)
    leverage = weight * np.einsum("ni,nij,nj->n", rows, n_inv[pair], rows)
    redundancy = np.clip(1.0 - leverage, 0.0, 1.0)
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


def _parallax(b: FloatArray, l: FloatArray, p: FloatArray, j: FloatArray):
    """q = b·(l×p)/(j·(l×p)) row-wise, with l×p and D."""
    lxp = np.cross(l, p)
    d = np.einsum("ij,ij->i", j, lxp) if j.ndim == 2 else lxp @ j
    q = np.einsum("ij,ij->i", b, lxp) / d
    return q, lxp, d


def _image_scale_parallax(q, b, l, p, j, lxp, d):
    """Convert a model-space y-parallax to mm at the left photo's image scale.

    The point lies at ``k_l · l`` from the left centre (J(12)); a model length
    at the point corresponds to ``length / k_l`` mm on the left image.
    """
    bxp = np.cross(b, p)
    jj = j if j.ndim == 2 else np.broadcast_to(j, bxp.shape)
    k = np.einsum("ij,ij->i", bxp, jj) / d
    return q / k


class _DependentState:
    """Unknowns of J's dependent pairs: relative rotation Q and base direction in
    the left image frame; the strip-frame values follow from the chain."""

    def __init__(self, left, right, pair, n_pairs, first):
        self.lz, self.pz, self.pair, self.first = left, right, pair, first
        self.relative = np.broadcast_to(np.eye(3), (n_pairs, 3, 3)).copy()
        self.beta = np.broadcast_to(_EX, (n_pairs, 3)).copy()  # base in the left image frame
        self._refresh()

    def _refresh(self):
        chain = chain_rotations(self.first, self.relative)
        self.r_left = chain[:-1]
        self.r_right = chain[1:]
        # Gauge: the base's component along the left photo's image x axis is 1
        # (J's b_x = 1 for the first pair of a strip along the strip x axis, and
        # valid for any given first orientation and heading).
        self.beta = self.beta / self.beta[:, :1]
        self.b = np.einsum("mij,mj->mi", self.r_left, self.beta)
        rl = self.r_left[self.pair]
        self.l = np.einsum("nij,nj->ni", rl, self.lz)
        self.p = np.einsum("nij,nj->ni", self.r_right[self.pair], self.pz)
        self.q, self.lxp, self.d = _parallax(self.b[self.pair], self.l, self.p, _J)

    def design(self):
        bn = self.b[self.pair]
        u = bn - self.q[:, None] * _J
        rot = np.cross(self.p, np.cross(u, self.l)) / self.d[:, None]
        # base corrections along the left photo's image y and z axes
        gb = self.lxp / self.d[:, None]
        r_l = self.r_left[self.pair]
        rows = np.column_stack(
            [np.einsum("ni,ni->n", gb, r_l[:, :, 1]), np.einsum("ni,ni->n", gb, r_l[:, :, 2]), rot]
        )
        return rows, self.q

    def restart(self, mask, relative, base_dir):
        self.relative[mask] = relative
        self.beta[mask] = base_dir
        self._refresh()

    def update(self, corr):
        # Correct in the left image frame: R_l^T R_schut(a) R_l = R_schut(R_l^T a)
        # exactly, and only the corrections are rotated.  Writing the new relative
        # rotation as R_l^T R' R_r would feed the round-off of R_l^T R_l != I back
        # into every later pair of the chain and grow from one iteration to the next.
        a_left = np.einsum("mji,mj->mi", self.r_left, corr[:, 2:])
        self.relative = matrix_from_schut(_SCHUT_FACTOR * a_left) @ self.relative
        self.beta = self.beta.copy()
        self.beta[:, 1:] += corr[:, :2]
        self._refresh()

    def parallax_image_mm(self):
        return _image_scale_parallax(
            self.q, self.b[self.pair], self.l, self.p, _J, self.lxp, self.d
        )

    def max_parallax_um(self, keep_pairs=None):
        q = np.abs(self.parallax_image_mm())
        if keep_pairs is not None:
            q = q[keep_pairs[self.pair]]
        q = q[np.isfinite(q)]
        return float(np.max(q)) * 1000.0 if q.size else float("nan")

    def base_strip(self):
        return self.b.copy()

    def rotations(self):
        return self.r_left.copy(), self.r_right.copy(), self.relative.copy()

    def elements(self):
        return np.column_stack([self.beta[:, 1:], schut_from_matrix(self.relative)])


class _BaseState:
    """Unknowns of B's base system: alpha'1, chi'1 of the left photo and the right
    photo's rotation (alpha'2, omega'2, chi'2) relative to the base system, whose
    x axis is the base.  Independent of the chain; the strip values follow from
    A_tau_nu = R_left · A(alpha'1, 0, chi'1)^T, B(126)-(136)."""

    def __init__(self, left, right, pair, n_pairs, first):
        self.lz, self.pz, self.pair, self.first = left, right, pair, first
        self.angles_left = np.zeros((n_pairs, 2))  # alpha'1, chi'1
        self.r_right_base = np.broadcast_to(np.eye(3), (n_pairs, 3, 3)).copy()
        self._refresh()

    def _left_base(self):
        a = np.zeros((self.angles_left.shape[0], 3))
        a[:, 0] = self.angles_left[:, 0]
        a[:, 2] = self.angles_left[:, 1]
        return matrix_from_cardan(a)

    def _refresh(self):
        self.l_base = self._left_base()
        self.l = np.einsum("nij,nj->ni", self.l_base[self.pair], self.lz)
        self.p = np.einsum("nij,nj->ni", self.r_right_base[self.pair], self.pz)
        self.bx = np.broadcast_to(_EX, self.l.shape)
        self.q, self.lxp, self.d = _parallax(self.bx, self.l, self.p, _EY)

    def design(self):
        u = self.bx - self.q[:, None] * _EY
        g_left = np.cross(self.l, np.cross(self.p, u)) / self.d[:, None]
        g_right = np.cross(self.p, np.cross(u, self.l)) / self.d[:, None]
        ez_left = self.l_base[self.pair][:, :, 2]  # image z axis of the left photo
        rows = np.column_stack([-g_left[:, 1], np.einsum("ij,ij->i", g_left, ez_left), g_right])
        return rows, self.q

    def restart(self, mask, relative, base_dir):
        # Base system: x' along the base, z' in the principal plane of the left
        # photo (B §125), so the left photo needs no omega'.
        x = base_dir / np.linalg.norm(base_dir, axis=1, keepdims=True)
        z = _EZ - x[:, 2:3] * x
        z /= np.linalg.norm(z, axis=1, keepdims=True)
        y = np.cross(z, x)
        left_base = np.stack([x, y, z], axis=1)  # rows: base axes in the left image
        angles = cardan_from_matrix(left_base)
        self.angles_left[mask] = angles[:, [0, 2]]
        self.r_right_base[mask] = self._left_base()[mask] @ relative
        self._refresh()

    def update(self, corr):
        self.angles_left += corr[:, :2]
        self.r_right_base = matrix_from_schut(_SCHUT_FACTOR * corr[:, 2:]) @ self.r_right_base
        self._refresh()

    def parallax_image_mm(self):
        return _image_scale_parallax(self.q, self.bx, self.l, self.p, _EY, self.lxp, self.d)

    def max_parallax_um(self, keep_pairs=None):
        q = np.abs(self.parallax_image_mm())
        if keep_pairs is not None:
            q = q[keep_pairs[self.pair]]
        q = q[np.isfinite(q)]
        return float(np.max(q)) * 1000.0 if q.size else float("nan")

    def rotations(self):
        relative = np.swapaxes(self.l_base, 1, 2) @ self.r_right_base
        chain = chain_rotations(self.first, relative)
        return chain[:-1].copy(), chain[1:].copy(), relative

    def base_strip(self):
        r_left, _, _ = self.rotations()
        # A_tau_nu = R_left A'^T; its first column is the base direction, B(130).
        a_tau_nu = r_left @ np.swapaxes(self.l_base, 1, 2)
        b = a_tau_nu[:, :, 0]
        along = np.einsum("mi,mi->m", b, r_left[:, :, 0])  # component along image x
        return b / along[:, None]

    def elements(self):
        right = cardan_from_matrix(self.r_right_base)
        return np.column_stack([self.angles_left, right])
