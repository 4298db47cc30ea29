"""Tests of strip_aerotri.geometry.rotation: parametrisations, round trips, singularities.

Independent oracle: ``scipy.spatial.transform.Rotation``.
"""

from __future__ import annotations

import doctest
import re
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from strip_aerotri.errors import GeometryError, StripAerotriWarning
from strip_aerotri.geometry import rotation
from strip_aerotri.geometry.rotation import (
    SCHUT_MAX_ANGLE_DEG,
    cardan_from_matrix,
    cardan_from_opk,
    cardan_from_schut,
    check_matrix,
    matrix_from_cardan,
    matrix_from_opk,
    matrix_from_rotvec,
    matrix_from_schut,
    opk_from_cardan,
    opk_from_matrix,
    opk_from_schut,
    rotvec_from_matrix,
    schut_from_cardan,
    schut_from_matrix,
    schut_from_opk,
    skew,
)

N = 1000
ROUND = 1e-13  # round-trip tolerance on matrix elements / radians (rounding level)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(2345)


@pytest.fixture
def matrices() -> np.ndarray:
    """1000 uniformly distributed random rotations (seeded)."""
    return Rotation.random(N, random_state=2345).as_matrix()


def random_cardan(rng: np.random.Generator, n: int = N) -> np.ndarray:
    """(alpha, omega, chi) in the ranges cardan_from_matrix returns."""
    return np.column_stack(
        [
            rng.uniform(-np.pi, np.pi, n),
            rng.uniform(-np.pi / 2, np.pi / 2, n),
            rng.uniform(-np.pi, np.pi, n),
        ]
    )


def random_axes(rng: np.random.Generator, n: int = N) -> np.ndarray:
    axes = rng.normal(size=(n, 3))
    return axes / np.linalg.norm(axes, axis=1, keepdims=True)


