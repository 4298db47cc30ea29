"""Writing results: CSV text and an atomically replaced result folder.

Nothing here knows how results are computed.  :func:`format_points_csv` and
:func:`format_photos_csv` produce the contract's ``points.csv`` and
``photos.csv`` (required columns first, then extras); :class:`ResultFolder`
and :func:`write_result_folder` write a whole result folder so that a run
either replaces the previous result completely or leaves it exactly as it was.

The swap: everything is written into a hidden temporary folder beside the
target; every file of the old folder that the previous run did not write (a
user's notes, the exports of ``stripaero export``) is linked or copied into
it; at the end the old folder is renamed away, the new one renamed in and the
old one deleted.  A folder is only ever replaced if it is empty or carries
the marker file :data:`RESULT_MARKER` written by a previous run, which lists
the files that run wrote.  SIGINT (Ctrl-C) is held back during the swap, so
the folder always holds either the old or the new result whole.
"""

from __future__ import annotations

import csv
import io as _io
import os
import shutil
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path, PurePosixPath
from types import TracebackType
from typing import Any

import numpy as np

from .._atomic import folder_beside, input_inside, swap_folder
from .._signals import sigint_held
from .._typing import ArrayLike
from ..errors import StripAerotriError

__all__ = [
    "RESULT_MARKER",
    "OutputError",
    "ResultFolder",
    "format_csv",
    "format_photos_csv",
    "format_points_csv",
    "record_export",
    "write_csv",
    "write_result_folder",
]

RESULT_MARKER = ".stripaero-result"
"""Name of the marker file that identifies a result folder."""

_MARKER_TEXT = (
    "This folder holds results of stripaero; a new run replaces the files listed below\n"
    "and keeps every other file.\n"
)
_WRITTEN = "written: "
_EXPORTED = "exported: "
_LEGACY_WRITTEN = frozenset(
    {"points.csv", "photos.csv", "report.json", "report.html", "report.md", "points.geojson"}
)
"""What a run wrote into a result folder whose marker lists nothing (older versions)."""

METRE_DECIMALS = 4
DEGREE_DECIMALS = 6
GEOGRAPHIC_DECIMALS = 9  # 1e-9 degree of latitude is about 0.1 mm


class OutputError(StripAerotriError, OSError):
    """Results cannot be written where asked (not a result folder, input inside, I/O error)."""


# --------------------------------------------------------------------------- CSV text

Column = ArrayLike | tuple[ArrayLike, int]


def _format_column(values: ArrayLike, decimals: int | None, name: str) -> tuple[str, list[Any]]:
    """One column as a ``%`` conversion and its values: floats with ``decimals``
    (``%.4f``; NaN an empty cell), ints, bools (``true``/``false``) and text
    (``%s``)."""
    arr = np.asarray(values)
    if arr.ndim != 1:
        raise ValueError(f"Expected column `{name}` to have shape (N,), got {arr.shape}")
    if arr.dtype.kind == "b":
        return "%s", ["true" if v else "false" for v in arr.tolist()]
    if arr.dtype.kind in "iu":
        return "%d", arr.tolist()
    if arr.dtype.kind == "f":
        digits = METRE_DECIMALS if decimals is None else int(decimals)
        # round first and add 0.0 so that -0.00001 is written 0.0000, not -0.0000
        rounded = np.round(arr.astype(np.float64), digits) + 0.0
        finite = np.isfinite(rounded)
        if finite.all():
            return f"%.{digits}f", rounded.tolist()
        # only the finite values formatted (a tie point's residuals are empty)
        text = np.full(arr.shape, "", dtype=object)
        text[finite] = list(map(f"%.{digits}f".__mod__, rounded[finite].tolist()))
        return "%s", text.tolist()
    if arr.dtype.kind == "U":
        return "%s", arr.tolist()
    if arr.dtype.kind == "O":
        return "%s", [str(v) for v in arr.tolist()]
    raise ValueError(f"Expected column `{name}` of numbers or strings, got dtype {arr.dtype}")


def _plain_text(cells: list[str]) -> bool:
    """Whether no cell needs the quotes of CSV (a comma, a quote or a line end)."""
    joined = "".join(cells)
    return not any(c in joined for c in ',"\r\n')


