"""Tests of the 3D similarity transformation (method.md section 6.1, J section 2.2)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from strip_aerotri.errors import ConvergenceError, GeometryError, StripAerotriWarning
from strip_aerotri.geometry.similarity import (
    COLLINEAR_MAGNIFICATION,
    COLLINEAR_RTOL,
    SimilarityTransform,
    cross_tilt,
    fit_similarity,
    similarity_from_points,
)

# A synthetic strip model in strip units (first base = 1, J's default): 10 bases
# long, about 3 bases wide, small relief.  The "truth" takes it to a UTM-like
# grid with scale 1000 (strip unit 1 -> 1000 m on the ground), heading 200 deg
# (a strip flown south-south-west) and tilts of about 1-2 deg.
TRUE_ROTATION = Rotation.from_euler("ZYX", [200.0, 1.5, -2.0], degrees=True).as_matrix()
TRUTH = SimilarityTransform(1000.0, TRUE_ROTATION, np.array([512_345.0, 4_612_345.0, 310.0]))
# Same geometry, near the origin, so that "exact" can be checked to 1e-10 m absolute.
TRUTH_LOCAL = SimilarityTransform(1000.0, TRUE_ROTATION, np.array([1234.0, -2345.0, 310.0]))


def make_model(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.column_stack(
        [rng.uniform(0.0, 10.0, n), rng.uniform(-1.5, 1.5, n), rng.uniform(-0.08, 0.08, n)]
    )


def masked(target: np.ndarray, use_xy: np.ndarray, use_z: np.ndarray) -> np.ndarray:
    out = target.copy()
    out[~use_xy, :2] = np.nan
    out[~use_z, 2] = np.nan
    return out


def rotation_error(rotation: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Small rotation vector phi with rotation = expm([phi]x) truth (radians)."""
    return Rotation.from_matrix(rotation @ truth.T).as_rotvec()


# --------------------------------------------------------------------------- transform


def test_transform_apply_inverse_compose_identity():
    rng = np.random.default_rng(2345)
    pts = rng.normal(size=(5, 3))
    other = SimilarityTransform(
        0.5, Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix(), np.array([1.0, 2.0, 3.0])
    )
    np.testing.assert_allclose(TRUTH_LOCAL.inverse().apply(TRUTH_LOCAL.apply(pts)), pts, atol=1e-9)
    composed = TRUTH_LOCAL.compose(other)
    np.testing.assert_allclose(
        composed.apply(pts), TRUTH_LOCAL.apply(other.apply(pts)), rtol=0, atol=1e-9
    )
    np.testing.assert_allclose(SimilarityTransform.identity().apply(pts), pts, atol=0)
    ident = TRUTH_LOCAL.compose(TRUTH_LOCAL.inverse())
    np.testing.assert_allclose(ident.rotation, np.eye(3), atol=1e-14)
    assert ident.scale == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(ident.translation, 0.0, atol=1e-9)
    attitudes = Rotation.random(4, random_state=7).as_matrix()
    np.testing.assert_allclose(
        TRUTH_LOCAL.apply_to_rotation(attitudes), TRUE_ROTATION @ attitudes, atol=1e-15
    )
    # A single vector is accepted as well.
    np.testing.assert_allclose(TRUTH_LOCAL.apply(pts[0]), TRUTH_LOCAL.apply(pts[:1])[0])


def test_transform_rejects_bad_parameters():
    with pytest.raises(ValueError, match="scale"):
        SimilarityTransform(0.0, np.eye(3), np.zeros(3))
    with pytest.raises(ValueError, match="proper rotation"):
        SimilarityTransform(1.0, np.diag([1.0, 1.0, -1.0]), np.zeros(3))
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        TRUTH.apply(np.zeros((4, 2)))


# --------------------------------------------------------------------------- closed form


