"""The units of a simultaneous transformation (:mod:`strip_aerotri.geometry.simultaneous`):
their similarity transforms, their deformation polynomials, the coordinates of
points in them with their weights, the straight-line conditions, Baarda's
non-centrality for their tests, where to turn the rows' weights ahead of
the units (:class:`WeightLead`), and the result of their adjustment
(:class:`SimultaneousResult`).

A unit (a model of a strip, or a whole strip of a block) has coordinates of its
points in its own system; ``X = t_u + s_u R_u (x − c_u)`` takes them to the
work frame (``c_u`` the fixed centroid of the unit's coordinates, ``R_u`` an
active rotation premultiplying column vectors; metres or model units in, work
frame metres out).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from .rotation import matrix_from_rotvec

__all__ = [
    "N_UNIT",
    "LineCondition",
    "SimultaneousResult",
    "UnitObservations",
    "UnitPolynomial",
    "UnitTransforms",
    "WeightLead",
    "baarda_delta",
]

#: Parameters of a unit: translation (3), small rotation (3), relative scale.
N_UNIT = 7
_Z_BETA = 0.8416212335729143  # standard normal quantile of 0.8: power 80 %
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


class WeightLead:
    """Where to turn the weights for the next iteration (``weight_rotation``).

    Turning the weights to the units' rotations after every step is a
    fixed-point iteration: the step taken with the weights of one rotation
    turns the units on, by a share ``rho`` of the step before, where the
    solution is weakly held (the middle of a long strip between plan
    points: ``rho`` 0.5 at 10 000 photos, one halving per iteration).
    When two steps in a row turn the units the same way, the rest of that
    geometric series, ``rho / (1 - rho)`` times the last turn, is where
    they are heading: the weights are turned there at once (Aitken's
    extrapolation of the rotations; then two plain steps again to measure
    ``rho``).  The fixed point is the same: the lead vanishes with the
    steps."""

    def __init__(self) -> None:
        self.turns: list[FloatArray] = []
        self.led = False

    def record(self, turn: FloatArray) -> None:
        """The rotation vectors (U, 3) of the step just taken."""
        self.turns = [*self.turns[-1:], turn.copy()]

    def ahead(self, rotation: FloatArray) -> FloatArray:
        """The rotations (U, 3, 3) to turn the weights to, from the units' now."""
        if self.led or len(self.turns) < 2:
            self.led = False
            return rotation
        before, last = self.turns
        dot = float(np.vdot(before, last))
        norms = float(np.linalg.norm(before) * np.linalg.norm(last))
        if not norms > 0.0:
            return rotation
        rho = dot / float(np.vdot(before, before))
        if dot < _LEAD_COSINE * norms or not 0.0 < rho < _LEAD_MAX_RHO:
            return rotation
        self.led = True
        self.turns = []
        ahead: FloatArray = matrix_from_rotvec(last * (rho / (1.0 - rho))) @ rotation
        return ahead


#: Two steps turn the units "the same way" when their rotation vectors'
#: cosine is above this; the share ``rho`` of one step in the next is led
#: only below :data:`_LEAD_MAX_RHO` (above it the series is not geometric
#: enough to trust a lead of ``rho / (1 - rho)`` = 9 steps).
_LEAD_COSINE = 0.9
_LEAD_MAX_RHO = 0.9


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
    statistics_later : callable, optional
        Without the statistics (``statistics=False``): what computes them
        (:meth:`with_statistics`).
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
    statistics_later: Callable[[], SimultaneousResult] | None = field(
        default=None, repr=False, compare=False
    )

    def with_statistics(self) -> SimultaneousResult:
        """This result with the statistics of the control and lines, from the
        factor of its last full step (a result of ``statistics=False``; the
        adjustment is not solved again)."""
        return self if self.statistics_later is None else self.statistics_later()
