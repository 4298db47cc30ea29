"""What a user reads after a run: the lines and sentences that must say what
the figures are (a refined block's accuracy is the refinement's; the
correlations listed are those between the kept parameters)."""

from __future__ import annotations

from click.testing import CliRunner

from strip_aerotri.cli.main import cli
from strip_aerotri.report.calibration import calibration_html
from strip_aerotri.simulate import simulate_block

REFINED = "bundle refinement: accuracy below is the refined solution's"


def test_a_refined_block_says_its_accuracy_is_the_refinement_s(tmp_path):
    """As a refined strip does, a refined block says that the accuracy
    printed is the bundle's; an unrefined block does not."""
    simulate_block(2, 6, seed=2).write_project(tmp_path)
    toml = tmp_path / "strip.toml"
    plain = toml.read_text(encoding="utf-8")
    ran = CliRunner().invoke(cli, ["run", str(toml)])
    assert ran.exit_code == 0, ran.output
    assert REFINED not in ran.output
    assert "in the block's transformation" not in ran.output
    toml.write_text(plain.replace("[adjustment]\n", '[adjustment]\nrefine = "bundle"\n'), "utf-8")
    ran = CliRunner().invoke(cli, ["run", str(toml)])
    assert ran.exit_code == 0, ran.output
    lines = ran.output.splitlines()
    block = next(i for i, x in enumerate(lines) if x.startswith("block "))
    assert lines[block + 1] == REFINED
    assert lines[block + 2].startswith("control: ")
    # the joins are the block transformation's, not the refinement's: said
    (join,) = [x for x in lines if x.startswith("common points of the strips")]
    assert join.endswith("), in the block's transformation")


def _parameter(name: str, kept: bool, why_not: str | None = None) -> dict[str, object]:
    return {
        "name": name,
        "unit": "mm^-2",
        "estimate": 1e-4,
        "sd": 1e-5,
        "t": 10.0,
        "orientation_correlation": 0.5,
        "kept": kept,
        "why_not": why_not,
    }


def test_the_page_s_correlations_are_between_the_kept_parameters():
    """A parameter held for its correlation 0.981 with a kept one is named in
    the table; the line below lists the kept parameters' correlations
    (report.json's ``correlations_above_0_9``: none here) and says so,
    rather than "Correlations above 0.9: none" beside that 0.981."""
    record = {
        "choice": "auto",
        "kept": ["k1"],
        "sigma0": 0.38,
        "sigma0_without": 0.40,
        "parameters": [
            _parameter("k1", True),
            _parameter("k2", False, "correlation 0.981 with k1"),
        ],
        "correlations_above_0_9": [],
    }
    page = calibration_html(record, (None, None))
    assert "correlation 0.981 with k1" in page
    assert "<p>Correlations above 0.9 between the kept parameters: none</p>" in page


def test_the_page_says_when_the_camera_is_left_as_given() -> None:
    """The page's self-calibration paragraph speaks as the command line does:
    with a kept set, sigma0 with the camera as given beside it; with none,
    that the camera was left as given (it read "kept: none ... (without: X)")."""
    base = {
        "choice": "auto",
        "sigma0": 0.38,
        "sigma0_without": 0.40,
        "parameters": [_parameter("k1", True)],
        "correlations_above_0_9": [],
    }
    kept = calibration_html({**base, "kept": ["k1"]}, (None, None))
    assert "kept: k1. sigma0 0.380 (with the camera as given: 0.400)." in kept
    none = calibration_html(
        {**base, "kept": [], "sigma0": None, "parameters": [_parameter("k1", False, "t 1.2")]},
        (None, None),
    )
    # with nothing kept there is no adjusted sigma0: the given camera's is shown
    assert "no parameter kept: the camera is left as given (camera.toml holds it)." in none
    assert "sigma0 0.400." in none
    assert "without" not in none and "kept: none" not in none


def test_a_refined_strip_s_summary_table_gives_the_delivered_check(tmp_path):
    """The page's summary table gives the check RMSE of the delivered
    solution, the bundle refinement's, and says so; without a refinement
    the strip method's, unlabelled."""
    import json
    import re
    import warnings

    from strip_aerotri.errors import StripAerotriWarning
    from strip_aerotri.project import load_project, run_project
    from strip_aerotri.report.outputs import build_outputs
    from strip_aerotri.simulate import simulate_strip

    simulate_strip(8, seed=4).write_project(tmp_path)
    toml = tmp_path / "strip.toml"
    plain = toml.read_text(encoding="utf-8")
    rows = {}
    for label, extra in (("plain", ""), ("bundle", 'refine = "bundle"\n')):
        toml.write_text(plain.replace("[adjustment]\n", f"[adjustment]\n{extra}"), "utf-8")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StripAerotriWarning)
            project = load_project(toml)
            files = build_outputs(run_project(project), project=project, html=True)
        page, record = files["report.html"].decode(), json.loads(files["report.json"])
        found = re.search(r"check RMSE plan / mean plan \[m\]([^<]*)</td><td[^>]*>([^<]*)<", page)
        assert found is not None
        rows[label] = (found.group(1), found.group(2), record)
    suffix, value, record = rows["bundle"]
    chk = record["bundle"]["check"]
    assert suffix == " (bundle refinement)"
    assert value == f"{chk['rmse_plan_m']:.3f} / {chk['mean_plan_m']:.3f}"
    assert chk["rmse_plan_m"] != record["check"]["statistics"]["rmse_plan_m"]
    suffix, value, record = rows["plain"]
    chk = record["check"]["statistics"]
    assert suffix == "" and value == f"{chk['rmse_plan_m']:.3f} / {chk['mean_plan_m']:.3f}"


