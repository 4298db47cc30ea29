"""Tests of the outputs of a run (report.py): CSVs, report.json, report.html, GeoJSON."""

from __future__ import annotations

import base64
import csv
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest
from pyproj import Transformer
from scipy.spatial.transform import Rotation

from strip_aerotri.ground.polynomials import GroundOptions, LineSpec
from strip_aerotri.pipeline import triangulate
from strip_aerotri.project import load_project, run_project
from strip_aerotri.report.outputs import (
    build_html,
    build_outputs,
    build_report,
    point_roles,
    points_geojson,
)
from strip_aerotri.simulate import simulate_strip


def _no_nan(name):
    raise AssertionError(f"report.json holds {name}")


def _run(sim, polynomial=3, route="geocentric"):
    lines = [
        LineSpec(point_ids=tuple(ids), weight=w, name=f"road{k}")
        for k, (ids, w) in enumerate(sim.lines)
    ]
    return triangulate(
        sim.observations,
        sim.control,
        sim.crs,
        lines=lines,
        ground_options=GroundOptions(route=route, polynomial=polynomial),
    )


@pytest.fixture(scope="module")
def utm():
    sim = simulate_strip(
        7, preset="corridor", crs="EPSG:32634", seed=5, control="every_k_models", n_check=6
    )
    result = _run(sim, polynomial="auto")
    return sim, result, build_outputs(result, map_scale=2000)


@pytest.fixture(scope="module")
def local():
    sim = simulate_strip(5, preset="film", crs="local", seed=11, n_check=3)
    result = _run(sim, polynomial=1, route="projected")
    return sim, result, build_outputs(result)


def _rows(data: bytes) -> list[dict[str, str]]:
    return list(csv.DictReader(io.StringIO(data.decode("utf-8"))))


# ----------------------------------------------------------------- keys and CSVs


def test_output_files(utm, local):
    assert set(utm[2]) == {
        "points.csv",
        "photos.csv",
        "report.json",
        "report.html",
        "points.geojson",
    }
    assert all(isinstance(v, bytes) for v in utm[2].values())
    assert "points.geojson" not in local[2]
    report = json.loads(local[2]["report.json"])
    assert any("points.geojson" in w for w in report["warnings"])
    assert report["outputs"]["points.geojson"]["written"] is False


def test_points_csv_contract_columns_and_values(utm):
    sim, result, files = utm
    text = files["points.csv"].decode("utf-8")
    header = text.splitlines()[0].split(",")
    assert header[:4] == ["point", "X", "Y", "H"]  # formats.md "Outputs"
    assert header[4:] == ["role", "n_models", "n_images", "dE", "dN", "dH"]
    rows = _rows(files["points.csv"])
    ok = np.isfinite(result.points).all(axis=1)
    assert len(rows) == int(ok.sum())
    ids = [r["point"] for r in rows]
    assert ids == [p for p, k in zip(result.point_ids, ok, strict=True) if k]
    xyz = np.array([[float(r[c]) for c in "XYH"] for r in rows])
    np.testing.assert_allclose(xyz, result.points[ok], atol=5e-5)  # 4 decimals
    # near the simulated truth: largest errors measured 0.19, 0.21, 0.34 m (E, N, H)
    truth = sim.truth.points_crs[ok]
    assert np.all(np.max(np.abs(xyz - truth), axis=0) < [0.3, 0.3, 0.5])
    n_models = np.array([int(r["n_models"]) for r in rows])
    np.testing.assert_array_equal(n_models, result.strip.n_determinations[ok])
    n_images = np.array([int(r["n_images"]) for r in rows])
    assert n_images.min() >= 2
    assert np.all(n_images >= n_models)