def assert_rotation(m: np.ndarray) -> None:
    """Orthonormal with det +1, to rounding level."""
    eye = np.broadcast_to(np.eye(3), m.shape)
    np.testing.assert_allclose(np.swapaxes(m, -1, -2) @ m, eye, rtol=0, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(m), 1.0, rtol=0, atol=1e-14)


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angle difference reduced to (-pi, pi]."""
    return np.angle(np.exp(1j * angle))


# ---------------------------------------------------------------------------
# skew


def test_skew_is_cross_product(rng):
    a, b = rng.normal(size=(2, N, 3))
    np.testing.assert_allclose(
        np.einsum("nij,nj->ni", skew(a), b), np.cross(a, b), rtol=0, atol=1e-14
    )
    np.testing.assert_array_equal(skew(a), -np.swapaxes(skew(a), -1, -2))


# ---------------------------------------------------------------------------
# forward formulas against scipy


def test_matrix_from_cardan_equals_scipy_yxz(rng):
    # B(133) = Ry(-alpha) Rx(omega) Rz(chi), method.md 2.1
    ang = rng.uniform(-np.pi, np.pi, (N, 3))
    expected = Rotation.from_euler("YXZ", ang * [-1, 1, 1]).as_matrix()
    np.testing.assert_allclose(matrix_from_cardan(ang), expected, rtol=0, atol=1e-15)


def test_matrix_from_cardan_elements_b133():
    # element formulas of B(133), written out independently
    alpha, omega, chi = 0.3, -0.2, 1.1
    sa, ca, sw, cw, sc, cc = (
        np.sin(alpha),
        np.cos(alpha),
        np.sin(omega),
        np.cos(omega),
        np.sin(chi),
        np.cos(chi),
    )
    a = matrix_from_cardan([alpha, omega, chi])
    assert a[0, 0] == pytest.approx(ca * cc - sa * sw * sc, abs=1e-16)
    assert a[0, 1] == pytest.approx(-ca * sc - sa * sw * cc, abs=1e-16)
    assert a[0, 2] == pytest.approx(-sa * cw, abs=1e-16)
    assert a[1, 0] == pytest.approx(cw * sc, abs=1e-16)
    assert a[1, 1] == pytest.approx(cw * cc, abs=1e-16)
    assert a[1, 2] == pytest.approx(-sw, abs=1e-16)
    assert a[2, 0] == pytest.approx(sa * cc + ca * sw * sc, abs=1e-16)
    assert a[2, 1] == pytest.approx(-sa * sc + ca * sw * cc, abs=1e-16)
    assert a[2, 2] == pytest.approx(ca * cw, abs=1e-16)


def test_matrix_from_opk_equals_scipy_xyz(rng):
    opk = rng.uniform(-np.pi, np.pi, (N, 3))
    expected = Rotation.from_euler("XYZ", opk).as_matrix()
    np.testing.assert_allclose(matrix_from_opk(opk), expected, rtol=0, atol=1e-15)


def test_matrix_from_opk_is_transposed_wolf_m():
    # Wolf, Dewitt & Wilkinson: M = M_kappa M_phi M_omega maps object -> image,
    # with M_omega = [[1, 0, 0], [0, cos w, sin w], [0, -sin w, cos w]] etc.
    w, p, k = 0.2, -0.4, 2.5
    m_w = np.array([[1, 0, 0], [0, np.cos(w), np.sin(w)], [0, -np.sin(w), np.cos(w)]])
    m_p = np.array([[np.cos(p), 0, -np.sin(p)], [0, 1, 0], [np.sin(p), 0, np.cos(p)]])
    m_k = np.array([[np.cos(k), np.sin(k), 0], [-np.sin(k), np.cos(k), 0], [0, 0, 1]])
    np.testing.assert_allclose(matrix_from_opk([w, p, k]), (m_k @ m_p @ m_w).T, rtol=0, atol=1e-15)


def test_matrix_from_schut_equals_scipy_rotvec(rng):
    # J(2) is the Cayley/Gibbs form: (a, b, c) = tan(theta/2) axis
    axes = random_axes(rng)
    theta = rng.uniform(0.0, np.deg2rad(179.0), N)
    abc = np.tan(theta / 2)[:, None] * axes
    expected = Rotation.from_rotvec(theta[:, None] * axes).as_matrix()
    np.testing.assert_allclose(matrix_from_schut(abc), expected, rtol=0, atol=1e-14)


def test_matrix_from_rotvec_equals_scipy(rng):
    rv = random_axes(rng) * rng.uniform(0.0, np.pi, N)[:, None]
    np.testing.assert_allclose(
        matrix_from_rotvec(rv), Rotation.from_rotvec(rv).as_matrix(), rtol=0, atol=1e-15
    )


@pytest.mark.parametrize(
    "func",
    [matrix_from_cardan, matrix_from_opk, matrix_from_rotvec, matrix_from_schut],
    ids=lambda f: f.__name__,
)
def test_matrices_are_proper_rotations(func, rng):
    params = rng.uniform(-3.0, 3.0, (N, 3))
    assert_rotation(func(params))


# ---------------------------------------------------------------------------
# round trips over 1000 random rotations


def test_cardan_round_trip(rng, matrices):
    ang = random_cardan(rng)
    back = cardan_from_matrix(matrix_from_cardan(ang))
    np.testing.assert_allclose(wrap(back - ang), 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        matrix_from_cardan(cardan_from_matrix(matrices)), matrices, rtol=0, atol=ROUND
    )
    deg = cardan_from_matrix(matrices, degrees=True)
    np.testing.assert_allclose(matrix_from_cardan(deg, degrees=True), matrices, atol=ROUND)
    assert np.all(np.abs(deg[:, 1]) <= 90.0)


def test_opk_round_trip(rng, matrices):
    opk = random_cardan(rng)[:, [0, 1, 2]]  # omega, kappa in (-pi, pi], phi in [-pi/2, pi/2]
    back = opk_from_matrix(matrix_from_opk(opk))
    np.testing.assert_allclose(wrap(back - opk), 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        matrix_from_opk(opk_from_matrix(matrices)), matrices, rtol=0, atol=ROUND
    )
    # scipy agrees on the angles themselves (same ranges)
    expected = Rotation.from_matrix(matrices).as_euler("XYZ")
    np.testing.assert_allclose(wrap(opk_from_matrix(matrices) - expected), 0.0, atol=1e-12)


def test_schut_round_trip(rng):
    axes = random_axes(rng)
    theta = rng.uniform(0.0, np.deg2rad(170.0), N)
    abc = np.tan(theta / 2)[:, None] * axes
    np.testing.assert_allclose(schut_from_matrix(matrix_from_schut(abc)), abc, atol=1e-12)


def test_schut_round_trip_170_to_179_deg(rng):
    axes = random_axes(rng)
    theta = np.deg2rad(rng.uniform(170.0, SCHUT_MAX_ANGLE_DEG - 1e-6, N))
    abc = np.tan(theta / 2)[:, None] * axes  # |abc| up to 114.6
    m = matrix_from_rotvec(theta[:, None] * axes)
    back = schut_from_matrix(m)
    # relative accuracy degrades as 1/cos^2(theta/2), about 1.3e4 at 179 deg
    np.testing.assert_allclose(back, abc, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(matrix_from_schut(back), m, rtol=0, atol=1e-13)


def test_rotvec_round_trip(rng, matrices):
    rv = random_axes(rng) * rng.uniform(0.0, np.pi - 1e-6, N)[:, None]
    np.testing.assert_allclose(rotvec_from_matrix(matrix_from_rotvec(rv)), rv, atol=1e-12)
    back = rotvec_from_matrix(matrices)
    np.testing.assert_allclose(matrix_from_rotvec(back), matrices, rtol=0, atol=ROUND)
    assert np.all(np.linalg.norm(back, axis=1) <= np.pi + 1e-15)


@pytest.mark.parametrize("theta", [0.0, 1e-300, 1e-12, 1e-6, 1e-3], ids=lambda t: f"{t:g}")
def test_rotvec_near_zero(theta, rng):
    rv = random_axes(rng, 50) * theta
    m = matrix_from_rotvec(rv)
    assert_rotation(m)
    # two ulps of 1.0
    np.testing.assert_allclose(m, Rotation.from_rotvec(rv).as_matrix(), rtol=0, atol=4.5e-16)
    # relative accuracy of the recovered vector, also for tiny angles
    np.testing.assert_allclose(rotvec_from_matrix(m), rv, rtol=1e-9, atol=1e-300)


@pytest.mark.parametrize("gap", [0.0, 1e-12, 1e-7, 1e-3], ids=lambda g: f"pi-{g:g}")
def test_rotvec_near_pi(gap, rng):
    rv = random_axes(rng, 50) * (np.pi - gap)
    m = matrix_from_rotvec(rv)
    back = rotvec_from_matrix(m)
    np.testing.assert_allclose(np.linalg.norm(back, axis=1), np.pi - gap, rtol=0, atol=1e-12)
    np.testing.assert_allclose(matrix_from_rotvec(back), m, rtol=0, atol=ROUND)
    if gap > 0.0:  # off the exact half turn the sign of the axis is defined
        np.testing.assert_allclose(back, rv, rtol=0, atol=1e-8)


@pytest.fixture
def schut_matrices() -> np.ndarray:
    """Random rotations that Schut's parameters can express (angle < 175 deg)."""
    m = Rotation.random(N, random_state=7)
    return m[np.linalg.norm(m.as_rotvec(), axis=1) < np.deg2rad(175.0)].as_matrix()


