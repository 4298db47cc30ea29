"""Polynomial correction of the systematic deformation of a strip.

After the similarity transformation a strip still shows systematic errors
(bending along the strip, twist, scale drift).  Following J(16)-(18) and
B(150)-(151) (method.md sections 6.3 and 6.4), each coordinate of the
deformation

``w = photogrammetric - control``

is modelled by a polynomial in the photogrammetric plan coordinates (X, Y) of
a frame whose X axis runs along the strip:

====  ============================================
kind  terms of each polynomial (J(16))
====  ============================================
0     none (similarity only)
1     1, X, Y, XY
2     1, X, Y, XY, X²
3     1, X, Y, XY, X², X³   (= B(150))
====  ============================================

Full control feeds the X, Y and Z polynomials, plan control X and Y, height
control Z (J(17), B(151)).  Points on a straight line along the strip (a
road, a railway, a staked line; no ground coordinates) add equations to the
Y polynomial (J(18) with the fix of method.md section 6.4).  Corrected
coordinates are ``xyz - w(X, Y)``.

For conditioning, X and Y are normalised inside :func:`fit_deformation`
about the centroid of the data by the half-extent along X (see
:class:`Normalization`); coefficients refer to the normalised variables.

Long strips (``sections > 1``, an extension of J(16)): each polynomial is
``w = f(u) + v g(u)``, J's terms grouped by their power of v.  One section
is J(16) itself (f of degree 1, 2 or 3 in u, g linear); with S sections of
equal length along the strip f becomes a spline of the same degree (C1 for
type 2, C2 for type 3, with its pieces joined at the section breakpoints) and
g a continuous piecewise-linear function, both fitted in one least-squares
solution, so that a strip whose error accumulated over many models along the
chain (a random walk, docs/strip-formation.md) is followed piece by piece
without steps between sections.  The splines are represented in the
B-spline basis (local, well conditioned); beyond the first and last
breakpoints the end pieces continue as polynomials.

All coordinates are Cartesian, metres, rows of shape (N, 3).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np

from .._typing import ArrayLike, BoolArray, FloatArray, IntArray
from ..errors import GeometryError, StripAerotriWarning
from ..observations import LineSpec
from ..options import DEFAULT_LINE_WEIGHT, DEFAULT_SECTIONS, check_sections
from ._banded import BandedNormals
from .control_geometry import _quote
from .similarity import (
    RowSupport,
    _check_ids,
    _check_mask,
    _check_points,
    _check_sigma,
    _normal_inverse,
    _normalized,
    _redundancy_numbers,
    row_support,
)
from .deformation_basis import (
    _check_kind,
    _dense,
    _section_support,
    _section_values,
    _spline_pieces,
    _stations,
    bspline_basis,
    n_terms,
    polynomial_terms,
    section_terms,
    term_names,
)

__all__ = [
    "DeformationResult",
    "Normalization",
    "StraightLine",
    "bspline_basis",
    "check_sections",
    "fit_deformation",
    "n_terms",
    "polynomial_count_problems",
    "polynomial_terms",
    "section_terms",
    "term_names",
]

#: Condition number of a column-equilibrated normal matrix treated as singular.
SINGULAR_COND = 1e12
#: Condition number above which a warning is issued.
WEAK_COND = 1e8


class Normalization(NamedTuple):
    """Normalisation of the plan coordinates of the polynomials.

    ``u = (X - centre[0]) / half_extent``, ``v = (Y - centre[1]) / half_extent``
    (metres in, unitless out); the strip then spans about -1..1 in u.
    """

    centre: FloatArray
    half_extent: float

    def apply(self, xyz: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Normalised (u, v), each of shape (N,), from points of shape (N, 3) or (N, 2)."""
        arr = np.asarray(xyz, dtype=np.float64)
        return (
            (arr[..., 0] - self.centre[0]) / self.half_extent,
            (arr[..., 1] - self.centre[1]) / self.half_extent,
        )


@dataclass(frozen=True)
class StraightLine:
    """Points with no ground coordinates that lie on one straight vertical plane.

    Attributes
    ----------
    point_ids : tuple of str, length M
        Ids of the line points.
    xyz : ndarray, shape (M, 3)
        Their photogrammetric coordinates in the strip-aligned frame of the
        fit (metres).
    weight : float
        Weight of a line equation relative to a control coordinate of weight 1
        (J found about 100 necessary for the condition to show).
    name : str
        Name used in messages and reports.
    """

    point_ids: tuple[str, ...]
    xyz: FloatArray
    weight: float = DEFAULT_LINE_WEIGHT
    name: str = "line"

    def __post_init__(self) -> None:
        ids = tuple(str(p) for p in self.point_ids)
        xyz = np.array(self.xyz, dtype=np.float64)
        if xyz.ndim != 2 or xyz.shape[1] != 3:
            raise ValueError(
                f"Expected `xyz` of straight line {self.name!r} to have shape (M, 3), "
                f"got {xyz.shape}"
            )
        if len(ids) != xyz.shape[0]:
            raise ValueError(
                f"Straight line {self.name!r}: {len(ids)} point ids for {xyz.shape[0]} points"
            )
        weight = float(self.weight)
        if not np.isfinite(weight) or weight <= 0.0:
            raise ValueError(
                f"Expected the weight of straight line {self.name!r} to be > 0, got {weight!r}"
            )
        xyz.setflags(write=False)
        object.__setattr__(self, "point_ids", ids)
        object.__setattr__(self, "xyz", xyz)
        object.__setattr__(self, "weight", weight)
        object.__setattr__(self, "name", str(self.name))


