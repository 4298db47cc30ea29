"""Mistakes in the camera inputs (``[camera]``, ``[distortion]``,
``[adjustment] self_calibration``) found by the catalogue fuzz
(``benchmarks/fuzz_inputs.py``, its camera entries): each is one line
naming the key and the likely cause.

Before these checks, a principal point beyond the format's edge along the
flight ran to exit 0 (the drone corridor with [7.0, 0.0] mm: check points at
5 m instead of 0.1 m); a principal point in pixels, or a k1 a million times too
large, was blamed on the image coordinates ("not in millimetres"); a k1 for
normalised coordinates read as mm folded the drone format and stopped the run
on the image sigma; and ``self_calibration = []`` said "got a list".
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli
from strip_aerotri.errors import ConfigError
from strip_aerotri.interior import BrownDistortion, correct_distortion
from strip_aerotri.plausibility import image_coordinate_problems
from strip_aerotri.project import load_project

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _project(tmp_path: Path, example: str, old: str, new: str) -> Path:
    folder = tmp_path / example
    shutil.copytree(EXAMPLES / example, folder, ignore=shutil.ignore_patterns("out"))
    toml = folder / "strip.toml"
    text = toml.read_text(encoding="utf-8")
    assert old in text
    toml.write_text(text.replace(old, new, 1), encoding="utf-8")
    return toml


def _camera(tmp_path: Path, example: str, lines: str) -> Path:
    """``lines`` added to the example's [camera] table."""
    return _project(tmp_path, example, "[camera]\n", f"[camera]\n{lines}\n")


def _lens(tmp_path: Path, example: str, table: str) -> Path:
    """A [distortion] table added to the example."""
    return _project(tmp_path, example, "[images]\n", f"[distortion]\n{table}\n\n[images]\n")


def _one_line(toml: Path, *words: str) -> None:
    """check and run: exit 1, one line holding the words, no result folder."""
    for command in ("check", "run"):
        result = CliRunner().invoke(cli, [command, str(toml)])
        assert result.exit_code == 1, result.output
        (line,) = result.stderr.splitlines()
        assert line.startswith("stripaero: error: ") and len(line) < 500, line
        for word in words:
            assert word in line, (word, line)
    assert not (toml.parent / "out").exists()


# ---------------------------------------------------------------- the principal point


def test_flight_axis_off_centre_alone_is_a_problem() -> None:
    """Along the flight the forward overlap spreads the points on both sides of
    the principal point: a middle beyond half the half range there alone is
    refused (across it, alone, it is a strip along a coast: allowed)."""
    obs = load_project(EXAMPLES / "drone-corridor" / "strip.toml").observations
    xy = np.asarray(obs.xy)
    half = 0.5 * np.ptp(xy, axis=0)
    c = obs.principal_distance
    (message,) = image_coordinate_problems(xy + half * [0.6, 0.0], c, file="i.csv")
    assert message.startswith(
        "i.csv: the image points are not centred on the principal point along the flight"
    ), message
    assert image_coordinate_problems(xy + half * [0.4, 0.0], c) == []
    assert image_coordinate_problems(xy + half * [0.0, 0.6], c) == []


@pytest.mark.parametrize(
    ("example", "principal_point", "said"),
    [
        # beyond the 4.4 mm half format along the flight, and the 6.6 mm across
        ("drone-corridor", "[5.0, 0.0]", "lies outside the image points"),
        ("drone-corridor", "[0.0, -7.0]", "lies outside the image points"),
        # inside the format, 0.68 of its half off the middle along the flight
        ("drone-corridor", "[3.0, 0.0]", "lies far off the middle of the image points"),
        # pixels of the 5472 x 3648 sensor, of 10 um film scans
        ("drone-corridor", "[2736.0, 1824.0]", "lies outside the image points"),
        ("film-strip", "[11500.0, 11500.0]", "lies outside the image points"),
    ],
)
def test_a_principal_point_outside_the_format_is_named(
    tmp_path: Path, example: str, principal_point: str, said: str
) -> None:
    toml = _camera(tmp_path, example, f"principal_point_mm = {principal_point}")
    _one_line(
        toml,
        f"[camera] principal_point_mm = {principal_point.replace('.0', '')} {said}",
        "in pixels, or from another origin?",
    )