def format_csv(
    header: Sequence[str],
    columns: Sequence[Column],
    *,
    decimals: int | Sequence[int | None] | None = None,
) -> str:
    """CSV text with one header line and one row per element of the columns.

    Parameters
    ----------
    header : sequence of str, length C
        Column names.
    columns : sequence of array_like, length C, each shape (N,)
        Values; an entry may be ``(values, decimals)`` to fix its decimals.
        Floats are written with fixed decimals (NaN as an empty cell), ints
        as integers, bools as ``true``/``false``, strings as they are (quoted
        only where CSV needs it).
    decimals : int or sequence of (int or None), optional
        Decimals of float columns (default 4, millimetre resolution in metres).

    Returns
    -------
    str
        UTF-8-ready text with ``\\n`` line ends, ending with a newline.

    Raises
    ------
    ValueError
        If header and columns differ in number, or the columns in length.

    Examples
    --------
    >>> print(format_csv(["point", "H"], [["7", "08"], [1.23456, float("nan")]]), end="")
    point,H
    7,1.2346
    08,
    """
    if len(header) != len(columns):
        raise ValueError(
            f"Expected as many columns as header names, got {len(columns)} and {len(header)}"
        )
    for name in header:
        if not isinstance(name, str) or not name or any(c in name for c in ',"\n\r'):
            raise ValueError(f"Expected a plain column name, got {name!r}")
    if decimals is None or isinstance(decimals, int):
        per_column: list[int | None] = [decimals] * len(columns)
    else:
        per_column = list(decimals)
        if len(per_column) != len(columns):
            raise ValueError(f"Expected {len(columns)} decimals entries, got {len(per_column)}")
    formatted = []
    for name, column, digits in zip(header, columns, per_column, strict=True):
        if isinstance(column, tuple) and len(column) == 2 and isinstance(column[1], int):
            column, digits = column
        formatted.append(_format_column(column, digits, name))
    lengths = {len(values) for _, values in formatted}
    if len(lengths) > 1:
        raise ValueError(
            "Expected columns of equal length, got "
            + ", ".join(f"{n}: {len(v)}" for n, (_, v) in zip(header, formatted, strict=True))
        )
    lone_empty = len(formatted) == 1 and not all(formatted[0][1])  # written ""
    if not lone_empty and all(spec != "%s" or _plain_text(values) for spec, values in formatted):
        # one % per row: nothing to quote
        row = ",".join(spec for spec, _ in formatted).__mod__
        rows = map(row, zip(*(values for _, values in formatted), strict=True))
        return ",".join(header) + "\n" + "".join(line + "\n" for line in rows)
    buffer = _io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    texts = [values if spec == "%s" else [spec % v for v in values] for spec, values in formatted]
    writer.writerows(zip(*texts, strict=True))
    return buffer.getvalue()


def write_csv(
    path: str | os.PathLike[str],
    header: Sequence[str],
    columns: Sequence[Column],
    *,
    decimals: int | Sequence[int | None] | None = None,
) -> Path:
    """Write :func:`format_csv` text to ``path`` (UTF-8, no BOM) and return the path.

    Use it inside a :class:`ResultFolder` (``folder.path / name``) so that the
    file becomes visible only when the whole result is complete.
    """
    path = Path(path)
    path.write_text(format_csv(header, columns, decimals=decimals), encoding="utf-8")
    return path


def _extras(
    extra: Mapping[str, Column] | None, reserved: Sequence[str]
) -> tuple[list[str], list[Column]]:
    names, columns = [], []
    for name, column in (extra or {}).items():
        if name in reserved:
            raise ValueError(f"Extra column `{name}` clashes with a required column")
        names.append(name)
        columns.append(column)
    return names, columns


