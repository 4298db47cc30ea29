"""Tests of strip_aerotri.geodesy: ground CRS, local tangent frame B(142)-(144), B(152), B(153).

Independent oracles: pyproj's own geocentric (``+proj=cart``) and topocentric
(``+proj=topocentric``, EPSG method 9836) operations built from PROJ strings,
and the published worked examples of IOGP Publication 373-7-2, Geomatics
Guidance Note 7 part 2 ("GN 7-2"), which PROJ also reproduces in its
documentation (``docs/source/operations/conversions/topocentric.rst``).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pyproj import CRS, Proj, Transformer

from strip_aerotri.errors import ConfigError, GeometryError
from strip_aerotri.frames import LocalTangentFrame
from strip_aerotri.geodesy import (
    MEAN_EARTH_RADIUS,
    GroundCRS,
    azimuth_from_local_enu,
    earth_curvature_correction,
    enu_rotation,
    gaussian_mean_radius,
)

SEED = 2345
WGS84 = GroundCRS.from_user_input("EPSG:4326")


def dms(degrees: float, minutes: float, seconds: float) -> float:
    return degrees + minutes / 60.0 + seconds / 3600.0


def topocentric(lat_deg: float, lon_deg: float, h: float, ellps: str = "WGS84") -> Transformer:
    """pyproj's ECEF -> ENU (EPSG 9836) with the origin given geographically."""
    return Transformer.from_pipeline(
        f"+proj=topocentric +ellps={ellps} "
        f"+lat_0={float(lat_deg)!r} +lon_0={float(lon_deg)!r} +h_0={float(h)!r}"
    )


def enu_of(transformer: Transformer, ecef: np.ndarray) -> np.ndarray:
    return np.column_stack(transformer.transform(ecef[:, 0], ecef[:, 1], ecef[:, 2]))


def local_from_enu(enu: np.ndarray, azimuth: float) -> np.ndarray:
    """Frame coordinates from E, N, U written out by hand (X at A0, Y left, Z up)."""
    e, n, u = enu.T
    ca, sa = math.cos(azimuth), math.sin(azimuth)
    return np.column_stack([e * sa + n * ca, -e * ca + n * sa, u])


def b143_fixed(b0: float, l0: float, a0: float) -> np.ndarray:
    """B(143) with the [fix], element by element as in method.md §6.2 (rows X, Y, Z)."""
    sb, cb, sl, cl, sa, ca = (
        math.sin(b0),
        math.cos(b0),
        math.sin(l0),
        math.cos(l0),
        math.sin(a0),
        math.cos(a0),
    )
    a1 = -sb * cl * ca - sl * sa
    a2 = -sb * cl * sa + sl * ca
    a3 = cb * cl
    b1 = -sb * sl * ca + cl * sa
    b2 = -sb * sl * sa - cl * ca
    b3 = cb * sl
    c1 = cb * ca
    c2 = cb * sa
    c3 = sb
    return np.array([[a1, b1, c1], [a2, b2, c2], [a3, b3, c3]])


def b143_printed(b0: float, l0: float, a0: float) -> np.ndarray:
    """B(143) exactly as printed in the Bulgarian source (000_9ee2ad07190be277.txt, eq. 143)."""
    sb, cb, sl, cl, sa, ca = (
        math.sin(b0),
        math.cos(b0),
        math.sin(l0),
        math.cos(l0),
        math.sin(a0),
        math.cos(a0),
    )
    a1 = -cl * sb * ca - sa * sl
    a2 = -cl * sb * sa - ca * sl  # printed sign; the fix is + cosA0 sinL0
    a3 = cl * cb
    b1 = -sl * sb * ca - sa * cl  # printed sign; the fix is + sinA0 cosL0
    b2 = -sl * sb * sa - ca * cl
    b3 = sl * cb
    c1 = cb * ca
    c2 = cb * sa
    c3 = sb
    return np.array([[a1, b1, c1], [a2, b2, c2], [a3, b3, c3]])


def random_angles(n: int) -> np.ndarray:
    rng = np.random.default_rng(SEED)
    return np.column_stack(
        [
            rng.uniform(-1.5, 1.5, n),  # B0
            rng.uniform(-math.pi, math.pi, n),  # L0
            rng.uniform(0.0, 2.0 * math.pi, n),  # A0
        ]
    )


# --------------------------------------------------------------------------- B(143) [fix]


