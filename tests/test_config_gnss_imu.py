"""``[gnss]`` and ``[imu]`` in the project file: loading, every rule, and a run.

The GNSS centres and IMU attitudes are observations of the bundle refinement
(docs/bundle.md, docs/project-file.md).  Small projects are the minimal
fixture (tests/data/minimal, crs = "local", photos 1201-1203) with the two
tables added; the run is a simulated film strip (strip_aerotri.simulate).
"""

from __future__ import annotations

import csv
import json
import re
import shutil
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from strip_aerotri.bundle.refine import GnssCentres, ImuAttitudes
from strip_aerotri.cli.main import cli
from strip_aerotri.errors import ConfigError, StripAerotriWarning
from strip_aerotri.geodesy import GroundCRS, enu_rotation
from strip_aerotri.geometry.rotation import opk_from_matrix
from strip_aerotri.project import (
    GNSS_COLUMNS,
    IMU_COLUMNS,
    PROJECT_KEYS,
    PROJECT_TABLES,
    load_project,
)
from strip_aerotri.simulate import simulate_strip

DATA = Path(__file__).parent / "data"
DOCS = Path(__file__).parents[1] / "docs"

BUNDLE = '\n[adjustment]\nrefine = "bundle"\n'
GNSS_TABLE = '\n[gnss]\nfile = "gnss.csv"\n'
IMU_TABLE = '\n[imu]\nfile = "imu.csv"\n'
# Centres of the minimal project's photos (site system, metres); any values load.
GNSS_CSV = "photo,X,Y,Z\n1201,0.0,0.0,1223.0\n1202,600.0,1.5,1224.25\n1203,1200.0,-2.0,1222.5\n"
IMU_CSV = "photo,omega,phi,kappa\n1201,0.1,-0.2,90.0\n1202,0.0,0.3,89.5\n1203,-0.25,0.0,270.0\n"


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


@pytest.fixture
def minimal(tmp_path: Path) -> Path:
    """The minimal fixture with refine = "bundle", [gnss] and [imu]; returns its folder."""
    folder = tmp_path / "proj"
    shutil.copytree(DATA / "minimal", folder)
    with (folder / "strip.toml").open("a", encoding="utf-8") as f:
        f.write(BUNDLE + GNSS_TABLE + IMU_TABLE)
    (folder / "gnss.csv").write_text(GNSS_CSV, encoding="utf-8")
    (folder / "imu.csv").write_text(IMU_CSV, encoding="utf-8")
    return folder


def load_quietly(folder: Path):
    with warnings.catch_warnings():
        warnings.simplefilter("error", StripAerotriWarning)  # none expected
        return load_project(folder / "strip.toml")


# --------------------------------------------------------------------------- valid files


def test_existing_projects_load_unchanged() -> None:
    project = load_project(DATA / "minimal" / "strip.toml")
    assert project.gnss is None and project.imu is None
    assert project.gnss_file is None and project.imu_file is None
    assert project.input_files == tuple(
        DATA / "minimal" / name for name in ("strip.toml", "image_points.csv", "control.csv")
    )


def test_gnss_and_imu_without_sigma_columns_take_the_table_defaults(minimal: Path) -> None:
    before = snapshot(minimal)
    project = load_quietly(minimal)
    assert snapshot(minimal) == before  # inputs only read
    gnss, imu = project.gnss, project.imu
    assert isinstance(gnss, GnssCentres) and isinstance(imu, ImuAttitudes)
    assert gnss.photo_ids == imu.photo_ids == ("1201", "1202", "1203")
    # GNSS_CSV above, metres as written
    np.testing.assert_array_equal(
        gnss.xyz, [[0.0, 0.0, 1223.0], [600.0, 1.5, 1224.25], [1200.0, -2.0, 1222.5]]
    )
    # defaults of docs/project-file.md: sigma_xy 0.05 m, sigma_z 0.08 m, sigma_deg 0.005
    np.testing.assert_array_equal(gnss.sigma_xy, 0.05)
    np.testing.assert_array_equal(gnss.sigma_z, 0.08)
    # degrees in the file, radians in the library (IMU_CSV above)
    np.testing.assert_allclose(
        imu.opk,
        np.radians([[0.1, -0.2, 90.0], [0.0, 0.3, 89.5], [-0.25, 0.0, 270.0]]),
        rtol=0,
        atol=1e-15,
    )
    np.testing.assert_allclose(imu.sigma, np.radians(0.005), rtol=1e-15)
    assert project.gnss_file == minimal / "gnss.csv"
    assert project.imu_file == minimal / "imu.csv"
    assert project.input_files[-2:] == (minimal / "gnss.csv", minimal / "imu.csv")
    assert project.warnings == ()


