"""What ``stripaero run`` and ``check`` print about a self-calibration, in
what order, and how a long warning is cut (cli/run.py, cli/options.py,
project/check.py, _text.py)."""

from __future__ import annotations

import json
import re
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner

from _shuffled import shuffled_block
from strip_aerotri._text import MAX_LINE, cut_at_items, shorten
from strip_aerotri.cli.main import cli
from strip_aerotri.simulate import simulate_block, simulate_strip

_AUTO = '[adjustment]\nrefine = "bundle"\nself_calibration = "auto"\n'


def _auto(folder: Path, sim) -> Path:
    """``sim``'s project in ``folder`` with a bundle refinement and ``"auto"``."""
    sim.write_project(folder)
    toml = folder / "strip.toml"
    toml.write_text(toml.read_text("utf-8").replace("[adjustment]\n", _AUTO), "utf-8")
    return toml


def _run(toml: Path):
    result = CliRunner().invoke(cli, ["run", str(toml)])
    assert result.exit_code == 0, result.output
    return result


def _line(stdout: str, start: str) -> tuple[int, str]:
    (found,) = [(i, ln) for i, ln in enumerate(stdout.splitlines()) if ln.startswith(start)]
    return found


# The camera without error: "auto" keeps nothing.
@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_self_calibration_keeping_nothing_says_the_camera_is_left_as_given(tmp_path):
    toml = _auto(tmp_path, simulate_strip(12, preset="drone", seed=2))
    result = _run(toml)
    _, line = _line(result.stdout, "self-calibration:")
    assert "kept none" not in line and "without" not in line, line
    assert line.startswith("self-calibration: no parameter kept, the camera is left as given")
    record = (tmp_path / "out" / "report.json").read_text("utf-8")
    assert re.search(r'"kept": \[\]', record)
    # formats.md promises camera.toml after a self-calibration: it is the given camera
    assert line.endswith(f"camera: {tmp_path / 'out' / 'camera.toml'} (the given camera)"), line
    given = tomllib.loads(toml.read_text("utf-8"))["camera"]
    written = tomllib.loads((tmp_path / "out" / "camera.toml").read_text("utf-8"))
    assert written["camera"]["principal_distance_mm"] == given["principal_distance_mm"]
    assert written["camera"]["principal_point_mm"] == given.get("principal_point_mm", [0.0, 0.0])
    terms = {k: v for k, v in written["distortion"].items() if k not in ("units", "model")}
    assert terms and set(terms.values()) == {0.0}  # the project gives no distortion


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_kept_calibration_says_what_the_other_sigma0_is(tmp_path):
    toml = _auto(tmp_path, simulate_strip(12, preset="drone", seed=2, camera_errors={"k1": -3e-4}))
    _, line = _line(_run(toml).stdout, "self-calibration:")
    match = re.fullmatch(
        r"self-calibration: kept (.+), sigma0 ([\d.]+) \(with the camera as given: ([\d.]+)\); "
        r"camera: (.+)",
        line,
    )
    assert match is not None, line
    assert "k1" in match[1].split(", ")
    # the camera error is absorbed: the residuals are smaller with the calibration
    assert float(match[2]) < float(match[3])
    assert match[4] == str(tmp_path / "out" / "camera.toml")


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_a_block_prints_its_calibration_where_a_strip_does(tmp_path):
    """Strip and block alike: the refinement's line, the self-calibration,
    then the control and the check points."""
    orders = []
    for name, sim in (
        ("strip", simulate_strip(12, preset="drone", seed=2)),
        ("block", simulate_block(2, 6, seed=3)),
    ):
        (tmp_path / name).mkdir()
        stdout = _run(_auto(tmp_path / name, sim)).stdout
        heads = ("bundle refinement:", "self-calibration:", "control:", "check points:")
        orders.append([_line(stdout, head)[0] for head in heads])
    for order in orders:
        assert order == sorted(order) and order[1] == order[0] + 1, orders


def test_check_and_run_name_the_file_then_the_strip(tmp_path):
    toml = shuffled_block(tmp_path)
    images = str(toml.parent / "image_points.csv")
    head = f"stripaero: error: {images}: strip 'S2': "
    run = CliRunner().invoke(cli, ["run", str(toml)])
    check = CliRunner().invoke(cli, ["check", str(toml)])
    assert run.exit_code == check.exit_code == 1
    for result in (run, check):
        lines = result.stderr.splitlines()
        assert lines and all(ln.startswith(head) for ln in lines), result.stderr
        assert not any("strip 'S2'" in ln[len(head) :] for ln in lines), result.stderr


# --------------------------------------------------------------- long warnings


def _held(n: int) -> str:
    names = [f"p{i}" for i in range(n)]
    return f"held {n} ({', '.join(names)}): " + "; ".join(
        f"{p} (t = 0.{i:02d}, below 3, a reason long enough to matter)"
        for i, p in enumerate(names)
    )


