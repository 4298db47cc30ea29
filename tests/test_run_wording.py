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