def test_similarity_from_points_exact_and_weighted():
    src = make_model(8, seed=1)
    tgt = TRUTH_LOCAL.apply(src)
    est = similarity_from_points(src, tgt)
    assert est.scale == pytest.approx(1000.0, rel=1e-12)
    np.testing.assert_allclose(est.rotation, TRUE_ROTATION, atol=1e-12)
    np.testing.assert_allclose(est.apply(src), tgt, atol=1e-9)
    # A gross error on a point with weight 0 has no influence.
    bad = tgt.copy()
    bad[3] += 50.0
    weights = np.ones(8)
    weights[3] = 0.0
    est_w = similarity_from_points(src, bad, weights)
    np.testing.assert_allclose(est_w.apply(src), tgt, atol=1e-9)


def test_similarity_from_points_never_returns_a_reflection():
    src = make_model(6, seed=2)
    mirrored = src * np.array([1.0, -1.0, 1.0])  # a reflection of the model
    est = similarity_from_points(src, mirrored)
    assert np.linalg.det(est.rotation) == pytest.approx(1.0, abs=1e-12)


def test_similarity_from_points_collinear_raises():
    src = np.column_stack([np.arange(4.0), 2.0 * np.arange(4.0), np.zeros(4)])
    with pytest.raises(GeometryError, match="collinear"):
        similarity_from_points(src, src)
    with pytest.raises(GeometryError, match="at least three"):
        similarity_from_points(src[:2], src[:2])


# --------------------------------------------------------------------------- least squares


def test_noise_free_full_control_is_exact():
    src = make_model(10, seed=3)
    tgt = TRUTH_LOCAL.apply(src)
    ones = np.ones(10, dtype=bool)
    res = fit_similarity(src, tgt, use_xy=ones, use_z=ones)
    assert res.transform.scale == pytest.approx(1000.0, rel=1e-12)
    np.testing.assert_allclose(res.transform.rotation, TRUE_ROTATION, atol=1e-12)
    np.testing.assert_allclose(res.transform.apply(src), tgt, rtol=0, atol=1e-10)
    assert np.nanmax(np.abs(res.residuals)) < 1e-10
    assert res.redundancy == 30 - 7


def test_noise_free_on_grid_coordinates():
    # Large grid coordinates (northing 4.6e6 m): conditioning by centring.
    src = make_model(10, seed=3)
    tgt = TRUTH.apply(src)
    ones = np.ones(10, dtype=bool)
    res = fit_similarity(src, tgt, use_xy=ones, use_z=ones)
    assert res.transform.scale == pytest.approx(1000.0, rel=1e-12)
    np.testing.assert_allclose(res.transform.rotation, TRUE_ROTATION, atol=1e-12)
    # 1e-8 m is a few ulps of 4.6e6.
    np.testing.assert_allclose(res.transform.translation, TRUTH.translation, rtol=0, atol=1e-8)


def test_minimum_configuration_two_full_one_height_solves_exactly():
    # J section 2.2: two full points and the height of a third, not in one vertical plane.
    src = np.array([[0.0, 1.0, 0.02], [10.0, -1.0, -0.03], [5.0, 1.4, 0.05], [3.0, 0.0, 0.0]])
    tgt = TRUTH.apply(src)
    use_xy = np.array([True, True, False, False])
    use_z = np.array([True, True, True, False])
    res = fit_similarity(src, masked(tgt, use_xy, use_z), use_xy=use_xy, use_z=use_z)
    assert res.redundancy == 0
    assert np.isnan(res.sigma0)
    assert res.transform.scale == pytest.approx(1000.0, rel=1e-11)
    assert np.max(np.abs(rotation_error(res.transform.rotation, TRUE_ROTATION))) < 1e-11
    # The unused fourth point is predicted exactly.
    np.testing.assert_allclose(res.transform.apply(src[3:]), tgt[3:], rtol=0, atol=1e-7)
    np.testing.assert_allclose(np.nansum(res.redundancy_numbers), 0.0, atol=1e-9)
    assert np.all(np.isnan(res.residuals[3]))
    assert np.all(np.isnan(res.residuals[2, :2]))