@dataclass(frozen=True)
class DeformationResult:
    """Polynomial deformation fitted to control (and straight-line) observations.

    Attributes
    ----------
    kind : int
        Highest polynomial type used (0..3); sets the number of columns of
        `coefficients`.
    kinds : tuple of int
        Polynomial type of the X, Y and Z polynomials.
    coefficients : ndarray, shape (3, n_terms(kind))
        Rows X, Y, Z; columns ``[1, u, v, uv, u², u³][:n]`` in the normalised
        variables of `normalization`, metres.  Terms above a coordinate's own
        type are zero.  Read-only: evaluations over sections keep the
        spline's pieces set up from them (replace the result, not the
        coefficients in place).
    normalization : Normalization
        Centre (metres) and half-extent (metres) of the normalisation.
    line_names : tuple of str
        Names of the straight lines, in order.
    line_parameters : ndarray, shape (K, 2)
        (a, b) of each line ``Y = a + b X`` in the un-normalised frame (a in
        metres, b unitless).
    residuals : ndarray, shape (N, 3)
        ``target - corrected`` at the control, metres; NaN where unobserved.
    line_residuals : tuple of ndarray, each shape (M_k,)
        Corrected Y of each line point minus the Y of its fitted line at the
        point's X (metres).
    sigma0 : float
        A posteriori standard deviation of unit weight over all three fits
        (unitless with sigmas given, metres with default unit weights); NaN
        with no redundancy.
    redundancy : int
        Total redundancy (observations - unknowns) of the three fits.
    sigma0_xyz : ndarray, shape (3,)
        sigma0 of the X, Y, Z fits separately (NaN where no redundancy).
    redundancy_xyz : tuple of int
        Redundancy of the X, Y, Z fits.
    redundancy_numbers : ndarray, shape (N, 3)
        Diagonal of ``I - A (AᵀPA)⁻¹ AᵀP`` for the control observations; NaN
        where unobserved.
    line_redundancy_numbers : tuple of ndarray, each shape (M_k,)
        The same for the line equations.
    normalized_residuals : ndarray, shape (N, 3)
        w-test ``v / (sigma sqrt(r))`` at the control (a priori sigma).
    line_normalized_residuals : tuple of ndarray, each shape (M_k,)
        The same for the line equations (sigma of a line equation is the
        reference control sigma divided by ``sqrt(weight)``).
    point_ids : tuple of str
        Ids of the N control rows.
    breakpoints : ndarray, shape (S + 1,) or None
        Section boundaries in the normalised u for ``sections > 1`` (module
        docstring); None for J(16)'s single polynomial.  With sections the
        columns of `coefficients` are those of :func:`section_terms`
        (names in :attr:`term_names`).
    """

    kind: int
    kinds: tuple[int, int, int]
    coefficients: FloatArray
    normalization: Normalization
    line_names: tuple[str, ...]
    line_parameters: FloatArray
    residuals: FloatArray
    line_residuals: tuple[FloatArray, ...]
    sigma0: float
    redundancy: int
    sigma0_xyz: FloatArray
    redundancy_xyz: tuple[int, int, int]
    redundancy_numbers: FloatArray
    line_redundancy_numbers: tuple[FloatArray, ...]
    normalized_residuals: FloatArray
    line_normalized_residuals: tuple[FloatArray, ...]
    point_ids: tuple[str, ...] = field(default_factory=tuple)
    breakpoints: FloatArray | None = None

    @property
    def sections(self) -> int:
        """Number of sections along the strip (1: J(16))."""
        return 1 if self.breakpoints is None else int(self.breakpoints.size - 1)

    @property
    def term_names(self) -> tuple[str, ...]:
        """Names of the columns of `coefficients` (:func:`term_names`)."""
        return term_names(self.kind, self.sections)

    @property
    def breakpoints_x(self) -> FloatArray:
        """Section boundaries as X of the fit's frame, metres, shape (S + 1,)
        (empty for a single polynomial)."""
        if self.breakpoints is None:
            return np.zeros(0)
        norm = self.normalization
        x: FloatArray = norm.centre[0] + norm.half_extent * self.breakpoints
        return x

    @cached_property
    def _pieces(self) -> tuple[FloatArray, FloatArray]:
        # the spline's pieces in the power basis, set up once for every
        # evaluation (the coefficients are read-only); only over sections
        assert self.breakpoints is not None  # evaluate() asks only then
        return _spline_pieces(self.kind, self.breakpoints, self.coefficients)

    def evaluate(self, xyz: ArrayLike) -> FloatArray:
        """Deformation ``w`` (metres) at photogrammetric points.

        Parameters
        ----------
        xyz : array_like, shape (N, 3)
            Photogrammetric coordinates in the frame of the fit.

        Returns
        -------
        ndarray, shape (N, 3)
            ``w = photogrammetric - control`` predicted by the polynomials.
        """
        arr = _check_points(xyz, "xyz")
        u, v = self.normalization.apply(arr)
        if self.breakpoints is not None:
            return _section_values(
                u, v, self.kind, self.breakpoints, self.coefficients, self._pieces
            )
        return polynomial_terms(u, v, self.kind) @ self.coefficients.T

    def correct(self, xyz: ArrayLike) -> FloatArray:
        """Corrected coordinates ``xyz - w(X, Y)``, shape (N, 3), metres."""
        arr = _check_points(xyz, "xyz")
        return arr - self.evaluate(arr)


