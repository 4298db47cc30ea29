"""Structured normal equations of strips and blocks (method.md 6B).

Every adjustment of photos or models along strips has the same shape: *units*
(photos with 6 parameters, or models/strips with 7 plus polynomial terms:
any fixed number ``d`` per problem) tied only to their neighbours along the
strip, *points* (3 parameters each) tied to a few units, and optionally a
dense *border* of ``k`` global parameters (self-calibration) tied to
anything.  This module forms and solves the linearised least-squares problem

    minimise  Σ ‖T (f + A δ)‖²       (T the whitening, Tᵀ T = P the weight)

by its normal equations ``N δ = -Aᵀ P f``: points eliminated by the Schur
complement (batched 3 x 3 inverses; the products summed per group of points
that share the same units), the reduced unit system held as a block band in
the units' order along the strip (or reverse Cuthill-McKee where that is
narrower) and factorised by LAPACK's banded Cholesky
(:func:`scipy.linalg.cholesky_banded`), the border eliminated after the band
(k right-hand sides).  Cofactors come from the *selected inverse* of the
banded factor (Takahashi's recursion): every unit's block and the band, every
point's 3 x 3 block, the unit-point blocks, the border, and from those every
observation's redundancy number ``rᵢ = 1 - (A Q Aᵀ P)ᵢᵢ``.

API
---
Observations are given as arrays, in four kinds (each a frozen dataclass;
``g`` row groups of ``r`` rows each, ``k`` border parameters):

:class:`UnitPointRows`
    rows on one unit and one point (an image point, a model point): ``unit``
    (g,), ``point`` (g,), ``unit_jacobian`` (g, r, d), ``point_jacobian``
    (g, r, 3), ``residual`` (g, r), optional ``weight`` and
    ``border_jacobian`` (g, r, k).
:class:`UnitRows`
    rows on units alone (GNSS centres, IMU attitudes, priors, conditions
    linking neighbouring units): ``units`` (g, q), ``jacobian`` (g, r, q, d).
:class:`PointRows`
    rows on points alone (control): ``point`` (g,), ``jacobian`` (g, r, 3).
:class:`BorderRows`
    rows on the border alone (priors of global parameters): ``jacobian``
    (g, r, k).

``residual`` is ``f``, the computed minus the observed value at the current
unknowns (the step δ makes ``f + A δ`` small); ``weight`` is None (unit
weights: rows already whitened), (g, r) diagonal weights ``1/σ²`` (0 drops a
row) or (g, r, r) full weight matrices (positive definite).  Units are those
of the caller (the engine is unit-free; a whitened residual is
dimensionless).

:class:`NormalStructure` is built once per problem from the index arrays
(which units each point is tied to and which units the unit rows link;
:meth:`NormalStructure.from_indices` takes the arrays themselves): it fixes
the units' order (``order="auto"``: as numbered, reverse Cuthill-McKee or
the caller's ``candidates``, whichever is narrowest) and the band
(``width``, ``order``).  :meth:`NormalStructure.form` forms the normal
blocks of the rows at the current unknowns (same ``unit``/``point``/
``units`` arrays) as a :class:`FormedNormals` (``cost`` ``Σ‖T f‖²``,
``point_blocks``, ``unit_blocks``, :meth:`FormedNormals.undetermined_points`),
whose :meth:`FormedNormals.solve` takes an optional Levenberg-Marquardt
``damping`` (diagonals of the unit, point and border blocks times
``1 + damping``; :meth:`NormalStructure.solve` is form and solve in one)
and returns a :class:`NormalSolution`: ``unit_step`` (n, d),
``point_step`` (p, 3), ``border_step`` (k,), ``cost``, ``predicted_cost``
(``Σ‖T (f + A δ)‖²``), ``min_pivot`` (smallest relative pivot of the
equilibrated reduced matrix, ``min_pivot_unit``, ``min_pivot_parameter``)
:meth:`NormalSolution.point_cofactors` (the 3 x 3 blocks of some points
alone, from the band of the selected inverse: a ground stage's control) and
:meth:`NormalSolution.cofactors`, a :class:`Cofactors` (undamped
solutions only) with ``unit`` (n, d, d), ``point`` (p, 3, 3), ``border``
(k, k), ``unit_border`` (n, d, k), ``point_border`` (p, 3, k),
:meth:`Cofactors.unit_blocks` (any unit pair within the band),
:meth:`Cofactors.unit_point` (any coupled pair) and
:meth:`Cofactors.redundancy` (the redundancy numbers (g, r) of any rows of
the four kinds).  A singular system raises :class:`SingularNormalsError`
(a :class:`~strip_aerotri.errors.GeometryError`) naming the unit, point or
border parameter.

Cost: forming O(G r d²) plus O(Σ_points (q d)²) for the Schur products,
factorising O(n d³ w²) with w the half-bandwidth in units (about the overlap
window along a strip; in a block, the window times the strips), selected
inversion about the same, so linear in the number of units for a strip.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ._blockband import BandFactor, NotPositiveDefinite, factor_band, selected_inverse
from ._normal_assembly import (
    Cofactors,
    Reduced,
    assemble,
    chord_step,
    cofactors,
    point_cofactors,
    predicted_cost,
    reduce_points,
    undetermined_points,
)
from ._normal_pattern import Pattern, bandwidth, build_pattern, sorted_unique, unit_graph_order
from ._normal_rows import (
    POINT_RANK_TOL,
    BorderRows,
    PointRows,
    Rows,
    SingularNormalsError,
    UnitPointRows,
    UnitRows,
    _Normals,
)

__all__ = [
    "BorderRows",
    "Cofactors",
    "FormedNormals",
    "NormalSolution",
    "NormalStructure",
    "PointRows",
    "SingularNormalsError",
    "UnitPointRows",
    "UnitRows",
]


class NormalStructure:
    """The pattern of a problem: units, points, border, the band and its order.

    Parameters
    ----------
    n_units, unit_size, n_points : int
        Number of units, parameters per unit (d), number of points.
    unit_point_rows : sequence of UnitPointRows
        The unit-point rows of the problem (only ``unit`` and ``point`` are
        read here).
    unit_rows : sequence of UnitRows, optional
        The unit rows (only ``units`` is read).
    n_border : int
        Number of global (border) parameters k.
    order : "auto", "given", "rcm" or array of int (n,)
        The units' order along the band: as numbered ("given", units
        numbered along the strip), reverse Cuthill-McKee of the units' graph
        ("rcm"), the narrowest of these two and the `candidates` ("auto"),
        or the unit at each place.
    candidates : sequence of array of int (n,), optional
        More orders for "auto" to consider, e.g. the photos by their
        position along a block (which numbers them across the strips).
    unit_names, point_names : sequence of str, optional
        For the messages (default "unit 3", "point 7").
    parameter_names : sequence of str, optional
        The d names of a unit's parameters, for the messages.
    """

    def __init__(
        self,
        n_units: int,
        unit_size: int,
        n_points: int,
        unit_point_rows: Sequence[UnitPointRows],
        unit_rows: Sequence[UnitRows] = (),
        *,
        n_border: int = 0,
        order: Literal["auto", "given", "rcm"] | ArrayLike = "auto",
        candidates: Sequence[ArrayLike] = (),
        unit_names: Sequence[str] | None = None,
        point_names: Sequence[str] | None = None,
        parameter_names: Sequence[str] | None = None,
    ):
        if n_units < 1 or unit_size < 1 or n_points < 0 or n_border < 0:
            raise ValueError(
                f"Expected n_units >= 1, unit_size >= 1, n_points >= 0, n_border >= 0; got "
                f"{n_units}, {unit_size}, {n_points}, {n_border}"
            )
        self.n_units, self.unit_size, self.n_points = n_units, unit_size, n_points
        self.n_border = n_border
        self._unit_names = unit_names
        self._point_names = point_names
        self._parameter_names = parameter_names
        row_unit = np.concatenate(
            [np.asarray(r.unit, np.intp) for r in unit_point_rows] or [np.zeros(0, np.intp)]
        )
        row_point = np.concatenate(
            [np.asarray(r.point, np.intp) for r in unit_point_rows] or [np.zeros(0, np.intp)]
        )
        if row_unit.size and (row_unit.min() < 0 or row_unit.max() >= n_units):
            raise ValueError("unit index out of range in `unit_point_rows`")
        if row_point.size and (row_point.min() < 0 or row_point.max() >= n_points):
            raise ValueError("point index out of range in `unit_point_rows`")
        sets = [np.asarray(r.units, np.intp) for r in unit_rows]
        for s in sets:
            if s.ndim != 2 or (s.size and (s.min() < 0 or s.max() >= n_units)):
                raise ValueError("Expected `units` of shape (g, q) with indices of units")
        self._pair_ordered: tuple[NormalStructure, IntArray] | None = None
        self._order = self._choose_order(order, row_unit, row_point, sets, candidates)
        self.pattern: Pattern = build_pattern(
            n_units, unit_size, n_points, row_unit, row_point, sets, self._order
        )

    def with_border(self, n_border: int) -> NormalStructure:
        """The same structure with ``n_border`` border parameters (the band's
        order and the point groups do not depend on the border)."""
        if n_border < 0:
            raise ValueError(f"Expected n_border >= 0, got {n_border}")
        if n_border == self.n_border:
            return self
        other = copy.copy(self)
        other.n_border = n_border
        return other

    def in_pair_order(self) -> tuple[NormalStructure, IntArray] | None:
        """The same structure for its unit-point rows given in the pairs'
        order, and the place among the rows as given of each row so ordered
        (rows in the pairs' order are ``rows[places]``): the pairs' blocks
        are then formed without gathering the rows.  None when a pair has
        more than one row.  Built once per structure."""
        if self._pair_ordered is None:
            pattern = self.pattern.in_pair_order()
            if pattern is None or self.pattern.pair_row is None:
                return None
            other = copy.copy(self)
            other.pattern = pattern
            other._pair_ordered = None
            self._pair_ordered = (other, self.pattern.pair_row)
        ordered, places = self._pair_ordered
        return ordered.with_border(self.n_border), places

    def _choose_order(
        self,
        order: Literal["auto", "given", "rcm"] | ArrayLike,
        row_unit: IntArray,
        row_point: IntArray,
        sets: list[IntArray],
        candidates: Sequence[ArrayLike] = (),
    ) -> IntArray:
        n = self.n_units
        if isinstance(order, str):
            if order not in ("auto", "given", "rcm"):
                raise ValueError(f"Expected `order` 'auto', 'given', 'rcm' or an array, got {order!r}")
            given = np.arange(n, dtype=np.intp)
            if order == "given":
                return given
            pairs = sorted_unique(row_point * n + row_unit)
            point_pairs = (pairs // n, pairs % n)
            if order == "rcm":
                return unit_graph_order(n, point_pairs, sets)

            def width(o: IntArray) -> int:
                pos = np.empty(n, np.intp)
                pos[o] = np.arange(n)
                return bandwidth(pos, point_pairs, sets)

            options = [given, *(self._permutation(c, "candidates") for c in candidates)]
            widths = [width(o) for o in options]
            # no order is narrower than the most units of one point or row, less one
            least = max(
                int(np.max(np.bincount(point_pairs[0]), initial=1)) - 1,
                *(s.shape[1] - 1 for s in sets if s.size),
                0,
            )
            if min(widths) > least:
                options.insert(1, unit_graph_order(n, point_pairs, sets))
                widths.insert(1, width(options[1]))
            return options[int(np.argmin(widths))]  # the first of the narrowest
        return self._permutation(order, "order")

    def _permutation(self, order: ArrayLike, name: str) -> IntArray:
        n = self.n_units
        arr = np.asarray(order, dtype=np.intp)
        if arr.shape != (n,) or not np.array_equal(np.sort(arr), np.arange(n)):
            raise ValueError(f"Expected `{name}` to hold permutations of the {n} units")
        return arr

    @property
    def order(self) -> IntArray:
        """The unit at each place along the band (n,)."""
        return self.pattern.order

    @property
    def width(self) -> int:
        """Half-bandwidth of the reduced matrix, in units."""
        return self.pattern.width

    # ------------------------------------------------------------------ names

    def unit_name(self, i: int) -> str:
        return f"'{self._unit_names[i]}'" if self._unit_names is not None else f"unit {i}"

    def point_name(self, i: int) -> str:
        return f"'{self._point_names[i]}'" if self._point_names is not None else f"point {i}"

    def parameter_name(self, j: int) -> str:
        names = self._parameter_names
        return names[j] if names is not None and j < len(names) else f"parameter {j}"

    # ------------------------------------------------------------------ solve

    def form(
        self,
        unit_point_rows: Sequence[UnitPointRows],
        unit_rows: Sequence[UnitRows] = (),
        point_rows: Sequence[PointRows] = (),
        border_rows: Sequence[BorderRows] = (),
    ) -> FormedNormals:
        """The normal blocks of the rows at the current unknowns, to be solved
        with one or more dampings (:meth:`FormedNormals.solve`)."""

        return FormedNormals(self, assemble(self, unit_point_rows, unit_rows, point_rows,
                                            border_rows))

    def solve(
        self,
        unit_point_rows: Sequence[UnitPointRows],
        unit_rows: Sequence[UnitRows] = (),
        point_rows: Sequence[PointRows] = (),
        border_rows: Sequence[BorderRows] = (),
        *,
        damping: float = 0.0,
    ) -> NormalSolution:
        """Form, reduce, factor and solve the normal equations of the rows at
        the current unknowns (see the module docstring)."""
        return self.form(unit_point_rows, unit_rows, point_rows, border_rows).solve(damping)

    @classmethod
    def from_indices(
        cls,
        n_units: int,
        unit_size: int,
        n_points: int,
        unit: ArrayLike,
        point: ArrayLike,
        unit_sets: Sequence[ArrayLike] = (),
        **options: object,
    ) -> NormalStructure:
        """As the constructor, from the unit-point rows' ``unit`` and ``point``
        (G,) and the unit rows' ``units`` (each (g, q)) instead of the rows;
        `options` are the constructor's keywords."""
        ui = np.asarray(unit, dtype=np.intp)
        pi = np.asarray(point, dtype=np.intp)
        empty = np.zeros((ui.size, 0, 0))
        rows = [UnitPointRows(ui, pi, empty, empty, empty)]
        sets = [UnitRows(np.asarray(u, dtype=np.intp), empty, empty) for u in unit_sets]
        return cls(n_units, unit_size, n_points, rows, sets, **options)  # type: ignore[arg-type]


class FormedNormals:
    """The normal blocks of one linearisation (:meth:`NormalStructure.form`);
    ``cost`` is ``Σ‖T f‖²``."""

    def __init__(self, structure: NormalStructure, normals: _Normals):
        self.structure = structure
        self._normals = normals
        self.cost = normals.cost

    @property
    def point_blocks(self) -> FloatArray:
        """The points' 3 x 3 normal blocks V (p, 3, 3), undamped."""
        return self._normals.v

    def undetermined_points(self, tol: float = POINT_RANK_TOL) -> IntArray:
        """Points whose 3 x 3 normal block (undamped) has ``λmin <= tol λmax``."""

        return undetermined_points(self._normals.v, tol)[0] if self._normals.v.size else (
            np.zeros(0, np.intp)
        )

    @property
    def unit_blocks(self) -> FloatArray:
        """The units' d x d normal blocks U (n, d, d), undamped, before the
        points are eliminated."""
        blocks: FloatArray = self._normals.band[self.structure.pattern.position, 0]
        return blocks

    def chord_step(self, solution: NormalSolution) -> tuple[FloatArray, FloatArray]:
        """The step (units (n, d), points (p, 3)) of these normals' gradients
        with the factor of an earlier undamped `solution` of the same
        structure (:meth:`NormalSolution.chord_step`); without a border."""
        return solution.chord_step(self._normals.g_unit, self._normals.g_point)

    def solve(self, damping: float = 0.0, *, step: bool = True) -> NormalSolution:
        """The step with Levenberg-Marquardt `damping` (diagonals of the unit,
        point and border blocks times ``1 + damping``); without `step` the
        factor and the cofactors alone (the steps NaN)."""

        if not damping >= 0.0:
            raise ValueError(f"Expected a non-negative `damping`, got {damping}")
        reduced = reduce_points(self.structure, self._normals, damping, step)
        return NormalSolution._from(self.structure, self._normals, reduced, damping)


@dataclass
class NormalSolution:
    """The step of one linearisation and what its cofactors need."""

    unit_step: FloatArray  # (n, d)
    point_step: FloatArray  # (p, 3)
    border_step: FloatArray  # (k,)
    cost: float
    min_pivot: float
    min_pivot_unit: int
    min_pivot_parameter: int
    damping: float
    _structure: NormalStructure = field(repr=False)
    _state: object = field(repr=False)
    _cofactors: Cofactors | None = field(default=None, repr=False)
    _band_inverse: FloatArray | None = field(default=None, repr=False)

    @classmethod
    def _from(cls, structure: NormalStructure, normals: _Normals, reduced: object,
              damping: float) -> NormalSolution:

        assert isinstance(reduced, Reduced)
        d = structure.unit_size
        j = reduced.factor.min_pivot_index
        return cls(
            unit_step=reduced.unit_step,
            point_step=reduced.point_step,
            border_step=reduced.border_step,
            cost=normals.cost,
            min_pivot=min(reduced.factor.min_pivot, reduced.border_min_pivot),
            min_pivot_unit=int(structure.order[j // d]),
            min_pivot_parameter=j % d,
            damping=damping,
            _structure=structure,
            _state=reduced,
        )

    @property
    def point_inverse(self) -> FloatArray:
        """``V⁻¹`` (p, 3, 3) of the points' normal blocks, as the elimination
        of the points formed it (from their closed-form Cholesky factors);
        damped when the solution is."""

        assert isinstance(self._state, Reduced)
        return self._state.v_inv

    def chord_step(self, g_unit: FloatArray, g_point: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The step (units (n, d), points (p, 3)) of other gradients ``Aᵀ P f``
        (units (n, d), points (p, 3), as :meth:`NormalStructure.form` forms
        them) with this solution's normal matrix, factored already: a
        simplified Gauss-Newton step at an unknown that moved little since.
        Undamped solutions without a border only."""
        if self.damping != 0.0:
            raise ValueError("Expected an undamped solution for a chord step")
        assert isinstance(self._state, Reduced)
        return chord_step(self._structure, self._state, g_unit, g_point)

    @property
    def predicted_cost(self) -> float:
        """``Σ‖T (f + A δ)‖²`` of the step with the undamped normal matrix."""

        assert isinstance(self._state, Reduced)
        return predicted_cost(self._structure, self._state)

    @property
    def border_cofactor(self) -> FloatArray:
        """The border's block of ``N⁻¹`` (k x k), the inverse of its Schur
        complement, without the rest of the selected inverse (undamped
        solutions only)."""
        if self.damping != 0.0:
            raise ValueError("cofactors of a damped system are not those of the adjustment")
        assert isinstance(self._state, Reduced)
        return self._state.t_inv

    def point_cofactors(self, points: ArrayLike) -> FloatArray:
        """The points' blocks of ``N⁻¹`` (m, 3, 3) for the points `points`
        (m,) alone, from the band of the selected inverse: a few points
        (the control of a ground stage) without the cost of every point's
        block (:meth:`cofactors`, which serves when it is computed already
        or there is a border).  Undamped solutions only."""
        if self.damping != 0.0:
            raise ValueError("cofactors of a damped system are not those of the adjustment")
        index = np.asarray(points, dtype=np.intp)
        if self._cofactors is not None or self._structure.n_border:
            return self.cofactors().point[index]
        assert isinstance(self._state, Reduced)
        if self._band_inverse is None:
            self._band_inverse = selected_inverse(self._state.factor)
        return point_cofactors(self._structure, self._state, self._band_inverse, index)

    def cofactors(self) -> Cofactors:
        """The selected inverse of the normal matrix (undamped solutions only)."""
        if self.damping != 0.0:
            raise ValueError("cofactors of a damped system are not those of the adjustment")
        if self._cofactors is None:

            assert isinstance(self._state, Reduced)
            self._cofactors = cofactors(self._structure, self._state)
        return self._cofactors