def test_plan_only_and_height_only_points():
    # No full point at all: two plan points and three height points (7 observations).
    src = make_model(5, seed=4)
    tgt = TRUTH_LOCAL.apply(src)
    use_xy = np.array([True, True, False, False, False])
    use_z = ~use_xy
    res = fit_similarity(src, masked(tgt, use_xy, use_z), use_xy=use_xy, use_z=use_z)
    assert res.redundancy == 0
    np.testing.assert_allclose(res.transform.apply(src), tgt, rtol=0, atol=1e-8)
    # A mix with redundancy: 1 full, 4 plan, 5 height.
    src = make_model(10, seed=5)
    tgt = TRUTH_LOCAL.apply(src)
    use_xy = np.array([True] * 5 + [False] * 5)
    use_z = np.array([True] + [False] * 4 + [True] * 5)
    res = fit_similarity(src, masked(tgt, use_xy, use_z), use_xy=use_xy, use_z=use_z)
    assert res.redundancy == 5 * 2 + 6 - 7
    np.testing.assert_allclose(res.transform.apply(src), tgt, rtol=0, atol=1e-9)


@pytest.mark.parametrize("heading_deg", [179.999, 180.0, 200.0, -170.0, 359.0], ids=str)
def test_any_heading_converges_from_the_minimum_configuration(heading_deg):
    rotation = Rotation.from_euler("ZYX", [heading_deg, -1.0, 2.5], degrees=True).as_matrix()
    truth = SimilarityTransform(1000.0, rotation, np.array([400_000.0, 5_500_000.0, 900.0]))
    src = np.array([[0.0, 1.0, 0.02], [10.0, -1.0, -0.03], [5.0, 1.4, 0.05]])
    tgt = truth.apply(src)
    use_xy = np.array([True, True, False])
    use_z = np.ones(3, dtype=bool)
    res = fit_similarity(src, masked(tgt, use_xy, use_z), use_xy=use_xy, use_z=use_z)
    assert res.iterations < 10
    assert np.max(np.abs(rotation_error(res.transform.rotation, rotation))) < 1e-10
    assert res.transform.scale == pytest.approx(1000.0, rel=1e-10)


def test_recovery_with_noise_within_sigma_and_sigma0_near_one():
    sigma_xy, sigma_z = 0.05, 0.08
    src = make_model(12, seed=6)
    rng = np.random.default_rng(2345)
    tgt = TRUTH.apply(src)
    noisy = tgt + rng.normal(size=tgt.shape) * np.array([sigma_xy, sigma_xy, sigma_z])
    ones = np.ones(12, dtype=bool)
    res = fit_similarity(src, noisy, use_xy=ones, use_z=ones, sigma_xy=sigma_xy, sigma_z=sigma_z)
    sd = np.sqrt(np.diag(res.covariance))
    assert abs(res.transform.scale - 1000.0) < 4.0 * sd[3]
    assert np.all(np.abs(rotation_error(res.transform.rotation, TRUE_ROTATION)) < 4.0 * sd[4:])
    assert np.all(np.abs(res.transform.translation - TRUTH.translation) < 4.0 * sd[:3])
    # r = 36 - 7 = 29: sigma0² ~ chi²(29)/29, 99.9 % interval about [0.44, 1.9].
    assert 0.66 < res.sigma0 < 1.38
    np.testing.assert_allclose(np.nansum(res.redundancy_numbers), res.redundancy, atol=1e-9)


def test_sigma0_and_covariance_are_calibrated_by_monte_carlo():
    # 300 repetitions: the mean of sigma0² must be 1 (standard error sqrt(2/29/300) = 0.015)
    # and the spread of the scale must match the a priori cofactor (standard error of the
    # variance ratio sqrt(2/299) = 0.08).
    sigma = 0.05
    src = make_model(12, seed=7)
    tgt = TRUTH_LOCAL.apply(src)
    ones = np.ones(12, dtype=bool)
    rng = np.random.default_rng(99)
    s02, scales = [], []
    cofactor = None
    for _ in range(300):
        res = fit_similarity(
            src,
            tgt + rng.normal(scale=sigma, size=tgt.shape),
            use_xy=ones,
            use_z=ones,
            sigma_xy=sigma,
            sigma_z=sigma,
        )
        s02.append(res.sigma0**2)
        scales.append(res.transform.scale)
        cofactor = res.covariance[3, 3] / res.sigma0**2
    assert abs(np.mean(s02) - 1.0) < 0.06
    ratio = np.var(scales, ddof=1) / cofactor
    assert 0.7 < ratio < 1.3


