"""Project file loading: values, units, defaults, enums, and one clear error per bad input."""

from __future__ import annotations

import csv
import re
import shutil
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.errors import ConfigError
from strip_aerotri.observations import ControlType
from strip_aerotri.options import AdjustmentOptions, Route, ScaleTransfer
from strip_aerotri.project import (
    CONTROL_COLUMNS,
    IMAGE_COLUMNS,
    PROJECT_KEYS,
    PROJECT_TABLES,
    Block,
    Intersection,
    RelativeOrientation,
    check_output_directory,
    load_project,
)

DATA = Path(__file__).parent / "data"
DOCS = Path(__file__).parents[1] / "docs" / "project-file.md"


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.fixture
def minimal(tmp_path: Path) -> Path:
    """A private copy of tests/data/minimal; returns its folder."""
    folder = tmp_path / "minimal"
    shutil.copytree(DATA / "minimal", folder)
    return folder


@pytest.fixture
def full(tmp_path: Path) -> Path:
    folder = tmp_path / "full"
    shutil.copytree(DATA / "full", folder)
    return folder


def read_rows(path: Path) -> list[dict[str, str]]:
    """Independent reader for the fixtures: csv.DictReader after dropping comments."""
    text = path.read_bytes().decode("utf-8-sig")
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    reader = csv.DictReader(lines)
    return [{k.strip().lower(): v.strip() for k, v in row.items()} for row in reader]


# --------------------------------------------------------------------------- valid projects


def test_minimal_project_values_and_defaults(minimal: Path) -> None:
    before = snapshot(minimal)
    project = load_project(minimal / "strip.toml")
    assert snapshot(minimal) == before

    assert project.path == minimal / "strip.toml"
    assert project.name == "minimal"  # default: the folder's name
    assert project.photo_ids == ("1201", "1202", "1203")
    assert project.camera.principal_distance_mm == 152.87
    np.testing.assert_array_equal(project.camera.principal_point_mm, [0.0, 0.0])
    assert project.crs == "local" and project.is_local
    # crs = "local" selects the projected route; the other options are defaults
    assert project.adjustment == AdjustmentOptions(route=Route.PROJECTED)
    assert project.adjustment.polynomial == 3
    assert project.adjustment.relative_orientation is RelativeOrientation.DEPENDENT
    assert project.adjustment.intersection is Intersection.MIDPOINT
    assert project.adjustment.scale_transfer is ScaleTransfer.Z
    assert project.adjustment.max_iterations == 50
    assert project.report.map_scale is None
    assert project.output_directory is None
    assert project.straight_lines == ()
    assert project.warnings == ()
    assert project.images_file == minimal / "image_points.csv"
    assert project.input_files == (
        minimal / "strip.toml",
        minimal / "image_points.csv",
        minimal / "control.csv",
    )

    obs = project.observations
    rows = read_rows(minimal / "image_points.csv")
    assert obs.xy.shape == (len(rows), 2) == (33, 2)
    assert obs.photo_ids == project.photo_ids
    assert obs.principal_distance == 152.87
    np.testing.assert_array_equal(obs.sigma, 0.005)  # [images] sigma_mm default
    assert obs.point_ids[0] == "001"  # leading zeros kept
    got = {
        (obs.photo_ids[f], obs.point_ids[p]): tuple(xy)
        for f, p, xy in zip(obs.photo, obs.point, obs.xy, strict=True)
    }
    want = {(r["photo"], r["point"]): (float(r["x"]), float(r["y"])) for r in rows}
    assert got == want
    # sorted by photo, then point; source lines name the file lines (header is line 1)
    assert np.all(np.diff(obs.photo * 1000 + obs.point) > 0)
    assert sorted(obs.source_line.tolist()) == list(range(2, 35))

    control = project.control
    assert control.point_ids == ("001", "005", "011", "015", "008")
    assert control.kind == (ControlType.FULL,) * 5
    # tests/data/minimal/control.csv line 2
    np.testing.assert_array_equal(control.xyz[0], [0.0, -400.0, 8.981])
    np.testing.assert_array_equal(control.sigma_xy, 0.02)
    np.testing.assert_array_equal(control.sigma_h, 0.03)
    np.testing.assert_array_equal(control.source_line, [2, 3, 4, 5, 6])


