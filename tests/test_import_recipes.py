"""The import samples' recipes as a new user follows them: every command of
examples/import-samples/README.md runs as written (Pix4D and Metashape
included), the help's image size is the sample's, an image size that
contradicts the marked pixels is an import error, Metashape chooses its
control as the other importers do, and export odm works on the FC300X
import (pixels from its mm coordinates)."""

from __future__ import annotations

import csv
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

SAMPLES = Path(__file__).resolve().parents[1] / "examples" / "import-samples"
CLI = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", CLI, *args], capture_output=True, text=True, timeout=300, cwd=cwd
    )


@pytest.fixture()
def samples(tmp_path: Path) -> Path:
    folder = tmp_path / "import-samples"
    shutil.copytree(SAMPLES, folder, ignore=shutil.ignore_patterns("projects"))
    return folder


def _readme_commands() -> list[list[str]]:
    text = (SAMPLES / "README.md").read_text(encoding="utf-8")
    block = re.search(r"```\n(.*?)```", text, re.S)
    assert block is not None
    joined = block.group(1).replace("\\\n", " ")
    return [shlex.split(line) for line in joined.splitlines() if line.startswith("stripaero ")]


def test_every_readme_command_runs_and_pix4d_and_metashape_are_there(samples: Path):
    """Each command of the README's recipe in order, from the samples folder;
    the Pix4D and Metashape projects run (on their GCPs) and land on the truth
    within a few centimetres. Today the README has no command for them."""
    commands = _readme_commands()
    formats = {c[2] for c in commands if c[1] == "import"}
    assert {"pix4d", "metashape", "patb", "odm", "colmap", "uav-fc300x"} <= formats
    for command in commands:
        done = _cli(*command[1:], cwd=samples)
        assert done.returncode == 0, (command, done.stderr)
    truth = {}
    with open(samples / "truth" / "points.csv", newline="") as f:
        for r in csv.DictReader(f):
            truth[r["point"]] = [float(r[k]) for k in ("X", "Y", "H")]
    known = np.array(list(truth.values()))
    for fmt in ("pix4d", "metashape"):
        with open(samples / "projects" / fmt / "out" / "points.csv", newline="") as f:
            got = np.array([[float(r[k]) for k in ("X", "Y", "H")] for r in csv.DictReader(f)])
        gap = np.hypot(*(got[:, None, :2] - known[None, :, :2]).transpose(2, 0, 1))
        d = got - known[np.argmin(gap, axis=1)]
        assert len(d) >= 20
        assert float(np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2))) < 0.08
        assert float(np.sqrt(np.mean(d[:, 2] ** 2))) < 0.08


def test_pix4d_help_gives_the_samples_image_size():
    from click.testing import CliRunner

    from strip_aerotri.cli.main import cli

    text = CliRunner().invoke(cli, ["import", "pix4d", "--help"]).output
    assert "--image-size 4000 3000" in text and "5472" not in text
    colmap = (SAMPLES / "colmap" / "cameras.txt").read_text()
    assert " 4000 3000 " in colmap  # the samples' camera


