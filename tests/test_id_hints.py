"""Ids that differ only in a way the eye does not see or a spreadsheet
makes: the messages name the likely cause (``project.schema.IdHints``).

Found by the catalogue fuzz (``benchmarks/fuzz_inputs.py``): a photo id in
NFD in the image file and NFC in strip.toml was refused as "photo 'Café'
is not in [strip] photos", naming a photo that looks the same as the listed
one; a control file whose ids lost their leading zeros in a spreadsheet ran
to "no full, plan or height control point is given (0 check point(s) only)"
although it gives 64.
"""

from __future__ import annotations

import re
import shutil
import unicodedata
from pathlib import Path

import pytest
from click.testing import CliRunner

from strip_aerotri.cli.main import cli
from strip_aerotri.project import load_project
from strip_aerotri.project.schema import IdHints, suggest_id

FILM = Path(__file__).resolve().parents[1] / "examples" / "film-strip"
NFC = unicodedata.normalize("NFC", "Caf\u00e9")
NFD = unicodedata.normalize("NFD", NFC)


@pytest.mark.parametrize(
    ("word", "candidates", "expected"),
    [
        (NFD, ["1001", NFC], f"differs from '{NFC}' only in its Unicode form"),
        (NFC, [NFD], f"differs from '{NFD}' only in its Unicode form"),
        ("301", ["0300", "0301"], "did you mean '0301'? a spreadsheet drops leading zeros"),
        ("1001.0", ["1001", "1002"], "did you mean '1001'?"),
        (" 7 ", ["007"], "did you mean '007'?"),
        ("0301", ["301"], "did you mean '301'?"),
        ("P0301", ["P301"], ""),  # letters before the digits: not a number a spreadsheet made
        ("p0301", ["P0301"], "did you mean 'P0301'? ids are case-sensitive"),
        ("GCP01", ["gcp01", "GCP02"], "did you mean 'gcp01'? ids are case-sensitive"),
        ("9999", ["0301"], ""),
        ("0301", ["0301"], ""),  # the same id: nothing to say
    ],
    ids=[
        "nfd",
        "nfc",
        "zeros",
        "float",
        "spaces",
        "zeros-added",
        "letters",
        "case",
        "case-gcp",
        "none",
        "same",
    ],
)
def test_id_hints(word: str, candidates: list[str], expected: str) -> None:
    hint = IdHints(candidates)(word)
    if expected:
        assert expected in hint, hint
    else:
        assert hint == ""


def test_suggest_id_falls_back_to_the_spelling_suggestion() -> None:
    assert suggest_id("1O01", ["1001", "2002"]) == " (did you mean '1001'?)"
    assert suggest_id("x" * 10_000, ["1001"]) == ""


def _copy(tmp_path: Path) -> Path:
    folder = tmp_path / "p"
    shutil.copytree(FILM, folder, ignore=shutil.ignore_patterns("out"))
    return folder


def _one_error(folder: Path, *pieces: str) -> None:
    for command in ("check", "run"):
        result = CliRunner().invoke(cli, [command, str(folder / "strip.toml")])
        assert result.exit_code == 1, result.output
        (line,) = result.stderr.splitlines()
        assert line.startswith("stripaero: error: ") and len(line) < 500, line
        for piece in pieces:
            assert piece in line, (piece, line)
    assert not (folder / "out").exists()


