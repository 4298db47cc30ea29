"""The typed summary of a run (report/summary.py): the same figures as the
result and report.json, computed in the library."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.geodesy import GroundCRS
from strip_aerotri.project import load_project, run_project
from strip_aerotri.report.outputs import GEOJSON_LOCAL_NOTE
from strip_aerotri.report.summary import build_run
from strip_aerotri.simulate import simulate_block, simulate_strip


def _project(tmp_path, sim, extra=""):
    sim.write_project(tmp_path)
    toml = tmp_path / "strip.toml"
    toml.write_text(toml.read_text(encoding="utf-8") + extra, encoding="utf-8")
    return load_project(toml)


def test_strip_summary_is_the_result_and_its_report(tmp_path):
    project = _project(tmp_path, simulate_strip(8, seed=4), "\n[report]\nmap_scale = 5000\n")
    result = run_project(project)
    outputs = build_run(result, project=project)
    summary, record = outputs.summary, json.loads(outputs.files["report.json"])
    assert summary.kind == "strip" and summary.name == project.name
    assert summary.n_points == int(result.strip.triangulated.sum())
    assert summary.check.rmse_plan == result.check_statistics.rmse_plan
    assert summary.check.n_height == result.check_statistics.n_height
    criteria = record["tolerances"]["criteria"]
    assert summary.tolerances is not None and summary.tolerances.map_scale == 5000
    assert summary.tolerances.failed == tuple(c["name"] for c in criteria if c["passed"] is False)
    assert summary.tolerances.n_judged == sum(c["passed"] is not None for c in criteria)
    assert summary.report_name == "report.html" and set(summary.files) == set(outputs.files)


def test_block_summary_judges_the_transfer_as_report_json(tmp_path):
    project = _project(tmp_path, simulate_block(3, 6, seed=2))
    result = run_project(project)
    outputs = build_run(result, project=project)
    summary, record = outputs.summary, json.loads(outputs.files["report.json"])
    joins = record["block"]["joins"]
    assert summary.kind == "block" and summary.n_strips == 3
    assert summary.tolerances is None  # no map scale
    worst = max(joins, key=lambda j: j["mean_plan_m"])
    assert summary.join is not None and list(summary.join.strips) == worst["strips"]
    transfer = max(joins, key=lambda j: j["mean_transfer_um"])
    assert list(summary.join.transfer_strips) == transfer["strips"]
    assert summary.join.mean_transfer_um == pytest.approx(transfer["mean_transfer_um"])
    assert summary.join.transfer_passed is transfer["transfer_passed"]
    assert math.isfinite(summary.join.mean_transfer_um)
    assert summary.control.rmse_plan == result.control_statistics.rmse_plan
    assert np.isfinite(summary.control_fit.rmse_plan)
    # one count of the delivered points: the command line's, report.json's, points.csv's
    rows = outputs.files["points.csv"].decode().strip().splitlines()
    n_header = sum(1 for r in rows if not r[:1].isalnum() or r.startswith("point,"))
    assert summary.n_points == record["inputs"]["n_points_triangulated"] == len(rows) - n_header


@pytest.mark.parametrize("map_scale", [None, 5000.0])
def test_strip_verdict_and_warnings_are_report_json_s(tmp_path, map_scale):
    """The verdict sentence and the warnings, made from the result alone, are
    those report.json writes (the page's banner prints the same sentence)."""
    project = _project(tmp_path, simulate_strip(8, seed=4))
    result = run_project(project)
    outputs = build_run(result, project=project, map_scale=map_scale)
    summary, record = outputs.summary, json.loads(outputs.files["report.json"])
    assert summary.verdict.text == record["tolerances"]["verdict"]["text"]
    assert summary.verdict.status == record["tolerances"]["verdict"]["status"]
    assert (summary.tolerances is None) == (map_scale is None)
    assert [*summary.warnings, *summary.output_warnings] == record["warnings"]


def test_a_local_strip_says_its_geojson_is_not_written(tmp_path):
    """A strip in a local frame: the summary's output warnings carry the note
    report.json carries, and no points.geojson is among the files."""
    project = _project(tmp_path, simulate_strip(6, seed=3))
    result = run_project(project)
    local = dataclasses.replace(
        result, ground=dataclasses.replace(result.ground, crs=GroundCRS.from_user_input("local"))
    )
    outputs = build_run(local, project=project)
    record = json.loads(outputs.files["report.json"])
    assert "points.geojson" not in outputs.files
    assert outputs.summary.output_warnings == (GEOJSON_LOCAL_NOTE,)
    assert GEOJSON_LOCAL_NOTE in record["warnings"]


@pytest.mark.parametrize("map_scale", [None, 2000.0])
def test_block_verdict_is_report_json_s(tmp_path, map_scale):
    project = _project(tmp_path, simulate_block(3, 6, seed=2))
    result = run_project(project)
    outputs = build_run(result, project=project, map_scale=map_scale)
    summary, record = outputs.summary, json.loads(outputs.files["report.json"])
    assert summary.verdict.text == record["tolerances"]["verdict"]["text"]
    assert summary.verdict.status == record["tolerances"]["verdict"]["status"]
    assert list(summary.warnings) == record["warnings"] and summary.output_warnings == ()
    formed = [r for strip in result.strips for r in strip.rejections]
    assert list(summary.rejections) == formed + list(result.rejections)
    assert [r.describe() for r in summary.rejections[len(formed) :]] == record["rejections"]


def test_build_run_writes_the_files_of_build_outputs(tmp_path):
    """build_run's files are build_outputs' byte for byte (report.json apart
    from its creation time)."""
    from strip_aerotri.report.outputs import build_outputs

    project = _project(tmp_path, simulate_strip(6, seed=5))
    result = run_project(project)
    ours = build_run(result, project=project, map_scale=5000).files
    theirs = build_outputs(result, project=project, map_scale=5000)
    assert set(ours) == set(theirs)
    for name in ours:
        if name == "report.json":
            a, b = json.loads(ours[name]), json.loads(theirs[name])
            a.pop("created_utc"), b.pop("created_utc")
            assert a == b
        elif name != "report.html":  # the page shows the creation time
            assert ours[name] == theirs[name], name


def _reads_report_json(source: str) -> list[str]:
    """Where a module's source reads a result's report.json back: an import
    of json, or a lookup of the key "report.json" (``files["report.json"]``,
    ``files.get("report.json")``, ``folder / "report.json"``)."""
    import ast

    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import | ast.ImportFrom):
            names = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
            if "json" in names:
                found.append(f"line {node.lineno}: imports json")
        key = None
        if isinstance(node, ast.Subscript):
            key = node.slice
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "get":
            key = node.args[0] if node.args else None
        elif isinstance(node, ast.BinOp) and isinstance(node.op, ast.Div):
            key = node.right
        if isinstance(key, ast.Constant) and key.value == "report.json":
            found.append(f"line {node.lineno}: looks up report.json")
    return found