class _Normals(NamedTuple):
    """Solver ``b -> Q b`` with ``Q = (AᵀPA)⁻¹``, its condition number and the
    redundancy numbers of a weighted design, reusable for another right-hand
    side of the same design (X and Y of the plan control)."""

    solve: Callable[[FloatArray], FloatArray]
    cond: float
    redundancy: FloatArray


#: Unknowns from which the banded factor is faster than the dense inverse
#: (at 106, 50 sections, it is 0.6-0.9 ms slower per ground stage).
_BANDED_MIN_UNKNOWNS = 200


def _band_order(kind: int, n_sections: int) -> IntArray:
    """The unknowns of a spline over sections along the strip: its B-splines
    (degree `kind`, centred kind / 2 sections before their index) and hats
    (half a section) interleaved by centre, which makes the normal matrix
    banded (about 6 wide)."""
    centres = np.concatenate(
        [np.arange(n_sections + kind) - 0.5 * kind, np.arange(n_sections + 1) - 0.5]
    )
    return np.argsort(centres, kind="stable")


def _normals(a_w: FloatArray | RowSupport, order: IntArray | None = None) -> _Normals:
    """Normals of whitened rows (dense, or their nonzero entries): through a
    banded factor for a spline over sections when its unknowns' `order`
    along the strip is given (a few nonzero terms per row,
    strip_aerotri._banded), else the dense inverse."""
    support = a_w if isinstance(a_w, RowSupport) else row_support(a_w)
    if support is not None and order is not None and support.n_columns >= _BANDED_MIN_UNKNOWNS:
        banded = BandedNormals.from_rows(support.columns, support.value, support.n_columns, order)
        if banded is not None:
            cond = banded.cond
            if not np.isfinite(cond):
                return _Normals(banded.solve, cond, np.full(len(support.columns), np.nan))
            h = banded.quadratic_forms(support.columns, support.value)
            return _Normals(banded.solve, cond, np.clip(1.0 - h, 0.0, 1.0))
    if isinstance(a_w, RowSupport):
        a_w = _dense(a_w)
    q, cond = _normal_inverse(a_w, support)
    return _Normals(q.__matmul__, cond, _redundancy_numbers(a_w, q, support))


def _solve(
    design: FloatArray | RowSupport,
    observed: FloatArray,
    sigma: FloatArray,
    *,
    what: str,
    names: Sequence[str],
    normals: _Normals | None = None,
    order: IntArray | None = None,
) -> tuple[FloatArray, FloatArray, _Normals]:
    """Weighted least squares ``design @ x ≈ observed``; returns x, v = observed - Ax
    and the normals (``normals`` given: those of the same design and sigma).
    `design`: dense, or the nonzero entries of its rows (a spline over
    sections: a few of hundreds or thousands of columns, `order` its
    unknowns along the strip, :func:`_band_order`)."""
    n_columns: int = design.n_columns if isinstance(design, RowSupport) else design.shape[1]
    if n_columns == 0:
        return np.zeros(0), observed.copy(), _Normals(np.asarray, 1.0, np.ones(len(observed)))
    a_w: FloatArray | RowSupport
    if isinstance(design, RowSupport):
        a_w = RowSupport(design.columns, design.value / sigma[:, None], n_columns)
    else:
        a_w = design / sigma[:, None]
    if normals is None:
        normals = _normals(a_w, order)
    cond = normals.cond
    if not np.isfinite(cond) or cond > SINGULAR_COND:
        raise GeometryError(
            f"{what}: the design is singular (condition {cond:.1e}); the points do not "
            "determine the polynomial (e.g. all control at too few distinct X positions, "
            f"or on one line across the strip): {_quote(names)}"
        )
    if cond > WEAK_COND:
        warnings.warn(
            f"{what}: the design is nearly singular (condition {cond:.1e}); the polynomial is "
            f"weakly determined by: {_quote(names)}",
            StripAerotriWarning,
            stacklevel=3,
        )
    rhs = observed / sigma
    # a_w is sparse exactly when the design is
    normal_rhs: FloatArray
    if isinstance(a_w, RowSupport):
        # with weights bincount gives float64 (the stubs say intp throughout)
        normal_rhs = np.bincount(  # type: ignore[assignment]
            a_w.columns.ravel(), (a_w.value * rhs[:, None]).ravel(), minlength=n_columns
        )
    else:
        normal_rhs = a_w.T @ rhs
    x = normals.solve(normal_rhs)
    if isinstance(design, RowSupport):
        v = observed - np.einsum("nw,nw->n", design.value, x[design.columns])
    else:
        v = observed - design @ x
    return x, v, normals


