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

Gauss-Newton on the linearised rotations (``R ← exp([ω]×) R``), each step
by the structured normal-equation engine (:mod:`strip_aerotri.geometry.normals`,
method.md §6B): the points eliminated block by block (3 × 3), the reduced
system of the units solved as a block band by LAPACK's banded Cholesky
(units in their order along the strip, or reverse Cuthill-McKee where
narrower, as in a block), the lines' ``a, b`` as its dense border; the
cofactors of the tests by the selected inverse of the banded factor.  One
iteration costs time linear in the observations.  Units are Cartesian
frames in metres or model units; the points are in the work frame (metres).

References: Ackermann, Ebner, Klein (1970), "Block triangulation with
independent models", Photogrammetric Engineering 36; R4 §2.2-§3.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ..errors import ConvergenceError, GeometryError
from ..options import DEFAULT_MAX_ITERATIONS
from ._row_kernels import by_rows as _by_rows
from ._row_kernels import row_gram as _gram
from ._row_kernels import rows_whitening as _rows_whitening
from ._row_kernels import upper_entries, upper_times
from .rotation import matrix_from_rotvec
from .units import (
    N_UNIT,
    LineCondition,
    SimultaneousResult,
    UnitObservations,
    UnitPolynomial,
    UnitTransforms,
    WeightLead,
    baarda_delta,
)

if TYPE_CHECKING:
    from .normals import NormalSolution

__all__ = [
    "LineCondition",
    "SimultaneousResult",
    "UnitObservations",
    "UnitPolynomial",
    "UnitTransforms",
    "adjust_units",
    "baarda_delta",
]

#: Below this redundancy number an observation is not tested (its w is NaN):
#: a share of 1e-3 of its error shows in its residual, so the least model
#: imperfection (the correlations a model's relative orientation puts
#: between its points are left out of the weights) looks like a blunder of
#: metres (a 0.1 mm residual at r = 1.4e-5 gave w = 4.9, "estimated error
#: 8.8 m", on a drone strip with four full points).  Its minimal detectable
#: error (σ δ0 / √r, more than 150 σ) is reported instead.
_MIN_TESTED_REDUNDANCY = 1e-3
#: Radians a unit must turn before its rows' weights are turned with it
#: (``weight_rotation``).  Where the solution is weakly held (the middle of
#: a long strip between plan points) a weight turned off moves the points by
#: far more than that share of their residuals: at 1e-6 rad the solution of
#: a 3000-photo strip depended on the path to it by 0.8 mm (two starts);
#: at 1e-10 rad by 1.3e-6 m.
_WEIGHT_TURN = 1e-10


