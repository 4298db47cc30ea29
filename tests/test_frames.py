"""The work frames: round trips CRS <-> work frame, and the rotation to local
east-north-up against an independent construction (the ENU basis of pyproj's
geocentric conversion)."""

from __future__ import annotations

import numpy as np
import pytest

from strip_aerotri.frames import (
    ProjectedWorkFrame,
    TangentWorkFrame,
    enu_residuals,
    make_work_frame,
)
from strip_aerotri.geodesy import GroundCRS
from strip_aerotri.geometry.rotation import matrix_from_opk
from strip_aerotri.options import Route

UTM = GroundCRS.from_user_input("EPSG:32634")
GEOGRAPHIC = GroundCRS.from_user_input("EPSG:4326")
LOCAL = GroundCRS.from_user_input("local")


def _points(crs: GroundCRS, n: int = 40, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if crs.is_geographic:
        lon = 21.0 + rng.uniform(-0.05, 0.05, n)
        lat = 50.0 + rng.uniform(-0.03, 0.03, n)
        return np.column_stack([lon, lat, rng.uniform(100.0, 1500.0, n)])
    base = np.array([500_000.0, 5_540_000.0, 0.0]) if not crs.is_local else np.zeros(3)
    return base + np.column_stack(
        [rng.uniform(-4000, 4000, n), rng.uniform(-2000, 2000, n), rng.uniform(100, 1500, n)]
    )


@pytest.mark.parametrize("route", [Route.GEOCENTRIC, Route.PROJECTED])
@pytest.mark.parametrize("crs", [UTM, GEOGRAPHIC, LOCAL], ids=["utm", "geographic", "local"])
def test_to_work_and_back_is_the_identity(route, crs):
    if route is Route.GEOCENTRIC and crs.is_local:
        pytest.skip("the geocentric route needs a datum")
    if route is Route.PROJECTED and crs.is_geographic:
        pytest.skip("the projected route needs a map grid")
    xyh = _points(crs)
    work = make_work_frame(route, crs, xyh[:6], azimuth=0.7)
    back = work.from_work(work.to_work(xyh))
    plan_tol = 1e-11 if crs.is_geographic else 1e-6  # degrees or metres
    np.testing.assert_allclose(back[:, :2], xyh[:, :2], rtol=0, atol=plan_tol)
    np.testing.assert_allclose(back[:, 2], xyh[:, 2], rtol=0, atol=1e-6)


@pytest.mark.parametrize("route", [Route.GEOCENTRIC, Route.PROJECTED])
def test_work_from_enu_inverts_rotations_to_enu(route):
    xyh = _points(UTM)
    work = make_work_frame(route, UTM, xyh[:6], azimuth=1.1)
    rot = matrix_from_opk(np.random.default_rng(1).uniform(-0.1, 0.1, (5, 3)))
    to_enu = work.rotations_to_enu(rot, xyh[:5])
    np.testing.assert_allclose(work.work_from_enu(xyh[:5]) @ to_enu, rot, atol=1e-12)


def test_tangent_frame_rotation_to_enu_is_the_geodetic_basis():
    """A photo whose image axes are east, north, up at its own centre comes
    out as the identity, whatever the frame's origin and azimuth (checked
    against ENU unit vectors built from pyproj's geodetic -> ECEF)."""
    xyh = _points(UTM, n=4, seed=3)
    work = TangentWorkFrame.at_control(UTM, xyh, azimuth=0.4)
    llh = UTM.to_geodetic(xyh)
    eps = 1e-6  # central differences: error of order eps**2
    rows = []
    for lat, lon, h in llh:
        east = GEOGRAPHIC.geodetic2ecef([lat, lon + eps, h]) - GEOGRAPHIC.geodetic2ecef(
            [lat, lon - eps, h]
        )
        north = GEOGRAPHIC.geodetic2ecef([lat + eps, lon, h]) - GEOGRAPHIC.geodetic2ecef(
            [lat - eps, lon, h]
        )
        east /= np.linalg.norm(east)
        north -= east * (north @ east)
        north /= np.linalg.norm(north)
        rows.append(np.column_stack([east, north, np.cross(east, north)]))  # image -> ECEF
    image_to_ecef = np.array(rows)
    image_to_work = work.frame.rotation @ image_to_ecef
    np.testing.assert_allclose(
        work.rotations_to_enu(image_to_work, xyh), np.broadcast_to(np.eye(3), (4, 3, 3)), atol=1e-8
    )


def test_the_site_system_is_its_own_work_frame():
    xyh = _points(LOCAL)
    work = TangentWorkFrame(LOCAL, None)
    np.testing.assert_array_equal(work.to_work(xyh), xyh)
    assert not work.curved
    with pytest.raises(ValueError, match="tangent frame"):
        TangentWorkFrame(UTM, None)


def test_projected_frame_heights_follow_b153():
    """B(153): a point at distance D from the centre of the net lies
    D^2 / (2R) below the tangent plane (to second order)."""
    centre = np.array([[500_000.0, 5_540_000.0, 0.0]])
    work = ProjectedWorkFrame(UTM, centre, azimuth=0.0)
    d = 5000.0 * work.grid_scale
    pts = centre + np.array([[d, 0.0, 0.0], [0.0, d, 0.0]])
    z = work.to_work(pts)[:, 2]
    np.testing.assert_allclose(z, -(5000.0**2) / (2 * work.radius), rtol=1e-6)


def test_enu_residuals_on_a_geographic_crs_are_metres():
    adjusted = np.array([[21.0, 50.0, 200.0]])
    # 1 m north along the meridian: latitude step of 1 / M radians
    m_radius = (
        np.linalg.norm(
            GEOGRAPHIC.to_ecef([[21.0, 50.0 + 1e-5, 200.0]]) - GEOGRAPHIC.to_ecef(adjusted)
        )
        / 1e-5
    )
    one_metre_north = adjusted + np.array([[0.0, 1.0 / m_radius, 0.0]])
    resid = enu_residuals(GEOGRAPHIC, one_metre_north, adjusted)
    np.testing.assert_allclose(resid, [[0.0, 1.0, 0.0]], atol=1e-6)
    projected = enu_residuals(UTM, adjusted + 1.0, adjusted)
    np.testing.assert_array_equal(projected, [[1.0, 1.0, 1.0]])