def test_points_csv_roles_and_residuals(utm):
    sim, result, files = utm
    rows = {r["point"]: r for r in _rows(files["points.csv"])}
    kinds = dict(zip(result.control.point_ids, result.control.kind, strict=True))
    lines = {p for ids, _ in sim.lines for p in ids}
    assert lines, "the corridor preset simulates a road"
    for pid, row in rows.items():
        if pid in kinds:
            expected = {"full": "control-full", "check": "check"}.get(
                kinds[pid].value, f"control-{kinds[pid].value}"
            )
            assert row["role"] == expected
        elif pid in lines:
            assert row["role"] == "line"
        else:
            assert row["role"] == ("tie" if int(row["n_models"]) >= 2 else "model")
        has_resid = row["dE"] != "" or row["dH"] != ""
        assert has_resid == (pid in kinds)
    # residual columns are the ground stage's given - adjusted
    ground = result.ground
    for k, r in enumerate(ground.control_index):
        pid = result.control.point_ids[r]
        for j, col in enumerate(("dE", "dN", "dH")):
            value = ground.control_residuals[k, j]
            if np.isfinite(value):
                assert float(rows[pid][col]) == pytest.approx(value, abs=5e-5)
            else:
                assert rows[pid][col] == ""


def test_photos_csv_contract_and_angle_convention(utm):
    sim, result, files = utm
    text = files["photos.csv"].decode("utf-8")
    header = text.splitlines()[0].split(",")
    assert header[:7] == ["photo", "X", "Y", "Z", "omega", "phi", "kappa"]
    rows = _rows(files["photos.csv"])
    assert [r["photo"] for r in rows] == list(result.photo_ids)
    xyz = np.array([[float(r[c]) for c in "XYZ"] for r in rows])
    # largest errors of the projection centres measured 0.26, 0.34, 0.22 m (X, Y, Z)
    assert np.all(np.max(np.abs(xyz - sim.truth.photo_centres_crs), axis=0) < 0.5)
    opk = np.array([[float(r[c]) for c in ("omega", "phi", "kappa")] for r in rows])
    # R = Rx(omega) Ry(phi) Rz(kappa), image -> local east-north-up (docs/conventions.md);
    # scipy's intrinsic "XYZ" is that product (independent oracle).  The simulation's
    # truth is image -> ENU at the strip centre; the verticals differ by D/R < 0.05 deg.
    r_csv = Rotation.from_euler("XYZ", opk, degrees=True)
    r_true = Rotation.from_matrix(np.array(sim.truth.photo_rotations_local))
    angle = np.degrees((r_csv * r_true.inv()).magnitude())
    assert np.max(angle) < 0.2


def test_geographic_crs_writes_degrees_with_nine_decimals():
    sim = simulate_strip(4, preset="drone", crs="EPSG:4326", centre_lonlat=(21.0, 52.0), seed=2)
    result = _run(sim, polynomial=0)
    files = build_outputs(result, html=False)
    assert "report.html" not in files
    row = _rows(files["points.csv"])[0]
    assert len(row["X"].split(".")[1]) == 9
    assert len(row["H"].split(".")[1]) == 4
    assert abs(float(row["X"]) - 21.0) < 0.1
    photo = _rows(files["photos.csv"])[0]
    assert len(photo["Y"].split(".")[1]) == 9


# ----------------------------------------------------------------- report.json


def test_report_json_plain_and_complete(utm):
    sim, result, files = utm
    report = json.loads(files["report.json"], parse_constant=_no_nan)
    for key in (
        "format",
        "format_version",
        "software",
        "project",
        "inputs",
        "options",
        "relative_orientation",
        "pairs",
        "models",
        "ground",
        "similarity",
        "polynomial",
        "straight_lines",
        "control",
        "check",
        "tolerances",
        "warnings",
        "timings_s",
        "outputs",
    ):
        assert key in report, key
    assert report["format"] == "stripaero-report"
    assert report["inputs"]["n_photos"] == 7
    assert len(report["pairs"]) == 6
    assert len(report["models"]) == 6
    pair = report["pairs"][2]
    assert set(pair["elements"]) == {"b_y", "b_z", "a", "b", "c"}
    assert pair["sigma0_um"] == pytest.approx(result.strip.relative.sigma0_um[2])
    assert pair["max_parallax_um"] == pytest.approx(result.strip.relative.max_parallax_um[2])
    # tie RMS in metres = strip units x the similarity scale
    scale = result.ground.similarity.transform.scale
    for m in report["models"][1:]:
        np.testing.assert_allclose(
            m["tie_rms_m"], np.array(m["tie_rms_strip"]) * scale, rtol=1e-12
        )
    assert report["models"][0]["tie_rms_m"] == [None, None, None]
    st = report["check"]["statistics"]
    cs = result.check_statistics
    assert st["rmse_plan_m"] == pytest.approx(cs.rmse_plan)
    assert st["mean_plan_m"] == pytest.approx(cs.mean_plan)
    np.testing.assert_allclose([st["rmse_e_m"], st["rmse_n_m"], st["rmse_h_m"]], cs.rmse)
    assert len(report["check"]["points"]) == int(result.ground.is_check.sum())
    assert report["similarity"]["scale"] == pytest.approx(scale)
    assert len(report["similarity"]["rotation_opk_deg"]) == 3
    poly = report["polynomial"]
    assert poly["requested"] == "auto"
    assert poly["kind"] == result.ground.polynomial_kind
    assert [row["kind"] for row in poly["auto"]["table"]] == [0, 1, 2, 3]
    line = report["straight_lines"][0]
    assert line["n_points"] == len(line["residuals"]) == len(sim.lines[0][0])


