"""Implausible input found by the catalogue fuzz (``benchmarks/fuzz_inputs.py``).

Control plan coordinates and heights in different units (X, Y in km with
H in m): ``plausibility.control_relief_problems``, against the same rule
written photo by photo, and through ``stripaero check`` and ``run``; image
coordinates from a corner of the format; a reversed image axis.

Before this check, the film example with X and Y divided by 1000 passed
``stripaero check`` and stopped the run with "similarity transformation did
not converge", which names no cause.
"""

from __future__ import annotations

import dataclasses
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import strip_aerotri as sa
from strip_aerotri.cli.main import cli
from strip_aerotri.plausibility import (
    _RELIEF_FACTOR,
    control_problems,
    control_relief_problems,
    image_coordinate_problems,
)
from strip_aerotri.project import load_project

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _point_index(obs: sa.ImageObservations, ids: tuple[str, ...]) -> np.ndarray:
    lookup = {p: i for i, p in enumerate(obs.point_ids)}
    return np.array([lookup.get(p, -1) for p in ids], dtype=np.intp)


def _by_loop(obs: sa.ImageObservations, control: sa.ControlPoints) -> tuple[float, float]:
    """(median span of the control heights per photo, camera above ground),
    photo by photo, every pair of plan points on a photo by a double loop."""
    where = {p: i for i, p in enumerate(control.point_ids)}
    xyz = control.xyz
    spans: list[float] = []
    on_photo: list[float] = []
    ground: list[float] = []
    for k in range(obs.n_photos):
        seen = [
            (o, where.get(obs.point_ids[obs.point[o]], -1)) for o in np.flatnonzero(obs.photo == k)
        ]
        plan = [(o, r) for o, r in seen if r >= 0 and np.isfinite(xyz[r, :2]).all()]
        heights = [xyz[r, 2] for _, r in seen if r >= 0 and np.isfinite(xyz[r, 2])]
        if len(heights) >= 2:
            spans.append(max(heights) - min(heights))
        for u in range(len(plan)):
            for v in range(u + 1, len(plan)):
                (o1, r1), (o2, r2) = plan[u], plan[v]
                on_photo.append(float(np.hypot(*(obs.xy[o1] - obs.xy[o2]))))
                ground.append(float(np.hypot(*(xyz[r1, :2] - xyz[r2, :2]))))
    on = np.maximum(np.array(on_photo), 0.05 * np.median(on_photo))
    scale = float(np.median(np.array(ground) / on))
    return float(np.median(spans)), scale * obs.principal_distance


def _scaled(control: sa.ControlPoints, plan: float, height: float) -> sa.ControlPoints:
    xyz = control.xyz * np.array([plan, plan, height])
    return dataclasses.replace(control, xyz=xyz)


@pytest.fixture(scope="module", params=["film", "drone"])
def strip(request: pytest.FixtureRequest) -> sa.SimulatedStrip:
    return sa.simulate_strip(10, preset=request.param, crs="EPSG:32634", seed=4)


def test_true_units_pass_and_the_figures_match_a_loop(strip: sa.SimulatedStrip) -> None:
    obs, control = strip.observations, strip.control
    point = _point_index(obs, control.point_ids)
    assert control_relief_problems(obs, point, control.xyz) == []
    span, above = _by_loop(obs, control)
    assert span < 0.2 * above  # the simulated relief: a few per cent of the flying height
    # X, Y in km: the camera 1000 times lower, the same span
    (message,) = control_relief_problems(obs, point, _scaled(control, 1e-3, 1.0).xyz)
    # the figures in the units they are in, which is what is in doubt (not "m")
    numbers = re.search(
        r"span ([0-9.e+-]+) in H's unit .* camera about ([0-9.e+-]+) in X, Y's unit above", message
    )
    assert numbers is not None, message
    assert float(numbers.group(1)) == pytest.approx(span, rel=1e-3)
    assert float(numbers.group(2)) == pytest.approx(above * 1e-3, rel=1e-3)
    assert "X, Y in km" in message


