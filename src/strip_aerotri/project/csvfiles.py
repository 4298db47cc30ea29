"""The strict CSV reader of the project's tables.

UTF-8 (a BOM allowed), comma-separated, one header line, ``#`` comment lines
and blank lines skipped while keeping every row's line number for errors;
ids stay text (leading zeros kept).
"""

from __future__ import annotations

import csv
import itertools
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._text import clean, shorten
from .._typing import BoolArray, FloatArray, IntArray
from ..errors import ConfigError
from ..options import OptionError, check_range
from .schema import MAX_ID_LENGTH, ColumnSpec, suggest

#: Largest CSV file read (bytes): far above any strip or block's tables (a
#: 10 x 100 drone block's image points are about 8 MB), far below what would
#: exhaust the memory of the machine reading it.
MAX_CSV_BYTES = 512 * 2**20
#: Largest project file read (bytes): a block of a thousand strips of a
#: thousand photos each is under 16 MB.
MAX_TOML_BYTES = 16 * 2**20


def read_bytes(path: Path, what: str, limit: int | None = None) -> bytes:
    """The content of the regular file ``path`` (``what`` names it in messages).

    Anything that is not a regular file (a named pipe, a device such as
    ``/dev/zero``, a socket, a folder) is refused before it is opened: a pipe
    with no writer would block the read forever, a device never ends.  A
    file larger than ``limit`` bytes (default :data:`MAX_CSV_BYTES`) is
    refused too.
    """
    import os
    import stat

    limit = MAX_CSV_BYTES if limit is None else limit
    try:
        info = path.stat()
    except FileNotFoundError:
        raise ConfigError(f"{path}: {what} not found") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        reason = getattr(exc, "strerror", None) or exc
        raise ConfigError(f"{shorten(path, 200)}: cannot read {what}: {reason}") from None
    if stat.S_ISDIR(info.st_mode):
        raise ConfigError(f"{path}: {what} is a folder, not a file")
    if not stat.S_ISREG(info.st_mode):
        kind = (
            "a named pipe (FIFO)"
            if stat.S_ISFIFO(info.st_mode)
            else "a device"
            if stat.S_ISCHR(info.st_mode) or stat.S_ISBLK(info.st_mode)
            else "a socket"
            if stat.S_ISSOCK(info.st_mode)
            else "not a regular file"
        )
        raise ConfigError(
            f"{path}: {what} is {kind}, not a regular file; give the path of the file itself"
        )
    if info.st_size > limit:
        raise ConfigError(
            f"{path}: {what} is {_size(info.st_size)}, larger than the {_size(limit)} a "
            "project's file may have: is it the right file?"
        )
    try:
        # not path.read_bytes(): the file may have been swapped since the stat
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as stream:
            if not stat.S_ISREG(os.fstat(stream.fileno()).st_mode):
                raise ConfigError(f"{path}: {what} is not a regular file")
            data = stream.read(limit + 1)
    except IsADirectoryError:
        raise ConfigError(f"{path}: {what} is a folder, not a file") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read {what}: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise ConfigError(
            f"{path}: {what} is larger than the {_size(limit)} a project's file may have"
        )
    return data


def _size(n_bytes: int) -> str:
    return f"{n_bytes / 2**20:.0f} MB" if n_bytes >= 2**20 else f"{n_bytes} bytes"


def decode(path: Path, data: bytes) -> str:
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ConfigError(
            f"{path}:{line}: not valid UTF-8 (byte 0x{data[exc.start]:02x}); "
            "save the file as UTF-8"
        ) from None


@dataclass
class CsvTable:
    """Columns of a CSV as stripped strings, with the file line of each row."""

    path: Path
    columns: dict[str, Sequence[str]]
    line: IntArray
    header_line: int
    specs: dict[str, ColumnSpec] = field(default_factory=dict)

    @property
    def n_rows(self) -> int:
        return int(self.line.shape[0])

    def where(self, row: int) -> str:
        return f"{self.path}:{int(self.line[row])}"


_SKIPPED_LINE = re.compile(r"\n[ \t\f\v]*(?:#[^\n]*)?(?=\n|\Z)")


def _split_lines(text: str) -> tuple[list[str], IntArray]:
    """Data lines of ``text`` (no comments, no blank lines) and their 1-based numbers."""
    lines = text.split("\n")
    skipped: list[int] = []
    index, position = 0, 0
    text = "\n" + text  # so that every line, the first too, starts after a newline
    for match in _SKIPPED_LINE.finditer(text):
        index += text.count("\n", position, match.start())
        position = match.start()
        skipped.append(index)
    if not skipped:
        return lines, np.arange(1, len(lines) + 1, dtype=np.intp)
    kept: list[str] = []
    start = 0
    for i in skipped:
        kept.extend(lines[start:i])
        start = i + 1
    kept.extend(lines[start:])
    numbers = np.delete(np.arange(1, len(lines) + 1, dtype=np.intp), skipped)
    return kept, numbers


