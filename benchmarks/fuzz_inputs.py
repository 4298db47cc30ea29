"""A catalogue of the input mistakes real users make, applied to a project's
strip.toml and CSV files, each run through ``stripaero check`` and
``stripaero run`` in a temporary copy.

Where ``tests/test_fuzz.py`` draws random mutations, this catalogue names
each mistake and what the program must answer (docs/project-file.md and
formats.md, the contract):

* ``FAIL``: exit code 1, one line on stderr (``stripaero: error: ...``, for
  ``run``; ``check`` may list one line per problem), holding the words that
  name the culprit (a file, line, key, photo or point);
* ``OK``: exit code 0 (warnings allowed), a result folder with points.csv,
  photos.csv and report.json;
* ``EITHER``: 0 or 1, each with the rules above.

The camera's entries (``-k camera -k distortion -k self_calibration``) put
the mistakes of a first self-calibrated project into ``[camera]``,
``[distortion]`` and ``[adjustment] self_calibration``, and paste a
self-calibration's ``camera.toml`` into the next project: c and the
principal point in pixels, metres or beyond the format, coefficients a
million times too large or for normalised coordinates, unknown, repeated or
missing names and keys.  An entry whose answer may rightly differ between a
film and a drone camera (k1 of the wrong sign, normalised coefficients read
as mm: a 20 % correction at the drone format's corner, 20 times the radius on film; Ebner's film
parameters on the drone) is ``EITHER``.

Every run, whatever its answer: no traceback, no stderr line that is neither
an error nor a warning, the input files byte-identical afterwards, and the
project folder either holds a new complete result (exit 0) or exactly what it
held before (exit 1: the earlier result folder byte-identical, no stray
temporary folder).

Usage::

    python benchmarks/fuzz_inputs.py                  # both examples, every mutation
    python benchmarks/fuzz_inputs.py PROJECT_DIR ...  # other projects (strip.toml inside)
    python benchmarks/fuzz_inputs.py -k bom -k crlf   # the mutations whose name holds a word

It runs each command in a fresh interpreter (``python -m strip_aerotri``), as
a user does, and prints one line per mutation and command; it exits with 1
when any answer breaks the rules.  ``tests/test_fuzz_inputs.py`` runs the same
catalogue in-process on the film example.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import io
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

FAIL, OK, EITHER = "fail", "ok", "either"
ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = (ROOT / "examples" / "film-strip", ROOT / "examples" / "drone-corridor")


# ----------------------------------------------------------------------------- file helpers


class Project:
    """A project folder being mutated: strip.toml and its two CSV files."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.toml = folder / "strip.toml"
        text = self.toml.read_text(encoding="utf-8")
        self.images = folder / _toml_string(text, "images", "file")
        self.control = folder / _toml_string(text, "control", "file")

    def rows(self, path: Path) -> tuple[list[str], list[list[str]]]:
        """Header and data rows of a CSV (comments and blank lines dropped)."""
        lines = [
            ln for ln in path.read_text(encoding="utf-8").splitlines()
            if ln.strip() and not ln.lstrip().startswith("#")
        ]  # fmt: skip
        table = list(csv.reader(lines))
        return table[0], table[1:]

    def write_rows(self, path: Path, header: list[str], rows: list[list[str]]) -> None:
        out = io.StringIO()
        csv.writer(out, lineterminator="\n").writerows([header, *rows])
        path.write_text(out.getvalue(), encoding="utf-8")

    def photos(self) -> list[str]:
        match = re.search(r"^photos\s*=\s*\[(.*?)\]", self.toml.read_text("utf-8"), re.S | re.M)
        if match is None:
            raise ValueError(f"{self.toml}: no photos list")
        return re.findall(r'"([^"]*)"', match.group(1))

    def set_photos(self, photos: list[str]) -> None:
        text = self.toml.read_text(encoding="utf-8")
        listed = "[" + ", ".join(f'"{p}"' for p in photos) + "]"
        text = re.sub(
            r"^photos\s*=\s*\[.*?\]", f"photos = {listed}", text, count=1, flags=re.S | re.M
        )
        self.toml.write_text(text, encoding="utf-8")

    def edit_toml(self, old: str, new: str) -> None:
        text = self.toml.read_text(encoding="utf-8")
        if old not in text:
            raise ValueError(f"{self.toml}: {old!r} not found")
        self.toml.write_text(text.replace(old, new, 1), encoding="utf-8")

    def map_column(self, path: Path, column: str, fn: Callable[[str], str]) -> None:
        """``fn`` of every non-empty cell of ``column`` (nothing when it is absent)."""
        header, rows = self.rows(path)
        if column not in header:
            return
        i = header.index(column)
        for row in rows:
            if row[i].strip():
                row[i] = fn(row[i])
        self.write_rows(path, header, rows)

    def set_cell(self, path: Path, row: int, column: str, value: str) -> None:
        """One cell; an absent optional column is added, empty elsewhere."""
        header, rows = self.rows(path)
        if column not in header:
            header.append(column)
            for r in rows:
                r.append("")
        rows[row][header.index(column)] = value
        self.write_rows(path, header, rows)

    def rename_id(self, old: str, new: str) -> None:
        """Rename a photo or point id everywhere: strip.toml's strings and the
        CSVs' id cells."""
        text = self.toml.read_text(encoding="utf-8")
        self.toml.write_text(text.replace(f'"{old}"', f'"{new}"'), encoding="utf-8")
        for path, columns in ((self.images, ("photo", "point")), (self.control, ("point",))):
            header, rows = self.rows(path)
            for column in columns:
                i = header.index(column)
                for r in rows:
                    r[i] = new if r[i].strip() == old else r[i]
            self.write_rows(path, header, rows)

    def tie_point(self, photos_at_least: int = 3) -> str:
        """A point that is not control, measured on at least so many photos."""
        _, rows = self.rows(self.images)
        control = {r[0] for r in self.rows(self.control)[1]}
        counts: dict[str, int] = {}
        for r in rows:
            counts[r[1]] = counts.get(r[1], 0) + 1
        return next(p for p, n in counts.items() if n >= photos_at_least and p not in control)


