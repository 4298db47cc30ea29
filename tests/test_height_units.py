"""Control heights in another unit than the plan control (feet, US survey
feet, decimetres with X, Y in metres): the slope of the control heights
against the strip's heights scaled to the plan control
(:func:`strip_aerotri.ground.height_units.height_slope`), and the stop of the
ground stage, ``stripaero run`` and ``stripaero check`` on it."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli
from strip_aerotri.errors import HeightUnitError
from strip_aerotri.geodesy import GroundCRS
from strip_aerotri.ground.common import control_rows, resolve_route
from strip_aerotri.ground.height_units import gradient_ratio, height_slope, height_unit_problems
from strip_aerotri.ground.polynomials import (
    _first_look,
    _unit_inputs,
    adjust_to_ground,
    height_unit_check,
)
from strip_aerotri.observations import ControlPoints
from strip_aerotri.pipeline import form_strip_of
from strip_aerotri.project import Project, load_project
from strip_aerotri.results import StripModel

ROOT = Path(__file__).resolve().parents[1]
FILM = ROOT / "examples" / "film-strip"
FEET = 1.0 / 0.3048
US_FEET = 3937.0 / 1200.0


def _model(n: int, relief: float, seed: int = 0) -> np.ndarray:
    """Strip-model points (plan units): a 6 x 1.5 km strip, heights spanning ``relief``."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 6000.0, n)
    y = rng.uniform(-750.0, 750.0, n)
    z = rng.uniform(0.0, relief, n)
    return np.column_stack([x, y, z])


def _heights(model: np.ndarray, factor: float) -> np.ndarray:
    """Ground heights of the model's points in a unit ``factor`` times smaller
    than the plan's: the model tilted (2e-2 along, -1e-2 across) and raised."""
    x, y, z = model.T
    return factor * (120.0 + z + 0.02 * x - 0.01 * y)


def _fit(model: np.ndarray, h: np.ndarray, sigma: float) -> tuple[float, float]:
    fit = height_slope(model, h, np.full(h.size, sigma))
    assert fit is not None
    return fit


@pytest.mark.parametrize("factor", [1.0, FEET, US_FEET, 0.3048, 10.0])
def test_the_slope_is_the_unit_factor_through_the_model_tilt(factor: float) -> None:
    model = _model(8, 80.0)
    s, sd = _fit(model, _heights(model, factor), 0.1)
    assert s == pytest.approx(factor, rel=1e-10)
    # no redundant scatter: the expected error alone, 0.1 m over an 80 m span
    assert 0.0 < sd < 0.01


def test_three_points_give_the_slope_without_a_tilt() -> None:
    model = np.array([[0.0, 0.0, 10.0], [3000.0, 200.0, 60.0], [6000.0, -300.0, 25.0]])
    h = FEET * (50.0 + model[:, 2])  # level: a tilt cannot be told from three points
    fit = height_slope(model, h, np.full(3, 0.1))
    assert fit is not None and fit[0] == pytest.approx(FEET, rel=1e-12)
    assert height_slope(model[:2], h[:2], np.full(2, 0.1)) is None


def test_height_points_on_one_line_leave_the_cross_tilt_out() -> None:
    model = _model(6, 60.0)
    model[:, 1] = 0.0  # every height point on the strip's axis
    fit = height_slope(model, _heights(model, 10.0), np.full(6, 0.1))
    assert fit is not None and fit[0] == pytest.approx(10.0, rel=1e-10)


def test_scatter_beyond_the_expected_error_widens_the_slope() -> None:
    model = _model(12, 80.0)
    h = _heights(model, 1.0)
    noise = np.random.default_rng(1).normal(0.0, 2.0, 12)
    _, sd_clean = _fit(model, h, 0.1)
    s, sd = _fit(model, h + noise, 0.1)
    assert sd > 5.0 * sd_clean
    assert abs(s - 1.0) < 4.0 * sd


