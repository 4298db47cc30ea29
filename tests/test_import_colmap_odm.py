"""``stripaero import colmap`` and ``stripaero import odm``: COLMAP text models and gcp_list.txt.

Samples: ``tests/data/import/colmap`` (an OPENCV camera, geo-registered in
UTM 32N) and ``tests/data/import/odm/gcp_list.txt`` of the same synthetic
flight (tests/data/SOURCES.md).  Their pixel coordinates were distorted with
COLMAP's OPENCV model; after the import the loader must give back the true
image coordinates, which checks the conversion of the camera.
"""

from __future__ import annotations

import csv
import tomllib
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.errors import ConfigError
from strip_aerotri.importers.colmap import (
    camera_from_colmap,
    import_colmap,
    read_cameras,
    read_model,
)
from strip_aerotri.importers.common import ImportOptions, write_project
from strip_aerotri.interior import flight_matrix
from strip_aerotri.importers.odm import PixelCamera, crs_from_odm, import_odm, read_gcp_list
from strip_aerotri.project import load_project

SAMPLE = Path(__file__).resolve().parent / "data" / "import"
PIXEL_MM = 0.00241  # make_import_fixtures.py


def _truth():
    obs = {
        (r["photo"], r["point"]): (float(r["x"]), float(r["y"]))
        for r in csv.DictReader((SAMPLE / "truth" / "observations.csv").open())
    }
    names = [r["point"] for r in csv.DictReader((SAMPLE / "truth" / "points.csv").open())]
    photos = {r["photo"]: r for r in csv.DictReader((SAMPLE / "truth" / "photos.csv").open())}
    return obs, names, photos


def _true_xy(loaded, names):
    obs, _, _ = _truth()
    o = loaded.observations
    photos = np.asarray(o.photo_ids)[o.photo]
    points = np.asarray(o.point_ids)[o.point]
    ids = [names[int(q[1:]) - 1] if q.startswith("C") else q for q in points]
    xy = np.array([obs[(p, q)] for p, q in zip(photos, ids, strict=True)])
    return xy @ flight_matrix(loaded.images.flight_direction.value)[:2, :2].T


# --------------------------------------------------------------------------- COLMAP


def test_colmap_strip_gives_back_the_true_image_coordinates(tmp_path: Path) -> None:
    project = import_colmap(
        SAMPLE / "colmap",
        ImportOptions(strips=(1,)),
        pixel_size_mm=PIXEL_MM,
        gcps=SAMPLE / "odm" / "gcp_list.txt",
        pose_crs="EPSG:32632",
    )
    loaded = load_project(write_project(project, tmp_path / "p"))
    _, names, photos = _truth()
    assert loaded.photo_ids == tuple(f"DJI_{k:04d}" for k in range(1, 6))
    assert loaded.camera.principal_distance_mm == pytest.approx(8.8)
    assert loaded.distortion.model.value == "projection"
    # pixels rounded to 1e-4 px (ties) and 0.01 px (GCPs) in the sample: 1.2e-5 mm
    np.testing.assert_allclose(loaded.observations.xy, _true_xy(loaded, names), atol=2e-5)
    # the geo-registered poses give the projection centres
    gnss = loaded.gnss
    true = np.array([[float(photos[p][k]) for k in "XYZ"] for p in gnss.photo_ids])
    np.testing.assert_allclose(gnss.xyz, true, atol=1e-4)  # truth written to 0.1 mm


def test_colmap_block_finds_the_strips_from_the_poses(tmp_path: Path) -> None:
    project = import_colmap(
        SAMPLE / "colmap", pixel_size_mm=PIXEL_MM, gcps=SAMPLE / "odm" / "gcp_list.txt"
    )
    toml = write_project(project, tmp_path / "p")
    doc = tomllib.loads(toml.read_text(encoding="utf-8"))
    photos = [s["photos"] for s in doc["strips"]]
    assert photos[0] == [f"DJI_{k:04d}" for k in range(1, 6)]
    # flown back south with the camera's heading kept: listed in reverse
    assert photos[1] == [f"DJI_{k:04d}" for k in range(11, 6, -1)]
    assert "DJI_0006" in " ".join(project.warnings)  # the photo in the turn
    assert "gnss" not in doc  # the model frame was not declared geo-registered


