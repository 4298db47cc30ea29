"""``stripaero export cameras``: the photos as PATB omega-phi-kappa on the map grid."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli
from strip_aerotri.errors import ConfigError
from strip_aerotri.export import camera_rotations_grid, cameras_opk_text
from strip_aerotri.geometry.rotation import matrix_from_opk
from strip_aerotri.importers.common import attitudes_from_opk
from strip_aerotri.interior import flight_from_sensor
from strip_aerotri.simulate import simulate_strip


@pytest.mark.parametrize("direction", ["+x", "-x", "+y", "-y"])
def test_the_importers_reading_gives_the_photos_back(direction):
    """Written by the exporter, read by the Pix4D/Metashape importers' reading
    of the same convention (attitudes_from_opk): the sensor -> ENU rotations
    of the photos come back to the file's rounding (angles to 1e-6 degree,
    under 2e-8 in a matrix element)."""
    rng = np.random.default_rng(3)
    opk = np.column_stack([rng.normal(0, 0.03, 5), rng.normal(0, 0.03, 5), rng.uniform(-3, 3, 5)])
    centres = np.column_stack(
        [rng.uniform(4e5, 6e5, 5), rng.uniform(5e6, 6e6, 5), np.full(5, 900.0)]
    )
    text = cameras_opk_text([f"p{i}" for i in range(5)], centres, opk, "EPSG:32634", direction)
    rows = [line.split() for line in text.splitlines()[1:]]
    back = attitudes_from_opk(
        np.array([r[0] for r in rows]),
        np.array([[float(v) for v in r[4:7]] for r in rows]),
        np.array([[float(v) for v in r[1:3]] for r in rows]),
        "EPSG:32634",
        "test",
    )
    flight = np.eye(3)
    flight[:2, :2] = flight_from_sensor(np.eye(2), direction).T
    np.testing.assert_allclose(back.matrix, matrix_from_opk(opk) @ flight, rtol=0, atol=3e-8)


def test_a_vertical_photo_flown_north_on_the_grid():
    """A level photo whose image x (the flight) points grid north, in a local
    site system: the sensor x axis (right) is grid north, so kappa = 90."""
    opk_enu = np.array([[0.0, 0.0, np.pi / 2]])  # image x -> north
    grid = camera_rotations_grid(opk_enu, np.zeros((1, 2)), "local", "+x")
    np.testing.assert_allclose(grid[0] @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-12)
    text = cameras_opk_text(["a"], np.zeros((1, 3)), opk_enu, "local")
    assert [float(v) for v in text.splitlines()[1].split()[4:]] == pytest.approx([0.0, 0.0, 90.0])


def test_a_geographic_crs_is_refused():
    with pytest.raises(ConfigError, match="not a projected CRS"):
        cameras_opk_text(["a"], np.zeros((1, 3)), np.zeros((1, 3)), "EPSG:4326")


def test_cli_writes_the_file_next_to_the_results(tmp_path):
    toml = simulate_strip(8, seed=2).write_project(tmp_path / "p")
    runner = CliRunner()
    assert runner.invoke(cli, ["-q", "run", str(toml)]).exit_code == 0
    result = runner.invoke(cli, ["export", "cameras", str(toml)])
    assert result.exit_code == 0, result.output
    lines = (toml.parent / "out" / "cameras_opk.txt").read_text().splitlines()
    assert lines[0] == "imageName X Y Z Omega Phi Kappa" and len(lines) == 9
    missing = runner.invoke(cli, ["export", "cameras", str(toml), "--from", str(tmp_path / "x")])
    assert missing.exit_code == 1 and "run the project first" in missing.stderr


def _pixel_project(tmp_path):
    """A simulated strip whose image coordinates are written as pixel column
    and row (1-inch camera geometry: 2.41 µm pixels, principal point at
    (2736, 1824))."""
    import csv

    toml = simulate_strip(8, seed=4, preset="drone").write_project(tmp_path / "p")
    folder = toml.parent
    rows = list(csv.DictReader((folder / "image_points.csv").open()))
    pixel, cx, cy = 0.00241, 2736.0, 1824.0
    with (folder / "image_points.csv").open("w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["photo", "point", "x", "y"])
        for r in rows:
            out.writerow(
                [
                    r["photo"],
                    r["point"],
                    f"{cx + float(r['x']) / pixel:.4f}",
                    f"{cy - float(r['y']) / pixel:.4f}",
                ]
            )
    text = toml.read_text().replace(
        "[images]\n",
        f'[images]\nunits = "pixel"\npixel_size_mm = {pixel}\nprincipal_point_px = [{cx}, {cy}]\n',
    )
    toml.write_text(text.replace("sigma_mm", "# sigma_mm"))
    return toml


def test_odm_gcp_list_round_trip(tmp_path):
    """A project measured in pixels, run and exported: read back by the ODM
    importer's reader, every observation of a control or check point has its
    measured pixel column and row on its image, and the point its adjusted
    coordinates."""
    import csv

    from strip_aerotri.importers.odm import read_gcp_list

    toml = _pixel_project(tmp_path)
    runner = CliRunner()
    run = runner.invoke(cli, ["-q", "run", str(toml)])
    assert run.exit_code == 0, run.output
    done = runner.invoke(cli, ["export", "odm", str(toml), "--image-ext", ".JPG"])
    assert done.exit_code == 0, done.output
    exported = read_gcp_list(toml.parent / "out" / "gcp_list.txt")
    assert exported.crs == "EPSG:32634"
    measured = {
        (r["photo"] + ".JPG", r["point"]): (float(r["x"]), float(r["y"]))
        for r in csv.DictReader((toml.parent / "image_points.csv").open())
    }
    images = exported.images
    pairs = list(zip(images.photo, images.point, images.xy, strict=True))
    assert len(pairs) > 20
    for photo, point, xy in pairs:
        assert tuple(xy) == pytest.approx(measured[(str(photo) + ".JPG", str(point))], abs=1e-3)
    rows = {r["point"]: r for r in csv.DictReader((toml.parent / "out" / "points.csv").open())}
    assert {rows[str(p)]["role"] for p in exported.control.point} <= {
        "control-full",
        "control-plan",
        "control-height",
        "check",
    }
    for name, xyz in zip(exported.control.point, exported.control.xyz, strict=True):
        assert xyz == pytest.approx([float(rows[str(name)][c]) for c in "XYH"], abs=1e-4)


def test_odm_export_refuses_millimetres_without_their_pixel_keys(tmp_path):
    toml = simulate_strip(6, seed=1).write_project(tmp_path / "p")
    runner = CliRunner()
    assert runner.invoke(cli, ["-q", "run", str(toml)]).exit_code == 0
    refused = runner.invoke(cli, ["export", "odm", str(toml)])
    assert refused.exit_code == 1 and "without pixel_size_mm and principal_point_px" in (
        refused.stderr
    )