def test_a_plausible_principal_point_still_runs(tmp_path: Path) -> None:
    """0.3 mm (120 pixels) off the image centre: unusual, not impossible."""
    toml = _camera(tmp_path, "drone-corridor", "principal_point_mm = [0.3, -0.2]")
    assert load_project(toml).camera.principal_point_mm.tolist() == [0.3, -0.2]


def test_coordinates_from_the_corner_are_still_the_coordinates(tmp_path: Path) -> None:
    """Measurements that are implausible without the camera are named as the
    coordinates, whatever the principal point."""
    toml = _camera(tmp_path, "film-strip", "principal_point_mm = [0.01, 0.02]")
    images = toml.parent / "image_points.csv"
    header, *rows = images.read_text(encoding="utf-8").splitlines()
    scaled = [r.split(",") for r in rows]
    for r in scaled:
        r[2], r[3] = repr(float(r[2]) * 1000), repr(float(r[3]) * 1000)
    images.write_text("\n".join([header, *map(",".join, scaled)]) + "\n", encoding="utf-8")
    _one_line(toml, "image_points.csv", "the coordinates are not in millimetres")


# ---------------------------------------------------------------- the distortion


@pytest.mark.parametrize(
    ("example", "table", "words"),
    [
        # k1 a million times too large: moved by 1e5 mm (was "not in millimetres")
        ("drone-corridor", "k1 = -300.0", ("k1 = -300,", "moves a point", "more than its")),
        ("film-strip", "k1 = -3e-2", ("k1 = -0.03,", "moves a point")),
        ("film-strip", "k1 = 3e-2", ("k1 = 0.03,", "moves a point")),
        # the FC300X k1 for normalised coordinates read as mm on the 8.8 mm
        # lens: folds the format's outer third (was "the image sigma")
        ("drone-corridor", "k1 = -0.0114", ("k1 = -0.0114,", "folds the image beyond")),
        ("drone-corridor", "b1 = 1.5", ("b1 is 1.5, an affinity",)),
        # an affinity or shear in percent: 50 % (it stopped the run on its
        # control: "more than 20% of the control observations fail")
        ("film-strip", "b1 = 0.5", ("b1 is 0.5, an affinity of more than 1%",)),
        ("drone-corridor", "b2 = -0.02", ("b2 is -0.02, a shear of more than 1%",)),
    ],
)
def test_an_impossible_distortion_is_named(
    tmp_path: Path, example: str, table: str, words: tuple[str, ...]
) -> None:
    toml = _lens(tmp_path, example, table)
    _one_line(toml, "strip.toml: [distortion] (", *words)


def test_the_fold_rule_against_a_dense_radial_profile() -> None:
    """The rule (1 + 3 k1 r² + ... <= 0 at a measured radius) against the
    corrected radius itself on a fine radial line: it falls first beyond
    r = 1/sqrt(-3 k1) (Brown's correction model, radial terms only)."""
    k1 = -0.0114
    lens = BrownDistortion(k1=k1)
    r = np.linspace(0.0, 7.5, 15001)
    corrected = correct_distortion(np.column_stack([r, np.zeros_like(r)]), lens, 8.8)[:, 0]
    falls = r[1:][np.diff(corrected) <= 0.0]
    assert falls.min() == pytest.approx(1.0 / np.sqrt(-3.0 * k1), abs=1e-3)


@pytest.mark.parametrize(
    "table",
    [
        "k1 = -3e-4\nk2 = 2e-6",  # a wide-angle drone lens, tens of micrometres
        'units = "normalized"\nmodel = "projection"\nk1 = -0.0114\nk2 = 0.0148',  # FC300X
        "k1 = 3e-4\np1 = 1e-5\np2 = -1e-5\nb1 = 1e-4\nb2 = -1e-4",
    ],
)
def test_a_plausible_distortion_still_loads(tmp_path: Path, table: str) -> None:
    project = load_project(_lens(tmp_path, "drone-corridor", table))
    assert project.observations.xy.shape[0] > 300