def test_b143_fixed_is_orthonormal_and_right_handed():
    for b0, l0, a0 in random_angles(200):
        r = LocalTangentFrame(np.zeros(3), b0, l0, a0).rotation
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-14)
        # The implementation is the table of method.md §6.2, element by element.
        np.testing.assert_allclose(r, b143_fixed(b0, l0, a0), atol=1e-15)
        # Y = Z x X: Y points to the left of X, like the photos' y.
        np.testing.assert_allclose(np.cross(r[2], r[0]), r[1], atol=1e-15)


def test_b143_as_printed_is_not_orthonormal():
    angles = random_angles(200)
    defects = np.array(
        [np.abs(b @ b.T - np.eye(3)).max() for b in (b143_printed(*a) for a in angles)]
    )
    # The printed b1 and a2 are the fixed ones minus 2 cosL0 sinA0 and minus 2 sinL0 cosA0: the
    # rows are no longer orthogonal unit vectors unless both terms vanish. Away from there:
    generic = (np.abs(np.cos(angles[:, 1]) * np.sin(angles[:, 2])) > 0.1) | (
        np.abs(np.sin(angles[:, 1]) * np.cos(angles[:, 2])) > 0.1
    )
    assert generic.sum() > 150
    assert np.all(defects[generic] > 1e-3)
    # A concrete case (Sofia, strip heading 30 degrees): the defect is of order one.
    printed = b143_printed(math.radians(42.7), math.radians(23.3), math.radians(30.0))
    assert np.abs(printed @ printed.T - np.eye(3)).max() > 0.3
    assert abs(np.linalg.det(printed) - 1.0) > 0.1