def test_sigma_columns_and_table_defaults_for_blank_cells(minimal: Path) -> None:
    toml = minimal / "strip.toml"
    toml.write_text(
        toml.read_text()
        .replace(GNSS_TABLE, GNSS_TABLE + "sigma_xy = 0.1\nsigma_z = 0.2\n")
        .replace(IMU_TABLE, IMU_TABLE + "sigma_deg = 0.01\n"),
        encoding="utf-8",
    )
    # BOM, CRLF, comments, blank lines, header in other case and order, rows not in
    # strip order: read as the other CSVs of the project are
    (minimal / "gnss.csv").write_bytes(
        "\ufeff# GNSS centres\r\nSIGMA_Z,Photo,x,y,z,Sigma_XY\r\n"
        ",1203,1200.0,-2.0,1222.5,0.03\r\n\r\n"
        "0.04,1201,0.0,0.0,1223.0,\r\n"
        "  # a comment\r\n"
        "0.06,1202,600.0,1.5,1224.25,0.02\r\n".encode()
    )
    (minimal / "imu.csv").write_text(
        "photo,omega,phi,kappa,SIGMA_DEG\n1202,0.0,0.3,89.5,\n1201,0.1,-0.2,90.0,0.002\n",
        encoding="utf-8",
    )
    project = load_quietly(minimal)
    gnss, imu = project.gnss, project.imu
    assert gnss.photo_ids == ("1201", "1202", "1203")  # strip order
    np.testing.assert_array_equal(gnss.xyz[0], [0.0, 0.0, 1223.0])
    np.testing.assert_array_equal(gnss.sigma_xy, [0.1, 0.02, 0.03])  # blank -> [gnss] sigma_xy
    np.testing.assert_array_equal(gnss.sigma_z, [0.04, 0.06, 0.2])  # blank -> [gnss] sigma_z
    assert imu.photo_ids == ("1201", "1202")  # a photo without a row is not an error
    np.testing.assert_allclose(imu.sigma, np.radians([0.002, 0.01]), rtol=1e-15)


def test_geographic_crs_gnss_is_longitude_latitude_as_the_control(tmp_path: Path) -> None:
    sim = simulate_strip(4, seed=2, crs="EPSG:4326", centre_lonlat=(23.3, 42.7))
    toml = sim.write_project(tmp_path)
    text = toml.read_text().replace("[adjustment]\n", '[adjustment]\nrefine = "bundle"\n')
    toml.write_text(text + GNSS_TABLE)
    lon_lat_h = sim.truth.photo_centres_crs
    rows = [
        f"{p},{x:.10f},{y:.10f},{h:.4f}"
        for p, (x, y, h) in zip(sim.observations.photo_ids, lon_lat_h.tolist(), strict=True)
    ]
    (tmp_path / "gnss.csv").write_text("photo,X,Y,Z\n" + "\n".join(rows) + "\n")
    project = load_quietly(tmp_path)
    # X longitude, Y latitude in degrees (pyproj always_xy), as control.csv
    written = np.array([[float(v) for v in r.split(",")[1:]] for r in rows])
    np.testing.assert_array_equal(project.gnss.xyz, written)
    np.testing.assert_allclose(project.gnss.xyz, lon_lat_h, rtol=0, atol=1e-4)
    assert 23.0 < project.gnss.xyz[0, 0] < 23.6 and 42.4 < project.gnss.xyz[0, 1] < 43.0

    # latitude and longitude swapped in one row: 23.3 passes, so swap to an impossible one
    rows[1] = rows[1].replace(f"{lon_lat_h[1, 1]:.10f}", "95.0000000000")
    (tmp_path / "gnss.csv").write_text("photo,X,Y,Z\n" + "\n".join(rows) + "\n")
    with pytest.raises(ConfigError) as info:
        load_project(toml)
    assert re.fullmatch(
        r".*gnss\.csv:3: latitude Y outside -90\.\.90 degrees \(crs 'EPSG:4326' is geographic: "
        r"X is the longitude and Y the latitude, in degrees\)",
        str(info.value),
    ), info.value