def test_colmap_points_and_errors(tmp_path: Path) -> None:
    model, notes = read_model(SAMPLE / "colmap")
    assert np.all(np.char.startswith(model.ties.point, "C"))
    assert any("track under 2" in n for n in notes)
    images = (SAMPLE / "colmap" / "images.txt").read_text().splitlines()
    for name in ("cameras.txt", "points3D.txt"):
        (tmp_path / name).write_text((SAMPLE / "colmap" / name).read_text())
    # an image without observations has an empty second line: still read
    images[4] = ""
    (tmp_path / "images.txt").write_text("\n".join(images) + "\n")
    model, _ = read_model(tmp_path)
    assert "DJI_0001" not in set(model.ties.photo.tolist())
    # an observation of a 3D point that points3D.txt does not list
    points = (SAMPLE / "colmap" / "points3D.txt").read_text().splitlines()
    (tmp_path / "points3D.txt").write_text("\n".join(points[:3] + points[4:]) + "\n")
    with pytest.raises(ConfigError, match="does not list"):
        read_model(tmp_path)


@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("1 PINHOLE 4000 3000 3651.0 3660.0 2000 1500", "fx = 3651.0 and fy = 3660.0 differ"),
        ("1 OPENCV_FISHEYE 4000 3000 3651 3651 2000 1500 0 0 0 0", "fisheye"),
        ("1 FULL_OPENCV 4000 3000 3651 3651 2000 1500 0 0 0 0 0 0.1 0 0", "k4 = 0.1"),
        ("1 OPENCV 4000 3000 3651 3651 2000 1500 0.1", "takes 8 parameters"),
    ],
    ids=["affinity", "fisheye", "rational", "count"],
)
def test_colmap_cameras_without_a_faithful_conversion_are_refused(tmp_path, line, match) -> None:
    (tmp_path / "cameras.txt").write_text(line + "\n")
    with pytest.raises(ConfigError, match=match):
        cameras = read_cameras(tmp_path / "cameras.txt")
        camera_from_colmap(cameras[1], PIXEL_MM)


def test_colmap_radial_models_convert(tmp_path: Path) -> None:
    (tmp_path / "cameras.txt").write_text(
        "1 SIMPLE_RADIAL 4000 3000 3651.5 2001 1502 -0.02\n"
        "2 RADIAL 4000 3000 3651.5 2001 1502 -0.02 0.003\n"
    )
    cameras = read_cameras(tmp_path / "cameras.txt")
    cam, frame, dist, _ = camera_from_colmap(cameras[1], PIXEL_MM)
    assert cam.principal_distance_mm == pytest.approx(3651.5 * PIXEL_MM)
    assert frame.principal_point_px == (2001.0, 1502.0)
    assert (dist.k1, dist.k2, dist.p1, dist.p2) == (-0.02, 0.0, 0.0, 0.0)
    _, _, dist, _ = camera_from_colmap(cameras[2], PIXEL_MM)
    assert (dist.k1, dist.k2) == (-0.02, 0.003)


# --------------------------------------------------------------------------- OpenDroneMap


@pytest.mark.parametrize(
    ("header", "crs"),
    [
        ("EPSG:32632", "EPSG:32632"),
        ("WGS84 UTM 32N", "EPSG:32632"),
        ("WGS84 UTM 33S", "EPSG:32733"),
        (
            "+proj=utm +zone=32 +datum=WGS84 +units=m +no_defs",
            "+proj=utm +zone=32 +datum=WGS84 +units=m +no_defs",
        ),
    ],
    ids=["epsg", "utm-north", "utm-south", "proj"],
)
def test_odm_crs_line(header: str, crs: str) -> None:
    assert crs_from_odm(header, "gcp_list.txt:1") == crs