def test_b143_fixed_with_zero_azimuth_is_north_minus_east_up_of_pyproj_topocentric():
    rng = np.random.default_rng(SEED)
    for _ in range(20):
        lat, lon, h = rng.uniform(-80, 80), rng.uniform(-180, 180), rng.uniform(-100, 3000)
        frame = LocalTangentFrame.at(lat, lon, h, 0.0, crs=WGS84, degrees=True)
        points = frame.origin_ecef + rng.uniform(-1000.0, 1000.0, (25, 3))
        enu = enu_of(topocentric(lat, lon, h), points)
        local = frame.ecef2local(points)
        np.testing.assert_allclose(local[:, 0], enu[:, 1], rtol=0, atol=1e-9)
        np.testing.assert_allclose(local[:, 1], -enu[:, 0], rtol=0, atol=1e-9)
        np.testing.assert_allclose(local[:, 2], enu[:, 2], rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- vs pyproj


@pytest.mark.parametrize("azimuth_deg", [0.0, 37.0, 123.4, 200.3, 315.0])
def test_local_tangent_frame_matches_pyproj_topocentric_over_a_100_km_strip(azimuth_deg):
    rng = np.random.default_rng(SEED)
    utm = GroundCRS.from_user_input("EPSG:32634")
    a0 = math.radians(azimuth_deg)
    # A strip 100 km long at azimuth A0, 4 km wide, heights -3 km .. +3 km, in UTM 34N,
    # laid out at the grid bearing A0 - gamma (meridian convergence at the centre).
    centre = np.array([480_000.0, 5_540_000.0])
    bearing = a0 - float(utm.meridian_convergence(centre))
    along = rng.uniform(-50_000.0, 50_000.0, 300)
    across = rng.uniform(-2_000.0, 2_000.0, 300)
    east = centre[0] + along * math.sin(bearing) - across * math.cos(bearing)
    north = centre[1] + along * math.cos(bearing) + across * math.sin(bearing)
    height = rng.uniform(-3_000.0, 3_000.0, 300)
    ecef = utm.to_ecef(np.column_stack([east, north, height]))

    frame = LocalTangentFrame.from_ecef_centroid(ecef, a0, crs=utm)
    x0, y0, z0 = (float(v) for v in frame.origin_ecef)
    oracle = Transformer.from_pipeline(
        f"+proj=topocentric +ellps=WGS84 +X_0={x0!r} +Y_0={y0!r} +Z_0={z0!r}"
    )
    expected = local_from_enu(enu_of(oracle, ecef), a0)
    local = frame.ecef2local(ecef)
    np.testing.assert_allclose(local, expected, rtol=0, atol=1e-3)
    np.testing.assert_allclose(frame.local2ecef(local), ecef, rtol=0, atol=1e-6)
    # X really runs along the strip: the along-strip spread dominates.
    assert np.ptp(local[:, 0]) > 95_000.0
    assert np.ptp(local[:, 1]) < 4_100.0


def test_local_tangent_frame_uses_the_crs_own_datum():
    # DHDN / 3-degree Gauss-Kruger zone 4 (Bessel 1841): the frame must sit on Bessel.
    gk = GroundCRS.from_user_input("EPSG:31468")
    rng = np.random.default_rng(SEED)
    xyh = np.column_stack(
        [
            rng.uniform(4_460_000.0, 4_540_000.0, 50),
            rng.uniform(5_330_000.0, 5_340_000.0, 50),
            rng.uniform(300.0, 900.0, 50),
        ]
    )
    ecef = gk.to_ecef(xyh)
    frame = LocalTangentFrame.from_ecef_centroid(ecef, 1.0, crs=gk)
    lat, lon = math.degrees(frame.latitude), math.degrees(frame.longitude)
    origin_llh = gk.ecef2geodetic(frame.origin_ecef)
    oracle = topocentric(lat, lon, float(origin_llh[2]), ellps="bessel")
    np.testing.assert_allclose(
        frame.ecef2local(ecef), local_from_enu(enu_of(oracle, ecef), 1.0), rtol=0, atol=1e-3
    )


# --------------------------------------------------------------------------- GN 7-2


# IOGP Publication 373-7-2 (GN 7-2), section 4.1.1 "Geographic/geocentric conversions"
# (EPSG method 9602), worked example on the WGS 84 ellipsoid (numbered 2.2.1 in older
# editions): 53°48'33.820"N, 2°07'46.380"E, h = 73.000 m <-> X = 3771793.968 m,
# Y = 140253.342 m, Z = 5124304.349 m.
GN_LAT = dms(53, 48, 33.820)
GN_LON = dms(2, 7, 46.380)
GN_H = 73.000
GN_ECEF = np.array([3771793.968, 140253.342, 5124304.349])


def test_gn7_2_geographic_to_geocentric_epsg_9602():
    ecef = WGS84.geodetic2ecef([math.radians(GN_LAT), math.radians(GN_LON), GN_H])
    # Published to 1 mm: the exact value lies within 0.5 mm of it.
    np.testing.assert_allclose(ecef, GN_ECEF, rtol=0, atol=0.5e-3)
    # Same through the ground-CRS route (EPSG:4326 takes lon, lat in degrees, always_xy).
    np.testing.assert_allclose(WGS84.to_ecef([GN_LON, GN_LAT, GN_H]), GN_ECEF, rtol=0, atol=0.5e-3)


def test_gn7_2_geocentric_to_geographic_epsg_9602():
    lat, lon, h = WGS84.ecef2geodetic(GN_ECEF)
    # Published to 0.001" and 1 mm.
    assert math.degrees(lat) == pytest.approx(GN_LAT, abs=0.0005 / 3600)
    assert math.degrees(lon) == pytest.approx(GN_LON, abs=0.0005 / 3600)
    assert h == pytest.approx(GN_H, abs=0.5e-3)


# GN 7-2, "Geocentric/topocentric conversions" (EPSG method 9836), the subsection after
# 4.1.1 (numbered 2.2.2 in older editions), WGS 84 example: topocentric origin
# 55°00'00"N, 5°00'00"E, h = 200 m, i.e. X0 = 3652755.3058, Y0 = 319574.6799,
# Z0 = 5201547.3536 m; the point of the 9602 example (GN_ECEF) has
# U (east) = -189013.869, V (north) = -128642.040, W (up) = -4220.171 m.
# The same numbers are in PROJ's topocentric.rst usage example and builtins.gie.
GN_TOPO_ORIGIN = np.array([3652755.3058, 319574.6799, 5201547.3536])
GN_TOPO_ENU = np.array([-189013.869, -128642.040, -4220.171])


def test_gn7_2_topocentric_origin():
    frame = LocalTangentFrame.at(55.0, 5.0, 200.0, 0.0, crs=WGS84, degrees=True)
    # Published to 0.1 mm.
    np.testing.assert_allclose(frame.origin_ecef, GN_TOPO_ORIGIN, rtol=0, atol=0.05e-3)


@pytest.mark.parametrize("azimuth_deg", [0.0, 90.0, 200.0, 333.3])
def test_gn7_2_geocentric_to_topocentric_epsg_9836(azimuth_deg):
    a0 = math.radians(azimuth_deg)
    # The origin as published (geocentric) with B0, L0 = 55 N, 5 E.
    frame = LocalTangentFrame(GN_TOPO_ORIGIN, math.radians(55.0), math.radians(5.0), a0)
    expected = local_from_enu(GN_TOPO_ENU[None, :], a0)[0]
    # Published to 1 mm, origin to 0.1 mm: 0.5 mm + 0.1 mm.
    np.testing.assert_allclose(frame.ecef2local(GN_ECEF), expected, rtol=0, atol=0.6e-3)
    np.testing.assert_allclose(frame.enu2local @ GN_TOPO_ENU, expected, rtol=0, atol=1e-9)
    # Reverse (EPSG 9836 reverse example: topocentric -> geocentric).
    np.testing.assert_allclose(frame.local2ecef(expected), GN_ECEF, rtol=0, atol=0.6e-3)
    if azimuth_deg == 0.0:
        # Ours is (X along A0, Y left, Z up) = (N, -E, U) for A0 = 0.
        north_minus_east_up = GN_TOPO_ENU[[1, 0, 2]] * [1.0, -1.0, 1.0]
        np.testing.assert_allclose(frame.ecef2local(GN_ECEF), north_minus_east_up, atol=0.6e-3)


# --------------------------------------------------------------------------- GroundCRS


def _points_in(code: str, n: int = 40) -> np.ndarray:
    rng = np.random.default_rng(SEED)
    height = rng.uniform(-100.0, 3000.0, n)
    if code == "EPSG:32634":  # UTM 34N around 21 E, 50 N
        xy = [rng.uniform(300_000, 700_000, n), rng.uniform(5_300_000, 5_800_000, n)]
    elif code == "EPSG:31468":  # DHDN GK zone 4 (Bessel), Bavaria
        xy = [rng.uniform(4_400_000, 4_600_000, n), rng.uniform(5_250_000, 5_550_000, n)]
    elif code == "EPSG:2180":  # Poland CS92 (GRS 80), easting first with always_xy
        xy = [rng.uniform(200_000, 800_000, n), rng.uniform(200_000, 750_000, n)]
    elif code == "EPSG:2178":  # Poland CS2000 zone 7 (GRS 80)
        xy = [rng.uniform(7_400_000, 7_600_000, n), rng.uniform(5_450_000, 6_050_000, n)]
    else:  # EPSG:4326: longitude, latitude in degrees
        xy = [rng.uniform(-179, 179, n), rng.uniform(-85, 85, n)]
    return np.column_stack([*xy, height])


@pytest.mark.parametrize(
    "code", ["EPSG:32634", "EPSG:31468", "EPSG:2180", "EPSG:2178", "EPSG:4326"]
)
def test_ground_crs_round_trip_through_ecef(code):
    ground = GroundCRS.from_user_input(code)
    xyh = _points_in(code)
    before = xyh.copy()
    ecef = ground.to_ecef(xyh)
    back = ground.from_ecef(ecef)
    np.testing.assert_array_equal(xyh, before)  # input untouched
    if ground.is_geographic:
        # 1e-6 m is 9e-12 degrees of latitude.
        np.testing.assert_allclose(back[:, :2], xyh[:, :2], rtol=0, atol=1e-6 / 111_000)
    else:
        np.testing.assert_allclose(back[:, :2], xyh[:, :2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(back[:, 2], xyh[:, 2], rtol=0, atol=1e-6)
    # Geodetic route gives the same ECEF and round-trips too.
    llh = ground.to_geodetic(xyh)
    np.testing.assert_allclose(ground.geodetic2ecef(llh), ecef, rtol=0, atol=1e-6)
    again = ground.ecef2geodetic(ecef)
    np.testing.assert_allclose(again[:, :2], llh[:, :2], rtol=0, atol=1e-13)  # rad; 0.6 um
    np.testing.assert_allclose(again[:, 2], llh[:, 2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(ground.from_geodetic(llh)[:, 2], xyh[:, 2], rtol=0, atol=1e-6)


@pytest.mark.parametrize(
    ("code", "ellps"),
    [("EPSG:32634", "WGS84"), ("EPSG:31468", "bessel"), ("EPSG:2180", "GRS80")],
)
def test_to_ecef_is_pyproj_cart_on_the_crs_own_ellipsoid(code, ellps):
    """No datum shift: ECEF is +proj=cart of the geodetic coordinates on the datum's ellipsoid."""
    ground = GroundCRS.from_user_input(code)
    xyh = _points_in(code, 10)
    llh = ground.to_geodetic(xyh)
    cart = Transformer.from_pipeline(f"+proj=cart +ellps={ellps}")
    expected = np.column_stack(
        cart.transform(np.degrees(llh[:, 1]), np.degrees(llh[:, 0]), llh[:, 2])
    )
    np.testing.assert_allclose(ground.to_ecef(xyh), expected, rtol=0, atol=1e-6)


def test_to_ecef_of_utm_equals_epsg_4978():
    ground = GroundCRS.from_user_input("EPSG:32634")
    xyh = _points_in("EPSG:32634", 10)
    oracle = Transformer.from_crs(CRS("EPSG:32634").to_3d(), "EPSG:4978", always_xy=True)
    expected = np.column_stack(oracle.transform(*xyh.T))
    np.testing.assert_allclose(ground.to_ecef(xyh), expected, rtol=0, atol=1e-6)


def test_always_xy_axis_order_for_northing_first_crs():
    # EPSG:2180 declares northing first; with always_xy the input is easting, northing.
    # Its central meridian is 19 E with false easting 500000 m (EPSG:2180 definition).
    ground = GroundCRS.from_user_input("EPSG:2180")
    lat, lon, _ = ground.to_geodetic([500_000.0, 500_000.0, 0.0])
    assert math.degrees(lon) == pytest.approx(19.0, abs=1e-9)
    assert 51.0 < math.degrees(lat) < 53.0


@pytest.mark.parametrize("shape", [(3,), (7, 3), (2, 4, 3)], ids=["point", "rows", "stack"])
def test_shapes_broadcast(shape):
    ground = GroundCRS.from_user_input("EPSG:32634")
    rng = np.random.default_rng(SEED)
    xyh = np.empty(shape)
    xyh[..., 0] = rng.uniform(400_000, 600_000, shape[:-1])
    xyh[..., 1] = rng.uniform(5_400_000, 5_600_000, shape[:-1])
    xyh[..., 2] = rng.uniform(0, 1000, shape[:-1])
    assert ground.to_ecef(xyh).shape == shape
    assert ground.to_geodetic(xyh).shape == shape
    assert ground.to_wgs84_lonlat(xyh).shape == (*shape[:-1], 2)
    assert ground.meridian_convergence(xyh).shape == shape[:-1]
    frame = LocalTangentFrame.at(50.0, 21.0, 0.0, 0.3, crs=ground, degrees=True)
    assert frame.ecef2local(ground.to_ecef(xyh)).shape == shape


def test_nan_rows_pass_through():
    ground = GroundCRS.from_user_input("EPSG:32634")
    out = ground.to_ecef([[500_000.0, 5_500_000.0, 100.0], [500_000.0, 5_500_000.0, np.nan]])
    assert np.all(np.isfinite(out[0])) and np.all(np.isnan(out[1]))


def test_bad_shape_is_a_value_error():
    ground = GroundCRS.from_user_input("EPSG:32634")
    with pytest.raises(ValueError, match=r"Expected `xyh` to have shape \(\.\.\., 3\)"):
        ground.to_ecef([1.0, 2.0])


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("EPSG:99999", r"'EPSG:99999'.*crs not found"),
        ("not a crs", r"'not a crs'.*pyproj"),
        ("EPSG:4978", r"Geocentric CRS.*horizontal projected or geographic"),
        ("EPSG:5621", r"Vertical CRS.*horizontal projected or geographic"),
        ("EPSG:32634+5621", r"Compound CRS.*horizontal projected or geographic"),
        ('LOCAL_CS["site",LOCAL_DATUM["d",0],UNIT["metre",1]]', r"Engineering CRS"),
    ],
)
def test_config_error_for_bad_crs(text, match):
    with pytest.raises(ConfigError, match=match):
        GroundCRS.from_user_input(text)


def test_bound_crs_keeps_its_datum_for_ecef():
    # A PROJ string with +towgs84 is a bound CRS: ECEF stays on its own ellipsoid.
    bound = GroundCRS.from_user_input(
        "+proj=tmerc +lat_0=0 +lon_0=21 +k=1 +x_0=500000 +y_0=0 +ellps=krass "
        "+towgs84=25,-141,-78.5,0,0.35,0.736,0 +units=m"
    )
    assert bound.crs is not None and bound.crs.is_bound
    llh = bound.to_geodetic([500_000.0, 5_540_000.0, 0.0])
    assert math.degrees(llh[1]) == pytest.approx(21.0, abs=1e-12)
    cart = Transformer.from_pipeline("+proj=cart +ellps=krass")
    expected = cart.transform(21.0, math.degrees(llh[0]), 0.0)
    np.testing.assert_allclose(bound.to_ecef([500_000.0, 5_540_000.0, 0.0]), expected, atol=1e-6)


@pytest.mark.parametrize("text", ["local", "LOCAL", "  Local "])
def test_local_ground_system(text):
    local = GroundCRS.from_user_input(text)
    assert local.is_local and local.crs is None and local.name == "local"
    assert not local.is_geographic and local.ellipsoid is None
    for method in (
        local.to_ecef,
        local.from_ecef,
        local.to_geodetic,
        local.to_wgs84_lonlat,
        local.meridian_convergence,
    ):
        with pytest.raises(GeometryError, match=r"needs? a real CRS") as info:
            method([[0.0, 0.0, 0.0]])
        assert isinstance(info.value, ValueError) and not isinstance(info.value, ConfigError)
    with pytest.raises(ValueError, match="MEAN_EARTH_RADIUS"):
        gaussian_mean_radius(0.5, local)


def test_ground_crs_properties():
    utm = GroundCRS.from_user_input("EPSG:32634")
    assert not utm.is_local and not utm.is_geographic
    assert utm.name == "WGS 84 / UTM zone 34N"
    # WGS 84: a = 6378137 m, 1/f = 298.257223563 (NIMA TR8350.2, Table 3.1).
    assert utm.ellipsoid == (6378137.0, 298.257223563)
    assert GroundCRS.from_user_input("EPSG:4326").is_geographic
    # DHDN uses Bessel 1841: a = 6377397.155 m, 1/f = 299.1528128 (EPSG:7004).
    assert GroundCRS.from_user_input("EPSG:31468").ellipsoid == (6377397.155, 299.1528128)
    assert GroundCRS.from_user_input("EPSG:32634") == utm
    assert GroundCRS.from_user_input(utm) is utm


def test_to_wgs84_lonlat_sanity():
    utm = GroundCRS.from_user_input("EPSG:32634")
    # On the central meridian of zone 34 (21 E) easting is the false easting 500000 m.
    lonlat = utm.to_wgs84_lonlat([[500_000.0, 5_540_000.0, 123.0], [600_000.0, 5_540_000.0, 0.0]])
    assert lonlat.shape == (2, 2)
    assert lonlat[0, 0] == pytest.approx(21.0, abs=1e-9)
    assert 49.9 < lonlat[0, 1] < 50.1 and lonlat[1, 0] > 21.0
    # ETRF2000-PL and WGS 84 differ by well under a metre (< 1e-5 degree).
    pl = GroundCRS.from_user_input("EPSG:2180")
    xyh = _points_in("EPSG:2180", 5)
    llh = pl.to_geodetic(xyh)
    np.testing.assert_allclose(
        pl.to_wgs84_lonlat(xyh), np.degrees(llh[:, [1, 0]]), rtol=0, atol=1e-5
    )
    # DHDN is shifted against WGS 84 by roughly 100-200 m in Germany: a datum transformation
    # is applied here (and only here).
    gk = GroundCRS.from_user_input("EPSG:31468")
    xyh = _points_in("EPSG:31468", 5)
    llh = gk.to_geodetic(xyh)
    shift = np.degrees(llh[:, [1, 0]]) - gk.to_wgs84_lonlat(xyh)
    metres = np.hypot(shift[:, 0] * 111_000 * np.cos(llh[:, 0]), shift[:, 1] * 111_000)
    assert np.all((metres > 50.0) & (metres < 300.0))
    assert "DHDN" in gk.wgs84_operation  # e.g. "... + DHDN to WGS 84 (2) + ..."


def test_meridian_convergence_sign_and_size():
    utm = GroundCRS.from_user_input("EPSG:32634")
    # Geodetic north as seen on the grid, by finite differences of the projection (pyproj).
    to_grid = Transformer.from_crs("EPSG:4326", "EPSG:32634", always_xy=True)
    rng = np.random.default_rng(SEED)
    lon = rng.uniform(18.5, 23.5, 30)
    lat = rng.uniform(45.0, 55.0, 30)
    e0, n0 = to_grid.transform(lon, lat)
    e1, n1 = to_grid.transform(lon, lat + 1e-5)
    north_in_grid = np.arctan2(e1 - e0, n1 - n0)
    gamma = utm.meridian_convergence(np.column_stack([e0, n0]))
    # gamma is grid north clockwise from true north: true north's grid bearing is -gamma.
    np.testing.assert_allclose(gamma, -north_in_grid, rtol=0, atol=1e-7)
    # Positive east of the central meridian (21 E) in the northern hemisphere, and close to
    # the first-order value (lon - lon0) sin(lat) (e.g. Snyder 1987, eq. 8-19 ff.).
    assert np.all(np.sign(gamma) == np.sign(lon - 21.0))
    np.testing.assert_allclose(gamma, np.radians(lon - 21.0) * np.sin(np.radians(lat)), atol=2e-4)
    # Straight from pyproj's factors at one point.
    factors = Proj(CRS("EPSG:32634")).get_factors(23.0, 50.0)
    point = np.array(to_grid.transform(23.0, 50.0))
    assert utm.meridian_convergence(point) == pytest.approx(
        math.radians(factors.meridian_convergence), abs=1e-12
    )
    assert utm.meridian_convergence([500_000.0, 5_540_000.0]) == pytest.approx(0.0, abs=1e-12)
    assert np.all(WGS84.meridian_convergence([[21.0, 50.0, 0.0], [25.0, 60.0, 0.0]]) == 0.0)
    # Poland CS92 (northing-first CRS, always_xy input): east of 19 E gives positive gamma.
    pl = GroundCRS.from_user_input("EPSG:2180")
    assert pl.meridian_convergence([700_000.0, 500_000.0]) > 0.0
    assert pl.meridian_convergence([300_000.0, 500_000.0]) < 0.0


# --------------------------------------------------------------------------- ENU helpers


@pytest.mark.parametrize("shape", [(), (5,), (2, 3)], ids=["scalar", "vector", "stack"])
def test_enu_rotation_matches_pyproj_and_broadcasts(shape):
    rng = np.random.default_rng(SEED)
    lat = rng.uniform(-1.5, 1.5, shape)
    lon = rng.uniform(-3.1, 3.1, shape)
    r = enu_rotation(lat, lon)
    assert r.shape == (*shape, 3, 3)
    np.testing.assert_allclose(
        r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-15
    )
    for b, l_, m in zip(np.ravel(lat), np.ravel(lon), r.reshape(-1, 3, 3), strict=True):
        topo = topocentric(math.degrees(b), math.degrees(l_), 0.0)
        origin = WGS84.geodetic2ecef([b, l_, 0.0])
        # Images of origin + unit vectors are the columns of pyproj's ECEF -> ENU rotation.
        columns = enu_of(topo, origin + np.eye(3))
        np.testing.assert_allclose(m, columns.T, rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        enu_rotation(45.0, 10.0, degrees=True), enu_rotation(np.pi / 4, np.radians(10.0))
    )


def test_azimuth_helpers():
    quarter = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 5.0], [0.0, -1.0, 0.0], [-1.0, 0.0, 0.0]])
    np.testing.assert_allclose(
        azimuth_from_local_enu(quarter), [0.0, np.pi / 2, np.pi, 1.5 * np.pi]
    )
    with pytest.raises(ValueError, match="horizontal component"):
        azimuth_from_local_enu([0.0, 0.0, 1.0])
    frame = LocalTangentFrame.at(50.0, 21.0, 100.0, 200.0, crs=WGS84, degrees=True)
    assert math.degrees(frame.azimuth_of([1.0, 0.0, 0.0])) == pytest.approx(200.0)
    assert math.degrees(frame.azimuth_of([0.0, 1.0])) == pytest.approx(110.0)  # Y is left of X
    # enu2local is the frame's rotation expressed in ENU.
    np.testing.assert_allclose(
        frame.enu2local,
        frame.rotation @ enu_rotation(frame.latitude, frame.longitude).T,
        atol=1e-15,
    )