@pytest.mark.parametrize("degrees", [False, True], ids=["rad", "deg"])
def test_cardan_opk_conversions(degrees, matrices):
    cardan = cardan_from_matrix(matrices, degrees=degrees)
    opk = opk_from_cardan(cardan, degrees=degrees)
    np.testing.assert_allclose(matrix_from_opk(opk, degrees=degrees), matrices, atol=ROUND)
    np.testing.assert_allclose(cardan_from_opk(opk, degrees=degrees), cardan, atol=1e-10)


@pytest.mark.parametrize("degrees", [False, True], ids=["rad", "deg"])
def test_cardan_schut_conversions(degrees, schut_matrices):
    abc = schut_from_matrix(schut_matrices)
    cardan = cardan_from_schut(abc, degrees=degrees)
    np.testing.assert_allclose(
        matrix_from_cardan(cardan, degrees=degrees), schut_matrices, atol=ROUND
    )
    np.testing.assert_allclose(schut_from_cardan(cardan, degrees=degrees), abc, atol=1e-11)


@pytest.mark.parametrize("degrees", [False, True], ids=["rad", "deg"])
def test_opk_schut_conversions(degrees, schut_matrices):
    abc = schut_from_matrix(schut_matrices)
    opk = opk_from_schut(abc, degrees=degrees)
    np.testing.assert_allclose(matrix_from_opk(opk, degrees=degrees), schut_matrices, atol=ROUND)
    np.testing.assert_allclose(schut_from_opk(opk, degrees=degrees), abc, atol=1e-11)