def _kinds3(kind: int | Sequence[int]) -> tuple[int, int, int]:
    if isinstance(kind, int | np.integer) and not isinstance(kind, bool):
        k = _check_kind(kind)
        return (k, k, k)
    if isinstance(kind, str):
        raise ValueError(
            f"Expected polynomial `kind` to be 0, 1, 2, 3 or three of them, got {kind!r}"
        )
    # a bool kind (an int to the checker) gets here and tuple() raises TypeError
    seq = tuple(kind)  # type: ignore[arg-type]
    if len(seq) != 3:
        raise ValueError(f"Expected `kind` to be an int or three ints (X, Y, Z), got {kind!r}")
    kx, ky, kz = (_check_kind(k) for k in seq)
    return (kx, ky, kz)


def fit_deformation(
    xyz: ArrayLike,
    target: ArrayLike,
    *,
    use_xy: ArrayLike,
    use_z: ArrayLike,
    kind: int | Sequence[int],
    sigma_xy: ArrayLike | None = None,
    sigma_z: ArrayLike | None = None,
    lines: Sequence[StraightLine] = (),
    point_ids: Sequence[str] | None = None,
    sections: int = DEFAULT_SECTIONS,
) -> DeformationResult:
    """Fit the J(16) deformation polynomials by weighted least squares.

    Parameters
    ----------
    xyz : array_like, shape (N, 3)
        Photogrammetric coordinates of the control points, metres, in a frame
        whose X axis runs along the strip and which already matches the
        control by a similarity transformation.
    target : array_like, shape (N, 3)
        Control coordinates in the same frame; NaN where not given (entries
        not used are never read).
    use_xy, use_z : array_like of bool, shape (N,)
        X and Y observed (full and plan control); Z observed (full and height
        control).
    kind : int or sequence of three int
        Polynomial type 0..3 of J(16) for all coordinates, or one per
        coordinate (X, Y, Z): e.g. ``(1, 3, 1)`` when only the Y polynomial is
        strengthened by straight lines.
    sigma_xy, sigma_z : float or array_like, shape (N,), optional
        A priori standard deviations of the control coordinates, metres
        (weights ``1/sigma²``; default 1).
    lines : sequence of StraightLine
        Straight-line conditions for the Y polynomial.  The sigma of a line
        equation is ``sigma_ref / sqrt(line.weight)`` with ``sigma_ref`` the
        median `sigma_xy` of the plan control (1 by default): weight 100 means
        a line equation counts as 100 control coordinates.
    point_ids : sequence of str, length N, optional
        Names for messages and the result.
    sections : int
        Number of sections of equal length along the strip, between the
        first and last control (or line point) in X (module docstring).  1
        (default) is J(16); more need one type for X, Y and Z.

    Returns
    -------
    DeformationResult

    Raises
    ------
    GeometryError
        Fewer usable observations than terms for a coordinate, a straight
        line with fewer than three points, non-finite used coordinates, a
        section without control for a coordinate, or a singular design
        (messages name the rule and the points).
    ValueError
        Bad shapes or arguments.

    Notes
    -----
    For each coordinate c the observation equations are J(17)/B(151),
    ``w_c(X_i, Y_i) = xyz_ic - target_ic`` for the control that observes c.
    For each point i of straight line k the Y polynomial gets the equation
    (method.md section 6.4, J(18) with the [fix])

    ``w_Y(X_i, Y_i) + a_k + b_k X_i = Y_i``

    with a_k, b_k extra unknowns, so that the corrected ``Y_i - w_Y`` lies on
    ``Y = a_k + b_k X``.  (J(18) as printed lacks the observed ``Y_i``: it
    would force the deformation itself, rather than the corrected points, to
    be straight.)  The photogrammetric X is used on the right-hand side, an
    approximation of order ``b_k * w_X`` that vanishes for lines along the
    strip.

    X and Y are normalised by :class:`Normalization`: the centre is the
    centroid of the plan coordinates of the used control and line points and
    the half-extent is half their range in X (or in Y when X has no range).

    A coordinate needs at least as many observations as terms; for Y the
    line equations count with two fewer per line (the line's a, b).  Over
    sections, every section needs control (or line points, for Y) of every
    coordinate.
    """
    data = _fit_inputs(
        xyz, target, use_xy, use_z, kind, sigma_xy, sigma_z, lines, point_ids, sections
    )
    x_breaks = _check_coverage(data)
    norm = _normalization(data)
    design = _Design(data, norm, x_breaks)
    fit = _Fit.empty(data.n, n_terms(max(data.kinds), data.n_sections))
    normals_x = _fit_coordinate(data, design, fit, 0)
    _fit_coordinate(data, design, fit, 2)
    line_params, line_res, line_red, line_norm = _fit_y(data, design, norm, fit, normals_x)
    kinds = data.kinds
    exact = [
        f"{a} (type {kinds[c]})"
        for c, a in enumerate("XYZ")
        if kinds[c] > 0 and fit.redundancy_xyz[c] == 0
    ]
    if exact:
        warnings.warn(
            f"deformation polynomial{data.in_sections}: {', '.join(exact)} "
            f"{'has' if len(exact) == 1 else 'have'} as many control observations as terms "
            "(no redundancy): the polynomial passes through that control exactly and an "
            "error in it cannot be detected; add control or use a lower type",
            StripAerotriWarning,
            stacklevel=2,
        )
    redundancy = int(sum(fit.redundancy_xyz))
    sigma0 = float(np.sqrt(fit.vtpv / redundancy)) if redundancy > 0 else float("nan")
    fit.coefficients.setflags(write=False)  # DeformationResult caches their spline pieces
    return DeformationResult(
        kind=max(kinds),
        kinds=kinds,
        coefficients=fit.coefficients,
        normalization=norm,
        line_names=tuple(line.name for line in data.lines),
        line_parameters=line_params,
        residuals=fit.residuals,
        line_residuals=line_res,
        sigma0=sigma0,
        redundancy=redundancy,
        sigma0_xyz=fit.sigma0_xyz,
        redundancy_xyz=(fit.redundancy_xyz[0], fit.redundancy_xyz[1], fit.redundancy_xyz[2]),
        redundancy_numbers=fit.redundancy_numbers,
        line_redundancy_numbers=line_red,
        normalized_residuals=fit.normalized,
        line_normalized_residuals=line_norm,
        point_ids=data.ids,
        breakpoints=design.breakpoints,
    )


