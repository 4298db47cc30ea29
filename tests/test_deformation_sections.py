"""Tests of the deformation polynomials over sections along the strip (deformation.py).

With ``sections=S > 1`` each J(16) polynomial ``w = f(u) + v g(u)`` has f a B-spline of
degree 1/2/3 (type 1/2/3) on S equal sections between the first and last control X and g a
continuous piecewise-linear function; beyond the end breakpoints the end pieces continue as
polynomials (module docstring of deformation.py).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.interpolate import BSpline

from strip_aerotri.errors import GeometryError
from strip_aerotri.geometry.deformation import (
    StraightLine,
    bspline_basis,
    fit_deformation,
    n_terms,
    polynomial_terms,
    section_terms,
    term_names,
)
from strip_aerotri.geometry.deformation_auto import select_kind_auto

# A synthetic strip 12 km long (X along the strip), 2 km wide, in metres: stations every
# 1 km, so three sections of 4 km hold four or five stations each.
LENGTH, HALF_WIDTH = 12_000.0, 1_000.0
STATIONS = np.arange(0.0, LENGTH + 1.0, 1_000.0)
# Uneven breakpoints for the basis tests (normalised u).
UNEVEN = np.array([-1.0, -0.55, -0.4, 0.3, 1.0])


def strip_control(stations: np.ndarray, seed: int, across=(-HALF_WIDTH, HALF_WIDTH)) -> np.ndarray:
    """Full control at every station on the given lines across the strip, random heights."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.asarray(stations, dtype=float), np.asarray(across, dtype=float))
    return np.column_stack([x.ravel(), y.ravel(), rng.uniform(-30.0, 30.0, x.size)])


def all_true(n: int) -> np.ndarray:
    return np.ones(n, dtype=bool)


def fit_frame(xyz: np.ndarray) -> tuple[np.ndarray, float]:
    """Normalisation of fit_deformation (its docstring): centroid of the plan coordinates of
    the used points, half their range in X."""
    return xyz[:, :2].mean(axis=0), 0.5 * float(np.ptp(xyz[:, 0]))


def spline_w(
    points: np.ndarray,
    coefficients: np.ndarray,
    kind: int,
    x_breaks: np.ndarray,
    centre: np.ndarray,
    half: float,
) -> np.ndarray:
    """A deformation (metres) that lies in the space of section_terms on `x_breaks` (metres).

    The centre must be the fit's: another v origin adds ``c g(u)``, only C0, which is outside
    the spline space of f for types 2 and 3.
    """
    u = (points[:, 0] - centre[0]) / half
    v = (points[:, 1] - centre[1]) / half
    return section_terms(u, v, kind, (x_breaks - centre[0]) / half) @ coefficients.T


def j16_w(points: np.ndarray) -> np.ndarray:
    """A J(16) type-3 deformation (metres), in a normalisation of its own."""
    u = (points[:, 0] - 4_000.0) / 7_000.0
    v = (points[:, 1] + 300.0) / 7_000.0
    coefficients = np.array(
        [
            [0.3, 0.2, -0.5, 0.1, 0.4, -0.3],
            [-0.2, 0.1, 0.3, -0.2, 0.8, 0.5],
            [0.5, -0.3, 0.2, 0.3, -1.2, 0.6],
        ]
    )
    return polynomial_terms(u, v, 3) @ coefficients.T


def one_sided_taylor(res, x0: float, y: float, h: float, side: int) -> np.ndarray:
    """Taylor coefficients ``a_m = w^(m)(x0) h^m / m!`` (m = 0..3, metres, shape (4, 3)) of
    the piece of the fitted deformation on one side of x0 along X at fixed Y.

    The piece is a polynomial of degree <= 3 in X, so the cubic through the four points
    ``x0 + side * h * k`` (k = 1..4, none at x0) is the piece itself: one-sided finite
    differences exact for it.
    """
    t = side * np.arange(1.0, 5.0)
    pts = np.column_stack([x0 + h * t, np.full(4, y), np.zeros(4)])
    values = res.evaluate(pts)  # (4, 3)
    vander = np.vander(t, 4, increasing=True)  # columns 1, t, t², t³
    return np.linalg.solve(vander, values)