def test_conversions_state_same_rotation():
    ang = np.array([0.1, -0.25, 2.0])  # alpha, omega, chi
    m = matrix_from_cardan(ang)
    np.testing.assert_allclose(matrix_from_opk(opk_from_cardan(ang)), m, atol=ROUND)
    np.testing.assert_allclose(matrix_from_schut(schut_from_cardan(ang)), m, atol=ROUND)
    np.testing.assert_allclose(
        cardan_from_opk(opk_from_cardan(ang, degrees=False)), ang, rtol=0, atol=1e-14
    )
    deg = np.rad2deg(ang)
    np.testing.assert_allclose(
        opk_from_cardan(deg, degrees=True), np.rad2deg(opk_from_cardan(ang))
    )


# ---------------------------------------------------------------------------
# singularities


@pytest.mark.parametrize(
    "gap",
    [np.deg2rad(1e-7), 1e-7, 1e-6],
    ids=["1e-7deg", "1e-7rad", "1e-6rad"],
)
@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["+90", "-90"])
def test_cardan_near_gimbal_lock_round_trips_without_warning(gap, sign, rng):
    ang = random_cardan(rng)
    ang[:, 1] = sign * (np.pi / 2 - gap)
    m = matrix_from_cardan(ang)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = cardan_from_matrix(m)
    np.testing.assert_allclose(back[:, 1], ang[:, 1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(matrix_from_cardan(back), m, rtol=0, atol=ROUND)


@pytest.mark.parametrize(
    "gap",
    [np.deg2rad(1e-7), 1e-7, 1e-6],
    ids=["1e-7deg", "1e-7rad", "1e-6rad"],
)
@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["+90", "-90"])
def test_opk_near_gimbal_lock_round_trips_without_warning(gap, sign, rng):
    opk = random_cardan(rng)
    opk[:, 1] = sign * (np.pi / 2 - gap)
    m = matrix_from_opk(opk)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        back = opk_from_matrix(m)
    np.testing.assert_allclose(back[:, 1], opk[:, 1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(matrix_from_opk(back), m, rtol=0, atol=ROUND)


@pytest.mark.parametrize("gap", [0.0, 1e-10, 5e-10], ids=["exact", "1e-10rad", "5e-10rad"])
@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["+90", "-90"])
def test_cardan_gimbal_lock_warns_and_still_reproduces(gap, sign, rng):
    ang = random_cardan(rng, 20)
    ang[:, 1] = sign * (np.pi / 2 - gap)
    m = matrix_from_cardan(ang)
    with pytest.warns(
        StripAerotriWarning, match="Gimbal lock in alpha-omega-chi.*20 of 20"
    ) as rec:
        back = cardan_from_matrix(m)
    assert rec[0].filename == __file__  # stacklevel points at the caller
    np.testing.assert_array_equal(back[:, 2], 0.0)  # chi = 0 is the documented choice
    # documented bound: the matrix is reproduced to within 2 cos(omega)
    np.testing.assert_allclose(matrix_from_cardan(back), m, rtol=0, atol=2 * gap + 1e-15)


@pytest.mark.parametrize("gap", [0.0, 1e-10], ids=["exact", "1e-10rad"])
@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["+90", "-90"])
def test_opk_gimbal_lock_warns_and_still_reproduces(gap, sign, rng):
    opk = random_cardan(rng, 20)
    opk[:, 1] = sign * (np.pi / 2 - gap)
    m = matrix_from_opk(opk)
    with pytest.warns(StripAerotriWarning, match="Gimbal lock in omega-phi-kappa.*phi") as rec:
        back = opk_from_matrix(m)
    assert rec[0].filename == __file__
    np.testing.assert_array_equal(back[:, 2], 0.0)
    np.testing.assert_allclose(matrix_from_opk(back), m, rtol=0, atol=2 * gap + 1e-15)


def test_gimbal_lock_warning_from_conversion_points_at_caller():
    with pytest.warns(StripAerotriWarning, match="omega-phi-kappa") as rec:
        opk_from_schut([0.0, 1.0, 0.0])  # 90 deg about y: phi = 90 deg
    assert rec[0].filename == __file__
    with pytest.warns(StripAerotriWarning, match="alpha-omega-chi") as rec:
        cardan_from_opk([90.0, 0.0, 10.0], degrees=True)
    assert rec[0].filename == __file__


def test_only_locked_rotations_are_reported(rng):
    ang = random_cardan(rng, 5)
    ang[:, 1] = np.clip(ang[:, 1], -1.0, 1.0)
    ang[3, 1] = np.pi / 2
    with pytest.warns(StripAerotriWarning, match=r"1 of 5 rotation\(s\) \(first: rotation 3\)"):
        back = cardan_from_matrix(matrix_from_cardan(ang))
    np.testing.assert_allclose(back[[0, 1, 2, 4]], ang[[0, 1, 2, 4]], rtol=0, atol=1e-14)


@pytest.mark.parametrize("angle_deg", [179.0 + 1e-6, 179.5, 179.999, 180.0])
def test_schut_raises_near_half_turn(angle_deg, rng):
    axis = random_axes(rng, 1)[0]
    m = matrix_from_rotvec(np.deg2rad(angle_deg) * axis)
    pattern = rf"the rotation in Schut.*{re.escape(f'{angle_deg:.3f}')}\d* deg.*at 180 deg"
    with pytest.raises(GeometryError, match=pattern):
        schut_from_matrix(m)


def test_schut_error_names_rotation_in_stack(rng):
    axes = random_axes(rng, 6)
    theta = np.deg2rad([10.0, 20.0, 30.0, 40.0, 179.5, 50.0])
    m = matrix_from_rotvec(theta[:, None] * axes).reshape(2, 3, 3, 3)
    with pytest.raises(GeometryError, match=r"rotation \(1, 1\).*179\.5000 deg.*1 of 6"):
        schut_from_matrix(m)
    with pytest.raises(GeometryError, match="beyond the limit of 179 deg"):
        schut_from_opk([0.0, 0.0, 180.0], degrees=True)
    with pytest.raises(GeometryError):
        schut_from_cardan([np.pi, 0.0, 0.0])


# ---------------------------------------------------------------------------
# broadcasting, validation, immutability


SHAPES = [(3,), (5, 3), (2, 5, 3)]
SHAPE_IDS = ["(3,)", "(N,3)", "(2,N,3)"]


@pytest.mark.parametrize("shape", SHAPES, ids=SHAPE_IDS)
@pytest.mark.parametrize(
    ("to_matrix", "from_matrix"),
    [
        (matrix_from_cardan, cardan_from_matrix),
        (matrix_from_opk, opk_from_matrix),
        (matrix_from_schut, schut_from_matrix),
        (matrix_from_rotvec, rotvec_from_matrix),
    ],
    ids=["cardan", "opk", "schut", "rotvec"],
)
def test_broadcasting(shape, to_matrix, from_matrix, rng):
    params = rng.uniform(-1.0, 1.0, shape)
    m = to_matrix(params)
    assert m.shape == (*shape[:-1], 3, 3)
    assert m.dtype == np.float64
    # each element equals the single-rotation result
    flat = params.reshape(-1, 3)
    singles = np.array([to_matrix(p) for p in flat]).reshape(m.shape)
    np.testing.assert_array_equal(m, singles)
    back = from_matrix(m)
    assert back.shape == shape
    np.testing.assert_allclose(back, params, rtol=0, atol=1e-13)


@pytest.mark.parametrize("shape", SHAPES, ids=SHAPE_IDS)
@pytest.mark.parametrize(
    "func",
    [
        opk_from_cardan,
        cardan_from_opk,
        schut_from_cardan,
        cardan_from_schut,
        opk_from_schut,
        schut_from_opk,
    ],
    ids=lambda f: f.__name__,
)
def test_conversion_shapes(shape, func, rng):
    assert func(rng.uniform(-1.0, 1.0, shape)).shape == shape


@pytest.mark.parametrize(
    "func",
    [
        skew,
        matrix_from_cardan,
        matrix_from_opk,
        matrix_from_schut,
        matrix_from_rotvec,
        opk_from_cardan,
        cardan_from_opk,
        schut_from_cardan,
        cardan_from_schut,
        opk_from_schut,
        schut_from_opk,
    ],
    ids=lambda f: f.__name__,
)
def test_vector_inputs_not_modified(func, rng):
    params = rng.uniform(-1.0, 1.0, (4, 3))
    copy = params.copy()
    params.flags.writeable = False  # any write attempt would raise
    func(params)
    np.testing.assert_array_equal(params, copy)


@pytest.mark.parametrize(
    "func",
    [
        cardan_from_matrix,
        opk_from_matrix,
        schut_from_matrix,
        rotvec_from_matrix,
        check_matrix,
    ],
    ids=lambda f: f.__name__,
)
def test_matrix_inputs_not_modified(func, matrices):
    m = matrices[:10].copy()
    copy = m.copy()
    m.flags.writeable = False
    out = func(m)
    np.testing.assert_array_equal(m, copy)
    assert not np.shares_memory(out, m)


@pytest.mark.parametrize(
    "func",
    [skew, matrix_from_cardan, matrix_from_opk, matrix_from_schut, matrix_from_rotvec],
    ids=lambda f: f.__name__,
)
@pytest.mark.parametrize(
    "bad", [1.0, [1.0, 2.0], np.zeros((3, 4))], ids=["scalar", "(2,)", "(3,4)"]
)
def test_vector_shape_errors(func, bad):
    with pytest.raises(ValueError, match=r"Expected `\w+` to have shape \(\.\.\., 3\), got"):
        func(bad)


def test_check_matrix_shape_error():
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 3, 3\), got \(3,\)"):
        check_matrix(np.zeros(3))
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 3, 3\), got \(2, 3, 4\)"):
        cardan_from_matrix(np.zeros((2, 3, 4)))


