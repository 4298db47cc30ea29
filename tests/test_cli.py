"""Tests of the ``stripaero`` command line (click's CliRunner).

Projects are simulated (``strip_aerotri.simulate``), written to ``tmp_path``
and broken by editing their files.  Every bad input must give exit code 1,
exactly one line on stderr that names the culprit, and leave everything on
disk (inputs, a previous result, the output's parent) byte for byte as it was.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import strip_aerotri as sa
from strip_aerotri.cli.main import cli
from strip_aerotri.cli.simulate import CAMERA_NAMES, CONTROL_LAYOUTS, PRESET_NAMES
from strip_aerotri.project import run as project_run
from strip_aerotri.report.files import RESULT_MARKER

# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def film_files(tmp_path_factory) -> dict[str, bytes]:
    """A 6-photo film strip (6 full, 2 plan, 2 height control, 18 check points)."""
    folder = tmp_path_factory.mktemp("film")
    # J's polynomial type 3 (block = "strips"): the breakers below test its rules too
    sa.simulate_strip(6, preset="film", crs="EPSG:32634", seed=3).write_project(
        folder, polynomial=3
    )
    return {p.name: p.read_bytes() for p in folder.iterdir()}


@pytest.fixture(scope="module")
def corridor_sim() -> sa.SimulatedStrip:
    """A 6-photo corridor strip whose road points lie in one vertical plane."""
    return sa.simulate_strip(6, preset="corridor", crs="EPSG:32634", seed=4)


@pytest.fixture
def project(tmp_path, film_files) -> Path:
    folder = tmp_path / "proj"
    folder.mkdir()
    for name, data in film_files.items():
        (folder / name).write_bytes(data)
    return folder / "strip.toml"


FULL_REPORT = {"test_run_writes_result"}


@pytest.fixture(autouse=True)
def fast_report(request, monkeypatch):
    """Skip the matplotlib figures of report.html (about 2 s a run) except in the
    tests named in FULL_REPORT; everything else of the outputs is built."""
    if request.function.__name__ in FULL_REPORT:
        return
    from strip_aerotri.report import outputs as report

    build = report.strip_outputs

    def without_html(result, **kwargs):
        return build(result, **{**kwargs, "html": False})

    monkeypatch.setattr(report, "strip_outputs", without_html)


def invoke(*args: str | Path):
    return CliRunner().invoke(cli, [str(a) for a in args])


def snapshot(root: Path) -> dict[str, bytes | None]:
    """Every file and folder under ``root`` with its bytes (None for folders)."""
    return {
        str(p.relative_to(root)): (None if p.is_dir() else p.read_bytes())
        for p in sorted(root.rglob("*"))
    }


def previous_result(folder: Path) -> Path:
    """A previous result folder (marker and one file) that a failed run must not touch."""
    folder.mkdir(parents=True)
    (folder / RESULT_MARKER).write_text("previous\n", encoding="utf-8")
    (folder / "points.csv").write_text("point,X,Y,H\nOLD,1,2,3\n", encoding="utf-8")
    return folder


# --------------------------------------------------------------------------- file editing


def read_rows(path: Path) -> list[list[str]]:
    return list(csv.reader(io.StringIO(path.read_text(encoding="utf-8"))))


def write_rows(path: Path, rows: list[list[str]]) -> None:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    path.write_text(buffer.getvalue(), encoding="utf-8")


def edit_text(path: Path, old: str, new: str) -> None:
    text = path.read_text(encoding="utf-8")
    assert old in text, f"{old!r} not in {path}"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")


def images_by_photo(folder: Path) -> tuple[list[str], list[list[str]], dict[str, set[str]]]:
    rows = read_rows(folder / "image_points.csv")
    on_photo: dict[str, set[str]] = {}
    for row in rows[1:]:
        on_photo.setdefault(row[0], set()).add(row[1])
    return rows[0], rows[1:], on_photo


def keep_control(folder: Path, keep: Callable[[list[str]], bool]) -> None:
    rows = read_rows(folder / "control.csv")
    write_rows(folder / "control.csv", [rows[0], *[r for r in rows[1:] if keep(r)]])


# --------------------------------------------------------------------------- breakers
# Each breaker edits the project in `folder` (strip.toml, image_points.csv,
# control.csv) and returns the strings the error line must contain.


def break_missing_toml(folder: Path) -> tuple[str, ...]:
    (folder / "strip.toml").unlink()
    return ("strip.toml", "not found")


def break_toml_syntax(folder: Path) -> tuple[str, ...]:
    edit_text(folder / "strip.toml", "principal_distance_mm = ", "principal_distance_mm = = ")
    return ("strip.toml:7:", "TOML syntax error")


def break_unknown_key(folder: Path) -> tuple[str, ...]:
    edit_text(folder / "strip.toml", "principal_distance_mm", "principal_distanc_mm")
    return ("strip.toml", "unknown key 'principal_distanc_mm'", "principal_distance_mm")


def break_missing_key(folder: Path) -> tuple[str, ...]:
    edit_text(folder / "strip.toml", 'crs = "EPSG:32634"\n', "")
    return ("strip.toml", "[control]", "missing required key 'crs'")


def break_wrong_type(folder: Path) -> tuple[str, ...]:
    edit_text(
        folder / "strip.toml", "principal_distance_mm = 152.87", 'principal_distance_mm = "c"'
    )
    return ("strip.toml", "principal_distance_mm", "positive", "got")


def break_principal_distance(folder: Path) -> tuple[str, ...]:
    edit_text(folder / "strip.toml", "principal_distance_mm = 152.87", "principal_distance_mm = 0")
    return ("strip.toml", "principal_distance_mm", "positive", "got")


def break_unknown_route(folder: Path) -> tuple[str, ...]:
    edit_text(folder / "strip.toml", "[adjustment]\n", '[adjustment]\nroute = "geodetic"\n')
    return ("strip.toml", "route", "geodetic", "projected")


def break_one_photo(folder: Path) -> tuple[str, ...]:
    text = (folder / "strip.toml").read_text(encoding="utf-8")
    start = text.index("photos = [")
    end = text.index("]", start)
    (folder / "strip.toml").write_text(
        text[:start] + 'photos = ["1001"' + text[end:], encoding="utf-8"
    )
    return ("strip.toml", "[strip] photos", "at least two photos")


def break_nan_x(folder: Path) -> tuple[str, ...]:
    header, rows, _ = images_by_photo(folder)
    rows[2][2] = "nan"
    write_rows(folder / "image_points.csv", [header, *rows])
    return ("image_points.csv:4", "'x'")


def break_text_x(folder: Path) -> tuple[str, ...]:
    header, rows, _ = images_by_photo(folder)
    rows[4][2] = "4x6.220"
    write_rows(folder / "image_points.csv", [header, *rows])
    return ("image_points.csv:6", "column 'x'", "4x6.220")


def break_nan_control(folder: Path) -> tuple[str, ...]:
    rows = read_rows(folder / "control.csv")
    rows[1][1] = "NaN"
    write_rows(folder / "control.csv", rows)
    return ("control.csv:2", "'X'")


def break_missing_column(folder: Path) -> tuple[str, ...]:
    rows = read_rows(folder / "image_points.csv")
    write_rows(folder / "image_points.csv", [[r[0], r[1], r[2], r[4]] for r in rows])
    return ("image_points.csv:1", "missing required column(s) y")


def break_unknown_column(folder: Path) -> tuple[str, ...]:
    rows = read_rows(folder / "image_points.csv")
    rows[0][4] = "sigm"
    write_rows(folder / "image_points.csv", rows)
    return ("image_points.csv:1", "unknown column 'sigm'", "sigma")


def break_duplicate_observation(folder: Path) -> tuple[str, ...]:
    rows = read_rows(folder / "image_points.csv")
    rows.append(list(rows[3]))
    write_rows(folder / "image_points.csv", rows)
    return (f"image_points.csv:{len(rows)}", "duplicate observation", rows[3][1], "line 4")


def break_unknown_photo(folder: Path) -> tuple[str, ...]:
    rows = read_rows(folder / "image_points.csv")
    rows[5][0] = "9999"
    write_rows(folder / "image_points.csv", rows)
    return ("image_points.csv:6", "photo '9999'")


def break_photo_without_observations(folder: Path) -> tuple[str, ...]:
    edit_text(folder / "strip.toml", '"1006"]', '"1006", "1007"]')
    return ("image_points.csv", "photo '1007'", "no observations")


def break_missing_images_file(folder: Path) -> tuple[str, ...]:
    (folder / "image_points.csv").unlink()
    return ("image_points.csv", "not found")


def break_control_type(folder: Path) -> tuple[str, ...]:
    rows = read_rows(folder / "control.csv")
    rows[1][4] = "fulll"
    write_rows(folder / "control.csv", rows)
    return ("control.csv:2", "unknown type 'fulll'", "full")


def break_plan_with_h(folder: Path) -> tuple[str, ...]:
    rows = read_rows(folder / "control.csv")
    i = next(i for i, r in enumerate(rows) if r[4] == "plan")
    rows[i][3] = "150.0"
    write_rows(folder / "control.csv", rows)
    return (f"control.csv:{i + 1}", rows[i][0], "plan point leaves H empty")


def break_duplicate_control(folder: Path) -> tuple[str, ...]:
    rows = read_rows(folder / "control.csv")
    rows.append(list(rows[2]))
    write_rows(folder / "control.csv", rows)
    return (f"control.csv:{len(rows)}", rows[2][0], "listed twice")


def break_empty_control(folder: Path) -> tuple[str, ...]:
    write_rows(folder / "control.csv", [read_rows(folder / "control.csv")[0]])
    return ("control.csv",)


def break_few_pair_points(folder: Path) -> tuple[str, ...]:
    # Photo 1004 keeps only 4 of the points it shares with 1003.
    header, rows, on_photo = images_by_photo(folder)
    common = sorted(on_photo["1003"] & on_photo["1004"])
    drop = set(common[4:])
    rows = [r for r in rows if not (r[0] == "1004" and r[1] in drop)]
    write_rows(folder / "image_points.csv", [header, *rows])
    return ("strip.toml", "pair 1003-1004", "4 point(s)", "at least 5")


def break_no_tie(folder: Path) -> tuple[str, ...]:
    # Photo 1004 loses every point also seen on 1002: models 1002-1003 and
    # 1003-1004 share no point measured on all three photos.
    header, rows, on_photo = images_by_photo(folder)
    rows = [r for r in rows if not (r[0] == "1004" and r[1] in on_photo["1002"])]
    write_rows(folder / "image_points.csv", [header, *rows])
    return ("strip.toml", "pair 1003-1004", "no tie point", "pair 1002-1003")


def break_one_full_control(folder: Path) -> tuple[str, ...]:
    first = read_rows(folder / "control.csv")[1][0]
    keep_control(folder, lambda r: r[4] == "check" or r[0] == first)
    return ("strip.toml", "at least two full or plan control points")


def break_polynomial_minimum(folder: Path) -> tuple[str, ...]:
    # 4 full points: enough for the similarity, not for type 3 (6 terms).
    rows = read_rows(folder / "control.csv")
    full = [r[0] for r in rows[1:] if r[4] == "full"]
    keep = {full[0], full[1], full[-2], full[-1]}
    keep_control(folder, lambda r: r[4] == "check" or r[0] in keep)
    return ("strip.toml", "polynomial type 3", "at least 6", "got 4")


def break_coincident_plan(folder: Path) -> tuple[str, ...]:
    # Two plan-capable points at the same X, Y (the third is height only).
    rows = read_rows(folder / "control.csv")
    full = [r for r in rows[1:] if r[4] == "full"][:2]
    height = [r for r in rows[1:] if r[4] == "height"][:1]
    full[1][1], full[1][2] = full[0][1], full[0][2]
    write_rows(folder / "control.csv", [rows[0], *full, *height])
    edit_text(folder / "strip.toml", "polynomial = 3", "polynomial = 0")
    return ("strip.toml", "plan control points coincide")


def break_bad_crs(folder: Path) -> tuple[str, ...]:
    edit_text(folder / "strip.toml", 'crs = "EPSG:32634"', 'crs = "EPSG:99999999"')
    return ("strip.toml", "[control] crs", "EPSG:99999999")


def break_geocentric_local(folder: Path) -> tuple[str, ...]:
    edit_text(folder / "strip.toml", 'crs = "EPSG:32634"', 'crs = "local"')
    edit_text(folder / "strip.toml", "[adjustment]\n", '[adjustment]\nroute = "geocentric"\n')
    return ("strip.toml", "route", "geocentric", "local")


def break_line_unknown_point(folder: Path) -> tuple[str, ...]:
    edit_text(
        folder / "strip.toml",
        "[adjustment]\n",
        '[[straight_line]]\npoints = ["P0002", "P0003", "R99"]\n\n[adjustment]\n',
    )
    return ("strip.toml", "[[straight_line]] #1", "'R99'", "not observed")


def break_micrometres(folder: Path) -> tuple[str, ...]:
    """Image coordinates written in micrometres: 1000 times too large."""
    rows = read_rows(folder / "image_points.csv")
    x, y = rows[0].index("x"), rows[0].index("y")
    for row in rows[1:]:
        row[x] = f"{float(row[x]) * 1000:.3f}"
        row[y] = f"{float(row[y]) * 1000:.3f}"
    write_rows(folder / "image_points.csv", rows)
    return ("image_points.csv:", "beyond any film or sensor format", "micrometres")


def break_metres(folder: Path) -> tuple[str, ...]:
    """Image coordinates written in metres: 1000 times too small."""
    rows = read_rows(folder / "image_points.csv")
    x, y = rows[0].index("x"), rows[0].index("y")
    for row in rows[1:]:
        row[x] = f"{float(row[x]) / 1000:.9f}"
        row[y] = f"{float(row[y]) / 1000:.9f}"
    write_rows(folder / "image_points.csv", rows)
    return ("image_points.csv", "in metres instead of millimetres")


def break_swapped_control_axes(folder: Path) -> tuple[str, ...]:
    """Easting and northing swapped in control.csv: a mirrored system."""
    rows = read_rows(folder / "control.csv")
    x, y = rows[0].index("X"), rows[0].index("Y")
    for row in rows[1:]:
        row[x], row[y] = row[y], row[x]
    write_rows(folder / "control.csv", rows)
    return ("control.csv", "mirrored", "X and Y columns swapped")


def break_reversed_flight(folder: Path) -> tuple[str, ...]:
    """[strip] photos listed against the flight."""
    text = (folder / "strip.toml").read_text(encoding="utf-8")
    line = next(li for li in text.splitlines() if li.startswith("photos = "))
    photos = line[len("photos = [") : -1].split(", ")
    edit_text(folder / "strip.toml", line, "photos = [" + ", ".join(reversed(photos)) + "]")
    return ("listed against the flight direction", "negative x-parallax")


BREAKERS = [
    break_missing_toml,
    break_toml_syntax,
    break_unknown_key,
    break_missing_key,
    break_wrong_type,
    break_principal_distance,
    break_unknown_route,
    break_one_photo,
    break_nan_x,
    break_text_x,
    break_nan_control,
    break_missing_column,
    break_unknown_column,
    break_duplicate_observation,
    break_unknown_photo,
    break_photo_without_observations,
    break_missing_images_file,
    break_control_type,
    break_plan_with_h,
    break_duplicate_control,
    break_empty_control,
    break_few_pair_points,
    break_no_tie,
    break_one_full_control,
    break_polynomial_minimum,
    break_coincident_plan,
    break_bad_crs,
    break_geocentric_local,
    break_line_unknown_point,
    break_micrometres,
    break_metres,
    break_swapped_control_axes,
    break_reversed_flight,
]


def assert_one_error_line(result, expected: tuple[str, ...]) -> str:
    assert result.exit_code == 1, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    (line,) = lines
    assert line.startswith("stripaero: error: "), line
    for piece in expected:
        assert piece in line, (piece, line)
    assert "Traceback" not in result.output
    return line


@pytest.mark.parametrize("breaker", BREAKERS, ids=[b.__name__[6:] for b in BREAKERS])
def test_run_bad_input(tmp_path, project, breaker):
    expected = breaker(project.parent)
    out = previous_result(tmp_path / "results" / "out")
    before = snapshot(tmp_path)
    result = invoke("-q", "run", project, "--out", out)
    assert_one_error_line(result, expected)
    # Inputs, the previous result and its parent are exactly as before.
    assert snapshot(tmp_path) == before


def test_bad_input_has_one_error_line_without_quiet(tmp_path, project):
    """stderr is not a terminal here: a script or a CI log sees the one error
    line alone; with -v the progress comes first."""
    break_no_tie(project.parent)
    result = invoke("run", project)
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("stripaero: error: ")
    assert "no tie point" in lines[-1]
    verbose = invoke("-v", "run", project).stderr.splitlines()
    assert verbose[0].startswith("stripaero: loading")  # progress, then the one error line
    assert [ln for ln in verbose if not ln.startswith("stripaero: error: ")] == verbose[:-1]
    assert not (project.parent / "out").exists()


@pytest.mark.parametrize("off_road_m", [0.0, 0.02])
def test_run_collinear_height_control(tmp_path, corridor_sim, off_road_m):
    """Full control only on the road: all height control in one vertical plane,
    or every second point 2 cm off it (singular value ratio 1e-5, an error of
    the heights reaching the strip's edge thousands of times magnified): run
    and check refuse both."""
    folder = tmp_path / "proj"
    toml = corridor_sim.write_project(folder, polynomial=0)
    road = corridor_sim.lines[0][0]
    index = {p: i for i, p in enumerate(corridor_sim.observations.point_ids)}
    xyz = corridor_sim.truth.points_crs[[index[p] for p in road]]
    xyz[1::2, 1] += off_road_m
    rows = [["point", "X", "Y", "H", "type"]]
    rows += [
        [p, f"{x:.4f}", f"{y:.4f}", f"{h:.4f}", "full"]
        for p, (x, y, h) in zip(road, xyz, strict=True)
    ]
    write_rows(folder / "control.csv", rows)
    text = toml.read_text(encoding="utf-8")
    start = text.index("[[straight_line]]")
    toml.write_text(text[:start] + text[text.index("[adjustment]") :], encoding="utf-8")
    before = snapshot(tmp_path)
    for command in ("run", "check"):
        result = invoke("-q", command, toml)
        assert_one_error_line(result, ("one vertical plane", road[0]))
    assert snapshot(tmp_path) == before


def test_refuses_folder_that_is_not_a_result(tmp_path, project):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me\n", encoding="utf-8")
    before = snapshot(tmp_path)
    result = invoke("-q", "run", project, "--out", out)
    assert_one_error_line(result, ("mine", "not a stripaero result folder"))
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("where", ["project folder", "input inside"])
def test_refuses_output_over_inputs(tmp_path, project, where):
    out = project.parent if where == "project folder" else tmp_path
    before = snapshot(tmp_path)
    result = invoke("-q", "run", project, "--out", out)
    line = assert_one_error_line(result, ("--out",))
    assert "project folder" in line or "input file" in line
    assert snapshot(tmp_path) == before


# --------------------------------------------------------------------------- check


CHECK_BREAKERS = [
    break_toml_syntax,
    break_text_x,
    break_micrometres,
    break_swapped_control_axes,
    break_reversed_flight,
    break_few_pair_points,
    break_no_tie,
    break_one_full_control,
    break_polynomial_minimum,
    break_coincident_plan,
]


@pytest.mark.parametrize("breaker", CHECK_BREAKERS, ids=[b.__name__[6:] for b in CHECK_BREAKERS])
def test_check_bad_input(tmp_path, project, breaker):
    expected = breaker(project.parent)
    # geometry problems name the CSV that holds the culprit instead of strip.toml
    expected = tuple(e for e in expected if e != "strip.toml")
    before = snapshot(tmp_path)
    result = invoke("-q", "check", project)
    assert result.exit_code == 1, result.output
    lines = result.stderr.splitlines()
    assert lines and all(ln.startswith("stripaero: error: ") for ln in lines), result.stderr
    for piece in expected:
        assert piece in lines[0], (piece, lines[0])
    assert result.stdout == ""
    assert snapshot(tmp_path) == before


def test_check_lists_every_problem(project):
    break_few_pair_points(project.parent)
    break_one_full_control(project.parent)
    result = invoke("-q", "check", project)
    assert result.exit_code == 1
    lines = result.stderr.splitlines()
    assert all(ln.startswith("stripaero: error: ") for ln in lines)
    expected = [
        ("image_points.csv", "pair 1003-1004: 4 point(s)"),
        # the points dropped from 1004 were also the ties of the next model
        ("image_points.csv", "pair 1004-1005 shares no tie point with pair 1003-1004"),
        ("control.csv", "at least two full or plan control points", "got 1: 'P0001'"),
        ("control.csv", "at least three full or height control points", "got 1: 'P0001'"),
    ]
    assert len(lines) == len(expected), result.stderr
    for line, pieces in zip(lines, expected, strict=True):
        assert all(p in line for p in pieces), (pieces, line)


def test_check_follows_photo_step(project):
    # 60 % overlap: photos two apart share no triple overlap with the next model
    edit_text(project, "[adjustment]\n", "[adjustment]\nphoto_step = 2\n")
    result = invoke("-q", "check", project)
    assert result.exit_code == 1
    # model photos 1001, 1003, 1004, 1006 (densify.model_photo_index(6, 2) = [0, 2, 3, 5])
    assert "pair 1003-1004 shares no tie point with pair 1001-1003" in result.stderr


def test_check_ok(project):
    result = invoke("check", project)
    assert result.exit_code == 0, result.output
    assert "OK: the project can be run" in result.stdout
    assert "photos: 6 (1001 ... 1006), 5 pairs" in result.stdout
    # simulate_strip "ends" layout on 6 photos: 6 full, 2 plan, 2 height points
    assert "usable 8 plan, 8 height" in result.stdout
    assert not (project.parent / "out").exists()


def test_check_verbose_lists_pairs(project):
    result = invoke("check", "-v", project)
    assert result.exit_code == 0
    assert result.stdout.count("common points,") == 5


# --------------------------------------------------------------------------- run


def test_run_writes_result(project):
    inputs = snapshot(project.parent)
    result = invoke("run", project)
    assert result.exit_code == 0, result.output
    out = project.parent / "out"
    names = {p.name for p in out.iterdir()}
    assert {"points.csv", "photos.csv", "report.json", "report.html", RESULT_MARKER} <= names
    assert f"report: {out / 'report.html'}" in result.stdout
    assert "check points: 18 plan, 18 height" in result.stdout
    assert "RMSE plan" in result.stdout
    assert f"results: {out}" in result.stdout
    assert "forming the strip" not in result.stderr  # not a terminal: no progress
    verbose = invoke("-v", "run", project)
    assert "forming the strip" in verbose.stderr  # progress on stderr with -v
    assert "stripaero: error" not in result.stderr
    points = read_rows(out / "points.csv")
    assert points[0][:4] == ["point", "X", "Y", "H"]
    photos = read_rows(out / "photos.csv")
    assert [r[0] for r in photos[1:]] == ["1001", "1002", "1003", "1004", "1005", "1006"]
    # inputs untouched, nothing else created beside them
    after = snapshot(project.parent)
    assert {k: v for k, v in after.items() if not k.startswith("out")} == inputs


def test_run_twice_replaces_result(tmp_path, project):
    out = tmp_path / "res"
    assert invoke("-q", "run", project, "--out", out).exit_code == 0
    first = (out / "points.csv").read_bytes()
    # a file the previous run wrote (listed in the marker) that this one does not
    (out / "stale.txt").write_text("from an older run\n", encoding="utf-8")
    with (out / RESULT_MARKER).open("a", encoding="utf-8") as fh:
        fh.write("written: stale.txt\n")
    (out / "notes.txt").write_text("the user's\n", encoding="utf-8")
    result = invoke("-q", "run", project, "--out", out)
    assert result.exit_code == 0, result.output
    assert not (out / "stale.txt").exists()
    assert (out / "notes.txt").read_text(encoding="utf-8") == "the user's\n"
    assert (out / "points.csv").read_bytes() == first  # deterministic
    assert sorted(p.name for p in tmp_path.iterdir()) == ["proj", "res"]  # no temp folders


def test_run_output_directory_from_toml(project):
    edit_text(project, "[adjustment]\n", '[output]\ndirectory = "results"\n\n[adjustment]\n')
    assert invoke("-q", "run", project).exit_code == 0
    assert (project.parent / "results" / "points.csv").is_file()
    assert not (project.parent / "out").exists()


def test_run_quiet_levels(project):
    result = invoke("-q", "run", project)
    assert result.exit_code == 0
    assert result.stderr == ""
    assert "RMSE" in result.stdout
    result = invoke("-qq", "run", project)
    assert result.exit_code == 0
    assert result.output == ""


def test_run_verbose_details(project):
    result = invoke("run", "-v", project)
    assert result.exit_code == 0
    assert result.stderr.count("sigma0") == 5  # one line per pair of the 6-photo strip
    assert "pair 1002-1003" in result.stderr and "tie points" in result.stderr


def test_run_prints_loader_warning(project):
    rows = read_rows(project.parent / "control.csv")
    rows.append(["G99", "500000.0", "4649000.0", "150.0", "full"] + [""] * (len(rows[0]) - 5))
    write_rows(project.parent / "control.csv", rows)
    result = invoke("run", project)
    assert result.exit_code == 0, result.output
    warnings = [ln for ln in result.stderr.splitlines() if ln.startswith("stripaero: warning:")]
    assert len(warnings) == 1 and "'G99'" in warnings[0]


def test_debug_shows_traceback(project):
    break_no_tie(project.parent)
    result = invoke("--debug", "run", project)
    assert result.exit_code == 1
    assert "Traceback" in result.stderr
    assert result.stderr.rstrip().splitlines()[-1].startswith("stripaero: error: ")
    result = invoke("run", project, "--debug")  # also accepted after the command
    assert "Traceback" in result.stderr


def test_unexpected_error_is_one_line(project, monkeypatch):
    def boom(*args, **kwargs):
        raise RuntimeError("boom\nsecond line")

    monkeypatch.setattr(project_run, "run_project", boom)
    result = invoke("-q", "run", project)
    line = assert_one_error_line(result, ("RuntimeError", "boom", "--debug"))
    assert "second line" in line
    assert not (project.parent / "out").exists()


def test_map_scale_option(project):
    result = invoke("-q", "run", project, "--map-scale", "5000")
    assert result.exit_code == 0, result.output


# --------------------------------------------------------------------------- simulate


def test_simulate_then_run(tmp_path):
    folder = tmp_path / "demo"
    result = invoke("simulate", "corridor", "--out", folder, "--photos", "5", "--seed", "2")
    assert result.exit_code == 0, result.output
    assert {p.name for p in folder.iterdir()} == {"strip.toml", "image_points.csv", "control.csv"}
    assert "[[straight_line]]" in (folder / "strip.toml").read_text(encoding="utf-8")
    assert f"stripaero run {folder / 'strip.toml'}" in result.stdout
    result = invoke("-q", "run", folder / "strip.toml")
    assert result.exit_code == 0, result.output
    # the same arguments give the same files
    again = tmp_path / "again"
    invoke("simulate", "corridor", "--out", again, "--photos", "5", "--seed", "2")
    for name in ("image_points.csv", "control.csv"):
        assert (again / name).read_bytes() == (folder / name).read_bytes()


def test_simulate_options(tmp_path):
    folder = tmp_path / "d"
    result = invoke(
        "simulate", "drone", "--out", folder, "--photos", "6", "--crs", "EPSG:2180",
        "--heading", "120", "--noise-um", "0", "--polynomial", "auto", "--control", "dense",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    text = (folder / "strip.toml").read_text(encoding="utf-8")
    assert 'crs = "EPSG:2180"' in text and 'polynomial = "auto"' in text
    assert "principal_distance_mm = 8.8" in text  # drone preset: c = 8.8 mm
    sigma = np.array([float(r[4]) for r in read_rows(folder / "image_points.csv")[1:]])
    assert np.all(sigma == 0.005)  # noise 0: sigma written as 0.005 mm (simulate docs)


def test_simulate_refuses_to_overwrite(tmp_path):
    folder = tmp_path / "demo"
    assert invoke("simulate", "film", "--out", folder, "--photos", "4").exit_code == 0
    before = snapshot(tmp_path)
    result = invoke("-q", "simulate", "film", "--out", folder, "--photos", "5")
    assert_one_error_line(result, ("strip.toml", "already exists", "--force"))
    assert snapshot(tmp_path) == before
    assert invoke("-q", "simulate", "film", "--out", folder, "--force").exit_code == 0


def test_simulate_bad_crs(tmp_path):
    result = invoke("-q", "simulate", "film", "--out", tmp_path / "x", "--crs", "FOO")
    assert_one_error_line(result, ("FOO",))


def test_preset_names_match_library():
    assert tuple(sa.PRESETS) == PRESET_NAMES
    from strip_aerotri import simulate as simulate_module

    assert tuple(simulate_module.CAMERAS) == CAMERA_NAMES
    assert set(simulate_module._CONTROL_LAYOUTS) == set(CONTROL_LAYOUTS)


# --------------------------------------------------------------------------- help, usage


def test_version():
    result = invoke("--version")
    assert result.exit_code == 0
    assert sa.__version__ in result.output


@pytest.mark.parametrize("command", [[], ["run"], ["check"], ["simulate"]])
def test_help(command):
    result = invoke(*command, "--help")
    assert result.exit_code == 0, result.output
    assert "Examples:" in result.output
    assert "stripaero docs" in result.output


@pytest.mark.parametrize(
    "args",
    [
        ["run"],
        ["run", "strip.toml", "--bogus"],
        ["run", "strip.toml", "--map-scale", "-5"],
        ["run", "strip.toml", "--map-scale", "abc"],
        ["nonsense"],
        ["simulate", "film"],
        ["simulate", "balloon", "--out", "x"],
        ["simulate", "film", "--out", "x", "--photos", "1"],
    ],
    ids=lambda a: " ".join(a) or "none",
)
def test_usage_errors_exit_2(args, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    result = invoke(*args)
    assert result.exit_code == 2, result.output
    assert "Usage:" in result.stderr
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- bundled examples

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


@pytest.mark.parametrize("name", ["film-strip", "drone-corridor"])
def test_bundled_example_runs(tmp_path, name):
    toml = EXAMPLES / name / "strip.toml"
    before = snapshot(EXAMPLES / name)
    assert invoke("-q", "check", toml).exit_code == 0
    result = invoke("-q", "run", toml, "--out", tmp_path / "out")
    assert result.exit_code == 0, result.output
    assert "criteria met" in result.stdout  # [report] map_scale of the example
    out = read_rows(tmp_path / "out" / "points.csv")
    assert len(out) > 100
    assert snapshot(EXAMPLES / name) == before


def test_check_sizes_a_photo_footprint_from_its_control():
    """The check's stand-in for the strip's points served: a photo's ground
    radius from its plan control's spread over their image spread, times its
    farthest image point; the preset's scale times that point in truth."""
    from strip_aerotri.project.check import _footprint_radius

    sim = sa.simulate_strip(12, seed=2)
    obs, ctrl = sim.observations, sim.control
    lookup = {p: i for i, p in enumerate(obs.point_ids)}
    control_point = np.array([lookup.get(p, -1) for p in ctrl.point_ids])
    has_plan = np.isfinite(ctrl.xyz[:, :2]).all(axis=1)
    radius = _footprint_radius(obs, control_point, has_plan, ctrl.xyz[has_plan, :2])
    farthest = np.median([np.hypot(*obs.xy[obs.photo == k].T).max() for k in range(obs.n_photos)])
    truth = sim.preset.scale_m_per_mm * farthest
    assert radius == pytest.approx(truth, rel=0.1)
    # no photo with two plan control points: no size
    one = np.zeros_like(has_plan)
    one[np.flatnonzero(has_plan)[0]] = True
    assert _footprint_radius(obs, control_point, one, ctrl.xyz[one, :2]) is None


@pytest.mark.parametrize("command", ["run", "check"])
def test_two_photos_out_of_order_are_named(tmp_path, command):
    """At 80 % overlap two exchanged neighbours still overlap: the pair
    between them is oriented with its rays meeting behind the photos."""
    folder = tmp_path / "drone"
    sa.simulate_strip(10, preset="drone", crs="EPSG:32634", seed=2).write_project(folder)
    edit_text(folder / "strip.toml", '"1005", "1006"', '"1006", "1005"')
    result = invoke(
        "-q",
        command,
        folder / "strip.toml",
        *(["--out", tmp_path / "o"] if command == "run" else []),
    )
    assert_one_error_line(result, ("pair 1006-1005", "meet behind the photos", "flight order"))


def test_simulate_a_camera_and_flight_runs(tmp_path):
    """--camera with a flight of the envelope: a 35 mm drone strip at 80 %
    overlap with R4's control layout and two image blunders runs end to end
    (every model at once) and finds them."""
    folder = tmp_path / "drone35"
    result = invoke(
        "-q", "simulate", "--camera", "ff35", "--overlap", "80", "--height-m", "150",
        "--tilt-deg", "2.5", "--kappa-deg", "3", "--noise-um", "5", "--photos", "20",
        "--control", "fig4", "--image-blunders", "2", "--out", folder,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    text = (folder / "strip.toml").read_text(encoding="utf-8")
    assert "principal_distance_mm = 35.0" in text and "polynomial" not in text
    run = invoke("-q", "run", folder / "strip.toml", "--out", tmp_path / "out")
    assert run.exit_code == 0, run.output
    report = (tmp_path / "out" / "report.json").read_text(encoding="utf-8")
    assert '"construction": "models"' in report


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((), "give either PRESET or --camera"),
        (("film", "--camera", "ff35"), "give either PRESET or --camera"),
        (("film", "--overlap", "70"), "--overlap describes the flight of --camera"),
    ],
)
def test_simulate_preset_or_camera(tmp_path, args, message):
    result = invoke("simulate", *args, "--out", tmp_path / "x")
    assert result.exit_code == 2 and message in result.output