def test_report_tolerances_follow_map_scale(utm):
    _, result, files = utm
    tol = json.loads(files["report.json"])["tolerances"]
    assert tol["map_scale"] == 2000
    names = [c["name"] for c in tol["criteria"]]
    assert names[0] == "check_mean_plan"
    assert "y_parallax_limit_share" in names
    plan = tol["criteria"][0]
    assert plan["limit"] == pytest.approx(0.6)  # 0.3 mm at 1:2000
    assert plan["value"] == pytest.approx(result.check_statistics.mean_plan)
    assert plan["passed"] is (result.check_statistics.mean_plan <= 0.6)
    # a map scale so large that 0.3 mm is less than the discrepancies: fails
    tight = build_report(result, map_scale=10.0)["tolerances"]
    assert tight["criteria"][0]["passed"] is False
    assert tight["passed"] is False
    no_scale = build_report(result)["tolerances"]
    assert no_scale["map_scale"] is None
    assert no_scale["criteria"][0]["passed"] is None


def test_report_from_project_file(tmp_path):
    sim = simulate_strip(5, preset="film", crs="EPSG:32634", seed=4, n_check=3)
    path = sim.write_project(tmp_path, polynomial=1, name="Test strip")
    text = path.read_text(encoding="utf-8") + "\n[report]\nmap_scale = 5000\n"
    path.write_text(text, encoding="utf-8")
    project = load_project(path)
    result = run_project(project)
    report = build_report(result, project=project)
    assert report["project"]["name"] == "Test strip"
    assert report["project"]["file"].endswith("strip.toml")
    assert report["options"]["polynomial"] == 1
    assert report["tolerances"]["map_scale"] == 5000
    assert report["tolerances"]["criteria"][0]["limit"] == pytest.approx(1.5)
    # the explicit map scale overrides the project's
    assert build_report(result, project=project, map_scale=1000)["tolerances"]["map_scale"] == 1000
    json.dumps(report, allow_nan=False)


# ----------------------------------------------------------------- GeoJSON


def test_geojson_structure_and_coordinates(utm):
    sim, result, files = utm
    gj = json.loads(files["points.geojson"], parse_constant=_no_nan)
    assert gj["type"] == "FeatureCollection"
    ok = np.isfinite(result.points).all(axis=1)
    assert len(gj["features"]) == int(ok.sum())
    roles = dict(zip(result.point_ids, point_roles(result), strict=True))
    lonlat = []
    for f in gj["features"]:
        assert f["type"] == "Feature"
        assert f["geometry"]["type"] == "Point"
        assert len(f["geometry"]["coordinates"]) == 2
        assert set(f["properties"]) >= {"id", "role", "H"}
        assert f["properties"]["role"] == roles[f["properties"]["id"]]
        lonlat.append(f["geometry"]["coordinates"])
    lonlat = np.array(lonlat)
    # independent conversion of the simulated truth with pyproj (UTM 34N -> WGS 84)
    to_wgs = Transformer.from_crs("EPSG:32634", "EPSG:4326", always_xy=True)
    truth = sim.truth.points_crs[ok]
    lon, lat = to_wgs.transform(truth[:, 0], truth[:, 1])
    d_east = (lonlat[:, 0] - lon) * np.cos(np.radians(lat)) * 111_320.0
    d_north = (lonlat[:, 1] - lat) * 110_570.0
    assert np.max(np.hypot(d_east, d_north)) < 1.0  # metres: the adjustment's accuracy
    h = np.array([f["properties"]["H"] for f in gj["features"]])
    np.testing.assert_allclose(h, result.points[ok, 2], atol=5e-5)