@pytest.mark.parametrize(
    ("plan", "height", "found"),
    [(1e-3, 1.0, True), (1.0, 1e3, True), (1.0, 1.0 / 0.3048, False), (1e3, 1e3, False)],
    ids=["XY-km", "H-mm", "H-feet-too-small-to-tell", "all-in-mm"],
)
def test_only_a_disagreement_beyond_the_flying_height_is_found(
    strip: sa.SimulatedStrip, plan: float, height: float, found: bool
) -> None:
    obs, control = strip.observations, strip.control
    point = _point_index(obs, control.point_ids)
    span, above = _by_loop(obs, control)
    expected = span * height > _RELIEF_FACTOR * above * plan
    assert expected is found
    assert bool(control_relief_problems(obs, point, _scaled(control, plan, height).xyz)) is found


def test_a_geographic_crs_is_left_out() -> None:
    sim = sa.simulate_strip(8, preset="film", crs="EPSG:4326", seed=1)
    km = _scaled(sim.control, 1.0, 1e3)  # heights in mm: under degrees nothing can be said
    assert control_problems(sim.observations, km, "EPSG:4326") == []


def test_no_height_points_on_a_common_photo_finds_nothing(strip: sa.SimulatedStrip) -> None:
    obs, control = strip.observations, strip.control
    xyz = control.xyz.copy()
    xyz[:, 2] = np.nan
    point = _point_index(obs, control.point_ids)
    assert control_relief_problems(obs, point, xyz) == []


@pytest.mark.parametrize("example", ["film-strip", "drone-corridor"])
def test_control_in_km_is_one_line_in_check_and_run(tmp_path: Path, example: str) -> None:
    folder = tmp_path / example
    shutil.copytree(EXAMPLES / example, folder, ignore=shutil.ignore_patterns("out"))
    lines = (folder / "control.csv").read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    ix, iy = header.index("X"), header.index("Y")
    out = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        for i in (ix, iy):
            if cells[i].strip():
                cells[i] = repr(float(cells[i]) / 1000.0)
        out.append(",".join(cells))
    (folder / "control.csv").write_text("\n".join(out) + "\n", encoding="utf-8")
    for command in ("check", "run"):
        result = CliRunner().invoke(cli, [command, str(folder / "strip.toml")])
        assert result.exit_code == 1, result.output
        (line,) = result.stderr.splitlines()
        assert line.startswith("stripaero: error: "), line
        assert "control.csv" in line and "X, Y in km" in line, line
        assert len(line) < 500
    assert not (folder / "out").exists()


def test_a_reversed_image_axis_is_named_beside_swapped_control(tmp_path: Path) -> None:
    """Image y measured downwards (as pixel rows run) mirrors the photos
    against the control as swapped X and Y do: the message names both
    causes (it named the control's columns only, whatever was wrong)."""
    folder = tmp_path / "film"
    shutil.copytree(EXAMPLES / "film-strip", folder, ignore=shutil.ignore_patterns("out"))
    images = folder / "image_points.csv"
    lines = images.read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    iy = header.index("y")
    flipped = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[iy] = repr(-float(cells[iy]))
        flipped.append(",".join(cells))
    images.write_text("\n".join(flipped) + "\n", encoding="utf-8")
    result = CliRunner().invoke(cli, ["run", str(folder / "strip.toml")])
    assert result.exit_code == 1
    (line,) = result.stderr.splitlines()
    assert "control is mirrored against the photos" in line, line
    assert "X and Y columns swapped" in line and "one image axis reversed" in line, line
    assert len(line) < 500


def _shift_images(folder: Path, dx: float | None = None, dy: float | None = None) -> None:
    """x, y moved by dx, dy (default: half their range, as from the format's corner)."""
    images = folder / "image_points.csv"
    lines = images.read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    ix, iy = header.index("x"), header.index("y")
    rows = [line.split(",") for line in lines[1:]]
    for i, d in ((ix, dx), (iy, dy)):
        values = [float(r[i]) for r in rows]
        shift = 0.5 * (max(values) - min(values)) if d is None else d
        for r in rows:
            r[i] = repr(float(r[i]) + shift)
    images.write_text("\n".join([lines[0], *map(",".join, rows)]) + "\n", encoding="utf-8")