# --------------------------------------------------------------------------- B-spline basis


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_bspline_basis_shape_partition_of_unity_and_sign(degree):
    rng = np.random.default_rng(100 + degree)
    inside = rng.uniform(UNEVEN[0], UNEVEN[-1], 200)
    inside = np.concatenate([inside, UNEVEN])  # the breakpoints themselves too
    outside = np.concatenate([rng.uniform(-2.5, -1.0, 50), rng.uniform(1.0, 2.5, 50)])
    outside = outside[np.abs(np.abs(outside) - 1.0) > 1e-6]
    s = UNEVEN.size - 1
    basis_in = bspline_basis(inside, UNEVEN, degree)
    basis_out = bspline_basis(outside, UNEVEN, degree)
    assert basis_in.shape == (inside.size, s + degree)
    assert basis_out.shape == (outside.size, s + degree)
    np.testing.assert_allclose(basis_in.sum(axis=1), 1.0, rtol=0, atol=1e-13)
    # Outside, the end pieces continue as polynomials whose sum is still 1 identically.
    np.testing.assert_allclose(basis_out.sum(axis=1), 1.0, rtol=0, atol=1e-12)
    assert np.all(basis_in >= 0.0)
    # Outside the range the end pieces' continuations are not all positive (degree >= 2).
    if degree >= 2:
        assert np.any(basis_out < -1e-3)
    # Local support: at most degree + 1 nonzero columns per row.
    assert np.max(np.count_nonzero(basis_in, axis=1)) <= degree + 1
    # Clamped ends: the first / last basis function is 1 at the first / last breakpoint.
    ends = bspline_basis(UNEVEN[[0, -1]], UNEVEN, degree)
    np.testing.assert_allclose(ends[0], np.eye(s + degree)[0], atol=1e-15)
    np.testing.assert_allclose(ends[1], np.eye(s + degree)[-1], atol=1e-15)


def clamped_knots(breakpoints: np.ndarray, degree: int) -> np.ndarray:
    return np.concatenate(
        [np.full(degree, breakpoints[0]), breakpoints, np.full(degree, breakpoints[-1])]
    )


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_bspline_basis_matches_scipy_inside(degree):
    rng = np.random.default_rng(200 + degree)
    # Strictly inside the range (scipy's design_matrix needs t[k] <= x <= t[n]), with the
    # interior breakpoints among the points.
    u = np.concatenate([rng.uniform(-0.999, 0.999, 300), UNEVEN[1:-1]])
    knots = clamped_knots(UNEVEN, degree)
    expected = BSpline.design_matrix(u, knots, degree).toarray()
    got = bspline_basis(u, UNEVEN, degree)
    assert got.shape == expected.shape
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-14)


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_bspline_basis_continues_the_end_pieces_outside(degree):
    rng = np.random.default_rng(300 + degree)
    knots = clamped_knots(UNEVEN, degree)
    n_basis = UNEVEN.size - 1 + degree
    for end, inner, outer in (
        (
            UNEVEN[0],
            np.linspace(UNEVEN[0] + 0.02, UNEVEN[1] - 0.02, 4),
            rng.uniform(-2, -1.0001, 20),
        ),
        (
            UNEVEN[-1],
            np.linspace(UNEVEN[-2] + 0.05, UNEVEN[-1] - 0.05, 4),
            rng.uniform(1.0001, 2, 20),
        ),
    ):
        # The cubic through four points of the end span is the end piece of every column.
        piece = np.linalg.solve(
            np.vander(inner, 4, increasing=True), bspline_basis(inner, UNEVEN, degree)
        )
        continued = np.vander(outer, 4, increasing=True) @ piece
        got = bspline_basis(outer, UNEVEN, degree)
        np.testing.assert_allclose(got, continued, rtol=0, atol=1e-10)
        # scipy extrapolates a B-spline by its end pieces in the same way.
        scipy_basis = BSpline(knots, np.eye(n_basis), degree, extrapolate=True)(outer)
        np.testing.assert_allclose(got, scipy_basis, rtol=0, atol=1e-12)
        # ... and not by holding the values at the end breakpoint.
        held = bspline_basis(np.full(outer.size, end), UNEVEN, degree)
        assert np.max(np.abs(got - held)) > 0.1


