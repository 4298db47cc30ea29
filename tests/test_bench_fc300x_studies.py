"""Helpers of the FC300X studies in benchmarks/: the slopes of
bench_fc300x_height_slope.py, the virtual control cameras of
bench_fc300x_ceres.py and the mapped residuals of bench_fc300x_selfcal_bias.py."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import bench_fc300x_ceres as ceres_study  # noqa: E402
import bench_fc300x_height_slope as slope  # noqa: E402
import bench_fc300x_selfcal_bias as bias  # noqa: E402
import bench_reference_bundle as reference  # noqa: E402

from strip_aerotri.geometry.camera_model import CameraModel  # noqa: E402
from strip_aerotri.geometry.rotation import matrix_from_opk  # noqa: E402


def _terrain(rng: np.random.Generator, n: int) -> np.ndarray:
    """n ground points over 60 x 60 m with 5 m of relief (site X, Y, H)."""
    xy = rng.uniform(-30.0, 30.0, (n, 2))
    return np.column_stack([xy, 2180.0 + rng.normal(0.0, 5.0, n)])


def test_deming_recovers_the_slope_least_squares_attenuates() -> None:
    """x = t + e_x, y = 2 t + e_y with var(e_x) = var(t) / 2: least squares
    gives about 2 / 1.5; Deming with the true error ratio gives 2."""
    rng = np.random.default_rng(7)
    t = rng.normal(0.0, 1.0, 200_000)
    x = t + rng.normal(0.0, np.sqrt(0.5), t.size)
    y = 2.0 * t + rng.normal(0.0, 0.3, t.size)
    x, y = x - x.mean(), y - y.mean()
    assert abs(float(x @ y / (x @ x)) - 2.0 / 1.5) < 0.01
    assert abs(slope.deming(x, y, 0.3**2 / 0.5) - 2.0) < 0.01


def test_a_tilted_model_lowers_the_rule_slope_not_the_rotation_free_ratio() -> None:
    """A strip model that is the ground turned 44 deg about its y axis and
    scaled: the rule's fit (plan tilt terms, slope on z) gives cos 44 deg
    times the scale, the rotation-free ratio 1; heights in feet give it 3.28."""
    rng = np.random.default_rng(3)
    ground = _terrain(rng, 40)
    turn = matrix_from_opk(np.radians([[0.0, 44.0, 0.0]]))[0]
    model = 0.05 * (ground - ground.mean(axis=0)) @ turn  # rows: turnᵀ (X - mean)
    scaled = model / 0.05  # scaled to the ground's size, as the rule's plan scale would
    s = slope.ols_slope(scaled[:, :2], scaled[:, 2], ground[:, 2])
    assert abs(s - np.cos(np.radians(44.0))) < 0.01
    assert abs(slope.level_ratio(model, ground) - 1.0) < 1e-9
    feet = ground.copy()
    feet[:, 2] /= 0.3048
    assert abs(slope.level_ratio(model, feet) - 1.0 / 0.3048) < 1e-9


def test_partial_out_leaves_what_the_plan_does_not_explain() -> None:
    rng = np.random.default_rng(5)
    plan = rng.normal(0.0, 10.0, (50, 2))
    extra = rng.normal(0.0, 1.0, 50)
    column = 3.0 + plan @ np.array([0.2, -0.1]) + extra
    (left,) = slope.partial_out(plan, column)
    design = np.column_stack([np.ones(50), plan])
    np.testing.assert_allclose(design.T @ left, 0.0, atol=1e-9)


def test_virtual_views_observe_the_control_with_its_sigmas() -> None:
    """A point moved by d from its given position shows in the virtual
    cameras' pixels as dX / sigma_xy, dY / sigma_xy and dZ / sigma_h (the
    second camera's x residual ~ 0), to 1e-3 for centimetre moves."""
    given = np.array([607240.0, 3487050.0, 2185.0])
    sigma = np.array([0.02, 0.03])
    views = ceres_study._virtual_views(given, sigma)
    d = np.array([0.013, -0.021, 0.017])
    pixels = []
    for rot, centre, (fx, fy, cx, cy) in views:
        p = rot @ (given + d - centre)
        pixels.append([fx * p[0] / p[2], fy * p[1] / p[2]])
    expected = [[d[0] / sigma[0], d[1] / sigma[0]], [0.0, d[2] / sigma[1]]]
    np.testing.assert_allclose(pixels, expected, rtol=1e-3, atol=1e-6)
    for rot, _, _ in views:
        np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(rot) == pytest.approx(1.0)
    height_only = ceres_study._virtual_views(np.array([np.nan, np.nan, 2185.0]), sigma)
    assert len(height_only) == 1 and height_only[0][2][1] == pytest.approx(1000.0 / 0.03)


