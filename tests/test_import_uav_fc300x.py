"""``stripaero import uav-fc300x``: the FC300X block's text files.

Two data sets: the synthetic sample ``tests/data/import/fc300x`` (always) and
the real block in ``../shared/data/uav-block-fc300x`` (skipped when absent:
no licence is published with it, so it is never copied here).  Counts of the
real block are computed here from its files with a plain reader, not taken
from the importer.
"""

from __future__ import annotations

import csv
import importlib.util
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.errors import ConfigError
from strip_aerotri.importers.common import ImportOptions, write_project
from strip_aerotri.importers.uav_fc300x import import_uav_fc300x, read_calibration
from strip_aerotri.interior import flight_matrix
from strip_aerotri.project import load_project

REPO = Path(__file__).resolve().parents[1]
SAMPLE = REPO / "tests" / "data" / "import"
DATA = REPO.parent / "shared" / "data" / "uav-block-fc300x"
needs_data = pytest.mark.skipif(
    not (DATA / "GCP_UTM.txt").is_file(),
    reason=f"FC300X data not found in {DATA} (read from ../shared, never copied here)",
)

# --------------------------------------------------------------------------- synthetic sample


def _truth() -> tuple[dict, list[str]]:
    obs = {
        (r["photo"], r["point"]): (float(r["x"]), float(r["y"]))
        for r in csv.DictReader((SAMPLE / "truth" / "observations.csv").open())
    }
    names = [r["point"] for r in csv.DictReader((SAMPLE / "truth" / "points.csv").open())]
    return obs, names


def test_sample_strip_is_corrected_back_to_the_true_image_coordinates(tmp_path: Path) -> None:
    project = import_uav_fc300x(SAMPLE / "fc300x", ImportOptions(strips=(1,)))
    loaded = load_project(write_project(project, tmp_path / "p"))
    assert loaded.photo_ids == tuple(f"B1_{n}" for n in range(1, 6))
    assert loaded.images.flight_direction.value == "+y"
    assert loaded.crs == "local"
    truth, names = _truth()
    obs = loaded.observations
    photos = np.asarray(obs.photo_ids)[obs.photo]
    points = np.asarray(obs.point_ids)[obs.point]

    def true_id(pid: str) -> str:  # the generator's numbering (make_import_fixtures.py)
        n = int(pid.lstrip("TM"))
        return f"GCP{n - 100}" if pid.isdigit() else names[(n - 500 if n >= 500 else n - 1)]

    expected = np.array(
        [
            truth[(f"DJI_{int(p.split('_')[1]):04d}", true_id(q))]
            for p, q in zip(photos, points, strict=True)
        ]
    )
    # cal.cal's radial terms (CalCam model, General_scaling) undone by the loader's
    # projection-model inversion, then turned to the flight axes
    expected = expected @ flight_matrix("+y")[:2, :2].T
    np.testing.assert_allclose(obs.xy, expected, atol=1e-6)


def test_sample_block_drops_duplicates_and_reverses_the_strip_flown_back(tmp_path: Path) -> None:
    project = import_uav_fc300x(SAMPLE / "fc300x")
    toml = write_project(project, tmp_path / "p")
    doc = tomllib.loads(toml.read_text(encoding="utf-8"))
    assert [s["name"] for s in doc["strips"]] == ["B1", "B2"]
    assert doc["strips"][0]["photos"] == [f"B1_{n}" for n in range(1, 6)]
    # the camera kept its heading on the way back: strip B2 is listed in reverse
    assert doc["strips"][1]["photos"] == [f"B2_{n}" for n in range(5, 0, -1)]
    ids = {row["point"] for row in csv.DictReader((tmp_path / "p" / "image_points.csv").open())}
    # the matcher's copies of tie points 9-12 (make_import_fixtures.py) are left out;
    # its own points (those of 30-32 that the photos see) are kept, under M
    # (Matching.txt: 531) and MB2- (MatchingB2.txt: 30) ids
    assert sorted(i for i in ids if i.startswith("M")) == ["M531", "MB2-30"]
    control = list(csv.DictReader((tmp_path / "p" / "control.csv").open()))
    assert "999" not in {r["point"] for r in control}  # on no photo


