"""Space intersection: J(11)-(12) midpoint and B(137)-(138) normal case (method.md §4)."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from strip_aerotri.geometry.intersection import intersect, intersect_midpoint, intersect_normal

C = 152.0


def _rays(n=50, seed=0, tilt_deg=2.0):
    rng = np.random.default_rng(seed)
    base = np.array([1.0, 0.03, -0.02])
    pts = np.column_stack(
        [rng.uniform(-0.5, 1.5, n), rng.uniform(-1, 1, n), rng.uniform(-3.4, -3.0, n)]
    )
    r_l = Rotation.from_euler("XYZ", rng.normal(0, tilt_deg, 3), degrees=True).as_matrix()
    r_r = Rotation.from_euler("XYZ", rng.normal(0, tilt_deg, 3), degrees=True).as_matrix()
    l_img = pts @ r_l  # image-direction vectors, then scaled to z = -c
    l_img *= -C / l_img[:, 2:3]
    p_img = (pts - base) @ r_r
    p_img *= -C / p_img[:, 2:3]
    return base, l_img @ r_l.T, p_img @ r_r.T, pts


@pytest.mark.parametrize("method", ["midpoint", "normal"])
def test_meeting_rays_give_the_point(method):
    base, left, right, pts = _rays()
    res = intersect(base, left, right, method=method, principal_distance=C)
    np.testing.assert_allclose(res.points, pts, atol=1e-12)
    np.testing.assert_allclose(res.parallax, 0.0, atol=1e-12)


def test_midpoint_splits_the_y_parallel_gap():
    base, left, right, pts = _rays(seed=1)
    shifted = base + np.array([0.0, 0.01, 0.0])  # y-parallax of 0.01 base units
    res = intersect_midpoint(shifted, left, right)
    np.testing.assert_allclose(res.parallax, 0.01, atol=1e-12)
    # the point lies 0.005 above (in y) the left ray: the midpoint of the gap
    k = (res.points[:, 0] / left[:, 0])[:, None]
    np.testing.assert_allclose(
        res.points - k * left, np.tile([0, 0.005, 0], (len(pts), 1)), atol=1e-9
    )


def test_printed_b137_misprint_gives_wrong_points():
    """B(137) prints x2_0 = -f Y2'/Z2'; with it the X parallax is wrong."""
    base, left, right, pts = _rays(seed=2)
    c = C
    x1 = -c * left[:, 0] / left[:, 2]
    y1 = -c * left[:, 1] / left[:, 2]
    x2_printed = -c * right[:, 1] / right[:, 2]
    n = (base[0] + (x2_printed / c) * base[2]) / (x1 - x2_printed)
    printed = np.column_stack([n * x1, n * y1, -n * c])
    assert np.abs(printed - pts).max() > 0.1
    fixed = intersect_normal(base, left, right, c).points
    np.testing.assert_allclose(fixed, pts, atol=1e-12)


def test_inputs_unchanged_and_shapes_checked():
    base, left, right, _ = _rays()
    before = left.copy()
    intersect_midpoint(base, left, right)
    np.testing.assert_array_equal(left, before)
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        intersect_midpoint(base, left[:, :2], right)
    with pytest.raises(ValueError, match="principal_distance"):
        intersect(base, left, right, method="normal")


def test_midpoint_is_invariant_to_a_common_rotation_with_its_y_axis():
    # form_strip intersects in each left photo's image frame and turns the points
    # to the strip: the same as intersecting in the strip along the turned j.
    base, left, right, _ = _rays(seed=3)
    rng = np.random.default_rng(4)
    right = right + rng.normal(0.0, 0.01, right.shape)  # rays that do not meet
    turn = Rotation.from_euler("ZYX", [75.0, 1.5, -2.0], degrees=True).as_matrix()
    plain = intersect_midpoint(base, left, right)  # j = (0, 1, 0), the written-out form
    general = intersect_midpoint(base, left, right, across=np.array([0.0, 1.0, 0.0]))
    np.testing.assert_allclose(plain.points, general.points, rtol=0, atol=1e-14)
    np.testing.assert_allclose(plain.parallax, general.parallax, rtol=0, atol=1e-14)
    turned = intersect_midpoint(
        base @ turn.T, left @ turn.T, right @ turn.T, across=np.tile(turn[:, 1], (len(left), 1))
    )
    assert np.max(np.abs(plain.parallax)) > 1e-4
    np.testing.assert_allclose(turned.points, plain.points @ turn.T, rtol=0, atol=1e-13)
    np.testing.assert_allclose(turned.parallax, plain.parallax, rtol=0, atol=1e-13)