def test_blunder_has_the_largest_normalized_residual():
    sigma = 0.05
    src = make_model(12, seed=8)
    rng = np.random.default_rng(11)
    tgt = TRUTH_LOCAL.apply(src) + rng.normal(scale=sigma, size=(12, 3))
    tgt[4, 2] += 1.0  # 20 sigma in height
    ones = np.ones(12, dtype=bool)
    res = fit_similarity(src, tgt, use_xy=ones, use_z=ones, sigma_xy=sigma, sigma_z=sigma)
    w = np.abs(res.normalized_residuals)
    assert np.unravel_index(np.nanargmax(w), w.shape) == (4, 2)
    assert w[4, 2] > 10.0


def test_redundancy_numbers_sum_to_redundancy_with_mixed_weights():
    src = make_model(9, seed=9)
    tgt = TRUTH_LOCAL.apply(src)
    use_xy = np.array([True, True, True, False, False, True, True, False, True])
    use_z = np.array([True, False, True, True, True, False, True, True, False])
    sig_xy = np.linspace(0.02, 0.1, 9)
    res = fit_similarity(
        src, masked(tgt, use_xy, use_z), use_xy=use_xy, use_z=use_z, sigma_xy=sig_xy, sigma_z=0.1
    )
    assert res.redundancy == 2 * 6 + 6 - 7
    assert np.nansum(res.redundancy_numbers) == pytest.approx(res.redundancy, abs=1e-9)
    assert np.all(np.isnan(res.redundancy_numbers[~use_xy, :2]))
    assert np.all(np.isnan(res.redundancy_numbers[~use_z, 2]))
    r = res.redundancy_numbers[np.isfinite(res.redundancy_numbers)]
    assert np.all((r >= 0.0) & (r <= 1.0))


def test_inputs_are_not_modified():
    src = make_model(6, seed=10)
    tgt = TRUTH_LOCAL.apply(src)
    use_xy = np.array([True, True, True, False, True, True])
    use_z = np.array([True, False, True, True, True, True])
    tgt = masked(tgt, use_xy, use_z)
    copies = [a.copy() for a in (src, tgt, use_xy, use_z)]
    fit_similarity(src, tgt, use_xy=use_xy, use_z=use_z)
    for a, b in zip((src, tgt, use_xy, use_z), copies, strict=True):
        np.testing.assert_array_equal(a, b)


# --------------------------------------------------------------------------- degeneracies


IDS = ("P1", "P2", "P3", "P4", "P5", "P6", "P7")


def _degenerate(use_xy, use_z, src=None, tgt=None):
    src = make_model(7, seed=12) if src is None else src
    tgt = TRUTH_LOCAL.apply(src) if tgt is None else tgt
    use_xy = np.array(use_xy, dtype=bool)
    use_z = np.array(use_z, dtype=bool)
    return fit_similarity(
        src, masked(tgt, use_xy, use_z), use_xy=use_xy, use_z=use_z, point_ids=IDS
    )


def test_one_plan_point_raises_naming_it():
    with pytest.raises(
        GeometryError, match=r"needs at least two full or plan control points, got 1: 'P7'"
    ):
        _degenerate([0, 0, 0, 0, 0, 0, 1], [1, 1, 1, 1, 0, 0, 1])


def test_two_height_points_raise_naming_them():
    with pytest.raises(
        GeometryError, match=r"at least three full or height control points, got 2: 'P1', 'P2'"
    ):
        _degenerate([1, 1, 1, 1, 0, 0, 0], [1, 1, 0, 0, 0, 0, 0])


def test_coincident_plan_points_raise():
    src = make_model(7, seed=12)
    src[1, :2] = src[0, :2]  # same plan position in the model
    with pytest.raises(GeometryError, match=r"plan control points coincide .*'P1', 'P2'"):
        _degenerate([1, 1, 0, 0, 0, 0, 0], [1, 1, 1, 1, 0, 0, 0], src=src)


