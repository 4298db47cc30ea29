"""``stripaero import patb``: PATB ``.im``, ``.con`` and ``.ori`` files.

Sample: ``tests/data/import/patb`` (tests/data/SOURCES.md), the synthetic
flight of the other importers with photos numbered 1001-1011.
"""

from __future__ import annotations

import csv
import tomllib
from pathlib import Path

import numpy as np
import pytest

from strip_aerotri.errors import ConfigError
from strip_aerotri.importers.common import ImportOptions, write_project
from strip_aerotri.interior import flight_matrix
from strip_aerotri.importers.patb import import_patb, read_con, read_im, read_ori
from strip_aerotri.project import load_project

SAMPLE = Path(__file__).resolve().parent / "data" / "import"
PATB = SAMPLE / "patb"


def test_patb_strip_is_a_ready_project(tmp_path: Path) -> None:
    project = import_patb(
        PATB / "block.im",
        PATB / "block.con",
        ImportOptions(strips=(1,)),
        focal_mm=8.8,
        crs="EPSG:32632",
        ori_file=PATB / "block.ori",
    )
    loaded = load_project(write_project(project, tmp_path / "p"))
    assert loaded.photo_ids == ("1001", "1002", "1003", "1004", "1005")
    assert loaded.images.flight_direction.value == "+y"
    truth = {
        (r["photo"], r["point"]): (float(r["x"]), float(r["y"]))
        for r in csv.DictReader((SAMPLE / "truth" / "observations.csv").open())
    }
    o = loaded.observations
    photos = np.asarray(o.photo_ids)[o.photo]
    points = np.asarray(o.point_ids)[o.point]
    true = np.array(
        [truth[(f"DJI_{int(p) - 1000:04d}", q)] for p, q in zip(photos, points, strict=True)]
    )
    # .im written to 0.1 um (make_import_fixtures.py)
    np.testing.assert_allclose(o.xy, true @ flight_matrix("+y")[:2, :2].T, atol=6e-5)
    assert loaded.gnss is not None and len(loaded.gnss.photo_ids) == 5


def test_patb_block_from_the_ori_positions(tmp_path: Path) -> None:
    project = import_patb(
        PATB / "block.im",
        PATB / "block.con",
        focal_mm=8.8,
        crs="EPSG:32632",
        ori_file=PATB / "block.ori",
    )
    doc = tomllib.loads(write_project(project, tmp_path / "p").read_text(encoding="utf-8"))
    assert [s["photos"] for s in doc["strips"]] == [
        ["1001", "1002", "1003", "1004", "1005"],
        ["1011", "1010", "1009", "1008", "1007"],
    ]


def test_patb_without_ori_is_one_strip_in_name_order(tmp_path: Path) -> None:
    im = tmp_path / "s.im"
    text = (PATB / "block.im").read_text()
    im.write_text(text[: text.index("      1006")])  # photos 1001-1005
    project = import_patb(im, PATB / "block.con", focal_mm=8.8, crs="local")
    assert [s.photos for s in project.strips] == [("1001", "1002", "1003", "1004", "1005")]


def test_patb_units_um_are_converted(tmp_path: Path) -> None:
    mm = read_im(PATB / "block.im")
    lines = []
    for line in (PATB / "block.im").read_text().splitlines():
        f = line.split()
        if len(f) == 3:
            line = f"{f[0]} {float(f[1]) * 1000:.1f} {float(f[2]) * 1000:.1f}"
        lines.append(line)
    (tmp_path / "um.im").write_text("\n".join(lines) + "\n")
    um = read_im(tmp_path / "um.im", "um")
    np.testing.assert_allclose(um.xy, mm.xy, atol=1e-4)
    with pytest.raises(ConfigError, match=r"um\.im:\d+: .*too large for mm.*--units um"):
        read_im(tmp_path / "um.im", "mm")


@pytest.mark.parametrize(
    ("im_text", "match"),
    [
        ("1001\n  P1 1.0\n-99\n", r"a\.im:2: expected a point record"),
        ("1001\n  P1 1.0 2.0\n  P1 1.5 2.5\n-99\n", r"a\.im:3: point 'P1' is measured twice"),
        ("1001\n  P1 1.0 x\n-99\n", r"a\.im:2: y: expected a number, got 'x'"),
        ("-99\n", "no point record"),
    ],
    ids=["short", "twice", "number", "empty"],
)
def test_patb_im_errors_name_the_line(tmp_path: Path, im_text: str, match: str) -> None:
    (tmp_path / "a.im").write_text(im_text)
    with pytest.raises(ConfigError, match=match):
        read_im(tmp_path / "a.im")


def test_patb_con_refuses_records_it_does_not_read(tmp_path: Path) -> None:
    (tmp_path / "a.con").write_text("G1 100.0 200.0 30.0\nG2 110.0 210.0\n-99\n")
    with pytest.raises(ConfigError, match=r"a\.con:2: expected a control record 'point X Y Z'"):
        read_con(tmp_path / "a.con")
    (tmp_path / "b.con").write_text("G1 100.0 200.0 30.0\n-99\nG2 1 2\n")
    assert read_con(tmp_path / "b.con").point.tolist() == ["G1"]  # read up to -99


def test_patb_ori_needs_three_records_per_photo(tmp_path: Path) -> None:
    lines = (PATB / "block.ori").read_text().splitlines()
    (tmp_path / "a.ori").write_text("\n".join(lines[:4]) + "\n")
    with pytest.raises(ConfigError, match="three records per photo"):
        read_ori(tmp_path / "a.ori")
    assert len(read_ori(PATB / "block.ori").photo) == 11


def test_patb_con_repeated_point_names_both_lines(tmp_path: Path) -> None:
    (tmp_path / "a.con").write_text("G1 1.0 2.0 3.0\nG2 1.0 2.0 3.0\nG1 1.5 2.0 3.0\n-99\n")
    with pytest.raises(
        ConfigError, match=r"a\.con:3: control point 'G1' is listed twice \(first at line 1\)"
    ):
        read_con(tmp_path / "a.con")
