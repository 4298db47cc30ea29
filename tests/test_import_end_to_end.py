"""Import, then run, with no script in between: the runnable samples of
examples/import-samples (a drone block of 2 strips x 5 photos and a photo
in the turn, over 196 points of which 158 are on two photos or more, 36
GCPs, every image measurement with 0.3 px of noise, written by
tests/data/import/make_import_fixtures.py --dense) come out at the truth.

A wrong axis, sign, unit or distortion convention in an importer would put
the points metres off; right, they land within the noise (4.4 cm ground
pixel: 0.3 px is 1.3 cm).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli

SAMPLES = Path(__file__).resolve().parents[1] / "examples" / "import-samples"

COMMANDS = {
    "patb": [
        "patb",
        SAMPLES / "patb" / "block.im",
        SAMPLES / "patb" / "block.con",
        "--focal-mm",
        "8.8",
        "--crs",
        "EPSG:32632",
        "--ori",
        SAMPLES / "patb" / "block.ori",
    ],
    "odm": [
        "odm",
        SAMPLES / "odm" / "gcp_list.txt",
        "--ties",
        SAMPLES / "colmap",
        "--pixel-um",
        "2.41",
    ],
    "colmap": [
        "colmap",
        SAMPLES / "colmap",
        "--gcps",
        SAMPLES / "odm" / "gcp_list.txt",
        "--pixel-um",
        "2.41",
        "--pose-crs",
        "EPSG:32632",
    ],
    "uav-fc300x": ["uav-fc300x", SAMPLES / "fc300x"],
}


def _truth() -> dict[str, np.ndarray]:
    with open(SAMPLES / "truth" / "points.csv", newline="") as f:
        return {
            r["point"]: np.array([float(r[k]) for k in ("X", "Y", "H")]) for r in csv.DictReader(f)
        }


@pytest.mark.parametrize("fmt", list(COMMANDS), ids=list(COMMANDS))
def test_import_then_run_lands_on_the_truth(tmp_path: Path, fmt: str) -> None:
    runner = CliRunner()
    project = tmp_path / "project"
    result = runner.invoke(cli, ["import", *map(str, COMMANDS[fmt]), "--out", str(project)])
    assert result.exit_code == 0, result.output
    result = runner.invoke(cli, ["-q", "run", str(project / "strip.toml")])
    assert result.exit_code == 0, result.output
    truth = np.array(list(_truth().values()))
    with open(project / "out" / "points.csv", newline="") as f:
        adjusted = np.array([[float(r[k]) for k in ("X", "Y", "H")] for r in csv.DictReader(f)])
    # each format numbers the points its own way: match each point to the
    # nearest truth in plan (grid spacing 7 m, errors of centimetres)
    gap = np.hypot(*(adjusted[:, None, :2] - truth[None, :, :2]).transpose(2, 0, 1))
    d = adjusted - truth[np.argmin(gap, axis=1)]
    assert len(d) > 150
    plan = float(np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2)))
    height = float(np.sqrt(np.mean(d[:, 2] ** 2)))
    # measured 0.007-0.009 m plan, 0.020-0.022 m height over the 158 points
    assert plan < 0.05 and height < 0.08, (plan, height)