# --------------------------------------------------------------------------- unknown photos


def test_rows_of_photos_not_in_the_strip_are_warned_and_ignored(minimal: Path) -> None:
    with (minimal / "gnss.csv").open("a") as f:
        f.write("9001,5.0,5.0,1200.0\n9002,6.0,6.0,1200.0\n")
    (minimal / "imu.csv").write_text(IMU_CSV.replace("1202,", "0999,"), encoding="utf-8")
    with pytest.warns(StripAerotriWarning) as record:
        project = load_project(minimal / "strip.toml")
    messages = [str(w.message) for w in record]
    assert len(messages) == 2, messages
    assert re.fullmatch(
        r".*gnss\.csv:5: 2 row\(s\) of photo\(s\) not in \[strip\] photos ignored: "
        r"'9001', '9002'",
        messages[0],
    ), messages[0]
    assert re.fullmatch(
        r".*imu\.csv:3: 1 row\(s\) of photo\(s\) not in \[strip\] photos ignored: '0999'",
        messages[1],
    ), messages[1]
    # stacklevel: the warning points at the caller of load_project
    assert all(w.filename == __file__ for w in record)
    # the same lines among the project's warnings (the CLI prints those)
    assert project.warnings == tuple(messages)
    assert project.gnss.photo_ids == ("1201", "1202", "1203")
    assert project.imu.photo_ids == ("1201", "1203")
    np.testing.assert_allclose(project.imu.opk[1], np.radians([-0.25, 0.0, 270.0]))


def test_a_file_of_other_photos_only_leaves_no_observations(minimal: Path) -> None:
    (minimal / "gnss.csv").write_text("photo,X,Y,Z\n9001,5.0,5.0,1200.0\n")
    with pytest.warns(StripAerotriWarning, match=r"gnss\.csv:2: 1 row\(s\) .*'9001'"):
        project = load_project(minimal / "strip.toml")
    assert project.gnss.photo_ids == () and project.gnss.xyz.shape == (0, 3)
    assert len(project.imu.photo_ids) == 3


# --------------------------------------------------------------------------- bad inputs

Mutator = Callable[[Path], None]


def sub(name: str, old: str, new: str) -> Mutator:
    def mutate(folder: Path) -> None:
        path = folder / name
        text = path.read_text(encoding="utf-8")
        assert old in text, f"fixture changed: {old!r} not in {name}"
        path.write_text(text.replace(old, new, 1), encoding="utf-8")

    return mutate


def write(name: str, content: str) -> Mutator:
    def mutate(folder: Path) -> None:
        (folder / name).write_text(content, encoding="utf-8")

    return mutate


def remove(name: str) -> Mutator:
    def mutate(folder: Path) -> None:
        (folder / name).unlink()

    return mutate


T, G, U = "strip.toml", "gnss.csv", "imu.csv"
FIX = r'; add refine = "bundle" to \[adjustment\], or remove \[{}\]$'

