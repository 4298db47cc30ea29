"""Seeded mutations of whole projects, run through ``stripaero check`` and
``stripaero run``: whatever the input, the program answers in words.

Three projects of 12 photos each (a film strip, a drone strip, a block of
three drone strips) are simulated and run once, so that each has an earlier
result folder.  Every case copies one of them, applies one to three
mutations drawn from a seeded generator (TOML values, keys, lines and
nesting; CSV cells, rows, columns, encodings; files replaced by folders,
links or nothing) and asserts that:

* the exit code is 0, 1 or 2, and nothing prints a traceback;
* a failed run prints exactly one stderr line, ``stripaero: error: ...``,
  not the generic "unexpected" form, under 500 characters (``check`` prints
  one such line per problem);
* a failed run leaves the earlier result folder byte-identical;
* a run that succeeds writes no NaN or infinity, and no run succeeds on
  data that cannot give a result (a photo's points on one line, control
  with X and Y swapped, a control coordinate at 1e308 or thousands of
  kilometres away);
* no command takes more than 30 s.

The cases run in-process (click's CliRunner); a few that could block a
process (a named pipe, a device) run in a subprocess with a timeout.  The
number of cases is bounded for CI (``STRIPAERO_FUZZ_CASES``, default 90:
about half a minute); more cases, or another ``STRIPAERO_FUZZ_SEED``, search
further.
"""

from __future__ import annotations

import json
import os
import random
import re
import shutil
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from click.testing import CliRunner

from _cli_process import cli_subprocess
from strip_aerotri.cli.main import cli

N_CASES = int(os.environ.get("STRIPAERO_FUZZ_CASES", "90"))
SEED = int(os.environ.get("STRIPAERO_FUZZ_SEED", "20261128"))
MAX_SECONDS = 30.0
MAX_LINE_CHARS = 500

PROJECTS = {
    "film": ["film", "--photos", "12", "--seed", "1"],
    "drone": ["drone", "--photos", "12", "--seed", "2"],
    "block": ["drone", "--strips", "3", "--photos", "4", "--seed", "3"],
}
FILES = ("strip.toml", "image_points.csv", "control.csv")
#: A file in a case's folder (ignored by stripaero) listing why its run must fail.
MUST_FAIL = "must-fail.txt"
SWAPPED = "control X and Y swapped (mirrored)"

# --------------------------------------------------------------------------- mutations

TOML_VALUES = [
    "0", "-1", "3", "1.5", "1e308", "-1e308", "5e-324", "1e-320", "1.2e29", "nan", "inf",
    "-inf", "99999999999999999999", "true", '""', '" "', '"x"', '"auto"', '"\\u0000"',
    '"\\u001b[31m"', "[]", "{}", "[1, 2]", '["1"]', '"EPSG:4326"', '"local"', '"EPSG:99999"',
    "2024-01-01", '"' + "n" * 5000 + '"',
]  # fmt: skip
CSV_VALUES = [
    "", " ", "nan", "inf", "-inf", "1e308", "-1e308", "1e-320", "1.2e29", "0", "-0", "abc",
    '"', '""', "1,5", "\x00", "\x1b[31m", "3.000", "1e5", "-1e5", "9" * 400, "P" * 10_000,
    "full", "plan", "height", "check", "1001", "P0001",
]  # fmt: skip
_KEY_LINE = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)[ \t]*=[ \t]*(.+)$", re.MULTILINE)

Mutation = Callable[[random.Random, Path], None]


def _text(path: Path) -> str:
    return path.read_bytes().decode("utf-8", errors="replace")


def _put(path: Path, text: str) -> None:
    path.write_bytes(text.encode("utf-8", errors="surrogatepass"))


def toml_value(rng: random.Random, folder: Path) -> None:
    """A key's value replaced by a value of another kind or range."""
    path = folder / "strip.toml"
    text = _text(path)
    lines = list(_KEY_LINE.finditer(text))
    if lines:
        m = rng.choice(lines)
        _put(path, text[: m.start(2)] + rng.choice(TOML_VALUES) + text[m.end(2) :])