def _small_problem(camera: tuple[str, ...] = ()) -> reference.ReferenceBundle:
    """Two photos 40 m apart, 50 m above eight points, c = 3.6 mm."""
    rng = np.random.default_rng(11)
    points = _terrain(rng, 8)
    centres = np.array([[-20.0, 0.0, 2230.0], [20.0, 0.0, 2230.0]])
    rotations = matrix_from_opk(np.radians([[1.0, -2.0, 90.0], [-1.5, 1.0, 91.0]]))
    photo = np.repeat([0, 1], 8)
    point = np.tile(np.arange(8), 2)
    u = np.einsum("kji,kj->ki", rotations[photo], points[point] - centres[photo])
    xy = -3.6 * u[:, :2] / u[:, 2:3] + rng.normal(0.0, 0.002, (16, 2))
    return reference.ReferenceBundle(
        xy=xy, sigma=np.full(16, 0.0016), photo=photo, point=point, c=3.6,
        centres0=centres, rotations0=rotations, points0=points,
        control_point=np.arange(3), control_xyz=points[:3] + 0.01,
        control_sigma=np.full((3, 3), 0.02), camera=camera,
    )  # fmt: skip


def _mapped(mapped: bool, dc: float) -> bias.MappedBundle:
    base = _small_problem(("t0",))
    fields = {k: getattr(base, k) for k in (
        "xy", "sigma", "photo", "point", "c", "centres0", "rotations0", "points0",
        "control_point", "control_xyz", "control_sigma", "camera")}  # fmt: skip
    return bias.MappedBundle(
        **fields, model=CameraModel("brown", ("c",), 3.6), start=np.array([dc]), mapped=mapped
    )


def test_mapped_c_is_the_camera_constant_on_the_projections_side() -> None:
    """c as a correction of the observations, -(x/c) dc, with the residual
    mapped back by (I + dD/dx)^-1 = 1 / (1 - dc/c), is exactly a camera
    constant c / (1 - dc/c) in the projection (the reference's c term)."""
    dc = 0.02
    mapped = _mapped(True, dc).residuals(np.zeros(6 * 2 + 3 * 8 + 1))
    projection = _small_problem(("c",))
    v = np.zeros(projection.n_unknowns)
    v[-1] = 3.6 / (1.0 - dc / 3.6) - 3.6
    np.testing.assert_allclose(mapped, projection.residuals(v), rtol=1e-12, atol=1e-12)


def test_unmapped_residuals_shrink_as_c_grows() -> None:
    """Unmapped, the image residuals are the mapped ones times (1 - dc/c):
    a larger c lowers the sum of squares by itself (the pull on c)."""
    dc = 0.02
    n = 6 * 2 + 3 * 8 + 1
    plain = _mapped(False, dc).residuals(np.zeros(n))[:32]
    mapped = _mapped(True, dc).residuals(np.zeros(n))[:32]
    np.testing.assert_allclose(plain, (1.0 - dc / 3.6) * mapped, rtol=1e-12)


def test_observed_centres_enter_the_reference_with_their_sigmas() -> None:
    """Observed centres add one residual per given component, (centre -
    observed) / sigma, and the sparsity the solver is given covers every
    nonzero of the Jacobian."""
    from scipy.optimize._numdiff import approx_derivative

    bundle = _small_problem(("c", "k1"))
    n_plain = bundle.residuals(np.zeros(bundle.n_unknowns)).size
    observed = bundle.centres0 + np.array([[0.1, -0.2, 0.3], [np.nan, 0.05, -0.1]])
    bundle.centre_xyz, bundle.centre_sigma = observed, np.full((2, 3), 0.5)
    v = np.zeros(bundle.n_unknowns)
    r = bundle.residuals(v)
    assert r.size == n_plain + 5
    np.testing.assert_allclose(r[n_plain:], [-0.2, 0.4, -0.6, -0.1, 0.2], atol=1e-12)
    v[3 * 2 + 3 * 1 + 1] = 0.25  # the second photo's centre Y
    assert bundle.residuals(v)[n_plain + 3] == pytest.approx(0.4)
    dense = approx_derivative(bundle.residuals, v, "3-point")
    pattern = bundle._sparsity().toarray() != 0
    assert not np.any((np.abs(dense) > 1e-9) & ~pattern)