def test_odm_bad_crs_line_is_named() -> None:
    with pytest.raises(ConfigError, match=r"gcp_list\.txt:1: the first line must be the CRS"):
        crs_from_odm("609969.625 5039990.029 102.1 172 2034 DJI_0001.JPG", "gcp_list.txt:1")


def test_odm_gcps_without_names_are_grouped_by_coordinates(tmp_path: Path) -> None:
    lines = (SAMPLE / "odm" / "gcp_list.txt").read_text().splitlines()
    unnamed = [lines[0]] + [" ".join(line.split()[:6]) for line in lines[1:]]
    (tmp_path / "gcp_list.txt").write_text("\n".join(unnamed) + "\n")
    named = read_gcp_list(SAMPLE / "odm" / "gcp_list.txt")
    grouped = read_gcp_list(tmp_path / "gcp_list.txt")
    assert len(grouped.control) == len(named.control)
    assert grouped.control.point[0] == "gcp1"
    assert len(grouped.images) == len(named.images)


def test_odm_conflicting_gcp_coordinates_name_the_line(tmp_path: Path) -> None:
    lines = (SAMPLE / "odm" / "gcp_list.txt").read_text().splitlines()
    first = lines[1].split()
    lines.append(" ".join(["1.0", *first[1:]]))
    (tmp_path / "gcp_list.txt").write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigError, match=rf"gcp_list.txt:{len(lines)}: GCP '{first[6]}'"):
        read_gcp_list(tmp_path / "gcp_list.txt")


def test_odm_with_a_given_camera_is_a_ready_project(tmp_path: Path) -> None:
    camera = PixelCamera.from_options(8.8, 2.41, None, (4000, 3000), (2010.5, 1490.25))
    order = (tuple(f"DJI_{k:04d}" for k in range(1, 6)),)
    project = import_odm(
        SAMPLE / "odm" / "gcp_list.txt", ImportOptions(photo_order=order), camera=camera
    )
    loaded = load_project(write_project(project, tmp_path / "p"))
    assert loaded.photo_ids == order[0]
    assert loaded.crs == "EPSG:32632"
    assert set(loaded.observations.point_ids) == set(loaded.control.point_ids)  # no ties
    assert any("no tie points" in n for n in project.notes)


def test_odm_needs_a_camera_or_ties() -> None:
    with pytest.raises(ConfigError, match="holds no camera"):
        import_odm(SAMPLE / "odm" / "gcp_list.txt")
    with pytest.raises(ConfigError, match="--pixel-um or --sensor-width-mm"):
        PixelCamera.from_options(8.8, None, None, (4000, 3000))


def test_odm_with_colmap_ties_combines_both(tmp_path: Path) -> None:
    project = import_odm(
        SAMPLE / "odm" / "gcp_list.txt",
        ImportOptions(strips=(1,)),
        ties=SAMPLE / "colmap",
        pixel_size_mm=PIXEL_MM,
    )
    points = set(project.images.point.tolist())
    assert any(p.startswith("C") for p in points)
    assert any(p.startswith("GCP") for p in points)
    load_project(write_project(project, tmp_path / "p"))


def test_centres_of_an_ecef_registered_model_are_transformed() -> None:
    from pyproj import Transformer

    from strip_aerotri.importers.colmap import georeferenced_centres
    from strip_aerotri.importers.common import PhotoPositions

    _, _, photos = _truth()
    utm = np.array([[float(r[k]) for k in "XYZ"] for r in photos.values()])
    to_ecef = Transformer.from_crs("EPSG:32632", "EPSG:4978", always_xy=True)
    ecef = np.column_stack(to_ecef.transform(*utm.T))
    got = georeferenced_centres(PhotoPositions(list(photos), ecef), "EPSG:4978", "EPSG:32632")
    np.testing.assert_allclose(got.xyz, utm, atol=1e-6)
    with pytest.raises(ConfigError, match="local site system"):
        georeferenced_centres(PhotoPositions(list(photos), ecef), "EPSG:4978", "local")
