"""``self_calibration = "ebner12"`` on a camera that is not a film camera:
one warning line, once, naming "auto"; the run estimates Ebner's 12 as
asked (project/camera_checks.py)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli
from strip_aerotri.project.camera_checks import ebner_on_digital
from strip_aerotri.simulate import simulate_strip

TOML = Path("strip.toml")
EBNER = SimpleNamespace(self_calibration="ebner12")


def _warned(c_mm: float, xy: np.ndarray, fiducials: bool, options=EBNER) -> list[str]:
    return ebner_on_digital(
        TOML, options, c_mm, SimpleNamespace(xy=xy), (object(),) if fiducials else ()
    )  # type: ignore[arg-type]


def _square(half_mm: float) -> np.ndarray:
    g = np.linspace(-half_mm, half_mm, 5)
    return np.column_stack([np.repeat(g, 5), np.tile(g, 5)])


@pytest.mark.parametrize(
    ("c_mm", "half_mm", "fiducials", "seen"),
    [
        (3.61, 3.0, False, "c 3.61 mm, image points over 6 mm"),  # the FC300X
        (35.0, 17.0, False, "c 35 mm, image points over 34 mm"),  # full frame
        (100.5, 17.0, False, "image points over 34 mm"),  # a long lens on a small sensor
        (45.0, 40.0, False, "c 45 mm"),
    ],
)
def test_a_digital_camera_is_told_once(c_mm, half_mm, fiducials, seen):
    (line,) = _warned(c_mm, _square(half_mm), fiducials)
    assert line.startswith('strip.toml: [adjustment] self_calibration = "ebner12" on a digital')
    assert f"({seen}, no fiducials)" in line
    assert '"auto"' in line and "film" in line and "\n" not in line


@pytest.mark.parametrize(
    ("c_mm", "half_mm", "fiducials"),
    [
        (152.9, 105.0, False),  # a wide-angle film camera
        (88.0, 100.0, False),  # super-wide film
        (3.61, 3.0, True),  # fiducials: film whatever the numbers say
        (50.0, 20.0, False),  # the limits themselves are film's
    ],
)
def test_a_film_camera_is_not(c_mm, half_mm, fiducials):
    assert _warned(c_mm, _square(half_mm), fiducials) == []


def test_no_point_leaves_only_the_principal_distance_to_judge():
    empty = np.full((3, 2), np.nan)
    assert _warned(152.9, empty, False) == []
    (line,) = _warned(8.8, empty, False)
    assert "(c 8.8 mm, no fiducials)" in line


@pytest.mark.parametrize("choice", ["auto", ("k1", "b1"), "none"])
def test_other_choices_are_not_judged(choice):
    assert _warned(3.61, _square(3.0), False, SimpleNamespace(self_calibration=choice)) == []


def _ebner(folder: Path, preset: str) -> Path:
    simulate_strip(12, preset=preset, seed=2).write_project(folder)
    toml = folder / "strip.toml"
    text = toml.read_text("utf-8").replace(
        "[adjustment]\n", '[adjustment]\nrefine = "bundle"\nself_calibration = "ebner12"\n'
    )
    toml.write_text(text, "utf-8")
    return toml


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_drone_strip_with_ebner12_warns_once_and_estimates_ebner_s(tmp_path):
    toml = _ebner(tmp_path, "drone")
    result = CliRunner().invoke(cli, ["run", str(toml)])
    assert result.exit_code == 0, result.output
    said = [ln for ln in result.stderr.splitlines() if '"ebner12" on a digital camera' in ln]
    assert len(said) == 1, result.stderr
    report = json.loads((tmp_path / "out" / "report.json").read_text("utf-8"))
    assert sum('"ebner12" on a digital camera' in w for w in report["warnings"]) == 1
    record = report["bundle"]["self_calibration"]
    assert record["family"] == "ebner"
    assert [p["name"] for p in record["parameters"]] == [f"e{i}" for i in range(1, 13)]


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_film_strip_with_ebner12_runs_without_the_word(tmp_path):
    toml = _ebner(tmp_path, "film")
    result = CliRunner().invoke(cli, ["run", str(toml)])
    assert result.exit_code == 0, result.output
    assert "digital camera" not in result.output