# ---------------------------------------------------------------- self_calibration


@pytest.mark.parametrize(
    ("value", "said"),
    [
        ("[]", 'got an empty list (to estimate nothing: "none")'),
        ('"k1"', 'got the string "k1" (one parameter is a list too: ["k1"])'),
        ('["k1", 2]', "got a list whose item 2 is the number 2 (names in quotes"),
        ('"ebner"', 'got the string "ebner" (did you mean "ebner12"?)'),
        ("true", "got the boolean true"),
    ],
)
def test_a_refused_self_calibration_says_what_was_meant(
    tmp_path: Path, value: str, said: str
) -> None:
    toml = _project(
        tmp_path,
        "film-strip",
        "[adjustment]\n",
        f'[adjustment]\nrefine = "bundle"\nself_calibration = {value}\n',
    )
    with pytest.raises(ConfigError) as info:
        load_project(toml)
    message = str(info.value)
    assert "[adjustment] self_calibration: expected" in message and said in message, message


# ---------------------------------------------------------------- camera.toml pasted


def test_a_camera_toml_added_instead_of_replacing_is_named(tmp_path: Path) -> None:
    """camera.toml appended to a project that keeps its own [camera]: tomllib's
    "Cannot declare ('camera',) twice" now says where the first is and why."""
    toml = _project(tmp_path, "film-strip", "[report]\n", "[report]\n")
    camera = (
        "# The camera adjusted by the bundle's self-calibration\n[camera]\n"
        "principal_distance_mm = 152.9\nprincipal_point_mm = [0.0, 0.0]\n\n"
        '[distortion]\nunits = "mm"\nmodel = "correction"\nk1 = -3e-8\n'
    )
    toml.write_text(toml.read_text(encoding="utf-8") + "\n" + camera, encoding="utf-8")
    _one_line(
        toml,
        "TOML syntax error: Cannot declare ('camera',) twice",
        "(the table [camera] is declared twice (first at line 6): merge them",
        "camera.toml replace the project's [camera] and [distortion]",
    )


def test_a_key_given_twice_is_named(tmp_path: Path) -> None:
    toml = _camera(tmp_path, "film-strip", "principal_distance_mm = 152.9")
    _one_line(toml, "Cannot overwrite a value", "the key 'principal_distance_mm' is given twice")


# ---------------------------------------------------------------- the principal distance


@pytest.mark.parametrize(
    ("example", "c"),
    [("film-strip", "30574.0"), ("drone-corridor", "3666.7")],  # c in pixels of 5 and 2.4 um
)
def test_a_principal_distance_in_pixels_is_named(tmp_path: Path, example: str, c: str) -> None:
    """It was 'are the coordinates in metres instead of millimetres?' for
    coordinates spanning the film's 228 mm: c alone says it."""
    toml = _project(
        tmp_path, example, "principal_distance_mm = ", f"principal_distance_mm = {c}\n#"
    )
    _one_line(
        toml,
        f"strip.toml: [camera] principal_distance_mm = {float(c):g} is longer than any "
        "aerial camera's",
        "in pixels (c divided by the pixel size) or micrometres",
    )


def test_a_principal_distance_in_pixels_under_2000_is_named_by_the_span(tmp_path: Path) -> None:
    """The corridor's 8.8 mm in pixels of 5 um, 1760, is within every camera's
    range: the points' span, 13 mm, a real format, under 0.02 c names it
    (as the FC300X block's 3.6 mm in pixels of 2.4 um, 1510, was not)."""
    toml = _project(
        tmp_path, "drone-corridor", "principal_distance_mm = 8.8", "principal_distance_mm = 1760.0"
    )
    _one_line(
        toml,
        "strip.toml: [camera] principal_distance_mm = 1760: the image points span 13",
        "a real format, but less than 0.02 c",
        "is c in pixels",
    )