def test_a_photo_in_nfd_is_named_as_such(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    toml = folder / "strip.toml"
    toml.write_text(toml.read_text("utf-8").replace('"1002"', f'"{NFC}"'), encoding="utf-8")
    images = folder / "image_points.csv"
    text = re.sub(r"^1002,", f"{NFD},", images.read_text("utf-8"), flags=re.M)
    images.write_text(text, encoding="utf-8")
    _one_error(folder, "image_points.csv:", "only in its Unicode form")


def test_photo_ids_without_their_leading_zeros(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    toml = folder / "strip.toml"
    text = re.sub(r'"1(\d\d\d)"', lambda m: f'"{int(m[1]):04d}"', toml.read_text("utf-8"))
    toml.write_text(text, encoding="utf-8")  # photos 0001 ... 0012
    images = folder / "image_points.csv"
    text = re.sub(r"^1(\d\d\d),", lambda m: f"{int(m[1])},", images.read_text("utf-8"), flags=re.M)
    images.write_text(text, encoding="utf-8")  # photos 1 ... 12, as a spreadsheet leaves them
    _one_error(folder, "image_points.csv:2:", "photo '1' is not in", "did you mean '0001'?")


def _numeric_points(folder: Path, control_zeros: bool) -> None:
    """Point ids 'P0003' become '0003' in both files, or '3' in control.csv."""
    images = folder / "image_points.csv"
    images.write_text(images.read_text("utf-8").replace(",P0", ",0"), encoding="utf-8")
    control = folder / "control.csv"
    text = re.sub(r"^P0", "0", control.read_text("utf-8"), flags=re.M)
    if not control_zeros:
        text = re.sub(r"^0+", "", text, flags=re.M)
    control.write_text(text, encoding="utf-8")


def test_control_ids_without_their_leading_zeros_are_one_line(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    _numeric_points(folder, control_zeros=False)
    _one_error(
        folder,
        "control.csv: none of its 64 points is observed on any photo",
        "control '3' (did you mean '0003'?",
        "'0001', '0002', '0003'",
    )


def test_numeric_ids_alike_in_both_files_still_run(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    _numeric_points(folder, control_zeros=True)
    assert load_project(folder / "strip.toml").warnings == ()


def test_a_few_unobserved_control_points_are_warned_with_the_hint(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    _numeric_points(folder, control_zeros=True)
    control = folder / "control.csv"
    control.write_text(re.sub(r"^0003,", "3,", control.read_text("utf-8"), flags=re.M), "utf-8")
    (warning,) = load_project(folder / "strip.toml").warnings
    assert "control point '3' (full) is not observed on any photo" in warning
    assert "did you mean '0003'?" in warning


def test_control_left_too_small_by_unmatched_ids_is_one_line_naming_them(tmp_path: Path) -> None:
    """Most control ids lost their zeros, one did not: the run used to stop on
    "similarity transformation needs at least two full or plan control
    points, got 1" (and with -q without the warnings that named the rest)."""
    folder = _copy(tmp_path)
    _numeric_points(folder, control_zeros=False)
    control = folder / "control.csv"
    control.write_text(re.sub(r"^3,", "0003,", control.read_text("utf-8"), flags=re.M), "utf-8")
    _one_error(
        folder,
        "control.csv:3: control point '8' (did you mean '0008'?",
        "and 12 other(s) are not observed on any photo",
        "two full or plan control points, got 1: '0003'",
    )


def test_unmatched_check_points_alone_stop_nothing(tmp_path: Path) -> None:
    folder = _copy(tmp_path)
    _numeric_points(folder, control_zeros=True)
    control = folder / "control.csv"  # the check points' ids lose their zeros
    text = re.sub(
        r"^0+(\d+,[^,]*,[^,]*,[^,]*,check)", r"\1", control.read_text("utf-8"), flags=re.M
    )
    control.write_text(text, encoding="utf-8")
    warnings = load_project(folder / "strip.toml").warnings
    assert len(warnings) == 50 and all("(check) is not observed" in w for w in warnings)


def test_a_straight_line_point_in_another_case(tmp_path: Path) -> None:
    folder = tmp_path / "p"
    shutil.copytree(FILM.parent / "drone-corridor", folder, ignore=shutil.ignore_patterns("out"))
    toml = folder / "strip.toml"
    toml.write_text(toml.read_text("utf-8").replace('"P0006"', '"p0006"', 1), encoding="utf-8")
    _one_error(
        folder,
        "[[straight_line]] #1 points: point 'p0006' is not observed on any photo",
        "(did you mean 'P0006'? ids are case-sensitive)",
    )