def test_bspline_basis_rejects_bad_arguments():
    with pytest.raises(ValueError, match="increasing"):
        bspline_basis([0.0], [0.0, 1.0, 1.0], 2)
    with pytest.raises(ValueError, match="increasing"):
        bspline_basis([0.0], [1.0], 2)
    with pytest.raises(ValueError, match="degree"):
        bspline_basis([0.0], [0.0, 1.0], 4)
    with pytest.raises(ValueError, match="degree"):
        bspline_basis([0.0], [0.0, 1.0], 0)


@pytest.mark.parametrize("degree", [True, 2.0])
def test_bspline_basis_rejects_bool_and_float_degree(degree):
    # style.md: ValueError for bad arguments (as _check_kind does for kind=True).
    with pytest.raises(ValueError, match="degree"):
        bspline_basis([0.0], [0.0, 1.0], degree)


# --------------------------------------------------------------------------- section terms


@pytest.mark.parametrize("kind", [1, 2, 3])
@pytest.mark.parametrize("breakpoints", [(-1.0, 1.0), (-0.7, 1.4)])
def test_one_section_spans_j16_polynomial(kind, breakpoints):
    rng = np.random.default_rng(400 + kind)
    u = rng.uniform(-1.6, 1.6, 60)  # inside and beyond the section
    v = rng.uniform(-0.3, 0.3, 60)
    sec = section_terms(u, v, kind, breakpoints)
    poly = polynomial_terms(u, v, kind)
    assert sec.shape == poly.shape == (60, n_terms(kind))
    for a, b in ((sec, poly), (poly, sec)):
        coef, *_ = np.linalg.lstsq(a, b, rcond=None)
        assert np.max(np.abs(a @ coef - b)) < 1e-12
    # Full rank: the same space, not a subspace of it.
    assert np.linalg.matrix_rank(sec) == n_terms(kind)


@pytest.mark.parametrize("kind", [1, 2, 3])
@pytest.mark.parametrize("sections", [2, 3, 5])
def test_several_sections_contain_j16_and_more(kind, sections):
    # The section space contains J's polynomial and is larger (a genuine spline).
    rng = np.random.default_rng(500 + 10 * kind + sections)
    u = rng.uniform(-1.2, 1.2, 120)
    v = rng.uniform(-0.3, 0.3, 120)
    bp = np.linspace(-1.0, 1.0, sections + 1)
    sec = section_terms(u, v, kind, bp)
    poly = polynomial_terms(u, v, kind)
    coef, *_ = np.linalg.lstsq(sec, poly, rcond=None)
    assert np.max(np.abs(sec @ coef - poly)) < 1e-12
    assert np.linalg.matrix_rank(sec) == n_terms(kind, sections) > n_terms(kind)


def test_term_counts_and_names():
    u = np.linspace(-1.0, 1.0, 7)
    v = np.linspace(-0.2, 0.2, 7)
    assert [n_terms(k, 1) for k in range(4)] == [0, 4, 5, 6]
    for kind, degree in ((1, 1), (2, 2), (3, 3)):
        for s in (1, 2, 3, 4, 7):
            n = n_terms(kind, s)
            assert n == degree + 2 * s + 1
            bp = np.linspace(-1.0, 1.0, s + 1)
            assert section_terms(u, v, kind, bp).shape == (7, n)
            names = term_names(kind, s)
            assert len(names) == n
            assert len(set(names)) == n
        assert term_names(kind) == ("1", "X", "Y", "XY", "X^2", "X^3")[: n_terms(kind)]
    assert term_names(3, 2) == ("f0", "f1", "f2", "f3", "f4", "Y·g0", "Y·g1", "Y·g2")
    assert n_terms(0, 3) == 0
    assert term_names(0, 3) == ()
    assert section_terms(u, v, 0, [-1.0, 0.0, 1.0]).shape == (7, 0)
    # The v part is v times the piecewise-linear basis: zero on v = 0.
    sec = section_terms(u, np.zeros(7), 3, [-1.0, 0.0, 1.0])
    np.testing.assert_array_equal(sec[:, 5:], 0.0)
    np.testing.assert_allclose(
        section_terms(u, v, 2, [-1.0, 0.0, 1.0])[:, 4:],
        v[:, None] * bspline_basis(u, [-1.0, 0.0, 1.0], 1),
        rtol=0,
        atol=1e-15,
    )