def _split_fields(path: Path, lines: list[str], numbers: IntArray) -> list[list[str]]:
    """Fields of each line by the csv module (quotes allowed, one line per record)."""
    reader = csv.reader(lines, strict=True)
    try:
        rows = list(reader)
        failure = None if len(rows) == len(lines) else "a quoted field is not closed on its line"
    except csv.Error as exc:
        failure = str(exc)
    if failure is None:
        return rows
    # a record may not span lines: the culprit is the first line with an odd number of quotes
    odd = [i for i, item in enumerate(lines) if item.count('"') % 2]
    index = odd[0] if odd else min(max(reader.line_num - 1, 0), len(lines) - 1)
    raise ConfigError(f"{path}:{numbers[index]}: malformed CSV: {failure}")


#: A unit written after a column name: ``x_mm``, ``X [m]``, ``sigma (mm)``.
_UNIT_SUFFIX = re.compile(
    r"[\s_-]*[\[(]?\s*(?:mm|m|um|µm|px|pixels?|deg|degrees|metres?|meters?)\s*[\])]?$",
    re.IGNORECASE,
)


def read_csv(path: Path, columns: Sequence[ColumnSpec], named_by: str) -> CsvTable:
    """Read a comma-separated file into string columns (cells not yet stripped).

    Comment lines (first non-blank character ``#``) and blank lines are
    skipped; UTF-8 with or without BOM; LF or CRLF line ends.  Header names
    are matched case-insensitively against ``columns``; unknown columns are
    an error.
    """
    data = read_bytes(path, f"file named by {named_by}")
    text = decode(path, data)
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    kept, numbers = _split_lines(text)
    if not kept:
        raise ConfigError(f"{path}: no header line (the file is empty or all comments)")
    header_line = int(numbers[0])
    header = [name.strip() for name in _split_fields(path, kept[:1], numbers[:1])[0]]
    if len(header) == 1 and "\t" in header[0]:
        raise ConfigError(
            f"{path}:{header_line}: the header is separated by tabs: the file must be "
            "comma-separated (save it from the spreadsheet as CSV with ',' between columns, "
            "or replace the tabs by commas)"
        )
    if len(header) == 1 and ";" in header[0]:
        raise ConfigError(
            f"{path}:{header_line}: the header '{shorten(header[0])}' is separated by ';': the "
            "file must be comma-separated (a spreadsheet set to a decimal comma writes ';'; "
            "save it as CSV with ',' between columns and '.' as the decimal mark)"
        )
    canonical = {c.name.lower(): c.name for c in columns}
    names: list[str] = []
    for name in header:
        if not name:
            raise ConfigError(f"{path}:{header_line}: empty column name in the header")
        if clean(name) != name:
            raise ConfigError(
                f"{path}:{header_line}: column name '{shorten(name)}' (as read without them) "
                "holds a control character (a NUL byte or a terminal escape sequence); retype "
                "the header"
            )
        if name.lower() not in canonical:
            allowed = ", ".join(c.name for c in columns)
            bare = _UNIT_SUFFIX.sub("", name).lower()
            hint = (
                f" (did you mean '{canonical[bare]}'? the unit is not part of the name: "
                "docs/project-file.md gives each column's)"
                if bare in canonical
                else suggest(name, [c.name for c in columns])
            )
            raise ConfigError(
                f"{path}:{header_line}: unknown column '{shorten(name)}'{hint}; "
                f"allowed columns: {allowed}"
            )
        if canonical[name.lower()] in names:
            raise ConfigError(f"{path}:{header_line}: column '{shorten(name)}' appears twice")
        names.append(canonical[name.lower()])
    missing = [c.name for c in columns if c.required and c.name not in names]
    if missing:
        raise ConfigError(
            f"{path}:{header_line}: missing required column(s) {', '.join(missing)} "
            f"(header is: {shorten(','.join(header), 120)})"
        )
    body = kept[1:]
    line = numbers[1:]
    n_col = len(names)
    if '"' in text:
        rows = _split_fields(path, body, line)
        lengths = np.fromiter(map(len, rows), dtype=np.intp, count=len(rows))
    else:  # fast path without quoting: one split of the whole body
        rows = []
        lengths = 1 + np.fromiter(
            map(str.count, body, itertools.repeat(",")), dtype=np.intp, count=len(body)
        )
    bad = np.flatnonzero(lengths != n_col)
    if bad.size:
        row = int(bad[0])
        hint = " (decimal commas? use a point)" if lengths[row] > n_col else ""
        raise ConfigError(
            f"{path}:{line[row]}: expected {n_col} fields ({','.join(names)}), "
            f"got {lengths[row]}{hint}"
        )
    if rows:
        cells: Sequence[Sequence[str]] = list(zip(*rows, strict=True))
    elif body:
        flat = ",".join(body).split(",")
        cells = [flat[j::n_col] for j in range(n_col)]
    else:
        cells = [[] for _ in names]
    specs = {c.name: c for c in columns}
    return CsvTable(path, dict(zip(names, cells, strict=True)), line, header_line, specs)


