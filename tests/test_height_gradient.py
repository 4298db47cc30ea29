"""The ratio of the control heights' gradient over a strip model to the plan
coordinates' (:func:`strip_aerotri.ground.height_units.gradient_ratio`): the
unit factor whatever the model's rotation, its standard deviation against
simulation, and the stops it adds: heights in feet on oblique strips (where
the slope of :func:`~strip_aerotri.ground.height_units.height_slope` gives 2
instead of 3.28), X, Y in feet with H in metres (the film example, the real
FC300X block, an external strip)."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from strip_aerotri.cli.main import cli
from strip_aerotri.ground.height_units import (
    GradientRatio,
    gradient_ratio,
    height_slope,
    height_unit_problems,
)

ROOT = Path(__file__).resolve().parents[1]
FILM = ROOT / "examples" / "film-strip"
SHARED = ROOT.parent / "shared" / "data"
FC300X = SHARED / "uav-block-fc300x"
ONE_INCH = SHARED / "external-strips" / "one-inch-75pct"
FEET = 1.0 / 0.3048


def _ground(n: int, seed: int, relief: float = 40.0) -> np.ndarray:
    """Ground points of a 1.2 x 0.4 km strip (metres), heights spanning ``relief``."""
    rng = np.random.default_rng(seed)
    return np.column_stack([
        rng.uniform(-600.0, 600.0, n), rng.uniform(-200.0, 200.0, n),
        100.0 + rng.uniform(0.0, relief, n),
    ])  # fmt: skip


def _model(ground: np.ndarray, tilt_deg: float, scale: float) -> np.ndarray:
    """The ground seen in a model frame whose z axis is ``tilt_deg`` from the
    vertical (a rotation about an oblique horizontal axis) and ``scale``
    times the ground's size: ground = R m / scale + t."""
    rot = Rotation.from_rotvec(np.radians(tilt_deg) * np.array([0.6, 0.8, 0.0]))
    return scale * rot.inv().apply(ground - ground.mean(axis=0)) + np.array([5.0, -3.0, 50.0])


def _ratio(model: np.ndarray, ground: np.ndarray, plan: float, height: float, sd: float = 0.05):
    n = len(ground)
    return gradient_ratio(
        model, plan * ground[:, :2], np.full(n, sd), model, height * ground[:, 2],
        np.full(n, sd),
    )  # fmt: skip


@pytest.mark.parametrize("tilt", [0.0, 5.0, 44.0, 80.0])
@pytest.mark.parametrize(("plan", "height"), [(1.0, 1.0), (1.0, FEET), (FEET, 1.0), (1.0, 10.0)])
def test_the_ratio_is_the_unit_factor_whatever_the_tilt(
    tilt: float, plan: float, height: float
) -> None:
    ground = _ground(12, 1)
    model = _model(ground, tilt, 1.3)
    got = _ratio(model, ground, plan, height)
    assert got is not None and got.ratio == pytest.approx(height / plan, rel=1e-9)
    # the slope sees the gradient's share on the model's z only: k s cos(tilt)
    # (the model frame's scale 1.3 of the ground's, so s = 1 / 1.3)
    slope = height_slope(model, height * ground[:, 2], np.full(12, 0.05))
    assert slope is not None
    assert slope[0] == pytest.approx(height * np.cos(np.radians(tilt)) / 1.3, rel=1e-6)


@pytest.mark.parametrize("n", [10, 16])
@pytest.mark.parametrize("bending", [0.0, 3.0])
def test_the_standard_deviation_matches_the_scatter_of_the_ratio(n: int, bending: float) -> None:
    """300 draws of 5 cm noise on n points over 8 m of relief, the model
    straight or bent (a cubic of 3 m at the ends); the ratio is the better
    told of the affine fit and the fit with the bending.  The stated standard
    deviation within 20 % of the ratio's own scatter.  Straight: the mean 1
    within its own precision, 1 within two standard deviations in 90-99 % of
    the draws (95 % for a normal estimate).  Bent: where the affine fit is
    chosen it keeps some bending, which moves the mean by less than one
    standard deviation (measured 0.9 % at 10 points, 0.5 % at 16; within two
    of them in 89 % and 94 % of the draws)."""
    rng = np.random.default_rng(2345)
    ground = _ground(n, 2, relief=8.0)
    model = _model(ground, 30.0, 1.0)
    model[:, 2] += bending * ((model[:, 0] - model[:, 0].mean()) / 600.0) ** 3
    ratios, stated = [], []
    for _ in range(300):
        noisy = ground + rng.normal(0.0, 0.05, ground.shape)
        got = _ratio(model, noisy, 1.0, 1.0)
        assert got is not None
        ratios.append(got.ratio)
        stated.append(got.sd)
    spread = float(np.std(ratios))
    assert np.median(stated) == pytest.approx(spread, rel=0.2)
    covered = np.mean(np.abs(np.asarray(ratios) - 1.0) < 2.0 * np.asarray(stated))
    if bending == 0.0:
        assert abs(np.mean(ratios) - 1.0) < 3.0 * spread / np.sqrt(300) + 1e-3
        assert 0.90 <= covered <= 0.99
    else:
        assert abs(np.mean(ratios) - 1.0) < spread
        assert 0.85 <= covered <= 0.99