def _toml_string(text: str, table: str, key: str) -> str:
    section = re.search(rf"^\[{table}\](.*?)(?=^\[|\Z)", text, re.S | re.M)
    value = section and re.search(rf'^{key}\s*=\s*"([^"]*)"', section.group(1), re.M)
    if not value:
        raise ValueError(f"no [{table}] {key}")
    return value.group(1)


def _scale(factor: float) -> Callable[[str], str]:
    return lambda v: repr(float(v) * factor)


# ----------------------------------------------------------------------------- the mutations


@dataclass(frozen=True)
class Mutation:
    name: str
    expect: str
    apply: Callable[[Project], None]
    #: Words the error line must hold (any of the alternatives of each group).
    words: tuple[tuple[str, ...], ...] = ()


def _drop_column(which: str, column: str) -> Callable[[Project], None]:
    def apply(p: Project) -> None:
        path = getattr(p, which)
        header, rows = p.rows(path)
        i = header.index(column)
        p.write_rows(path, header[:i] + header[i + 1 :], [r[:i] + r[i + 1 :] for r in rows])

    return apply


def _extra_column(which: str) -> Callable[[Project], None]:
    def apply(p: Project) -> None:
        path = getattr(p, which)
        header, rows = p.rows(path)
        p.write_rows(path, [*header, "note"], [[*r, "ok"] for r in rows])

    return apply


def _cell(which: str, column: str, value: str, row: int = 3) -> Callable[[Project], None]:
    return lambda p: p.set_cell(getattr(p, which), row, column, value)


def _bytes(which: str, fn: Callable[[bytes], bytes]) -> Callable[[Project], None]:
    def apply(p: Project) -> None:
        path = getattr(p, which)
        path.write_bytes(fn(path.read_bytes()))

    return apply


def _duplicate_row(which: str, change: str | None = None) -> Callable[[Project], None]:
    def apply(p: Project) -> None:
        path = getattr(p, which)
        header, rows = p.rows(path)
        copy = list(rows[4])
        if change is not None:
            copy[header.index(change)] = repr(float(copy[header.index(change)]) + 1.0)
        rows.insert(9, copy)
        p.write_rows(path, header, rows)

    return apply


def _semicolons(decimal_comma: bool) -> Callable[[Project], None]:
    def apply(p: Project) -> None:
        for path in (p.images, p.control):
            header, rows = p.rows(path)
            lines = [";".join(header)]
            for r in rows:
                cells = [c.replace(".", ",") if decimal_comma else c for c in r]
                lines.append(";".join(cells))
            path.write_text("\n".join(lines) + "\n", encoding="utf-8")

    return apply


def _quoted_decimal_comma(p: Project) -> None:
    p.map_column(p.images, "x", lambda v: v.replace(".", ","))


def _swap_columns(which: str, a: str, b: str) -> Callable[[Project], None]:
    def apply(p: Project) -> None:
        path = getattr(p, which)
        header, rows = p.rows(path)
        i, j = header.index(a), header.index(b)
        for r in rows:
            r[i], r[j] = r[j], r[i]
        p.write_rows(path, header, rows)

    return apply


def _reorder_photos(how: str) -> Callable[[Project], None]:
    def apply(p: Project) -> None:
        photos = p.photos()
        if how == "reversed":
            photos = photos[::-1]
        elif how == "two swapped":
            k = len(photos) // 2
            photos[k], photos[k + 1] = photos[k + 1], photos[k]
        else:  # every other one first: a shuffle with a fixed answer
            photos = photos[::2] + photos[1::2]
        p.set_photos(photos)

    return apply