# --------------------------------------------------------------------------- fit: identity


# Points where the deformation is evaluated: between the control, off its lines across the
# strip, and 2.5 km beyond both ends of the strip.
OFF_CONTROL = np.column_stack(
    [
        np.array(
            [-2_500.0, -700.0, 550.0, 3_999.0, 4_001.0, 6_123.0, 8_000.0, 11_800.0, 14_500.0]
        ),
        np.array([0.0, 800.0, -350.0, 120.0, -999.0, 0.0, 640.0, -20.0, 1_300.0]),
        np.zeros(9),
    ]
)


@pytest.mark.parametrize("sections", [1, 3])
def test_j16_polynomial_is_reproduced_with_and_without_sections(sections):
    xyz = strip_control(STATIONS, seed=1)
    n = xyz.shape[0]
    target = xyz - j16_w(xyz)
    res = fit_deformation(
        xyz, target, use_xy=all_true(n), use_z=all_true(n), kind=3, sections=sections
    )
    assert np.max(np.abs(res.residuals)) < 1e-9
    np.testing.assert_allclose(res.evaluate(OFF_CONTROL), j16_w(OFF_CONTROL), rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.correct(xyz), target, rtol=0, atol=1e-9)
    assert res.sections == sections
    assert res.coefficients.shape == (3, n_terms(3, sections))
    assert res.term_names == term_names(3, sections)
    assert res.redundancy_xyz == (n - n_terms(3, sections),) * 3
    if sections == 1:
        assert res.breakpoints is None
        assert res.breakpoints_x.shape == (0,)
    else:
        np.testing.assert_allclose(res.breakpoints_x, [0.0, 4_000.0, 8_000.0, LENGTH], atol=1e-9)
        # Normalised breakpoints: the X breakpoints in the fit's normalisation.
        centre, half = fit_frame(xyz)
        np.testing.assert_allclose(res.normalization.centre, centre, atol=1e-9)
        assert res.normalization.half_extent == pytest.approx(half, rel=1e-15)
        np.testing.assert_allclose(
            res.breakpoints, (res.breakpoints_x - centre[0]) / half, rtol=0, atol=1e-15
        )


def random_spline_case(kind: int, sections: int, seed: int):
    """Control of the whole strip and a deformation that is a genuine spline of `kind` on
    `sections` equal sections between the first and last station."""
    xyz = strip_control(STATIONS, seed=seed)
    centre, half = fit_frame(xyz)
    x_breaks = np.linspace(STATIONS[0], STATIONS[-1], sections + 1)
    rng = np.random.default_rng(seed + 1000)
    coefficients = rng.normal(scale=0.5, size=(3, n_terms(kind, sections)))

    def w(points):
        return spline_w(points, coefficients, kind, x_breaks, centre, half)

    return xyz, w


@pytest.mark.parametrize("kind", [1, 2, 3])
def test_spline_deformation_needs_its_sections(kind):
    xyz, w = random_spline_case(kind, 3, seed=20 + kind)
    n = xyz.shape[0]
    target = xyz - w(xyz)
    ones = all_true(n)
    res = fit_deformation(xyz, target, use_xy=ones, use_z=ones, kind=kind, sections=3)
    assert np.max(np.abs(res.residuals)) < 1e-9
    np.testing.assert_allclose(res.evaluate(OFF_CONTROL), w(OFF_CONTROL), rtol=0, atol=1e-9)
    # Six sections contain the three (their breakpoints include these): still exact.
    res6 = fit_deformation(xyz, target, use_xy=ones, use_z=ones, kind=kind, sections=6)
    assert np.max(np.abs(res6.residuals)) < 1e-9
    np.testing.assert_allclose(res6.evaluate(OFF_CONTROL), w(OFF_CONTROL), rtol=0, atol=1e-9)
    # One polynomial (J(16)) and two sections (other breakpoints) cannot follow it.  The
    # deformation is 0.5 m-scale; what is left is tens of centimetres in some coordinate.
    for other in (1, 2):
        bad = fit_deformation(xyz, target, use_xy=ones, use_z=ones, kind=kind, sections=other)
        assert np.max(np.abs(bad.residuals)) > 0.05