def test_height_points_in_one_vertical_plane_raise():
    # J: "none of the points lies in the vertical plane through the two others".
    src = np.array(
        [
            [0.0, 0.0, 0.01],
            [10.0, 1.0, -0.02],
            [5.0, 0.5, 0.05],  # on the plan line through P1 and P2
            [2.0, 1.0, 0.0],
            [3.0, -1.0, 0.0],
            [4.0, 1.0, 0.0],
            [6.0, -1.0, 0.0],
        ]
    )
    with pytest.raises(GeometryError, match=r"one vertical plane .*: 'P1', 'P2', 'P3'$"):
        _degenerate([1, 1, 0, 0, 0, 0, 0], [1, 1, 1, 0, 0, 0, 0], src=src)
    # Moving the third point off the plane makes the same configuration solvable.
    src[2, 1] = 1.5
    res = _degenerate([1, 1, 0, 0, 0, 0, 0], [1, 1, 1, 0, 0, 0, 0], src=src)
    assert res.redundancy == 0


def test_height_points_nearly_in_one_vertical_plane_warn():
    # Third height point 30 m (in ground units) off the 10 km line: singular value ratio ~3e-3.
    src = np.array([[0.0, 0.0, 0.01], [10.0, 1.0, -0.02], [5.0, 0.53, 0.05]])
    tgt = TRUTH_LOCAL.apply(src)
    use_xy = np.array([True, True, False])
    use_z = np.ones(3, dtype=bool)
    with pytest.warns(StripAerotriWarning, match=r"nearly in one vertical plane"):
        res = fit_similarity(
            src, masked(tgt, use_xy, use_z), use_xy=use_xy, use_z=use_z, point_ids=IDS[:3]
        )
    np.testing.assert_allclose(res.transform.apply(src), tgt, rtol=0, atol=1e-8)


def test_non_finite_used_coordinates_raise_naming_the_point():
    src = make_model(7, seed=12)
    tgt = TRUTH_LOCAL.apply(src)
    tgt[2, 0] = np.nan  # P3 is used as plan control
    use_xy = np.array([1, 1, 1, 0, 0, 0, 0], dtype=bool)
    use_z = np.array([1, 1, 1, 1, 0, 0, 0], dtype=bool)
    with pytest.raises(GeometryError, match=r"non-finite target X or Y: 'P3'"):
        fit_similarity(src, tgt, use_xy=use_xy, use_z=use_z, point_ids=IDS)
    src[5, 2] = np.inf  # P6 is not used: no error from it
    tgt[2, 0] = 0.0
    fit_similarity(src, tgt, use_xy=use_xy, use_z=use_z, point_ids=IDS)
    src[3, 2] = np.nan  # P4 is used as height control
    with pytest.raises(GeometryError, match=r"non-finite model coordinates: 'P4'"):
        fit_similarity(src, tgt, use_xy=use_xy, use_z=use_z, point_ids=IDS)


def test_bad_arguments_raise_value_error():
    src = make_model(4, seed=1)
    ones = np.ones(4, dtype=bool)
    with pytest.raises(ValueError, match="use_xy"):
        fit_similarity(src, src, use_xy=np.ones(3, dtype=bool), use_z=ones)
    with pytest.raises(ValueError, match="sigma_z"):
        fit_similarity(src, src, use_xy=ones, use_z=ones, sigma_z=-1.0)
    with pytest.raises(ValueError, match=r"`target` to have shape \(4, 3\)"):
        fit_similarity(src, src[:3], use_xy=ones, use_z=ones)


# --------------------------------------------------------------------------- start values