@pytest.mark.parametrize(
    ("factor", "named"),
    [
        (FEET, "H in feet"),
        (US_FEET, "H in feet"),
        (10.0, "H in decimetres"),
        (0.1, "X, Y in decimetres"),
    ],
)
def test_a_unit_factor_stops_with_the_file_and_the_unit(factor: float, named: str) -> None:
    model = _model(8, 80.0)
    problems = height_unit_problems(
        model, _heights(model, factor), np.full(8, 0.1), file="ctl.csv"
    )
    assert len(problems) == 1
    assert problems[0].startswith("ctl.csv: ") and named in problems[0]
    assert "\n" not in problems[0]


# the slope alone lets 0.3048 (X, Y in feet) through: an oblique strip's
# model tilt lowers it to 0.57-0.66 with agreeing units (the FC300X block);
# the gradient ratio, given the plan control, names it (test_height_gradient)
@pytest.mark.parametrize("factor", [1.0, 0.3048, 0.6, 1.3, 2.0, 5.0])
def test_slopes_away_from_every_unit_factor_pass(factor: float) -> None:
    model = _model(8, 80.0)
    assert height_unit_problems(model, _heights(model, factor), np.full(8, 0.1)) == []


def test_too_little_relief_to_tell_passes() -> None:
    # 0.5 m of relief against 0.3 m expected errors: the slope's standard
    # deviation is far above 5 % of it, heights in feet pass untold
    model = _model(6, 0.5)
    assert _fit(model, _heights(model, FEET), 0.3)[1] > 0.05 * FEET
    assert height_unit_problems(model, _heights(model, FEET), np.full(6, 0.3)) == []


# ----------------------------------------------------------------------------- the film example


def _copy_with_heights(tmp_path: Path, factor: float) -> Path:
    folder = tmp_path / "film"
    shutil.copytree(FILM, folder, ignore=shutil.ignore_patterns("out", "out*"))
    _scale_heights(folder / "control.csv", factor)
    return folder