def toml_new_key(rng: random.Random, folder: Path) -> None:
    """A key added to a table (known keys of other tables, typos, numbers)."""
    path = folder / "strip.toml"
    text = _text(path)
    key = rng.choice(
        ["sigma_mm", "alpha", "map_scale", "polynomial", "refine", "route", "photo_step",
         "sigma_xy_m", "max_fraction", "principal_point_mm", "name", "crs", "directory",
         "units", "flight_direction", "block", "models", "sections", "relative_orientation",
         "foo", "Photos"]
    )  # fmt: skip
    headers = [m.end() for m in re.finditer(r"^\[[^\n]*\]$", text, re.MULTILINE)]
    at = rng.choice(headers) if headers else len(text)
    _put(path, text[:at] + f"\n{key} = {rng.choice(TOML_VALUES)}" + text[at:])


def toml_table(rng: random.Random, folder: Path) -> None:
    """A table added (with keys that need other tables or options)."""
    table = rng.choice(
        [
            "[blunders]\nalpha = " + rng.choice(["5e-324", "0.5", "1", "0.01", "1e-12"]),
            "[blunders]\naction = " + rng.choice(['"report"', '"off"', '"x"']),
            '[adjustment]\nrefine = "bundle"',
            "[adjustment]\npolynomial = " + rng.choice(["0", "1", "2", "3", '"auto"', "4"]),
            "[adjustment]\nphoto_step = " + rng.choice(['"auto"', "2", "3", "0"]),
            '[adjustment]\nmodels = "independent"',
            "[adjustment]\nblock = " + rng.choice(['"strips"', '"models"']),
            "[report]\nmap_scale = " + rng.choice(["500", "1e308", "5e-324", "-1"]),
            "[distortion]\nk1 = " + rng.choice(["1e-5", "1e308", "-1e10"]),
            '[[straight_line]]\npoints = ["P0001", "P0002", "P0003"]',
            '[gnss]\nfile = "control.csv"',
            "[output]\ndirectory = " + rng.choice(['"."', '"out"', '".."', '"control.csv"']),
        ]
    )
    path = folder / "strip.toml"
    text = _text(path)
    header = table.partition("\n")[0]
    if header.startswith("[[") or header not in text:
        text = text + "\n" + table + "\n"
    else:  # into the table the project has already
        text = text.replace(header, table, 1)
    _put(path, text)


def toml_structure(rng: random.Random, folder: Path) -> None:
    """Deep nesting, long dotted keys, a line dropped or doubled, a header swapped."""
    path = folder / "strip.toml"
    text = _text(path)
    lines = text.split("\n")
    kind = rng.randrange(5)
    if kind == 0:
        depth = rng.choice([5, 9, 50, 1000])
        value = rng.choice(["[" * depth + "]" * depth, "{a=" * depth + "1" + "}" * depth])
        text = text + f"\n[report]\nmap_scale = {value}\n"
    elif kind == 1:
        parts = rng.choice([3, 17, 5000])
        text = ".".join(["a"] * parts) + " = 1\n" + text
    elif kind == 2 and lines:
        del lines[rng.randrange(len(lines))]
        text = "\n".join(lines)
    elif kind == 3 and lines:
        i = rng.randrange(len(lines))
        lines.insert(i, lines[i])
        text = "\n".join(lines)
    else:
        headers = re.findall(r"^\[[^\n]*\]$", text, re.MULTILINE)
        if len(headers) >= 2:
            a, b = rng.sample(headers, 2)
            text = text.replace(a, "\0", 1).replace(b, a, 1).replace("\0", b, 1)
    _put(path, text)


def _rows(path: Path) -> list[str]:
    return _text(path).split("\n")


def csv_cell(rng: random.Random, folder: Path) -> None:
    """One cell of a CSV replaced (ids, numbers, types, control characters)."""
    path = folder / rng.choice(FILES[1:])
    rows = _rows(path)
    body = [i for i in range(1, len(rows)) if rows[i].strip()]
    if not body:
        return
    i = rng.choice(body)
    cells = rows[i].split(",")
    cells[rng.randrange(len(cells))] = rng.choice(CSV_VALUES)
    rows[i] = ",".join(cells)
    _put(path, "\n".join(rows))