def test_calibration_terms_without_a_definition_are_refused(tmp_path: Path) -> None:
    text = (
        (SAMPLE / "fc300x" / "cal.cal")
        .read_text()
        .replace("Tangential_t1 0.0", "Tangential_t1 1e-3")
    )
    (tmp_path / "cal.cal").write_text(text)
    with pytest.raises(ConfigError, match=r"cal\.cal:\d+: Tangential_t1 = 0\.001"):
        read_calibration(tmp_path / "cal.cal")


def test_a_bad_coordinate_names_file_and_line(tmp_path: Path) -> None:
    for f in (SAMPLE / "fc300x").iterdir():
        (tmp_path / f.name).write_bytes(f.read_bytes())
    lines = (tmp_path / "Tie_points_for_AO.txt").read_text().splitlines()
    fields = lines[3].split()
    lines[3] = " ".join([fields[0], fields[1], fields[2].replace(".", ","), *fields[3:]])
    (tmp_path / "Tie_points_for_AO.txt").write_text("\n".join(lines))
    with pytest.raises(ConfigError, match=r"Tie_points_for_AO\.txt:4: x: expected a number"):
        import_uav_fc300x(tmp_path)


# --------------------------------------------------------------------------- the real block


def _read(path: Path) -> list[tuple[str, str, float, float]]:
    """A plain reader of the image point files (independent of the importer)."""
    rows = []
    for line in path.read_text().splitlines():
        parts = line.split()
        if len(parts) >= 4 and parts[0].upper().endswith(".JPG"):
            rows.append((parts[0][:-4], parts[1], float(parts[2]), float(parts[3])))
    return rows


def _expected(photos: set[str]) -> set[tuple[str, str, float, float]]:
    """Observations after the duplicate rule, by plain loops (files in priority order)."""
    files = [
        ("GCP_ImageCs.txt", ""),
        ("Tie_points_for_AO.txt", "T"),
        ("Matching.txt", "M"),
        ("MatchingB2.txt", "MB2-"),
        ("MatchingB3.txt", "MB3-"),
    ]
    kept: list[tuple[str, str, float, float]] = []
    for name, prefix in files:
        rows = [(p, prefix + i, x, y) for p, i, x, y in _read(DATA / name) if p in photos]
        dup = {
            i
            for p, i, x, y in rows
            if any(q == p and np.hypot(x - a, y - b) < 0.005 for q, _, a, b in kept)
        }
        kept += [r for r in rows if r[1] not in dup]
    return {(p, i, float(f"{x:.9f}"), float(f"{y:.9f}")) for p, i, x, y in kept}  # as written


def _written(folder: Path) -> set[tuple[str, str, float, float]]:
    return {
        (r["photo"], r["point"], float(r["x"]), float(r["y"]))
        for r in csv.DictReader((folder / "image_points.csv").open())
    }


@needs_data
def test_real_strip_one(tmp_path: Path) -> None:
    project = import_uav_fc300x(DATA, ImportOptions(strips=(1,)))
    toml = write_project(project, tmp_path / "b1")
    loaded = load_project(toml)
    photos = {f"B1_{n}" for n in range(1, 11)}
    assert loaded.photo_ids == tuple(f"B1_{n}" for n in range(1, 11))
    assert loaded.images.flight_direction.value == "+y"
    written = _written(tmp_path / "b1")
    assert written == _expected(photos)
    # docs/uav.md: strip 1 has 1003 observations of 192 points (the example script's rows)
    assert len(written) == 1003
    assert len({r[1] for r in written}) == 192
    control = list(csv.DictReader((tmp_path / "b1" / "control.csv").open()))
    # data README: 27 GCPs are observed on strip 1
    assert len(control) == 27
    assert sum(r["type"] == "full" for r in control) == 6
    # cal.cal: f = 2320.1052500623382 px, sensor 6.2477 mm / 4000 px
    assert loaded.camera.principal_distance_mm == pytest.approx(2320.1052500623382 * 6.2477 / 4000)
    assert loaded.distortion.units.value == "normalized"
    assert loaded.distortion.model.value == "projection"


