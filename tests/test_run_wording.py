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
    toml.write_text(plain.replace("[adjustment]\n", '[adjustment]\nrefine = "bundle"\n'), "utf-8")
    ran = CliRunner().invoke(cli, ["run", str(toml)])
    assert ran.exit_code == 0, ran.output
    lines = ran.output.splitlines()
    block = next(i for i, x in enumerate(lines) if x.startswith("block "))
    assert lines[block + 1] == REFINED
    assert lines[block + 2].startswith("control: ")


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
        "parameters": [_parameter("k1", True), _parameter("k2", False, "correlation 0.981 with k1")],
        "correlations_above_0_9": [],
    }
    page = calibration_html(record, (None, None))
    assert "correlation 0.981 with k1" in page
    assert "<p>Correlations above 0.9 between the kept parameters: none</p>" in page


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