def test_full_project_every_key_bom_crlf_comments(full: Path) -> None:
    before = snapshot(full)
    project = load_project(full / "strip.toml")
    assert snapshot(full) == before

    assert project.name == "Full fixture"
    assert project.photo_ids == ("0101", "0102", "0103", "0104", "0105")
    assert project.crs == "EPSG:32634" and not project.is_local
    np.testing.assert_array_equal(project.camera.principal_point_mm, [0.012, -0.008])
    assert project.adjustment == AdjustmentOptions(
        route=Route.PROJECTED,  # written "Projected"
        polynomial="auto",
        relative_orientation=RelativeOrientation.BASE,  # written "BASE"
        intersection=Intersection.NORMAL,
        scale_transfer=ScaleTransfer.DISTANCE,
        max_iterations=12,
        block=Block.STRIPS,  # written "Strips"
    )
    assert project.report.map_scale == 5000.0
    assert project.output_directory == full / "results"
    assert len(project.straight_lines) == 1
    line = project.straight_lines[0]
    assert (line.point_ids, line.weight, line.name) == (
        ("R1", "R2", "R3", "R4"),
        50.0,
        "north road",
    )

    obs = project.observations
    rows = read_rows(full / "data" / "image_points.csv")
    assert obs.xy.shape == (len(rows), 2)
    # tests/data/full/data/image_points.csv line 18: "0101, R1 ,17.687, 29.474 ,"
    # (after the BOM, 3 comment/blank lines, header, 11 rows, a blank and a comment line)
    k = int(np.flatnonzero(obs.source_line == 18)[0])
    assert obs.photo_ids[obs.photo[k]] == "0101" and obs.point_ids[obs.point[k]] == "R1"
    # principal point (0.012, -0.008) subtracted; empty sigma cell -> [images] sigma_mm
    np.testing.assert_allclose(obs.xy[k], [17.687 - 0.012, 29.474 + 0.008], rtol=0, atol=1e-12)
    assert obs.sigma[k] == 0.004
    # line 5: "0101, T01 ,-5.655, -66.932 ,0.003"
    k = int(np.flatnonzero(obs.source_line == 5)[0])
    assert obs.point_ids[obs.point[k]] == "T01" and obs.sigma[k] == 0.003
    want = {(r["photo"], r["point"]): (float(r["x"]) - 0.012, float(r["y"]) + 0.008) for r in rows}
    got = {
        (obs.photo_ids[f], obs.point_ids[p]): tuple(xy)
        for f, p, xy in zip(obs.photo, obs.point, obs.xy, strict=True)
    }
    assert got.keys() == want.keys()
    np.testing.assert_allclose([got[key] for key in want], list(want.values()), atol=1e-12)

    control = project.control
    # G99 (line 11) is observed on no photo: a warning naming it, and left out
    assert "G99" not in control.point_ids
    assert len(project.warnings) == 1
    assert re.search(r"control\.csv:11: control point 'G99' .*not observed", project.warnings[0])
    assert control.point_ids == ("T01", "T11", "T23", "T33", "T17", "T06", "T28", "T20")
    assert control.kind == (
        (ControlType.FULL,) * 5 + (ControlType.PLAN, ControlType.HEIGHT, ControlType.CHECK)
    )
    i_plan, i_height = control.point_ids.index("T06"), control.point_ids.index("T28")
    assert np.isnan(control.xyz[i_plan, 2]) and np.isfinite(control.xyz[i_plan, :2]).all()
    assert np.isnan(control.xyz[i_height, :2]).all()
    # tests/data/full/data/control.csv line 9: "T28,,,326.114,height,,0.04"
    assert control.xyz[i_height, 2] == 326.114
    # sigma columns: given values, else [control] sigma_xy_m = 0.05, sigma_h_m = 0.08
    np.testing.assert_array_equal(control.sigma_xy, [0.05] * 4 + [0.01, 0.03, 0.05, 0.05])
    np.testing.assert_array_equal(control.sigma_h, [0.08] * 4 + [0.02, 0.08, 0.04, 0.08])
    np.testing.assert_array_equal(control.uses_xy, [1, 1, 1, 1, 1, 1, 0, 0])
    np.testing.assert_array_equal(control.uses_h, [1, 1, 1, 1, 1, 0, 1, 0])


