"""rays_information: the information of points and projection centres from the
same rays at once, against the one-purpose functions and a finite-difference
Jacobian of the collinearity equations."""

from __future__ import annotations

import numpy as np
import pytest

from strip_aerotri.geometry.collinearity import image_vectors
from strip_aerotri.geometry.precision import (
    centre_information,
    ray_information,
    rays_information,
)
from strip_aerotri.geometry.rotation import matrix_from_opk, matrix_from_rotvec

C_MM = 8.8


def _rays(n: int, n_photos: int, seed: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    centres = np.column_stack(
        [rng.uniform(-50, 50, n_photos), rng.uniform(-5, 5, n_photos), np.full(n_photos, 120.0)]
    )
    rotations = matrix_from_opk(rng.normal(0.0, 0.1, (n_photos, 3)))
    photo = rng.integers(0, n_photos, n)
    points = centres[photo] + np.column_stack(
        [rng.uniform(-40, 40, n), rng.uniform(-30, 30, n), rng.uniform(-125, -115, n)]
    )
    sigma = rng.uniform(0.001, 0.004, n)
    return points, photo, centres, rotations, sigma


def _image(point: np.ndarray, centre: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    v = image_vectors(centre[None], rotation[None], point[None])[0]
    return -C_MM * v[:2] / v[2]


@pytest.mark.parametrize("shuffled", [False, True])
def test_rays_information_equals_the_one_purpose_functions(shuffled: bool) -> None:
    """Points' information as ray_information, centres' as centre_information
    (groups sorted or not; a group of two rays is not determined: NaN; a
    group with no rays too)."""
    points, photo, centres, rotations, sigma = _rays(400, 6, seed=3)
    group = np.sort(np.random.default_rng(4).integers(0, 9, 400))
    group[group == 7] = 8
    group[np.flatnonzero(group == 8)[:2]] = 7  # two rays only
    group[group == 8] = 6  # and group 8 has none
    if shuffled:
        order = np.random.default_rng(5).permutation(400)
        points, photo, sigma, group = points[order], photo[order], sigma[order], group[order]
    info, centre = rays_information(points, photo, centres, rotations, C_MM, sigma, group, 9)
    want_info = ray_information(points, centres[photo], rotations[photo], C_MM, sigma)
    want_centre = centre_information(
        points, centres[photo], rotations[photo], C_MM, sigma, group, 9
    )
    np.testing.assert_allclose(info, want_info, rtol=1e-12, atol=1e-12 * np.abs(want_info).max())
    assert np.array_equal(np.isnan(centre), np.isnan(want_centre))
    assert np.isnan(centre[[7, 8]]).all() and np.isfinite(centre[:7]).all()
    ok = np.isfinite(want_centre)
    np.testing.assert_allclose(centre[ok], want_centre[ok], rtol=1e-9)


def test_rays_information_against_finite_differences() -> None:
    """J^T J / sigma^2 of each ray with J the numerical derivative of the image
    coordinates by the point; the centre's information of one photo's rays
    from the numerical 6-column Jacobian (centre, attitude), the attitude
    eliminated."""
    points, photo, centres, rotations, sigma = _rays(12, 1, seed=8)
    info, centre = rays_information(
        points, photo, centres, rotations, C_MM, sigma, np.zeros(12, dtype=int), 1
    )
    h = 1e-4
    rows = []
    for k in range(12):
        jac = np.empty((2, 3))
        for j in range(3):
            step = np.eye(3)[j] * h
            jac[:, j] = (
                _image(points[k] + step, centres[0], rotations[0])
                - _image(points[k] - step, centres[0], rotations[0])
            ) / (2 * h)
        np.testing.assert_allclose(info[k], jac.T @ jac / sigma[k] ** 2, rtol=1e-6)
        full = np.empty((2, 6))
        for j in range(3):
            step = np.eye(3)[j] * h
            full[:, j] = (
                _image(points[k], centres[0] + step, rotations[0])
                - _image(points[k], centres[0] - step, rotations[0])
            ) / (2 * h)
            # attitude about the image axes: R <- R exp([delta]x)
            turn = matrix_from_rotvec(np.eye(3)[j] * 1e-6)
            turn_back = matrix_from_rotvec(-np.eye(3)[j] * 1e-6)
            full[:, 3 + j] = (
                _image(points[k], centres[0], rotations[0] @ turn)
                - _image(points[k], centres[0], rotations[0] @ turn_back)
            ) / 2e-6
        rows.append(full / sigma[k])
    stacked = np.vstack(rows)
    cov = np.linalg.inv(stacked.T @ stacked)[:3, :3]
    np.testing.assert_allclose(centre[0], np.linalg.inv(cov), rtol=1e-5)


def test_outer_sums_are_the_broadcast_products_to_the_bit():
    from strip_aerotri.geometry.precision import _outer_sum

    rng = np.random.default_rng(3)
    a, b = rng.normal(size=(40, 3)), rng.normal(size=(40, 3))
    expected = a[:, :, None] * a[:, None, :] + b[:, :, None] * b[:, None, :]
    np.testing.assert_array_equal(_outer_sum(a, b), expected)
