"""benchmarks/bench_height_units.py: the unit changes it makes and its
measures on the film example, the ground stage's verdict among them."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.ground.polynomials import height_unit_check
from strip_aerotri.observations import ControlType
from strip_aerotri.project import Project, load_project

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
import bench_height_units as bench

FEET = 1.0 / 0.3048


@pytest.fixture(scope="module")
def film() -> tuple[Project, object]:
    project = load_project(ROOT / "examples" / "film-strip" / "strip.toml")
    ((name, strip),) = bench.strips_of(project)
    assert name == "strip"
    return project, strip


def test_a_change_scales_the_coordinates_columns_only(film: tuple[Project, object]) -> None:
    control = film[0].control
    before = control.xyz.copy()
    moved = bench.changed(control, FEET, 10.0)
    np.testing.assert_array_equal(moved.xyz, before * np.array([FEET, FEET, 10.0]))
    np.testing.assert_array_equal(control.xyz, before)  # the original as it was
    for name in ("point_ids", "kind", "sigma_xy", "sigma_h", "source_line"):
        assert getattr(moved, name) is getattr(control, name)


@pytest.mark.parametrize(
    ("plan", "height", "verdict"),
    [(1.0, 1.0, "pass"), (1.0, FEET, "H in feet"), (1.0, 10.0, "H in decimetres")],
)
def test_the_measures_and_the_ground_stages_verdict(
    film: tuple[Project, object], plan: float, height: float, verdict: str
) -> None:
    project, strip = film
    control = bench.changed(project.control, plan, height)
    m = bench.measure(project, strip, control)
    assert m["by"] == "ratio" and m["verdict"] == verdict
    assert m["ratio"].told and abs(m["ratio"].ratio - height / plan) < 3.0 * m["ratio"].sd
    assert (m["ratio"].n_plan, m["ratio"].n_height) == (8, 12)
    problems = height_unit_check(strip, control, project.crs)
    assert bool(problems) is (verdict != "pass") and all(verdict in p for p in problems)


def test_control_too_scant_for_the_first_look_passes(film: tuple[Project, object]) -> None:
    project, strip = film
    control = project.control
    heights = dataclasses.replace(  # height control alone: no plan point
        control,
        kind=tuple(
            ControlType.HEIGHT if k is ControlType.FULL
            else ControlType.CHECK if k is ControlType.PLAN else k
            for k in control.kind
        ),
    )  # fmt: skip
    assert heights.uses_h.any() and not heights.uses_xy.any()
    m = bench.measure(project, strip, heights)
    assert m == {"slope": None, "ratio": None, "by": "-", "verdict": "pass (no similarity)"}
    assert height_unit_check(strip, heights, project.crs) == []