def test_route_defaults_to_geocentric_for_a_geodetic_crs(full: Path) -> None:
    toml = full / "strip.toml"
    toml.write_text(toml.read_text().replace('route = "Projected"\n', ""))
    assert load_project(toml).adjustment.route is Route.GEOCENTRIC


def test_result_arrays_are_read_only(minimal: Path) -> None:
    project = load_project(minimal / "strip.toml")
    for arr in (project.observations.xy, project.control.xyz, project.camera.principal_point_mm):
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 1.0


def test_single_ray_points_are_warned(minimal: Path) -> None:
    with (minimal / "image_points.csv").open("a") as f:
        f.write("1202,LONE,1.0,2.0\n")
    project = load_project(minimal / "strip.toml")
    assert "LONE" in project.observations.point_ids
    assert any("one photo only" in w and "'LONE'" in w for w in project.warnings)


def test_check_points_may_lie_on_a_straight_line(minimal: Path) -> None:
    (minimal / "control.csv").write_text(
        (minimal / "control.csv").read_text() + "002,300.0,-400.0,5.0,check\n"
    )
    (minimal / "strip.toml").write_text(
        (minimal / "strip.toml").read_text()
        + '\n[[straight_line]]\npoints = ["002", "003", "004"]\n'
    )
    line = load_project(minimal / "strip.toml").straight_lines[0]
    assert line == type(line)(("002", "003", "004"), 100.0, "line 1")  # defaults


@pytest.mark.parametrize(
    ("enum", "text", "member"),
    [
        (Route, "GeoCentric", Route.GEOCENTRIC),
        (RelativeOrientation, " base ", RelativeOrientation.BASE),
        (Intersection, "NORMAL", Intersection.NORMAL),
        (ScaleTransfer, "Distance", ScaleTransfer.DISTANCE),
    ],
    ids=["route", "relative", "intersection", "scale"],
)
def test_enums_are_case_insensitive(enum, text, member) -> None:
    assert enum.create(text) is member
    assert enum(text) is member
    assert str(member) == member.value and f"{member}" == member.value


def test_enum_error_lists_valid_values() -> None:
    with pytest.raises(ValueError, match='valid values: "midpoint", "normal"'):
        Intersection.create("middle")


def test_check_output_directory(minimal: Path, tmp_path: Path) -> None:
    project = load_project(minimal / "strip.toml")
    assert check_output_directory(tmp_path / "elsewhere", project) == tmp_path / "elsewhere"
    with pytest.raises(ConfigError, match=r"--out: output folder .* is the project folder"):
        check_output_directory(minimal, project)
    with pytest.raises(ConfigError, match=r"contains the input file .*strip\.toml"):
        check_output_directory(tmp_path, project)


def test_docs_name_every_key_and_column() -> None:
    text = DOCS.read_text(encoding="utf-8")
    for table in PROJECT_TABLES:
        assert f"[{table.name}]" in text, table.name
    for spec in PROJECT_KEYS:
        assert f"`{spec.key}`" in text, spec.qualified
    for column in IMAGE_COLUMNS + CONTROL_COLUMNS:
        assert f"`{column.name}`" in text, column.name