def format_points_csv(
    point_ids: ArrayLike,
    xyz: ArrayLike,
    *,
    extra: Mapping[str, Column] | None = None,
    geographic: bool = False,
) -> str:
    """Text of ``points.csv``: ``point,X,Y,H`` then the extra columns.

    Parameters
    ----------
    point_ids : array_like of str, shape (N,)
    xyz : array_like, shape (N, 3)
        X, Y in the control CRS (easting, northing in metres; or longitude,
        latitude in degrees when ``geographic``) and H in metres; NaN is
        written as an empty cell.
    extra : mapping of str to array_like (N,), optional
        Further columns in the order given; an entry may be ``(values, decimals)``.
        Float columns default to 4 decimals.
    geographic : bool
        True when X, Y are degrees: written with 9 decimals (about 0.1 mm)
        instead of 4.

    Returns
    -------
    str
        CSV text.
    """
    ids = np.asarray(point_ids, dtype=str).reshape(-1)
    xyz = np.asarray(xyz, dtype=np.float64)
    if xyz.shape != (ids.shape[0], 3):
        raise ValueError(f"Expected `xyz` to have shape ({ids.shape[0]}, 3), got {xyz.shape}")
    xy_digits = GEOGRAPHIC_DECIMALS if geographic else METRE_DECIMALS
    header = ["point", "X", "Y", "H"]
    names, columns = _extras(extra, header)
    return format_csv(
        header + names,
        [
            ids,
            (xyz[:, 0], xy_digits),
            (xyz[:, 1], xy_digits),
            (xyz[:, 2], METRE_DECIMALS),
            *columns,
        ],
    )


def format_photos_csv(
    photo_ids: ArrayLike,
    xyz: ArrayLike,
    opk: ArrayLike,
    *,
    degrees: bool = False,
    extra: Mapping[str, Column] | None = None,
    geographic: bool = False,
) -> str:
    """Text of ``photos.csv``: ``photo,X,Y,Z,omega,phi,kappa`` then the extra columns.

    Parameters
    ----------
    photo_ids : array_like of str, shape (M,)
    xyz : array_like, shape (M, 3)
        Projection centres: X, Y in the control CRS (degrees when
        ``geographic``), Z ellipsoidal height in metres.
    opk : array_like, shape (M, 3)
        omega, phi, kappa of ``R = R_x(omega) R_y(phi) R_z(kappa)`` (image to
        ground), in radians unless ``degrees``; written in degrees with 6
        decimals.
    degrees : bool
        ``opk`` is already in degrees.
    extra : mapping of str to array_like (M,), optional
        Further columns; an entry may be ``(values, decimals)``.
    geographic : bool
        X, Y are degrees: 9 decimals instead of 4.

    Returns
    -------
    str
        CSV text.
    """
    ids = np.asarray(photo_ids, dtype=str).reshape(-1)
    m = ids.shape[0]
    xyz = np.asarray(xyz, dtype=np.float64)
    opk = np.asarray(opk, dtype=np.float64)
    if xyz.shape != (m, 3):
        raise ValueError(f"Expected `xyz` to have shape ({m}, 3), got {xyz.shape}")
    if opk.shape != (m, 3):
        raise ValueError(f"Expected `opk` to have shape ({m}, 3), got {opk.shape}")
    angles = opk if degrees else np.rad2deg(opk)
    xy_digits = GEOGRAPHIC_DECIMALS if geographic else METRE_DECIMALS
    header = ["photo", "X", "Y", "Z", "omega", "phi", "kappa"]
    names, columns = _extras(extra, header)
    return format_csv(
        header + names,
        [
            ids,
            (xyz[:, 0], xy_digits),
            (xyz[:, 1], xy_digits),
            (xyz[:, 2], METRE_DECIMALS),
            (angles[:, 0], DEGREE_DECIMALS),
            (angles[:, 1], DEGREE_DECIMALS),
            (angles[:, 2], DEGREE_DECIMALS),
            *columns,
        ],
    )


# --------------------------------------------------------------------------- result folder


def _check_name(name: str) -> PurePosixPath:
    rel = PurePosixPath(name)
    if (
        not name
        or rel.is_absolute()
        or any(part in ("", ".", "..") for part in rel.parts)
        or "\\" in name
        or rel.parts[0] == RESULT_MARKER
    ):
        raise ValueError(f"Expected a relative file name inside the result folder, got {name!r}")
    return rel


