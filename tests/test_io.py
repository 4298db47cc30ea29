"""Result writing: CSV formatting round trips and atomic replacement of the result folder."""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.errors import StripAerotriError
from strip_aerotri.report.files import (
    RESULT_MARKER,
    OutputError,
    ResultFolder,
    format_csv,
    format_photos_csv,
    format_points_csv,
    write_csv,
    write_result_folder,
)


def parse(text: str) -> tuple[list[str], list[list[str]]]:
    rows = list(csv.reader(io.StringIO(text)))
    return rows[0], rows[1:]


def tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in folder.rglob("*") if p.is_file()}


# --------------------------------------------------------------------------- CSV


def test_points_csv_round_trip() -> None:
    rng = np.random.default_rng(2345)
    ids = np.array(["001", "a,b", 'q"t', "7"])  # leading zero, comma and quote in ids
    xyz = rng.uniform(-1e6, 1e6, size=(4, 3))
    xyz[2, 2] = np.nan  # a plan point has no H
    n = np.array([2, 3, 1, 4])
    role = ["tie", "full", "plan", "check"]
    before = xyz.copy()
    text = format_points_csv(ids, xyz, extra={"role": role, "n": n, "dz": (xyz[:, 2] / 7, 6)})
    np.testing.assert_array_equal(xyz, before)  # caller's array untouched
    header, rows = parse(text)
    assert header == ["point", "X", "Y", "H", "role", "n", "dz"]
    assert [r[0] for r in rows] == ids.tolist()
    back = np.array([[float(v) if v else np.nan for v in r[1:4]] for r in rows])
    np.testing.assert_allclose(back, xyz, rtol=0, atol=0.5e-4)  # 4 decimals: 0.1 mm
    assert rows[2][3] == ""  # NaN -> empty cell, as in the input files
    assert [r[4] for r in rows] == role and [int(r[5]) for r in rows] == n.tolist()
    assert all(len(r[6].split(".")[1]) == 6 for r in rows if r[6])
    assert all(len(r[1].split(".")[1]) == 4 for r in rows)


def test_points_csv_geographic_uses_nine_decimals() -> None:
    text = format_points_csv(["1"], [[21.123456789012, 42.7, 300.0]], geographic=True)
    # 1e-9 degree is about 0.1 mm on the ground
    assert text == "point,X,Y,H\n1,21.123456789,42.700000000,300.0000\n"


def test_photos_csv_angles_in_degrees() -> None:
    opk = np.deg2rad([[1.5, -0.25, 179.9999995]])
    text = format_photos_csv(["0101"], [[500000.0, 4727000.0, 1300.12346]], opk)
    header, rows = parse(text)
    assert header == ["photo", "X", "Y", "Z", "omega", "phi", "kappa"]
    assert rows == [["0101", "500000.0000", "4727000.0000", "1300.1235", "1.500000",
                     "-0.250000", "180.000000"]]  # fmt: skip
    same = format_photos_csv(["0101"], [[500000.0, 4727000.0, 1300.12346]], np.rad2deg(opk),
                             degrees=True)  # fmt: skip
    assert same == text


def test_negative_zero_is_written_as_zero() -> None:
    assert format_csv(["v"], [np.array([-0.00001, -0.0])]) == "v\n0.0000\n0.0000\n"


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: format_points_csv(["1", "2"], np.zeros((3, 3))), r"`xyz` to have shape \(2, 3\)"),
        (lambda: format_photos_csv(["1"], np.zeros((1, 3)), np.zeros(3)), r"`opk` to have shape"),
        (lambda: format_points_csv(["1"], np.zeros((1, 3)), extra={"X": [1.0]}), "clashes"),
        (lambda: format_csv(["a", "b"], [[1.0]]), "as many columns as header names"),
        (lambda: format_csv(["a", "b"], [[1.0], [1.0, 2.0]]), "equal length"),
        (lambda: format_csv(["a,b"], [[1.0]]), "plain column name"),
    ],
    ids=["points-shape", "opk-shape", "extra-clash", "header-count", "lengths", "name"],
)
def test_format_errors(call, match) -> None:
    with pytest.raises(ValueError, match=match):
        call()


def test_write_csv(tmp_path: Path) -> None:
    path = write_csv(tmp_path / "a.csv", ["point", "H"], [["x"], [1.0]], decimals=2)
    assert path.read_bytes() == b"point,H\nx,1.00\n"


# --------------------------------------------------------------------------- result folder


def test_new_folder_is_created_with_marker(tmp_path: Path) -> None:
    target = tmp_path / "deep" / "out"
    write_result_folder(target, {"points.csv": "p\n", "fig/a.png": b"\x89PNG"})
    assert tree(target) == {
        RESULT_MARKER: (target / RESULT_MARKER).read_bytes(),
        "points.csv": b"p\n",
        str(Path("fig/a.png")): b"\x89PNG",
    }
    assert sorted(os.listdir(tmp_path / "deep")) == ["out"]  # no temporary left


def test_previous_result_is_replaced_as_a_whole(tmp_path: Path) -> None:
    target = tmp_path / "out"
    write_result_folder(target, {"points.csv": "old\n", "stale.txt": "x"})
    write_result_folder(target, {"points.csv": "new\n"})
    assert set(tree(target)) == {RESULT_MARKER, "points.csv"}  # stale.txt is gone
    assert (target / "points.csv").read_text() == "new\n"
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_empty_folder_is_accepted(tmp_path: Path) -> None:
    target = tmp_path / "out"
    target.mkdir()
    write_result_folder(target, {"a.txt": "a"})
    assert (target / "a.txt").read_text() == "a"