def _scale_heights(path: Path, factor: float) -> None:
    """Every height of the control file ``path`` multiplied by ``factor``."""
    with path.open(newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            if row["H"]:
                row["H"] = repr(float(row["H"]) * factor)
            writer.writerow(row)


@pytest.fixture(scope="module")
def film_strip() -> tuple[Project, StripModel]:
    project = load_project(FILM / "strip.toml")
    return project, form_strip_of(
        project.observations, project.adjustment, blunders=project.blunders
    )


def _scaled(control: ControlPoints, factor: float) -> ControlPoints:
    xyz = control.xyz.copy()
    xyz[:, 2] *= factor
    return ControlPoints(
        control.point_ids, xyz, control.kind, control.sigma_xy, control.sigma_h * factor,
        control.source_line,
    )  # fmt: skip


@pytest.mark.parametrize("factor", [FEET, 10.0])
def test_the_ground_stage_stops_on_the_film_example_in_another_unit(
    film_strip: tuple[Project, StripModel], factor: float
) -> None:
    project, strip = film_strip
    control = _scaled(project.control, factor)
    with pytest.raises(HeightUnitError, match=r"^heights\.csv: .*H in (feet|decimetres)"):
        adjust_to_ground(strip, control, project.crs, control_name="heights.csv")
    assert height_unit_check(strip, control, project.crs, control_name="c.csv")[0].startswith(
        "c.csv: "
    )


def test_the_film_example_in_metres_passes(film_strip: tuple[Project, StripModel]) -> None:
    project, strip = film_strip
    assert height_unit_check(strip, project.control, project.crs) == []


@pytest.mark.parametrize("factor", [1.0, FEET])
def test_the_unit_inputs_are_the_ground_stages(
    film_strip: tuple[Project, StripModel], factor: float
) -> None:
    """The inputs of the unit test read off the first look: the plan and
    height control's rows, the ratio of the heights' gradient to the plan's
    at the heights' unit factor (film example: 8 plan, 12 height points),
    the plan control's expected errors its own and the photogrammetric
    ones, and the same verdict as :func:`height_unit_check`."""
    project, strip = film_strip
    control = _scaled(project.control, factor)
    crs = GroundCRS.from_user_input(project.crs)
    picked = control_rows(strip, control)
    first = _first_look(strip, picked, crs, resolve_route(project.adjustment.route, crs))
    inputs = _unit_inputs(first, picked)
    n_plan, n_height = int(picked.use_xy.sum()), int(picked.use_z.sum())
    assert (n_plan, n_height) == (8, 12)
    assert inputs["model_xyz"].shape == (n_height, 3) and inputs["plan"][0].shape == (n_plan, 3)
    np.testing.assert_array_equal(inputs["given"][0], control.xyz[picked.rows[picked.use_z], 2])
    # the photogrammetric plan error: the median image error at the image scale
    sigma_plan = np.median(strip.observations.sigma) * first.metres_per_mm
    np.testing.assert_allclose(
        first.exp_xy**2 - picked.sigma_xy**2, sigma_plan**2, rtol=1e-9, atol=1e-15
    )
    ratio = gradient_ratio(*inputs["plan"], inputs["model_xyz"], *inputs["given"])
    assert ratio is not None and ratio.told and abs(ratio.ratio - factor) < 3.0 * ratio.sd
    problems = height_unit_problems(**inputs, file="c.csv")
    assert problems == height_unit_check(strip, control, project.crs, control_name="c.csv")
    assert bool(problems) is (factor != 1.0)


@pytest.mark.parametrize("command", ["run", "check"])
def test_the_cli_stops_on_heights_in_feet(tmp_path: Path, command: str) -> None:
    folder = _copy_with_heights(tmp_path, FEET)
    before = sorted(p.name for p in folder.iterdir())
    result = CliRunner().invoke(cli, [command, str(folder / "strip.toml")])
    assert result.exit_code == 1
    lines = [ln for ln in result.stderr.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("stripaero: error: ")]
    assert len(errors) == 1 and "Traceback" not in result.stderr
    assert "control.csv: " in errors[0] and "feet" in errors[0]
    assert sorted(p.name for p in folder.iterdir()) == before  # nothing written


def test_a_block_in_feet_stops_naming_the_control(tmp_path: Path) -> None:
    out = tmp_path / "block"
    made = CliRunner().invoke(
        cli, ["simulate", "film", "--strips", "2", "--photos", "8", "--out", str(out)]
    )
    assert made.exit_code == 0, made.output
    fine = CliRunner().invoke(cli, ["-qq", "check", str(out / "strip.toml")])
    assert fine.exit_code == 0, fine.stderr
    path = out / "control.csv"
    _scale_heights(path, FEET)
    for command in ("run", "check"):
        result = CliRunner().invoke(cli, [command, str(out / "strip.toml")])
        assert result.exit_code == 1, (command, result.output)
        errors = [ln for ln in result.stderr.splitlines() if ln.startswith("stripaero: error: ")]
        assert len(errors) == 1, (command, result.stderr)
        assert f"{path}: the control heights" in errors[0] and "feet" in errors[0]
    assert not (out / "out").exists()


def test_the_models_construction_stops_as_well(film_strip: tuple[Project, StripModel]) -> None:
    from strip_aerotri.ground.models import adjust_models_to_ground

    project, strip = film_strip
    with pytest.raises(HeightUnitError, match=r"^c\.csv: .*H in feet") as caught:
        adjust_models_to_ground(
            strip, _scaled(project.control, US_FEET), project.crs, control_name="c.csv"
        )
    assert caught.value.detail.startswith("the control heights change 3.2")


def test_the_block_names_the_control_it_is_given() -> None:
    # the name goes down to the placement of the strips (adjust_block ->
    # _prepare -> _start_in_crs), as adjust_to_ground's does
    from strip_aerotri.block.strips import adjust_block
    from strip_aerotri.observations import StripSpec
    from strip_aerotri.simulate import simulate_block

    sim = simulate_block(n_strips=2, n_photos_per_strip=8, preset="film", seed=4)
    strips = [StripSpec(s.name, s.photo_ids) for s in sim.strips]
    control = _scaled(sim.control, FEET)
    with pytest.raises(HeightUnitError, match=r"^heights\.csv: the control heights .*feet") as e:
        adjust_block(sim.observations, control, sim.crs, strips, control_name="heights.csv")
    assert str(e.value) == f"heights.csv: {e.value.detail}"
    with pytest.raises(HeightUnitError, match=r"^control: the control heights"):
        adjust_block(sim.observations, control, sim.crs, strips)
