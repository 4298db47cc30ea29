"""The basis functions of J(16)'s deformation polynomials: the terms of each
type (1, X, Y, XY, X², X³), the cubic B-spline basis of the sections along
the strip and its piecewise-power form, evaluated for every point at once
(:mod:`.deformation` fits them).
"""

from __future__ import annotations

import numpy as np

from .._typing import ArrayLike, FloatArray, IntArray
from ..options import DEFAULT_SECTIONS, check_sections
from .similarity import RowSupport

__all__ = ["bspline_basis", "n_terms", "polynomial_terms", "section_terms", "term_names"]


_N_TERMS = {0: 0, 1: 4, 2: 5, 3: 6}


_TERM_NAMES = ("1", "X", "Y", "XY", "X^2", "X^3")


def _check_kind(kind: object) -> int:
    if (
        isinstance(kind, bool)
        or not isinstance(kind, int | np.integer)
        or int(kind) not in _N_TERMS
    ):
        raise ValueError(f"Expected polynomial `kind` to be one of 0, 1, 2, 3, got {kind!r}")
    return int(kind)


def n_terms(kind: int, sections: int = DEFAULT_SECTIONS) -> int:
    """Number of terms per coordinate of a J(16) polynomial type: 0, 4, 5 or 6
    for one section; ``degree + 2 S + 1`` over S sections (module docstring)."""
    k = _check_kind(kind)
    s = check_sections(sections)
    # f: k + S B-splines, g: S + 1 (for S = 1 J's 4, 5, 6 terms)
    return 0 if k == 0 else k + 2 * s + 1


def polynomial_terms(x: ArrayLike, y: ArrayLike, kind: int) -> FloatArray:
    """Design columns of the J(16) polynomial of type `kind`.

    Parameters
    ----------
    x, y : array_like, shape (...)
        Plan coordinates, broadcast against each other.  No normalisation is
        done here: pass normalised values (as :func:`fit_deformation` does,
        see :class:`Normalization`) to keep the columns well conditioned.
    kind : int
        0 (no terms), 1 ``[1, X, Y, XY]``, 2 ``+ X²``, 3 ``+ X³`` (B(150)).

    Returns
    -------
    ndarray, shape (..., n_terms(kind))

    Examples
    --------
    >>> polynomial_terms([2.0], [3.0], 3)
    array([[1., 2., 3., 6., 4., 8.]])
    """
    k = _check_kind(kind)
    x_arr, y_arr = np.broadcast_arrays(
        np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    )
    columns = [np.ones_like(x_arr), x_arr, y_arr, x_arr * y_arr, x_arr**2, x_arr**3]
    if k == 0:
        return np.zeros((*x_arr.shape, 0))
    return np.stack(columns[: _N_TERMS[k]], axis=-1)


def _bspline_nonzero(
    x: FloatArray, breakpoints: FloatArray, degree: int
) -> tuple[FloatArray, IntArray]:
    """The ``degree + 1`` B-spline values that can be nonzero at each x, (N, d + 1),
    and the index of the first of them, (N,): the local support that lets a
    spline be evaluated without a dense (N, S + d) design."""
    d = degree
    n_sections = breakpoints.size - 1
    knots = np.concatenate([np.full(d, breakpoints[0]), breakpoints, np.full(d, breakpoints[-1])])
    span = d + np.clip(np.searchsorted(breakpoints, x, side="right") - 1, 0, n_sections - 1)
    values = np.zeros((x.size, d + 1))
    values[:, 0] = 1.0
    left = np.empty((x.size, d + 1))
    right = np.empty((x.size, d + 1))
    for j in range(1, d + 1):
        left[:, j] = x - knots[span + 1 - j]
        right[:, j] = knots[span + j] - x
        saved = np.zeros(x.size)
        for r in range(j):
            temp = values[:, r] / (right[:, r + 1] + left[:, j - r])
            values[:, r] = saved + right[:, r + 1] * temp
            saved = left[:, j - r] * temp
        values[:, j] = saved
    return values, span - d


def _check_breakpoints(breakpoints: ArrayLike) -> FloatArray:
    b = np.asarray(breakpoints, dtype=np.float64)
    if b.ndim != 1 or b.size < 2 or np.any(np.diff(b) <= 0.0):
        raise ValueError("Expected at least two increasing `breakpoints`")
    return b