def test_image_points_off_centre_by_the_rule_and_its_figures() -> None:
    obs = load_project(EXAMPLES / "drone-corridor" / "strip.toml").observations
    xy = np.asarray(obs.xy)
    assert image_coordinate_problems(xy, obs.principal_distance) == []
    moved = xy + 0.5 * np.ptp(xy, axis=0)
    (message,) = image_coordinate_problems(moved, obs.principal_distance, file="i.csv")
    low, high = moved.min(axis=0), moved.max(axis=0)
    assert message.startswith("i.csv: the image points are not centred"), message
    assert (
        f"x from {low[0]:.4g} to {high[0]:.4g} mm, y from {low[1]:.4g} to {high[1]:.4g}" in message
    )
    # both axes beyond the rule's half of the half range are needed
    half = 0.5 * np.ptp(xy, axis=0)
    assert image_coordinate_problems(xy + 0.6 * half, obs.principal_distance)
    assert (
        image_coordinate_problems(xy + np.array([0.0, 0.6 * half[1]]), obs.principal_distance)
        == []
    )
    assert image_coordinate_problems(xy + 0.4 * half, obs.principal_distance) == []
    # too few points to tell
    assert image_coordinate_problems(moved[:19], obs.principal_distance) == []


def test_a_strip_along_a_coast_is_not_off_centre() -> None:
    """A strip flown along a shore sees land on one side of its flight line
    only: its image points lie on one side across the flight (y), spread
    along it (x) by the forward overlap.  That is a real project, not a
    corner origin (the rule on one axis refused it)."""
    obs = load_project(EXAMPLES / "drone-corridor" / "strip.toml").observations
    xy = np.asarray(obs.xy)
    land = xy[xy[:, 1] < -0.2 * np.ptp(xy[:, 1]) / 2]
    low, high = land.min(axis=0), land.max(axis=0)
    assert abs(0.5 * (low[1] + high[1])) > 0.5 * (0.5 * (high[1] - low[1]))  # y off-centre
    assert image_coordinate_problems(land, obs.principal_distance) == []


@pytest.mark.parametrize("example", ["drone-corridor", "film-strip"])
def test_image_points_from_the_format_corner_are_one_line(tmp_path: Path, example: str) -> None:
    """The corridor's ran to exit 0 with check points at 10.9 m plan and
    11.5 m height; the film's was called 'a typing error' of 35 points."""
    folder = tmp_path / example
    shutil.copytree(EXAMPLES / example, folder, ignore=shutil.ignore_patterns("out"))
    _shift_images(folder)
    for command in ("check", "run"):
        result = CliRunner().invoke(cli, [command, str(folder / "strip.toml")])
        assert result.exit_code == 1, result.output
        (line,) = result.stderr.splitlines()
        assert "image_points.csv: the image points are not centred" in line, line
        assert "measured from a corner of the format" in line and len(line) < 500
    assert not (folder / "out").exists()


def test_a_corner_origin_is_named_before_the_distortion_it_breaks(tmp_path: Path) -> None:
    """With a [distortion] of the projection model (the FC300X block's
    coefficients), coordinates from the format's corner broke its inversion
    first: the run said 'check the coefficients and their units'."""
    folder = tmp_path / "corridor"
    shutil.copytree(EXAMPLES / "drone-corridor", folder, ignore=shutil.ignore_patterns("out"))
    toml = folder / "strip.toml"
    lens = (
        '\n[distortion]\nunits = "normalized"\nmodel = "projection"\nk1 = -0.0114\nk2 = 0.0148\n'
    )
    toml.write_text(toml.read_text(encoding="utf-8") + lens, encoding="utf-8")
    assert CliRunner().invoke(cli, ["check", str(toml)]).exit_code == 0
    _shift_images(folder)
    for command in ("check", "run"):
        result = CliRunner().invoke(cli, [command, str(toml)])
        assert result.exit_code == 1
        (line,) = result.stderr.splitlines()
        assert "image_points.csv: the image points are not centred" in line, line
        assert "the [distortion] could not be removed from them" in line and len(line) < 500
