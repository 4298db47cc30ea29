"""A new user's first steps: the README's install, ``python -m strip_aerotri``,
the help pointing to the installed docs, hints for files saved by a
spreadsheet, and ``stripaero check`` on a block as detailed as on a strip."""

from __future__ import annotations

import csv
import re
import subprocess
import sys
from pathlib import Path

from strip_aerotri.simulate import simulate_block, simulate_strip

ROOT = Path(__file__).resolve().parents[1]
CLI = "import sys; from strip_aerotri.cli.main import cli; sys.exit(cli())"


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", CLI, *args], capture_output=True, text=True, timeout=300
    )


def test_readme_makes_a_virtual_environment_before_pip_install():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    venv = text.index("python3 -m venv .venv")
    assert venv < text.index("pip install . && stripaero run examples/film-strip/strip.toml")
    assert "externally-managed-environment" in text
    assert "about a minute" not in text


def test_python_dash_m_is_the_command():
    done = subprocess.run(
        [sys.executable, "-m", "strip_aerotri", "--help"], capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert "Usage: stripaero" in done.stdout and "simulate" in done.stdout


def test_import_help_points_to_the_installed_docs():
    for args in (["import", "--help"], ["import", "pix4d", "--help"]):
        text = " ".join(_cli(*args).stdout.split())
        assert "stripaero docs import" in text and "docs/import.md" not in text


def _control(tmp_path: Path) -> tuple[Path, Path]:
    toml = simulate_strip(6, seed=1).write_project(tmp_path / "p")
    return toml, toml.parent / "control.csv"


def test_a_tab_separated_file_gets_a_hint(tmp_path: Path):
    toml, control = _control(tmp_path)
    control.write_text(control.read_text().replace(",", "\t"))
    done = _cli("check", str(toml))
    assert done.returncode == 1 and done.stderr.count("\n") == 1
    assert "separated by tabs" in done.stderr and "control.csv:1" in done.stderr


def test_a_quoted_decimal_comma_gets_a_hint(tmp_path: Path):
    toml, control = _control(tmp_path)
    with control.open(newline="") as f:
        rows = list(csv.reader(f))
    column = rows[0].index("H")
    rows[1][column] = rows[1][column].replace(".", ",")
    with control.open("w", newline="") as f:
        csv.writer(f).writerows(rows)
    done = _cli("check", str(toml))
    assert done.returncode == 1 and done.stderr.count("\n") == 1
    assert re.search(
        r"control\.csv:2: column 'H': expected a number, got '[0-9]+,[0-9]+'", done.stderr
    )
    assert "decimal comma: use a point" in done.stderr


def test_check_on_a_block_prints_what_it_prints_on_a_strip(tmp_path: Path):
    """Every summary line of a strip's check has its block counterpart, and
    the block adds the points two strips share."""
    strip = _cli("check", str(simulate_strip(8, seed=2).write_project(tmp_path / "s")))
    block = _cli(
        "check",
        str(simulate_block(3, 6, preset="drone", seed=1).write_project(tmp_path / "b")),
    )
    assert strip.returncode == 0 and block.returncode == 0, block.stderr
    heads = {line.split(":")[0].split(" ")[0] for line in strip.stdout.splitlines()}
    block_text = block.stdout
    for head in heads - {"photos", "pairs", "OK"}:
        assert re.search(rf"^{head}\b", block_text, re.M), head
    assert "pairs" in block_text and "tie points per model" in block_text
    assert re.search(r"^strips 'S1' / 'S2': \d+ common points$", block_text, re.M)