def bspline_basis(u: ArrayLike, breakpoints: ArrayLike, degree: int) -> FloatArray:
    """B-spline basis of a spline of `degree` with the given `breakpoints`.

    The knot vector is clamped: the first and last breakpoints repeated
    ``degree + 1`` times, the interior ones simple (a spline of class
    C^(degree-1)).  Outside the first and last breakpoints the basis of the
    end piece continues as polynomials, so the spline extrapolates by its end
    pieces (as a single polynomial would).

    Parameters
    ----------
    u : array_like, shape (N,)
        Abscissae (normalised along-strip coordinate).
    breakpoints : array_like, shape (S + 1,)
        Increasing section boundaries, S >= 1.
    degree : int
        1, 2 or 3.

    Returns
    -------
    ndarray, shape (N, S + degree)
        Column j is B_j(u); the columns sum to 1 everywhere.

    Notes
    -----
    Cox-de Boor recurrence in the triangular form of Piegl & Tiller, The
    NURBS Book, algorithm A2.2, vectorised over u with the knot span
    clipped to the first and last.
    """
    x = np.asarray(u, dtype=np.float64).reshape(-1)
    b = _check_breakpoints(breakpoints)
    if (
        isinstance(degree, bool)
        or not isinstance(degree, int | np.integer)
        or degree not in (1, 2, 3)
    ):
        raise ValueError(f"Expected `degree` 1, 2 or 3, got {degree!r}")
    values, first = _bspline_nonzero(x, b, degree)
    out = np.zeros((x.size, b.size - 1 + degree))
    np.put_along_axis(out, first[:, None] + np.arange(degree + 1), values, axis=1)
    return out


def _power_pieces(degree: int, breakpoints: FloatArray, coefficients: FloatArray) -> FloatArray:
    """Each section's piece of the splines ``Σ_j coefficients[:, j] B_j`` in
    the power basis of ``t = (u - b_s) / (b_(s+1) - b_s)``: shape
    (degree + 1, C, S) for coefficients (C, S + degree), row k the
    coefficient of t^k.

    The pieces are interpolated at degree + 1 equally spaced t in [0, 1] of
    each section (exact for polynomials of that degree; the Vandermonde
    matrix of those nodes has condition below 100 for degree 3)."""
    n_sections = breakpoints.size - 1
    nodes = np.linspace(0.0, 1.0, degree + 1)
    width = np.diff(breakpoints)
    u = (breakpoints[:-1, None] + width[:, None] * nodes).reshape(-1)  # (S (d + 1),)
    values, first = _bspline_nonzero(u, breakpoints, degree)
    gathered = np.take(coefficients, first[:, None] + np.arange(degree + 1), axis=1)
    at_nodes = np.einsum("nr,cnr->cn", values, gathered).reshape(-1, n_sections, degree + 1)
    vandermonde = nodes[:, None] ** np.arange(degree + 1)
    return np.linalg.solve(
        vandermonde, at_nodes.transpose(2, 0, 1).reshape(degree + 1, -1)
    ).reshape(degree + 1, -1, n_sections)


def _horner(pieces: FloatArray, section: IntArray, t: FloatArray) -> FloatArray:
    """Value at t of the piece of each point's section, from (d + 1, S) power-basis rows."""
    out = np.take(pieces[-1], section)
    for row in pieces[-2::-1]:
        out *= t
        out += np.take(row, section)
    return out


#: Points per chunk of a spline evaluation (the gathers and Horner steps stay in cache).
_CHUNK_POINTS = 32_768


