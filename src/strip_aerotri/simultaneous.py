"""Simultaneous similarity transformation of units to the control and to each other.

The construction of R4 §3 (method.md §6A): every *unit* (a model of a strip,
or a whole strip of a block) has coordinates of its points in its own
system; all units are transformed at once, each by its own 3D similarity,

``X = t_u + s_u R_u (x − c_u)``

(``c_u`` the fixed centroid of the unit's coordinates, ``R_u`` an active
rotation premultiplying column vectors), so that the points they share
coincide and the control is met.  The unknowns are the seven parameters of
every unit and the coordinates of every point; the observations are

* each unit coordinate of a point, ``T_u(x) − X_p = v`` with a full 3 × 3
  weight matrix (the information of the point in its unit, e.g. from the
  two rays of a model: its error is mostly along the rays);
* the control, ``X_p − X_c = v`` per given component with its sigma;
* optionally straight lines, J(18): points on one vertical plane along the
  work frame's X axis, ``Y_p − a − b X_p = v`` with unknown ``a, b``.

Gauss-Newton on the linearised rotations (``R ← exp([ω]×) R``), normal
equations with the points eliminated block by block (3 × 3) and the reduced
system of the units (and lines) solved by a sparse LU (SuperLU): one
iteration costs time linear in the observations, and the reduced system is
banded along a strip.  Units are Cartesian frames in metres or model units;
the points are in the work frame (metres).

References: Ackermann, Ebner, Klein (1970), "Block triangulation with
independent models", Photogrammetric Engineering 36; R4 §2.2-§3.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

from ._typing import ArrayLike, FloatArray, IntArray
from .errors import ConvergenceError, GeometryError
from .rotation import matrix_from_rotvec

__all__ = [
    "LineCondition",
    "SimultaneousResult",
    "UnitObservations",
    "UnitTransforms",
    "adjust_units",
    "baarda_delta",
]

#: Parameters of a unit: translation (3), small rotation (3), relative scale.
N_UNIT = 7
_Z_BETA = 0.8416212335729143  # standard normal quantile of 0.8: power 80 %


def baarda_delta(critical: float) -> float:
    """Non-centrality δ0 of Baarda's minimal detectable error for a test
    with critical value ``critical`` (|w| beyond it rejects) and power 80 %:
    ``critical + z(0.8)``; the error an observation must have to be found
    is ``σ δ0 / sqrt(r)`` (Baarda 1968, "A testing procedure for use in
    geodetic networks"; Förstner 1987)."""
    return float(critical) + _Z_BETA


@dataclass(frozen=True)
class UnitTransforms:
    """Similarities of the units: ``X = translation + scale R (x − centroid)``.

    Attributes
    ----------
    scale : ndarray, shape (U,)
    rotation : ndarray, shape (U, 3, 3)
        Active rotations, unit axes -> work frame axes.
    translation : ndarray, shape (U, 3)
        Work-frame position of each unit's centroid (metres).
    centroid : ndarray, shape (U, 3)
        The fixed reference point of each unit, unit coordinates.
    """

    scale: FloatArray
    rotation: FloatArray
    translation: FloatArray
    centroid: FloatArray

    def apply(self, unit: ArrayLike, xyz: ArrayLike) -> FloatArray:
        """Rows ``xyz`` (n, 3) of units ``unit`` (n,) in the work frame."""
        unit = np.asarray(unit, dtype=np.intp)
        d = np.asarray(xyz, dtype=np.float64) - self.centroid[unit]
        rotated = np.einsum("nij,nj->ni", self.rotation[unit], d)
        return self.translation[unit] + self.scale[unit, None] * rotated

    def apply_to_rotation(self, unit: ArrayLike, rotations: ArrayLike) -> FloatArray:
        """Image -> unit rotations (n, 3, 3) turned into image -> work frame."""
        unit = np.asarray(unit, dtype=np.intp)
        return self.rotation[unit] @ np.asarray(rotations, dtype=np.float64)


@dataclass(frozen=True)
class UnitObservations:
    """The coordinates of points in their units, with their weights.

    Attributes
    ----------
    unit : ndarray of int, shape (n,)
    point : ndarray of int, shape (n,)
        Index of the point (0 .. n_points − 1) each row determines.
    xyz : ndarray, shape (n, 3)
        Coordinates in the unit's system.
    weight : ndarray, shape (n, 3, 3)
        Symmetric positive definite information matrix of each row in the
        work frame, 1/m² (the inverse covariance of ``T_u(x)``).
    """

    unit: IntArray
    point: IntArray
    xyz: FloatArray
    weight: FloatArray

    def __post_init__(self) -> None:
        n = self.unit.shape[0]
        shapes = (self.point.shape, self.xyz.shape, self.weight.shape)
        if shapes != ((n,), (n, 3), (n, 3, 3)):
            raise ValueError(
                f"Expected unit (n,), point (n,), xyz (n, 3), weight (n, 3, 3); got "
                f"{self.unit.shape}, {shapes[0]}, {shapes[1]}, {shapes[2]}"
            )


@dataclass(frozen=True)
class LineCondition:
    """Points on one vertical plane along the work frame's X axis, J(18).

    Attributes
    ----------
    point : ndarray of int, shape (k,)
        Points of the line (k >= 3).
    sigma : float
        Standard deviation of ``Y − a − b X`` in metres.
    """

    point: IntArray
    sigma: float


@dataclass(frozen=True)
class SimultaneousResult:
    """Result of :func:`adjust_units`.

    Attributes
    ----------
    transforms : UnitTransforms
    points : ndarray, shape (P, 3)
        Adjusted points, work frame (NaN for points no row determines).
    residuals : ndarray, shape (n, 3)
        ``T_u(x) − X_p`` of every row at the solution, metres.
    row_statistic : ndarray, shape (n,)
        ``v̄ᵀ W v̄`` of each row's residual over its redundancy share (about
        chi-square with 3 degrees of freedom when the weights are right;
        the share is estimated with the units held fixed and spread evenly
        over the units' parameters).
    control_residuals : ndarray, shape (C, 3)
        Given minus adjusted control coordinates (NaN where not given).
    control_cofactor : ndarray, shape (C, 3, 3)
        Cofactor (covariance at σ0 = 1) of the adjusted control points.
    control_redundancy : ndarray, shape (C, 3)
        Redundancy numbers ``1 − q_kk / σ_k²`` of the given components.
    control_w : ndarray, shape (C, 3)
        Baarda's w of the given components at their a priori sigmas (NaN
        where the redundancy is below 1e-6: the error cannot show).
    line_parameters : ndarray, shape (L, 2)
        ``a, b`` of each line.
    line_residuals : tuple of ndarray
        ``Y − a − b X`` of each line's points, metres.
    line_w : tuple of ndarray
        Baarda's w of each line equation at its sigma, with its exact
        redundancy number ``1 − q_ee / σ²`` (``q_ee`` the cofactor of the
        adjusted ``Y − a − b X``, the line's ``a, b`` included); NaN where r
        is below 1e-6.
    line_redundancy : tuple of ndarray
        Those redundancy numbers.
    sigma0 : float
        A posteriori standard deviation of unit weight (NaN without
        redundancy).
    redundancy : int
    iterations : int
    converged : bool
    """

    transforms: UnitTransforms
    points: FloatArray
    residuals: FloatArray
    row_statistic: FloatArray
    control_residuals: FloatArray
    control_cofactor: FloatArray
    control_redundancy: FloatArray
    control_w: FloatArray
    line_parameters: FloatArray
    line_residuals: tuple[FloatArray, ...]
    line_w: tuple[FloatArray, ...]
    line_redundancy: tuple[FloatArray, ...]
    sigma0: float
    redundancy: int
    iterations: int
    converged: bool


def _rows_whitening(weight: FloatArray) -> FloatArray:
    """``Lᵀ`` of each row's weight ``W = L Lᵀ`` (n, 3, 3): ``‖Lᵀ v‖² = vᵀ W v``."""
    try:
        low = np.linalg.cholesky(weight)
    except np.linalg.LinAlgError as exc:
        raise ValueError("Expected positive definite row weights") from exc
    return np.swapaxes(low, 1, 2)


def _skew_rows(y: FloatArray) -> FloatArray:
    """``−[y]×`` of rows y (n, 3): the derivative of ``ω × y`` by ω."""
    out = np.zeros((y.shape[0], 3, 3))
    out[:, 0, 1], out[:, 0, 2] = y[:, 2], -y[:, 1]
    out[:, 1, 0], out[:, 1, 2] = -y[:, 2], y[:, 0]
    out[:, 2, 0], out[:, 2, 1] = y[:, 1], -y[:, 0]
    return out


class _Problem:
    """Fixed structure of an adjustment: rows, control, lines and indices."""

    def __init__(
        self,
        obs: UnitObservations,
        n_units: int,
        n_points: int,
        control_point: IntArray,
        control_xyz: FloatArray,
        control_sigma: FloatArray,
        lines: Sequence[LineCondition],
    ):
        self.obs = obs
        self.n_units = n_units
        self.n_points = n_points
        self.whiten = _rows_whitening(obs.weight)
        self.control_point = control_point
        self.control_xyz = control_xyz
        self.control_sigma = control_sigma
        self.control_given = np.isfinite(control_xyz)
        self.lines = list(lines)
        self.n_lines = len(self.lines)
        self.n_reduced = N_UNIT * n_units + 2 * self.n_lines
        counts = np.bincount(obs.unit, minlength=n_units).astype(np.float64)
        if np.any(counts == 0):
            raise GeometryError(f"unit {int(np.flatnonzero(counts == 0)[0])} has no points")
        self.centroid = np.column_stack(
            [np.bincount(obs.unit, obs.xyz[:, k], minlength=n_units) / counts for k in range(3)]
        )
        self.offset = obs.xyz - self.centroid[obs.unit]
        self.observed = np.bincount(obs.point, minlength=n_points) > 0

    @property
    def n_observations(self) -> int:
        n_line = sum(line.point.shape[0] for line in self.lines)
        return 3 * self.obs.unit.shape[0] + int(self.control_given.sum()) + n_line

    @property
    def n_unknowns(self) -> int:
        return self.n_reduced + 3 * int(self.observed.sum())


class _State:
    def __init__(self, scale, rotation, translation, points, line_ab):
        self.scale = scale
        self.rotation = rotation
        self.translation = translation
        self.points = points
        self.line_ab = line_ab


def _predict(prob: _Problem, st: _State) -> tuple[FloatArray, FloatArray]:
    """Rows in the work frame relative to their unit's translation
    (``s R (x − c)``, n × 3) and their residuals ``T_u(x) − X_p``."""
    u = prob.obs.unit
    y = st.scale[u, None] * np.einsum("nij,nj->ni", st.rotation[u], prob.offset)
    v = st.translation[u] + y - st.points[prob.obs.point]
    return y, v


def _line_terms(prob: _Problem, st: _State, k: int):
    line = prob.lines[k]
    xyz = st.points[line.point]
    a, b = st.line_ab[k]
    e = xyz[:, 1] - a - b * xyz[:, 0]
    return xyz, e, 1.0 / line.sigma**2


def _cost(prob: _Problem, st: _State) -> float:
    _, v = _predict(prob, st)
    wv = np.einsum("nij,nj->ni", prob.whiten, v)
    total = float(np.einsum("ij,ij->", wv, wv))
    c = st.points[prob.control_point] - prob.control_xyz
    g = prob.control_given
    total += float(np.sum((c[g] / prob.control_sigma[g]) ** 2))
    for k in range(prob.n_lines):
        _, e, w = _line_terms(prob, st, k)
        total += float(w * np.sum(e**2))
    return total


class _Normals:
    """Reduced normal equations of one iteration: ``S z = r`` for the units
    and lines, and what back-substitution needs."""

    def __init__(self, s_matrix, rhs, v_inv, n_zp, g_p):
        self.s_matrix = s_matrix
        self.rhs = rhs
        self.v_inv = v_inv  # (P, 3, 3), 0 for unobserved points
        self.n_zp = n_zp  # sparse (n_reduced, 3P)
        self.g_p = g_p  # (P, 3)


def _normals(prob: _Problem, st: _State) -> _Normals:
    obs = prob.obs
    n = obs.unit.shape[0]
    u, p = obs.unit, obs.point
    y, v = _predict(prob, st)
    # Design of a row in its unit's 7 parameters: dt, dω (R <- exp(ω) R),
    # ds / s; its point's is -I.
    a_u = np.zeros((n, 3, N_UNIT))
    a_u[:, :, :3] = np.eye(3)
    a_u[:, :, 3:6] = _skew_rows(y)
    a_u[:, :, 6] = y
    w = obs.weight
    wa = w @ a_u  # W A_u
    n_uu = np.swapaxes(a_u, 1, 2) @ wa  # (n, 7, 7)
    g_u_rows = -np.einsum("nki,nk->ni", wa, v)  # -A_uᵀ W v
    # point blocks: Σ W, gradient Σ W v (A_p = -I)
    v_blocks = np.zeros((prob.n_points, 3, 3))
    np.add.at(v_blocks, p, w)
    g_p = np.zeros((prob.n_points, 3))
    np.add.at(g_p, p, np.einsum("nij,nj->ni", w, v))
    # control
    cp, given, sig = prob.control_point, prob.control_given, prob.control_sigma
    cw = np.where(given, 1.0 / np.where(given, sig, 1.0) ** 2, 0.0)
    resid_c = np.where(given, st.points[cp] - np.where(given, prob.control_xyz, 0.0), 0.0)
    diag = np.zeros((cp.shape[0], 3, 3))
    diag[:, [0, 1, 2], [0, 1, 2]] = cw
    np.add.at(v_blocks, cp, diag)
    np.add.at(g_p, cp, -cw * resid_c)

    # Reduced unknowns: units then lines.  N_zz, N_zp, g_z as sparse/dense parts.
    nz = prob.n_reduced
    # N_uu blocks (unit diagonal)
    blocks = np.zeros((prob.n_units, N_UNIT, N_UNIT))
    np.add.at(blocks, u, n_uu)
    g_z = np.zeros(nz)
    np.add.at(g_z.reshape(-1)[: N_UNIT * prob.n_units].reshape(prob.n_units, N_UNIT), u, g_u_rows)
    rows_i = np.repeat(np.arange(N_UNIT), N_UNIT)
    cols_i = np.tile(np.arange(N_UNIT), N_UNIT)
    zz_r = [(N_UNIT * np.arange(prob.n_units)[:, None] + rows_i).ravel()]
    zz_c = [(N_UNIT * np.arange(prob.n_units)[:, None] + cols_i).ravel()]
    zz_v = [blocks.reshape(prob.n_units, -1).ravel()]
    # N_zp per row: A_uᵀ W A_p = -(W A_u)ᵀ  (7 x 3)
    n_up = -np.swapaxes(wa, 1, 2)  # (n, 7, 3)
    zp_r = [(N_UNIT * u[:, None, None] + np.arange(N_UNIT)[None, :, None] + 0 * np.arange(3)).ravel()]
    zp_c = [(3 * p[:, None, None] + np.arange(3)[None, None, :] + 0 * np.arange(N_UNIT)[:, None]).ravel()]
    zp_v = [n_up.ravel()]
    # lines: e = Y - a - b X; de = dY - b dX - da - X db
    for k in range(prob.n_lines):
        xyz, e, wl = _line_terms(prob, st, k)
        b = st.line_ab[k, 1]
        lp = prob.lines[k].point
        m = lp.shape[0]
        d_p = np.zeros((m, 3))
        d_p[:, 0], d_p[:, 1] = -b, 1.0
        d_l = np.column_stack([-np.ones(m), -xyz[:, 0]])
        np.add.at(v_blocks, lp, wl * d_p[:, :, None] * d_p[:, None, :])
        np.add.at(g_p, lp, -wl * d_p * e[:, None])
        col0 = N_UNIT * prob.n_units + 2 * k
        nll = wl * d_l.T @ d_l
        zz_r.append(col0 + np.array([0, 0, 1, 1]))
        zz_c.append(col0 + np.array([0, 1, 0, 1]))
        zz_v.append(nll.ravel())
        g_z[col0 : col0 + 2] += -wl * d_l.T @ e
        lp_block = wl * d_l[:, :, None] * d_p[:, None, :]  # (m, 2, 3)
        zp_r.append((col0 + np.arange(2)[None, :, None] + 0 * lp[:, None, None]).repeat(3, axis=2).ravel())
        zp_c.append((3 * lp[:, None, None] + np.arange(3)[None, None, :]).repeat(2, axis=1).ravel())
        zp_v.append(lp_block.ravel())
    n_zz = sp.csr_matrix(
        (np.concatenate(zz_v), (np.concatenate(zz_r), np.concatenate(zz_c))), shape=(nz, nz)
    )
    n_zp = sp.csr_matrix(
        (np.concatenate(zp_v), (np.concatenate(zp_r), np.concatenate(zp_c))),
        shape=(nz, 3 * prob.n_points),
    )
    # V⁻¹ block by block (unobserved points: 0)
    obs_pts = prob.observed
    v_inv = np.zeros_like(v_blocks)
    try:
        v_inv[obs_pts] = np.linalg.inv(v_blocks[obs_pts])
    except np.linalg.LinAlgError as exc:
        raise GeometryError("a point is not determined by its rows (singular 3 x 3 block)") from exc
    reduce = n_zp @ _block_diag(v_inv)
    s_matrix = (n_zz - reduce @ n_zp.T).tocsc()
    rhs = g_z - reduce @ g_p.ravel()
    return _Normals(s_matrix, rhs, v_inv, n_zp, g_p)


def _block_diag(blocks: FloatArray) -> sp.csr_matrix:
    """Sparse block-diagonal matrix of (P, 3, 3) blocks."""
    n = blocks.shape[0]
    return sp.bsr_matrix(
        (blocks, np.arange(n), np.arange(n + 1)), shape=(3 * n, 3 * n)
    ).tocsr()


def _factor(s_matrix: sp.csc_matrix):
    """SuperLU factors of the reduced matrix, Jacobi-scaled; raises
    GeometryError when it is singular (units not tied to the control)."""
    d = s_matrix.diagonal()
    if np.any(~(d > 0)):
        raise GeometryError(
            "the units are not determined: a unit shares too few points with the others "
            "and the control"
        )
    scale = 1.0 / np.sqrt(d)
    scaled = (sp.diags(scale) @ s_matrix @ sp.diags(scale)).tocsc()
    try:
        lu = spl.splu(scaled, permc_spec="MMD_AT_PLUS_A")
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise GeometryError(
            "the units are not determined: a unit shares too few points with the others "
            "and the control"
        ) from exc
    return lu, scale


def _solve_reduced(lu, scale, rhs):
    return scale * lu.solve(scale * rhs)


def adjust_units(
    observations: UnitObservations,
    n_units: int,
    n_points: int,
    *,
    start: UnitTransforms,
    points0: ArrayLike,
    control_point: ArrayLike = (),
    control_xyz: ArrayLike | None = None,
    control_sigma: ArrayLike | None = None,
    lines: Sequence[LineCondition] = (),
    max_iterations: int = 20,
    tolerance: float = 1e-10,
) -> SimultaneousResult:
    """Transform all units at once to the control and to each other.

    Parameters
    ----------
    observations : UnitObservations
        Unit coordinates of points with their 3 × 3 weights (work frame).
    n_units, n_points : int
    start : UnitTransforms
        Initial similarities (their ``centroid`` is replaced by each unit's
        centroid, the translation moved to match).
    points0 : array_like, shape (P, 3)
        Initial points in the work frame (any value for points no row has).
    control_point : array_like of int, shape (C,)
        The point of each control row.
    control_xyz : array_like, shape (C, 3)
        Given coordinates in the work frame, NaN for components not given.
    control_sigma : array_like, shape (C, 3)
        Their standard deviations in metres.
    lines : sequence of LineCondition
    max_iterations : int
    tolerance : float
        Converged when the largest correction is below ``tolerance`` times
        the extent of the points (translations and points) and below
        ``tolerance`` (rotations in radians, relative scales), or when the
        weighted sum of squares changes by less than ``tolerance``
        relative.

    Returns
    -------
    SimultaneousResult

    Raises
    ------
    GeometryError
        A unit or point that the observations do not determine.
    ConvergenceError
        The sum of squares cannot be reduced.
    """
    obs = observations
    control_point = np.asarray(control_point, dtype=np.intp).reshape(-1)
    n_c = control_point.shape[0]
    control_xyz = (
        np.full((n_c, 3), np.nan)
        if control_xyz is None
        else np.asarray(control_xyz, dtype=np.float64).reshape(n_c, 3)
    )
    control_sigma = (
        np.ones((n_c, 3))
        if control_sigma is None
        else np.broadcast_to(np.asarray(control_sigma, dtype=np.float64), (n_c, 3)).copy()
    )
    given = np.isfinite(control_xyz)
    if np.any(given & ~(control_sigma > 0)):
        raise ValueError("Expected control_sigma > 0 for every given control component")
    prob = _Problem(obs, n_units, n_points, control_point, control_xyz, control_sigma, lines)
    # The start's similarity re-expressed about each unit's own centroid.
    s0 = np.asarray(start.scale, dtype=np.float64).copy()
    r0 = np.asarray(start.rotation, dtype=np.float64).copy()
    t0 = start.apply(np.arange(n_units), prob.centroid)
    points = np.array(points0, dtype=np.float64, copy=True)
    line_ab = np.zeros((prob.n_lines, 2))
    for k, line in enumerate(prob.lines):
        xyz = points[line.point]
        design = np.column_stack([np.ones(len(xyz)), xyz[:, 0]])
        line_ab[k] = np.linalg.lstsq(design, xyz[:, 1], rcond=None)[0]
    st = _State(s0, r0, t0, points, line_ab)
    extent = float(np.nanmax(np.ptp(points[prob.observed], axis=0))) if prob.observed.any() else 1.0
    extent = max(extent, 1.0)

    cost = _cost(prob, st)
    converged = False
    iterations = 0
    normals = None
    for iterations in range(1, max_iterations + 1):
        normals = _normals(prob, st)
        lu, scale = _factor(normals.s_matrix)
        dz = _solve_reduced(lu, scale, normals.rhs)
        dp = np.einsum(
            "pij,pj->pi", normals.v_inv, normals.g_p - (normals.n_zp.T @ dz).reshape(-1, 3)
        )
        step = 1.0
        for _ in range(30):
            trial = _step(prob, st, dz, dp, step)
            trial_cost = _cost(prob, trial)
            if trial_cost <= cost * (1.0 + 1e-12) + 1e-300:
                break
            step *= 0.5
        else:
            raise ConvergenceError(
                "the simultaneous transformation of the units diverges: no step lowers the "
                "sum of squares (start values too far off)"
            )
        du = dz[: N_UNIT * n_units].reshape(n_units, N_UNIT) * step
        largest = max(
            float(np.max(np.abs(du[:, :3]), initial=0.0)) / extent,
            float(np.max(np.abs(du[:, 3:]), initial=0.0)),
            float(np.max(np.abs(dp[prob.observed]), initial=0.0)) * step / extent,
        )
        change = abs(cost - trial_cost) / max(cost, 1e-300)
        st, cost = trial, trial_cost
        if largest < tolerance or change < tolerance:
            converged = True
            break
    normals = _normals(prob, st)
    lu, scale = _factor(normals.s_matrix)
    return _result(prob, st, normals, lu, scale, cost, iterations, converged)


def _step(prob: _Problem, st: _State, dz: FloatArray, dp: FloatArray, step: float) -> _State:
    n_u = prob.n_units
    du = dz[: N_UNIT * n_u].reshape(n_u, N_UNIT) * step
    dl = dz[N_UNIT * n_u :].reshape(-1, 2) * step
    rotation = matrix_from_rotvec(du[:, 3:6]) @ st.rotation
    points = st.points + step * dp
    return _State(
        st.scale * (1.0 + du[:, 6]),
        rotation,
        st.translation + du[:, :3],
        points,
        st.line_ab + dl,
    )


def _result(prob, st, normals, lu, scale, cost, iterations, converged) -> SimultaneousResult:
    obs = prob.obs
    _, v = _predict(prob, st)
    redundancy = prob.n_observations - prob.n_unknowns
    sigma0 = float(np.sqrt(cost / redundancy)) if redundancy > 0 else float("nan")

    # Cofactors of the control points: Q_pp = V⁻¹ + V⁻¹ N_pz S⁻¹ N_zp V⁻¹.
    cp = prob.control_point
    cof = point_cofactors(normals, lu, scale, cp)
    given = prob.control_given
    resid_c = np.where(given, prob.control_xyz - st.points[cp], np.nan)
    sig = prob.control_sigma
    q_diag = np.einsum("cii->ci", cof)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(given, 1.0 - q_diag / np.where(given, sig, 1.0) ** 2, np.nan)
        w = resid_c / (sig * np.sqrt(np.maximum(r, 0.0)))
    w[~(r > 1e-6)] = np.nan

    # Row statistics: the row's leverage on its own point with the units
    # fixed, h = W^(1/2) V⁻¹ W^(1/2); the units' 7 U parameters spread evenly.
    lt = prob.whiten
    wv = np.einsum("nij,nj->ni", lt, v)
    h = lt @ normals.v_inv[obs.point] @ np.swapaxes(lt, 1, 2)
    free = 3.0 - np.einsum("nii->n", h)
    share = max(1.0 - N_UNIT * prob.n_units / max(float(free.sum()), 1e-300), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        stat = np.einsum("ni,ni->n", wv, wv) / (free * share)
    # a row alone on its point (a point of one model) cannot be tested
    stat[~(free * share > 1e-6)] = np.nan

    line_resid = []
    line_w = []
    line_r = []
    for k, line in enumerate(prob.lines):
        xyz, e, _ = _line_terms(prob, st, k)
        r_line = 1.0 - _line_cofactors(prob, st, normals, lu, scale, k, xyz) / line.sigma**2
        with np.errstate(invalid="ignore", divide="ignore"):
            wl = e / (line.sigma * np.sqrt(np.maximum(r_line, 0.0)))
        wl[~(r_line > 1e-6)] = np.nan
        line_resid.append(e)
        line_w.append(wl)
        line_r.append(r_line)
    transforms = UnitTransforms(st.scale, st.rotation, st.translation, prob.centroid)
    points = st.points.copy()
    points[~prob.observed] = np.nan
    return SimultaneousResult(
        transforms=transforms,
        points=points,
        residuals=v,
        row_statistic=stat,
        control_residuals=resid_c,
        control_cofactor=cof,
        control_redundancy=r,
        control_w=w,
        line_parameters=st.line_ab.copy(),
        line_residuals=tuple(line_resid),
        line_w=tuple(line_w),
        line_redundancy=tuple(line_r),
        sigma0=sigma0,
        redundancy=int(redundancy),
        iterations=int(iterations),
        converged=bool(converged),
    )


def _line_cofactors(prob, st, normals, lu, scale, k, xyz) -> FloatArray:
    """Cofactors of the adjusted ``e = Y − a − b X`` of line k's points (m,).

    With ``d_p = (−b, 1, 0)`` the derivative by the point and ``d_z`` by the
    reduced unknowns (``−1, −X`` at the line's ``a, b``), and
    ``u = N_zp V⁻¹ d_p``: ``q_ee = d_pᵀ V⁻¹ d_p + (u − d_z)ᵀ S⁻¹ (u − d_z)``.
    """
    line = prob.lines[k]
    points = line.point
    m = points.shape[0]
    d_p = np.zeros((m, 3))
    d_p[:, 0], d_p[:, 1] = -st.line_ab[k, 1], 1.0
    vd = np.einsum("mij,mj->mi", normals.v_inv[points], d_p)  # V⁻¹ d_p
    cols = (3 * points[:, None] + np.arange(3)).ravel()
    sel = sp.csr_matrix(
        (vd.ravel(), (cols, np.repeat(np.arange(m), 3))), shape=(3 * prob.n_points, m)
    )
    u = (normals.n_zp @ sel).toarray()  # (nz, m)
    col0 = N_UNIT * prob.n_units + 2 * k
    u[col0] += 1.0  # − d_z: d_z = −1 at a
    u[col0 + 1] += xyz[:, 0]  # and −X at b
    x = scale[:, None] * lu.solve(scale[:, None] * u)
    return np.einsum("mi,mi->m", d_p, vd) + np.einsum("zm,zm->m", u, x)


_COFACTOR_CHUNK = 256  # points per block of right-hand sides (memory: 3 x 256 x n_reduced)


def point_cofactors(normals: _Normals, lu, scale: FloatArray, points: IntArray) -> FloatArray:
    """Cofactor blocks (C, 3, 3) of adjusted points at the solution:
    ``Q_pp = V⁻¹ + V⁻¹ N_pz S⁻¹ N_zp V⁻¹``, solved in chunks of points."""
    n_c = points.shape[0]
    out = normals.v_inv[points].copy()
    for lo in range(0, n_c, _COFACTOR_CHUNK):
        chunk = points[lo : lo + _COFACTOR_CHUNK]
        m = chunk.shape[0]
        cols = (3 * chunk[:, None] + np.arange(3)).ravel()
        # N_zp V⁻¹ restricted to the chunk's columns: (nz, 3m)
        b = (normals.n_zp[:, cols] @ sp.csr_matrix(_block_diag(normals.v_inv[chunk]))).toarray()
        x = scale[:, None] * lu.solve(scale[:, None] * b)
        out[lo : lo + m] += np.einsum("zci,zcj->cij", b.reshape(-1, m, 3), x.reshape(-1, m, 3))
    return out
