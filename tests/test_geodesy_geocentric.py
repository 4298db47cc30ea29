"""The geocentric CRS of a ground CRS's datum: the registered one from PROJ's
database where there is one, else one built from PROJJSON; both give the same
PROJ pipeline and the same ECEF coordinates to the last bit."""

from __future__ import annotations

import numpy as np
import pytest
from pyproj import CRS, Transformer

from strip_aerotri import geodesy
from strip_aerotri.geodesy import GroundCRS

# projected and geographic CRSs on datum ensembles (WGS 84, ETRS89), on
# plain datums (RGF93, CH1903+, OSGB 1936, DHDN) and one given as a PROJ string
CODES = [
    "EPSG:32634",
    "EPSG:25832",
    "EPSG:4326",
    "EPSG:4258",
    "EPSG:3857",
    "EPSG:2154",
    "EPSG:2056",
    "EPSG:27700",
    "EPSG:31467",
    "+proj=utm +zone=34 +datum=WGS84 +units=m",
]


def _crs3d(code: str) -> tuple[CRS, CRS]:
    crs3d = CRS.from_user_input(code).to_3d()
    geodetic = crs3d.geodetic_crs
    assert geodetic is not None
    return crs3d, geodetic.to_3d()


def _sample(crs3d: CRS, n: int = 2000) -> np.ndarray:
    """Points inside the CRS's area of use (UTM zone 34 north's where it has
    none), heights -100 to 3000 m."""
    area = crs3d.area_of_use
    west, south, east, north = (18.0, 0.0, 24.0, 84.0) if area is None else area.bounds
    rng = np.random.default_rng(7)
    lon = rng.uniform(west, east, n)
    lat = rng.uniform(max(south, -80.0), min(north, 80.0), n)
    h = rng.uniform(-100.0, 3000.0, n)
    to_crs = Transformer.from_crs(CRS.from_epsg(4326), crs3d.geodetic_crs, always_xy=True)
    lon, lat = to_crs.transform(lon, lat)
    forward = Transformer.from_crs(crs3d.geodetic_crs, crs3d, always_xy=True)
    x, y = forward.transform(lon, lat)
    return np.column_stack([x, y, h])


@pytest.mark.parametrize("code", CODES)
def test_registered_geocentric_gives_the_pipeline_of_the_projjson_one(code):
    crs3d, geodetic3d = _crs3d(code)
    chosen = geodesy._geocentric_of(geodetic3d)
    built = geodesy._geocentric_from_json(geodetic3d)
    assert chosen.is_geocentric
    for source in (crs3d, geodetic3d):
        a = Transformer.from_crs(source, chosen, always_xy=True)
        b = Transformer.from_crs(source, built, always_xy=True)
        assert a.definition == b.definition
        assert "cart" in a.definition and "helmert" not in a.definition  # no datum shift
    xyz = _sample(crs3d)
    a = np.column_stack(Transformer.from_crs(crs3d, chosen, always_xy=True).transform(*xyz.T))
    b = np.column_stack(Transformer.from_crs(crs3d, built, always_xy=True).transform(*xyz.T))
    assert np.all(np.isfinite(a))
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    ("code", "expected"),
    [
        ("EPSG:32634", ("EPSG", "4978")),
        ("EPSG:4326", ("EPSG", "4978")),
        ("EPSG:25832", ("EPSG", "4936")),
    ],
)
def test_registered_geocentric_is_the_datum_s_own(code, expected):
    _, geodetic3d = _crs3d(code)
    registered = geodesy._registered_geocentric(geodetic3d)
    assert registered is not None
    assert registered.to_authority() == expected


def test_unregistered_geodetic_crs_falls_back_to_projjson():
    # a custom ellipsoid: no authority code, so no database look-up
    custom = CRS.from_proj4("+proj=longlat +a=6378000 +rf=300 +no_defs").to_3d()
    assert geodesy._registered_geocentric(custom) is None
    geocentric = geodesy._geocentric_of(custom)
    assert geocentric.is_geocentric
    x, y, z = Transformer.from_crs(custom, geocentric, always_xy=True).transform(0.0, 0.0, 0.0)
    assert (x, y, z) == pytest.approx((6378000.0, 0.0, 0.0), abs=1e-6)


def test_unreadable_database_falls_back_to_projjson(monkeypatch, tmp_path):
    xyz = _sample(_crs3d("EPSG:32634")[0], 50)
    expected = GroundCRS.from_user_input("EPSG:32634").to_ecef(xyz)
    monkeypatch.setattr("pyproj.datadir.get_data_dir", lambda: str(tmp_path))
    _, geodetic3d = _crs3d("EPSG:32634")
    assert geodesy._registered_geocentric(geodetic3d) is None
    ground = GroundCRS.from_user_input("EPSG:32634")
    np.testing.assert_array_equal(ground.to_ecef(xyz), expected)
    np.testing.assert_allclose(ground.from_ecef(expected), xyz, rtol=0, atol=1e-6)



def test_the_database_is_found_along_the_whole_search_path(monkeypatch, tmp_path):
    # pyproj's data directory may be a list (PROJ_DATA=a:b, or pyproj's own
    # directory after the user's); proj.db is the first one found along it
    import os

    from pyproj.datadir import get_data_dir

    real = get_data_dir()
    _, geodetic3d = _crs3d("EPSG:32634")
    expected = geodesy._registered_geocentric(geodetic3d)
    assert expected is not None
    empty = [tmp_path / "a", tmp_path / "b"]
    for folder in empty:
        folder.mkdir()
    crs3d = _crs3d("EPSG:32634")[0]
    xyz = _sample(crs3d, 200)
    ecef = Transformer.from_crs(crs3d, expected, always_xy=True).transform(*xyz.T)
    for paths in ([*empty, real], [empty[0], real, empty[1]], ["", real]):
        listed = os.pathsep.join(map(str, paths))
        monkeypatch.setattr("pyproj.datadir.get_data_dir", lambda listed=listed: listed)
        found = geodesy._registered_geocentric(geodetic3d)
        assert found is not None and found == expected, listed
        again = Transformer.from_crs(crs3d, found, always_xy=True).transform(*xyz.T)
        np.testing.assert_array_equal(again, ecef)  # the same coordinates to the bit
    monkeypatch.setattr("pyproj.datadir.get_data_dir", lambda: os.pathsep.join(map(str, empty)))
    assert geodesy._registered_geocentric(geodetic3d) is None

def test_transformers_built_once_per_ground_crs(monkeypatch):
    built: list[tuple[object, object]] = []
    from_crs = Transformer.from_crs

    def counted(source, target, **kwargs):
        built.append((source, target))
        return from_crs(source, target, **kwargs)

    monkeypatch.setattr(Transformer, "from_crs", staticmethod(counted))
    ground = GroundCRS.from_user_input("EPSG:32634")
    xyz = np.array([[500000.0, 5000000.0, 100.0], [501000.0, 5001000.0, 120.0]])
    for _ in range(3):
        ecef = ground.to_ecef(xyz)
        ground.from_ecef(ecef)
        llh = ground.to_geodetic(xyz)
        ground.geodetic2ecef(llh)
        ground.ecef2geodetic(ecef)
        ground.to_wgs84_lonlat(xyz)
    assert len(built) == 4  # geocentric, geodetic, geodetic2ecef, wgs84