class _Problem:
    """Fixed structure of an adjustment: rows, control, lines and indices.

    The unknowns of the normal-equation engine
    (:mod:`strip_aerotri.geometry.normals`): every unit a block of ``width``
    parameters (7, then its polynomial's coefficients), every point that a
    row observes (numbered ``engine_point``), and the lines' ``a, b`` as the
    dense border (2 per line: a line ties points all along the strip).
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
        order: Literal["auto", "given", "rcm"] | IntArray = "auto",
        weight_rotation: FloatArray | None = None,
    ):
        from .normals import NormalStructure

        self.obs = obs
        self.polynomial = polynomial
        self.n_extra = 0 if polynomial is None else polynomial.n_terms
        self.width = N_UNIT + self.n_extra  # parameters of a unit
        self.n_units = n_units
        self.n_points = n_points
        self.whiten0 = _rows_whitening(obs.weight)
        self.whiten = self.whiten0
        self.whiten0_entries = upper_entries(self.whiten0)  # for turn_weights
        self.weight_rotation = weight_rotation
        self.turned_at: FloatArray | None = None
        self.control_point = control_point
        self.control_xyz = control_xyz
        self.control_sigma = control_sigma
        self.control_given = np.isfinite(control_xyz)
        self.lines = list(lines)
        self.n_lines = len(self.lines)
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
        # the engine's points: those a row observes (others stay where they are)
        self.points_used = np.flatnonzero(self.observed)
        self.engine_point = np.full(n_points, -1, dtype=np.intp)
        self.engine_point[self.points_used] = np.arange(self.points_used.size)
        self.control_used = self.observed[control_point]
        self.line_used = [self.observed[line.point] for line in self.lines]
        self.unit_index = np.arange(n_units, dtype=np.intp)[:, None]
        self.point_jacobian = -self.whiten  # Lᵀ ∂v/∂X_p, ∂v/∂X_p = -I
        self.structure = NormalStructure.from_indices(
            n_units,
            self.width,
            self.points_used.size,
            obs.unit,
            self.engine_point[obs.point],
            [self.unit_index] if self.n_extra else [],
            n_border=2 * self.n_lines,
            order=order,
        )

    def set_control(self, control_xyz: FloatArray) -> None:
        """New control coordinates (C, 3), NaN where not given (the same
        components as before)."""
        control_xyz = np.asarray(control_xyz, dtype=np.float64).reshape(self.control_xyz.shape)
        if not np.array_equal(np.isfinite(control_xyz), self.control_given):
            raise ValueError("Expected the control update to give the same components")
        self.control_xyz = control_xyz

    def turn_weights(self, rotation: FloatArray) -> bool:
        """The rows' whitening at the units' ``rotation`` (U, 3, 3): the weights
        given at :attr:`weight_rotation` turned with their unit,
        ``W = Δ W₀ Δᵀ``, ``Δ = R R₀ᵀ`` (whitening ``L₀ᵀ Δᵀ``).  Only when a
        unit has turned by more than :data:`_WEIGHT_TURN` since the weights
        were last turned (below it the weights' change moves the solution by
        nothing that counts, and holding them lets the iterations converge
        quadratically); True when turned."""
        if self.weight_rotation is None:
            return False
        if self.turned_at is not None:
            # |R - R_t| (Frobenius) / sqrt(2) is the angle between them, to first order
            moved = np.sqrt(np.einsum("uij,uij->u", *(rotation - self.turned_at,) * 2) / 2.0)
            if not float(np.max(moved, initial=0.0)) > _WEIGHT_TURN:
                return False
        self.turned_at = rotation.copy()
        delta_t = np.swapaxes(rotation @ np.swapaxes(self.weight_rotation, 1, 2), 1, 2)
        delta_entries = np.ascontiguousarray(delta_t.reshape(-1, 9).T)  # (9, U)
        unit, entries = self.obs.unit, self.whiten0_entries
        shape = self.whiten0.shape
        whiten, point_jacobian = np.empty(shape), np.empty(shape)

        def block(rows: slice) -> None:
            # L₀ᵀ is upper triangular: its product with Δᵀ entry by entry
            g = np.take(delta_entries, unit[rows], axis=1)
            whiten[rows] = upper_times(entries[:, rows], g)
            np.negative(whiten[rows], out=point_jacobian[rows])

        _by_rows(unit.size, block)
        self.whiten, self.point_jacobian = whiten, point_jacobian
        return True

    @property
    def n_observations(self) -> int:
        n_line = sum(int(line.point.shape[0]) for line in self.lines)
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
        self.turned: FloatArray | None = None  # s R (x − c) of the rows, once computed
        self.residual: FloatArray | None = None  # T_u(x) − X_p of the rows, once computed
        # Σ ‖Lᵀ v‖² of the rows with the whitening it was computed with, once computed
        self.rows_cost: tuple[FloatArray, float] | None = None

    def with_points(self, points: FloatArray) -> _State:
        """The same units (and their rows as turned) with other points."""
        moved = _State(
            self.scale, self.rotation, self.translation, points, self.line_ab, self.coefficients
        )
        moved.turned = self.turned
        return moved


def _predict(prob: _Problem, st: _State) -> tuple[FloatArray, FloatArray]:
    """Rows in the work frame relative to their unit's translation
    (``s R (x − c)``, n × 3) and their residuals ``T_u(x) − X_p``."""
    y = _turned(prob, st)
    v = st.residual
    if v is None:
        st.residual = v = st.translation[prob.obs.unit] + y - st.points[prob.obs.point]
    return y, v


def _turned(prob: _Problem, st: _State) -> FloatArray:
    """``s R (x − c)`` of the rows (n, 3), once per state."""
    u = prob.obs.unit
    y = st.turned
    if y is None:
        basis, coefficients = prob.basis, st.coefficients
        turned = np.empty(prob.offset.shape)

        def block(rows: slice) -> None:
            offset = prob.offset[rows]
            if basis is not None:
                offset = offset + np.einsum("nik,nk->ni", basis[rows], coefficients[u[rows]])
            ur = u[rows]
            turned[rows] = st.scale[ur, None] * np.einsum("nij,nj->ni", st.rotation[ur], offset)

        _by_rows(u.size, block)
        st.turned = y = turned
    return y


def _whitened(prob: _Problem, v: FloatArray) -> FloatArray:
    """``Lᵀ v`` of every row (n, 3), by blocks of rows (:func:`_by_rows`)."""
    whiten = prob.whiten
    out = np.empty(v.shape)

    def block(rows: slice) -> None:
        out[rows] = np.einsum("nij,nj->ni", whiten[rows], v[rows])

    _by_rows(v.shape[0], block)
    return out


def _line_terms(prob: _Problem, st: _State, k: int) -> tuple[FloatArray, FloatArray, float]:
    line = prob.lines[k]
    xyz = st.points[line.point]
    a, b = st.line_ab[k]
    e = xyz[:, 1] - a - b * xyz[:, 0]
    return xyz, e, 1.0 / line.sigma**2


def _cost(prob: _Problem, st: _State) -> float:
    """The weighted sum of squares at ``st``: the rows' share computed once
    per state and whitening (the control moving between passes leaves it)."""
    if st.rows_cost is not None and st.rows_cost[0] is prob.whiten:
        total = st.rows_cost[1]
    else:
        _, v = _predict(prob, st)
        wv = _whitened(prob, v)
        total = float(np.einsum("ij,ij->", wv, wv))
        st.rows_cost = (prob.whiten, total)
    c = st.points[prob.control_point] - prob.control_xyz
    g = prob.control_given
    total += float(np.sum((c[g] / prob.control_sigma[g]) ** 2))
    if prob.polynomial is not None:
        total += float(np.sum(prob.prior_weights * st.coefficients**2))
    for k in range(prob.n_lines):
        _, e, w = _line_terms(prob, st, k)
        total += float(w * np.sum(e**2))
    return total


def _engine_rows(prob: _Problem, st: _State) -> tuple[list[Any], list[Any], list[Any]]:
    """The rows of the linearised problem at ``st`` for the engine: the unit
    observations (whitened), the coefficients' priors, and the control and
    line equations on the points (the lines' ``a, b`` in the border)."""
    from .normals import UnitPointRows, UnitRows

    obs = prob.obs
    y, v = _predict(prob, st)
    unit_point = [
        UnitPointRows(
            obs.unit,
            prob.engine_point[obs.point],
            _whitened_design(prob, st, y),
            prob.point_jacobian,
            _whitened(prob, v),
        )
    ]
    unit_rows = []
    if prob.n_extra:  # the coefficients' priors a = 0
        jac = np.zeros((prob.n_units, prob.n_extra, 1, prob.width))
        jac[:, np.arange(prob.n_extra), 0, N_UNIT + np.arange(prob.n_extra)] = 1.0
        unit_rows.append(
            UnitRows(prob.unit_index, jac, st.coefficients.copy(), prob.prior_weights)
        )
    return unit_point, unit_rows, _point_rows(prob, st)


def _whitened_design(prob: _Problem, st: _State, y: FloatArray) -> FloatArray:
    """``Lᵀ A`` of every row (n, 3, width): the design ``A`` of a row in its
    unit's parameters is ``[I | -[y]× | y | s R B]`` (dt, dω with
    ``R <- exp(ω) R``, ds / s, then its polynomial's coefficients; its
    point's is -I), so ``Lᵀ A = [Lᵀ | rows y × l_i | Lᵀ y | Lᵀ s R B]``
    with ``l_i`` the rows of ``Lᵀ`` (written out: a batched product of
    3 × 3 by 3 × 7 matrices costs three times as much)."""
    whiten = prob.whiten
    out = np.empty((whiten.shape[0], 3, prob.width))
    u, basis = prob.obs.unit, prob.basis

    def block(rows: slice) -> None:
        lt, yr, o = whiten[rows], y[rows], out[rows]
        o[:, :, 0:3] = lt
        l0, l1, l2 = lt[:, :, 0], lt[:, :, 1], lt[:, :, 2]
        y0, y1, y2 = yr[:, 0, None], yr[:, 1, None], yr[:, 2, None]
        o[:, :, 3] = y1 * l2 - y2 * l1  # (y × l_i), the rows of -Lᵀ [y]×
        o[:, :, 4] = y2 * l0 - y0 * l2
        o[:, :, 5] = y0 * l1 - y1 * l0
        o[:, :, 6] = l0 * y0 + l1 * y1 + l2 * y2
        if basis is not None:
            ur = u[rows]
            o[:, :, N_UNIT:] = lt @ (st.scale[ur, None, None] * (st.rotation[ur] @ basis[rows]))

    _by_rows(whiten.shape[0], block)
    return out


def _point_rows(prob: _Problem, st: _State) -> list[Any]:
    """Control (``X_p − X_c``, weight 1/σ² on the given components) and line
    equations (``Y − a − b X``, weight 1/σ², ``a, b`` in the border) at ``st``."""
    from .normals import PointRows

    cp, f, weight = _control_terms(prob, st)
    rows = [PointRows(prob.engine_point[cp], np.broadcast_to(np.eye(3), (cp.shape[0], 3, 3)),
                      f, weight)]
    for k in range(prob.n_lines):
        rows.append(_line_rows(prob, st, k))
    return rows


def _control_terms(prob: _Problem, st: _State) -> tuple[IntArray, FloatArray, FloatArray]:
    """The control rows on observed points: their point, their residual
    ``X_p − X_c`` and weight ``1/σ²`` (C, 3), both 0 where not given."""
    used = prob.control_used
    cp, given = prob.control_point[used], prob.control_given[used]
    f = np.where(given, st.points[cp] - np.where(given, prob.control_xyz[used], 0.0), 0.0)
    weight = np.where(given, 1.0 / np.where(given, prob.control_sigma[used], 1.0) ** 2, 0.0)
    return cp, f, weight


def _line_rows(prob: _Problem, st: _State, k: int) -> Any:
    """Line k's equations ``e = Y − a − b X`` of its (observed) points:
    ``de = dY − b dX − da − X db``."""
    from .normals import PointRows

    xyz, e, wl = _line_terms(prob, st, k)
    used = prob.line_used[k]
    m = int(used.sum())
    d_p = np.zeros((m, 1, 3))
    d_p[:, 0, 0], d_p[:, 0, 1] = -st.line_ab[k, 1], 1.0
    d_b = np.zeros((m, 1, 2 * prob.n_lines))
    d_b[:, 0, 2 * k], d_b[:, 0, 2 * k + 1] = -1.0, -xyz[used, 0]
    return PointRows(
        prob.engine_point[prob.lines[k].point[used]],
        d_p,
        e[used, None],
        np.full((m, 1), wl),
        d_b,
    )


def _solve(prob: _Problem, st: _State) -> NormalSolution:
    """The step of one Gauss-Newton iteration at ``st``, with the points'
    ``V⁻¹`` of its normal equations (their rows' and their control's
    weights: :attr:`NormalSolution.point_inverse`, in the order of
    :attr:`_Problem.points_used`) and its cofactors."""
    from .normals import SingularNormalsError

    unit_point, unit_rows, point_rows = _engine_rows(prob, st)
    try:
        return prob.structure.solve(unit_point, unit_rows, point_rows)
    except SingularNormalsError as exc:
        if exc.kind == "unit":
            what = f"unit {exc.index} shares too few points with the others and the control"
        elif exc.kind == "point":
            what = f"point {int(prob.points_used[exc.index])} is not fixed by its rows"
        else:  # the border: a line's a, b
            what = f"line {exc.index // 2} is not fixed by its points"
        raise GeometryError(f"the units are not determined: {what}") from exc


def _gradients(prob: _Problem, st: _State) -> tuple[FloatArray, FloatArray]:
    """``Aᵀ P f`` of the units (U, width) and of the engine's points (p, 3) at
    ``st``: the right-hand side :meth:`NormalStructure.form` would form for
    a chord step (no lines, no polynomial).

    Without the design: a row's is ``A = [I | -[y]× | y]`` on its unit and
    ``-I`` on its point, so with ``q = W v`` (``W = L Lᵀ``) its share is
    ``Aᵀ q = [q, y × q, y · q]`` and ``-q``."""
    from ._normal_assembly import sum_into

    obs = prob.obs
    y, v = _predict(prob, st)
    lt = prob.whiten
    per_row = np.empty((v.shape[0], N_UNIT))

    def block(rows: slice) -> None:
        lr, yr = lt[rows], y[rows]
        q = np.einsum("nji,nj->ni", lr, np.einsum("nij,nj->ni", lr, v[rows]))  # L Lᵀ v
        out = per_row[rows]
        out[:, 0:3] = q
        out[:, 3:6] = np.cross(yr, q)
        out[:, 6] = np.einsum("ni,ni->n", yr, q)

    _by_rows(v.shape[0], block)
    g_unit = sum_into(obs.unit, per_row, prob.n_units)
    n_used = prob.points_used.size
    g_point = -sum_into(prob.engine_point[obs.point], per_row[:, 0:3], n_used)
    cp, f, weight = _control_terms(prob, st)
    g_point += sum_into(prob.engine_point[cp], weight * f, n_used)
    return g_unit, g_point


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
    order: Literal["auto", "given", "rcm"] | IntArray = "auto",
    weight_rotation: ArrayLike | None = None,
    control_update: Callable[[FloatArray, bool], FloatArray | None] | None = None,
    project_points: bool = False,
) -> SimultaneousResult:
    """Transform all units at once to the control and to each other.

    Length: most of it is the documentation of its eighteen parameters; the
    iteration is :func:`_iterate`, its pieces in the functions below.

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
        NaN, at a fraction of the cost (start values, intermediate passes),
        and :meth:`SimultaneousResult.with_statistics` computes them later
        from the factor of the last step.
    polynomial : UnitPolynomial, optional
        A deformation polynomial of every unit, adjusted with its
        similarity (the block of independent strips, R4 3); the start's
        coefficients are used when it has them, else zeros.
    order : "auto", "given", "rcm" or array of int (U,)
        The units' order along the band of the reduced normal equations
        (:class:`~strip_aerotri.geometry.normals.NormalStructure`): as
        numbered, reverse Cuthill-McKee, the narrower of the two ("auto"),
        or the unit at each place.  It changes the cost, not the solution.
    weight_rotation : array_like, shape (U, 3, 3), optional
        The units' rotations at which the rows' weights are given: the
        weights are then the information of the rows in their unit and turn
        with it, ``W = Δ W₀ Δᵀ`` with ``Δ = R_u R₀ᵀ`` (a model point is weak
        along its rays wherever the model is turned to).  They are turned at
        the start of every iteration (iteratively reweighted: the step of an
        iteration holds them), ahead to where the units are heading when two
        steps turn them the same way
        (:class:`~strip_aerotri.geometry.units.WeightLead`).  None: the
        weights are fixed in the work frame.
    control_update : callable, optional
        Called after every iteration with the points (P, 3, work frame) and
        whether the iteration met the tolerance; returns the control
        coordinates (C, 3) for the next iteration, or None when they stay:
        control whose coordinates depend on the adjustment (a plan point's
        height in a curved work frame, guessed from its adjusted position).
        The adjustment converges only in an iteration after which they stay.
    project_points : bool
        At the start and after every step put each point where its rows and
        its control put it for the units' transforms (the least-squares point with the
        units held; without lines only): the linearised step moves a point
        along the tangent of its unit's turn, which from start values far
        off (a long strip's model turned by a radian) lands it metres away
        and makes the line search halve the step again and again.  The
        solution is the same.

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
        obs, n_units, n_points, control_point, control_xyz, control_sigma, lines, polynomial, order,
        None if weight_rotation is None
        else np.asarray(weight_rotation, dtype=np.float64).reshape(n_units, 3, 3),
    )  # fmt: skip
    from .._threads import compute_workers

    # the rows' own work (turning weights, the design, the residuals) shared
    # with the engine's worker thread where a second core is free
    with compute_workers(int(obs.unit.shape[0])):
        return _iterate(
            prob, start, points0, max_iterations, tolerance, statistics, control_update,
            project_points,
        )  # fmt: skip


def _iterate(
    prob: _Problem,
    start: UnitTransforms,
    points0: ArrayLike,
    max_iterations: int,
    tolerance: float,
    statistics: bool,
    control_update: Callable[[FloatArray, bool], FloatArray | None] | None,
    project_points: bool,
) -> SimultaneousResult:
    """:func:`adjust_units`' Gauss-Newton iterations from the start, and its
    result (Length: the loop of full and chord steps with the control's
    passes and the convergence test, in one place)."""
    st = _start_state(prob, start, points0)
    prob.turn_weights(st.rotation)
    if project_points:  # the points where the units put them, not yet the control
        st = _projected(prob, st)
    points = st.points
    extent = (
        float(np.nanmax(np.ptp(points[prob.observed], axis=0))) if prob.observed.any() else 1.0
    )
    extent = max(extent, 1.0)

    cost = _cost(prob, st)
    converged = False
    iterations = 0
    sol = None
    lead = WeightLead()
    # chord steps on the last factor once a full step was below chord_from
    chords = _Chords(prob, tolerance)
    for iterations in range(1, max_iterations + 1):
        if iterations > 1 and prob.turn_weights(lead.ahead(st.rotation)):
            cost = _cost(prob, st)
        taken = chords.step(st, sol, cost)
        if taken is None:
            sol = None  # the last step's factor goes before the next is formed
            sol = _solve(prob, st)
            taken = _full_step(prob, st, sol, cost, project_points)
        trial, trial_cost, du, dp = taken
        lead.record(du[:, 3:6])
        largest = max(
            float(np.max(np.abs(du[:, :3]), initial=0.0)) / extent,
            float(np.max(np.abs(du[:, 3:]), initial=0.0)),
            float(np.max(np.abs(dp[prob.observed]), initial=0.0)) / extent,
        )
        chords.record(largest)
        change = abs(cost - trial_cost) / max(cost, 1e-300)
        settled = largest < tolerance or change < tolerance
        st, cost = trial, trial_cost
        target = None if control_update is None else control_update(st.points, settled)
        if target is not None:  # the control moved: not converged yet
            prob.set_control(target)
            cost = _cost(prob, st)
        elif settled:
            converged = True
            break
    if not converged:
        sol = None
        if prob.turn_weights(st.rotation):
            cost = _cost(prob, st)
        sol = _solve(prob, st)
    assert sol is not None  # set in the loop, or just above
    # Converged: the normal equations of the last full step serve the
    # statistics (the state moved by less than the chords' threshold since).
    result = _result(prob, st, sol, cost, iterations, converged, statistics)
    if statistics:
        return result
    later = partial(_result, prob, st, sol, cost, iterations, converged, True)
    return replace(result, statistics_later=later)


def _full_step(
    prob: _Problem, st: _State, sol: NormalSolution, cost: float, project_points: bool
) -> tuple[_State, float, FloatArray, FloatArray]:
    """The Gauss-Newton step of ``sol`` from ``st``, halved until the sum of
    squares does not grow (the points projected after it, with
    ``project_points``): the state, its cost and the unit and point steps
    taken (U, width), (P, 3)."""
    dp = np.zeros((prob.n_points, 3))
    dp[prob.points_used] = sol.point_step
    step = 1.0
    for _ in range(30):
        trial = _step(prob, st, sol.unit_step, sol.border_step, dp, step)
        if project_points:
            trial = _projected(prob, trial, sol.point_inverse)
        trial_cost = _cost(prob, trial)
        if trial_cost <= cost * (1.0 + 1e-12) + 1e-300:
            return trial, trial_cost, sol.unit_step * step, dp * step
        step *= 0.5
    raise ConvergenceError(
        "the simultaneous transformation of the units diverges: no step lowers the "
        "sum of squares (start values too far off)"
    )


#: A full step below this many times the tolerance (relative, as the
#: convergence test measures it) is followed by chord steps (:class:`_Chords`).
_CHORD_FROM = 1e3
#: So is a full step below this move (relative, as the convergence test
#: measures it), whatever the tolerance: the normal matrix changes by about
#: that share, and the chord converges faster than the weights' turning lets
#: a full step converge (a 1000-photo strip's models: 5e-6, then chords of
#: 7e-8 and 1e-9 where full steps moved 7e-8 and then 1e-9).  At 1e-3 the
#: chord's slower convergence ends it 1.5 mm short on a weakly controlled
#: strip (the cost's change meets the tolerance first).
_CHORD_BELOW_MOVE = 1e-5


class _Chords:
    """Chord (simplified Gauss-Newton) steps near the solution.

    Once a full step has moved the unknowns by less than :data:`_CHORD_FROM`
    times the tolerance or less than :data:`_CHORD_BELOW_MOVE`, the normal
    matrix hardly changes any more (the units turn by 1e-5 rad and less):
    the next steps solve the new
    right-hand side ``Aᵀ P f`` (:func:`_gradients`) with the factor of that
    last full step (:meth:`NormalSolution.chord_step`), a fifth of a full
    step's cost, and the points follow their own step (no projection).
    They converge to the same solution (the one where the gradient
    vanishes, the weights turned with the units), as fast as full steps
    do there, where the weights' turning sets the pace.  A chord step
    that does not lower the sum of squares, or that is not below half the
    step before it, gives way to full steps again.  Without lines or
    polynomials only (their border and priors are not in the chord's
    right-hand side); the statistics then come from the last full factor.
    """

    def __init__(self, prob: _Problem, tolerance: float) -> None:
        self.prob = prob
        self.allowed = prob.n_lines == 0 and prob.polynomial is None
        self.threshold = max(_CHORD_FROM * tolerance, _CHORD_BELOW_MOVE)
        self.last_full = np.inf  # largest (relative) move of the last full step
        self.previous = np.inf  # of the step before the last
        self.last = np.inf  # of the last step
        self.was_chord = False
        self.chord = False  # the step being taken is a chord

    def step(
        self, st: _State, sol: NormalSolution | None, cost: float
    ) -> tuple[_State, float, FloatArray, FloatArray] | None:
        """A chord step from ``st`` with the factor of ``sol`` (state, cost,
        unit and point steps), or None where a full step is due."""
        self.chord = False
        ready = self.allowed and sol is not None and self.last_full < self.threshold
        if not ready or (self.was_chord and not self.last < 0.5 * self.previous):
            return None
        assert sol is not None  # ready
        prob = self.prob
        du, dp_used = sol.chord_step(*_gradients(prob, st))
        dp = np.zeros((prob.n_points, 3))
        dp[prob.points_used] = dp_used
        trial = _step(prob, st, du, sol.border_step, dp, 1.0)
        trial_cost = _cost(prob, trial)
        if not trial_cost <= cost * (1.0 + 1e-12) + 1e-300:
            return None
        self.chord = True
        return trial, trial_cost, du, dp

    def record(self, largest: float) -> None:
        """The largest move (relative) of the step just taken."""
        self.previous, self.last = self.last, largest
        self.was_chord = self.chord
        if not self.chord:
            self.last_full = largest


def _start_state(prob: _Problem, start: UnitTransforms, points0: ArrayLike) -> _State:
    """The start: its similarities re-expressed about each unit's own
    centroid (the deformation, if any, kept as it is), the points, and each
    line's ``a, b`` fitted to its points."""
    n_units = prob.n_units
    s0 = np.asarray(start.scale, dtype=np.float64).copy()
    r0 = np.asarray(start.rotation, dtype=np.float64).copy()
    coefficients = np.zeros((n_units, prob.n_extra))
    if prob.polynomial is None:
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
    return _State(s0, r0, t0, points, line_ab, coefficients)