# --------------------------------------------------------------------------- continuity


@pytest.mark.parametrize("kind", [1, 2, 3])
def test_fitted_deformation_is_continuous_across_breakpoints(kind):
    # A smooth deformation that is no spline: the fit has generic coefficients.
    xyz = strip_control(STATIONS, seed=30, across=(-HALF_WIDTH, 0.0, HALF_WIDTH))
    n = xyz.shape[0]
    phase = xyz[:, 0] / LENGTH * 2.0 * np.pi
    w = np.column_stack(
        [
            0.4 * np.sin(1.7 * phase) + 0.2 * xyz[:, 1] / HALF_WIDTH * np.cos(phase),
            0.6 * np.cos(2.3 * phase + 0.4) - 0.3 * xyz[:, 1] / HALF_WIDTH * np.sin(2 * phase),
            0.5 * np.sin(2.9 * phase + 1.0) + 0.1 * xyz[:, 1] / HALF_WIDTH,
        ]
    )
    ones = all_true(n)
    res = fit_deformation(xyz, xyz - w, use_xy=ones, use_z=ones, kind=kind, sections=3)
    centre_y = float(res.normalization.centre[1])
    h = 500.0  # stencil step along X, metres (sections are 4 km long)
    interior = res.breakpoints_x[1:-1]
    assert interior.size == 2
    for x0 in interior:
        # On the centre line (v = 0) only f(u) acts: C^(d-1) with d the degree of the type.
        left = one_sided_taylor(res, x0, centre_y, h, -1)
        right = one_sided_taylor(res, x0, centre_y, h, +1)
        # a_m = w^(m) h^m / m! in metres: derivatives 0..d-1 agree, the d-th jumps.
        np.testing.assert_allclose(left[:kind], right[:kind], rtol=0, atol=1e-12)
        assert np.max(np.abs(left[kind] - right[kind])) > 1e-3
        # Off the centre line the value is still continuous, but v g(u) has a kink
        # (g is only piecewise linear): the slope along X jumps there.
        for y in (-900.0, 700.0):
            left = one_sided_taylor(res, x0, y, h, -1)
            right = one_sided_taylor(res, x0, y, h, +1)
            np.testing.assert_allclose(left[0], right[0], rtol=0, atol=1e-9)
            if kind >= 2:
                assert np.max(np.abs(left[1] - right[1])) > 1e-2
    # Evaluated just left and right of a breakpoint, the deformation does not step.
    eps = 1e-6  # metres
    for x0 in interior:
        pts = np.array([[x0 - eps, 300.0, 0.0], [x0 + eps, 300.0, 0.0]])
        wl, wr = res.evaluate(pts)
        np.testing.assert_allclose(wl, wr, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- errors


@pytest.mark.parametrize("sections", [0, -1, True, 2.5, "2", None])
def test_bad_sections_raise_value_error(sections):
    xyz = strip_control(STATIONS, seed=40)
    n = xyz.shape[0]
    with pytest.raises(ValueError, match="sections"):
        fit_deformation(xyz, xyz, use_xy=all_true(n), use_z=all_true(n), kind=2, sections=sections)
    with pytest.raises(ValueError, match="sections"):
        n_terms(2, sections)
    with pytest.raises(ValueError, match="sections"):
        term_names(2, sections)


@pytest.mark.parametrize("kind", [(1, 3, 1), (3, 3, 2), (0, 0, 0), 0])
def test_sections_need_one_type_for_x_y_and_z(kind):
    xyz = strip_control(STATIONS, seed=41)
    n = xyz.shape[0]
    with pytest.raises(ValueError, match="one polynomial type"):
        fit_deformation(xyz, xyz, use_xy=all_true(n), use_z=all_true(n), kind=kind, sections=2)
    # The same types are accepted with one section.
    res = fit_deformation(xyz, xyz, use_xy=all_true(n), use_z=all_true(n), kind=kind)
    assert res.sections == 1


def test_a_section_without_control_is_named():
    xyz = strip_control(STATIONS, seed=42)
    # Sections of 4 km: 0-4000, 4000-8000, 8000-12000; X = 4000 belongs to the second.
    keep = (xyz[:, 0] < 4_000.0) | (xyz[:, 0] >= 8_000.0)
    pts = xyz[keep]
    n = pts.shape[0]
    ones = all_true(n)
    with pytest.raises(
        GeometryError,
        match=r"type 3 in 3 sections: section 2 \(X 4000\.0 to 8000\.0 m\) has no full or plan "
        r"control for X",
    ):
        fit_deformation(pts, pts, use_xy=ones, use_z=ones, kind=3, sections=3)
    # The same control serves two sections (each end holds control) and one polynomial.
    fit_deformation(pts, pts, use_xy=ones, use_z=ones, kind=3, sections=2)
    fit_deformation(pts, pts, use_xy=ones, use_z=ones, kind=3)
    # Height control missing in the last section only: the message names Z.
    n = xyz.shape[0]
    use_z = xyz[:, 0] < 8_000.0
    target = xyz.copy()
    target[~use_z, 2] = np.nan
    with pytest.raises(
        GeometryError, match=r"section 3 \(X 8000\.0 to 12000\.0 m\) has no height control for Z"
    ):
        fit_deformation(xyz, target, use_xy=all_true(n), use_z=use_z, kind=2, sections=3)


def test_too_few_stations_or_points_for_the_sections():
    # Five stations, three points across each: 15 points >= 10 terms of type 3 over three
    # sections, every section holds control, but a cubic spline on three sections needs
    # 3 + 3 = 6 stations.
    xyz = strip_control(
        np.array([0.0, 3_000.0, 6_000.0, 9_000.0, 12_000.0]),
        seed=43,
        across=(-HALF_WIDTH, 0.0, HALF_WIDTH),
    )
    n = xyz.shape[0]
    ones = all_true(n)
    with pytest.raises(
        GeometryError, match=r"type 3 in 3 sections needs .* at least 6 stations .* got 5"
    ):
        fit_deformation(xyz, xyz, use_xy=ones, use_z=ones, kind=3, sections=3)
    # Two sections need 3 + 2 = 5 stations: enough.
    res = fit_deformation(xyz, xyz, use_xy=ones, use_z=ones, kind=3, sections=2)
    assert res.sections == 2
    # Too few points: type 2 on four sections has 2 + 8 + 1 = 11 terms.
    few = strip_control(STATIONS[::2], seed=44)  # 7 stations x 2 = 14 points
    with pytest.raises(GeometryError, match=r"type 2 in 4 sections needs at least 11 .*got 8"):
        fit_deformation(
            few[:8], few[:8], use_xy=all_true(8), use_z=all_true(8), kind=2, sections=4
        )


# --------------------------------------------------------------------------- straight line


LINE_A, LINE_B = 300.0, 0.002  # the road in the ground frame: Y = 300 m + 0.002 X


def test_straight_line_with_sections():
    # Control at five stations on both edges; a road along the strip between them.
    stations = np.array([0.0, 2_500.0, 5_000.0, 7_500.0, 10_000.0])
    xyz = strip_control(stations, seed=50, across=(-900.0, 900.0))
    # Deformation in Y only: a C2 cubic spline on the sections 0-5 km and 5-10 km of f
    # (in a normalisation of its own: the spline space does not depend on it) and a twist.
    breaks_u = np.array([-1.0, 0.0, 1.0])
    f_coef = np.array([0.3, -0.8, 1.2, -0.9, 0.5])

    def w_y(points):
        u = (points[:, 0] - 5_000.0) / 5_000.0
        v = points[:, 1] / 5_000.0
        w = np.zeros_like(points)
        w[:, 1] = bspline_basis(u, breaks_u, 3) @ f_coef + 0.3 * u * v - 0.1 * v
        return w

    target = xyz - w_y(xyz)
    x_line = np.linspace(0.0, 10_000.0, 21)
    true_line = np.column_stack([x_line, LINE_A + LINE_B * x_line, np.zeros(21)])
    line_xyz = true_line.copy()
    for _ in range(40):  # photogrammetric = true + w(photogrammetric), a contraction
        line_xyz = true_line + w_y(line_xyz)
    road = StraightLine(tuple(f"R{i}" for i in range(21)), line_xyz, weight=100.0, name="road")
    ones = all_true(xyz.shape[0])
    res = fit_deformation(xyz, target, use_xy=ones, use_z=ones, kind=3, sections=2, lines=[road])
    assert res.sections == 2
    np.testing.assert_allclose(res.breakpoints_x, [0.0, 5_000.0, 10_000.0], atol=1e-9)
    assert np.max(np.abs(res.line_residuals[0])) < 1e-9
    np.testing.assert_allclose(res.correct(road.xyz)[:, 1], true_line[:, 1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.line_parameters[0], [LINE_A, LINE_B], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(res.evaluate(OFF_CONTROL), w_y(OFF_CONTROL), rtol=0, atol=1e-9)
    # The redundancy of Y: 10 control + 21 line equations - 8 terms - 2 line parameters.
    assert res.redundancy_xyz == (2, 21, 2)
    # One polynomial cannot straighten the road: the spline bend stays in it.
    res1 = fit_deformation(xyz, target, use_xy=ones, use_z=ones, kind=3, lines=[road])
    assert np.max(np.abs(res1.line_residuals[0])) > 1e-3


# --------------------------------------------------------------------------- auto choice


def test_auto_choice_with_sections():
    sigma = 0.01
    xyz, w = random_spline_case(3, 2, seed=60)
    n = xyz.shape[0]
    rng = np.random.default_rng(2345)
    target = xyz - w(xyz) + rng.normal(scale=sigma, size=xyz.shape)
    kind, table = select_kind_auto(
        xyz,
        target,
        use_xy=all_true(n),
        use_z=all_true(n),
        expected_sigma_xy=sigma,
        expected_sigma_z=sigma,
        sections=2,
    )
    assert [row.kind for row in table] == [0, 1, 2, 3]
    assert all(row.feasible for row in table)  # type 0 is still a plain similarity
    assert table[0].redundancy_xyz == (n, n, n)
    for row in table[1:]:  # types >= 1 were fitted on two sections
        assert row.redundancy_xyz == (n - n_terms(row.kind, 2),) * 3
    # A C2 cubic spline of 0.5 m scale: types 0-2 leave 3-60 cm RMS (T in the hundreds or
    # more against a critical value of about 34), type 3 on two sections leaves the noise.
    assert [row.passed for row in table] == [False, False, False, True]
    assert kind == 3
    assert np.all(table[2].rms_xyz > 2 * sigma)
    assert np.all(table[3].rms_xyz < 1.5 * sigma)


@pytest.mark.parametrize("kind", [1, 2, 3])
@pytest.mark.parametrize("breakpoints", [UNEVEN, np.linspace(-1.0, 1.0, 14)], ids=["uneven", "13"])
def test_piecewise_evaluation_equals_the_basis_times_the_coefficients(kind, breakpoints):
    """The fast evaluation (each section's piece by Horner's rule, in chunks of points)
    against the dense design of section_terms: inside, at the breakpoints, beyond the ends,
    over more points than one chunk."""
    from strip_aerotri.geometry.deformation_basis import _CHUNK_POINTS, _section_values

    rng = np.random.default_rng(kind)
    n = 2 * _CHUNK_POINTS + 17
    u = rng.uniform(-1.6, 1.6, n)
    u[: breakpoints.size] = breakpoints
    u[-1] = np.nan  # a point not triangulated stays NaN
    v = rng.uniform(-0.2, 0.2, n)
    coefficients = rng.normal(0.0, 2.0, (3, n_terms(kind, breakpoints.size - 1)))
    expected = section_terms(u, v, kind, breakpoints) @ coefficients.T
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = _section_values(u, v, kind, breakpoints, coefficients)
    assert np.isnan(got[-1]).all()
    np.testing.assert_allclose(
        got[:-1], expected[:-1], rtol=0, atol=1e-12 * np.abs(expected[:-1]).max()
    )