def csv_rows(rng: random.Random, folder: Path) -> None:
    """Rows dropped, doubled, swapped with the header, or all but a few removed."""
    path = folder / rng.choice(FILES[1:])
    rows = _rows(path)
    kind = rng.randrange(5)
    if len(rows) < 3:
        return
    i = rng.randrange(1, len(rows))
    if kind == 0:
        del rows[i]
    elif kind == 1:
        rows.insert(i, rows[i])
    elif kind == 2:
        rows[0], rows[i] = rows[i], rows[0]
    elif kind == 3:
        rows = rows[: rng.choice([1, 2, 4, 7])]
    else:
        rows.append(rng.choice(["#", ",,,,", "a,b", "\ufeffphoto,point,x,y", "1001,P1,1,2,3,4"]))
    _put(path, "\n".join(rows))


def csv_columns(rng: random.Random, folder: Path) -> None:
    """A column dropped, two header names swapped, a name mistyped."""
    path = folder / rng.choice(FILES[1:])
    rows = _rows(path)
    header = rows[0].split(",")
    kind = rng.randrange(3)
    if kind == 0 and len(header) > 1:
        j = rng.randrange(len(header))
        rows = [
            ",".join(c for k, c in enumerate(r.split(",")) if k != j) if r else r for r in rows
        ]
    elif kind == 1 and len(header) > 1:
        a, b = rng.sample(range(len(header)), 2)
        header[a], header[b] = header[b], header[a]
        rows[0] = ",".join(header)
    else:
        j = rng.randrange(len(header))
        header[j] = header[j] + rng.choice(["s", " ", "\x00", "é"])
        rows[0] = ",".join(header)
    _put(path, "\n".join(rows))


def geometry(rng: random.Random, folder: Path) -> None:
    """Image or ground geometry broken (:func:`_geometry`); a file an earlier
    mutation left without the columns or numbers it needs is left as it is."""
    try:
        _geometry(rng, folder)
    except (ValueError, IndexError, OSError):
        pass


def _geometry(rng: random.Random, folder: Path) -> None:
    """Image or ground geometry broken: one photo's points on a line, a column
    scaled (micrometres for millimetres), a photo's points moved, control
    coordinates swapped or far away."""
    images, control = folder / "image_points.csv", folder / "control.csv"
    kind = rng.randrange(5)
    path = images if kind < 3 else control
    rows = _rows(path)
    header = rows[0].split(",")
    body = [i for i in range(1, len(rows)) if rows[i].strip() and not rows[i].startswith("#")]
    if not body:
        return
    cells = {i: rows[i].split(",") for i in body}
    if kind == 0:  # every point of one photo on a line x = const or y = const
        photo = rng.choice([cells[i][0] for i in body])
        j = header.index(rng.choice(["x", "y"]))
        for i in body:
            if cells[i][0] == photo:
                cells[i][j] = "3.000"
        _must_fail(folder, f"photo {photo}'s points on one line")
    elif kind == 1:  # a coordinate column scaled
        j = header.index(rng.choice(["x", "y"]))
        factor = rng.choice([1000.0, 0.001, -1.0])
        for i in body:
            cells[i][j] = f"{float(cells[i][j]) * factor:.6f}"
        if factor != -1.0:  # a reversed axis with swapped control is a consistent mirror
            _must_fail(folder, f"image {header[j]} times {factor:g}")  # µm or m for mm
    elif kind == 2:  # one photo's points all shifted
        photo = rng.choice([cells[i][0] for i in body])
        for i in body:
            if cells[i][0] == photo:
                cells[i][2] = f"{float(cells[i][2]) + rng.choice([5.0, 50.0, 500.0]):.6f}"
    elif kind == 3:  # X and Y swapped
        for i in body:
            cells[i][1], cells[i][2] = cells[i][2], cells[i][1]
        _must_fail(folder, SWAPPED)  # twice: swapped back
    else:  # one control point far away
        i = rng.choice(body)
        j = rng.choice([1, 2, 3])
        if cells[i][j]:
            cells[i][j] = rng.choice(["1e308", "1e12", "-4e7", "1e5", "0"])
            if cells[i][j] in ("1e308", "1e12", "-4e7"):
                _must_fail(folder, f"control point {cells[i][0]} at {cells[i][j]}")
    for i in body:
        rows[i] = ",".join(cells[i])
    _put(path, "\n".join(rows))