def test_the_command_line_never_reads_report_json():
    """``stripaero run`` prints the library's summary: no module of cli/ reads
    report.json back (nor imports json to parse it)."""
    cli = Path(__file__).parents[1] / "src" / "strip_aerotri" / "cli"
    found = {
        path.name: hits
        for path in sorted(cli.glob("*.py"))
        if (hits := _reads_report_json(path.read_text(encoding="utf-8")))
    }
    assert found == {}


@pytest.mark.parametrize(
    "source",
    [
        "import json\n",
        "v = files.get('report.json')\n",
        "v = files['report.json']\n",
        "p = folder / 'report.json'\n",
    ],
)
def test_the_report_json_rule_can_fail(source):
    assert _reads_report_json(source) != []


def test_the_python_example_of_the_cli_page_runs(tmp_path, monkeypatch):
    """docs/cli.md's "Python instead of the command line" runs as written
    (from the repository root) and prints what ``stripaero run`` prints."""
    import re

    root = Path(__file__).parents[1]
    page = (root / "docs" / "cli.md").read_text(encoding="utf-8")
    section = page.split("## Python instead of the command line", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S)
    assert code is not None
    source = code.group(1).replace("examples/", f"{root.as_posix()}/examples/")
    source = source.replace('"my-out"', repr(str(tmp_path / "my-out")))
    printed: list[str] = []
    exec(compile(source, "docs/cli.md", "exec"), {"print": lambda *a: printed.append(a)})
    assert (tmp_path / "my-out" / "points.csv").is_file()
    assert len(printed) == 2 and all(math.isfinite(v) for v in printed[0])
    record = json.loads((tmp_path / "my-out" / "report.json").read_text(encoding="utf-8"))
    assert printed[1] == (record["tolerances"]["verdict"]["text"],)
    assert printed[0] == (
        record["check"]["statistics"]["rmse_plan_m"],
        record["check"]["statistics"]["rmse_h_m"],
    )


