"""TOML syntax errors a user of spreadsheets and other formats makes get
their likely cause (``project.loader._toml_hint``): tomllib's own words
("Unclosed array" for ``photos = [0301, 0302]``) name none.

Found by the catalogue fuzz (``benchmarks/fuzz_inputs.py``, "photos as
numbers" on photo ids with leading zeros).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli

FILM = Path(__file__).resolve().parents[1] / "examples" / "film-strip"


ZEROS = 'start with 0: write ids as strings, "01001"'
CASES = {
    "leading-zeros": ('"1001", "1002"', "01001, 01002", ":4:12:", ZEROS),
    "bare-id": ('"1001", "1002"', 'P1001, "1002"', ":4:11:", 'must be in quotes: "P1001"'),
    "bare-crs": ('"EPSG:2180"', "EPSG:2180", ":14:7:", 'must be in quotes: "EPSG:2180"'),
    "bare-name": ('"Film strip 1:8000, 12 photos (simulated)"', "Film strip", ":3:8:",
                  'in quotes: "Film strip"'),
    "decimal-comma": ("152.87", "152,87", ":7:28:", "a decimal comma"),
}  # fmt: skip
HINTS = ("cannot start with 0", "must be in quotes", "a decimal comma")


@pytest.mark.parametrize(("old", "new", "where", "hint"), CASES.values(), ids=CASES.keys())
def test_the_cause_of_a_toml_syntax_error(
    tmp_path: Path, old: str, new: str, where: str, hint: str
) -> None:
    folder = tmp_path / "p"
    shutil.copytree(FILM, folder, ignore=shutil.ignore_patterns("out"))
    toml = folder / "strip.toml"
    text = toml.read_text(encoding="utf-8")
    assert old in text
    toml.write_text(text.replace(old, new, 1), encoding="utf-8")
    for command in ("check", "run"):
        result = CliRunner().invoke(cli, [command, str(toml)])
        assert result.exit_code == 1
        (line,) = result.stderr.splitlines()
        assert f"strip.toml{where} TOML syntax error" in line and hint in line, line


@pytest.mark.parametrize("line", ['a = "b" c', 'photos = ["1001" "1002"]', "[camera", "x = 1.5.3"])
def test_other_syntax_errors_get_no_guess(tmp_path: Path, line: str) -> None:
    toml = tmp_path / "strip.toml"
    toml.write_text(line + "\n", encoding="utf-8")
    result = CliRunner().invoke(cli, ["check", str(toml)])
    assert result.exit_code == 1
    (error,) = result.stderr.splitlines()
    assert "TOML syntax error" in error, error
    assert not any(h in error for h in HINTS), error