def _photo_without_points(where: str) -> Callable[[Project], None]:
    def apply(p: Project) -> None:
        photos = p.photos()
        photo = photos[len(photos) // 2] if where == "middle" else photos[-1]
        header, rows = p.rows(p.images)
        p.write_rows(p.images, header, [r for r in rows if r[0] != photo])

    return apply


def _point_on_one_photo(p: Project) -> None:
    point = p.tie_point()
    header, rows = p.rows(p.images)
    seen = False
    kept = []
    for r in rows:
        if r[1] == point:
            if seen:
                continue
            seen = True
        kept.append(r)
    p.write_rows(p.images, header, kept)


def _new_point_on_one_photo(p: Project) -> None:
    header, rows = p.rows(p.images)
    row = list(rows[0])
    row[1] = "LONE1"
    rows.append(row)
    p.write_rows(p.images, header, rows)


def _photo_not_listed(p: Project) -> None:
    p.set_photos(p.photos()[:-1])


def _unicode(kind: str) -> Callable[[Project], None]:
    def apply(p: Project) -> None:
        if kind == "point":
            p.rename_id(p.tie_point(), "Pünkt-道路-1")
        elif kind == "control point":
            p.rename_id(p.rows(p.control)[1][0][0], "Ørsted-Δ1")
        elif kind == "photo":
            p.rename_id(p.photos()[1], "Фото-2")
        else:  # a photo id in NFC in strip.toml and NFD in the CSV
            photo = p.photos()[1]
            p.rename_id(photo, "Caf\u00e9")
            text = p.images.read_text("utf-8").replace("Caf\u00e9", "Cafe\u0301")
            p.images.write_text(text, encoding="utf-8")

    return apply


def _duplicate_photo_in_list(p: Project) -> None:
    photos = p.photos()
    p.set_photos([*photos[:3], photos[2], *photos[3:]])


def _encode(which: str, codec: str, non_ascii: bool) -> Callable[[Project], None]:
    def apply(p: Project) -> None:
        if non_ascii:
            p.rename_id(p.tie_point(), "Pünkt1")
        path = getattr(p, which)
        path.write_bytes(path.read_text("utf-8").encode(codec))

    return apply


def _tabs(p: Project) -> None:
    p.images.write_text(p.images.read_text("utf-8").replace(",", "\t"), encoding="utf-8")


def _heights_in_feet(p: Project) -> None:
    p.map_column(p.control, "H", _scale(1 / 0.3048))


def _trailing_comma(p: Project) -> None:
    lines = p.images.read_text("utf-8").splitlines()
    p.images.write_text("".join(f"{ln},\n" for ln in lines), encoding="utf-8")


def _header_again(p: Project) -> None:
    lines = p.images.read_text("utf-8").splitlines()
    half = len(lines) // 2
    p.images.write_text("\n".join([*lines[:half], lines[0], *lines[half:]]) + "\n", "utf-8")


def _field_missing(p: Project) -> None:
    lines = p.images.read_text("utf-8").splitlines()
    lines[6] = lines[6].rsplit(",", 1)[0]
    p.images.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _header(p: Project, fn: Callable[[str], str]) -> None:
    lines = p.images.read_text("utf-8").splitlines()
    lines[0] = ",".join(fn(c) for c in lines[0].split(","))
    p.images.write_text("\n".join(lines) + "\n", encoding="utf-8")


def _spaces(p: Project) -> None:
    text = p.images.read_text("utf-8").replace(",", " , ")
    p.images.write_text(text, encoding="utf-8")


def _rows_reversed(p: Project) -> None:
    header, rows = p.rows(p.images)
    p.write_rows(p.images, header, rows[::-1])


def _numeric_points(p: Project, control_zeros: bool) -> None:
    """Every point id becomes a number with leading zeros ('00012') in both
    files, or without them ('12') in the control."""
    header, rows = p.rows(p.images)
    ids = sorted({r[1] for r in rows} | {r[0] for r in p.rows(p.control)[1]})
    number = {pid: f"{k + 1:05d}" for k, pid in enumerate(ids)}
    p.write_rows(p.images, header, [[r[0], number[r[1]], *r[2:]] for r in rows])
    header, rows = p.rows(p.control)
    p.write_rows(p.control, header, [
        [number[r[0]] if control_zeros else str(int(number[r[0]])), *r[1:]] for r in rows
    ])  # fmt: skip
    text = p.toml.read_text("utf-8")  # [[straight_line]] points name them too
    text = re.sub(r'"([^"]*)"', lambda m: f'"{number.get(m[1], m[1])}"', text)
    p.toml.write_text(text, encoding="utf-8")


def _photo_zeros(p: Project) -> None:
    """Photos '0001', ... in strip.toml, '1', ... in the image file."""
    photos = p.photos()
    new = [f"{i + 1:04d}" for i in range(len(photos))]
    p.set_photos(new)
    header, rows = p.rows(p.images)
    number = {old: str(int(n)) for old, n in zip(photos, new, strict=True)}
    p.write_rows(p.images, header, [[number.get(r[0], r[0]), *r[1:]] for r in rows])


def _photos_as_numbers(p: Project) -> None:
    """``photos = [1001, 1002]``, or ``[0301, ...]`` (not even TOML)."""
    p.set_photos(p.photos())
    listed = re.search(r"^photos = \[.*\]$", p.toml.read_text("utf-8"), re.M)
    if listed is None:
        raise ValueError("no photos list")
    text = p.toml.read_text("utf-8").replace(listed.group(), listed.group().replace('"', ""))
    p.toml.write_text(text, encoding="utf-8")


def _control_types(p: Project, kind: str, keep_full: int = 0) -> None:
    header, rows = p.rows(p.control)
    i = header.index("type")
    full = 0
    for r in rows:
        if r[i] != "check" and not (r[i] == "full" and full < keep_full):
            r[i] = kind
        full += r[i] == "full"
    p.write_rows(p.control, header, rows)


def _from_the_corner(p: Project) -> None:
    for c in ("x", "y"):
        p.map_column(p.images, c, lambda v: repr(float(v) + 115.0))


def _from_the_format_corner(p: Project) -> None:
    """x, y from the corner of the format: each shifted by half its range."""
    header, rows = p.rows(p.images)
    for c in ("x", "y"):
        i = header.index(c)
        values = [float(r[i]) for r in rows]
        shift = 0.5 * (max(values) - min(values))
        for r in rows:
            r[i] = repr(float(r[i]) + shift)
    p.write_rows(p.images, header, rows)


def _pixels_top_left(p: Project) -> None:
    p.map_column(p.images, "x", lambda v: repr(float(v) / 0.005 + 23000.0))
    p.map_column(p.images, "y", lambda v: repr(-float(v) / 0.005 + 23000.0))
    p.map_column(p.images, "sigma", _scale(200.0))


def _toml_line(old: str, new: str) -> Callable[[Project], None]:
    return lambda p: p.edit_toml(old, new)


# ----------------------------------------------------------------------------- the camera


def _without_table(text: str, name: str) -> str:
    """``text`` without the table ``[name]`` (its header and keys)."""
    return re.sub(rf"^\[{name}\]\n(?:[^\[\n].*\n|\n)*", "", text, count=1, flags=re.M)


def _adjustment(lines: str) -> Callable[[Project], None]:
    """Keys added to [adjustment] (the table added when the project has none)."""

    def apply(p: Project) -> None:
        text = p.toml.read_text("utf-8")
        if re.search(r"^\[adjustment\]\n", text, re.M) is None:
            text += "\n[adjustment]\n"
        p.toml.write_text(text.replace("[adjustment]\n", f"[adjustment]\n{lines}\n", 1), "utf-8")

    return apply


def _bundle(choice: str) -> Callable[[Project], None]:
    return _adjustment(f'refine = "bundle"\nself_calibration = {choice}')


def _camera_keys(lines: str) -> Callable[[Project], None]:
    """Keys set in [camera] (in place of the project's own of the same name)."""

    def apply(p: Project) -> None:
        text = p.toml.read_text("utf-8")
        table = re.search(r"^\[camera\]\n(?:[^\[\n].*\n|\n)*", text, re.M)
        if table is None:
            raise ValueError(f"{p.toml}: no [camera] table")
        body = table.group()
        for key in re.findall(r"^(\w+)\s*=", lines, re.M):
            body = re.sub(rf"^{key}\s*=.*\n", "", body, flags=re.M)
        body = body.replace("[camera]\n", f"[camera]\n{lines}\n", 1)
        p.toml.write_text(text[: table.start()] + body + text[table.end() :], encoding="utf-8")

    return apply


def _image_reach(p: Project) -> tuple[float, float]:
    """The largest |x| and the largest distance of the image points from the origin (mm)."""
    header, rows = p.rows(p.images)
    ix, iy = header.index("x"), header.index("y")
    x = [float(r[ix]) for r in rows]
    y = [float(r[iy]) for r in rows]
    return max(map(abs, x)), max(a * a + b * b for a, b in zip(x, y, strict=True)) ** 0.5


def _k1(p: Project) -> float:
    """A plausible k1 (mm^-2) of the project's camera: 20 um at its farthest point."""
    return -0.020 / _image_reach(p)[1] ** 3


def _distortion(table: Callable[[Project], str]) -> Callable[[Project], None]:
    """A [distortion] table (its lines from the project) before [images], in
    place of the project's own."""

    def apply(p: Project) -> None:
        lines = table(p)
        text = _without_table(p.toml.read_text("utf-8"), "distortion")
        text = text.replace("[images]\n", f"[distortion]\n{lines}\n\n[images]\n", 1)
        p.toml.write_text(text, encoding="utf-8")

    return apply


def _principal_point_beyond_the_format(p: Project) -> None:
    """x0 beyond the farthest image point along the flight (x)."""
    _camera_keys(f"principal_point_mm = [{1.3 * _image_reach(p)[0]!r}, 0.0]")(p)


def _c(p: Project) -> float:
    match = re.search(r"principal_distance_mm\s*=\s*([0-9.eE+-]+)", p.toml.read_text("utf-8"))
    if match is None:
        raise ValueError("no principal_distance_mm")
    return float(match.group(1))


def _camera_toml(p: Project, camera: str, distortion: str, replace: bool = True) -> None:
    """A self-calibration's camera.toml pasted in place of [camera] (``replace``)
    or added after the project's own."""
    text = p.toml.read_text("utf-8")
    if replace:
        text = _without_table(_without_table(text, "camera"), "distortion")
    pasted = (
        "# The camera adjusted by the bundle's self-calibration; paste these tables\n"
        f"[camera]\n{camera}\n\n[distortion]\n{distortion}\n"
    )
    p.toml.write_text(text + "\n" + pasted, encoding="utf-8")


def _pasted(
    camera: str = "c",
    distortion: str = 'units = "mm"\nmodel = "correction"\nk1 = K1',
    replace: bool = True,
) -> Callable[[Project], None]:
    """camera.toml's tables with the project's c (``c``) and a plausible k1 (``K1``)."""

    def apply(p: Project) -> None:
        cam = camera.replace("c", f"principal_distance_mm = {_c(p)!r}", 1) if camera else ""
        cam = cam.replace("PP", "principal_point_mm = [0.0012, -0.0021]")
        _camera_toml(p, cam, distortion.replace("K1", repr(_k1(p))), replace)

    return apply


MUTATIONS: tuple[Mutation, ...] = (
    # columns
    Mutation("images: column x missing", FAIL, _drop_column("images", "x"), (("column(s) x",),)),
    Mutation("images: column point missing", FAIL, _drop_column("images", "point"), (("point",),)),
    Mutation("control: column type missing", FAIL, _drop_column("control", "type"), (("type",),)),
    Mutation("control: column H missing", FAIL, _drop_column("control", "H"), (("column(s) H",),)),
    Mutation("images: an extra column", FAIL, _extra_column("images"), (("note",),)),
    Mutation("control: an extra column", FAIL, _extra_column("control"), (("note",),)),
    # types, NaN, infinity, huge values
    Mutation("images: x is text", FAIL, _cell("images", "x", "4x6.2"), (("4x6.2",), (":5",))),
    Mutation("control: H is text", FAIL, _cell("control", "H", "abc"), (("abc",), (":5",))),
    Mutation("images: x is nan", FAIL, _cell("images", "x", "nan"), ((":5",),)),
    Mutation("images: y is inf", FAIL, _cell("images", "y", "inf"), ((":5",),)),
    Mutation("control: X is -inf", FAIL, _cell("control", "X", "-inf"), ((":5",),)),
    Mutation("control: Y is nan", FAIL, _cell("control", "Y", "NaN"), ((":5",),)),
    Mutation("images: x is 1e300", FAIL, _cell("images", "x", "1e300"), ()),
    Mutation("images: sigma is 1e300", FAIL, _cell("images", "sigma", "1e300"), ()),
    Mutation("control: X is 1e300", FAIL, _cell("control", "X", "1e300"), ()),
    Mutation("control: H is 1e7", FAIL, _cell("control", "H", "1e7"), ()),
    Mutation("images: photo id is a float", FAIL, _cell("images", "photo", "1001.0"), ()),
    Mutation("control: type is FULL", EITHER, _cell("control", "type", "FULL"), ()),
    Mutation("control: type is 'ful'", FAIL, _cell("control", "type", "ful"), (("ful",),)),
    # duplicates
    Mutation("images: a row twice", FAIL, _duplicate_row("images"), ()),
    Mutation("images: a photo/point twice, other x", FAIL, _duplicate_row("images", "x"), ()),
    Mutation("control: a point twice", FAIL, _duplicate_row("control"), ()),
    Mutation("control: a point twice, other X", FAIL, _duplicate_row("control", "X"), ()),
    Mutation("strip.toml: a photo listed twice", FAIL, _duplicate_photo_in_list, ()),
    # empty files
    Mutation("images: empty file", FAIL, _bytes("images", lambda b: b""), (("image",),)),
    Mutation("control: empty file", FAIL, _bytes("control", lambda b: b""), (("control",),)),
    Mutation("strip.toml: empty file", FAIL, _bytes("toml", lambda b: b""), (("strip.toml",),)),
    Mutation("images: header only", FAIL, _bytes("images", lambda b: b.split(b"\n")[0] + b"\n")),
    Mutation("control: header only", FAIL, _bytes("control", lambda b: b.split(b"\n")[0] + b"\n")),
    Mutation("images: whitespace only", FAIL, _bytes("images", lambda b: b"  \n\n \n")),
    # encodings, line ends, separators
    Mutation("images: UTF-8 BOM", OK, _bytes("images", lambda b: b"\xef\xbb\xbf" + b)),
    Mutation("control: UTF-8 BOM", OK, _bytes("control", lambda b: b"\xef\xbb\xbf" + b)),
    Mutation("strip.toml: UTF-8 BOM", OK, _bytes("toml", lambda b: b"\xef\xbb\xbf" + b)),
    Mutation("images: CRLF", OK, _bytes("images", lambda b: b.replace(b"\n", b"\r\n"))),
    Mutation("control: CRLF", OK, _bytes("control", lambda b: b.replace(b"\n", b"\r\n"))),
    Mutation("strip.toml: CRLF", OK, _bytes("toml", lambda b: b.replace(b"\n", b"\r\n"))),
    Mutation(
        "images: CR only (old Mac)", EITHER, _bytes("images", lambda b: b.replace(b"\n", b"\r"))
    ),
    Mutation(
        "both CSVs: BOM and CRLF",
        OK,
        lambda p: (
            [
                path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes().replace(b"\n", b"\r\n"))
                for path in (p.images, p.control)
            ]
            and None
        ),
    ),
    Mutation("CSVs: semicolons", FAIL, _semicolons(False), ((";", "semicolon"),)),
    Mutation("CSVs: semicolons, decimal commas", FAIL, _semicolons(True), ((";", "semicolon"),)),
    Mutation("images: quoted decimal commas", FAIL, _quoted_decimal_comma, ((",",),)),
    Mutation("images: tab-separated", FAIL, _tabs, (("image_points.csv",),)),
    Mutation(
        "images: Latin-1 with a non-ASCII id",
        FAIL,
        _encode("images", "latin-1", True),
        (("UTF-8", "utf-8"),),
    ),
    Mutation("images: UTF-16", FAIL, _encode("images", "utf-16", False), (("UTF-8", "utf-8"),)),
    Mutation("control: UTF-16", FAIL, _encode("control", "utf-16", False), (("UTF-8", "utf-8"),)),
    # units and axes
    Mutation(
        "images: x, y in metres",
        FAIL,
        lambda p: [p.map_column(p.images, c, _scale(1e-3)) for c in ("x", "y", "sigma")] and None,
    ),
    Mutation(
        "images: x, y in micrometres",
        FAIL,
        lambda p: [p.map_column(p.images, c, _scale(1e3)) for c in ("x", "y", "sigma")] and None,
    ),
    Mutation(
        "images: x, y in pixels of 5 um",
        FAIL,
        lambda p: [p.map_column(p.images, c, _scale(200.0)) for c in ("x", "y", "sigma")] and None,
    ),
    Mutation(
        "images: y only in pixels", FAIL, lambda p: p.map_column(p.images, "y", _scale(200.0))
    ),
    Mutation("images: x and y swapped", FAIL, _swap_columns("images", "x", "y")),
    Mutation(
        "images: x reversed (flown the other way)",
        FAIL,
        lambda p: p.map_column(p.images, "x", lambda v: repr(-float(v))),
    ),
    Mutation(
        "camera: c in metres", FAIL, lambda p: _set_c(p, 1e-3), (("principal_distance_mm",),)
    ),
    Mutation(
        "camera: c in micrometres", FAIL, lambda p: _set_c(p, 1e3), (("principal_distance_mm",),)
    ),
    Mutation("control: X, Y swapped", FAIL, _swap_columns("control", "X", "Y")),
    Mutation(
        "control: X, Y in km",
        FAIL,
        lambda p: [p.map_column(p.control, c, _scale(1e-3)) for c in ("X", "Y")] and None,
    ),
    Mutation("control: heights in feet", FAIL, _heights_in_feet, (("control",), ("feet",))),
    Mutation(
        "control: heights in US survey feet",
        FAIL,
        lambda p: p.map_column(p.control, "H", _scale(3937 / 1200)),
        (("control",), ("feet",)),
    ),
    Mutation(
        "control: heights in decimetres",
        FAIL,
        lambda p: p.map_column(p.control, "H", _scale(10.0)),
        # the FC300X block's relief (0.37 of the flying height) so changed
        # stops first on the heights' span on a photo, "in H's unit"
        (("control",), ("decimetres", "H's unit")),
    ),
    # X, Y in feet with H in metres: the ratio of the heights' gradient over
    # the strip to the plan's (ground/height_units.py) names it; under a UTM
    # CRS the coordinates so changed leave its area of use first
    Mutation(
        "control: X, Y in feet, H in metres",
        FAIL,
        lambda p: [p.map_column(p.control, c, _scale(1 / 0.3048)) for c in ("X", "Y")] and None,
        (("control",), ("feet", "implausible coordinates")),
    ),
    Mutation(
        "control: X, Y in decimetres, H in metres",
        FAIL,
        lambda p: [p.map_column(p.control, c, _scale(10.0)) for c in ("X", "Y")] and None,
        (("control",), ("decimetres", "implausible coordinates")),
    ),
    Mutation("control: H and X swapped", FAIL, _swap_columns("control", "X", "H")),
    # photos and points
    Mutation("strip.toml: photos reversed", FAIL, _reorder_photos("reversed"), (("photo",),)),
    Mutation(
        "strip.toml: two photos swapped",
        FAIL,
        _reorder_photos("two swapped"),
        (("photo", "pair"),),
    ),
    Mutation(
        "strip.toml: photos shuffled", FAIL, _reorder_photos("shuffled"), (("photo", "pair"),)
    ),
    Mutation(
        "images: a middle photo has no points",
        FAIL,
        _photo_without_points("middle"),
        (("photo",),),
    ),
    Mutation(
        "images: the last photo has no points", FAIL, _photo_without_points("last"), (("photo",),)
    ),
    Mutation("images: a photo not in strip.toml", FAIL, _photo_not_listed, (("photo",),)),
    Mutation("images: a tie point on one photo only", OK, _point_on_one_photo),
    Mutation("images: a new point on one photo only", OK, _new_point_on_one_photo),
    Mutation("ids: a Unicode tie point", OK, _unicode("point")),
    Mutation("ids: a Unicode control point", OK, _unicode("control point")),
    Mutation("ids: a Unicode photo", OK, _unicode("photo")),
    Mutation("ids: a photo in NFC and NFD", FAIL, _unicode("nfd"), (("Unicode form",),)),
    Mutation(
        "ids: control ids lost their zeros",
        FAIL,
        lambda p: _numeric_points(p, False),
        (("did you mean '0",),),
    ),
    Mutation("ids: numeric point ids", OK, lambda p: _numeric_points(p, True)),
    Mutation("ids: photo ids lost their zeros", FAIL, _photo_zeros, (("did you mean '0001'",),)),
    # layout of the CSV
    Mutation("images: a trailing comma on every line", FAIL, _trailing_comma),
    Mutation("images: the header again mid-file", FAIL, _header_again, (("image_points.csv:",),)),
    Mutation(
        "images: a row with a field missing", FAIL, _field_missing, (("image_points.csv:7",),)
    ),
    Mutation("images: header in capitals", OK, lambda p: _header(p, str.upper)),
    Mutation(
        "images: header with units",
        FAIL,
        lambda p: _header(p, lambda c: f"{c}_mm" if c in ("x", "y") else c),
        (("x_mm",),),
    ),
    Mutation("images: spaces around fields", OK, _spaces),
    Mutation("images: rows in reverse order", OK, _rows_reversed),
    Mutation("images: from the film corner", FAIL, _from_the_corner),
    Mutation("images: from the format corner", FAIL, _from_the_format_corner, (("not centred",),)),
    Mutation("images: pixels from the top left", FAIL, _pixels_top_left),
    # strip.toml and the control
    Mutation(
        "strip.toml: photos as numbers",
        FAIL,
        _photos_as_numbers,
        (("photos", "cannot start with 0", "must be in quotes"),),
    ),
    Mutation(
        "strip.toml: c as a string", FAIL, lambda p: _set_c_text(p), (("principal_distance_mm",),)
    ),
    Mutation("strip.toml: crs missing", FAIL, lambda p: _drop_crs(p), (("crs",),)),
    Mutation(
        "strip.toml: crs EPSG:4326 for projected X, Y", FAIL, lambda p: _set_crs(p, "EPSG:4326")
    ),
    Mutation("strip.toml: crs of another country", EITHER, lambda p: _set_crs(p, "EPSG:2193")),
    Mutation("strip.toml: crs local", EITHER, lambda p: _set_crs(p, "local")),
    Mutation("control: every point a check point", FAIL, lambda p: _control_types(p, "check")),
    Mutation("control: two full points only", FAIL, lambda p: _control_types(p, "check", 2)),
    Mutation("control: sigma_xy 0", FAIL, _cell("control", "sigma_xy", "0"), (("sigma_xy",),)),
    # the camera: [camera]
    Mutation("camera: c negative", FAIL, lambda p: _set_c(p, -1.0), (("principal_distance_mm",),)),
    Mutation(
        "camera: c in pixels of 2.4 um",
        FAIL,
        lambda p: _set_c(p, 1 / 0.0024),
        (("principal_distance_mm",), ("pixels",)),
    ),
    Mutation(
        "camera: principal point beyond the format",
        FAIL,
        _principal_point_beyond_the_format,
        (("principal_point_mm",),),
    ),
    Mutation(
        "camera: principal point in pixels",
        FAIL,
        _camera_keys("principal_point_mm = [2736.0, 1824.0]"),
        (("principal_point_mm",), ("pixels",)),
    ),
    Mutation(
        "camera: principal point of 0.3 mm", OK, _camera_keys("principal_point_mm = [0.3, -0.2]")
    ),
    Mutation(
        "camera: principal point with one number",
        FAIL,
        _camera_keys("principal_point_mm = [0.01]"),
        (("principal_point_mm",),),
    ),
    Mutation(
        "camera: principal point as a table",
        FAIL,
        _camera_keys("principal_point_mm = { x = 0.0, y = 0.0 }"),
        (("principal_point_mm",),),
    ),
    Mutation(
        "camera: focal_length_mm as well",
        FAIL,
        _camera_keys("focal_length_mm = 8.8"),
        (("focal_length_mm",),),
    ),
    Mutation(
        "camera: self_calibration in [camera]",
        FAIL,
        _camera_keys('self_calibration = "auto"'),
        (("self_calibration",),),
    ),
    Mutation(
        "camera: the table twice",
        FAIL,
        _toml_line("[images]\n", "[camera]\n\n[images]\n"),
        (("[camera]",), ("twice",)),
    ),
    # [distortion]
    Mutation("distortion: a plausible k1", OK, _distortion(lambda p: f"k1 = {_k1(p)!r}")),
    Mutation(
        "distortion: k1 of the wrong sign", EITHER, _distortion(lambda p: f"k1 = {-_k1(p)!r}")
    ),
    Mutation(
        "distortion: k1 1e6 times too large",
        FAIL,
        _distortion(lambda p: f"k1 = {1e6 * _k1(p)!r}"),
        (("[distortion]",), ("k1 =",)),
    ),
    Mutation(
        "distortion: k1 1e6 times too large, other sign",
        FAIL,
        _distortion(lambda p: f"k1 = {-1e6 * _k1(p)!r}"),
        (("[distortion]",), ("k1 =",)),
    ),
    Mutation(
        "distortion: projection k1 1e6 times too large",
        FAIL,
        _distortion(lambda p: f'model = "projection"\nk1 = {1e6 * _k1(p)!r}'),
        (("[distortion]",),),
    ),
    Mutation(
        "distortion: normalized k1 read as mm",
        EITHER,  # the drone: 20 % at the corner
        _distortion(lambda p: f"k1 = {_k1(p) * _c(p) ** 2!r}"),
    ),
    Mutation(
        "distortion: units pixel",
        FAIL,
        _distortion(lambda p: 'units = "pixel"\nk1 = 1e-9'),
        (("units",), ("pixel",)),
    ),
    Mutation("distortion: units px", FAIL, _distortion(lambda p: 'units = "px"'), (("units",),)),
    Mutation("distortion: k4", FAIL, _distortion(lambda p: "k4 = 1e-9"), (("k4",),)),
    Mutation("distortion: K1 in capitals", FAIL, _distortion(lambda p: "K1 = 1e-9"), (("K1",),)),
    Mutation("distortion: k1 as a string", FAIL, _distortion(lambda p: 'k1 = "1e-9"'), (("k1",),)),
    Mutation("distortion: k1 nan", FAIL, _distortion(lambda p: "k1 = nan"), (("k1",),)),
    Mutation("distortion: an empty table", OK, _distortion(lambda p: "")),
    Mutation(
        "distortion: affinity in percent",
        FAIL,
        _distortion(lambda p: "b1 = 0.5"),
        (("b1",), ("affinity",)),
    ),
    # [adjustment] self_calibration
    Mutation("self_calibration: auto", OK, _bundle('"auto"')),
    Mutation("self_calibration: a list", OK, _bundle('["k1", "b1"]')),
    Mutation("self_calibration: ebner12", EITHER, _bundle('"ebner12"')),  # the drone: a film model
    Mutation(
        "self_calibration: auto without refine",
        FAIL,
        _adjustment('self_calibration = "auto"'),
        (("self_calibration",), ('refine = "bundle"',)),
    ),
    Mutation("self_calibration: unknown name", FAIL, _bundle('["k1", "k4"]'), (("'k4'",),)),
    Mutation(
        "self_calibration: unknown choice", FAIL, _bundle('"everything"'), (("self_calibration",),)
    ),
    Mutation("self_calibration: ebner misspelt", FAIL, _bundle('"ebner"'), (('"ebner12"?',),)),
    Mutation("self_calibration: a name twice", FAIL, _bundle('["k1", "k1"]'), (("twice",),)),
    Mutation("self_calibration: an empty list", FAIL, _bundle("[]"), (("an empty list",),)),
    Mutation("self_calibration: a bare name", FAIL, _bundle('"k1"'), (('["k1"]',),)),
    Mutation("self_calibration: a number in the list", FAIL, _bundle('["k1", 2]'), (("item 2",),)),
    Mutation("self_calibration: true", FAIL, _bundle("true"), (("self_calibration",),)),
    Mutation(
        "self_calibration: auto, refine none",
        FAIL,
        _adjustment('refine = "none"\nself_calibration = "auto"'),
        (('refine = "bundle"',),),
    ),
    # a self-calibration's camera.toml in the next project
    Mutation("camera.toml: pasted in place", OK, _pasted("c\nPP")),
    Mutation(
        "camera.toml: added, [camera] kept",
        FAIL,
        _pasted("c\nPP", replace=False),
        (("camera.toml",), ("twice",)),
    ),
    Mutation(
        "camera.toml: principal_distance_mm missing",
        FAIL,
        _pasted("PP"),
        (("principal_distance_mm",),),
    ),
    Mutation("camera.toml: [distortion] without units, model", OK, _pasted("c", "k1 = K1")),
    Mutation(
        "camera.toml: an extra key",
        FAIL,
        _pasted("c", "k1 = K1\ndistortion_fit_rms_um = 1e-14"),
        (("distortion_fit_rms_um",),),
    ),
    Mutation(
        "camera.toml: the report's camera keys",
        FAIL,
        _pasted("c\ndistortion = { k1 = 0.0 }"),
        (("distortion",),),
    ),
)