@needs_data
def test_real_strip_one_equals_the_example_script(tmp_path: Path) -> None:
    script = REPO / "examples" / "uav_fc300x.py"
    if not script.is_file():
        pytest.skip("examples/uav_fc300x.py is not in this tree")
    spec = importlib.util.spec_from_file_location("uav_fc300x_example", script)
    module = importlib.util.module_from_spec(spec)
    sys.modules["uav_fc300x_example"] = module
    spec.loader.exec_module(module)
    rows = set(module.read_strip(DATA, 1).image_rows)
    project = import_uav_fc300x(DATA, ImportOptions(strips=(1,)))
    write_project(project, tmp_path / "b1")
    as_written = {(p, i, float(f"{x:.9f}"), float(f"{y:.9f}")) for p, i, x, y in rows}
    assert as_written == _written(tmp_path / "b1")


@needs_data
def test_real_block(tmp_path: Path) -> None:
    project = import_uav_fc300x(DATA)
    toml = write_project(project, tmp_path / "block")
    doc = tomllib.loads(toml.read_text(encoding="utf-8"))
    assert "strip" not in doc
    assert [s["name"] for s in doc["strips"]] == ["B1", "B2", "B3"]
    for k, strip in enumerate(doc["strips"], start=1):
        assert strip["photos"] == [f"B{k}_{n}" for n in range(1, 11)]
    assert doc["images"]["flight_direction"] == "+y"
    assert doc["control"]["crs"] == "local"
    photos = {f"B{s}_{n}" for s in (1, 2, 3) for n in range(1, 11)}
    written = _written(tmp_path / "block")
    assert written == _expected(photos)
    control = list(csv.DictReader((tmp_path / "block" / "control.csv").open()))
    # data README: 33 GCPs are observed on the photos
    assert len(control) == 33
    gcp_ids = {r["point"] for r in control}
    # GCPs shared by strips keep one id: GCP 24 is seen on strips 1 and 2
    seen_on = {p.split("_")[0] for p, i, _, _ in written if i == "24"}
    assert "24" in gcp_ids and len(seen_on) >= 2


@needs_data
def test_real_calibration_matches_its_3dm_calibcam_export() -> None:
    cal = read_calibration(DATA / "cal.cal")
    s = cal.pixel_size_mm
    f = 2320.1052500623382  # cal.cal Focal_length
    # Calibration/tex.txt of rashidyreza/Strip-Adjustment-with-Matlab, the same
    # calibration exported in the 3DM CalibCam layout (correction form, r in mm):
    # K1 = 8.653781038e-004, K2 = -8.592621298e-005.  In normalised units these are
    # -K1 (f s)^2 and -K2 (f s)^4.
    assert cal.distortion.k1 == pytest.approx(-8.653781038e-4 * (f * s) ** 2, rel=1e-6)
    assert cal.distortion.k2 == pytest.approx(8.592621298e-5 * (f * s) ** 4, rel=1e-6)


def test_no_distortion_is_said_in_strip_toml(tmp_path: Path) -> None:
    """Without cal.cal's distortion (--no-distortion) strip.toml has no
    [distortion] and a comment says it was left out, as the other import
    comments do; with it, neither the comment nor the absence."""
    from click.testing import CliRunner

    from strip_aerotri.cli.main import cli

    texts = {}
    for flag in ([], ["--no-distortion"]):
        out = tmp_path / ("without" if flag else "with")
        ran = CliRunner().invoke(
            cli, ["import", "uav-fc300x", str(SAMPLE / "fc300x"), "-o", str(out), *flag]
        )
        assert ran.exit_code == 0, ran.output
        texts[bool(flag)] = (out / "strip.toml").read_text("utf-8")
    comment = (
        "# no [distortion]: cal.cal's radial distortion left out (--no-distortion), so the "
        "coordinates are taken as free of it; to estimate the lens from these photos: "
        '[adjustment] refine = "bundle" and self_calibration = "auto"'
    )
    assert comment in texts[True].splitlines()
    assert "distortion" not in tomllib.loads(texts[True])
    assert "distortion left out" not in texts[False]
    assert "distortion" in tomllib.loads(texts[False])