def test_run_very_verbose_shows_more_than_verbose(project):
    """-vv adds every control and check point's residual to -v's figures."""
    verbose = invoke("-v", "run", project).stderr.splitlines()
    very = invoke("-vv", "run", project).stderr.splitlines()
    timings = {ln for ln in verbose if ln.endswith(" s")}  # seconds differ between runs
    assert set(verbose) - timings <= set(very)
    residuals = [ln for ln in very if "dE, dN, dH" in ln]
    assert len(residuals) > len([ln for ln in verbose if "dE, dN, dH" in ln]) == 0
    assert any(ln.startswith("stripaero: check ") for ln in residuals)


def test_lost_control_with_quotes_and_commas_is_one_warning_line(project):
    """Three control points each measured on one photo only, named with a
    quote, a comma and double quotes (CSV-quoted in both files): `run`
    prints one line naming the three, `-v` a line for each."""
    ids = ["G'1", "G,2", '"G3"']
    control = read_rows(project.parent / "control.csv")
    first = control[1]
    control += [[pid, *first[1:4], "full", *first[5:]] for pid in ids]
    write_rows(project.parent / "control.csv", control)
    images = read_rows(project.parent / "image_points.csv")
    images += [[images[1][0], pid, *images[1][2:]] for pid in ids]
    write_rows(project.parent / "image_points.csv", images)
    lost = "is not triangulated (seen on fewer than two photos of a model): left out"

    result = invoke("run", project)
    assert result.exit_code == 0, result.output
    summed = [ln for ln in result.stderr.splitlines() if "control point" in ln]
    assert summed == [
        "stripaero: warning: 3 control points are not triangulated "
        "(\"G'1\", 'G,2', '\"G3\"') and left out (each: seen on fewer than two photos of a "
        "model) (listed in report.json; -v lists them here)"
    ]
    result = invoke("run", project, "-v")
    each = [ln for ln in result.stderr.splitlines() if "control point" in ln]
    assert each == [f"stripaero: warning: control point {pid!r} {lost}" for pid in ids]