def test_a_bent_strip_gives_its_ratio_with_the_bending_terms() -> None:
    """A strip model bent as J's polynomials bend it (a cubic in the height
    along the strip, 3 m at the ends): the affine fit alone leaves the
    bending in its scatter; the ratio keeps to 1 within 2 % and is told."""
    ground = _ground(14, 3, relief=30.0)
    model = _model(ground, 2.0, 1.0)
    along = (model[:, 0] - model[:, 0].mean()) / 600.0
    model[:, 2] += 3.0 * along**3 - 2.0 * along**2
    got = _ratio(model, ground, 1.0, 1.0, sd=0.02)
    assert got is not None
    assert abs(got.ratio - 1.0) < 0.02 and got.sd < 0.05 * got.ratio


def test_a_ratio_is_told_up_to_a_twentieth_of_it() -> None:
    assert GradientRatio(FEET, 0.05 * FEET, 4, 4).told
    assert not GradientRatio(FEET, 0.0501 * FEET, 4, 4).told
    assert not GradientRatio(FEET, float("nan"), 4, 4).told
    ground = _ground(12, 5)
    model = _model(ground, 10.0, 1.0)
    told = _ratio(model, ground, 1.0, FEET, sd=0.05)
    untold = _ratio(model, ground, 1.0, FEET, sd=10.0)  # 40 m of relief, 10 m errors
    assert told is not None and told.told and untold is not None and not untold.told


def test_the_message_counts_the_points_of_the_ratio() -> None:
    ground = _ground(12, 5)
    model = _model(ground, 44.0, 1.0)
    n = len(ground)
    problems = height_unit_problems(
        model, FEET * ground[:, 2], np.full(n, 0.05),
        plan=(model[:9], ground[:9, :2], np.full(9, 0.05)),
        given=(FEET * ground[:, 2], np.full(n, 0.05), 0.0),
    )  # fmt: skip
    assert len(problems) == 1 and "over 9 plan and 12 height points" in problems[0]


def test_too_few_points_or_points_on_one_plane_give_no_ratio() -> None:
    ground = _ground(6, 4)
    model = _model(ground, 10.0, 1.0)
    assert _ratio(model[:3], ground[:3], 1.0, 1.0) is None
    flat = ground.copy()
    flat[:, 2] = 100.0  # level ground: nothing tells the height's gradient
    flat_model = _model(flat, 10.0, 1.0)
    assert _ratio(flat_model, flat, 1.0, 1.0) is None


def _problems(tilt: float, plan: float, height: float) -> list[str]:
    ground = _ground(12, 5)
    model = _model(ground, tilt, 1.0 / plan)  # the model scaled to the plan control
    n = len(ground)
    return height_unit_problems(
        model, height * ground[:, 2], np.full(n, 0.05), file="c.csv",
        plan=(model, plan * ground[:, :2], np.full(n, 0.05)),
        given=(height * ground[:, 2], np.full(n, 0.05), 0.0),
    )  # fmt: skip


def test_heights_in_feet_on_an_oblique_strip_stop() -> None:
    # the slope alone: 3.28 cos 44 deg = 2.36, outside the window of 3.28
    ground = _ground(12, 5)
    model = _model(ground, 44.0, 1.0)
    slope = height_slope(model, FEET * ground[:, 2], np.full(12, 0.05))
    assert slope is not None and abs(slope[0] - 2.36) < 0.01
    assert height_unit_problems(model, FEET * ground[:, 2], np.full(12, 0.05)) == []
    problems = _problems(44.0, 1.0, FEET)
    assert len(problems) == 1 and problems[0].startswith("c.csv: ") and "H in feet" in problems[0]


@pytest.mark.parametrize("tilt", [0.0, 44.0])
def test_plan_in_feet_with_heights_in_metres_stops(tilt: float) -> None:
    problems = _problems(tilt, FEET, 1.0)
    assert len(problems) == 1 and "X, Y in feet with H in metres" in problems[0]


@pytest.mark.parametrize("tilt", [0.0, 44.0, 80.0])
def test_agreeing_units_pass_at_any_tilt(tilt: float) -> None:
    assert _problems(tilt, 1.0, 1.0) == []


# ----------------------------------------------------------------------------- real projects