def _must_fail(folder: Path, reason: str) -> None:
    """Mark the case as one that no run may turn into a result (a false
    success); a second swap of X and Y undoes the first, a column scaled
    twice is scaled by the product."""
    path = folder / MUST_FAIL
    reasons = path.read_text("utf-8").splitlines() if path.exists() else []
    scaled = re.fullmatch(r"(image \w+ times )(\S+)", reason)
    before = [r for r in reasons if scaled and r.startswith(scaled.group(1))]
    if reason == SWAPPED and SWAPPED in reasons:
        reasons.remove(SWAPPED)
    elif scaled and before:  # a column scaled again: the product (1: undone)
        reasons.remove(before[0])
        factor = float(scaled.group(2)) * float(before[0].split()[-1])
        if abs(factor - 1.0) > 1e-6:
            reasons.append(f"{scaled.group(1)}{factor:g}")
    else:
        reasons.append(reason)
    path.write_text("".join(f"{r}\n" for r in reasons), encoding="utf-8")


def bytes_level(rng: random.Random, folder: Path) -> None:
    """A file truncated, given random bytes, a BOM, CR line ends or UTF-16."""
    path = folder / rng.choice(FILES)
    data = path.read_bytes()
    kind = rng.randrange(5)
    if kind == 0:
        data = data[: rng.randrange(len(data) + 1)]
    elif kind == 1:
        at = rng.randrange(len(data) + 1)
        data = (
            data[:at] + bytes(rng.randrange(256) for _ in range(rng.randrange(1, 9))) + data[at:]
        )
    elif kind == 2:
        data = b"\xef\xbb\xbf" + data
    elif kind == 3:
        data = data.replace(b"\n", rng.choice([b"\r\n", b"\r"]))
    else:
        data = data.decode("utf-8", errors="replace").encode("utf-16")
    path.write_bytes(data)


def file_system(rng: random.Random, folder: Path) -> None:
    """An input replaced by a folder, an empty file, a link to another input, or removed."""
    name = rng.choice(FILES)
    path = folder / name
    kind = rng.randrange(4)
    if path.is_dir() and not path.is_symlink():
        path.rmdir()
    elif path.exists() or path.is_symlink():
        path.unlink()
    if kind == 0:
        path.mkdir()
    elif kind == 1:
        path.write_bytes(b"")
    elif kind == 2:
        path.symlink_to(rng.choice([n for n in FILES if n != name]))


MUTATIONS: tuple[Mutation, ...] = (
    toml_value,
    toml_value,
    toml_new_key,
    toml_table,
    toml_table,
    toml_structure,
    csv_cell,
    csv_cell,
    csv_rows,
    csv_columns,
    geometry,
    geometry,
    geometry,
    bytes_level,
    file_system,
)


# --------------------------------------------------------------------------- fixtures


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file()
    }


@pytest.fixture(scope="module")
def projects(tmp_path_factory) -> dict[str, Path]:
    """The three projects, each with the result folder of a successful run."""
    root = tmp_path_factory.mktemp("fuzz")
    out = {}
    for name, args in PROJECTS.items():
        folder = root / name
        runner = CliRunner()
        made = runner.invoke(cli, ["simulate", *args, "--out", str(folder), "-q"])
        assert made.exit_code == 0, made.output
        ran = runner.invoke(cli, ["run", str(folder / "strip.toml"), "-q"])
        assert ran.exit_code == 0, ran.output
        out[name] = folder
    return out


@pytest.fixture
def fast_report(monkeypatch):
    """No matplotlib figures (most of a successful run's time)."""
    from strip_aerotri.report import block, outputs

    strip, blk = outputs.build_outputs, block.build_block_outputs
    monkeypatch.setattr(outputs, "build_outputs", lambda r, **kw: strip(r, html=False, **kw))
    if "html" in blk.__code__.co_varnames:
        monkeypatch.setattr(block, "build_block_outputs", lambda r, **kw: blk(r, html=False, **kw))