def test_warning_lines_sum_up_each_stage_s_rejections():
    """Two or more rejections of a stage are one line at the place of the
    first, naming the files that list them; one rejection stays as it is;
    with ``every`` (``-v``) every warning is printed, each once."""
    from strip_aerotri.report.summary import Accuracy, RunSummary
    from strip_aerotri.report.verdict import Verdict
    from strip_aerotri.results import Rejection

    def rejection(stage, point, applied=True, effect=""):
        return Rejection(
            stage, point, ("1", "2"), "y-parallax", 30.0, "µm", 9.0, 4.8, applied, effect
        )

    ro = [rejection("relative_orientation", p) for p in ("A", "B", "C")]
    kept = [rejection("control", p, applied=False, effect="kept: too few left") for p in "DE"]
    tie = rejection("tie_points", "F")
    none = Accuracy(0, 0, math.nan, math.nan)
    summary = RunSummary(
        "strip",
        "s",
        1,
        2,
        3,
        False,
        "models",
        none,
        none,
        Verdict("na", "nothing"),
        rejections=(*ro, *kept, tie),
        files=("report.json", "report.html", "points.csv"),
    )
    texts = ["first", ro[0].describe(), "second", ro[1].describe(), tie.describe()]
    texts += [kept[0].describe(), ro[2].describe(), kept[1].describe(), "first"]
    assert summary.warning_lines(texts) == [
        "first",
        "relative_orientation: 3 y-parallaxes rejected as blunders (listed in report.json / "
        "report.html; -v lists them here)",
        "second",
        tie.describe(),
        "control: 2 control coordinates fail the blunder test, kept (too few left) (listed in "
        "report.json / report.html; -v lists them here)",
    ]
    assert summary.warning_lines(texts, every=True) == list(dict.fromkeys(texts))



def test_warning_lines_count_restored_points_as_restored():
    """The points the refinement restored are left out of the strip method's
    warnings of points left out (their own, and the count of the points
    not triangulated, made again without them); every other warning, and
    ``every`` (``-v``, as report.json), stay as they are."""
    import pickle

    from strip_aerotri.report.summary import Accuracy, RunSummary
    from strip_aerotri.report.verdict import Verdict
    from strip_aerotri.results import PointWarning

    none = Accuracy(0, 0, math.nan, math.nan)
    restored = ("A", "C", "Q,'x")
    summary = RunSummary(
        "strip", "s", 1, 2, 3, True, "models", none, none, Verdict("na", "nothing"),
        restored=restored, files=("report.json",),
    )  # fmt: skip
    cause = "their observations failed the blunder tests"
    own = [PointWarning.not_triangulated(p, "a cause") for p in ("A", "B")]
    own.append(PointWarning.not_triangulated("Q,'x", "a cause", check=True))
    lost = PointWarning.points_not_triangulated(["A", "B", "C", "D", "E", "F", "G", "Q,'x"], cause)
    only_restored = PointWarning.points_not_triangulated(["C"], "seen on fewer than two photos")
    weak = PointWarning.weak_check("Q,'x", "check point 'Q,\'x' is weak")
    assert str(lost) == (
        f"8 point(s) not triangulated ({cause}): 'A', 'B', 'C', 'D', 'E' and 3 more"
    )  # the text the strip's run has always written
    assert pickle.loads(pickle.dumps(lost)).points == lost.points
    texts = ["first", *own, lost, only_restored, weak]
    assert summary.warning_lines(texts) == [
        "first",
        own[1],
        f"5 point(s) not triangulated ({cause}): 'B', 'D', 'E', 'F', 'G'",
        weak,
    ]
    assert summary.warning_lines(texts, every=True) == texts
    lines = dataclasses.replace(summary, restored=()).warning_lines(texts)
    assert lines[1].startswith("2 control points are not triangulated ('A', 'B')")
    assert str(lost) in lines and str(only_restored) in lines

# the ground stage before the bundle sees the camera error in the control
@pytest.mark.filterwarnings("ignore:control.*fail the blunder test alike")
def test_a_refined_strip_s_summary_is_the_bundle_s(tmp_path):
    """After a bundle refinement with self-calibration the summary's accuracy
    is the refinement's (the delivered points; report.json's "bundle"); the
    calibration names what was kept and camera.toml among the files."""
    sim = simulate_strip(12, preset="drone", seed=2, camera_errors={"k1": -3e-4})
    project = _project(tmp_path, sim)
    text = project.path.read_text(encoding="utf-8")
    project.path.write_text(
        text.replace(
            "[adjustment]\n", '[adjustment]\nrefine = "bundle"\nself_calibration = "auto"\n'
        ),
        encoding="utf-8",
    )
    project = load_project(project.path)
    result = run_project(project)
    outputs = build_run(result, project=project)
    summary, record = outputs.summary, json.loads(outputs.files["report.json"])
    assert summary.refined and result.refined is not None
    # report.json keeps the refinement's figures under "bundle"
    assert summary.check.rmse_plan == record["bundle"]["check"]["rmse_plan_m"]
    assert summary.control.rmse_height == record["bundle"]["control"]["rmse_h_m"]
    assert summary.check.rmse_plan == result.refined.check_statistics.rmse_plan
    assert summary.check.rmse_plan != result.check_statistics.rmse_plan  # not the strip's
    outcome = result.refined.self_calibration
    assert summary.calibration is not None and summary.calibration.kept == outcome.kept
    assert "k1" in summary.calibration.kept
    assert summary.calibration.camera_written == ("camera.toml" in outputs.files) is True