def test_geojson_none_for_local(local):
    assert points_geojson(local[1]) is None


# ----------------------------------------------------------------- HTML


def test_html_self_contained_with_figures(utm):
    _, result, files = utm
    page = files["report.html"].decode("utf-8")
    assert page.startswith("<!DOCTYPE html>")
    images = re.findall(r"<img [^>]*src='data:image/png;base64,([A-Za-z0-9+/=]+)'", page)
    assert page.count("<img") == 4
    assert len(images) == 4
    for b64 in images:
        assert base64.b64decode(b64)[:8] == b"\x89PNG\r\n\x1a\n"
    assert not re.search(r"(?:src|href)\s*=\s*['\"]?(?:https?:)?//", page)
    assert "http://" not in page and "https://" not in page
    assert "<script" not in page.lower()
    assert "Tolerance verdicts" in page
    assert "mean plan error at the check points within 0.3 mm at the map scale" in page
    for photo in result.photo_ids:
        assert f"<td class='l'>{photo}</td>" in page or f"<td>{photo}</td>" in page


def test_html_escapes_project_text(monkeypatch, utm):
    import strip_aerotri.report.html as rep

    _, result, _ = utm
    for name in ("figure_layout", "figure_residuals", "figure_parallax", "figure_ties"):
        monkeypatch.setattr(rep, name, lambda *args: None)
    report = build_report(result)
    report["project"]["name"] = "<b>Strip & co</b>"
    report["warnings"] = ["point '<x>' left out"]
    page = build_html(result, report)
    assert "&lt;b&gt;Strip &amp; co&lt;/b&gt;" in page
    assert "<b>Strip" not in page
    assert "&lt;x&gt;" in page


def test_html_local_crs(local):
    page = local[2]["report.html"].decode("utf-8")
    assert page.count("<img") == 4
    assert "points.geojson not written" in page


def test_report_enums_are_plain_strings(utm):
    _, _, files = utm
    report = json.loads(files["report.json"])
    assert report["ground"]["route"] == "geocentric"
    assert report["options"]["intersection"] in ("midpoint", "normal")
    page = files["report.html"].decode("utf-8")
    assert "Route." not in page and "geocentric" in page


def test_long_strip_drawn_along_its_axis(monkeypatch, utm):
    import strip_aerotri.report.figures as rep

    _, result, _ = utm
    calls = []
    original = rep._figure_residuals_along

    def spy(*args):
        calls.append(args)
        return original(*args)

    monkeypatch.setattr(rep, "_figure_residuals_along", spy)
    plan = rep.Plan(result)
    ok = np.isfinite(result.points).all(axis=1)
    plan.decide_long(np.vstack([plan.xy(plan.centres), plan.xy(result.points[ok])]))
    assert plan.long is False  # 7 photos of a corridor: drawn to scale
    monkeypatch.setattr(rep, "LONG_STRIP_RATIO", 0.1)
    page = build_html(result, build_report(result))
    assert len(calls) == 1
    assert page.count("<img") == 4


def test_report_of_the_models_construction_and_control_detectability():
    """block = "models": the model adjustment's section, the construction in
    the options, and per control component its redundancy number and
    minimal detectable error."""
    sim = simulate_strip(8, preset="corridor", crs="EPSG:32634", seed=5, n_check=6)
    lines = [LineSpec(point_ids=tuple(ids), weight=w) for ids, w in sim.lines]
    result = triangulate(sim.observations, sim.control, sim.crs, lines=lines)
    report = json.loads(json.dumps(build_report(result)))
    assert report["options"]["block"] == "models" and report["options"]["polynomial"] is None
    assert report["ground"]["construction"] == "models"
    adj = report["model_adjustment"]
    assert len(adj["models"]) == 7 and adj["converged"]
    assert 0.5 < adj["sigma0"] < 1.5  # the ray-derived weights fit the noise
    assert all(len(m["discrepancy_rms_m"]) == 3 for m in adj["models"])
    points = report["control"]["points"]
    assert all({"redundancy", "mde_m", "detectable"} <= p.keys() for p in points)
    full = [p for p in points if p["type"] == "full"]
    for p in full:
        assert all(0.0 <= r <= 1.0 for r in p["redundancy"])
        # MDE = sigma delta0 / sqrt(r) with sigma 2 cm: at least sigma * delta0
        assert all(m is None or m > 0.02 * 4.0 for m in p["mde_m"])
    html = build_html(result, report)
    assert "Every model at once" in html and "MDE" in html
    # J's construction reports no model adjustment
    j = triangulate(
        sim.observations,
        sim.control,
        sim.crs,
        lines=lines,
        ground_options=GroundOptions(polynomial=3),
    )
    assert build_report(j)["model_adjustment"] is None