def test_check_matrix_orthonormality_and_det(matrices):
    out = check_matrix(matrices.tolist())
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, matrices)
    bad = matrices[:4].copy()
    bad[2, 0, 0] += 1e-4
    with pytest.raises(
        ValueError, match=r"orthonormal, got max \|R\^T R - I\| = 0\.0001\d* .*rotation 2\."
    ):
        check_matrix(bad)
    check_matrix(bad, tolerance=1e-3)  # accepted with a looser tolerance
    reflection = matrices[:3] * np.array([1.0, 1.0, -1.0])
    with pytest.raises(ValueError, match=r"det = \+1\), got det = -1 for rotation 0"):
        check_matrix(reflection)
    with pytest.raises(ValueError, match="finite"):
        check_matrix(np.full((3, 3), np.nan))
    with pytest.raises(ValueError, match="orthonormal"):
        opk_from_matrix(2.0 * np.eye(3))


# ---------------------------------------------------------------------------
# textbook regression and the [fix] of B(135)


def test_textbook_r3_collinearity_example():
    # Source: shared/seeds/003_6f0298aea3bd11c6.txt, R3 (3.5)-(3.13), worked example
    # ("Пример"): x = 80.637 mm, y = 2.517 mm, alpha = 3 deg, omega = kappa = 0,
    # c = 100 mm; X_S = 6426.16, Y_S = 52346.11, Z_S = 1654.17, Z_A = 154.160 m.
    c = 100.0
    a = matrix_from_cardan([3.0, 0.0, 0.0], degrees=True)
    x_, y_, z_ = a @ np.array([80.637, 2.517, -c])
    # printed (85.7601, 2.517, -95.6428); the source rounds sin/cos to six
    # digits (0.0523360, 0.998630), which moves Z' by 4.3e-5: one unit of the
    # printed last digit is the honest tolerance.
    np.testing.assert_allclose([x_, y_, z_], [85.7601, 2.517, -95.6428], rtol=0, atol=1e-4)
    x_s, y_s, z_s, z_a = 6426.16, 52346.11, 1654.17, 154.160
    x_a = x_s + (z_a - z_s) * x_ / z_
    y_a = y_s + (z_a - z_s) * y_ / z_
    # printed X_A = 7771.176 m, Y_A = 52385.585 m (to the millimetre)
    assert x_a == pytest.approx(7771.176, abs=1e-3)
    assert y_a == pytest.approx(52385.585, abs=1e-3)
    # and with the source's own six-digit trigonometric values, to 1e-4
    a6 = np.array([[0.998630, 0.0, -0.0523360], [0.0, 1.0, 0.0], [0.0523360, 0.0, 0.998630]])
    np.testing.assert_allclose(a6 @ [80.637, 2.517, -c], [85.7601, 2.517, -95.6428], atol=5e-5)