def _with_weights(project, weights=True):
    """``project`` again with ``refine = "bundle"`` (and ``weights =
    "estimated"``)."""
    extra = 'refine = "bundle"\n' + ('weights = "estimated"\n' if weights else "")
    text = project.path.read_text(encoding="utf-8")
    project.path.write_text(text.replace("[adjustment]\n", f"[adjustment]\n{extra}"), "utf-8")
    return load_project(project.path)


def test_the_run_prints_the_estimated_weights_as_report_json(tmp_path):
    """``weights = "estimated"``: the summary carries each group's given and
    estimated sigma as report.json's ``bundle.variance_components``, and
    ``stripaero run`` prints them on one line with their units; without the
    key there is neither."""
    from click.testing import CliRunner

    from strip_aerotri.cli.main import cli

    project = _with_weights(_project(tmp_path, simulate_strip(10, seed=2, crs="local")))
    result = run_project(project)
    outputs = build_run(result, project=project)
    record = json.loads(outputs.files["report.json"])["bundle"]["variance_components"]
    weights = outputs.summary.weights
    assert weights is not None and weights.applied == record["applied"]
    assert [g[0] for g in weights.groups] == [g["group"] for g in record["groups"]]
    for (_, unit, given, sigma, estimated), g in zip(
        weights.groups, record["groups"], strict=True
    ):
        assert (unit, estimated) == (g["unit"], g["estimated"])
        assert (given, sigma) == pytest.approx((g["sigma_apriori"], g["sigma"]), rel=1e-9)
    ran = CliRunner().invoke(cli, ["run", str(project.path)])
    assert ran.exit_code == 0, ran.output
    lines = [x for x in ran.output.splitlines() if "observation weights estimated" in x]
    assert len(lines) == 1, ran.output
    ties = record["groups"][0]
    assert ties["estimated"] and ties["unit"] == "µm"
    tie_text = f"{ties['group']} {ties['sigma']:.3g} µm (given {ties['sigma_apriori']:.3g})"
    assert tie_text in lines[0]
    held = [g for g in record["groups"] if not g["estimated"]]
    assert held and all(
        f"{g['group']} {g['sigma_apriori']:.3g} {g['unit']} as given" in lines[0] for g in held
    )
    plain = _with_weights(
        _project(tmp_path / "plain", simulate_strip(10, seed=2, crs="local")), False
    )
    assert build_run(run_project(plain), project=plain).summary.weights is None
    ran = CliRunner().invoke(cli, ["run", str(plain.path)])
    assert ran.exit_code == 0 and "observation weights" not in ran.output


def test_a_block_s_summary_carries_its_estimated_weights(tmp_path):
    project = _with_weights(_project(tmp_path, simulate_block(2, 6, seed=2)))
    result = run_project(project)
    weights = build_run(result, project=project).summary.weights
    vc = result.variance_components
    assert vc is not None and weights is not None
    assert [(g[0], g[3]) for g in weights.groups] == [(g.name, g.sigma) for g in vc.groups]


def test_a_refined_strip_counts_the_delivered_points(tmp_path):
    """After a refinement the summary's points are those of points.csv, the
    refinement's: a point it no longer determines is not counted."""
    project = _with_weights(_project(tmp_path, simulate_strip(8, seed=4)), False)
    result = run_project(project)
    refined = result.refined
    assert refined is not None
    tie = ~np.isin(np.array(result.point_ids), np.array(result.control.point_ids))
    lost = int(np.flatnonzero(np.isfinite(refined.points).all(axis=1) & tie)[0])
    points = np.array(refined.points)
    points[lost] = np.nan
    result = dataclasses.replace(result, refined=dataclasses.replace(refined, points=points))
    outputs = build_run(result, project=project)
    rows = outputs.files["points.csv"].decode().strip().splitlines()
    n_header = sum(1 for r in rows if not r[:1].isalnum() or r.startswith("point,"))
    assert outputs.summary.n_points == len(rows) - n_header
    assert outputs.summary.n_points == int(result.strip.triangulated.sum()) - 1
    # report.json and the page say the same count as the command line
    record = json.loads(outputs.files["report.json"])
    assert record["inputs"]["n_points_triangulated"] == outputs.summary.n_points