def _check_target(target: Path, protect: Iterable[os.PathLike[str] | str]) -> None:
    """Raise OutputError unless ``target`` may be replaced by a result folder."""
    if target.is_symlink():
        raise OutputError(f"output folder '{target}' is a symbolic link; give the real folder")
    if target.exists():
        if not target.is_dir():
            raise OutputError(f"output folder '{target}' is a file, not a folder")
        is_result = (target / RESULT_MARKER).is_file()
        if not is_result and any(target.iterdir()):
            raise OutputError(
                f"output folder '{target}' is not empty and is not a stripaero result folder "
                f"(no {RESULT_MARKER} file); refusing to replace it"
            )
    item = input_inside(target, protect)
    if item is not None:
        raise OutputError(
            f"output folder '{target}' contains the input file '{item}'; refusing to replace it"
        )


def _marker_lists(folder: Path) -> tuple[frozenset[str], frozenset[str]] | None:
    """The files a result folder's marker says the run wrote and those
    ``stripaero export`` wrote; None when it is no result folder."""
    try:
        lines = (folder / RESULT_MARKER).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return None
    written = frozenset(x[len(_WRITTEN) :] for x in lines if x.startswith(_WRITTEN))
    exported = frozenset(x[len(_EXPORTED) :] for x in lines if x.startswith(_EXPORTED))
    return (written or _LEGACY_WRITTEN), exported


def _write_marker(folder: Path, written: Iterable[str], exported: Iterable[str]) -> None:
    lines = [_MARKER_TEXT]
    lines += [f"{_WRITTEN}{name}\n" for name in written]
    lines += [f"{_EXPORTED}{name}\n" for name in exported]
    (folder / RESULT_MARKER).write_text("".join(lines), encoding="utf-8")


def record_export(path: str | os.PathLike[str]) -> None:
    """Note in the marker of the result folder holding ``path`` that
    ``stripaero export`` wrote it (nothing when the folder is no result
    folder); a new run keeps it and says it describes the previous result."""
    path = Path(path)
    listed = _marker_lists(path.parent)
    if listed is None or path.name in listed[1]:
        return
    with (path.parent / RESULT_MARKER).open("a", encoding="utf-8") as fh:
        fh.write(f"{_EXPORTED}{path.name}\n")