class _FitInputs(NamedTuple):
    """The validated arguments of :func:`fit_deformation`."""

    pts: FloatArray
    tgt: FloatArray
    mask_xy: BoolArray
    mask_z: BoolArray
    sxy: FloatArray
    sz: FloatArray
    ids: tuple[str, ...]
    kinds: tuple[int, int, int]
    n_sections: int
    lines: tuple[StraightLine, ...]

    @property
    def n(self) -> int:
        n: int = self.pts.shape[0]
        return n

    @property
    def used(self) -> BoolArray:
        return self.mask_xy | self.mask_z

    @property
    def plan_ids(self) -> list[str]:
        return [self.ids[i] for i in np.flatnonzero(self.mask_xy)]

    @property
    def height_ids(self) -> list[str]:
        return [self.ids[i] for i in np.flatnonzero(self.mask_z)]

    @property
    def in_sections(self) -> str:
        return f" in {self.n_sections} sections" if self.n_sections > 1 else ""


def _fit_inputs(
    xyz: ArrayLike,
    target: ArrayLike,
    use_xy: ArrayLike,
    use_z: ArrayLike,
    kind: int | Sequence[int],
    sigma_xy: ArrayLike | None,
    sigma_z: ArrayLike | None,
    lines: Sequence[StraightLine],
    point_ids: Sequence[str] | None,
    sections: int,
) -> _FitInputs:
    """Shapes, types and finiteness of what is used (ValueError, TypeError or
    GeometryError naming the points)."""
    pts = _check_points(xyz, "xyz")
    n = pts.shape[0]
    tgt = _check_points(target, "target", n)
    mask_xy = _check_mask(use_xy, n, "use_xy")
    mask_z = _check_mask(use_z, n, "use_z")
    ids = _check_ids(point_ids, n)
    kinds = _kinds3(kind)
    n_sections = check_sections(sections)
    if n_sections > 1 and (len(set(kinds)) > 1 or kinds[0] == 0):
        raise ValueError(
            f"Expected one polynomial type >= 1 for X, Y and Z with sections > 1, got {kind!r}"
        )
    lines = tuple(lines)
    for line in lines:
        if not isinstance(line, StraightLine):
            raise TypeError(f"Expected StraightLine objects in `lines`, got {type(line).__name__}")
    used = mask_xy | mask_z
    bad = (used & ~np.all(np.isfinite(pts[:, :2]), axis=1)) | (mask_z & ~np.isfinite(pts[:, 2]))
    bad |= mask_xy & ~np.all(np.isfinite(tgt[:, :2]), axis=1)
    bad |= mask_z & ~np.isfinite(tgt[:, 2])
    if np.any(bad):
        raise GeometryError(
            "deformation polynomial: control points with non-finite used coordinates: "
            f"{_quote([ids[i] for i in np.flatnonzero(bad)])}"
        )
    for line in lines:
        if line.xyz.shape[0] < 3:
            raise GeometryError(
                f"straight line {line.name!r} needs at least 3 points (2 define the line), got "
                f"{line.xyz.shape[0]}" + (f": {_quote(line.point_ids)}" if line.point_ids else "")
            )
        bad_line = ~np.all(np.isfinite(line.xyz[:, :2]), axis=1)
        if np.any(bad_line):
            raise GeometryError(
                f"straight line {line.name!r}: points with non-finite coordinates: "
                f"{_quote([line.point_ids[i] for i in np.flatnonzero(bad_line)])}"
            )
    return _FitInputs(
        pts,
        tgt,
        mask_xy,
        mask_z,
        _check_sigma(sigma_xy, n, "sigma_xy"),
        _check_sigma(sigma_z, n, "sigma_z"),
        ids,
        kinds,
        n_sections,
        lines,
    )


