"""Tests of the deformation polynomials J(16)-(18), B(150)-(151) (method.md 6.3, 6.4)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from strip_aerotri.errors import GeometryError, StripAerotriWarning
from strip_aerotri.geometry.deformation import (
    StraightLine,
    fit_deformation,
    n_terms,
    polynomial_terms,
)
from strip_aerotri.geometry.deformation_auto import select_kind_auto

# A synthetic strip 10 km long (X along the strip), 2 km wide, +-30 m relief, in metres.
LENGTH, HALF_WIDTH = 10_000.0, 1_000.0


def true_w(xyz: np.ndarray) -> np.ndarray:
    """A type-3 deformation (metres) of the photogrammetric coordinates."""
    u = (xyz[:, 0] - 5000.0) / 5000.0
    v = xyz[:, 1] / 5000.0
    wx = 0.3 + 0.2 * u - 0.5 * v + 0.1 * u * v + 0.4 * u**2 - 0.3 * u**3
    wy = -0.2 + 0.1 * u + 0.3 * v - 0.2 * u * v + 0.8 * u**2 + 0.5 * u**3
    wz = 0.5 - 0.3 * u + 0.2 * v + 0.3 * u * v - 1.2 * u**2 + 0.6 * u**3
    return np.column_stack([wx, wy, wz])


def control_grid(nx: int, ny: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.linspace(0.0, LENGTH, nx), np.linspace(-HALF_WIDTH, HALF_WIDTH, ny))
    z = rng.uniform(-30.0, 30.0, x.size)
    return np.column_stack([x.ravel(), y.ravel(), z])


def all_true(n: int) -> np.ndarray:
    return np.ones(n, dtype=bool)


# --------------------------------------------------------------------------- terms


def test_polynomial_terms_match_j16():
    x, y = np.array([2.0, -1.0]), np.array([3.0, 0.5])
    # J(16) type 3 = B(150): 1, X, Y, XY, X², X³.
    np.testing.assert_array_equal(
        polynomial_terms(x, y, 3), [[1, 2, 3, 6, 4, 8], [1, -1, 0.5, -0.5, 1, -1]]
    )
    assert polynomial_terms(x, y, 0).shape == (2, 0)
    assert polynomial_terms(x, y, 1).shape == (2, 4)
    assert polynomial_terms(x, y, 2).shape == (2, 5)
    assert [n_terms(k) for k in range(4)] == [0, 4, 5, 6]
    with pytest.raises(ValueError, match="one of 0, 1, 2, 3"):
        polynomial_terms(x, y, 4)
    with pytest.raises(ValueError, match="one of 0, 1, 2, 3"):
        polynomial_terms(x, y, True)


# --------------------------------------------------------------------------- control only


def test_type3_deformation_is_removed_exactly_without_noise():
    xyz = control_grid(5, 3, seed=1)  # 15 full points
    target = xyz - true_w(xyz)  # w = photogrammetric - control
    res = fit_deformation(xyz, target, use_xy=all_true(15), use_z=all_true(15), kind=3)
    np.testing.assert_allclose(res.correct(xyz), target, rtol=0, atol=1e-9)
    assert np.max(np.abs(res.residuals)) < 1e-9
    # Between the control: independent points of the strip are corrected exactly too.
    check = control_grid(9, 5, seed=2)[3:-3]
    np.testing.assert_allclose(res.evaluate(check), true_w(check), rtol=0, atol=1e-9)
    assert res.coefficients.shape == (3, 6)
    assert res.redundancy == 3 * (15 - 6)
    # Normalisation: centroid of the data, half the extent along X.
    np.testing.assert_allclose(res.normalization.centre[0], 5000.0)
    assert res.normalization.half_extent == pytest.approx(5000.0)


def test_type3_with_noise_corrects_to_noise_level():
    sigma = 0.03
    xyz = control_grid(6, 3, seed=3)  # 18 full points
    rng = np.random.default_rng(2345)
    target = xyz - true_w(xyz) + rng.normal(scale=sigma, size=xyz.shape)
    n = xyz.shape[0]
    res = fit_deformation(
        xyz, target, use_xy=all_true(n), use_z=all_true(n), kind=3, sigma_xy=sigma, sigma_z=sigma
    )
    # r = 3 * 12 = 36: sigma0 within its 99.9 % interval [0.64, 1.4].
    assert 0.64 < res.sigma0 < 1.4
    check = control_grid(11, 5, seed=4)
    error = res.correct(check) - (check - true_w(check))
    # Prediction error ~ sigma sqrt(6/18) = 0.017 m; the deformation itself is 0.46 m RMS.
    assert np.sqrt(np.mean(error**2)) < sigma
    assert np.sqrt(np.mean(true_w(check) ** 2)) > 0.4
    np.testing.assert_allclose(np.nansum(res.redundancy_numbers), res.redundancy, atol=1e-9)


def test_type1_cannot_remove_a_bend_but_type2_can():
    # Pure bend in Z: w_Z = 0.5 m * u², u = (X - 5000) / 5000, control at u = -1, 0, 1
    # on both edges.  Type 1 [1, X, Y, XY] can only fit the mean of u², 2/3, so the residuals
    # are 0.5 * (1/3) at the ends and 0.5 * (-2/3) in the middle:
    # RMS = 0.5 * sqrt((4 * 1/9 + 2 * 4/9) / 6) = 0.5 * sqrt(2) / 3 = 0.23570 m.
    xyz = control_grid(3, 2, seed=5)
    u = (xyz[:, 0] - 5000.0) / 5000.0
    target = xyz.copy()
    target[:, 2] -= 0.5 * u**2
    n = xyz.shape[0]
    res1 = fit_deformation(xyz, target, use_xy=all_true(n), use_z=all_true(n), kind=1)
    rms1 = np.sqrt(np.mean(res1.residuals[:, 2] ** 2))
    assert rms1 == pytest.approx(0.5 * np.sqrt(2.0) / 3.0, rel=1e-12)
    res2 = fit_deformation(xyz, target, use_xy=all_true(n), use_z=all_true(n), kind=2)
    assert np.max(np.abs(res2.residuals[:, 2])) < 1e-12
    # The bend coefficient (u² column, metres) is 0.5 exactly.
    assert res2.coefficients[2, 4] == pytest.approx(0.5, rel=1e-12)


def test_kind0_is_the_identity_and_reports_the_differences():
    xyz = control_grid(3, 2, seed=6)
    target = xyz + 0.1
    n = xyz.shape[0]
    res = fit_deformation(xyz, target, use_xy=all_true(n), use_z=all_true(n), kind=0)
    np.testing.assert_array_equal(res.correct(xyz), xyz)
    np.testing.assert_allclose(res.residuals, 0.1, atol=1e-12)
    assert res.redundancy == 3 * n
    assert res.coefficients.shape == (3, 0)


def test_plan_and_height_control_feed_their_own_polynomials():
    xyz = control_grid(5, 3, seed=7)
    n = xyz.shape[0]
    target = xyz - true_w(xyz)
    use_xy = np.arange(n) % 3 != 0  # 10 plan/full
    use_z = np.arange(n) % 3 != 1  # 10 height/full
    target[~use_xy, :2] = np.nan
    target[~use_z, 2] = np.nan
    copies = (xyz.copy(), target.copy(), use_xy.copy(), use_z.copy())
    res = fit_deformation(xyz, target, use_xy=use_xy, use_z=use_z, kind=3)
    np.testing.assert_allclose(res.evaluate(xyz), true_w(xyz), rtol=0, atol=1e-9)
    assert res.redundancy_xyz == (4, 4, 4)
    assert np.all(np.isnan(res.residuals[~use_xy, :2]))
    assert np.all(np.isnan(res.residuals[~use_z, 2]))
    for a, b in zip((xyz, target, use_xy, use_z), copies, strict=True):
        np.testing.assert_array_equal(a, b)  # inputs not modified


# --------------------------------------------------------------------------- straight line


def bend_y(xyz: np.ndarray) -> np.ndarray:
    """Deformation in Y only: a 1.5 m bend along the strip and a small twist."""
    u = (xyz[:, 0] - 5000.0) / 5000.0
    v = xyz[:, 1] / 5000.0
    w = np.zeros_like(xyz)
    w[:, 1] = 0.4 + 0.2 * u - 1.5 * u**2 + 0.3 * u * v
    return w


LINE_A, LINE_B = 300.0, 0.002  # the road in the ground frame: Y = 300 m + 0.002 X


def end_control_and_line(blunder: float = 0.0):
    """Six full points at the two ends of the strip and 11 points of a straight road."""
    xyz = np.array(
        [
            [0.0, -900.0, 5.0],
            [0.0, 0.0, 2.0],
            [0.0, 900.0, -3.0],
            [LENGTH, -900.0, 8.0],
            [LENGTH, 0.0, 4.0],
            [LENGTH, 900.0, 1.0],
        ]
    )
    target = xyz - bend_y(xyz)
    x_line = np.linspace(0.0, LENGTH, 11)
    true_line = np.column_stack([x_line, LINE_A + LINE_B * x_line, np.zeros(11)])
    line_xyz = true_line.copy()
    for _ in range(30):  # photogrammetric = true + w(photogrammetric), a contraction
        line_xyz = true_line + bend_y(line_xyz)
    line_xyz[5, 1] += blunder
    ids = tuple(f"R{i}" for i in range(11))
    return xyz, target, StraightLine(ids, line_xyz, weight=100.0, name="road")


def test_straight_line_recovers_the_bend_without_control_in_the_middle():
    xyz, target, road = end_control_and_line()
    ones = all_true(6)
    # Without the line the X² term of Y is undetermined (control at two X only).
    with pytest.raises(GeometryError, match=r"singular|stations along the strip"):
        fit_deformation(xyz, target, use_xy=ones, use_z=ones, kind=(1, 2, 1))
    res = fit_deformation(xyz, target, use_xy=ones, use_z=ones, kind=(1, 2, 1), lines=[road])
    assert res.kinds == (1, 2, 1)
    corrected = res.correct(road.xyz)
    np.testing.assert_allclose(corrected[:, 1], LINE_A + LINE_B * road.xyz[:, 0], atol=1e-9)
    np.testing.assert_allclose(res.line_parameters[0], [LINE_A, LINE_B], rtol=1e-12, atol=1e-9)
    assert np.max(np.abs(res.line_residuals[0])) < 1e-9
    # The middle of the strip, where there is no control, is right.
    middle = np.array([[5000.0, -500.0, 0.0], [5000.0, 500.0, 0.0]])
    np.testing.assert_allclose(res.evaluate(middle), bend_y(middle), atol=1e-9)
    assert res.line_names == ("road",)


def test_printed_j18_without_the_observed_term_is_wrong():
    """The [fix] of method.md 6.4: J(18) as printed, V = w_Y - a - bX (no -Y_i), fails."""
    xyz, target, road = end_control_and_line()
    res = fit_deformation(
        xyz, target, use_xy=all_true(6), use_z=all_true(6), kind=(1, 2, 1), lines=[road]
    )
    norm = res.normalization
    u_c, v_c = norm.apply(xyz)
    u_l, v_l = norm.apply(road.xyz)
    # Printed J(18): control rows w_Y = dY; line rows w_Y - a - b u = 0 (weight 100).
    a_ctrl = np.column_stack([polynomial_terms(u_c, v_c, 2), np.zeros((6, 2))])
    a_line = np.column_stack([polynomial_terms(u_l, v_l, 2), -np.ones(11), -u_l])
    design = np.vstack([a_ctrl, 10.0 * a_line])  # sqrt(100) on the line rows
    rhs = np.concatenate([(xyz - target)[:, 1], np.zeros(11)])
    x_printed, *_ = np.linalg.lstsq(design, rhs, rcond=None)
    w_printed = polynomial_terms(u_l, v_l, 2) @ x_printed[:5]
    corrected_printed = road.xyz[:, 1] - w_printed
    straight = LINE_A + LINE_B * road.xyz[:, 0]
    # The printed form leaves (nearly) the whole 1.5 m bend in the road ...
    assert np.max(np.abs(corrected_printed - straight)) > 1.4
    # ... while the fixed form straightens it exactly.
    np.testing.assert_allclose(res.correct(road.xyz)[:, 1], straight, atol=1e-9)


def test_blunder_on_a_line_point_is_exposed():
    # J: a blunder on a line point is easy to detect.
    xyz, target, road = end_control_and_line(blunder=0.5)
    rng = np.random.default_rng(2345)
    noisy = StraightLine(
        road.point_ids, road.xyz + rng.normal(scale=0.003, size=road.xyz.shape), name="road"
    )
    res = fit_deformation(
        xyz, target, use_xy=all_true(6), use_z=all_true(6), kind=(1, 2, 1), lines=[noisy]
    )
    residuals = np.abs(res.line_residuals[0])
    normalized = np.abs(res.line_normalized_residuals[0])
    assert int(np.argmax(residuals)) == 5
    assert int(np.argmax(normalized)) == 5
    assert residuals[5] > 0.3
    assert normalized[5] > 3.0 * np.sort(normalized)[-2]
    total = np.nansum(res.redundancy_numbers) + sum(np.sum(r) for r in res.line_redundancy_numbers)
    assert total == pytest.approx(res.redundancy, abs=1e-9)


def test_several_lines_have_their_own_parameters():
    xyz, target, road = end_control_and_line()
    x2 = np.linspace(500.0, 9500.0, 6)
    true2 = np.column_stack([x2, -400.0 - 0.001 * x2, np.zeros(6)])
    rail_xyz = true2.copy()
    for _ in range(30):
        rail_xyz = true2 + bend_y(rail_xyz)
    rail = StraightLine(tuple(f"T{i}" for i in range(6)), rail_xyz, weight=50.0, name="rail")
    res = fit_deformation(
        xyz, target, use_xy=all_true(6), use_z=all_true(6), kind=(1, 3, 1), lines=[road, rail]
    )
    np.testing.assert_allclose(res.line_parameters, [[300.0, 0.002], [-400.0, -0.001]], atol=1e-8)
    np.testing.assert_allclose(res.evaluate(rail_xyz), bend_y(rail_xyz), atol=1e-8)


# --------------------------------------------------------------------------- too few points


def test_too_few_height_points_for_type3():
    xyz = control_grid(3, 2, seed=8)  # 6 points
    ids = ("A", "B", "C", "D", "E", "F")
    use_z = np.array([True, True, True, True, False, False])
    target = xyz.copy()
    target[~use_z, 2] = np.nan
    with pytest.raises(
        GeometryError,
        match=r"polynomial type 3 needs at least 6 height control points for Z, got 4 "
        r"\('A', 'B', 'C', 'D'\)",
    ):
        fit_deformation(xyz, target, use_xy=all_true(6), use_z=use_z, kind=3, point_ids=ids)


def test_too_few_plan_points_and_short_lines():
    xyz = control_grid(2, 2, seed=9)
    ids = ("A", "B", "C", "D")
    with pytest.raises(
        GeometryError, match=r"type 2 needs at least 5 full or plan control points for X, got 4 "
    ):
        fit_deformation(xyz, xyz, use_xy=all_true(4), use_z=all_true(4), kind=2, point_ids=ids)
    short = StraightLine(("R1", "R2"), np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), name="road")
    with pytest.raises(
        GeometryError, match=r"straight line 'road' needs at least 3 points .*got 2: 'R1', 'R2'"
    ):
        fit_deformation(
            xyz, xyz, use_xy=all_true(4), use_z=all_true(4), kind=1, lines=[short], point_ids=ids
        )
    # Y type 3 with 4 control points and a 3-point line: 4 + (3 - 2) = 5 < 6.
    line = StraightLine(("R1", "R2", "R3"), np.array([[0.0, 0, 0], [5e3, 0, 0], [1e4, 0, 0]]))
    with pytest.raises(GeometryError, match=r"at least 6 observations for Y .*got 5"):
        fit_deformation(
            xyz,
            xyz,
            use_xy=all_true(4),
            use_z=all_true(4),
            kind=(1, 3, 1),
            lines=[line],
            point_ids=ids,
        )


def test_singular_design_all_control_at_one_x():
    xyz = np.column_stack([np.full(5, 2000.0), np.linspace(-900, 900, 5), np.zeros(5)])
    with pytest.raises(
        GeometryError, match=r"singular.*'#0', '#1'|at least 2 stations along the strip"
    ):
        fit_deformation(xyz, xyz, use_xy=all_true(5), use_z=all_true(5), kind=1)


# --------------------------------------------------------------------------- auto choice


def test_auto_picks_kind0_for_an_undeformed_strip():
    sigma = 0.05
    xyz = control_grid(5, 3, seed=10)  # 15 full points: type 3 has redundancy 9
    rng = np.random.default_rng(2345)
    target = xyz + rng.normal(scale=sigma, size=xyz.shape)
    n = xyz.shape[0]
    kind, table = select_kind_auto(
        xyz,
        target,
        use_xy=all_true(n),
        use_z=all_true(n),
        expected_sigma_xy=sigma,
        expected_sigma_z=sigma,
    )
    assert kind == 0
    assert [row.kind for row in table] == [0, 1, 2, 3]
    assert all(row.feasible for row in table)
    assert table[0].passed


def test_auto_picks_at_least_type2_for_a_bent_strip():
    sigma = 0.05
    xyz = control_grid(5, 3, seed=11)
    u = (xyz[:, 0] - 5000.0) / 5000.0
    rng = np.random.default_rng(2345)
    target = xyz + rng.normal(scale=sigma, size=xyz.shape)
    target[:, 2] += 0.6 * u**2  # a 0.6 m bend in height and 0.4 m across the strip
    target[:, 1] -= 0.4 * u**2
    n = xyz.shape[0]
    kind, table = select_kind_auto(
        xyz,
        target,
        use_xy=all_true(n),
        use_z=all_true(n),
        expected_sigma_xy=sigma,
        expected_sigma_z=sigma,
    )
    assert kind == 2
    assert not table[0].passed and not table[1].passed
    assert table[1].rms_xyz[2] > 0.2  # type 1 leaves the bend (about 0.6 * 0.3 m RMS)
    assert table[2].rms_xyz[2] < 2 * sigma


def test_auto_marks_infeasible_kinds_and_falls_back_to_highest_feasible():
    # 6 points at 3 distinct X: type 2 has redundancy 1 < 2, type 3 (X³) is singular.
    xyz = control_grid(3, 2, seed=12)
    u = (xyz[:, 0] - 5000.0) / 5000.0
    target = xyz.copy()
    target[:, 2] -= 2.0 * u**2  # a bend far above the expected 1 cm
    n = xyz.shape[0]
    kind, table = select_kind_auto(
        xyz,
        target,
        use_xy=all_true(n),
        use_z=all_true(n),
        expected_sigma_xy=0.01,
        expected_sigma_z=0.01,
    )
    assert [row.feasible for row in table] == [True, True, False, False]
    assert "redundancy" in table[2].reason
    assert "singular" in table[3].reason or "stations along the strip" in table[3].reason
    assert kind == 1


def test_four_control_points_and_a_line_suffice_for_the_y_polynomial():
    # J section 3: "control points 1, 2, 3, 4 and the line points suffice for the Y polynomial".
    xyz, target, road = end_control_and_line()
    corners = [0, 2, 3, 5]
    with pytest.warns(StripAerotriWarning, match=r"X \(type 1\), Z \(type 1\) have .*"):
        res = fit_deformation(
            xyz[corners],
            target[corners],
            use_xy=all_true(4),
            use_z=all_true(4),
            kind=(1, 3, 1),
            lines=[road],
        )
    assert res.redundancy_xyz == (0, 4 + 11 - 6 - 2, 0)
    np.testing.assert_allclose(res.evaluate(road.xyz), bend_y(road.xyz), atol=1e-9)


def test_a_polynomial_without_redundancy_is_a_warning():
    """As many control observations as terms: the fit passes through the control and cannot
    show an error in it; the user is told which coordinates, and not for a fit with redundancy
    nor for the candidates of the automatic choice (judged by their redundancy there)."""
    # 5 points at 5 stations, alternately on the two sides: type 2 (5 terms) has none to spare
    rng = np.random.default_rng(4)
    xyz = np.column_stack(
        [
            np.linspace(0.0, LENGTH, 5),
            HALF_WIDTH * np.array([1, -1, 1, -1, 1]),
            rng.uniform(-30, 30, 5),
        ]
    )
    target = xyz - true_w(xyz)
    n = xyz.shape[0]
    with pytest.warns(
        StripAerotriWarning,
        match=r"X \(type 2\), Z \(type 2\) have .*no redundancy",
    ):
        res = fit_deformation(xyz, target, use_xy=all_true(n), use_z=all_true(n), kind=(2, 1, 2))
    assert res.redundancy_xyz == (0, 1, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StripAerotriWarning)
        more = control_grid(4, 2, seed=4)
        fit_deformation(
            more, more - true_w(more), use_xy=all_true(8), use_z=all_true(8), kind=(2, 1, 2)
        )
        select_kind_auto(
            xyz,
            target,
            use_xy=all_true(n),
            use_z=all_true(n),
            expected_sigma_xy=0.01,
            expected_sigma_z=0.01,
        )