BAD_INPUTS = [
    # ---- strip.toml
    (
        sub(T, 'refine = "bundle"', 'refine = "none"'),
        r"strip\.toml: \[gnss\]: GNSS centres are observations of the bundle refinement "
        r"only" + FIX.format("gnss"),
        "gnss-without-bundle",
    ),
    (
        sub(T, BUNDLE + GNSS_TABLE, ""),
        r"strip\.toml: \[imu\]: IMU attitudes are observations of the bundle refinement "
        r"only" + FIX.format("imu"),
        "imu-without-adjustment-table",
    ),
    (
        sub(T, 'file = "gnss.csv"', 'file = "gnss.csv"\nsigma_h = 0.1'),
        r"strip\.toml: unknown key 'sigma_h' in \[gnss\] \(did you mean 'sigma_z'\?\); "
        r"valid keys: file, sigma_xy, sigma_z$",
        "gnss-unknown-key",
    ),
    (
        sub(T, 'file = "imu.csv"', 'file = "imu.csv"\nsigma = 0.1'),
        r"strip\.toml: unknown key 'sigma' in \[imu\] \(did you mean 'sigma_deg'\?\); "
        r"valid keys: file, sigma_deg$",
        "imu-unknown-key",
    ),
    (
        sub(T, 'file = "gnss.csv"', "sigma_xy = 0.05"),
        r"strip\.toml: \[gnss\]: missing required key 'file'$",
        "gnss-missing-file-key",
    ),
    (
        sub(T, 'file = "gnss.csv"', 'file = "gnss.csv"\nsigma_xy = 0'),
        r"strip\.toml: \[gnss\] sigma_xy: expected a positive finite number, got 0$",
        "gnss-sigma-zero",
    ),
    (
        sub(T, 'file = "gnss.csv"', 'file = "gnss.csv"\nsigma_z = inf'),
        r"strip\.toml: \[gnss\] sigma_z: expected a positive finite number, got inf$",
        "gnss-sigma-infinite",
    ),
    (
        sub(T, 'file = "imu.csv"', 'file = "imu.csv"\nsigma_deg = -0.005'),
        r"strip\.toml: \[imu\] sigma_deg: expected a positive finite number, got -0\.005$",
        "imu-sigma-negative",
    ),
    (
        sub(T, 'file = "imu.csv"', 'file = "imu.csv"\nsigma_deg = "0.005"'),
        r'strip\.toml: \[imu\] sigma_deg: expected a positive number, got the string "0\.005"$',
        "imu-sigma-string",
    ),
    (
        sub(T, "[imu]", "[imus]"),
        r"strip\.toml: unknown table 'imus' \(did you mean 'imu'\?\)",
        "unknown-table",
    ),
    # ---- gnss.csv
    (
        remove(G),
        r"gnss\.csv: file named by \[gnss\] file not found$",
        "gnss-file-missing",
    ),
    (
        write(G, "photo,X,Y,Z\n"),
        r"gnss\.csv: no GNSS centres \(only a header\)$",
        "gnss-header-only",
    ),
    (
        sub(G, "photo,X,Y,Z", "photo,X,Y,H"),
        r"gnss\.csv:1: unknown column 'H'.*; allowed columns: photo, X, Y, Z, sigma_xy, "
        r"sigma_z$",
        "gnss-unknown-column",
    ),
    (
        sub(G, "photo,X,Y,Z", "photo,X,Y,Z,sigma_zz"),
        r"gnss\.csv:1: unknown column 'sigma_zz' \(did you mean 'sigma_z'\?\)",
        "gnss-misspelt-column",
    ),
    (
        write(G, "photo,X,Y\n1201,0,0\n"),
        r"gnss\.csv:1: missing required column\(s\) Z \(header is: photo,X,Y\)$",
        "gnss-missing-column",
    ),
    (
        sub(G, "1202,600.0,", "1202,6OO.0,"),
        r"gnss\.csv:3: column 'X': expected a number, got '6OO\.0'$",
        "gnss-not-a-number",
    ),
    (
        sub(G, "1224.25", "inf"),
        r"gnss\.csv:3: column 'Z': expected a finite number, got 'inf'$",
        "gnss-infinite",
    ),
    (
        sub(G, "1203,1200.0,", "1203,nan,"),
        r"gnss\.csv:4: column 'X': expected a finite number, got 'nan'$",
        "gnss-nan",
    ),
    (
        sub(G, "1202,600.0,1.5,", "1202,600.0,,"),
        r"gnss\.csv:3: column 'Y' is empty$",
        "gnss-empty-coordinate",
    ),
    (
        write(G, "photo,X,Y,Z,sigma_xy\n1201,0,0,1223,0.05\n1202,600,0,1223,-0.05\n"),
        r"gnss\.csv:3: column 'sigma_xy': expected a positive number, got '-0\.05'$",
        "gnss-sigma-column-negative",
    ),
    (
        write(G, "photo,X,Y,Z,sigma_z\n1201,0,0,1223,0\n"),
        r"gnss\.csv:2: column 'sigma_z': expected a positive number, got '0'$",
        "gnss-sigma-column-zero",
    ),
    (
        write(G, GNSS_CSV + "# repeated\n1202,600.0,1.5,1224.25\n"),
        r"gnss\.csv:6: photo '1202' is listed twice \(first at line 3\)$",
        "gnss-duplicate-photo",
    ),
    (
        sub(G, "1202,", " ,"),
        r"gnss\.csv:3: column 'photo': empty id$",
        "gnss-empty-id",
    ),
    (
        sub(G, "1202,600.0,1.5,1224.25", "1202,600,0,1.5,1224.25"),
        r"gnss\.csv:3: expected 4 fields \(photo,X,Y,Z\), got 5 \(decimal commas\? use a "
        r"point\)$",
        "gnss-decimal-comma",
    ),
    # ---- imu.csv
    (
        remove(U),
        r"imu\.csv: file named by \[imu\] file not found$",
        "imu-file-missing",
    ),
    (
        write(U, "# nothing yet\nphoto,omega,phi,kappa\n"),
        r"imu\.csv: no IMU attitudes \(only a header\)$",
        "imu-header-only",
    ),
    (
        sub(U, "photo,omega,phi,kappa", "photo,omega,phi,kapa"),
        r"imu\.csv:1: unknown column 'kapa' \(did you mean 'kappa'\?\); allowed columns: "
        r"photo, omega, phi, kappa, sigma_deg$",
        "imu-misspelt-column",
    ),
    (
        sub(U, "89.5", "89,5"),
        r"imu\.csv:3: expected 4 fields \(photo,omega,phi,kappa\), got 5",
        "imu-decimal-comma",
    ),
    (
        sub(U, "-0.25", "-Infinity"),
        r"imu\.csv:4: column 'omega': expected a finite number, got '-Infinity'$",
        "imu-infinite",
    ),
    (
        write(U, "photo,omega,phi,kappa,sigma_deg\n1201,0,0,90,0.005\n1202,0,0,90,abc\n"),
        r"imu\.csv:3: column 'sigma_deg': expected a number, got 'abc'$",
        "imu-sigma-not-a-number",
    ),
    (
        write(U, "photo,omega,phi,kappa,sigma_deg\n1201,0,0,90,-1\n"),
        r"imu\.csv:2: column 'sigma_deg': expected a positive number, got '-1'$",
        "imu-sigma-negative-column",
    ),
    (
        write(U, IMU_CSV + "1201,0.1,-0.2,90.0\n"),
        r"imu\.csv:5: photo '1201' is listed twice \(first at line 2\)$",
        "imu-duplicate-photo",
    ),
]