def test_the_points_a_refinement_loses_are_named():
    """A point whose rays the refinement rejects down to one is no longer
    determined: the warning counts and names such points (the first five),
    and only those the start had."""
    import numpy as np

    from strip_aerotri.bundle.refine import lost_points_note

    ids = [f"p{i}" for i in range(9)]
    start = np.zeros((9, 3))
    start[8] = np.nan  # never determined: not lost
    used = np.ones(9, dtype=bool)
    assert lost_points_note(ids, start, used) == []
    used[[1, 2, 3, 4, 5, 6, 8]] = False
    (note,) = lost_points_note(ids, start, used)
    assert note.startswith("bundle: 6 point(s) ")
    assert note.endswith(": 'p1', 'p2', 'p3', 'p4', 'p5' and 1 more")


def test_a_block_s_refinement_names_the_points_it_loses(tmp_path):
    """The FC300X block with estimated weights: the refinement's rejections
    leave some points with one ray; the warning's count is the difference
    between the points of the block's transformation and the refinement's,
    and each named point is missing from the refinement."""
    import re
    import warnings
    from pathlib import Path

    import numpy as np
    import pytest

    from strip_aerotri.errors import StripAerotriWarning
    from strip_aerotri.importers.uav_fc300x import import_uav_fc300x
    from strip_aerotri.importers.writer import write_project
    from strip_aerotri.project import load_project, run_project

    data = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "uav-block-fc300x"
    if not data.is_dir():
        pytest.skip("needs ../shared/data/uav-block-fc300x")
    write_project(import_uav_fc300x(data), tmp_path, force=True)
    toml = tmp_path / "strip.toml"
    plain = toml.read_text()
    counts, results = [], []
    for extra in ("", 'refine = "bundle"\nweights = "estimated"\n'):
        toml.write_text(plain + f"\n[adjustment]\n{extra}")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", StripAerotriWarning)
            result = run_project(load_project(toml))
        counts.append(int(np.isfinite(result.points).all(axis=1).sum()))
        results.append(result)
    notes = [w for w in results[1].warnings if "no longer determined" in w]
    # points the block left out and the refinement restored (bundle/start_points.py)
    back = [w for w in results[1].warnings if "left out before the refinement" in w]
    restored = int(re.search(r"bundle: (\d+) point", back[0]).group(1)) if back else 0
    assert counts[0] + restored > counts[1] and len(notes) == 1, (counts, notes)
    assert notes[0].startswith(f"bundle: {counts[0] + restored - counts[1]} point(s) ")
    named = re.findall(r"'([^']+)'", notes[0])
    index = [results[1].observations.point_ids.index(n) for n in named]
    assert len(named) == 5 and not np.isfinite(results[1].points[index]).all(axis=1).any()
    assert np.isfinite(results[0].points[index]).all()


def test_the_page_leaves_the_unit_of_dimensionless_parameters_out() -> None:
    """b1, b2 (and Ebner's e1, e2) are dimensionless: their unit cell shows
    "–", not "1" (read as a number beside the estimate); k1 keeps mm^-2."""
    import re

    record = {
        "choice": "auto",
        "kept": ["k1", "b1"],
        "sigma0": 0.38,
        "sigma0_without": 0.40,
        "parameters": [
            _parameter("k1", True),
            {**_parameter("b1", True), "unit": "1"},
            {**_parameter("e2", False, "t 0.4"), "unit": "1"},
        ],
        "correlations_above_0_9": [],
    }
    page = calibration_html(record, (None, None))
    cells = {
        m[1]: m[2]
        for m in re.finditer(r"<tr><td[^>]*>(k1|b1|e2)</td><td[^>]*>([^<]*)</td>", page)
    }
    assert cells == {"k1": "mm^-2", "b1": "–", "e2": "–"}, cells


def test_the_page_names_camera_toml_when_it_holds_the_start_camera() -> None:
    """Without an adjusted [distortion] (Ebner's family, or nothing kept) the
    section still names camera.toml and says what it holds."""
    base = {
        "choice": "ebner12",
        "family": "ebner",
        "sigma0": 0.38,
        "sigma0_without": 0.40,
        "parameters": [{**_parameter("e1", True), "unit": "1"}],
        "correlations_above_0_9": [],
        "camera": None,
    }
    ebner = calibration_html({**base, "kept": ["e1"]}, (None, None))
    assert (
        "<code>camera.toml</code>, written beside this page, holds the start camera, "
        "Ebner's estimates as comments: paste its [camera] and [distortion] tables" in ebner
    )
    none = calibration_html({**base, "kept": [], "sigma0": None}, (None, None))
    assert "<code>camera.toml</code>, written beside this page, holds the start camera:" in none
    assert "The adjusted camera" not in ebner + none