def _carry_over(
    old: Path, new: Path, written: Sequence[str]
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Link (else copy) into ``new`` every entry of the result folder ``old``
    that the previous run did not write and the new one does not write.

    Returns the names kept and, among them, those ``stripaero export`` wrote.
    """
    listed = _marker_lists(old) if old.is_dir() else None
    if listed is None:
        return (), ()
    previous, exported = listed
    mine = {PurePosixPath(n).parts[0] for n in written} | {RESULT_MARKER}
    ours = {PurePosixPath(n).parts[0] for n in previous}
    kept = []
    for entry in sorted(old.iterdir()):
        if entry.name in mine or entry.name in ours:
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.copytree(entry, new / entry.name, symlinks=True, copy_function=_link_or_copy)
        else:
            _link_or_copy(entry, new / entry.name)
        kept.append(entry.name)
    return tuple(kept), tuple(n for n in kept if n in exported)


def _link_or_copy(source: str | os.PathLike[str], dest: str | os.PathLike[str]) -> None:
    """A hard link (no copy, same file), else a copy with its metadata."""
    if os.path.islink(source):
        os.symlink(os.readlink(source), dest)
        return
    try:
        os.link(source, dest)
    except OSError:
        shutil.copy2(source, dest)


class ResultFolder:
    """Write a result folder atomically.

    Use as a context manager: files are written into ``folder.path`` (a
    hidden temporary folder beside ``target``); leaving the block normally
    swaps it in for ``target``; leaving it by an exception deletes it and
    leaves ``target`` exactly as it was.

    Parameters
    ----------
    target : str or Path
        The result folder.  It may not exist yet (missing parents are
        created), be empty, or be a previous result folder (it holds
        :data:`RESULT_MARKER`); anything else is refused.
    protect : iterable of path, optional
        Input files: a ``target`` that contains one of them is refused.

    Raises
    ------
    OutputError
        If ``target`` may not be replaced, or on an I/O error.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "out"
    >>> with ResultFolder(out) as folder:
    ...     _ = folder.write_text("points.csv", "point,X,Y,H\\n")
    >>> sorted(p.name for p in out.iterdir())
    ['.stripaero-result', 'points.csv']
    """

    def __init__(
        self, target: str | os.PathLike[str], *, protect: Iterable[str | os.PathLike[str]] = ()
    ) -> None:
        self.target = Path(target)
        self._protect = tuple(protect)
        self._tmp: Path | None = None
        self._done = False
        self._written: list[str] = []
        self.kept: tuple[str, ...] = ()
        """Files of the previous folder that the run did not write, kept (after commit)."""
        self.exports: tuple[str, ...] = ()
        """Those of :attr:`kept` that ``stripaero export`` wrote from the previous result."""

    @property
    def committed(self) -> bool:
        """True once the new result is in place."""
        return self._done

    @property
    def path(self) -> Path:
        """The temporary folder to write into (valid inside the ``with`` block)."""
        if self._tmp is None:
            raise RuntimeError("ResultFolder is not open; use it in a with statement")
        return self._tmp

    def open(self) -> ResultFolder:
        """Check the target and create the temporary folder (done by ``with``)."""
        _check_target(self.target, self._protect)
        parent = self.target.parent
        try:
            tmp = folder_beside(self.target)
            self._tmp = tmp
            _write_marker(tmp, (), ())
        except OSError as exc:
            self.abort()
            raise OutputError(f"cannot write into '{parent}': {exc.strerror or exc}") from exc
        return self

    def __enter__(self) -> ResultFolder:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.abort()

    def write_bytes(self, name: str, data: bytes) -> Path:
        """Write ``data`` to ``name`` (a relative path, sub-folders allowed)."""
        path = self.path / _check_name(name)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(data)
            self._written.append(str(PurePosixPath(name)))
        except OSError as exc:
            raise OutputError(f"cannot write '{name}': {exc.strerror or exc}") from exc
        return path

    def write_text(self, name: str, text: str) -> Path:
        """Write ``text`` as UTF-8 to ``name``."""
        return self.write_bytes(name, text.encode("utf-8"))

    def commit(self) -> Path:
        """Swap the temporary folder in for the target; returns the target."""
        tmp = self.path
        if self._done:
            raise RuntimeError("ResultFolder was already committed")
        target = self.target
        # check again: the folder may have changed while results were computed
        try:
            _check_target(target, self._protect)
        except OutputError:
            self.abort()
            raise
        try:
            kept, exports = _carry_over(target, tmp, self._written)
            _write_marker(tmp, self._written, exports)
            with sigint_held():
                swap_folder(tmp, target)
                self._tmp = None
                self._done = True
        except OSError as exc:
            self.abort()
            raise OutputError(f"cannot replace '{target}': {exc.strerror or exc}") from exc
        self.kept, self.exports = kept, exports
        return target

    def abort(self) -> None:
        """Delete the temporary folder; the target is left as it was."""
        if self._tmp is not None:
            shutil.rmtree(self._tmp, ignore_errors=True)
            self._tmp = None


def write_result_folder(
    target_dir: str | os.PathLike[str],
    files: Mapping[str, bytes | str],
    *,
    protect: Iterable[str | os.PathLike[str]] = (),
) -> Path:
    """Replace ``target_dir`` by a result folder holding ``files``, atomically.

    Parameters
    ----------
    target_dir : str or Path
        Result folder: missing, empty, or a previous result folder.
    files : mapping of str to bytes or str
        Relative file name (``/`` for sub-folders) to content; text is
        written as UTF-8.
    protect : iterable of path, optional
        Input files that must not lie inside ``target_dir``.

    Returns
    -------
    Path
        ``target_dir``.

    Raises
    ------
    OutputError
        If ``target_dir`` is not a result folder, contains an input, or on an
        I/O error; ``target_dir`` is then unchanged.
    ValueError
        If a file name is absolute, leaves the folder or is the marker.
    """
    for name in files:
        _check_name(name)
    with ResultFolder(target_dir, protect=protect) as folder:
        for name, content in files.items():
            if isinstance(content, str):
                folder.write_text(name, content)
            else:
                folder.write_bytes(name, bytes(content))
    return Path(target_dir)
