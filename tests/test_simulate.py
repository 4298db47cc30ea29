"""Strip simulator: collinearity truth, geometry, CRS round trips, project files.

The simulator is the ground truth of the other tests, so these tests check it
against independent oracles: a collinearity projection written here, the
closed-form geodetic -> geocentric formulas, pyproj's CRS transformations and
meridian convergence, and the project format of formats.md.
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import math
import re
import tomllib

import numpy as np
import pytest
from pyproj import CRS, Proj, Transformer

from strip_aerotri.observations import ControlType
from strip_aerotri.simulate import PRESETS, SimulatedStrip, StripPreset, simulate_strip

# formats.md: the keys strip.toml may hold, per table.
TOML_KEYS = {
    "strip": {"name", "photos"},
    "camera": {"principal_distance_mm", "principal_point_mm"},
    "images": {"file"},
    "control": {"file", "crs"},
    "straight_line": {"points", "weight"},
    "adjustment": {
        "route",
        "polynomial",
        "relative_orientation",
        "intersection",
        "scale_transfer",
    },
    "output": {"directory"},
}


def _project(strip: SimulatedStrip, points_local: np.ndarray | None = None) -> np.ndarray:
    """Collinearity written out here: x = -c v_x / v_z, y = -c v_y / v_z, v = R.T (X - S)."""
    obs, truth = strip.observations, strip.truth
    pts = truth.points_local if points_local is None else points_local
    c = obs.principal_distance
    out = np.empty((obs.photo.size, 2))
    for k in range(obs.n_photos):
        rows = obs.photo == k
        v = (pts[obs.point[rows]] - truth.photo_centres_local[k]) @ truth.photo_rotations_local[k]
        out[rows, 0] = -c * v[:, 0] / v[:, 2]
        out[rows, 1] = -c * v[:, 1] / v[:, 2]
    return out


def _visibility(strip: SimulatedStrip) -> np.ndarray:
    obs = strip.observations
    vis = np.zeros((obs.n_photos, obs.n_points), dtype=bool)
    vis[obs.photo, obs.point] = True
    return vis


def _geodetic2ecef(lon_deg, lat_deg, h, a, rf):
    """Closed-form geodetic -> geocentric (any text on geodesy, e.g. Hofmann-Wellenhof)."""
    lam, phi = np.radians(lon_deg), np.radians(lat_deg)
    e2 = (2.0 - 1.0 / rf) / rf
    n = a / np.sqrt(1.0 - e2 * np.sin(phi) ** 2)
    return np.column_stack(
        [
            (n + h) * np.cos(phi) * np.cos(lam),
            (n + h) * np.cos(phi) * np.sin(lam),
            (n * (1.0 - e2) + h) * np.sin(phi),
        ]
    )


def _enu_rows(lon_deg, lat_deg):
    lam, phi = math.radians(lon_deg), math.radians(lat_deg)
    return np.array(
        [
            [-math.sin(lam), math.cos(lam), 0.0],
            [-math.sin(phi) * math.cos(lam), -math.sin(phi) * math.sin(lam), math.cos(phi)],
            [math.cos(phi) * math.cos(lam), math.cos(phi) * math.sin(lam), math.sin(phi)],
        ]
    )


# ---------------------------------------------------------------------------
# Collinearity and observations


@pytest.mark.parametrize("preset", ["film", "drone", "corridor"])
def test_noise_free_observations_are_the_collinearity_projection_of_the_truth(preset):
    strip = simulate_strip(8, preset=preset, image_noise_mm=0.0, seed=3)
    np.testing.assert_allclose(strip.observations.xy, _project(strip), rtol=0, atol=1e-12)
    # noise 0 still gives usable weights: sigma 5 µm (module contract)
    np.testing.assert_array_equal(strip.observations.sigma, 0.005)


def test_systematic_errors_are_applied_after_collinearity():
    k1, shrink = 2e-6, 0.9995  # mm^-2; scale of y
    strip = simulate_strip(6, image_noise_mm=0.0, systematic_k1=k1, film_shrink_y=shrink, seed=4)
    xy = _project(strip)
    radial = 1.0 + k1 * (xy**2).sum(axis=1)
    expected = np.column_stack([xy[:, 0] * radial, xy[:, 1] * radial * shrink])
    np.testing.assert_allclose(strip.observations.xy, expected, rtol=0, atol=1e-12)
    # and they really move the points: at r = 100 mm, k1 r^3 = 2 mm
    assert np.abs(strip.observations.xy - xy).max() > 0.01


def test_image_noise_has_the_requested_standard_deviation():
    strip = simulate_strip(20, image_noise_mm=0.005, seed=5)
    resid = strip.observations.xy - _project(strip)
    k = resid.size
    assert k > 1000
    # sample sd of k normal values has relative sd 1/sqrt(2k) < 2 %: allow 3 of them
    assert abs(resid.std() / 0.005 - 1.0) < 0.06
    assert abs(resid.mean()) < 3 * 0.005 / math.sqrt(k)
    np.testing.assert_array_equal(strip.observations.sigma, 0.005)


@pytest.mark.parametrize(
    ("preset", "n_photos"),
    [("film", 5), ("film", 12), ("film", 50), ("drone", 12), ("corridor", 12)],
    ids=["film5", "film12", "film50", "drone12", "corridor12"],
)
def test_every_point_is_seen_on_two_photos_inside_the_format(preset, n_photos):
    strip = simulate_strip(n_photos, preset=preset, seed=1)
    obs = strip.observations
    assert obs.photo_ids == tuple(str(1001 + i) for i in range(n_photos))
    assert obs.point_ids == tuple(f"P{i + 1:04d}" for i in range(obs.n_points))
    assert np.bincount(obs.point, minlength=obs.n_points).min() >= 2
    assert np.bincount(obs.photo, minlength=n_photos).min() > 0
    half = np.array(strip.preset.format_mm) / 2.0
    assert np.all(np.abs(obs.xy) <= half + 5 * strip.preset.image_noise_mm)
    # in front of every camera that sees it
    truth = strip.truth
    depth = np.einsum(
        "ki,ki->k",
        truth.points_local[obs.point] - truth.photo_centres_local[obs.photo],
        truth.photo_rotations_local[obs.photo][:, :, 2],
    )
    assert np.all(depth < 0)
    assert truth.points_local.shape == (obs.n_points, 3)


@pytest.mark.parametrize(
    ("preset", "n_photos", "crs"),
    [("film", 40, "EPSG:32634"), ("drone", 60, "EPSG:32634"), ("film", 25, "EPSG:4326")],
    ids=["film40", "drone60", "film25-geographic"],
)
def test_each_point_is_observed_on_every_photo_that_sees_it(preset, n_photos, crs):
    # The simulator projects a point only into photos near it along the strip;
    # the full (photos x points) projection here must find no photo it missed.
    strip = simulate_strip(n_photos, preset=preset, crs=crs, image_noise_mm=0.0, seed=2)
    truth, obs = strip.truth, strip.observations
    v = np.einsum(
        "mji,mpj->mpi",
        truth.photo_rotations_local,
        truth.points_local[None] - truth.photo_centres_local[:, None],
    )
    c = obs.principal_distance
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = -c * v[..., 0] / v[..., 2], -c * v[..., 1] / v[..., 2]
    half = np.array(strip.preset.format_mm) / 2.0
    sees = (v[..., 2] < 0) & (np.abs(x) <= half[0]) & (np.abs(y) <= half[1])
    np.testing.assert_array_equal(_visibility(strip), sees)


def test_a_strip_of_two_thousand_photos_is_simulated():
    strip = simulate_strip(2000, preset="drone", seed=0)
    assert strip.observations.n_photos == 2000
    assert np.bincount(strip.observations.photo, minlength=2000).min() >= 6  # R4: six tie points


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize(
    ("preset", "n_photos", "minimum"),
    [("film", 12, 6), ("film", 50, 6), ("drone", 20, 6)],
    ids=["film12", "film50", "drone20"],
)
def test_every_triple_overlap_has_tie_points(preset, n_photos, minimum, seed):
    # R4: 2-3 points in each of the Gruber zones -> >= 6 ties per triple overlap
    vis = _visibility(simulate_strip(n_photos, preset=preset, seed=seed))
    ties = (vis[:-2] & vis[1:-1] & vis[2:]).sum(axis=1)
    assert ties.min() >= minimum, ties


@pytest.mark.parametrize("preset", ["film", "drone"])
def test_forward_overlap_and_flying_height_follow_the_preset(preset):
    strip = simulate_strip(12, preset=preset, seed=2)
    pre, truth = strip.preset, strip.truth
    steps = np.diff(truth.photo_centres_local[:, :2], axis=0)
    base = np.linalg.norm(steps, axis=1).mean()
    footprint = pre.format_mm[0] * pre.flying_height_m / pre.principal_distance_mm
    assert abs((1.0 - base / footprint) - pre.forward_overlap) < 0.01
    # film: 60 % of 230 mm at 1:8000 -> base 736 m (the classic 1:8000 layout)
    if preset == "film":
        assert abs(base - 0.4 * 230.0 * 8.0) < 5.0
    height = truth.photo_centres_crs[:, 2] - pre.terrain_height_m
    assert np.all(np.abs(height - pre.flying_height_m) <= pre.height_wander_m + 1e-9)
    # terrain within mean ± relief (ellipsoidal heights)
    assert np.all(np.abs(truth.points_crs[:, 2] - pre.terrain_height_m) <= pre.relief_m + 1e-6)
    # the ground really is at about one flying height below the cameras
    below = truth.photo_centres_local[:, 2].mean() - truth.points_local[:, 2].mean()
    assert abs(below / pre.flying_height_m - 1.0) < 0.1


def test_photo_rotations_are_near_vertical_along_the_heading():
    strip = simulate_strip(30, heading_deg=200.0, seed=6)
    rot = strip.truth.photo_rotations_local
    np.testing.assert_allclose(
        rot @ np.swapaxes(rot, -1, -2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-14
    )
    np.testing.assert_allclose(np.linalg.det(rot), 1.0, atol=1e-14)
    # camera axis (image -z) within the 2-sigma truncated tilts (3° each of omega, phi)
    tilt = np.degrees(np.arccos(rot[:, 2, 2]))  # angle between -z_image and local down
    assert np.all(tilt < 3.0 * math.sqrt(2) + 0.2)
    assert tilt.max() > 0.3  # not all vertical
    # image x in plan points along the heading (kappa noise 2°, truncated at 4°)
    azimuth = np.degrees(np.arctan2(rot[:, 0, 0], rot[:, 1, 0])) % 360.0
    assert np.all(np.abs(azimuth - 200.0) < 4.0 + 0.5)


def test_zero_attitude_photos_are_vertical_at_their_own_nadir():
    # R = T Rz(90° - heading): camera axis along the ellipsoid normal below the
    # photo, image x at the heading from that point's north
    heading = 75.0
    strip = simulate_strip(
        50, heading_deg=heading, attitude_sigma_deg=0.0, kappa_sigma_deg=0.0, seed=16
    )
    truth = strip.truth
    proj = CRS.from_user_input(strip.crs)
    lon, lat = Transformer.from_crs(proj, proj.geodetic_crs, always_xy=True).transform(
        truth.photo_centres_crs[:, 0], truth.photo_centres_crs[:, 1]
    )
    lam, phi = np.radians(lon), np.radians(lat)
    up = np.column_stack([np.cos(phi) * np.cos(lam), np.cos(phi) * np.sin(lam), np.sin(phi)])
    north = np.column_stack([-np.sin(phi) * np.cos(lam), -np.sin(phi) * np.sin(lam), np.cos(phi)])
    east = np.column_stack([-np.sin(lam), np.cos(lam), np.zeros_like(lam)])
    ecef2enu = truth.local_to_ecef.ecef2enu
    rot = truth.photo_rotations_local
    h = math.radians(heading)
    np.testing.assert_allclose(rot[:, :, 2], up @ ecef2enu.T, rtol=0, atol=1e-12)
    x_axis = (math.sin(h) * east + math.cos(h) * north) @ ecef2enu.T
    np.testing.assert_allclose(rot[:, :, 0], x_axis, rtol=0, atol=1e-12)
    # the strip is long enough for the vertical to turn by > 0.1° at its ends
    assert np.degrees(np.arccos(rot[:, 2, 2])).max() > 0.1


@pytest.mark.parametrize(
    ("crs", "centre"),
    [("EPSG:32634", (23.5, 52.0)), ("EPSG:2180", None), ("EPSG:32634", (18.5, -30.0))],
    ids=["utm34-east", "pl1992", "utm34-south-west"],
)
def test_heading_200_strip_flies_the_right_way(crs, centre):
    heading = 200.0
    strip = simulate_strip(12, crs=crs, centre_lonlat=centre, heading_deg=heading, seed=7)
    truth = strip.truth
    loc, grid = truth.photo_centres_local, truth.photo_centres_crs
    az_local = math.degrees(math.atan2(loc[-1, 0] - loc[0, 0], loc[-1, 1] - loc[0, 1])) % 360
    # first and last photo wander <= 10 m across over ~8 km: 0.15°
    assert abs(az_local - heading) < 0.15
    az_grid = math.degrees(math.atan2(grid[-1, 0] - grid[0, 0], grid[-1, 1] - grid[0, 1])) % 360
    lon, lat, _ = truth.origin_lonlat_h
    gamma = Proj(CRS(crs)).get_factors(lon, lat).meridian_convergence  # pyproj oracle
    assert abs(az_grid - (heading - gamma)) < 0.15
    # consecutive photos step forward along the heading, never back
    ahead = np.array([math.sin(math.radians(heading)), math.cos(math.radians(heading))])
    assert np.all(np.diff(loc[:, :2], axis=0) @ ahead > 0)


# ---------------------------------------------------------------------------
# Geodesy


@pytest.mark.parametrize(
    "crs", ["EPSG:32634", "EPSG:2180", "EPSG:31468", "EPSG:2177", "EPSG:4326"]
)
def test_crs_truth_round_trips_to_local(crs):
    strip = simulate_strip(12, crs=crs, seed=8)
    truth = strip.truth
    proj = CRS.from_user_input(crs)
    ell = proj.ellipsoid
    a, rf = ell.semi_major_metre, ell.inverse_flattening
    assert truth.ellipsoid == pytest.approx((a, rf), rel=1e-15)
    to_geo = Transformer.from_crs(proj, proj.geodetic_crs, always_xy=True)
    lon0, lat0, h0 = truth.origin_lonlat_h
    origin = _geodetic2ecef(lon0, lat0, h0, a, rf)[0]
    rows = _enu_rows(lon0, lat0)
    np.testing.assert_allclose(truth.local_to_ecef.origin_ecef, origin, rtol=0, atol=1e-6)
    np.testing.assert_allclose(truth.local_to_ecef.ecef2enu, rows, rtol=0, atol=1e-15)
    for crs_xyz, local in [
        (truth.points_crs, truth.points_local),
        (truth.photo_centres_crs, truth.photo_centres_local),
    ]:
        lon, lat = to_geo.transform(crs_xyz[:, 0], crs_xyz[:, 1])
        ecef = _geodetic2ecef(np.asarray(lon), np.asarray(lat), crs_xyz[:, 2], a, rf)
        np.testing.assert_allclose((ecef - origin) @ rows.T, local, rtol=0, atol=1e-3)
        np.testing.assert_allclose(truth.local_to_ecef.local2ecef(local), ecef, atol=1e-3)
        np.testing.assert_allclose(truth.local_to_ecef.ecef2local(ecef), local, atol=1e-3)


def test_default_centre_is_the_middle_of_the_area_of_use():
    strip = simulate_strip(5, crs="EPSG:2180", seed=0)
    west, south, east, north = CRS("EPSG:2180").area_of_use.bounds
    lon, lat, _ = strip.truth.origin_lonlat_h
    assert lon == pytest.approx((west + east) / 2) and lat == pytest.approx((south + north) / 2)


def test_local_crs_uses_the_local_frame_itself():
    strip = simulate_strip(12, crs="local", seed=8)
    truth = strip.truth
    np.testing.assert_array_equal(truth.points_crs, truth.points_local)
    np.testing.assert_array_equal(truth.photo_centres_crs, truth.photo_centres_local)
    assert truth.origin_lonlat_h[:2] == (21.0, 52.0)
    assert strip.crs == "local"
    check = np.array([k is ControlType.CHECK for k in strip.control.kind])
    ids = np.array(strip.observations.point_ids)
    lookup = {p: i for i, p in enumerate(ids)}
    idx = [lookup[p] for p in np.array(strip.control.point_ids)[check]]
    np.testing.assert_array_equal(strip.control.xyz[check], truth.points_local[idx])


def test_earth_curvature_is_in_the_local_heights():
    # Flat terrain on the ellipsoid: local up = -D^2 / (2 R) (B(153)), D up to ~4 km
    strip = simulate_strip(12, crs="EPSG:32634", centre_lonlat=(21.0, 52.0), relief_m=0.0)
    pts = strip.truth.points_local
    d2 = (pts[:, :2] ** 2).sum(axis=1)
    # Gaussian mean radius at 52° N on WGS 84 ~ 6.38e6 m; direction-dependent radius
    # varies by < 0.4 %, i.e. < 5 mm on a 1.3 m drop
    np.testing.assert_allclose(pts[:, 2], -d2 / (2 * 6.38e6), rtol=0, atol=0.01)
    assert -pts[:, 2].min() > 0.5  # the drop is really there


# ---------------------------------------------------------------------------
# Control and straight lines


def _index(strip: SimulatedStrip, ids) -> np.ndarray:
    lookup = {p: i for i, p in enumerate(strip.observations.point_ids)}
    return np.array([lookup[p] for p in ids], dtype=np.intp)


def test_ends_layout_has_full_ends_and_middle_heights_plans_and_checks():
    m = 12
    strip = simulate_strip(m, control_noise_m=0.0, seed=9)
    ctrl, truth = strip.control, strip.truth
    kinds = np.array([k.value for k in ctrl.kind])
    ahead = np.array([math.sin(math.radians(75.0)), math.cos(math.radians(75.0)), 0.0])
    idx = _index(strip, ctrl.point_ids)
    along = truth.points_local[idx] @ ahead
    nadir_along = truth.photo_centres_local @ ahead
    full = kinds == "full"
    assert full.sum() == 6  # 2 across each end + 2 in the middle
    assert (np.abs(along[full, None] - nadir_along[[0, -1]]).min(axis=1) < 100).sum() == 4
    assert (kinds == "height").sum() >= 4 and (kinds == "plan").sum() >= 1
    # check points: all the other seen Gruber points except at the end nadirs
    assert (kinds == "check").sum() >= 6 * (m - 2) - 12
    check = kinds == "check"
    assert np.abs(along[check, None] - nadir_along[[0, -1]]).min() > 200
    # NaN where a coordinate is not given
    assert np.isnan(ctrl.xyz[kinds == "plan", 2]).all()
    assert np.isnan(ctrl.xyz[kinds == "height", :2]).all()
    assert not np.isnan(ctrl.xyz[full | check]).any()
    # without control noise every given coordinate is the truth
    given = ~np.isnan(ctrl.xyz)
    np.testing.assert_array_equal(ctrl.xyz[given], truth.points_crs[idx][given])
    assert len(set(ctrl.point_ids)) == len(ctrl.point_ids)
    assert not set(ctrl.point_ids) & {p for ids, _ in strip.lines for p in ids}


def test_control_noise_is_added_to_control_only():
    strip = simulate_strip(12, control_noise_m=0.02, crs="EPSG:32634", seed=10)
    ctrl, truth = strip.control, strip.truth
    idx = _index(strip, ctrl.point_ids)
    diff = ctrl.xyz - truth.points_crs[idx]
    check = np.array([k is ControlType.CHECK for k in ctrl.kind])
    np.testing.assert_array_equal(diff[check], 0.0)
    d = diff[~check][~np.isnan(diff[~check])]
    assert np.all(d != 0.0)
    assert np.abs(d).max() < 5 * 0.02 * 1.001  # UTM scale ~0.9996..1.0004
    np.testing.assert_array_equal(ctrl.sigma_xy, 0.02)
    np.testing.assert_array_equal(ctrl.sigma_h, 0.02)


@pytest.mark.parametrize(
    ("control", "kwargs", "n_full"),
    [("dense", {}, 2 * 9), ("every_k_models", {"control_every": 2}, 2 * 5)],
)
def test_other_control_layouts(control, kwargs, n_full):
    strip = simulate_strip(9, control=control, seed=11, **kwargs)
    kinds = [k.value for k in strip.control.kind]
    assert kinds.count("full") == n_full
    assert set(kinds) <= {"full", "check"}


def test_n_check_limits_the_check_points():
    strip = simulate_strip(12, n_check=5, seed=12)
    assert [k.value for k in strip.control.kind].count("check") == 5


def test_corridor_line_points_lie_on_one_vertical_plane():
    strip = simulate_strip(12, preset="corridor", seed=13)
    assert len(strip.lines) == 1
    ids, weight = strip.lines[0]
    assert weight == 100.0  # J §2.2: weight about 100 against 1 for control
    assert len(ids) >= 2 * 11 - 2  # ~2 per model
    pts = strip.truth.points_local[_index(strip, ids)]
    # a straight line in plan (ENU): fit, residuals at round-off level
    centred = pts[:, :2] - pts[:, :2].mean(axis=0)
    _, sv, _ = np.linalg.svd(centred, full_matrices=False)
    assert sv[1] / math.sqrt(len(ids)) < 1e-6
    assert np.ptp(pts[:, 2]) > 5.0  # heights follow the terrain
    assert not set(ids) & set(strip.control.point_ids)
    # the film preset has no line unless asked
    assert simulate_strip(6, seed=13).lines == ()
    assert len(simulate_strip(6, seed=13, line=True).lines) == 1


# ---------------------------------------------------------------------------
# Project files


def read_csv(path):
    with path.open(newline="", encoding="utf-8") as fh:
        rows = [r for r in csv.reader(fh) if r and not r[0].startswith("#")]
    return rows[0], rows[1:]


@pytest.mark.parametrize(
    ("preset", "crs", "route"),
    [
        ("corridor", "EPSG:2180", None),
        ("film", "local", "projected"),
        ("drone", "EPSG:4326", "geocentric"),
    ],
)
def test_write_project_follows_formats_md(tmp_path, preset, crs, route):
    strip = simulate_strip(7, preset=preset, crs=crs, seed=14)
    toml_path = strip.write_project(
        tmp_path / "proj", polynomial=2, route=route, name='A "q" \\ b'
    )
    assert toml_path == tmp_path / "proj" / "strip.toml"
    with toml_path.open("rb") as fh:
        doc = tomllib.load(fh)
    assert set(doc) <= set(TOML_KEYS)
    for table, value in doc.items():
        for entry in value if isinstance(value, list) else [value]:
            assert set(entry) <= TOML_KEYS[table], table
    assert doc["strip"]["name"] == 'A "q" \\ b'
    assert doc["strip"]["photos"] == list(strip.observations.photo_ids)
    assert doc["camera"]["principal_distance_mm"] == strip.observations.principal_distance
    assert doc["control"]["crs"] == crs
    assert doc["adjustment"]["polynomial"] == 2
    assert doc["adjustment"].get("route") == route
    lines = doc.get("straight_line", [])
    assert [(tuple(t["points"]), t["weight"]) for t in lines] == list(strip.lines)
    assert (len(lines) == 1) == (preset == "corridor")

    obs = strip.observations
    header, rows = read_csv(toml_path.parent / doc["images"]["file"])
    assert header[:4] == ["photo", "point", "x", "y"]
    assert len(rows) == obs.photo.size
    six = re.compile(r"^-?\d+\.\d{6}$")
    assert all(six.match(r[2]) and six.match(r[3]) for r in rows)
    assert [r[0] for r in rows] == [obs.photo_ids[i] for i in obs.photo]
    assert [r[1] for r in rows] == [obs.point_ids[i] for i in obs.point]
    xy = np.array([[float(r[2]), float(r[3])] for r in rows])
    np.testing.assert_allclose(xy, obs.xy, rtol=0, atol=5e-7)

    ctrl = strip.control
    header, rows = read_csv(toml_path.parent / doc["control"]["file"])
    assert header[:5] == ["point", "X", "Y", "H", "type"]
    assert [r[0] for r in rows] == list(ctrl.point_ids)
    assert [r[4] for r in rows] == [k.value for k in ctrl.kind]
    for r in rows:
        assert r[4] in {"full", "plan", "height", "check"}
        assert (r[3] == "") == (r[4] == "plan")
        assert (r[1] == "" and r[2] == "") == (r[4] == "height")
    xyz = np.array([[float(v) if v else np.nan for v in r[1:4]] for r in rows])
    tol = 5e-10 if crs == "EPSG:4326" else 5e-5  # 10 decimals of degrees / 4 of metres
    np.testing.assert_allclose(xyz[:, :2], ctrl.xyz[:, :2], rtol=0, atol=tol)
    np.testing.assert_allclose(xyz[:, 2], ctrl.xyz[:, 2], rtol=0, atol=5e-5)


def test_write_project_rejects_bad_options(tmp_path):
    strip = simulate_strip(5, crs="local", seed=0)
    with pytest.raises(ValueError, match="polynomial"):
        strip.write_project(tmp_path, polynomial=4)
    with pytest.raises(ValueError, match="route"):
        strip.write_project(tmp_path, route="bundle")
    with pytest.raises(ValueError, match="local"):
        strip.write_project(tmp_path, route="geocentric")
    assert not (tmp_path / "strip.toml").exists()
    path = strip.write_project(tmp_path, polynomial="auto")
    with path.open("rb") as fh:
        assert tomllib.load(fh)["adjustment"] == {"polynomial": "auto"}


# ---------------------------------------------------------------------------
# Determinism, sizes, inputs


def test_same_seed_same_strip_other_seed_other_strip():
    a, b = simulate_strip(10, seed=21), simulate_strip(10, seed=21)
    assert a.observations.point_ids == b.observations.point_ids
    np.testing.assert_array_equal(a.observations.xy, b.observations.xy)
    np.testing.assert_array_equal(a.truth.points_local, b.truth.points_local)
    np.testing.assert_array_equal(a.control.xyz, b.control.xyz)
    assert a.control.kind == b.control.kind
    c = simulate_strip(10, seed=22)
    assert not np.array_equal(c.truth.photo_centres_local, a.truth.photo_centres_local)


def test_inputs_and_presets_are_not_changed():
    before = copy.deepcopy(dict(PRESETS))
    centre = [21.0, 52.0]
    custom = dataclasses.replace(PRESETS["film"], extra_points_per_photo=2)
    custom_before = copy.deepcopy(custom)
    strip = simulate_strip(6, preset=custom, centre_lonlat=centre, gruber_points_per_zone=3)
    assert strip.preset.gruber_points_per_zone == 3 and strip.preset.extra_points_per_photo == 2
    assert custom == custom_before
    assert centre == [21.0, 52.0]
    assert dict(PRESETS) == before
    with pytest.raises(TypeError):
        PRESETS["film"] = custom  # type: ignore[index]
    with pytest.raises(dataclasses.FrozenInstanceError):
        PRESETS["film"].principal_distance_mm = 100.0  # type: ignore[misc]
    with pytest.raises(ValueError, match="read-only"):
        strip.truth.points_local[0, 0] = 0.0


def test_presets_hold_the_documented_values():
    film, drone = PRESETS["film"], PRESETS["drone"]
    # film: 152.87 mm, 230 x 230 mm, 1:8000 (brief of the simulator)
    assert film.principal_distance_mm == 152.87 and film.format_mm == (230.0, 230.0)
    assert film.flying_height_m == pytest.approx(1222.96)
    assert film.scale_m_per_mm == pytest.approx(8.0)
    assert film.gruber_y_mm == (75.0, 0.0, -75.0)
    # drone: 1" sensor 13.2 x 8.8 mm with the long side across, c = 8.8 mm, 120 m
    assert drone.format_mm == (8.8, 13.2) and drone.flying_height_m == 120.0
    assert PRESETS["corridor"].line and not film.line
    assert isinstance(film, StripPreset)


def test_drone_photos_see_about_thirty_points():
    strip = simulate_strip(15, preset="drone", seed=15)
    per_photo = np.bincount(strip.observations.photo)[2:-2]  # inner photos
    assert 20 <= per_photo.mean() <= 40


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"n_photos": 1}, "n_photos"),
        ({"preset": "balloon"}, "preset"),
        ({"control": "some"}, "control"),
        ({"crs": "EPSG:4978"}, "crs"),
        ({"crs": "not a crs"}, "crs"),
        ({"forward_overlap": 0.4}, "forward_overlap"),
        ({"wingspan": 3.0}, "wingspan"),
    ],
)
def test_bad_arguments_raise_value_error(kwargs, match):
    with pytest.raises(ValueError, match=match):
        simulate_strip(**kwargs)


@pytest.mark.parametrize("camera", ["film152", "ff35", "oneinch"])
def test_camera_preset_long_side_and_overlap(camera):
    """The format's long side follows `long_side`; the photos' footprints
    overlap as asked (measured on the truth: the along-track spacing of the
    projection centres over the footprint length at the mean terrain)."""
    from strip_aerotri.simulate import CAMERAS, camera_preset

    cam = CAMERAS[camera]
    along = camera_preset(camera, long_side="along", forward_overlap=0.8)
    across = camera_preset(camera, long_side="across", forward_overlap=0.8)
    assert along.format_mm == (cam.format_long_mm, cam.format_short_mm)
    assert across.format_mm == (cam.format_short_mm, cam.format_long_mm)
    sim = simulate_strip(8, preset=across, seed=2, position_wander_m=0.0)
    centres = sim.truth.photo_centres_local
    spacing = np.median(np.linalg.norm(np.diff(centres[:, :2], axis=0), axis=1))
    footprint = across.format_mm[0] * across.scale_m_per_mm
    assert 1.0 - spacing / footprint == pytest.approx(0.8, abs=0.01)


def test_blunders_are_where_the_truth_says():
    clean = simulate_strip(10, seed=4)
    bad = simulate_strip(10, seed=4, image_blunders=3, control_blunders=2)
    rows = np.asarray(bad.truth.blunder_observations)
    assert rows.size == 3 and len(bad.truth.blunder_control) == 2
    shift = np.hypot(*(bad.observations.xy - clean.observations.xy).T)
    assert np.flatnonzero(shift > 0).tolist() == sorted(rows.tolist())
    assert np.all(shift[rows] >= 0.05)  # at least 50 um (15-40 sigma of 5 um)
    diff = np.abs(np.nan_to_num(bad.control.xyz - clean.control.xyz))
    changed = np.flatnonzero(diff.max(axis=1) > 0)
    assert changed.tolist() == sorted(bad.truth.blunder_control)
    assert np.all((diff[changed].max(axis=1) >= 0.5) & (diff[changed].max(axis=1) <= 2.0))
    # everything else as without blunders (the errors come from their own stream)
    np.testing.assert_array_equal(clean.truth.points_local, bad.truth.points_local)