def test_b135_fix_sin_omega_is_minus_b3():
    # B(135) prints sin omega2 = -b32/c32; B(129) and the matrix B(133) give
    # sin omega = -b3 (method.md 2.1 [fix]).
    ang = np.deg2rad([10.0, 20.0, 5.0])
    a = matrix_from_cardan(ang)
    b3, c3 = a[1, 2], a[2, 2]
    printed = np.arcsin(-b3 / c3)
    fixed = np.arcsin(-b3)
    # arcsin(sin 20 deg / (cos 10 deg cos 20 deg)) = 21.69 deg: wrong by 1.7 deg
    assert np.rad2deg(printed) == pytest.approx(21.69, abs=0.01)
    assert fixed == pytest.approx(ang[1], abs=1e-15)
    np.testing.assert_allclose(cardan_from_matrix(a), ang, rtol=0, atol=1e-15)
    # for larger tilts the printed form is not even a sine
    a = matrix_from_cardan(np.deg2rad([50.0, 50.0, 0.0]))
    assert abs(-a[1, 2] / a[2, 2]) > 1.0
    np.testing.assert_allclose(cardan_from_matrix(a, degrees=True), [50.0, 50.0, 0.0], atol=1e-12)


# ---------------------------------------------------------------------------
# small-angle identity