def float_column(
    table: CsvTable, name: str, *, allow_empty: bool = False, positive: bool = False
) -> tuple[FloatArray, BoolArray]:
    """Column ``name`` as float64 (NaN where empty) and the mask of empty cells.

    Raises ConfigError naming the line and column of the first value that is
    not a number, not finite, or (``positive``) not > 0, and of the first
    empty cell unless ``allow_empty``.
    """
    strings = table.columns[name]
    n = len(strings)
    empty = np.zeros(n, dtype=bool)
    try:  # fast path: float() accepts surrounding white space, not empty cells
        values = np.asarray(strings, dtype=np.float64).reshape(n)
    except ValueError:
        stripped = [s.strip() for s in strings]
        empty = np.fromiter((not s for s in stripped), dtype=bool, count=n)
        if empty.any() and not allow_empty:
            row = int(np.flatnonzero(empty)[0])
            raise ConfigError(f"{table.where(row)}: column '{name}' is empty") from None
        filled = [s or "nan" for s in stripped]
        try:
            values = np.asarray(filled, dtype=np.float64).reshape(n)
        except ValueError:
            row = next(i for i, s in enumerate(filled) if not _is_float(s))
            comma = _is_float(stripped[row].replace(",", ".", 1))
            hint = " (a decimal comma: use a point, e.g. '12.5')" if comma else ""
            if stripped[row].lower() == name.lower():
                hint = " (the line repeats the header: two files joined? delete the line)"
            raise ConfigError(
                f"{table.where(row)}: column '{name}': expected a number, got "
                f"'{shorten(stripped[row])}'{hint}"
            ) from None
    bad = ~np.isfinite(values) & ~empty
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise ConfigError(
            f"{table.where(row)}: column '{name}': expected a finite number, "
            f"got '{shorten(strings[row].strip())}'"
        )
    if positive:
        bad = (values <= 0.0) & ~empty
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise ConfigError(
                f"{table.where(row)}: column '{name}': expected a positive number, "
                f"got '{shorten(strings[row].strip())}'"
            )
    spec = table.specs.get(name)
    if spec is not None and spec.bounds is not None:
        low, high = spec.bounds
        bad = ((values < low) | (values > high)) & ~empty
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            try:
                check_range(name, float(values[row]), spec.bounds, spec.unit)
            except OptionError as exc:
                raise ConfigError(f"{table.where(row)}: column '{name}': {exc.rule}") from None
    return values, empty


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def id_column(table: CsvTable, name: str) -> np.ndarray:
    """Column ``name`` as a str array with white space stripped; an empty id is an error."""
    strings = table.columns[name]
    # the length and characters first: the array's width is its longest id
    lengths = np.fromiter(map(len, strings), dtype=np.intp, count=len(strings))
    long = np.flatnonzero(lengths > MAX_ID_LENGTH)
    if long.size:
        row = int(long[0])
        raise ConfigError(
            f"{table.where(row)}: column '{name}': an id of {int(lengths[row])} characters "
            f"('{shorten(strings[row], 40)}'); at most {MAX_ID_LENGTH} are allowed"
        )
    # str.strip per cell: a third of np.char.strip's time (6 against 20 ms for
    # 100 000 ids), the array as wide as the cells before stripping, as that gave
    width = max(int(lengths.max(initial=0)), 1)
    arr = np.asarray(list(map(str.strip, strings)), dtype=f"U{width}").reshape(len(strings))
    bad = _control_rows(arr)
    if bad.size:
        row = int(bad[0])
        raise ConfigError(
            f"{table.where(row)}: column '{name}': an id holding a control character (a NUL "
            f"byte or a terminal escape sequence): '{shorten(arr[row])}' as read without them"
        )
    empty = arr == ""
    if empty.any():
        row = int(np.flatnonzero(empty)[0])
        raise ConfigError(f"{table.where(row)}: column '{name}': empty id")
    return arr


def _control_rows(arr: np.ndarray) -> IntArray:
    """Rows of the str array ``arr`` holding a control character (tab included)."""
    if not arr.size:
        return np.zeros(0, dtype=np.intp)
    joined = "".join(arr.tolist())  # one scan of all ids
    if clean(joined) == joined and "\t" not in joined:
        return np.zeros(0, dtype=np.intp)
    return np.flatnonzero([clean(s) != s or "\t" in s for s in arr.tolist()])


def optional_sigma(table: CsvTable, name: str, default: float) -> FloatArray:
    """Positive column ``name`` with ``default`` where absent or empty."""
    if name not in table.columns:
        return np.full(table.n_rows, default)
    values, empty = float_column(table, name, allow_empty=True, positive=True)
    values[empty] = default
    return values