def polynomial_count_problems(
    kinds: tuple[int, int, int],
    n_sections: int,
    plan_ids: Sequence[str],
    height_ids: Sequence[str],
    lines: Sequence[StraightLine | LineSpec] = (),
) -> list[str]:
    """J(16)'s counting rule, one line per coordinate short of observations.

    A coordinate needs at least as many observations as its polynomial has
    terms (:func:`n_terms` of its type, per section): X the full or plan
    points, Z the full or height points, Y the plan points plus every line
    point beyond two per straight line.  :func:`fit_deformation` raises the
    first line; ``stripaero check`` lists them all.
    """
    in_sections = f" in {n_sections} sections" if n_sections > 1 else ""
    n_plan, n_height = len(plan_ids), len(height_ids)
    problems = []
    for axis, count, label, names in (
        ("X", n_plan, "full or plan control points", plan_ids),
        ("Z", n_height, "height control points", height_ids),
    ):
        need = n_terms(kinds["XYZ".index(axis)], n_sections)
        if count < need:
            problems.append(
                f"polynomial type {kinds['XYZ'.index(axis)]}{in_sections} needs at least "
                f"{need} {label} "
                f"for {axis}, got {count}" + (f" ({_quote(names)})" if names else "")
            )
    n_line_extra = sum(len(line.point_ids) - 2 for line in lines)
    need_y = n_terms(kinds[1], n_sections)
    if n_plan + n_line_extra < need_y:
        line_text = ", ".join(f"{ln.name!r}: {len(ln.point_ids)}" for ln in lines)
        problems.append(
            f"polynomial type {kinds[1]}{in_sections} needs at least {need_y} observations for Y "
            "(full or plan control points, plus line points beyond two per straight line), got "
            f"{n_plan + n_line_extra}: {n_plan} control"
            + (f" ({_quote(plan_ids)})" if plan_ids else "")
            + (f" and {n_line_extra} from lines ({line_text})" if lines else "")
        )
    return problems


def _check_coverage(data: _FitInputs) -> FloatArray | None:
    """Enough observations for every coordinate, at enough stations along the
    strip and in every section (GeometryError naming the rule and the points).
    Returns the section breakpoints in X (m), None for one polynomial."""
    kinds, n_sections, lines, in_sections = (
        data.kinds,
        data.n_sections,
        data.lines,
        data.in_sections,
    )
    plan_ids, height_ids = data.plan_ids, data.height_ids
    problems = polynomial_count_problems(kinds, n_sections, plan_ids, height_ids, lines)
    if problems:
        raise GeometryError(problems[0])

    # Stations along the strip: a polynomial of degree d in X needs control at
    # d + 1 distinct X positions, however many points stand at each.
    pts, mask_xy, mask_z = data.pts, data.mask_xy, data.mask_z
    all_x = np.concatenate([pts[data.used, 0]] + [line.xyz[:, 0] for line in lines])
    # Points closer in X than a tenth of the mean spacing of all data points
    # stand at one station (e.g. the two sides of the strip at one model).
    tol = 0.1 * max(float(np.ptp(all_x)), 1e-12) / max(all_x.size, 1)
    line_x = [line.xyz[:, 0] for line in lines]
    # Sections of equal length between the first and last data point in X
    # (data exist: a type >= 1 has passed the counts above).
    x_breaks = np.linspace(all_x.min(), all_x.max(), n_sections + 1) if n_sections > 1 else None
    for c, axis, xs, label in (
        (0, "X", [pts[mask_xy, 0]], "full or plan control"),
        (1, "Y", [pts[mask_xy, 0], *line_x], "full or plan control and line points"),
        (2, "Z", [pts[mask_z, 0]], "height control"),
    ):
        # degree + 1 for one polynomial, degree + S for a spline over S sections
        need = 0 if kinds[c] == 0 else kinds[c] + n_sections
        x_c = np.concatenate(xs)
        got = _stations(x_c, tol)
        if got < need:
            raise GeometryError(
                f"polynomial type {kinds[c]}{in_sections} needs {label} at at least {need} "
                f"stations along the strip for {axis}, got {got} (points at one X within "
                f"{tol:.3g} m count once)"
            )
        if x_breaks is not None:
            section = np.clip(np.searchsorted(x_breaks, x_c, side="right") - 1, 0, n_sections - 1)
            empty = np.flatnonzero(np.bincount(section, minlength=n_sections) == 0)
            if empty.size:
                j = int(empty[0])
                raise GeometryError(
                    f"polynomial type {kinds[c]} in {n_sections} sections: section {j + 1} "
                    f"(X {x_breaks[j]:.1f} to {x_breaks[j + 1]:.1f} m) has no {label} for "
                    f"{axis}; use fewer sections or add control there"
                )
    return x_breaks


