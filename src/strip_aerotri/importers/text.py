"""Reading the text of a source: its lines as records of fields
(:class:`Rows`), numbers with the line of a bad one, photo ids from file
names.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._typing import FloatArray, IntArray, StrArray
from ..errors import ConfigError
from ..project.csvfiles import decode

__all__ = [
    "Rows",
    "check_unique",
    "line_floats",
    "natural_key",
    "photo_id",
    "pixel_size_mm",
    "read_photo_order",
    "read_text",
    "split_rows",
    "to_floats",
]


def read_text(path: str | Path, what: str) -> str:
    """The text of ``path`` (UTF-8, with or without a BOM).

    Raises
    ------
    ConfigError
        The file is missing, unreadable or not UTF-8; the message names the
        file (and the line of a bad byte) and ``what`` it should hold.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise ConfigError(f"{path}: file not found ({what})") from None
    except IsADirectoryError:
        raise ConfigError(f"{path}: is a folder, expected a file ({what})") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot be read ({what}): {exc.strerror or exc}") from None
    return decode(path, data)


@dataclass(frozen=True)
class Rows:
    """The records of a text file, split into fields, with their line numbers.

    Attributes
    ----------
    path : Path
    lines : ndarray of int, shape (R,)
        1-based line number of each record.
    fields : list of list of str
        The fields of each record.
    """

    path: Path
    lines: IntArray
    fields: list[list[str]]

    def __len__(self) -> int:
        return len(self.fields)

    def where(self, index: int) -> str:
        """``file:line`` of record ``index``, for messages."""
        return f"{self.path}:{int(self.lines[index])}"

    def take(self, index: Sequence[int] | IntArray) -> Rows:
        """The records at ``index``, in that order."""
        idx = np.asarray(index, dtype=np.intp)
        return Rows(self.path, self.lines[idx], [self.fields[i] for i in idx])

    def column(self, k: int) -> StrArray:
        """Field ``k`` of every record (every record must have it)."""
        if not self.fields:
            return np.empty(0, dtype=str)
        return np.array([f[k] for f in self.fields], dtype=str)

    def counts(self) -> IntArray:
        """Number of fields of each record."""
        return np.fromiter((len(f) for f in self.fields), dtype=np.intp, count=len(self.fields))

    def require_fields(self, minimum: int, layout: str) -> None:
        """Raise naming the first record with fewer than ``minimum`` fields."""
        short = np.flatnonzero(self.counts() < minimum)
        if short.size:
            k = int(short[0])
            raise ConfigError(
                f"{self.where(k)}: expected at least {minimum} fields ({layout}), "
                f"got {len(self.fields[k])}"
            )