@pytest.mark.parametrize(
    ("example", "c"), [("film-strip", "0.15287"), ("drone-corridor", "0.0088")]
)
def test_a_principal_distance_in_metres_is_named(tmp_path: Path, example: str, c: str) -> None:
    """It was 'the coordinates are not in millimetres (micrometres? pixels?)'
    for the film's coordinates, which are."""
    toml = _project(
        tmp_path, example, "principal_distance_mm = ", f"principal_distance_mm = {c}\n#"
    )
    _one_line(
        toml,
        f"strip.toml: [camera] principal_distance_mm = {float(c):g} is shorter than any camera's",
        "in metres instead of millimetres?",
    )


def test_coordinates_in_pixels_are_still_the_coordinates(tmp_path: Path) -> None:
    """With c in mm, coordinates far beyond any format are the coordinates'."""
    toml = _project(tmp_path, "drone-corridor", "[camera]\n", "[camera]\n")
    images = toml.parent / "image_points.csv"
    header, *rows = images.read_text(encoding="utf-8").splitlines()
    scaled = [r.split(",") for r in rows]
    for r in scaled:
        r[2], r[3] = repr(float(r[2]) / 0.0024), repr(float(r[3]) / 0.0024)
    images.write_text("\n".join([header, *map(",".join, scaled)]) + "\n", encoding="utf-8")
    _one_line(toml, "image_points.csv", "the coordinates are not in millimetres")


def test_the_imports_control_comment_reads_as_a_rule(tmp_path: Path) -> None:
    """The comment an import writes at the top of strip.toml said '..., 2 when
    fewer qualify, two of them consecutive)', which reads as two consecutive
    control points; the rule is on the photos that see each point."""
    samples = EXAMPLES / "import-samples" / "fc300x"
    out = tmp_path / "p"
    result = CliRunner().invoke(
        cli, ["-q", "import", "uav-fc300x", str(samples), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    (line,) = [
        ln for ln in (out / "strip.toml").read_text("utf-8").splitlines() if "full control" in ln
    ]
    assert "seen on 3 or more photos (2 when fewer qualify) of which two are consecutive)" in line


def test_a_principal_point_across_the_flight_before_the_distortion(tmp_path: Path) -> None:
    """The FC300X layout (flight along image +y, a projection-model
    [distortion] from cal.cal): x0 beyond the sensor's half width stopped on
    '[distortion]: ... did not converge ...; check the coefficients'."""
    out = tmp_path / "p"
    samples = EXAMPLES / "import-samples" / "fc300x"
    result = CliRunner().invoke(
        cli, ["-q", "import", "uav-fc300x", str(samples), "--out", str(out)]
    )
    assert result.exit_code == 0, result.output
    toml = out / "strip.toml"
    text = toml.read_text(encoding="utf-8")
    old = next(ln for ln in text.splitlines() if ln.startswith("principal_point_mm"))
    toml.write_text(text.replace(old, "principal_point_mm = [5.0, 0.0]"), encoding="utf-8")
    _one_line(toml, "[camera] principal_point_mm = [5, 0] lies outside the image points")


# ---------------------------------------------------------------- camera.toml's comments


def test_ebner_estimates_in_camera_toml_carry_no_unit_1(tmp_path: Path) -> None:
    """After "ebner12" camera.toml lists the twelve estimates as comments; the
    dimensionless ones ended in a bare '1' ('e1 = -2.67e-05 (2.3e-05) 1'), read
    as a number; the others keep their unit."""
    toml = _project(
        tmp_path, "film-strip", "[adjustment]\n",
        '[adjustment]\nrefine = "bundle"\nself_calibration = "ebner12"\n',
    )  # fmt: skip
    result = CliRunner().invoke(cli, ["-qq", "run", str(toml)])
    assert result.exit_code == 0, result.output
    lines = (toml.parent / "out" / "camera.toml").read_text(encoding="utf-8").splitlines()
    listed = {ln.split()[1]: ln for ln in lines if re.match(r"#   e\d+ = ", ln)}
    assert sorted(listed, key=lambda n: int(n[1:])) == [f"e{k}" for k in range(1, 13)]
    assert listed["e1"].endswith(")") and listed["e2"].endswith(")"), listed
    assert listed["e3"].endswith(") mm^-1") and listed["e12"].endswith(") mm^-3"), listed