@pytest.mark.slow
def test_300k_observations_load_fast(tmp_path: Path) -> None:
    rng = np.random.default_rng(2345)
    photos = [f"{i:04d}" for i in range(100)]
    xy = rng.uniform(-110.0, 110.0, size=(100, 3000, 2))
    lines = ["photo,point,x,y"]
    for i, photo in enumerate(photos):
        lines += [f"{photo},P{1500 * i + j},{x:.3f},{y:.3f}" for j, (x, y) in enumerate(xy[i])]
    (tmp_path / "image_points.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "control.csv").write_text("point,X,Y,H,type\nP1,0,0,0,full\n")
    (tmp_path / "strip.toml").write_text(
        "[strip]\nphotos = [" + ", ".join(f'"{p}"' for p in photos) + "]\n"
        "[camera]\nprincipal_distance_mm = 100.0\n"
        '[images]\nfile = "image_points.csv"\n'
        '[control]\nfile = "control.csv"\ncrs = "local"\n'
    )
    start = time.perf_counter()
    project = load_project(tmp_path / "strip.toml")
    elapsed = time.perf_counter() - start
    assert project.observations.xy.shape == (300_000, 2)
    np.testing.assert_allclose(project.observations.xy[0], np.round(xy[0, 0], 3))
    # about 0.5-1 s on a shared 2-core machine; the bound only catches a per-row Python path
    assert elapsed < 4.0, elapsed


# --------------------------------------------------------------------------- bad inputs

Mutator = Callable[[Path], None]


def sub(name: str, old: str, new: str) -> Mutator:
    def mutate(folder: Path) -> None:
        path = folder / name
        text = path.read_text(encoding="utf-8")
        assert old in text, f"fixture changed: {old!r} not in {name}"
        path.write_text(text.replace(old, new, 1), encoding="utf-8")

    return mutate


def append(name: str, text: str | bytes) -> Mutator:
    def mutate(folder: Path) -> None:
        with (folder / name).open("ab") as f:
            f.write(text.encode() if isinstance(text, str) else text)

    return mutate


def write(name: str, content: str | bytes) -> Mutator:
    def mutate(folder: Path) -> None:
        data = content.encode() if isinstance(content, str) else content
        (folder / name).write_bytes(data)

    return mutate


def add_column(name: str, column: str, values: dict[int, str]) -> Mutator:
    """Add a column; ``values`` maps file line numbers to cells (others empty)."""

    def mutate(folder: Path) -> None:
        path = folder / name
        lines = path.read_text(encoding="utf-8").splitlines()
        lines[0] += f",{column}"
        for i in range(1, len(lines)):
            lines[i] += "," + values.get(i + 1, "")
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")

    return mutate


T, I, C = "strip.toml", "image_points.csv", "control.csv"
PD = "principal_distance_mm = 152.87"

BAD_INPUTS = [
    # ---- strip.toml
    (
        sub(T, PD, "principal_distance_mm = "),
        r"strip\.toml:5:\d+: TOML syntax error",
        "toml-syntax",
    ),
    (
        sub(T, PD, "principal_distanc_mm = 152.87"),
        r"strip\.toml: unknown key 'principal_distanc_mm' in \[camera\] "
        r"\(did you mean 'principal_distance_mm'\?\)",
        "unknown-key",
    ),
    (
        sub(T, "[images]", "[image]"),
        r"strip\.toml: unknown table 'image' \(did you mean 'images'\?\)",
        "unknown-table",
    ),
    (
        sub(T, PD, PD + "\nsigma_mm = 0.003"),
        r"unknown key 'sigma_mm' in \[camera\] \(it belongs in \[images\] sigma_mm\)",
        "key-in-wrong-table",
    ),
    (
        sub(T, "[strip]", 'photos = ["1201"]\n[strip]'),
        r"strip\.toml: unknown top-level key 'photos' .*did you mean \[strip\] photos\?",
        "top-level-key",
    ),
    (
        sub(T, 'crs = "local"', ""),
        r"strip\.toml: \[control\]: missing required key 'crs'",
        "missing-key",
    ),
    (
        sub(T, "[camera]\n" + PD, ""),
        r"strip\.toml: missing required table \[camera\]",
        "missing-table",
    ),
    (
        sub(T, PD, 'principal_distance_mm = "abc"'),
        r"strip\.toml: \[camera\] principal_distance_mm: expected a positive number, "
        r'got the string "abc"',
        "type-string-for-number",
    ),
    (
        sub(T, PD, "principal_distance_mm = -152.87"),
        r"\[camera\] principal_distance_mm: expected a positive finite number, got -152\.87",
        "negative",
    ),
    (
        sub(T, PD, "principal_distance_mm = nan"),
        r"\[camera\] principal_distance_mm: expected a positive finite number, got nan",
        "nan",
    ),
    (
        sub(T, PD, "principal_distance_mm = true"),
        r"principal_distance_mm: expected a positive number, got the boolean true",
        "bool-for-number",
    ),
    (
        sub(T, PD, PD + "\nprincipal_point_mm = [0.0]"),
        r"\[camera\] principal_point_mm: expected a list of two finite numbers",
        "principal-point-length",
    ),
    (
        sub(T, '["1201", "1202", "1203"]', "[]"),
        r"strip\.toml: \[strip\] photos: a strip needs at least two photos, got 0",
        "photos-empty",
    ),
    (
        sub(T, '"1202", "1203"]', '"1202", "1202", "1203"]'),
        r"\[strip\] photos: id '1202' is listed twice",
        "photos-duplicate",
    ),
    (
        sub(T, '["1201", "1202", "1203"]', "[1201, 1202, 1203]"),
        r'\[strip\] photos: ids must be strings, got the number 1201 \(write "1201"\)',
        "photos-not-strings",
    ),
    (
        append(T, '[adjustment]\nroute = "geodetic"\n'),
        r'strip\.toml: \[adjustment\] route: expected one of "geocentric", "projected" '
        r'\(any case\), got the string "geodetic"',
        "enum-invalid",
    ),
    (
        append(T, "[adjustment]\npolynomial = 4\n"),
        r'\[adjustment\] polynomial: expected 0, 1, 2, 3 or "auto", got the number 4',
        "polynomial-range",
    ),
    (
        append(T, "[adjustment]\nsections = 0\n"),
        r"\[adjustment\] sections: expected a positive integer",
        "sections-zero",
    ),
    (
        append(T, "[adjustment]\npolynomial = 0\nsections = 3\n"),
        r"\[adjustment\] sections: 3 sections need a polynomial type 1, 2, 3 or \"auto\", "
        r"got polynomial = 0",
        "sections-without-polynomial",
    ),
    (
        append(T, "[adjustment]\nmax_iterations = 0\n"),
        r"\[adjustment\] max_iterations: expected a positive integer",
        "max-iterations",
    ),
    (
        append(T, '[adjustment]\nroute = "geocentric"\n'),
        r'strip\.toml: \[adjustment\] route: "geocentric" needs a geodetic CRS',
        "geocentric-with-local",
    ),
    (
        sub(T, 'crs = "local"', 'crs = "EPSG:4326"\n[adjustment]\nroute = "projected"'),
        r'\[adjustment\] route: "projected" needs a projected CRS',
        "projected-with-geographic",
    ),
    (
        sub(T, 'crs = "local"', 'crs = "EPSG:999999"'),
        r"strip\.toml: \[control\] crs: not a CRS pyproj understands: 'EPSG:999999'",
        "crs-unknown",
    ),
    (
        sub(T, 'crs = "local"', 'crs = "EPSG:32634+5773"'),
        r"\[control\] crs: 'EPSG:32634\+5773' has a vertical component",
        "crs-with-vertical",
    ),
    (
        sub(T, 'crs = "local"', 'crs = "EPSG:4326"'),
        r"control\.csv:2: latitude Y outside -90\.\.90 degrees \(crs 'EPSG:4326' is geographic",
        "geographic-range",
    ),
    (
        write(T, b'[strip]\nname = "caf\xe9"\n'),
        r"strip\.toml:2: not valid UTF-8 \(byte 0xe9\)",
        "toml-not-utf8",
    ),
    (
        append(T, '[straight_line]\npoints = ["002", "003", "004"]\n'),
        r"strip\.toml: 'straight_line' must be an array of tables, written \[\[straight_line\]\]",
        "line-not-array",
    ),
    (
        append(T, '[[straight_line]]\npoints = ["002", "003", "004"]\nweight = 0\n'),
        r"\[\[straight_line\]\] #1 weight: expected a positive finite number, got 0",
        "line-weight",
    ),
    (
        append(T, '[[straight_line]]\npoints = ["002", "003", "X9"]\n'),
        r"\[\[straight_line\]\] #1 points: point 'X9' is not observed on any photo",
        "line-point-unobserved",
    ),
    (
        append(T, '[[straight_line]]\npoints = ["002", "001", "003"]\n'),
        r"\[\[straight_line\]\] #1 points: point '001' is a control point",
        "line-point-is-control",
    ),
    (
        append(T, '[[straight_line]]\npoints = ["002", "003"]\n'),
        r"\[\[straight_line\]\] #1 points: a straight line needs at least three points",
        "line-too-short",
    ),
    (
        append(T, '[output]\ndirectory = "."\n'),
        r"strip\.toml: \[output\] directory: output folder .* is the project folder",
        "output-is-project-folder",
    ),
    (
        append(T, '[output]\ndirectory = ".."\n'),
        r"\[output\] directory: output folder .* contains the input file",
        "output-contains-inputs",
    ),
    # ---- image_points.csv
    (
        sub(T, 'file = "image_points.csv"', 'file = "nope.csv"'),
        r"nope\.csv: file named by \[images\] file not found",
        "csv-missing",
    ),
    (append(I, b"1203,099,1.0,\xe9\n"), r"image_points\.csv:35: not valid UTF-8", "csv-latin1"),
    (
        sub(I, "photo,point,x,y", "photo,point,x"),
        r"image_points\.csv:1: missing required column\(s\) y",
        "csv-missing-column",
    ),
    (
        sub(I, "photo,point,x,y", "photo,point,x,y,sigm"),
        r"image_points\.csv:1: unknown column 'sigm' \(did you mean 'sigma'\?\)",
        "csv-unknown-column",
    ),
    (
        sub(I, "photo,point,x,y", "photo,point,x,X"),
        r"image_points\.csv:1: column 'X' appears twice",
        "csv-duplicate-column",
    ),
    (
        sub(I, "1201,002,46.220", "1201,002,4x6.220"),
        r"image_points\.csv:3: column 'x': expected a number, got '4x6\.220'",
        "csv-bad-number",
    ),
    (
        sub(I, "1201,002,46.220", "1201,002,inf"),
        r"image_points\.csv:3: column 'x': expected a finite number, got 'inf'",
        "csv-inf",
    ),
    (
        sub(I, "1201,002,46.220,-66.336", "1201,002,46.220, "),
        r"image_points\.csv:3: column 'y' is empty",
        "csv-empty-value",
    ),
    (
        sub(I, "1201,002,46.220", "1201,002,46,220"),
        r"image_points\.csv:3: expected 4 fields \(photo,point,x,y\), got 5 \(decimal commas",
        "csv-field-count",
    ),
    (
        sub(I, "1201,002", ",002"),
        r"image_points\.csv:3: column 'photo': empty id",
        "csv-empty-id",
    ),
    (
        sub(I, "1201,002", '1201,"002'),
        r"image_points\.csv:3: malformed CSV: ",
        "csv-unclosed-quote",
    ),
    (
        append(I, "1201,001,1.0,2.0\n"),
        r"image_points\.csv:35: duplicate observation of point '001' on photo '1201' "
        r"\(first at line 2\)",
        "csv-duplicate-row",
    ),
    (
        append(I, "9999,001,1.0,2.0\n"),
        r"image_points\.csv:35: photo '9999' is not in \[strip\] photos",
        "csv-unknown-photo",
    ),
    (
        sub(T, '"1203"]', '"1203", "1204"]'),
        r"image_points\.csv: photo '1204' \(listed in \[strip\] photos\) has no observations",
        "photo-without-observations",
    ),
    (
        add_column(I, "sigma", {3: "-0.001"}),
        r"image_points\.csv:3: column 'sigma': expected a positive number, got '-0\.001'",
        "csv-sigma-negative",
    ),
    (write(I, "# only a comment\n\n"), r"image_points\.csv: no header line", "csv-no-header"),
    # ---- control.csv
    (
        sub(C, "8.981,full", "8.981,fulll"),
        r"control\.csv:2: column 'type': unknown type 'fulll' \(did you mean 'full'\?\)",
        "control-unknown-type",
    ),
    (
        sub(C, "8.981,full", "8.981,plan"),
        r"control\.csv:2: point '001' of type 'plan': a plan point leaves H empty",
        "control-plan-with-h",
    ),
    (
        sub(C, "8.981,full", "8.981,height"),
        r"control\.csv:2: point '001' of type 'height': a height point leaves X and Y empty",
        "control-height-with-xy",
    ),
    (
        sub(C, "8.981,full", ",full"),
        r"control\.csv:2: point '001' of type 'full': a full point needs X, Y and H",
        "control-full-missing-h",
    ),
    (
        append(C, "005,1.0,2.0,3.0,check\n"),
        r"control\.csv:7: point '005' is listed twice \(first at line 3\)",
        "control-duplicate",
    ),
    (
        add_column(C, "sigma_xy", {4: "0"}),
        r"control\.csv:4: column 'sigma_xy': expected a positive number, got '0'",
        "control-sigma-zero",
    ),
    (write(C, "point,X,Y,H,type\n"), r"control\.csv: no control points", "control-empty"),
    (
        sub(C, "point,X,Y,H,type", "point,X,Y,type"),
        r"control\.csv:1: missing required column\(s\) H",
        "control-missing-column",
    ),
]


@pytest.mark.parametrize(
    ("mutate", "pattern"),
    [pytest.param(m, p, id=i) for m, p, i in BAD_INPUTS],
)
def test_bad_input_raises_one_line_naming_the_culprit(
    minimal: Path, mutate: Mutator, pattern: str
) -> None:
    mutate(minimal)
    before = snapshot(minimal)
    with pytest.raises(ConfigError) as info:
        load_project(minimal / "strip.toml")
    message = str(info.value)
    assert re.search(pattern, message), message
    assert "\n" not in message
    assert snapshot(minimal) == before  # inputs never modified, nothing written


def test_missing_project_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"nothere\.toml: project file not found"):
        load_project(tmp_path / "nothere.toml")