def _set_c_text(p: Project) -> None:
    text = p.toml.read_text("utf-8")
    text = re.sub(
        r"principal_distance_mm\s*=\s*([0-9.eE+-]+)", r'principal_distance_mm = "\1"', text
    )
    p.toml.write_text(text, encoding="utf-8")


def _drop_crs(p: Project) -> None:
    text = re.sub(r"^crs\s*=.*\n", "", p.toml.read_text("utf-8"), flags=re.M)
    p.toml.write_text(text, encoding="utf-8")


def _set_crs(p: Project, crs: str) -> None:
    text = re.sub(r"^crs\s*=.*$", f'crs = "{crs}"', p.toml.read_text("utf-8"), flags=re.M)
    p.toml.write_text(text, encoding="utf-8")


def _set_c(p: Project, factor: float) -> None:
    text = p.toml.read_text("utf-8")
    match = re.search(r"principal_distance_mm\s*=\s*([0-9.eE+-]+)", text)
    if match is None:
        raise ValueError("no principal_distance_mm")
    new = f"principal_distance_mm = {float(match.group(1)) * factor!r}"
    p.toml.write_text(text.replace(match.group(0), new, 1), encoding="utf-8")


# ----------------------------------------------------------------------------- the oracle


def snapshot(folder: Path) -> dict[str, str]:
    """Every file below ``folder`` with a digest of its bytes (folders too)."""
    out: dict[str, str] = {}
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder).as_posix()
        out[rel] = hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "<dir>"
    return out