@pytest.mark.parametrize(
    ("size", "says"),
    [
        (("5472", "3648"), "far from the centre of an image of --image-size 5472 3648"),
        (("3000", "3000"), "lies outside the image of --image-size 3000 3000"),
    ],
)
def test_an_image_size_contradicting_the_marks_is_an_import_error(
    samples: Path, size: tuple[str, str], says: str
):
    """Today 5472 x 3648 imports, check says OK and run fails on the control."""
    done = _cli(
        "import", "pix4d", "pix4d/marks.csv", "pix4d/gcps.csv", "--crs", "EPSG:32632",
        "--focal-mm", "8.8", "--pixel-um", "2.41", "--image-size", *size, "--out", "p",
        cwd=samples,
    )  # fmt: skip
    assert done.returncode == 1
    assert done.stderr.count("\n") == 1 and says in done.stderr
    assert "pix4d/marks.csv" in done.stderr and "check the image size" in done.stderr
    assert not (samples / "p").exists()
    # the principal point given: the image size no longer places it, so only
    # marks outside the image are refused
    done = _cli(
        "import", "pix4d", "pix4d/marks.csv", "pix4d/gcps.csv", "--crs", "EPSG:32632",
        "--focal-mm", "8.8", "--pixel-um", "2.41", "--image-size", "5472", "3648",
        "--principal-point-px", "2000", "1500", "--out", "q",
        cwd=samples,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr


def _control_types(project: Path) -> dict[str, int]:
    with open(project / "control.csv", newline="") as f:
        kinds = [r["type"] for r in csv.DictReader(f)]
    return {k: kinds.count(k) for k in set(kinds)}


def test_metashape_chooses_control_as_the_others(samples: Path):
    """10 full control points and the rest check points, as PATB, ODM, COLMAP,
    Pix4D and FC300X (today 35 full and 1 check from the reference flags);
    --source-types keeps the flags."""
    base = ["import", "metashape", "metashape/markers.xml", "--cameras"]
    base += ["metashape/cameras_opk.txt"]
    done = _cli(*base, "--out", "ms", cwd=samples)
    assert done.returncode == 0, done.stderr
    pix = _cli(
        "import", "pix4d", "pix4d/marks.csv", "pix4d/gcps.csv", "--crs", "EPSG:32632",
        "--focal-mm", "8.8", "--pixel-um", "2.41", "--image-size", "4000", "3000",
        "--external", "pix4d/flight_calibrated_external_camera_parameters.txt", "--out", "px",
        cwd=samples,
    )  # fmt: skip
    assert pix.returncode == 0, pix.stderr
    assert _control_types(samples / "ms") == _control_types(samples / "px")
    assert _control_types(samples / "ms")["full"] == 10
    flags = _cli(*base, "--source-types", "--out", "ms2", cwd=samples)
    assert flags.returncode == 0, flags.stderr
    assert _control_types(samples / "ms2") == {"full": 35, "check": 1}


def test_export_odm_works_on_the_fc300x_import(samples: Path):
    """The FC300X import writes the pixel size and the pixel position of its
    mm origin (the image centre of cal.cal's 4000 x 3000); export odm turns
    the mm measurements back into the pixels they came from. Today it
    refuses the project (mm)."""
    done = _cli("import", "uav-fc300x", "fc300x", "--crs", "EPSG:32632", "--out", "f", cwd=samples)
    assert done.returncode == 0, done.stderr
    toml = (samples / "f" / "strip.toml").read_text()
    assert "principal_point_px = [2000.0, 1500.0]" in toml
    assert _cli("-q", "run", "f/strip.toml", cwd=samples).returncode == 0
    export = _cli("export", "odm", "f/strip.toml", "--points", "all", cwd=samples)
    assert export.returncode == 0, export.stderr
    lines = (samples / "f" / "out" / "gcp_list.txt").read_text().splitlines()
    assert lines[0] == "EPSG:32632"
    exported = {(r[5], r[6]): (float(r[3]), float(r[4])) for r in map(str.split, lines[1:])}
    with open(samples / "f" / "image_points.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if (r["photo"], r["point"]) in exported]
    assert len(rows) == len(exported) > 300
    col = np.array([exported[r["photo"], r["point"]][0] for r in rows])
    row = np.array([exported[r["photo"], r["point"]][1] for r in rows])
    x = np.array([float(r["x"]) for r in rows])
    y = np.array([float(r["y"]) for r in rows])
    # x right and y up in mm from the image centre; 3 decimals in the file
    np.testing.assert_allclose((col - 2000.0) * 0.00241, x, atol=0.0006 * 0.00241 + 1e-9)
    np.testing.assert_allclose(-(row - 1500.0) * 0.00241, y, atol=0.0006 * 0.00241 + 1e-9)
    assert 0 < col.min() and col.max() < 4000 and 0 < row.min() and row.max() < 3000