def test_at_least_twenty_distinct_bad_inputs() -> None:
    assert len({i for _, _, i in BAD_INPUTS}) == len(BAD_INPUTS) >= 20


def test_key_list_defaults_match_the_dataclass_defaults() -> None:
    from strip_aerotri.options import BlunderOptions, ImageOptions

    dataclass_of = {
        "adjustment": AdjustmentOptions(),
        "blunders": BlunderOptions(),
        "images": ImageOptions(),
    }
    compared = 0
    for spec in PROJECT_KEYS:
        options = dataclass_of.get(spec.table)
        # route and block are resolved by the loader (from the CRS; from the
        # polynomial and sections keys)
        if (
            options is not None
            and hasattr(options, spec.key)
            and spec.key not in ("route", "block")
        ):
            assert getattr(options, spec.key) == spec.default, spec.qualified
            compared += 1
        assert spec.default_display  # something to show in docs and `stripaero check`
    assert compared >= 15
    assert {s.table for s in PROJECT_KEYS} == {t.name for t in PROJECT_TABLES}


def test_docs_show_the_key_list_defaults() -> None:
    """docs/project-file.md's default column is the key list's default."""
    import re

    text = DOCS.read_text(encoding="utf-8")
    rows: dict[tuple[str, str], str] = {}
    table = None
    for line in text.splitlines():
        heading = re.match(r"### `\[\[?(\w+)\]\]?`", line)
        if heading:
            table = heading.group(1)
            continue
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|"))]
        if table and len(cells) == 5 and re.fullmatch(r"`\w+`", cells[0]):
            rows[(table, cells[0].strip("`"))] = cells[3]
    checked = 0
    for spec in PROJECT_KEYS:
        shown = rows.get((spec.table, spec.key))
        assert shown is not None, f"{spec.qualified} has no row in the docs"
        if spec.required:
            assert shown.lower() in ("required", ""), (spec.qualified, shown)
            continue
        if spec.default is None or spec.default_text:
            continue  # derived defaults are explained in words
        first = shown.split(";")[0].strip().strip("`")
        assert first == spec.default_display, (spec.qualified, shown, spec.default_display)
        checked += 1
    assert checked >= 25