def split_rows(
    path: str | Path,
    text: str,
    *,
    delimiter: str | None = None,
    comments: tuple[str, ...] = ("#",),
) -> Rows:
    """The non-blank, non-comment lines of ``text`` split into fields.

    ``delimiter=None`` splits on runs of whitespace; any other delimiter
    splits on it and strips the spaces around each field.
    """
    numbers: list[int] = []
    fields: list[list[str]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or (comments and stripped.startswith(comments)):
            continue
        if delimiter is None:
            parts = stripped.split()
        else:
            parts = [part.strip() for part in stripped.split(delimiter)]
        numbers.append(number)
        fields.append(parts)
    return Rows(Path(path), np.asarray(numbers, dtype=np.intp), fields)


def to_floats(values: Sequence[str] | StrArray, rows: Rows, column: str) -> FloatArray:
    """``values`` (one per record of ``rows``) as finite floats.

    Raises
    ------
    ConfigError
        Naming the file, the line and ``column`` of the first value that is
        not a finite number.
    """
    arr = np.asarray(values, dtype=object)
    try:
        out = arr.astype(np.float64)
    except (TypeError, ValueError):
        out = None
    if out is None:  # find the culprit (error path only)
        for k, value in enumerate(arr):
            try:
                float(value)
            except (TypeError, ValueError):
                raise ConfigError(
                    f"{rows.where(k)}: {column}: expected a number, got {str(value)!r}"
                ) from None
        raise AssertionError("unreachable")  # pragma: no cover
    bad = np.flatnonzero(~np.isfinite(out))
    if bad.size:
        k = int(bad[0])
        raise ConfigError(
            f"{rows.where(k)}: {column}: expected a finite number, got {str(arr[k])!r}"
        )
    return out


def check_unique(values: StrArray, rows: Rows, what: str) -> None:
    """Raise naming the line of the first repeated value (and of its first use).

    ``values`` has one entry per record of ``rows``.
    """
    values = np.asarray(values, dtype=str)
    _, inverse, counts = np.unique(values, return_inverse=True, return_counts=True)
    repeated = np.flatnonzero(counts[inverse.reshape(-1)] > 1)
    if repeated.size:
        first = int(repeated[0])
        second = int(np.flatnonzero(values == values[first])[1])
        raise ConfigError(
            f"{rows.where(second)}: {what} '{values[first]}' is listed twice (first at line "
            f"{int(rows.lines[first])})"
        )


def line_floats(values: Sequence[str], where: str, what: str) -> FloatArray:
    """The fields of one record as finite floats; ``where`` is ``file:line``."""
    try:
        out = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        bad = next(v for v in values if not _is_number(v))
        raise ConfigError(f"{where}: {what}: expected a number, got {str(bad)!r}") from None
    if not np.isfinite(out).all():
        bad = values[int(np.flatnonzero(~np.isfinite(out))[0])]
        raise ConfigError(f"{where}: {what}: expected a finite number, got {str(bad)!r}")
    return out


def _is_number(text: str) -> bool:
    try:
        float(text)
    except (TypeError, ValueError):
        return False
    return True


def photo_id(names: Iterable[str]) -> StrArray:
    """Photo ids from image file names: the base name without its extension.

    ``"images/DJI_0001.JPG"`` and ``"C:\\flight\\DJI_0001.jpg"`` both give
    ``"DJI_0001"``.
    """
    out = []
    for name in names:
        base = re.split(r"[\\/]", str(name).strip())[-1]
        stem, dot, ext = base.rpartition(".")
        out.append(stem if dot and stem and ext.isalnum() else base)
    return np.asarray(out, dtype=str)


_DIGITS = re.compile(r"(\d+)")


def natural_key(name: str) -> tuple[tuple[int, int, str], ...]:
    """Sort key that orders ``"B1_2"`` before ``"B1_10"`` (digit runs as numbers)."""
    parts = _DIGITS.split(str(name))
    return tuple((0, int(p), p) if p.isdigit() else (1, 0, p.lower()) for p in parts if p)


def read_photo_order(path: Path | None) -> tuple[tuple[str, ...], ...] | None:
    """The ``--photo-order`` file: one strip a line, its photo ids in flight
    order (separated by spaces or commas; ``#`` starts a comment)."""
    if path is None:
        return None
    strips = []
    for line in read_text(path, "photo order, one strip per line").splitlines():
        text = line.split("#", 1)[0].replace(",", " ").split()
        if text:
            strips.append(tuple(text))
    if not strips:
        raise ConfigError(f"{path}: no photo ids (one strip per line)")
    return tuple(strips)


def pixel_size_mm(
    pixel_um: float | None, sensor_width_mm: float | None, width_px: int | None = None
) -> float | None:
    """The pixel size in mm from ``--pixel-um`` or ``--sensor-width-mm`` and the
    image width in pixels (None when neither is given).

    Examples
    --------
    >>> pixel_size_mm(2.5, None), pixel_size_mm(None, 13.2, 4000)
    (0.0025, 0.0033)
    """
    if pixel_um is not None and sensor_width_mm is not None:
        raise ConfigError("give --pixel-um or --sensor-width-mm, not both")
    if pixel_um is not None:
        return pixel_um / 1000.0
    if sensor_width_mm is not None:
        if width_px is None:
            raise ConfigError("--sensor-width-mm needs the image width: use --pixel-um")
        return sensor_width_mm / width_px
    return None
