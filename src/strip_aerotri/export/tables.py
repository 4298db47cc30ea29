"""The tables of a finished run, read back for the GIS exports.

:func:`read_results` reads ``points.csv`` and ``photos.csv`` of a result
folder (docs/outputs.md) into :class:`ResultTable` objects: the ids, the
coordinates (X, Y, H of the points; X, Y, Z of the photo centres, in the
project's CRS) and every column as typed values, so that an export carries
whatever the run wrote (role, residuals, counts, angles, strip) without
knowing which columns a strip or a block writes.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._typing import FloatArray
from ..errors import ConfigError

__all__ = ["ResultTable", "Value", "read_results", "read_table"]

#: A cell: a string (ids, roles, names), an integer (counts), a float, or None (empty).
Value = str | int | float | None


@dataclass(frozen=True)
class ResultTable:
    """One table of a result folder.

    Attributes
    ----------
    path : Path
        The CSV file read.
    ids : list of str
        The first column (``point`` or ``photo``), kept as strings.
    xyz : ndarray, shape (N, 3)
        The coordinates in the project's CRS (NaN where empty).
    columns : dict of str to list
        Every column in file order, typed by :func:`read_table` (the id and
        coordinate columns included).
    """

    path: Path
    ids: list[str]
    xyz: FloatArray
    columns: dict[str, list[Value]]

    def row(self, k: int) -> dict[str, Value]:
        """Row ``k`` as a dict of column to value."""
        return {name: values[k] for name, values in self.columns.items()}


#: Columns that hold names, never numbers (leading zeros kept).
TEXT_COLUMNS = frozenset({"point", "photo", "role", "strip"})


def _typed(name: str, cells: list[str]) -> list[Value]:
    """A column's cells as str (names, or any cell not a number), int (every
    cell an integer) or float; an empty cell is None."""
    if name in TEXT_COLUMNS:
        return [c if c != "" else None for c in cells]
    filled = [c for c in cells if c != ""]
    try:
        ints = [int(c) for c in filled]
    except ValueError:
        pass
    else:
        it = iter(ints)
        return [next(it) if c != "" else None for c in cells]
    try:
        floats = [float(c) for c in filled]
    except ValueError:
        return [c if c != "" else None for c in cells]
    it_f = iter(floats)
    typed: list[float | None] = [next(it_f) if c != "" else None for c in cells]
    return [v if v is not None and math.isfinite(v) else None for v in typed]


def read_table(path: Path, key: str, coordinates: tuple[str, str, str]) -> ResultTable:
    """Read one result CSV whose id column is ``key``.

    Raises
    ------
    ConfigError
        The file is missing (the project has not been run) or is not a table
        of ``stripaero run`` (a required column is missing or not a number).
    """
    if not path.is_file():
        raise ConfigError(f"{path}: not found; run the project first (stripaero run)")
    with path.open(encoding="utf-8-sig", newline="") as fh:
        reader = csv.reader(line for line in fh if not line.startswith("#"))
        header = next(reader, None)
        rows = list(reader)
    needed = (key, *coordinates)
    if header is None or any(c not in header for c in needed):
        raise ConfigError(
            f"{path}: not a {path.name} of stripaero run (columns {', '.join(needed)} needed)"
        )
    if any(len(r) != len(header) for r in rows):
        raise ConfigError(f"{path}: rows of unequal length; not a table of stripaero run")
    columns = {name: _typed(name, [r[i] for r in rows]) for i, name in enumerate(header)}
    try:
        xyz = np.array(
            [[np.nan if v is None else float(v) for v in columns[c]] for c in coordinates],
            dtype=np.float64,
        ).T.reshape(-1, 3)
    except (TypeError, ValueError):
        raise ConfigError(
            f"{path}: {', '.join(coordinates)} must be numbers; not a table of stripaero run"
        ) from None
    ids = [str(v) for v in columns[key]]
    return ResultTable(path=path, ids=ids, xyz=xyz, columns=columns)


def read_results(folder: Path) -> tuple[ResultTable, ResultTable]:
    """``points.csv`` (X, Y, H) and ``photos.csv`` (X, Y, Z) of a result folder."""
    points = read_table(folder / "points.csv", "point", ("X", "Y", "H"))
    photos = read_table(folder / "photos.csv", "photo", ("X", "Y", "Z"))
    return points, photos