@dataclass(frozen=True)
class Answer:
    code: int
    stderr: str


def judge(mutation: Mutation, command: str, answer: Answer, before: dict[str, str],
          after: dict[str, str], out_dir: str) -> list[str]:  # fmt: skip
    """The rules an answer breaks (empty when it keeps them all)."""
    broken: list[str] = []
    lines = [ln for ln in answer.stderr.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("stripaero: error: ")]
    other = [
        ln for ln in lines if not ln.startswith(("stripaero: error: ", "stripaero: warning: "))
    ]
    if "Traceback" in answer.stderr:
        broken.append("a traceback")
    if other:
        broken.append(f"stray stderr lines: {other[:2]}")
    if answer.code not in (0, 1):
        broken.append(f"exit code {answer.code}")
    wanted = {FAIL: (1,), OK: (0,), EITHER: (0, 1)}[mutation.expect]
    if answer.code not in wanted:
        broken.append(f"exit {answer.code}, expected {mutation.expect}")
    if answer.code == 1:
        if not errors or (command == "run" and len(errors) != 1):
            broken.append(f"{len(errors)} error lines")
        if any(e.startswith("stripaero: error: unexpected ") for e in errors):
            broken.append("the generic 'unexpected' error")
        if any(len(e) >= 500 for e in errors):
            broken.append("an error line of 500 characters or more")
        text = " ".join(errors)
        broken += [
            f"the error does not name {' or '.join(group)}"
            for group in mutation.words
            if not any(w in text for w in group)
        ]
    inputs = {k: v for k, v in before.items() if not k.startswith(out_dir)}
    if any(after.get(k) != v for k, v in inputs.items()):
        broken.append("an input file changed")
    stray = [k for k in after if k not in before and not k.startswith(out_dir)]
    if stray:
        broken.append(f"stray files {stray[:3]}")
    outputs = {k: v for k, v in before.items() if k.startswith(out_dir)}
    if answer.code != 0 or command == "check":
        if {k: v for k, v in after.items() if k.startswith(out_dir)} != outputs:
            broken.append("the result folder changed")
    elif not all(f"{out_dir}/{n}" in after for n in ("points.csv", "photos.csv", "report.json")):
        broken.append("an incomplete result")
    return broken