def test_pairs_and_models_named_by_their_photos_with_a_photo_step():
    """With photo_step = 2 the models are formed by every second photo; the
    report names each pair by its two photos and states the step."""
    sim = simulate_strip(13, seed=3, preset="drone")
    result = triangulate(sim.observations, sim.control, sim.crs, photo_step=2)
    report = build_report(result)
    labels = result.strip.model_labels
    assert len(labels) == 6
    for entry in (*report["pairs"], *report["models"]):
        assert labels[entry["index"]] == f"pair {entry['left']}-{entry['right']}"
    ids = sim.observations.photo_ids
    assert (report["pairs"][1]["left"], report["pairs"][1]["right"]) == (ids[2], ids[4])
    assert report["options"]["photo_step"] == 2
    assert (
        build_report(triangulate(sim.observations, sim.control, sim.crs))["options"]["photo_step"]
        == 1
    )


def test_printed_tables_are_complete(utm):
    """On paper (or PDF) a scrolled table would show its first screenful only:
    the print style lifts the scroll box, keeps header rows and figures whole."""
    page = utm[2]["report.html"].decode("utf-8")
    css = page[page.index("<style>") : page.index("</style>")]
    printed = css[css.index("@media print") :]
    assert ".scroll{max-height:none;overflow:visible" in printed
    assert "break-inside:avoid" in printed


def test_the_page_opens_with_the_result_in_plain_words(utm):
    """The first paragraph says what a client needs: photos, points, control,
    the check points' RMSE in metres and the verdict, without jargon."""
    _, result, files = utm
    page = files["report.html"].decode("utf-8")
    plain = page[page.index("<p class='plain'>") :]
    plain = plain[: plain.index("</p>")]
    check = result.check_statistics
    assert f"{len(result.photo_ids)} photos were oriented" in plain
    assert f"{check.rmse_plan:.3f} m in plan" in plain
    assert f"{check.rmse[2]:.3f} m in height" in plain
    assert "y-parallax" not in plain and "σ0" not in plain
    assert page.index("class='plain'") < page.index("<h2>Summary</h2>")


def test_plain_summary_counts_the_check_points_compared(tmp_path):
    """A check point seen on one photo only is given but not compared: the
    page says "At n of the n + 1" instead of counting it."""
    import shutil
    import subprocess
    import sys

    src = Path(__file__).resolve().parents[1] / "examples" / "film-strip"
    project = tmp_path / "film"
    shutil.copytree(src, project, ignore=shutil.ignore_patterns("out"))
    control = project / "control.csv"
    header, first_row = (line.split(",") for line in control.read_text().splitlines()[:2])
    # within the strip (a point 4000 km away is refused as implausible)
    x, y = (float(first_row[header.index(c)]) + 50.0 for c in ("X", "Y"))
    row = {"point": "NOWHERE", "X": f"{x:.3f}", "Y": f"{y:.3f}", "H": "300", "type": "check"}
    control.write_text(
        control.read_text().rstrip("\n") + "\n" + ",".join(row.get(c, "") for c in header) + "\n"
    )
    images = project / "image_points.csv"  # seen on one photo only: not triangulated
    first = images.read_text().splitlines()[1].split(",")[0]
    images.write_text(images.read_text().rstrip("\n") + f"\n{first},NOWHERE,10.0,20.0,0.005\n")
    code = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"
    run = subprocess.run(
        [sys.executable, "-c", code, "run", str(project / "strip.toml")],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stderr
    report = json.loads((project / "out" / "report.json").read_text())
    given = report["inputs"]["control"]["check"]
    compared = report["check"]["statistics"]["n_plan"]
    assert compared == given - 1
    page = (project / "out" / "report.html").read_text()
    assert f"At {compared} of the {given} independent check points" in page