def test_blunders_table_sets_the_critical_value_of_every_stage(minimal: Path) -> None:
    """Every stage of blunders.STAGES, the bundle's GNSS and IMU tests included,
    takes its critical |w| from [blunders]; stages not given use alpha."""
    from strip_aerotri.blunders import STAGES

    values = {stage: 3.0 + 0.25 * i for i, stage in enumerate(STAGES)}
    lines = "\n".join(f"{stage} = {value}" for stage, value in values.items())
    append("strip.toml", f"\n[blunders]\n{lines}\n")(minimal)
    options = load_project(minimal / "strip.toml").blunders
    assert options.critical_values == values
    assert options.critical("gnss", 36) == values["gnss"]
    assert options.critical("imu", 36) == values["imu"]


def test_blunders_stage_value_must_be_positive(minimal: Path) -> None:
    append("strip.toml", "\n[blunders]\ngnss = -1.0\n")(minimal)
    with pytest.raises(ConfigError, match=r"\[blunders\].*gnss"):
        load_project(minimal / "strip.toml")


@pytest.mark.parametrize(
    ("lines", "block"),
    [
        ("", Block.MODELS),
        ("polynomial = 3\n", Block.STRIPS),
        ("sections = 2\n", Block.STRIPS),
        ('block = "models"\n', Block.MODELS),
        ('block = "STRIPS"\n', Block.STRIPS),
        ('block = "strips"\npolynomial = 2\n', Block.STRIPS),
    ],
)
def test_block_default_follows_the_polynomial_keys(minimal: Path, lines: str, block) -> None:
    """Without a polynomial the models are transformed at once; naming a
    polynomial or sections asks for J's construction."""
    append("strip.toml", f"\n[adjustment]\n{lines}")(minimal)
    assert load_project(minimal / "strip.toml").adjustment.block is block


def test_block_models_with_a_polynomial_is_an_error(minimal: Path) -> None:
    append("strip.toml", '\n[adjustment]\nblock = "models"\npolynomial = 3\n')(minimal)
    with pytest.raises(ConfigError, match=r"\[adjustment\] polynomial: applies to block"):
        load_project(minimal / "strip.toml")


def test_semicolon_csv_gets_a_hint(minimal: Path) -> None:
    path = minimal / "image_points.csv"
    path.write_text(path.read_text().replace(",", ";"))
    with pytest.raises(ConfigError, match=r"image_points\.csv:1: .*separated by ';'.*decimal"):
        load_project(minimal / "strip.toml")


@pytest.mark.parametrize(
    ("n", "text"), [(2, "2nd"), (3, "3rd"), (4, "4th"), (11, "11th"), (12, "12th"), (21, "21st")]
)
def test_english_ordinals(n: int, text: str) -> None:
    from strip_aerotri.project.check import _ordinal

    assert _ordinal(n) == text