def _projected(prob: _Problem, st: _State, inverse: FloatArray | None = None) -> _State:
    """``st`` with every observed point at its least-squares position for the
    units as they are: its rows only, or with ``inverse``, the ``V⁻¹`` of the
    points of the step's normal equations (their rows' and their control's
    weights, in the order of :attr:`_Problem.points_used`), its rows and its
    control.  Nothing when there are lines (they tie the points to each
    other), or when a point's rows do not fix it."""
    from ._normal_assembly import sum_into
    from ._normal_entries import point_factor

    if prob.n_lines:
        return st
    obs = prob.obs
    y = _turned(prob, st)
    lt = prob.whiten
    n = prob.n_points
    weighted = np.empty(y.shape)

    def block(rows: slice) -> None:
        placed = st.translation[obs.unit[rows]] + y[rows]  # T_u(x) of the rows
        # W x of each row, W = L Lᵀ (summed per point below)
        lr = lt[rows]
        weighted[rows] = np.einsum("nji,nj->ni", lr, np.einsum("nij,nj->ni", lr, placed))

    _by_rows(y.shape[0], block)
    rhs: FloatArray = np.column_stack(
        [np.bincount(obs.point, weighted[:, k], minlength=n) for k in range(3)]
    )
    used = prob.points_used
    if inverse is None:
        inverse = point_factor(sum_into(obs.point, _gram(lt), n)[used]).v_inv
        if not np.all(np.isfinite(inverse)):  # a point its rows do not fix: the step's own
            return st
    else:
        cp, given = prob.control_point, prob.control_given
        w_c = np.where(given, 1.0 / np.where(given, prob.control_sigma, 1.0) ** 2, 0.0)
        rhs += sum_into(cp, w_c * np.where(given, prob.control_xyz, 0.0), n)
    points = st.points.copy()
    assert inverse is not None  # computed above when not given
    points[used] = np.einsum("pij,pj->pi", inverse, rhs[used])
    return st.with_points(points)