@pytest.mark.parametrize(
    ("mutate", "pattern"),
    [(m, p) for m, p, _ in BAD_INPUTS],
    ids=[i for _, _, i in BAD_INPUTS],
)
def test_bad_input_is_one_config_error_naming_file_and_line_or_key(
    minimal: Path, mutate: Mutator, pattern: str
) -> None:
    mutate(minimal)
    before = snapshot(minimal)
    with pytest.raises(ConfigError) as info:
        load_project(minimal / "strip.toml")
    message = str(info.value)
    assert re.search(pattern, message), message
    assert str(minimal) in message  # the file is named with its path
    assert "\n" not in message
    assert snapshot(minimal) == before


def test_output_directory_may_not_hold_the_gnss_file(minimal: Path) -> None:
    (minimal / "data").mkdir()
    (minimal / "gnss.csv").rename(minimal / "data" / "gnss.csv")
    toml = minimal / "strip.toml"
    toml.write_text(
        toml.read_text().replace('"gnss.csv"', '"data/gnss.csv"')
        + '[output]\ndirectory = "data"\n'
    )
    with pytest.raises(ConfigError, match=r"contains the input file '.*data/gnss\.csv'"):
        load_project(toml)


# --------------------------------------------------------------------------- docs


def test_docs_name_the_tables_keys_and_columns() -> None:
    text = (DOCS / "project-file.md").read_text(encoding="utf-8")
    for name in ("gnss", "imu"):
        assert f"### `[{name}]` (optional, *extension*)" in text
    assert {t.name for t in PROJECT_TABLES} >= {"gnss", "imu"}
    for spec in PROJECT_KEYS:
        if spec.table in ("gnss", "imu"):
            assert not spec.contract, spec.qualified
            assert f"| `{spec.key}` |" in text, spec.qualified
    for column in GNSS_COLUMNS + IMU_COLUMNS:
        assert f"| `{column.name}` |" in text, column.name
    bundle = (DOCS / "bundle.md").read_text(encoding="utf-8")
    assert "proposed" not in bundle


