"""``stripaero import metashape`` and ``stripaero import pix4d``.

Samples: ``tests/data/import/metashape`` and ``tests/data/import/pix4d``
(tests/data/SOURCES.md).  The attitudes of both were written from the true
rotations as PATB omega, phi, kappa on the UTM grid (the convention Pix4D
documents and the importers assume for Metashape); the round trip checked
here is: file -> imu.csv -> load_project -> rotation, against the true
rotation turned to east-north-up by the meridian convergence (pyproj) and
to the flight axes.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from pyproj import CRS, Proj, Transformer

from strip_aerotri.errors import ConfigError
from strip_aerotri.geometry.rotation import matrix_from_opk
from strip_aerotri.importers.common import ImportOptions, write_project
from strip_aerotri.importers.metashape import import_metashape, read_markers_xml, read_opk_text
from strip_aerotri.importers.odm import PixelCamera
from strip_aerotri.importers.pix4d import import_pix4d, read_gcp_coordinates, read_marks
from strip_aerotri.interior import flight_matrix
from strip_aerotri.project import load_project

SAMPLE = Path(__file__).resolve().parent / "data" / "import"
CAMERA = PixelCamera(8.8, 0.00241, (4000, 3000), (2010.5, 1490.25))  # make_import_fixtures.py
EXTERNAL = SAMPLE / "pix4d" / "flight_calibrated_external_camera_parameters.txt"


def _rz(deg: float) -> np.ndarray:
    t = np.deg2rad(deg)
    return np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])


def _true_rotations(photo_ids, direction: str) -> np.ndarray:
    """Image (flight axes) -> east-north-up, from truth/photos.csv (sensor -> grid)."""
    rows = {r["photo"]: r for r in csv.DictReader((SAMPLE / "truth" / "photos.csv").open())}
    crs = CRS.from_user_input("EPSG:32632")
    to_geo = Transformer.from_crs(crs, crs.geodetic_crs, always_xy=True)
    out = []
    for pid in photo_ids:
        r = rows[pid]
        grid = matrix_from_opk([float(r[k]) for k in ("omega", "phi", "kappa")], degrees=True)
        lon, lat = to_geo.transform(float(r["X"]), float(r["Y"]))
        gamma = Proj(crs).get_factors(lon, lat).meridian_convergence  # independent of the importer
        out.append(_rz(-gamma) @ grid @ flight_matrix(direction).T)
    return np.array(out)


def _true_xy(loaded) -> np.ndarray:
    truth = {
        (r["photo"], r["point"]): (float(r["x"]), float(r["y"]))
        for r in csv.DictReader((SAMPLE / "truth" / "observations.csv").open())
    }
    o = loaded.observations
    photos = np.asarray(o.photo_ids)[o.photo]
    points = np.asarray(o.point_ids)[o.point]
    xy = np.array([truth[(p, q)] for p, q in zip(photos, points, strict=True)])
    return xy @ flight_matrix(loaded.images.flight_direction.value)[:2, :2].T


# --------------------------------------------------------------------------- Metashape


def test_metashape_strip_with_cameras(tmp_path: Path) -> None:
    project = import_metashape(
        SAMPLE / "metashape" / "markers.xml",
        ImportOptions(strips=(1,)),
        cameras_file=SAMPLE / "metashape" / "cameras_opk.txt",
    )
    loaded = load_project(write_project(project, tmp_path / "p"))
    assert loaded.photo_ids == tuple(f"DJI_{k:04d}" for k in range(1, 6))
    assert loaded.crs == "EPSG:32632"  # the chunk's WKT, identified
    # the sensor calibration (Metashape Appendix C) undone by the loader
    np.testing.assert_allclose(loaded.observations.xy, _true_xy(loaded), atol=5e-6)
    got = matrix_from_opk(loaded.imu.opk)
    np.testing.assert_allclose(got, _true_rotations(loaded.imu.photo_ids, "+y"), atol=1e-8)
    assert loaded.adjustment.refine.value == "bundle"


def test_metashape_marker_types_and_crs_come_from_the_xml() -> None:
    xml = read_markers_xml(SAMPLE / "metashape" / "markers.xml")
    kinds = dict(zip(xml.control.point.tolist(), xml.control.kind.tolist(), strict=True))
    assert kinds["GCP8"] == "check" and kinds["GCP1"] == "full"  # GCP8's reference is disabled
    assert xml.control.typed
    assert xml.crs == "EPSG:32632"


def test_metashape_vertical_crs_is_refused(tmp_path: Path) -> None:
    text = (SAMPLE / "metashape" / "markers.xml").read_text()
    start, end = text.index("<reference>PROJCS"), text.index("</reference>\n  </chunk>")
    compound = CRS.from_user_input("EPSG:32632+5773").to_wkt("WKT1_GDAL")
    (tmp_path / "m.xml").write_text(text[:start] + f"<reference>{compound}" + text[end:])
    with pytest.raises(ConfigError, match="vertical datum"):
        read_markers_xml(tmp_path / "m.xml")


def test_metashape_matrix_that_disagrees_with_the_angles_is_refused(tmp_path: Path) -> None:
    lines = (SAMPLE / "metashape" / "cameras_opk.txt").read_text().splitlines()
    fields = lines[3].split("\t")
    fields[4], fields[5] = fields[5], fields[4]  # omega and phi swapped: matrix no longer fits
    lines[3] = "\t".join(fields)
    (tmp_path / "opk.txt").write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigError, match=r"opk\.txt:4: the matrix r11\.\.r33 is neither"):
        read_opk_text(tmp_path / "opk.txt")


def test_attitudes_of_another_camera_convention_are_refused(tmp_path: Path) -> None:
    # cameras that would look up: angles of an x right, y down, z forward camera
    lines = (SAMPLE / "metashape" / "cameras_opk.txt").read_text().splitlines()
    out = lines[:3]
    for line in lines[3:]:
        f = line.split("\t")
        r = matrix_from_opk([float(v) for v in f[4:7]], degrees=True) @ np.diag([1.0, -1.0, -1.0])
        omega = np.degrees(np.arctan2(-r[1, 2], r[2, 2]))
        phi, kappa = np.degrees(np.arcsin(r[0, 2])), np.degrees(np.arctan2(-r[0, 1], r[0, 0]))
        out.append("\t".join([*f[:4], f"{omega:.9f}", f"{phi:.9f}", f"{kappa:.9f}"]))
    (tmp_path / "opk.txt").write_text("\n".join(out) + "\n")
    with pytest.raises(ConfigError, match="most cameras would look up"):
        import_metashape(SAMPLE / "metashape" / "markers.xml", cameras_file=tmp_path / "opk.txt")
    project = import_metashape(
        SAMPLE / "metashape" / "markers.xml",
        ImportOptions(strips=(1,)),
        cameras_file=tmp_path / "opk.txt",
        attitudes=False,
    )
    assert project.imu_opk_deg is None and project.gnss is not None


# --------------------------------------------------------------------------- Pix4D


def test_pix4d_strip_with_external_parameters(tmp_path: Path) -> None:
    project = import_pix4d(
        SAMPLE / "pix4d" / "marks.csv",
        SAMPLE / "pix4d" / "gcps.csv",
        ImportOptions(strips=(1,)),
        camera=CAMERA,
        crs="EPSG:32632",
        external_file=EXTERNAL,
    )
    loaded = load_project(write_project(project, tmp_path / "p"))
    assert loaded.photo_ids == tuple(f"DJI_{k:04d}" for k in range(1, 6))
    np.testing.assert_allclose(loaded.observations.xy, _true_xy(loaded), atol=2e-6)
    # the marks' accuracy of 0.5 px is each observation's sigma
    np.testing.assert_allclose(loaded.observations.sigma, 0.5 * 0.00241)
    got = matrix_from_opk(loaded.imu.opk)
    np.testing.assert_allclose(got, _true_rotations(loaded.imu.photo_ids, "+y"), atol=1e-8)
    np.testing.assert_allclose(loaded.control.sigma_xy, 0.02)  # gcps.csv: accuracy 0.02, 0.03
    np.testing.assert_allclose(loaded.control.sigma_h, 0.03)


def test_pix4d_block_reverses_the_strip_flown_back() -> None:
    project = import_pix4d(
        SAMPLE / "pix4d" / "marks.csv",
        SAMPLE / "pix4d" / "gcps.csv",
        camera=CAMERA,
        crs="EPSG:32632",
        external_file=EXTERNAL,
    )
    assert [s.photos for s in project.strips] == [
        tuple(f"DJI_{k:04d}" for k in range(1, 6)),
        tuple(f"DJI_{k:04d}" for k in range(11, 6, -1)),
    ]
    # attitudes do not depend on the photo order, only on the flight axes
    photo, opk = project.imu_opk_deg
    np.testing.assert_allclose(
        matrix_from_opk(opk, degrees=True), _true_rotations(photo, "+y"), atol=1e-8
    )


def test_pix4d_gcp_axis_order_follows_the_crs(tmp_path: Path) -> None:
    # EPSG:4326 lists latitude first (Pix4D's import format follows the CRS definition)
    (tmp_path / "g.csv").write_text("G1,45.5,10.4,100.0\n")
    table, note = read_gcp_coordinates(tmp_path / "g.csv", "EPSG:4326")
    assert table.xyz[0].tolist() == [10.4, 45.5, 100.0]  # written as longitude, latitude
    assert "northing/latitude" in note
    table, _ = read_gcp_coordinates(tmp_path / "g.csv", "EPSG:4326", "xy")
    assert table.xyz[0].tolist() == [45.5, 10.4, 100.0]


def test_pix4d_marks_with_a_header_and_bad_rows(tmp_path: Path) -> None:
    (tmp_path / "m.csv").write_text("image,label,x,y\nimg/DJI_0001.JPG,G1,10.5,20.5\n")
    marks = read_marks(tmp_path / "m.csv")
    assert marks.photo.tolist() == ["DJI_0001"] and marks.sigma_mm is None
    (tmp_path / "m.csv").write_text("DJI_0001.JPG,G1,10.5\n")
    with pytest.raises(ConfigError, match=r"m\.csv:1: expected at least 4 fields"):
        read_marks(tmp_path / "m.csv")
