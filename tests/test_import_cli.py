"""``stripaero import FORMAT``: the command line over the importers (click's CliRunner).

Every format writes a project from its sample in ``tests/data/import``; bad
input exits with 1 and one line on stderr, usage errors with 2, and an
existing folder is never replaced without ``--force``.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli
from strip_aerotri.project import load_project

SAMPLE = Path(__file__).resolve().parent / "data" / "import"
CAMERA = ["--focal-mm", "8.8", "--pixel-um", "2.41", "--image-size", "4000", "3000"]


def invoke(*args):
    return CliRunner().invoke(cli, [str(a) for a in args])


def _one_error_line(result) -> str:
    assert result.exit_code == 1, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("stripaero: error: ")
    assert "Traceback" not in result.output
    return lines[0]


FORMATS = {
    "uav-fc300x": ["uav-fc300x", SAMPLE / "fc300x"],
    "odm": [
        "odm",
        SAMPLE / "odm" / "gcp_list.txt",
        "--ties",
        SAMPLE / "colmap",
        "--pixel-um",
        "2.41",
    ],
    "colmap": [
        "colmap",
        SAMPLE / "colmap",
        "--gcps",
        SAMPLE / "odm" / "gcp_list.txt",
        "--pixel-um",
        "2.41",
        "--pose-crs",
        "EPSG:32632",
    ],
    "patb": [
        "patb",
        SAMPLE / "patb" / "block.im",
        SAMPLE / "patb" / "block.con",
        "--focal-mm",
        "8.8",
        "--crs",
        "EPSG:32632",
        "--ori",
        SAMPLE / "patb" / "block.ori",
    ],
    "metashape": [
        "metashape",
        SAMPLE / "metashape" / "markers.xml",
        "--cameras",
        SAMPLE / "metashape" / "cameras_opk.txt",
    ],
    "pix4d": [
        "pix4d",
        SAMPLE / "pix4d" / "marks.csv",
        SAMPLE / "pix4d" / "gcps.csv",
        "--crs",
        "EPSG:32632",
        *CAMERA,
        "--principal-point-px",
        "2010.5",
        "1490.25",
        "--external",
        SAMPLE / "pix4d" / "flight_calibrated_external_camera_parameters.txt",
    ],
}


@pytest.mark.parametrize("fmt", list(FORMATS), ids=list(FORMATS))
def test_every_format_writes_a_loadable_strip_and_a_block(tmp_path: Path, fmt: str) -> None:
    result = invoke("import", *FORMATS[fmt], "--out", tmp_path / "one", "--strips", "1")
    assert result.exit_code == 0, result.output
    assert "wrote" in result.stdout
    project = load_project(tmp_path / "one" / "strip.toml")
    assert len(project.photo_ids) == 5
    result = invoke("import", *FORMATS[fmt], "--out", tmp_path / "block")
    assert result.exit_code == 0, result.output
    doc = tomllib.loads((tmp_path / "block" / "strip.toml").read_text(encoding="utf-8"))
    assert len(doc["strips"]) == 2


def test_existing_folder_needs_force(tmp_path: Path) -> None:
    out = tmp_path / "proj"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    line = _one_error_line(invoke("import", *FORMATS["patb"], "--out", out))
    assert "give --force" in line
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    result = invoke("import", *FORMATS["patb"], "--out", out, "--force", "--strips", "1")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == [
        "control.csv",
        "gnss.csv",
        "image_points.csv",
        "strip.toml",
    ]


def test_bad_input_is_one_line_naming_the_file(tmp_path: Path) -> None:
    line = _one_error_line(
        invoke(
            "import",
            "patb",
            tmp_path / "none.im",
            SAMPLE / "patb" / "block.con",
            "--focal-mm",
            "8.8",
            "--crs",
            "local",
            "--out",
            tmp_path / "p",
        )
    )
    assert "none.im: file not found" in line
    assert not (tmp_path / "p").exists()


def test_control_check_and_photo_order_options(tmp_path: Path) -> None:
    order = tmp_path / "order.txt"
    order.write_text("# strip 1\nB1_1 B1_2 B1_3, B1_4 B1_5\n")
    result = invoke(
        "import",
        "uav-fc300x",
        SAMPLE / "fc300x",
        "--out",
        tmp_path / "p",
        "--photo-order",
        order,
        "--control",
        "101,103,105",
        "--check",
        "104",
    )
    assert result.exit_code == 0, result.output
    project = load_project(tmp_path / "p" / "strip.toml")
    assert project.photo_ids == ("B1_1", "B1_2", "B1_3", "B1_4", "B1_5")
    types = (tmp_path / "p" / "control.csv").read_text().splitlines()[1:]
    assert sorted(t.split(",")[-1] for t in types) == ["check", "full", "full", "full"]
    line = _one_error_line(
        invoke(
            "import", "uav-fc300x", SAMPLE / "fc300x", "--out", tmp_path / "q", "--control", "7777"
        )
    )
    assert "'7777' is not a control point" in line


def test_usage_errors_exit_2(tmp_path: Path) -> None:
    result = invoke(
        "import", "uav-fc300x", SAMPLE / "fc300x", "--out", tmp_path / "p", "--strips", "one"
    )
    assert result.exit_code == 2
    result = invoke("import", "patb", SAMPLE / "patb" / "block.im")
    assert result.exit_code == 2


def test_camera_options_are_checked(tmp_path: Path) -> None:
    line = _one_error_line(
        invoke(
            "import",
            "odm",
            SAMPLE / "odm" / "gcp_list.txt",
            "--out",
            tmp_path / "p",
            "--focal-mm",
            "8.8",
            "--image-size",
            "4000",
            "3000",
        )
    )
    assert "--pixel-um or --sensor-width-mm" in line
    line = _one_error_line(
        invoke(
            "import",
            "odm",
            SAMPLE / "odm" / "gcp_list.txt",
            "--ties",
            SAMPLE / "colmap",
            "--focal-mm",
            "8.8",
            "--pixel-um",
            "2.41",
            "--out",
            tmp_path / "p",
        )
    )
    assert "camera comes from the COLMAP model" in line