# --------------------------------------------------------------------------- CLI


def invoke(*args: str | Path):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_check_reports_the_counts_and_the_warning_once(minimal: Path) -> None:
    with (minimal / "gnss.csv").open("a") as f:
        f.write("9001,5.0,5.0,1200.0\n")
    (minimal / "imu.csv").write_text(IMU_CSV.replace("1202,0.0,0.3,89.5\n", ""))
    sub(T, 'refine = "bundle"', 'refine = "bundle"\npolynomial = 1')(minimal)  # 5 control points
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the command catches its own warnings
        result = invoke("check", minimal / "strip.toml")
    assert result.exit_code == 0, result.output
    assert f"GNSS centres: 3 of 3 photos ({minimal / 'gnss.csv'})" in result.stdout
    assert f"IMU attitudes: 2 of 3 photos ({minimal / 'imu.csv'})" in result.stdout
    assert result.stderr.count("not in [strip] photos ignored: '9001'") == 1


def true_opk_enu(sim) -> np.ndarray:
    """True omega, phi, kappa (rad) image -> local ENU at each centre (as tests/test_refine.py)."""
    truth = sim.truth
    llh = GroundCRS.from_user_input(sim.crs).to_geodetic(truth.photo_centres_crs)
    r_ecef = truth.local_to_ecef.ecef2enu.T @ truth.photo_rotations_local
    return opk_from_matrix(enu_rotation(llh[:, 0], llh[:, 1]) @ r_ecef)


# Three control points for a 12-photo strip of simulate_strip(seed=1): full at the
# start (left) and at the end (right), height in the middle (left): the least the
# strip method needs with polynomial 0 (two plan, three height points).  Every
# other control point of the simulation becomes a check point.
E2E_CONTROL = {"P0004": "full", "P0137": "full", "P0061": "height"}