def test_failure_mid_write_leaves_previous_folder_intact(tmp_path: Path) -> None:
    target = tmp_path / "out"
    write_result_folder(target, {"points.csv": "old\n", "photos.csv": "old\n"})
    before = tree(target)
    with pytest.raises(RuntimeError, match="boom"), ResultFolder(target) as folder:
        folder.write_text("points.csv", "new\n")
        raise RuntimeError("boom")  # e.g. the report fails after the first file
    assert tree(target) == before
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_io_error_mid_write_leaves_previous_folder_intact(tmp_path: Path, monkeypatch) -> None:
    target = tmp_path / "out"
    write_result_folder(target, {"points.csv": "old\n"})
    before = tree(target)
    real = Path.write_bytes
    calls = []

    def failing(self: Path, data: bytes) -> int:
        calls.append(self.name)
        if len(calls) == 2:
            raise OSError(28, "No space left on device")
        return real(self, data)

    monkeypatch.setattr(Path, "write_bytes", failing)
    with pytest.raises(OutputError, match=r"cannot write 'photos\.csv': No space left"):
        write_result_folder(target, {"points.csv": "new\n", "photos.csv": "new\n"})
    monkeypatch.undo()
    assert calls == ["points.csv", "photos.csv"]
    assert tree(target) == before
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_failed_swap_restores_previous_folder(tmp_path: Path, monkeypatch) -> None:
    target = tmp_path / "out"
    write_result_folder(target, {"points.csv": "old\n"})
    before = tree(target)
    real = os.replace

    def replace(src, dst):
        if ".tmp-" in str(src):  # moving the new folder in fails
            raise OSError(13, "Permission denied")
        return real(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OutputError, match="cannot replace"):
        write_result_folder(target, {"points.csv": "new\n"})
    monkeypatch.undo()
    assert tree(target) == before
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_refuses_a_folder_that_is_not_a_result(tmp_path: Path) -> None:
    target = tmp_path / "photos"
    target.mkdir()
    (target / "important.tif").write_bytes(b"data")
    with pytest.raises(OutputError, match=r"not a stripaero result folder") as info:
        write_result_folder(target, {"points.csv": "x"})
    assert isinstance(info.value, StripAerotriError)
    assert tree(target) == {"important.tif": b"data"}
    assert sorted(os.listdir(tmp_path)) == ["photos"]


def test_refuses_a_file_and_a_folder_holding_inputs(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputError, match="is a file"):
        write_result_folder(tmp_path / "file", {})
    target = tmp_path / "out"
    write_result_folder(target, {"a": "a"})
    (target / "strip.toml").write_text("[strip]\n")  # a user put an input inside
    with pytest.raises(OutputError, match="contains the input file"):
        write_result_folder(target, {"a": "b"}, protect=[target / "strip.toml"])
    assert (target / "strip.toml").read_text() == "[strip]\n"


@pytest.mark.parametrize("name", ["/abs.csv", "../up.csv", "a/../b", RESULT_MARKER, ""])
def test_bad_file_names(tmp_path: Path, name: str) -> None:
    with pytest.raises(ValueError, match="relative file name"):
        write_result_folder(tmp_path / "out", {name: "x"})
    assert not (tmp_path / "out").exists()


def test_atomic_file_leaves_the_old_file_when_writing_fails(tmp_path):
    from strip_aerotri._atomic import atomic_file

    target = tmp_path / "a.geojson"
    target.write_text("old")
    with pytest.raises(RuntimeError, match="half way"):
        with atomic_file(target) as partial:
            partial.write_text("new, half")
            raise RuntimeError("half way")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.geojson"]


def test_files_the_run_did_not_write_are_kept(tmp_path: Path) -> None:
    """A new result replaces what the previous run wrote (the marker lists
    it) and keeps the rest; an export recorded in the marker is named."""
    from strip_aerotri.report.files import ResultFolder, record_export

    target = tmp_path / "out"
    write_result_folder(target, {"points.csv": "old\n", "gone.txt": "x"})
    (target / "notes.txt").write_text("mine")
    (target / "sub").mkdir()
    (target / "sub" / "a.txt").write_text("a")
    (target / "results.geojson").write_text("{}")
    record_export(target / "results.geojson")
    record_export(target / "results.geojson")  # once only
    folder = ResultFolder(target)
    with folder:
        folder.write_text("points.csv", "new\n")
    assert set(tree(target)) == {
        RESULT_MARKER,
        "points.csv",
        "notes.txt",
        str(Path("sub/a.txt")),
        "results.geojson",
    }
    assert folder.kept == ("notes.txt", "results.geojson", "sub")
    assert folder.exports == ("results.geojson",)
    marker = (target / RESULT_MARKER).read_text().splitlines()
    assert "written: points.csv" in marker and marker.count("exported: results.geojson") == 1
    assert sorted(os.listdir(tmp_path)) == ["out"]


def test_a_failed_run_keeps_the_folder_and_its_foreign_files(tmp_path: Path) -> None:
    from strip_aerotri.report.files import ResultFolder

    target = tmp_path / "out"
    write_result_folder(target, {"points.csv": "old\n"})
    (target / "notes.txt").write_text("mine")
    with pytest.raises(RuntimeError), ResultFolder(target) as folder:
        folder.write_text("points.csv", "new\n")
        raise RuntimeError("failed")
    assert (target / "points.csv").read_text() == "old\n"
    assert (target / "notes.txt").read_text() == "mine"
    assert sorted(os.listdir(tmp_path)) == ["out"]