# --------------------------------------------------------------------------- frame API


def test_from_ecef_centroid_is_b142():
    utm = GroundCRS.from_user_input("EPSG:32634")
    xyh = _points_in("EPSG:32634", 30)
    ecef = utm.to_ecef(xyh)
    before = ecef.copy()
    frame = LocalTangentFrame.from_ecef_centroid(ecef, 0.5, crs=utm)
    np.testing.assert_array_equal(ecef, before)
    np.testing.assert_allclose(frame.origin_ecef, ecef.mean(axis=0), rtol=0, atol=1e-9)
    lat, lon, _ = utm.ecef2geodetic(ecef.mean(axis=0))
    assert (frame.latitude, frame.longitude, frame.azimuth) == (lat, lon, 0.5)
    # The centroid is the origin of the frame: control coordinates there average to zero.
    np.testing.assert_allclose(frame.ecef2local(ecef).mean(axis=0), 0.0, atol=1e-6)
    with pytest.raises(ValueError, match="finite"):
        LocalTangentFrame.from_ecef_centroid(np.vstack([ecef, [np.nan] * 3]), 0.0, crs=utm)
    with pytest.raises(ValueError, match="at least one"):
        LocalTangentFrame.from_ecef_centroid(np.empty((0, 3)), 0.0, crs=utm)