def test_start_values_change_the_iterations_not_the_solution():
    # Plan and height control only (no closed form): the constructive start needs
    # several Gauss-Newton steps; a start near the solution (a neighbouring
    # problem's, as the ground stage's passes give it) needs fewer, and the
    # solution is the same to the convergence tolerance.
    sigma = 0.05
    src = make_model(12, seed=8)
    rng = np.random.default_rng(77)
    tgt = TRUTH.apply(src) + rng.normal(size=(12, 3)) * sigma
    use_xy = np.array([1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0], dtype=bool)
    use_z = ~use_xy | (np.arange(12) < 2)
    kwargs = {"use_xy": use_xy, "use_z": use_z, "sigma_xy": sigma, "sigma_z": sigma}
    cold = fit_similarity(src, masked(tgt, use_xy, use_z), **kwargs)
    nudge = SimilarityTransform(
        1.0 + 2e-8,
        Rotation.from_rotvec([2e-8, -1e-8, 3e-8]).as_matrix(),
        np.array([3e-5, -2e-5, 1e-5]),
    )
    warm = fit_similarity(
        src, masked(tgt, use_xy, use_z), **kwargs, start=nudge.compose(cold.transform)
    )
    exact = fit_similarity(src, masked(tgt, use_xy, use_z), **kwargs, start=cold.transform)
    assert exact.iterations == 1
    assert warm.iterations < cold.iterations
    for res in (warm, exact):
        assert res.transform.scale == pytest.approx(cold.transform.scale, rel=1e-11)
        assert (
            np.max(np.abs(rotation_error(res.transform.rotation, cold.transform.rotation))) < 1e-11
        )
        np.testing.assert_allclose(
            res.transform.translation, cold.transform.translation, atol=1e-6
        )
        np.testing.assert_allclose(res.residuals, cold.residuals, atol=1e-6)
        np.testing.assert_allclose(res.covariance, cold.covariance, rtol=1e-8, atol=1e-14)


def test_start_must_be_a_similarity_transform():
    src = make_model(6, seed=9)
    ones = np.ones(6, dtype=bool)
    with pytest.raises(TypeError, match="start"):
        fit_similarity(src, TRUTH.apply(src), use_xy=ones, use_z=ones, start=np.eye(3))


@pytest.mark.parametrize("k", [5, 16, 17, 60])
def test_normal_inverse_and_condition_number_small_exact_large_bounded(k):
    """Up to 16 unknowns the condition number of the equilibrated normal matrix is exact;
    beyond, the bound ‖N‖∞‖N⁻¹‖∞ lies between the exact value and k times it.  The inverse
    is the inverse either way, and a rank-deficient design is singular either way."""
    from strip_aerotri.geometry.similarity import _EXACT_COND_MAX, _normal_inverse

    rng = np.random.default_rng(k)
    a = rng.normal(size=(3 * k, k)) * np.logspace(0, 3, k)  # columns of very different size
    inverse, cond = _normal_inverse(a)
    normal = a.T @ a
    np.testing.assert_allclose(inverse @ normal, np.eye(k), rtol=0, atol=1e-9)
    d = 1.0 / np.sqrt(np.diag(normal))
    eig = np.linalg.eigvalsh(normal * d[:, None] * d[None, :])
    exact = eig[-1] / eig[0]
    if k <= _EXACT_COND_MAX:
        assert cond == pytest.approx(exact, rel=1e-9)
    else:
        assert exact * (1 - 1e-9) <= cond <= k * exact
    deficient = a.copy()
    deficient[:, -1] = deficient[:, 0] - 2.0 * deficient[:, 1]
    _, cond_deficient = _normal_inverse(deficient)
    assert not cond_deficient <= 1e12


@pytest.mark.parametrize("shape", [(3,), (7, 3), (2, 4, 3), (5, 2)])
def test_add_to_columns_is_the_broadcast_sum_in_place(shape):
    from strip_aerotri._rows import add_to_columns

    rng = np.random.default_rng(len(shape))
    rows = rng.normal(size=shape)
    offset = rng.normal(size=shape[-1])
    expected = rows + offset
    out = add_to_columns(rows, offset)
    assert out is rows
    np.testing.assert_array_equal(out, expected)


def _bent_long_strip(bend: float):
    """A 1000-base strip model bent (quadratically in Y and Z) far beyond a
    similarity, as a chain of 1000 models bends; plan points on the even
    rows, height points on the odd ones (no closed-form start)."""
    rng = np.random.default_rng(3)
    n = 400
    x = np.sort(rng.uniform(0.0, 1000.0, n))
    src = np.column_stack([x, rng.choice([-1.5, 1.5], n), rng.uniform(-0.08, 0.08, n)])
    bent = src.copy()
    bent[:, 1] += bend * (x - 500.0) ** 2
    bent[:, 2] += 0.5 * bend * (x - 500.0) ** 2
    use_xy = np.arange(n) % 2 == 0
    use_z = ~use_xy | (np.arange(n) < 3)
    tgt = masked(TRUTH_LOCAL.apply(src) + rng.normal(size=src.shape) * 0.05, use_xy, use_z)
    return bent, tgt, {"use_xy": use_xy, "use_z": use_z, "sigma_xy": 0.05, "sigma_z": 0.05}