def _copy(source: Path, tmp_path: Path, columns: str, factor: float) -> Path:
    folder = tmp_path / "project"
    shutil.copytree(source, folder, ignore=shutil.ignore_patterns("out", "out*", "truth"))
    path = folder / "control.csv"
    with path.open(newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            for c in columns.split(","):
                if row[c].strip():
                    row[c] = repr(float(row[c]) * factor)
            writer.writerow(row)
    return folder


def _refused(folder: Path, words: tuple[str, ...], commands: tuple[str, ...]) -> None:
    before = sorted(p.name for p in folder.iterdir())
    for command in commands:
        result = CliRunner().invoke(cli, [command, str(folder / "strip.toml")])
        assert result.exit_code == 1, (command, result.output)
        errors = [ln for ln in result.stderr.splitlines() if ln.startswith("stripaero: error: ")]
        assert len(errors) == 1 and "Traceback" not in result.stderr, result.stderr
        assert "control.csv: the control heights change" in errors[0]
        assert all(w in errors[0] for w in words), errors[0]
        assert len(errors[0]) < 500
    assert sorted(p.name for p in folder.iterdir()) == before  # nothing written


def test_the_film_example_with_plan_in_feet_stops(tmp_path: Path) -> None:
    # before the ratio: exit 0, the check points 67 m off in height
    _refused(_copy(FILM, tmp_path, "X,Y", FEET), ("X, Y in feet with H in metres",),
             ("check", "run"))  # fmt: skip


@pytest.fixture(scope="module")
def fc300x(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if not FC300X.is_dir():
        pytest.skip("needs ../shared/data/uav-block-fc300x")
    out = tmp_path_factory.mktemp("fc300x")
    made = CliRunner().invoke(cli, ["import", "uav-fc300x", str(FC300X), "-o", str(out)])
    assert made.exit_code == 0, made.output
    return out


@pytest.mark.parametrize(
    ("columns", "named"), [("H", "H in feet"), ("X,Y", "X, Y in feet with H in metres")]
)
def test_the_fc300x_block_in_feet_stops(
    fc300x: Path, tmp_path: Path, columns: str, named: str
) -> None:
    # oblique photos: the slope gives 1.9-2.2 for heights in feet, 0.18-0.21
    # for X, Y in feet, and neither stopped before the ratio
    _refused(_copy(fc300x, tmp_path, columns, FEET), (named,), ("check",))


def test_the_fc300x_block_as_imported_passes(fc300x: Path) -> None:
    result = CliRunner().invoke(cli, ["-qq", "check", str(fc300x / "strip.toml")])
    assert result.exit_code == 0, result.stderr


@pytest.mark.skipif(not ONE_INCH.is_dir(), reason="needs ../shared/data/external-strips")
def test_an_external_strip_with_plan_in_feet_stops(tmp_path: Path) -> None:
    _refused(_copy(ONE_INCH, tmp_path, "X,Y", FEET), ("X, Y in feet with H in metres",),
             ("check",))  # fmt: skip


def test_without_a_ratio_the_slope_decides() -> None:
    """Three plan points give no plan gradient: the slope stops heights in
    feet on a level model, as it did alone; on a model 44 degrees from the
    vertical it cannot (3.28 cos 44 = 2.36), the limit the ratio lifts."""
    ground = _ground(12, 6)
    n = len(ground)
    for tilt, stops in ((0.0, True), (44.0, False)):
        model = _model(ground, tilt, 1.0)
        problems = height_unit_problems(
            model, FEET * ground[:, 2], np.full(n, 0.05),
            plan=(model[:3], ground[:3, :2], np.full(3, 0.05)),
            given=(FEET * ground[:, 2], np.full(n, 0.05), 0.0),
        )  # fmt: skip
        assert bool(problems) is stops, (tilt, problems)
        if stops:
            assert "the strip's heights" in problems[0] and "H in feet" in problems[0]


def test_the_model_heights_error_is_taken_to_the_heights_unit() -> None:
    """X, Y in feet: the model heights' expected error, in the plan's unit,
    is 3.28 times too large for H in metres; the ratio's second fit weights
    the heights with it times the first ratio, and its standard deviation
    is then the one of the same project in metres (within 10 %)."""
    rng = np.random.default_rng(7)
    ground = _ground(12, 7, relief=6.0)
    noisy = ground + np.column_stack([np.zeros((12, 2)), rng.normal(0.0, 0.1, 12)])
    n = len(ground)
    fits = []
    for plan in (1.0, FEET):
        model = _model(ground, 3.0, 1.0) * plan  # scaled to the plan control
        fits.append(gradient_ratio(
            model, plan * ground[:, :2], np.full(n, 0.01), model, noisy[:, 2],
            np.full(n, 0.01), 0.1 * plan,
        ))  # fmt: skip
    metres, feet = fits
    assert metres is not None and feet is not None
    assert feet.ratio == pytest.approx(metres.ratio / FEET, rel=1e-9)
    assert feet.sd / feet.ratio == pytest.approx(metres.sd / metres.ratio, rel=0.1)
