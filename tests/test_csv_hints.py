"""CSV mistakes named by their likely cause (``project.csvfiles``): a unit
written into a column name, and the header repeated inside the file (two
exports joined).  Found by the catalogue fuzz (``benchmarks/fuzz_inputs.py``):
they said "unknown column 'x_mm'" and "column 'x': expected a number, got 'x'".
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli

FILM = Path(__file__).resolve().parents[1] / "examples" / "film-strip"


def _film(tmp_path: Path) -> Path:
    folder = tmp_path / "p"
    shutil.copytree(FILM, folder, ignore=shutil.ignore_patterns("out"))
    return folder


def _error(folder: Path) -> str:
    result = CliRunner().invoke(cli, ["check", str(folder / "strip.toml")])
    assert result.exit_code == 1, result.output
    (line,) = result.stderr.splitlines()
    return line


@pytest.mark.parametrize(
    ("file", "old", "new", "means"),
    [
        ("image_points.csv", "photo,point,x,y,sigma", "photo,point,x_mm,y,sigma", "x"),
        ("image_points.csv", "photo,point,x,y,sigma", "photo,point,x,y,sigma (mm)", "sigma"),
        ("control.csv", "point,X,Y,H,type", "point,X [m],Y,H,type", "X"),
        ("control.csv", "sigma_xy,sigma_h", "sigma_xy_m,sigma_h", "sigma_xy"),
    ],
    ids=["x_mm", "sigma (mm)", "X [m]", "sigma_xy_m"],
)
def test_a_unit_in_a_column_name(
    tmp_path: Path, file: str, old: str, new: str, means: str
) -> None:
    folder = _film(tmp_path)
    path = folder / file
    path.write_text(path.read_text("utf-8").replace(old, new, 1), encoding="utf-8")
    line = _error(folder)
    assert f"{file}:1: unknown column" in line, line
    assert f"did you mean '{means}'? the unit is not part of the name" in line, line


def test_a_misspelt_column_still_gets_the_spelling_suggestion(tmp_path: Path) -> None:
    folder = _film(tmp_path)
    path = folder / "image_points.csv"
    path.write_text(path.read_text("utf-8").replace(",sigma", ",sigm", 1), encoding="utf-8")
    assert "unknown column 'sigm' (did you mean 'sigma'?)" in _error(folder)


def test_the_header_repeated_inside_the_file(tmp_path: Path) -> None:
    folder = _film(tmp_path)
    path = folder / "image_points.csv"
    lines = path.read_text("utf-8").splitlines()
    path.write_text("\n".join([*lines[:100], lines[0], *lines[100:]]) + "\n", encoding="utf-8")
    line = _error(folder)
    assert "image_points.csv:101: column 'x': expected a number, got 'x'" in line, line
    assert "the line repeats the header" in line, line