@pytest.mark.filterwarnings("ignore:height control points lie nearly")
def test_a_linearly_converging_fit_stops_when_its_steps_are_negligible(monkeypatch):
    """Gauss-Newton converges only linearly on a model bent far beyond a
    similarity; it stops once a step is below 1 % of its standard deviation
    instead of running on to the tolerance (3 iterations instead of 9 here),
    and the two solutions agree within that fraction."""
    from strip_aerotri.geometry import similarity as similarity_module

    bent, tgt, kwargs = _bent_long_strip(5e-6)
    stopped = fit_similarity(bent, tgt, **kwargs)
    monkeypatch.setattr(similarity_module, "_NEGLIGIBLE_FRACTION", 0.0)
    full = fit_similarity(bent, tgt, **kwargs)
    assert stopped.iterations <= full.iterations - 4, (stopped.iterations, full.iterations)
    sd = np.sqrt(np.diag(full.covariance))  # tx, ty, tz, scale, phi_x, phi_y, phi_z
    rot = rotation_error(stopped.transform.rotation, full.transform.rotation)
    assert np.all(np.abs(rot) < 0.01 * sd[4:7]), (rot, sd[4:7])
    assert abs(stopped.transform.scale - full.transform.scale) < 0.01 * sd[3]


@pytest.mark.filterwarnings("ignore:height control points lie nearly")
def test_a_fit_too_slow_for_the_tolerance_still_converges(monkeypatch):
    """Bent four times as much, the linear convergence is too slow to reach
    the tolerance in 30 iterations (the rule before, a ConvergenceError); it
    reaches negligible steps in 11."""
    from strip_aerotri.geometry import similarity as similarity_module

    bent, tgt, kwargs = _bent_long_strip(2e-5)
    assert fit_similarity(bent, tgt, **kwargs).iterations <= 12
    monkeypatch.setattr(similarity_module, "_NEGLIGIBLE_FRACTION", 0.0)
    with pytest.raises(ConvergenceError, match="did not converge in 30 iterations"):
        fit_similarity(bent, tgt, **kwargs, max_iterations=30)


def _long_strip_with_edges(n_stations: int = 200, across: float = 1.5):
    """Full control on both edges of a strip 2000 bases long and 3 wide
    (plan singular value ratio 2.6e-3), and the strip's points across its
    whole width."""
    x = np.repeat(np.linspace(0.0, 2000.0, n_stations), 2)
    src = np.column_stack([x, np.tile([-across, across], n_stations), np.zeros_like(x)])
    served = np.column_stack(
        [np.linspace(0.0, 2000.0, 999), np.tile([-1.6, 0.0, 1.6], 333), np.zeros(999)]
    )
    return src, TRUTH_LOCAL.apply(src), served


@pytest.mark.parametrize("stretch", [1.0, 5.0])
def test_a_long_strip_controlled_on_both_edges_is_judged_by_the_points_served(stretch):
    """Judged by the points it serves, the height control on both edges of a
    strip 2000 or 10 000 times longer than wide determines the tilt across it
    well (a height error reaches the strip's edge 0.05 times magnified): no
    warning.  The ratio of the plan singular values alone, 2.6e-3 and 5e-4,
    warns about the first and refuses the second (below COLLINEAR_RTOL)."""
    import warnings as _warnings

    src, _, served = _long_strip_with_edges()
    src[:, 0] *= stretch
    served[:, 0] *= stretch
    tgt = TRUTH_LOCAL.apply(src)
    ratio, magnified = cross_tilt(src[:, :2], served[:, :2])
    assert magnified < 0.1
    use = np.ones(len(src), dtype=bool)
    with _warnings.catch_warnings():
        _warnings.simplefilter("error")
        res = fit_similarity(src, tgt, use_xy=use, use_z=use, served=served)
    np.testing.assert_allclose(res.transform.apply(src), tgt, rtol=0, atol=1e-7)
    if ratio < COLLINEAR_RTOL:
        with pytest.raises(GeometryError, match=r"all lie in one vertical plane \(.* ratio 5"):
            fit_similarity(src, tgt, use_xy=use, use_z=use)
    else:
        with pytest.warns(StripAerotriWarning, match=r"nearly in one vertical plane \(singular"):
            fit_similarity(src, tgt, use_xy=use, use_z=use)