def test_a_long_list_is_cut_after_a_whole_item():
    text = _held(20)
    assert len(text) > MAX_LINE
    cut = cut_at_items(text, MAX_LINE, where="report.json")
    assert len(cut) <= MAX_LINE
    kept, more = cut.rsplit("; ", 1)
    items = text.split("; ")
    n_kept = len(kept.split("; "))
    assert kept == "; ".join(items[:n_kept])  # whole items, in order
    assert more == f"… and {len(items) - n_kept} more in report.json"
    # the longest such prefix: one more item would not fit
    tail = f"; … and {len(items) - n_kept - 1} more in report.json"
    longer = "; ".join(items[: n_kept + 1]) + tail
    assert len(longer) > MAX_LINE
    assert "characters)" not in cut


def test_a_short_text_or_one_huge_item_is_as_before():
    assert cut_at_items(_held(2), MAX_LINE) == _held(2)
    huge = "x" * 2000
    assert cut_at_items(huge, MAX_LINE) == shorten(huge, MAX_LINE)
    assert cut_at_items("a\x1b[31m; b", MAX_LINE) == "a; b"  # cleaned as ever
    assert len(cut_at_items("y; " * 10**6, MAX_LINE)) <= MAX_LINE  # no megabyte split


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_the_held_parameters_are_all_named_on_stderr(tmp_path):
    """The run's warning on the held parameters names every one of them on
    its one line, its reasons cut after a whole item; report.json has the
    whole text."""
    import json

    toml = _auto(tmp_path, simulate_block(2, 6, seed=3))
    result = _run(toml)
    (line,) = [ln for ln in result.stderr.splitlines() if "self-calibration held" in ln]
    assert len(line) <= MAX_LINE + len("stripaero: warning: ")
    record = json.loads((tmp_path / "out" / "report.json").read_text("utf-8"))
    held = [p["name"] for p in record["bundle"]["self_calibration"]["parameters"] if not p["kept"]]
    assert len(held) >= 8
    names = re.search(r"start values \(([^)]*)\)", line)
    assert names is not None and sorted(names[1].split(", ")) == sorted(held), line
    assert "characters)" not in line
    assert re.search(r"; … and \d+ more in report\.json$", line), line


def test_the_two_sigma0_of_a_calibration_have_three_significant_digits(capsys):
    """"sigma0 0.38 (with the camera as given: 0.577)" mixed two formats: both
    carry 3 significant digits, a trailing zero kept, an integral value
    without a bare point."""
    from types import SimpleNamespace

    import click

    from strip_aerotri.cli.run import _echo_calibration
    from strip_aerotri.report.summary import Calibration

    expected = {
        (0.38, 0.577): "sigma0 0.380 (with the camera as given: 0.577)",
        (1.0, 12.0): "sigma0 1.00 (with the camera as given: 12.0)",
        (0.0412, 100.0): "sigma0 0.0412 (with the camera as given: 100)",
    }
    with click.Context(cli):
        for (sigma0, without), text in expected.items():
            summary = SimpleNamespace(calibration=Calibration(("k1",), sigma0, without, False))
            _echo_calibration(summary, Path("out"))  # type: ignore[arg-type]
            line = capsys.readouterr().out.strip()
            assert line == f"self-calibration: kept k1, {text}", line
        # nothing kept: the given camera's sigma0 alone, in the same format
        summary = SimpleNamespace(calibration=Calibration((), None, 0.5, False))
        _echo_calibration(summary, Path("out"))  # type: ignore[arg-type]
        assert capsys.readouterr().out.strip().endswith("(sigma0 0.500)")


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_the_page_shows_the_adjusted_camera_and_names_camera_toml(tmp_path):
    """The page's self-calibration section gives the adjusted camera as
    camera.toml has it (c, x0, y0 and the kept distortion terms, each with
    its sd or "held") and names the file written beside it."""
    import html as html_text

    toml = _auto(tmp_path, simulate_strip(12, preset="drone", seed=2, camera_errors={"k1": -3e-4}))
    _run(toml)
    out = tmp_path / "out"
    page = (out / "report.html").read_text("utf-8")
    section = page[page.index("<h3>The adjusted camera</h3>") :]
    section = section[: section.index("</p>")]
    assert "<code>camera.toml</code>, written beside this page" in section
    rows = {
        m[1]: (html_text.unescape(m[2]), m[3], m[4])
        for m in re.finditer(
            r"<tr><td[^>]*>(\w+)</td><td>([^<]*)</td><td>([^<]*)</td><td>([^<]*)</td></tr>",
            section,
        )
    }
    written = tomllib.loads((out / "camera.toml").read_text("utf-8"))
    record = json.loads((out / "report.json").read_text("utf-8"))["bundle"]["self_calibration"]
    params = {p["name"]: p for p in record["parameters"]}
    assert "k1" in record["kept"]
    distortion = {k: v for k, v in written["distortion"].items() if k not in ("units", "model")}
    shown = {"c", "x0", "y0"} | {k for k, v in distortion.items() if v != 0.0}
    assert set(rows) == shown | set(record["kept"]), rows
    given = {
        "c": written["camera"]["principal_distance_mm"],
        "x0": written["camera"]["principal_point_mm"][0],
        "y0": written["camera"]["principal_point_mm"][1],
        **distortion,
    }
    for name, (value, sd, unit) in rows.items():
        assert float(value) == pytest.approx(given[name], rel=1e-5, abs=5e-5), name
        p = params[name]
        assert sd == (f"{p['sd']:.2g}" if p["kept"] else "held"), name
        assert unit == ("–" if p["unit"] == "1" else p["unit"]), name