def test_run_with_gnss_and_imu_end_to_end(tmp_path: Path, monkeypatch) -> None:
    from strip_aerotri.report import outputs as report

    build = report.strip_outputs  # the HTML figures take seconds; every other file is built
    monkeypatch.setattr(report, "strip_outputs", lambda r, **kw: build(r, **{**kw, "html": False}))

    sim = simulate_strip(12, seed=1, crs="EPSG:32634")
    folder = tmp_path / "film"
    toml = sim.write_project(folder, polynomial=0)
    path = folder / "control.csv"
    rows = list(csv.reader(path.read_text().splitlines()))
    assert rows[0][:5] == ["point", "X", "Y", "H", "type"]
    for row in rows[1:]:
        row[4] = E2E_CONTROL.get(row[0], "check")
        if row[4] == "height":
            row[1] = row[2] = ""
    path.write_text("\n".join(",".join(r) for r in rows) + "\n")
    assert sorted(r[4] for r in rows[1:] if r[4] != "check") == ["full", "full", "height"]

    ids = sim.observations.photo_ids
    m = len(ids)
    rng = np.random.default_rng(0)
    centres = sim.truth.photo_centres_crs + rng.normal(0.0, 0.05, (m, 3))  # GNSS, 5 cm
    opk_deg = np.degrees(true_opk_enu(sim)) + rng.normal(0.0, 0.005, (m, 3))  # IMU, 0.005 deg
    (folder / "gnss.csv").write_text(
        "photo,X,Y,Z,sigma_xy,sigma_z\n"
        + "".join(
            f"{p},{x:.4f},{y:.4f},{z:.4f},0.05,0.05\n"
            for p, (x, y, z) in zip(ids, centres.tolist(), strict=True)
        )
    )
    (folder / "imu.csv").write_text(
        "photo,omega,phi,kappa\n"
        + "".join(
            f"{p},{o:.6f},{f:.6f},{k:.6f}\n"
            for p, (o, f, k) in zip(ids, opk_deg.tolist(), strict=True)
        )
    )
    text = toml.read_text().replace("[adjustment]\n", '[adjustment]\nrefine = "bundle"\n')
    toml.write_text(text + GNSS_TABLE + IMU_TABLE)  # sigma_deg: the default 0.005

    result = invoke("-q", "run", toml)
    assert result.exit_code == 0, result.output
    # the summary reports the refined solution, whose points are written
    assert "bundle refinement: accuracy below is the refined solution's" in result.output
    out = folder / "out"
    rep = json.loads((out / "report.json").read_text())
    bundle = rep["bundle"]
    assert bundle["converged"] and bundle["rejections"] == []
    # every observation counted: 2 per image row, 3 + 3 + 1 control components,
    # 3 per GNSS centre and 3 per IMU attitude of the 12 photos
    n_image = 2 * len(sim.observations.photo)
    assert bundle["n_observations"] == n_image + 7 + 3 * m + 3 * m

    # Check points.  Measured for GNSS/IMU noise seeds 0-9 with this control:
    # bundle with GNSS + IMU, plan RMSE 0.052-0.074 m and height
    # 0.068-0.091 m (seed 0: 0.070 m, 0.075 m); with GNSS only 0.057-0.086 m and
    # 0.072-0.096 m; without them (the same three control points) 0.130 m and
    # 0.617 m, and the strip method (polynomial 0) 0.178 m and 0.526 m.  The
    # bounds (0.10 m, 0.12 m) pass every seed and fail without the GNSS.
    check = bundle["check"]
    # 50 check points of the simulation plus its other control as check points:
    # 3 full (plan and height), 2 plan, 6 height
    assert (check["n_plan"], check["n_height"]) == (55, 59)
    strip = bundle["strip_method_check"]
    plan, height = check["rmse_plan_m"], check["rmse_h_m"]
    assert plan < 0.10 and height < 0.12, (plan, height)
    assert strip["rmse_h_m"] > 0.4  # the strip method alone cannot hold the height
    # the adjusted centres follow the GNSS: within its 5 cm noise of the truth
    # (measured RMS 0.032 m against the truth; the GNSS written here 0.039 m)
    photos = list(csv.DictReader((out / "photos.csv").read_text().splitlines()))
    got = np.array([[float(r[k]) for k in ("X", "Y", "Z")] for r in photos])
    assert [r["photo"] for r in photos] == list(ids)
    err = got - sim.truth.photo_centres_crs
    assert np.sqrt(np.mean(err**2)) < 0.05, err