def test_with_azimuth_and_immutability():
    frame = LocalTangentFrame.at(42.7, 23.3, 600.0, 30.0, crs=WGS84, degrees=True)
    turned = frame.with_azimuth(math.radians(120.0))
    np.testing.assert_array_equal(turned.origin_ecef, frame.origin_ecef)
    assert turned.latitude == frame.latitude and turned.longitude == frame.longitude
    # Turning A0 by +90 degrees: new X = old -Y... i.e. new X is old X rotated clockwise.
    np.testing.assert_allclose(turned.rotation[0], -frame.rotation[1], atol=1e-15)
    np.testing.assert_allclose(turned.rotation[1], frame.rotation[0], atol=1e-15)
    with pytest.raises(AttributeError):
        frame.azimuth = 0.0  # type: ignore[misc]
    with pytest.raises(ValueError):
        frame.rotation[0, 0] = 1.0
    origin = np.array([1.0, 2.0, 3.0])
    LocalTangentFrame(origin, 0.1, 0.2, 0.3).origin_ecef  # noqa: B018
    np.testing.assert_array_equal(origin, [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="origin_ecef"):
        LocalTangentFrame(np.zeros(2), 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="latitude"):
        LocalTangentFrame(np.zeros(3), 2.0, 0.0, 0.0)


# --------------------------------------------------------------------------- curvature


def test_earth_curvature_is_the_sphere_sagitta_to_second_order():
    r = 6_371_000.0
    d = 10_000.0
    # Exact drop of a sphere below its tangent plane at horizontal distance D, written
    # without cancellation: R - sqrt(R² - D²) = D² / (R + sqrt(R² - D²)).
    exact = d * d / (r + math.sqrt(r * r - d * d))
    approx = float(earth_curvature_correction(d, r))
    next_term = d**4 / (8 * r**3)  # 4.8 micrometres
    assert exact - approx == pytest.approx(next_term, rel=1e-3)
    assert abs(exact - approx - next_term) < d**6 / (16 * r**5) * 1.01
    # The sizes quoted in docs/geodesy.md: 7.8 cm at 1 km, 7.8 m at 10 km.
    assert float(earth_curvature_correction(1_000.0, r)) == pytest.approx(0.0785, abs=5e-5)
    assert approx == pytest.approx(7.848, abs=5e-4)
    np.testing.assert_allclose(earth_curvature_correction([0.0, 2000.0], r), [0.0, 4e6 / (2 * r)])
    with pytest.raises(ValueError, match="radius"):
        earth_curvature_correction(1.0, 0.0)


def test_gaussian_mean_radius():
    utm = GroundCRS.from_user_input("EPSG:32634")
    # WGS 84 (NIMA TR8350.2, Table 3.3): semi-minor axis b = 6356752.3142 m and polar radius
    # of curvature c = a²/b = 6399593.6258 m; sqrt(M N) is b at the equator, c at the poles.
    assert gaussian_mean_radius(0.0, utm) == pytest.approx(6356752.3142, abs=1e-4)
    assert gaussian_mean_radius(90.0, utm, degrees=True) == pytest.approx(6399593.6258, abs=1e-4)
    # Against sqrt(M N) from pyproj's Geod (a, f) written the long way.
    geod = CRS("EPSG:32634").get_geod()
    lat = np.radians([10.0, 45.0, 52.3])
    e2 = geod.es
    m = geod.a * (1 - e2) / (1 - e2 * np.sin(lat) ** 2) ** 1.5
    n = geod.a / np.sqrt(1 - e2 * np.sin(lat) ** 2)
    np.testing.assert_allclose(gaussian_mean_radius(lat, utm), np.sqrt(m * n), rtol=1e-14)
    assert gaussian_mean_radius(0.9, "EPSG:31468") < gaussian_mean_radius(0.9, utm)
    # GRS 80 mean radius R1 (Moritz 2000): 6371008.7714 m.
    assert MEAN_EARTH_RADIUS == 6371008.7714