def test_schut_small_angle_identity(rng):
    # R_schut(phi/2) = I + [phi]x + O(|phi|^2): the remainder divided by t^2
    # tends to [u]x^2 / 2 (second-order term), and after subtracting it the
    # remainder is O(t^3).
    u = rng.normal(size=3)
    k = skew(u)
    ratios, third = [], []
    for t in (1e-2, 1e-3, 1e-4):
        phi = t * u
        rem = matrix_from_schut(phi / 2) - (np.eye(3) + skew(phi))
        ratios.append(np.abs(rem / t**2 - 0.5 * k @ k).max())
        third.append(np.abs(rem - 0.5 * t**2 * (k @ k)).max() / t**3)
    # the first-order form is wrong at second order, by [phi]x^2/2
    assert np.abs(0.5 * k @ k).max() > 0.1
    assert ratios[-1] < 1e-3
    assert max(third) < 5.0 * np.linalg.norm(u) ** 3
    # and the half angle matters: a full-angle argument is off at first order
    rem_full = matrix_from_schut(1e-4 * u) - (np.eye(3) + skew(1e-4 * u))
    assert np.abs(rem_full).max() > 0.4e-4 * np.abs(u).max()


def test_module_doctests():
    result = doctest.testmod(rotation, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 15
    assert result.failed == 0
