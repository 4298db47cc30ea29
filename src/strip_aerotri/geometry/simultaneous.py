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
from typing import TYPE_CHECKING

import numpy as np

from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..errors import ConvergenceError, GeometryError
from ..options import DEFAULT_MAX_ITERATIONS
from .rotation import matrix_from_rotvec, skew

if TYPE_CHECKING:
    import scipy.sparse as sp
    import scipy.sparse.linalg as spl

__all__ = [
    "LineCondition",
    "SimultaneousResult",
    "UnitObservations",
    "UnitPolynomial",
    "UnitTransforms",
    "adjust_units",
    "baarda_delta",
]

#: Parameters of a unit: translation (3), small rotation (3), relative scale.
N_UNIT = 7
_Z_BETA = 0.8416212335729143  # standard normal quantile of 0.8: power 80 %
#: Below this redundancy number an observation is not tested (its w is NaN):
#: a share of 1e-3 of its error shows in its residual, so the least model
#: imperfection (the correlations a model's relative orientation puts
#: between its points are left out of the weights) looks like a blunder of
#: metres (a 0.1 mm residual at r = 1.4e-5 gave w = 4.9, "estimated error
#: 8.8 m", on a drone strip with four full points).  Its minimal detectable
#: error (σ δ0 / √r, more than 150 σ) is reported instead.
_MIN_TESTED_REDUNDANCY = 1e-3
#: Standard deviation of the prior that holds a polynomial term at 0.
_FIXED_SIGMA = 1e-9


def baarda_delta(critical: float) -> float:
    """Non-centrality δ0 of Baarda's minimal detectable error for a test
    with critical value ``critical`` (|w| beyond it rejects) and power 80 %:
    ``critical + z(0.8)``; the error an observation must have to be found
    is ``σ δ0 / sqrt(r)`` (Baarda 1968, "A testing procedure for use in
    geodetic networks"; Förstner 1987)."""
    return float(critical) + _Z_BETA