def _road_control(offset: float):
    """Height points along a road 20 long, every second one `offset` off it,
    under a strip 3.2 wide: s1 about sqrt(40) offset / 2, the farthest served
    point about 1.6 from their plane."""
    x = np.linspace(0.0, 20.0, 40)
    src = np.column_stack([x, np.where(np.arange(40) % 2, offset, 0.0), np.zeros(40)])
    served = np.column_stack([x, np.tile([-1.6, 1.6], 20), np.zeros(40)])
    return src, TRUTH_LOCAL.apply(src), np.ones(40, dtype=bool), served


# Offsets 0.02 and 0.2: magnified 25 and 2.7 times (plan singular value
# ratios 1.7e-3 and 1.7e-2: the ratio rule would warn about the first only).
@pytest.mark.parametrize("offset, warns", [(0.02, True), (0.2, False)])
def test_the_weak_tilt_warning_judged_by_the_points_served(offset, warns):
    import warnings as _warnings

    src, tgt, use, served = _road_control(offset)
    if warns:
        with pytest.warns(StripAerotriWarning, match=r"nearly in one vertical plane .* 25 times"):
            fit_similarity(src, tgt, use_xy=use, use_z=use, served=served)
    else:
        with _warnings.catch_warnings():
            _warnings.simplefilter("error")
            fit_similarity(src, tgt, use_xy=use, use_z=use, served=served)
    # collinear height control is refused by the ratio either way
    flat = src.copy()
    flat[:, 1] = 0.0
    with pytest.raises(GeometryError, match=r"all lie in one vertical plane"):
        fit_similarity(flat, TRUTH_LOCAL.apply(flat), use_xy=use, use_z=use, served=served)


@pytest.mark.parametrize("offset, refused", [(0.002, True), (0.02, False)])
def test_height_control_nearly_on_one_road_is_refused_by_its_magnification(offset, refused):
    """The road of :func:`_road_control` with offsets 0.002 and 0.02: ratios
    1.7e-4 and 1.7e-3, magnified about 250 and 25 times at the edge.  Above
    COLLINEAR_MAGNIFICATION (100) and below COLLINEAR_RTOL the tilt is
    refused; 25 times is only warned about."""
    src, tgt, use, served = _road_control(offset)
    ratio, magnified = cross_tilt(src[:, :2], served[:, :2])
    assert (ratio < COLLINEAR_RTOL, magnified > COLLINEAR_MAGNIFICATION) == (refused, refused)
    if refused:
        with pytest.raises(GeometryError, match=r"reaches the farthest point 2\d\d times"):
            fit_similarity(src, tgt, use_xy=use, use_z=use, served=served)
    else:
        with pytest.warns(StripAerotriWarning, match=r"nearly in one vertical plane .* 25 times"):
            fit_similarity(src, tgt, use_xy=use, use_z=use, served=served)


def test_cross_tilt_magnification_by_hand():
    # Height points at (0, 0), (10, 0), (10, 2), (0, 2): best plane y = 1, s1 = 2
    # (4 points 1 off it); the served point (5, 7) is 6 off the plane: 3 times.
    h = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 2.0], [0.0, 2.0]])
    ratio, magnified = cross_tilt(h, np.array([[5.0, 7.0], [5.0, 1.0]]))
    assert ratio == pytest.approx(2.0 / 10.0)
    assert magnified == pytest.approx(3.0)
    assert cross_tilt(h, np.array([[5.0, 7.0]]), margin=2.0)[1] == pytest.approx(4.0)
    assert cross_tilt(h)[1] is None
    assert cross_tilt(h[:2], h[:1])[1] == np.inf