# --------------------------------------------------------------------------- assertions


def _assert_answer(result, command: str, seconds: float, case: str) -> None:
    where = f"{case}: {command}"
    assert result.exit_code in (0, 1, 2), (where, result.exit_code, repr(result.exception))
    assert "Traceback" not in result.output, (where, result.output[-3000:])
    assert seconds < MAX_SECONDS, (where, seconds)
    if result.exit_code == 0:
        return
    lines = result.stderr.splitlines()
    assert lines, (where, "no error line")
    if result.exit_code == 2:  # click's usage error: not reached by these mutations
        return
    if command == "run":
        assert len(lines) == 1, (where, result.stderr[:3000])
    for line in lines:
        assert line.startswith("stripaero: error: "), (where, line[:600])
        assert not line.startswith("stripaero: error: unexpected "), (where, line[:600])
        assert len(line) < MAX_LINE_CHARS, (where, len(line), line[:600])


def _assert_finite_outputs(folder: Path, case: str) -> None:
    for name in ("points.csv", "photos.csv"):
        text = (folder / name).read_text(encoding="utf-8").lower()
        assert not re.search(r"(^|,)[-+]?(nan|inf)", text, re.MULTILINE), (case, name)

    def refuse(constant: str) -> None:
        raise AssertionError((case, "report.json holds", constant))

    json.loads((folder / "report.json").read_text(encoding="utf-8"), parse_constant=refuse)


# --------------------------------------------------------------------------- the cases


@pytest.mark.parametrize("case", range(N_CASES))
def test_fuzzed_project(case, projects, tmp_path, request):
    rng = random.Random(SEED + case)
    name = list(PROJECTS)[case % len(PROJECTS)]
    folder = tmp_path / name
    shutil.copytree(projects[name], folder, symlinks=True)
    mutations = [rng.choice(MUTATIONS) for _ in range(rng.choice([1, 1, 2, 3]))]
    mutations.sort(key=lambda m: m is file_system)  # the others edit files, not folders
    for mutate in mutations:
        mutate(rng, folder)
    label = f"case {case} ({name}: {', '.join(m.__name__ for m in mutations)})"
    if case % 6:  # every sixth case draws its figures; the others skip them for speed
        request.getfixturevalue("fast_report")
    earlier = _snapshot(folder / "out")
    runner = CliRunner()
    for command in ("check", "run"):
        started = time.perf_counter()
        result = runner.invoke(cli, [command, str(folder / "strip.toml")])
        _assert_answer(result, command, time.perf_counter() - started, label)
    if result.exit_code == 0:
        reasons = (folder / MUST_FAIL).read_text("utf-8") if (folder / MUST_FAIL).exists() else ""
        assert not reasons, (label, "a false success:", reasons)
        _assert_finite_outputs(folder / "out", label)
    else:
        assert _snapshot(folder / "out") == earlier, (label, "the earlier result changed")


# --------------------------------------------------------------------------- in a subprocess


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes and devices are POSIX")
@pytest.mark.parametrize(
    ("name", "kind"),
    [("strip.toml", "fifo"), ("image_points.csv", "device"), ("control.csv", "fifo")],
)
def test_fuzzed_file_kinds_in_a_subprocess(projects, tmp_path, name, kind):
    folder = tmp_path / "p"
    shutil.copytree(projects["block"], folder, symlinks=True)
    earlier = _snapshot(folder / "out")
    (folder / name).unlink()
    if kind == "fifo":
        os.mkfifo(folder / name)
    else:
        (folder / name).symlink_to("/dev/zero")
    for command in ("check", "run"):
        proc = cli_subprocess(command, folder / "strip.toml", timeout=MAX_SECONDS)
        assert proc.returncode == 1, proc.stderr[-2000:]
        (line,) = proc.stderr.splitlines()
        assert line.startswith("stripaero: error: ") and "not a regular file" in line, line
    assert _snapshot(folder / "out") == earlier