@dataclass(frozen=True)
class UnitPolynomial:
    """A deformation polynomial of every unit, in the unit's own system.

    A unit coordinate ``x`` is corrected to ``x + B(x) a`` before the
    unit's similarity (``a`` the unit's coefficients, dimensionless).  With
    ``u, v`` the coordinates along and across the unit's principal axis in
    plan, divided by its half length ``L`` (about −1 … 1), the terms are
    those of J(16)'s types that a similarity does not already hold, each
    times ``L`` along the unit's along, across and vertical axes:

    * type 1: ``uv`` in each axis (the twist of a strip, its varying shear);
    * type 2: and ``u²`` (change of scale along the strip, bending in plan
      and in height);
    * type 3: and ``u³``.

    A weak prior ``a = 0 ± prior_sigma`` on every coefficient keeps a unit
    that its points cannot bend (one side overlap only, no control on the
    other side) determined without pulling a determined one.

    Attributes
    ----------
    degree : int
        1, 2 or 3.
    origin : ndarray, shape (U, 3)
        Unit coordinates of ``u = v = 0``.
    axes : ndarray, shape (U, 3, 3)
        Columns: along, across (plan) and vertical axes of each unit, unit
        system.
    half_length : ndarray, shape (U,)
        ``L`` in unit coordinates.
    prior_sigma : float
        Standard deviation of the coefficients' prior (dimensionless: a
        fraction of ``L`` at the ends of the unit).
    fixed : ndarray of bool, shape (U, n_terms), optional
        Terms held at 0 (a prior of 1e-9): those the data do not determine
        (:meth:`without`).
    """

    degree: int
    origin: FloatArray
    axes: FloatArray
    half_length: FloatArray
    prior_sigma: float = 0.01
    fixed: BoolArray | None = None

    def prior_weights(self) -> FloatArray:
        """``1 / σ²`` of every coefficient's prior, (U, n_terms)."""
        w = np.full((self.origin.shape[0], self.n_terms), 1.0 / self.prior_sigma**2)
        if self.fixed is not None:
            w[self.fixed] = 1.0 / _FIXED_SIGMA**2
        return w

    def without(self, terms: BoolArray) -> UnitPolynomial:
        """The same polynomial with ``terms`` (U, n_terms) held at 0 too."""
        fixed = terms if self.fixed is None else self.fixed | terms
        return UnitPolynomial(
            self.degree, self.origin, self.axes, self.half_length, self.prior_sigma, fixed
        )

    @classmethod
    def fit(cls, unit: IntArray, xyz: FloatArray, n_units: int, degree: int) -> UnitPolynomial:
        """The origin, axes and half length of every unit from its rows."""
        if degree not in (1, 2, 3):
            raise ValueError(f"Expected polynomial degree 1, 2 or 3, got {degree!r}")
        origin = np.zeros((n_units, 3))
        axes = np.zeros((n_units, 3, 3))
        half = np.ones(n_units)
        for k in range(n_units):  # per unit: a strip of a block, a handful
            here = xyz[unit == k]
            origin[k] = here.mean(axis=0)
            d = here[:, :2] - origin[k, :2]
            _, _, vt = np.linalg.svd(d, full_matrices=False)
            along = vt[0]
            axes[k, :2, 0] = along
            axes[k, :2, 1] = (-along[1], along[0])
            axes[k, 2, 2] = 1.0
            half[k] = max(float(np.max(np.abs(d @ along))), 1e-12)
        return cls(degree, origin, axes, half)

    @property
    def n_terms(self) -> int:
        return 3 * self.degree

    def _uv(self, unit: IntArray, xyz: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``u, v``: rows ``xyz`` along and across their unit over its half length."""
        local = np.einsum("nji,nj->ni", self.axes[unit], xyz - self.origin[unit])
        local /= self.half_length[unit, None]
        return local[:, 0], local[:, 1]

    def basis(self, unit: IntArray, xyz: FloatArray) -> FloatArray:
        """``B(x)`` of rows ``xyz`` (n, 3) of units ``unit``: (n, 3, n_terms)."""
        axes = self.axes[unit]
        half = self.half_length[unit]
        u, v = self._uv(unit, xyz)
        monomials = [u * v, u**2, u**3][: self.degree]
        out = np.empty((unit.shape[0], 3, self.n_terms))
        for j, m in enumerate(monomials):
            out[:, :, 3 * j : 3 * j + 3] = axes * (half * m)[:, None, None]
        return out

    def jacobian(self, unit: IntArray, xyz: FloatArray, coefficients: FloatArray) -> FloatArray:
        """``∂(B(x) a)/∂x`` at rows ``xyz``: (n, 3, 3)."""
        axes = self.axes[unit]
        u, v = self._uv(unit, xyz)
        a = coefficients[unit].reshape(-1, self.degree, 3)  # (n, term, axis)
        # d(monomial)/d(u, v), times L, over L for u = (...)/L: per unit length;
        # only uv depends on v
        du = [v, 2 * u, 3 * u**2][: self.degree]
        grad_uv = np.zeros((unit.shape[0], 3, 3))  # d(correction, local axes)/d(local)
        for j in range(self.degree):
            grad_uv[:, :, 0] += a[:, j, :] * du[j][:, None]
        grad_uv[:, :, 1] = a[:, 0, :] * u[:, None]
        jac: FloatArray = axes @ grad_uv @ np.swapaxes(axes, 1, 2)
        return jac


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
    polynomial : UnitPolynomial or None
        The units' deformation (``x`` is ``x + B(x) a`` before the
        similarity); None: similarities only.
    coefficients : ndarray, shape (U, n_terms) or None
        ``a`` of every unit, with ``polynomial``.
    """

    scale: FloatArray
    rotation: FloatArray
    translation: FloatArray
    centroid: FloatArray
    polynomial: UnitPolynomial | None = None
    coefficients: FloatArray | None = None

    def apply(self, unit: ArrayLike, xyz: ArrayLike) -> FloatArray:
        """Rows ``xyz`` (n, 3) of units ``unit`` (n,) in the work frame."""
        unit = np.asarray(unit, dtype=np.intp)
        xyz = np.asarray(xyz, dtype=np.float64)
        d = xyz - self.centroid[unit]
        if self.polynomial is not None and self.coefficients is not None:
            basis = self.polynomial.basis(unit, xyz)
            d = d + np.einsum("nik,nk->ni", basis, self.coefficients[unit])
        rotated: FloatArray = np.einsum("nij,nj->ni", self.rotation[unit], d)
        placed: FloatArray = self.translation[unit] + self.scale[unit, None] * rotated
        return placed

    def apply_to_rotation(
        self, unit: ArrayLike, rotations: ArrayLike, at: ArrayLike | None = None
    ) -> FloatArray:
        """Image -> unit rotations (n, 3, 3) turned into image -> work frame;
        with a polynomial, the rotation of its deformation at the unit
        coordinates ``at`` (n, 3) is applied first (the nearest rotation to
        ``I + ∂(B a)/∂x``)."""
        unit = np.asarray(unit, dtype=np.intp)
        rotations = np.asarray(rotations, dtype=np.float64)
        if self.polynomial is not None and self.coefficients is not None and at is not None:
            jac = self.polynomial.jacobian(
                unit, np.asarray(at, dtype=np.float64), self.coefficients
            )
            u_, _, vt = np.linalg.svd(np.eye(3) + jac)
            rotations = (u_ @ vt) @ rotations
        turned: FloatArray = self.rotation[unit] @ rotations
        return turned


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
        Cofactor (covariance at σ0 = 1) of the adjusted control points: the
        diagonal entries of their given components (NaN elsewhere).
    control_redundancy : ndarray, shape (C, 3)
        Redundancy numbers ``1 − q_kk / σ_k²`` of the given components.
    control_w : ndarray, shape (C, 3)
        Baarda's w of the given components at their a priori sigmas (NaN
        where the redundancy is below 1e-3: too little of an error shows to
        tell it from the model's imperfections).
    line_parameters : ndarray, shape (L, 2)
        ``a, b`` of each line.
    line_residuals : tuple of ndarray
        ``Y − a − b X`` of each line's points, metres.
    line_w : tuple of ndarray
        Baarda's w of each line equation at its sigma, with its exact
        redundancy number ``1 − q_ee / σ²`` (``q_ee`` the cofactor of the
        adjusted ``Y − a − b X``, the line's ``a, b`` included); NaN where r
        is below 1e-3.
    line_redundancy : tuple of ndarray
        Those redundancy numbers.
    sigma0 : float
        A posteriori standard deviation of unit weight (NaN without
        redundancy).
    redundancy : int
    iterations : int
    converged : bool
    coefficient_variance : ndarray, shape (U, n_terms), optional
        With a polynomial: the cofactor (variance at σ0 = 1) of every
        coefficient, its prior included; near the prior's variance, the
        data say little of that term.
    probe_points : ndarray of int, shape (U,), optional
        One point of each of at most 24 units evenly along the block (the
        point the most units share; -1 for the other units), whose plan
        precision :attr:`probe_plan_sigma` gives: how well the adjustment
        holds the plan position along the block of units.
    probe_plan_sigma : ndarray, shape (U,), optional
        A priori plan standard deviation ``sqrt(q_xx + q_yy)`` of the probe
        points (metres at σ0 = 1; NaN for -1). None without statistics.
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
    coefficient_variance: FloatArray | None = None
    probe_points: IntArray | None = None
    probe_plan_sigma: FloatArray | None = None


def _rows_whitening(weight: FloatArray) -> FloatArray:
    """``Lᵀ`` of each row's weight ``W = L Lᵀ`` (n, 3, 3): ``‖Lᵀ v‖² = vᵀ W v``."""
    try:
        low = np.linalg.cholesky(weight)
    except np.linalg.LinAlgError as exc:
        raise ValueError("Expected positive definite row weights") from exc
    return np.swapaxes(low, 1, 2)


def _summation(index: IntArray, n_groups: int) -> sp.csr_matrix:
    """(n_groups, n) matrix of ones that sums rows into their groups."""
    import scipy.sparse as sp

    n = index.shape[0]
    return sp.csr_matrix((np.ones(n), (index, np.arange(n))), shape=(n_groups, n))


class _Problem:
    """Fixed structure of an adjustment: rows, control, lines and indices.

    The *coupled rows* are the unit observations (3 equations each, one unit
    and one point) and the line equations (one equation each, one line and
    one point).  Every unit and every line is a *block* of 7 reduced unknowns
    (a line uses the first two, a and b; the other five are fixed at 0), so
    that the sparse structure of ``N_zp`` (blocks x points) is built once.
    """

    def __init__(
        self,
        obs: UnitObservations,
        n_units: int,
        n_points: int,
        control_point: IntArray,
        control_xyz: FloatArray,
        control_sigma: FloatArray,
        lines: Sequence[LineCondition],
        polynomial: UnitPolynomial | None = None,
    ):
        import scipy.sparse as sp

        self.obs = obs
        self.polynomial = polynomial
        self.n_extra = 0 if polynomial is None else polynomial.n_terms
        self.width = N_UNIT + self.n_extra  # reduced unknowns of a block
        self.n_units = n_units
        self.n_points = n_points
        self.whiten = _rows_whitening(obs.weight)
        self.control_point = control_point
        self.control_xyz = control_xyz
        self.control_sigma = control_sigma
        self.control_given = np.isfinite(control_xyz)
        self.lines = list(lines)
        self.n_lines = len(self.lines)
        self.n_blocks = n_units + self.n_lines
        self.n_reduced = self.width * self.n_blocks
        counts = np.bincount(obs.unit, minlength=n_units).astype(np.float64)
        if np.any(counts == 0):
            raise GeometryError(f"unit {int(np.flatnonzero(counts == 0)[0])} has no points")
        self.centroid = np.column_stack(
            [np.bincount(obs.unit, obs.xyz[:, k], minlength=n_units) / counts for k in range(3)]
        )
        self.offset = obs.xyz - self.centroid[obs.unit]
        self.basis = None if polynomial is None else polynomial.basis(obs.unit, obs.xyz)
        self.prior_weights = (
            np.zeros((n_units, 0)) if polynomial is None else polynomial.prior_weights()
        )
        self.observed = np.bincount(obs.point, minlength=n_points) > 0
        self.line_rows: list[int] = [line.point.shape[0] for line in self.lines]
        line_point = (
            np.concatenate([line.point for line in self.lines]) if self.lines else np.zeros(0, int)
        )
        line_block = np.repeat(n_units + np.arange(self.n_lines), self.line_rows).astype(np.intp)
        self.row_block = np.concatenate([obs.unit, line_block]).astype(np.intp)
        self.row_point = np.concatenate([obs.point, line_point]).astype(np.intp)
        self.to_block = _summation(self.row_block, self.n_blocks)
        self.to_point = _summation(self.row_point, n_points)
        # N_zp's CSR structure: each coupled row contributes a width x 3 block
        # at (its block, its point); data are given in that (row, width, 3) order.
        n_r = self.row_block.shape[0]
        width = self.width
        rows = (width * self.row_block[:, None, None] + np.arange(width)[None, :, None]).repeat(
            3, axis=2
        )
        cols = (3 * self.row_point[:, None, None] + np.arange(3)[None, None, :]).repeat(
            width, axis=1
        )
        order = sp.csr_matrix(
            (np.arange(1, n_r * 3 * width + 1, dtype=np.float64), (rows.ravel(), cols.ravel())),
            shape=(self.n_reduced, 3 * n_points),
        )
        order.sort_indices()
        if order.nnz != n_r * 3 * width:  # a point twice in one unit or line
            raise ValueError("Expected each point at most once in a unit and in a line")
        self.zp_order = order.data.astype(np.intp) - 1
        self.zp_indices = order.indices
        self.zp_indptr = order.indptr
        # the reduced unknowns fixed at 0: the five unused slots of a line block
        fixed = np.zeros((self.n_blocks, width), dtype=bool)
        fixed[n_units:, 2:] = True
        self.fixed = fixed

    def zp_matrix(self, blocks: FloatArray) -> sp.csr_matrix:
        """Sparse (n_reduced, 3P) matrix from per-row (n_r, width, 3) blocks."""
        import scipy.sparse as sp

        return sp.csr_matrix(
            (blocks.ravel()[self.zp_order], self.zp_indices, self.zp_indptr),
            shape=(self.n_reduced, 3 * self.n_points),
        )

    @property
    def n_observations(self) -> int:
        n_line = sum(self.line_rows)
        n_rows: int = self.obs.unit.shape[0]
        n_prior = self.n_extra * self.n_units  # the coefficients' priors
        return 3 * n_rows + int(self.control_given.sum()) + n_line + n_prior

    @property
    def n_unknowns(self) -> int:
        n_blocks = self.width * self.n_units
        return n_blocks + 2 * self.n_lines + 3 * int(self.observed.sum())


class _State:
    def __init__(
        self,
        scale: FloatArray,
        rotation: FloatArray,
        translation: FloatArray,
        points: FloatArray,
        line_ab: FloatArray,
        coefficients: FloatArray,
    ) -> None:
        self.scale = scale
        self.rotation = rotation
        self.translation = translation
        self.points = points
        self.line_ab = line_ab
        self.coefficients = coefficients


def _predict(prob: _Problem, st: _State) -> tuple[FloatArray, FloatArray]:
    """Rows in the work frame relative to their unit's translation
    (``s R (x − c)``, n × 3) and their residuals ``T_u(x) − X_p``."""
    u = prob.obs.unit
    offset = prob.offset
    if prob.basis is not None:
        offset = offset + np.einsum("nik,nk->ni", prob.basis, st.coefficients[u])
    y = st.scale[u, None] * np.einsum("nij,nj->ni", st.rotation[u], offset)
    v = st.translation[u] + y - st.points[prob.obs.point]
    return y, v


def _line_terms(prob: _Problem, st: _State, k: int) -> tuple[FloatArray, FloatArray, float]:
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
    if prob.polynomial is not None:
        total += float(np.sum(prob.prior_weights * st.coefficients**2))
    for k in range(prob.n_lines):
        _, e, w = _line_terms(prob, st, k)
        total += float(w * np.sum(e**2))
    return total


class _Normals:
    """Reduced normal equations of one iteration, ``S z = r`` for the blocks
    (units and lines), and what back-substitution and cofactors need:
    ``V⁻¹`` (P, 3, 3; 0 for unobserved points), ``reduce = N_zp V⁻¹``
    (sparse), the per-row ``N_zp`` blocks (n_r, 7, 3) and ``g_p`` (P, 3)."""

    def __init__(
        self,
        s_matrix: sp.csc_matrix,
        rhs: FloatArray,
        v_inv: FloatArray,
        reduce: sp.csr_matrix,
        n_zp_rows: FloatArray,
        g_p: FloatArray,
    ) -> None:
        self.s_matrix = s_matrix
        self.rhs = rhs
        self.v_inv = v_inv
        self.reduce = reduce
        self.n_zp_rows = n_zp_rows
        self.g_p = g_p


def _normals(prob: _Problem, st: _State) -> _Normals:
    import scipy.sparse as sp

    obs = prob.obs
    n = obs.unit.shape[0]
    y, v = _predict(prob, st)
    # Design of a row in its unit's 7 parameters: dt, dω (R <- exp(ω) R),
    # ds / s, then its polynomial's coefficients (s R B); its point's is -I.
    width = prob.width
    a_u = np.zeros((n, 3, width))
    a_u[:, 0, 0] = a_u[:, 1, 1] = a_u[:, 2, 2] = 1.0
    a_u[:, :, 3:6] = -skew(y)  # d(ω × y)/dω
    a_u[:, :, 6] = y
    if prob.basis is not None:
        u = obs.unit
        a_u[:, :, N_UNIT:] = st.scale[u, None, None] * (st.rotation[u] @ prob.basis)
    w = obs.weight
    wa = w @ a_u  # W A_u
    n_bb = [np.swapaxes(a_u, 1, 2) @ wa]  # (n, 7, 7)
    n_bp = [-np.swapaxes(wa, 1, 2)]  # A_uᵀ W A_p, A_p = -I
    n_pp = [w]
    g_b = [-np.einsum("nki,nk->ni", wa, v)]  # -A_uᵀ W v
    g_pr = [np.einsum("nij,nj->ni", w, v)]  # -A_pᵀ W v
    # lines: e = Y - a - b X; de = dY - b dX - da - X db
    for k in range(prob.n_lines):
        xyz, e, wl = _line_terms(prob, st, k)
        b = st.line_ab[k, 1]
        m = xyz.shape[0]
        d_p = np.zeros((m, 3))
        d_p[:, 0], d_p[:, 1] = -b, 1.0
        d_l = np.zeros((m, width))
        d_l[:, 0], d_l[:, 1] = -1.0, -xyz[:, 0]
        n_bb.append(wl * d_l[:, :, None] * d_l[:, None, :])
        n_bp.append(wl * d_l[:, :, None] * d_p[:, None, :])
        n_pp.append(wl * d_p[:, :, None] * d_p[:, None, :])
        g_b.append(-wl * d_l * e[:, None])
        g_pr.append(-wl * d_p * e[:, None])
    n_bb_r, n_bp_r = np.concatenate(n_bb), np.concatenate(n_bp)
    n_pp_r, g_b_r, g_p_r = np.concatenate(n_pp), np.concatenate(g_b), np.concatenate(g_pr)
    blocks = (prob.to_block @ n_bb_r.reshape(-1, width * width)).reshape(-1, width, width)
    fixed = prob.fixed
    blocks[:, np.arange(width), np.arange(width)] += fixed  # unused line slots
    g_z = prob.to_block @ g_b_r
    if prob.polynomial is not None:  # the coefficients' priors a = 0
        prior_w = prob.prior_weights
        extra = np.arange(N_UNIT, width)
        blocks[: prob.n_units, extra, extra] += prior_w
        g_z[: prob.n_units, N_UNIT:] -= prior_w * st.coefficients
    v_blocks = (prob.to_point @ n_pp_r.reshape(-1, 9)).reshape(-1, 3, 3)
    g_p = prob.to_point @ g_p_r
    # control
    cp, given, sig = prob.control_point, prob.control_given, prob.control_sigma
    cw = np.where(given, 1.0 / np.where(given, sig, 1.0) ** 2, 0.0)
    resid_c = np.where(given, st.points[cp] - np.where(given, prob.control_xyz, 0.0), 0.0)
    add_v = np.zeros((prob.n_points, 3))
    np.add.at(add_v, cp, cw)
    v_blocks[:, [0, 1, 2], [0, 1, 2]] += add_v
    g_pc = np.zeros((prob.n_points, 3))
    np.add.at(g_pc, cp, -cw * resid_c)
    g_p += g_pc
    # V⁻¹ block by block (unobserved points: 0)
    v_inv = np.zeros_like(v_blocks)
    try:
        v_inv[prob.observed] = np.linalg.inv(v_blocks[prob.observed])
    except np.linalg.LinAlgError as exc:
        raise GeometryError(
            "a point is not determined by its rows (singular 3 x 3 block)"
        ) from exc
    # Schur complement: S = N_zz − N_zp V⁻¹ N_pz, with N_zp V⁻¹ of N_zp's pattern
    n_zp = prob.zp_matrix(n_bp_r)
    reduce = prob.zp_matrix(n_bp_r @ v_inv[prob.row_point])
    n_zz = sp.bsr_matrix(
        (blocks, np.arange(prob.n_blocks), np.arange(prob.n_blocks + 1)),
        shape=(prob.n_reduced, prob.n_reduced),
    )
    s_matrix = (n_zz - reduce @ n_zp.T).tocsc()
    rhs = g_z.ravel() - reduce @ g_p.ravel()
    rhs[fixed.ravel()] = 0.0
    return _Normals(s_matrix, rhs, v_inv, reduce, n_bp_r, g_p)


def _factor(s_matrix: sp.csc_matrix) -> tuple[spl.SuperLU, FloatArray]:
    """SuperLU factors of the reduced matrix, Jacobi-scaled; raises
    GeometryError when it is singular (units not tied to the control)."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spl

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


def _solve_reduced(lu: spl.SuperLU, scale: FloatArray, rhs: FloatArray) -> FloatArray:
    solution: FloatArray = scale * lu.solve(scale * rhs)
    return solution


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
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    tolerance: float = 1e-10,
    statistics: bool = True,
    polynomial: UnitPolynomial | None = None,
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
    statistics : bool
        Compute the cofactors of the control points and lines (their
        redundancy numbers and w); without them (False) those fields are
        NaN, at a fraction of the cost (start values, intermediate passes).
    polynomial : UnitPolynomial, optional
        A deformation polynomial of every unit, adjusted with its
        similarity (the block of independent strips, R4 3); the start's
        coefficients are used when it has them, else zeros.

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
    prob = _Problem(
        obs, n_units, n_points, control_point, control_xyz, control_sigma, lines, polynomial
    )
    # The start's similarity re-expressed about each unit's own centroid
    # (its deformation, if any, kept as it is).
    s0 = np.asarray(start.scale, dtype=np.float64).copy()
    r0 = np.asarray(start.rotation, dtype=np.float64).copy()
    coefficients = np.zeros((n_units, prob.n_extra))
    if polynomial is None:
        t0 = start.apply(np.arange(n_units), prob.centroid)
    else:
        shift = np.einsum("uij,uj->ui", r0, prob.centroid - start.centroid)
        t0 = start.translation + s0[:, None] * shift
        if start.coefficients is not None and start.coefficients.shape == coefficients.shape:
            coefficients = np.array(start.coefficients, dtype=np.float64)
    points = np.array(points0, dtype=np.float64, copy=True)
    line_ab = np.zeros((prob.n_lines, 2))
    for k, line in enumerate(prob.lines):
        xyz = points[line.point]
        design = np.column_stack([np.ones(len(xyz)), xyz[:, 0]])
        line_ab[k] = np.linalg.lstsq(design, xyz[:, 1], rcond=None)[0]
    st = _State(s0, r0, t0, points, line_ab, coefficients)
    extent = (
        float(np.nanmax(np.ptp(points[prob.observed], axis=0))) if prob.observed.any() else 1.0
    )
    extent = max(extent, 1.0)

    cost = _cost(prob, st)
    converged = False
    iterations = 0
    normals = None
    for iterations in range(1, max_iterations + 1):  # noqa: B007 (reported after the loop)
        normals = _normals(prob, st)
        lu, scale = _factor(normals.s_matrix)
        dz = _solve_reduced(lu, scale, normals.rhs)
        dp = _back_substitute(prob, normals, dz)
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
        du = dz[: prob.width * n_units].reshape(n_units, prob.width) * step
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
    if not converged:
        normals = _normals(prob, st)
        lu, scale = _factor(normals.s_matrix)
    assert normals is not None  # set in the loop, or just above
    # Converged: the normal equations of the last step serve the statistics
    # (the state moved by less than the tolerance since).
    return _result(prob, st, normals, lu, scale, cost, iterations, converged, statistics)


def _back_substitute(prob: _Problem, normals: _Normals, dz: FloatArray) -> FloatArray:
    """Point corrections ``V⁻¹ (g_p − N_pz dz)`` (P, 3)."""
    dz_rows = dz.reshape(-1, prob.width)[prob.row_block]  # (n_r, width)
    coupled = prob.to_point @ np.einsum("rki,rk->ri", normals.n_zp_rows, dz_rows)
    corrections: FloatArray = np.einsum("pij,pj->pi", normals.v_inv, normals.g_p - coupled)
    return corrections


def _step(prob: _Problem, st: _State, dz: FloatArray, dp: FloatArray, step: float) -> _State:
    n_u, width = prob.n_units, prob.width
    du = dz[: width * n_u].reshape(n_u, width) * step
    dl = dz[width * n_u :].reshape(-1, width)[:, :2] * step
    rotation = matrix_from_rotvec(du[:, 3:6]) @ st.rotation
    points = st.points + step * dp
    return _State(
        st.scale * (1.0 + du[:, 6]),
        rotation,
        st.translation + du[:, :3],
        points,
        st.line_ab + dl,
        st.coefficients + du[:, N_UNIT:],
    )


def _result(
    prob: _Problem,
    st: _State,
    normals: _Normals,
    lu: spl.SuperLU,
    scale: FloatArray,
    cost: float,
    iterations: int,
    converged: bool,
    statistics: bool = True,
) -> SimultaneousResult:
    obs = prob.obs
    _, v = _predict(prob, st)
    redundancy = prob.n_observations - prob.n_unknowns
    sigma0 = float(np.sqrt(cost / redundancy)) if redundancy > 0 else float("nan")

    # Cofactors of the control points: Q_pp = V⁻¹ + V⁻¹ N_pz S⁻¹ N_zp V⁻¹.
    cp = prob.control_point
    if statistics:  # the diagonal of the given components: what the tests need
        cof = point_cofactors(normals, lu, scale, cp, prob.control_given)
    else:
        cof = np.full((cp.shape[0], 3, 3), np.nan)
    given = prob.control_given
    resid_c = np.where(given, prob.control_xyz - st.points[cp], np.nan)
    sig = prob.control_sigma
    q_diag = np.einsum("cii->ci", cof)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(given, 1.0 - q_diag / np.where(given, sig, 1.0) ** 2, np.nan)
        w = resid_c / (sig * np.sqrt(np.maximum(r, 0.0)))
    w[~(r > _MIN_TESTED_REDUNDANCY)] = np.nan

    # Row statistics: the row's leverage on its own point with the units
    # fixed, h = W^(1/2) V⁻¹ W^(1/2); the units' 7 U parameters spread evenly.
    lt = prob.whiten
    wv = np.einsum("nij,nj->ni", lt, v)
    h = lt @ normals.v_inv[obs.point] @ np.swapaxes(lt, 1, 2)
    free = 3.0 - np.einsum("nii->n", h)
    share = max(1.0 - prob.width * prob.n_units / max(float(free.sum()), 1e-300), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        stat = np.einsum("ni,ni->n", wv, wv) / (free * share)
    # a row alone on its point (a point of one model) cannot be tested
    stat[~(free * share > 1e-6)] = np.nan

    line_resid = []
    line_w = []
    line_r = []
    for k, line in enumerate(prob.lines):
        xyz, e, _ = _line_terms(prob, st, k)
        if statistics:
            r_line = 1.0 - _line_cofactors(prob, st, normals, lu, scale, k, xyz) / line.sigma**2
        else:
            r_line = np.full(e.shape, np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            wl = e / (line.sigma * np.sqrt(np.maximum(r_line, 0.0)))
        wl[~(r_line > _MIN_TESTED_REDUNDANCY)] = np.nan
        line_resid.append(e)
        line_w.append(wl)
        line_r.append(r_line)
    coefficient_variance = None
    if prob.polynomial is not None:  # a handful of columns: every unit's terms
        cols = (
            prob.width * np.arange(prob.n_units)[:, None] + np.arange(N_UNIT, prob.width)
        ).ravel()
        unit_vectors = np.zeros((scale.shape[0], cols.shape[0]))
        unit_vectors[cols, np.arange(cols.shape[0])] = 1.0
        x = scale[:, None] * lu.solve(scale[:, None] * unit_vectors)
        coefficient_variance = x[cols, np.arange(cols.shape[0])].reshape(prob.n_units, -1)
    transforms = UnitTransforms(
        st.scale,
        st.rotation,
        st.translation,
        prob.centroid,
        prob.polynomial,
        None if prob.polynomial is None else st.coefficients.copy(),
    )
    points = st.points.copy()
    points[~prob.observed] = np.nan
    probe = probe_sigma = None
    if statistics:
        probe, probe_sigma = _probe_plan_sigma(prob, normals, lu, scale)
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
        coefficient_variance=coefficient_variance,
        probe_points=probe,
        probe_plan_sigma=probe_sigma,
    )


_PROBES = 24
"""Units whose plan precision :func:`_probe_plan_sigma` computes, at most."""


def _probe_plan_sigma(
    prob: _Problem, normals: _Normals, lu: spl.SuperLU, scale: FloatArray
) -> tuple[IntArray, FloatArray]:
    """For at most :data:`_PROBES` units evenly along the block, the point most
    units share (ties first) and its a priori plan standard deviation (two
    solves each); -1 and NaN for the other units."""
    obs = prob.obs
    shared = np.bincount(obs.point, minlength=prob.n_points)
    order = np.lexsort((-shared[obs.point], obs.unit))
    units, first = np.unique(obs.unit[order], return_index=True)
    probe = np.full(prob.n_units, -1, dtype=np.intp)
    probe[units] = obs.point[order[first]]
    # at most _PROBES units evenly along the block: the precision varies slowly
    # from unit to unit, and every probe costs two solves
    sampled = np.zeros(prob.n_units, dtype=bool)
    sampled[np.round(np.linspace(0, prob.n_units - 1, min(prob.n_units, _PROBES))).astype(int)] = (
        True
    )
    probe[~sampled] = -1
    sigma = np.full(prob.n_units, np.nan)
    has = probe >= 0
    if has.any():
        plan = np.zeros((int(has.sum()), 3), dtype=bool)
        plan[:, :2] = True
        cof = point_cofactors(normals, lu, scale, probe[has], plan)
        sigma[has] = np.sqrt(np.maximum(cof[:, 0, 0] + cof[:, 1, 1], 0.0))
    return probe, sigma


def _line_cofactors(
    prob: _Problem,
    st: _State,
    normals: _Normals,
    lu: spl.SuperLU,
    scale: FloatArray,
    k: int,
    xyz: FloatArray,
) -> FloatArray:
    """Cofactors of the adjusted ``e = Y − a − b X`` of line k's points (m,).

    With ``d_p = (−b, 1, 0)`` the derivative by the point and ``d_z`` by the
    reduced unknowns (``−1, −X`` at the line's ``a, b``), and
    ``u = N_zp V⁻¹ d_p``: ``q_ee = d_pᵀ V⁻¹ d_p + (u − d_z)ᵀ S⁻¹ (u − d_z)``.
    """
    import scipy.sparse as sp

    line = prob.lines[k]
    points = line.point
    m = points.shape[0]
    d_p = np.zeros((m, 3))
    d_p[:, 0], d_p[:, 1] = -st.line_ab[k, 1], 1.0
    vd = np.einsum("mij,mj->mi", normals.v_inv[points], d_p)  # V⁻¹ d_p
    cols = (3 * points[:, None] + np.arange(3)).ravel()
    sel = sp.csr_matrix(
        (d_p.ravel(), (cols, np.repeat(np.arange(m), 3))), shape=(3 * prob.n_points, m)
    )
    u = (normals.reduce @ sel).toarray()  # N_zp V⁻¹ d_p: (nz, m)
    col0 = prob.width * (prob.n_units + k)
    u[col0] += 1.0  # − d_z: d_z = −1 at a
    u[col0 + 1] += xyz[:, 0]  # and −X at b
    x = scale[:, None] * lu.solve(scale[:, None] * u)
    cofactors: FloatArray = np.einsum("mi,mi->m", d_p, vd) + np.einsum("zm,zm->m", u, x)
    return cofactors


_COFACTOR_CHUNK = 768  # right-hand sides per solve (memory: 768 x n_reduced)


def point_cofactors(
    normals: _Normals,
    lu: spl.SuperLU,
    scale: FloatArray,
    points: IntArray,
    components: BoolArray | None = None,
) -> FloatArray:
    """Cofactor blocks (C, 3, 3) of adjusted points at the solution:
    ``Q_pp = V⁻¹ + V⁻¹ N_pz S⁻¹ N_zp V⁻¹``, solved in chunks of columns.

    With ``components`` (C, 3) only the diagonal entries of the components
    asked for are computed (one solve each instead of three per point: the
    redundancy numbers of a height point need its height only); the other
    entries are NaN.
    """
    n_c = points.shape[0]
    out = normals.v_inv[points].copy()
    reduce = normals.reduce.tocsc()
    if components is None:
        for lo in range(0, n_c, _COFACTOR_CHUNK // 3):
            chunk = points[lo : lo + _COFACTOR_CHUNK // 3]
            m = chunk.shape[0]
            cols = (3 * chunk[:, None] + np.arange(3)).ravel()
            b = reduce[:, cols].toarray()  # (N_zp V⁻¹) restricted to the chunk: (nz, 3m)
            x = scale[:, None] * lu.solve(scale[:, None] * b)
            out[lo : lo + m] += np.einsum("zci,zcj->cij", b.reshape(-1, m, 3), x.reshape(-1, m, 3))
        return out
    owner, axis = np.nonzero(components)
    diagonal = out[owner, axis, axis]
    out[:] = np.nan
    cols_all = 3 * points[owner] + axis
    for lo in range(0, cols_all.shape[0], _COFACTOR_CHUNK):
        cols = cols_all[lo : lo + _COFACTOR_CHUNK]
        b = reduce[:, cols].toarray()
        x = scale[:, None] * lu.solve(scale[:, None] * b)
        diagonal[lo : lo + cols.shape[0]] += np.einsum("zk,zk->k", b, x)
    out[owner, axis, axis] = diagonal
    return out