def _spline_pieces(
    kind: int, breakpoints: FloatArray, coefficients: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The power-basis pieces (:func:`_power_pieces`) of f (degree `kind`) and
    of g (degree 1) for coefficients (C, n_terms(kind, S))."""
    n_f = breakpoints.size - 1 + kind
    return (
        _power_pieces(kind, breakpoints, coefficients[:, :n_f]),
        _power_pieces(1, breakpoints, coefficients[:, n_f:]),
    )


def _section_values(
    u: FloatArray,
    v: FloatArray,
    kind: int,
    breakpoints: FloatArray,
    coefficients: FloatArray,
    pieces: tuple[FloatArray, FloatArray] | None = None,
) -> FloatArray:
    """``section_terms(u, v, kind, breakpoints) @ coefficients.T``: (N, 3) for
    coefficients (3, n_terms).

    Evaluated piece by piece: each point's section (by one division for
    equal sections, by binary search otherwise), then f and g by Horner's
    rule in the power basis of that section (the end pieces continue beyond
    the first and last breakpoints), which costs a few operations per point
    instead of the Cox-de Boor recurrence.  ``pieces``: those of
    :func:`_spline_pieces` for these coefficients, when already at hand."""
    f_pieces, g_pieces = pieces or _spline_pieces(kind, breakpoints, coefficients)
    left, width = breakpoints[:-1], np.diff(breakpoints)
    # Equal sections (those of fit_deformation): the section by one division
    # instead of a binary search per point (6 ms for 200 000 points); a point
    # on a breakpoint may go to either side, where both pieces agree.
    equal = float(np.ptp(width)) <= 1e-12 * float(width.max())
    out = np.empty((u.size, coefficients.shape[0]))
    for lo in range(0, u.size, _CHUNK_POINTS):
        uc, vc = u[lo : lo + _CHUNK_POINTS], v[lo : lo + _CHUNK_POINTS]
        if equal:
            with np.errstate(invalid="ignore"):  # NaN points stay NaN through t
                section = ((uc - breakpoints[0]) * (1.0 / width[0])).astype(np.intp)
        else:
            section = np.searchsorted(breakpoints, uc, side="right") - 1
        np.clip(section, 0, breakpoints.size - 2, out=section)
        t = (uc - np.take(left, section)) / np.take(width, section)
        for c in range(coefficients.shape[0]):
            g = _horner(g_pieces[:, c], section, t)
            g *= vc
            g += _horner(f_pieces[:, c], section, t)
            out[lo : lo + _CHUNK_POINTS, c] = g
    return out


def section_terms(u: ArrayLike, v: ArrayLike, kind: int, breakpoints: ArrayLike) -> FloatArray:
    """Design columns of a J(16) type over sections: ``[B_j(u)] + [v L_j(u)]``.

    ``B_j`` is the B-spline basis of the degree of the type (1, 2, 3) and
    ``L_j`` the piecewise-linear one, both on `breakpoints` (normalised u,
    shape (S + 1,)); see :func:`bspline_basis`.  With one section the columns
    span exactly J's ``[1, u, v, uv, u², u³][:n]``.

    Returns
    -------
    ndarray, shape (N, n_terms(kind, S))
    """
    k = _check_kind(kind)
    u_arr, v_arr = np.broadcast_arrays(
        np.asarray(u, dtype=np.float64).reshape(-1), np.asarray(v, dtype=np.float64).reshape(-1)
    )
    if k == 0:
        return np.zeros((u_arr.size, 0))
    return _dense(_section_support(u_arr, v_arr, k, _check_breakpoints(breakpoints)))


def _section_support(
    u: FloatArray, v: FloatArray, kind: int, breakpoints: FloatArray
) -> RowSupport:
    """:func:`section_terms` as the nonzero entries of each row: the
    ``kind + 1`` B-splines and the two hats of the row's section, (N, kind + 3)."""
    f_values, f_first = _bspline_nonzero(u, breakpoints, kind)
    g_values, g_first = _bspline_nonzero(u, breakpoints, 1)
    n_f = breakpoints.size - 1 + kind
    index = np.concatenate(
        [f_first[:, None] + np.arange(kind + 1), n_f + g_first[:, None] + np.arange(2)], axis=1
    )
    value = np.concatenate([f_values, g_values * v[:, None]], axis=1)
    return RowSupport(index, value, n_f + breakpoints.size)


def term_names(kind: int, sections: int = DEFAULT_SECTIONS) -> tuple[str, ...]:
    """Names of the design columns: J's ``1, X, Y, XY, X^2, X^3`` for one
    section, ``f0 .. f(n-1)`` (along-strip B-spline) and ``Y·g0 .. Y·gS``
    (Y times the piecewise-linear basis) for several."""
    k = _check_kind(kind)
    s = check_sections(sections)
    if s == 1:
        return _TERM_NAMES[: _N_TERMS[k]]
    if k == 0:
        return ()
    return tuple(f"f{j}" for j in range(s + k)) + tuple(f"Y·g{j}" for j in range(s + 1))


def _dense(rows: RowSupport) -> FloatArray:
    """The (n, k) matrix of rows given by their nonzero entries, each column
    at most once in a row (no padding, as :func:`_section_support`)."""
    out = np.zeros((rows.columns.shape[0], rows.n_columns))
    np.put_along_axis(out, rows.columns, rows.value, axis=1)
    return out


def _stations(x: FloatArray, tol: float) -> int:
    """Number of distinct positions in x, positions closer than tol counting once."""
    if x.size == 0:
        return 0
    xs = np.sort(x)
    return int(1 + np.count_nonzero(np.diff(xs) > tol))