def _normalization(data: _FitInputs) -> Normalization:
    """Centre: the centroid of the plan coordinates of the used control and
    line points; half-extent: half their range in X (in Y when X has none)."""
    xy_all = np.concatenate(
        [data.pts[data.used, :2]] + [line.xyz[:, :2] for line in data.lines], axis=0
    )
    if xy_all.shape[0]:
        centre = xy_all.mean(axis=0)
        half = 0.5 * float(np.ptp(xy_all[:, 0]))
        if half <= 0.0:
            half = 0.5 * float(np.ptp(xy_all[:, 1]))
    else:
        centre = np.zeros(2)
        half = 1.0
    if half <= 0.0:
        half = 1.0
    centre.setflags(write=False)
    return Normalization(centre=centre, half_extent=half)


class _Design:
    """Design rows of the polynomials at the control (dense for one
    polynomial; the few nonzero terms per row for a spline over sections)."""

    def __init__(self, data: _FitInputs, norm: Normalization, x_breaks: FloatArray | None):
        self.kind_max = max(data.kinds)
        self.breakpoints = None
        if x_breaks is not None:
            self.breakpoints = (x_breaks - norm.centre[0]) / norm.half_extent
            self.breakpoints.setflags(write=False)
        u_all, v_all = norm.apply(data.pts)
        u_all = np.where(data.used, u_all, 0.0)
        v_all = np.where(data.used, v_all, 0.0)
        if self.breakpoints is None:
            self.terms_all = polynomial_terms(u_all, v_all, self.kind_max)
            self.band_order = None
        else:  # a few nonzero terms of hundreds or thousands per row
            self.support_all = _section_support(u_all, v_all, self.kind_max, self.breakpoints)
            self.band_order = _band_order(self.kind_max, data.n_sections)

    def terms(self, u: FloatArray, v: FloatArray, kind: int) -> FloatArray:
        """Dense terms at normalised points (u, v)."""
        if self.breakpoints is None:
            return polynomial_terms(u, v, kind)
        return section_terms(u, v, kind, self.breakpoints)

    def rows(self, mask: BoolArray, k_c: int) -> FloatArray | RowSupport:
        """The first ``k_c`` terms at the control in ``mask``."""
        if self.breakpoints is None:
            return self.terms_all[mask, :k_c]
        return RowSupport(self.support_all.columns[mask], self.support_all.value[mask], k_c)


@dataclass
class _Fit:
    """The fit's results, coordinate by coordinate."""

    coefficients: FloatArray  # (3, n_terms)
    residuals: FloatArray  # (N, 3) target minus corrected
    redundancy_numbers: FloatArray  # (N, 3)
    normalized: FloatArray  # (N, 3)
    sigma0_xyz: FloatArray  # (3,)
    redundancy_xyz: list[int]
    vtpv: float

    @classmethod
    def empty(cls, n: int, nt: int) -> _Fit:
        return cls(
            np.zeros((3, nt)),
            np.full((n, 3), np.nan),
            np.full((n, 3), np.nan),
            np.full((n, 3), np.nan),
            np.full(3, np.nan),
            [0, 0, 0],
            0.0,
        )

    def add(self, c: int, vtpv: float, redundancy: int) -> None:
        self.redundancy_xyz[c] = redundancy
        self.vtpv += vtpv
        if redundancy > 0:
            self.sigma0_xyz[c] = np.sqrt(vtpv / redundancy)


def _observed(data: _FitInputs) -> FloatArray:
    """Observations w_obs = photogrammetric minus control, (N, 3), 0 where unused."""
    observed = np.column_stack([data.mask_xy, data.mask_xy, data.mask_z])
    return np.where(observed, data.pts - np.where(observed, data.tgt, 0.0), 0.0)