Runner = Callable[[list[str]], Answer]


def subprocess_runner(args: list[str]) -> Answer:
    proc = subprocess.run(
        [sys.executable, "-m", "strip_aerotri", *args],
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    return Answer(proc.returncode, proc.stderr)


def fuzz_one(source: Path, mutation: Mutation, work: Path, run: Runner,
             earlier: Path | None = None) -> dict[str, list[str]]:  # fmt: skip
    """Apply ``mutation`` to a copy of ``source`` in ``work`` and run check and run.

    ``earlier`` is a previous result folder copied in as ``out`` first (a failed
    run must leave it as it was).  Returns the broken rules per command.
    """
    folder = work / "project"
    if folder.exists():
        shutil.rmtree(folder)
    shutil.copytree(source, folder, ignore=shutil.ignore_patterns("out", "out*", "README.md"))
    if earlier is not None:
        shutil.copytree(earlier, folder / "out")
    mutation.apply(Project(folder))
    results: dict[str, list[str]] = {}
    for command in ("check", "run"):
        before = snapshot(folder)
        answer = run([command, str(folder / "strip.toml"), "--out", str(folder / "out")])
        results[command] = judge(mutation, command, answer, before, snapshot(folder), "out")
        if answer.code == 1:
            results[command + " said"] = [answer.stderr.strip().splitlines()[-1][:300]]
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("projects", nargs="*", type=Path, default=list(EXAMPLES))
    parser.add_argument("-k", action="append", default=[], help="run the mutations naming this")
    parser.add_argument("--said", action="store_true", help="print each error line too")
    args = parser.parse_args(argv)
    chosen = [m for m in MUTATIONS if not args.k or any(k in m.name for k in args.k)]
    failures = 0
    with tempfile.TemporaryDirectory(prefix="fuzz-inputs-") as tmp:
        for source in args.projects:
            earlier = Path(tmp) / f"earlier-{source.name}"
            base = subprocess_runner(
                ["-qq", "run", str(source / "strip.toml"), "--out", str(earlier)]
            )
            if base.code != 0:
                print(f"{source}: the unmutated project fails: {base.stderr.strip()}")
                return 1
            for mutation in chosen:
                results = fuzz_one(source, mutation, Path(tmp), subprocess_runner, earlier)
                for command in ("check", "run"):
                    broken = results[command]
                    failures += bool(broken)
                    verdict = "BROKEN: " + "; ".join(broken) if broken else "ok"
                    print(f"{source.name:15} {mutation.name:42} {command:5} {verdict}")
                    if args.said and command + " said" in results:
                        print(f"{'':64}{results[command + ' said'][0]}")
                sys.stdout.flush()
    print(f"{failures} broken answer(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