def _step(
    prob: _Problem,
    st: _State,
    unit_step: FloatArray,
    border_step: FloatArray,
    dp: FloatArray,
    step: float,
) -> _State:
    du = unit_step * step
    dl = border_step.reshape(-1, 2) * step
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
    sol: NormalSolution,
    cost: float,
    iterations: int,
    converged: bool,
    statistics: bool = True,
) -> SimultaneousResult:
    """The solution with its tests' statistics (Length: every output field of
    the adjustment, each a few lines from the selected inverse)."""
    obs = prob.obs
    _, v = _predict(prob, st)
    redundancy = prob.n_observations - prob.n_unknowns
    sigma0 = float(np.sqrt(cost / redundancy)) if redundancy > 0 else float("nan")
    # every block of the selected inverse where the lines' or the coefficients'
    # statistics need it; else the control's and the probes' point blocks alone
    full = (statistics and prob.n_lines > 0) or prob.polynomial is not None
    cof = sol.cofactors() if full else None

    # Cofactors of the control points (the selected inverse's point blocks):
    # the diagonal of the given components, which the tests need.
    cp = prob.control_point
    given = prob.control_given
    q_diag = np.full(given.shape, np.nan)
    if statistics:
        q_all = np.zeros((cp.shape[0], 3, 3))  # a point no row observes: V⁻¹ = 0
        used = prob.control_used
        q_all[used] = sol.point_cofactors(prob.engine_point[cp[used]])
        q_diag = np.where(given, np.einsum("cii->ci", q_all), np.nan)
    cof_blocks = np.full((cp.shape[0], 3, 3), np.nan)
    cof_blocks[:, [0, 1, 2], [0, 1, 2]] = q_diag
    resid_c = np.where(given, prob.control_xyz - st.points[cp], np.nan)
    sig = prob.control_sigma
    with np.errstate(invalid="ignore", divide="ignore"):
        r = np.where(given, 1.0 - q_diag / np.where(given, sig, 1.0) ** 2, np.nan)
        w = resid_c / (sig * np.sqrt(np.maximum(r, 0.0)))
    w[~(r > _MIN_TESTED_REDUNDANCY)] = np.nan

    # Row statistics: the row's leverage on its own point with the units
    # fixed, h = W^(1/2) V⁻¹ W^(1/2); the units' 7 U parameters spread evenly.
    lt = prob.whiten
    wv = _whitened(prob, v)
    # V⁻¹ of the points the rows observe: the engine's (statistics only)
    v_inv = sol.point_inverse
    row_point = prob.engine_point[obs.point]
    leverage = np.empty(v.shape[0])

    def block(rows: slice) -> None:
        # trace(Lᵀ V⁻¹ L) = Σ_ij (L Lᵀ)_ij (V⁻¹)_ij
        leverage[rows] = np.einsum("nij,nij->n", _gram(lt[rows]), v_inv[row_point[rows]])

    _by_rows(v.shape[0], block)
    free = 3.0 - leverage
    share = max(1.0 - prob.width * prob.n_units / max(float(free.sum()), 1e-300), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        stat = np.einsum("ni,ni->n", wv, wv) / (free * share)
    # a row alone on its point (a point of one model) cannot be tested
    stat[~(free * share > 1e-6)] = np.nan

    line_resid = []
    line_w = []
    line_r = []
    for k, line in enumerate(prob.lines):
        _, e, _ = _line_terms(prob, st, k)
        r_line = np.full(e.shape, np.nan)
        if statistics and cof is not None:  # exact: with the line's a, b (the border)
            r_line[prob.line_used[k]] = cof.redundancy(_line_rows(prob, st, k))[:, 0]
        with np.errstate(invalid="ignore", divide="ignore"):
            wl = e / (line.sigma * np.sqrt(np.maximum(r_line, 0.0)))
        wl[~(r_line > _MIN_TESTED_REDUNDANCY)] = np.nan
        line_resid.append(e)
        line_w.append(wl)
        line_r.append(r_line)
    coefficient_variance = None
    if prob.polynomial is not None and cof is not None:
        extra = np.arange(N_UNIT, prob.width)
        coefficient_variance = cof.unit[:, extra, extra]
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
        probe, probe_sigma = _probe_plan_sigma(prob, sol)
    return SimultaneousResult(
        transforms=transforms,
        points=points,
        residuals=v.copy(),  # the state keeps its own
        row_statistic=stat,
        control_residuals=resid_c,
        control_cofactor=cof_blocks,
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
"""Units whose plan precision :func:`_probe_plan_sigma` gives, at most."""


def _probe_plan_sigma(prob: _Problem, sol: NormalSolution) -> tuple[IntArray, FloatArray]:
    """For at most :data:`_PROBES` units evenly along the block, the point most
    units share (ties first) and its a priori plan standard deviation (from
    the selected inverse's point block); -1 and NaN for the other units."""
    obs = prob.obs
    shared = np.bincount(obs.point, minlength=prob.n_points)
    order = np.lexsort((-shared[obs.point], obs.unit))
    units, first = np.unique(obs.unit[order], return_index=True)
    probe = np.full(prob.n_units, -1, dtype=np.intp)
    probe[units] = obs.point[order[first]]
    # at most _PROBES units evenly along the block: the precision varies slowly
    # from unit to unit
    sampled = np.zeros(prob.n_units, dtype=bool)
    sampled[np.round(np.linspace(0, prob.n_units - 1, min(prob.n_units, _PROBES))).astype(int)] = (
        True
    )
    probe[~sampled] = -1
    sigma = np.full(prob.n_units, np.nan)
    has = probe >= 0
    q = sol.point_cofactors(prob.engine_point[probe[has]])
    sigma[has] = np.sqrt(np.maximum(q[:, 0, 0] + q[:, 1, 1], 0.0))
    return probe, sigma