def _fit_coordinate(data: _FitInputs, design: _Design, fit: _Fit, c: int) -> _Normals:
    """X (c = 0) or Z (c = 2) from the control alone; returns the normals."""
    mask, sig, names = (
        (data.mask_xy, data.sxy, data.plan_ids)
        if c == 0
        else (data.mask_z, data.sz, data.height_ids)
    )
    k_c = n_terms(data.kinds[c], data.n_sections)
    x, v_fit, normals = _solve(
        design.rows(mask, k_c),
        _observed(data)[mask, c],
        sig[mask],
        what=f"polynomial type {data.kinds[c]} for {'XYZ'[c]}",
        names=names,
        order=design.band_order,
    )
    r = normals.redundancy
    fit.coefficients[c, :k_c] = x
    # residual target - corrected = w_fit - w_obs = -(w_obs - A x)
    fit.residuals[mask, c] = -v_fit
    fit.redundancy_numbers[mask, c] = r
    fit.normalized[mask, c] = _normalized(-v_fit, sig[mask], r)
    fit.add(c, float(np.sum((v_fit / sig[mask]) ** 2)), int(v_fit.size - k_c))
    return normals


def _fit_y(
    data: _FitInputs, design: _Design, norm: Normalization, fit: _Fit, normals_x: _Normals
) -> tuple[FloatArray, tuple[FloatArray, ...], tuple[FloatArray, ...], tuple[FloatArray, ...]]:
    """Y from the plan control and the straight lines (each line its own a, b).

    Returns the lines' (a, b) in the frame (L, 2) and, line by line, the
    residuals (corrected Y minus the line's Y), redundancy numbers and
    normalised residuals."""
    lines, kinds, mask_xy, sxy = data.lines, data.kinds, data.mask_xy, data.sxy
    centre, half = norm.centre, norm.half_extent
    n_plan = int(mask_xy.sum())
    k_y = n_terms(kinds[1], data.n_sections)
    n_lines = len(lines)
    sigma_ref = float(np.median(sxy[mask_xy])) if n_plan else 1.0
    plan_rows = design.rows(mask_xy, k_y)
    rows = [plan_rows]
    extra = [np.zeros((n_plan, 2 * n_lines))]
    obs_y = [_observed(data)[mask_xy, 1]]
    sig_y = [sxy[mask_xy]]
    for k, line in enumerate(lines):
        u_l, v_l = norm.apply(line.xyz)
        rows.append(design.terms(u_l, v_l, kinds[1])[:, :k_y])
        block = np.zeros((u_l.shape[0], 2 * n_lines))
        block[:, 2 * k] = 1.0
        block[:, 2 * k + 1] = u_l
        extra.append(block)
        obs_y.append(line.xyz[:, 1] - centre[1])
        sig_y.append(np.full(u_l.shape[0], sigma_ref / np.sqrt(line.weight)))
    design_y: FloatArray | RowSupport
    if lines:  # the lines' a, b couple all sections: a dense design
        if isinstance(plan_rows, RowSupport):
            rows[0] = _dense(plan_rows)
        design_y = np.concatenate(
            # every entry of rows is dense now (the plan rows just above)
            [np.concatenate(rows, axis=0), np.concatenate(extra, axis=0)],  # type: ignore[arg-type]
            axis=1,
        )
    else:  # the plan control's rows alone, sparse over sections
        design_y = plan_rows
    observed_y = np.concatenate(obs_y)
    sigma_y = np.concatenate(sig_y)
    x, v_fit, normals = _solve(
        design_y,
        observed_y,
        sigma_y,
        what=f"polynomial type {kinds[1]} for Y" + (" with straight lines" if lines else ""),
        names=data.plan_ids + [p for line in lines for p in line.point_ids],
        # Without lines Y has the design and weights of X: one inverse serves both.
        normals=normals_x if not lines and kinds[1] == kinds[0] else None,
        order=None if lines else design.band_order,
    )
    r = normals.redundancy
    fit.coefficients[1, :k_y] = x[:k_y]
    alpha_beta = x[k_y:].reshape(n_lines, 2)
    fit.residuals[mask_xy, 1] = -v_fit[:n_plan]
    fit.redundancy_numbers[mask_xy, 1] = r[:n_plan]
    fit.normalized[mask_xy, 1] = _normalized(-v_fit[:n_plan], sxy[mask_xy], r[:n_plan])
    fit.add(1, float(np.sum((v_fit / sigma_y) ** 2)), int(observed_y.size - k_y - 2 * n_lines))

    # Lines: residual = corrected Y - line Y = (Y - w_Y) - (a + bX) = v (observed - fitted).
    line_res: list[FloatArray] = []
    line_red: list[FloatArray] = []
    line_norm: list[FloatArray] = []
    line_params = np.zeros((n_lines, 2))
    start = n_plan
    for k, line in enumerate(lines):
        m = line.xyz.shape[0]
        v_k = v_fit[start : start + m].copy()
        r_k = r[start : start + m].copy()
        line_res.append(v_k)
        line_red.append(r_k)
        line_norm.append(_normalized(v_k, sigma_y[start : start + m], r_k))
        alpha, beta = alpha_beta[k]
        b = beta / half
        line_params[k] = (alpha + centre[1] - b * centre[0], b)
        start += m
    return line_params, tuple(line_res), tuple(line_red), tuple(line_norm)


# --------------------------------------------------------------------------- automatic choice


