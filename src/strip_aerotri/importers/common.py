"""What every importer shares: reading text, the imported project, its strips, its writing.

An importer reads one source format into arrays (image observations, control
points, optional projection centres and attitudes) and calls :func:`assemble`.
:func:`assemble` decides what the source does not say and records each
decision as a note:

* the strips and the photo order in each (given by the importer or by
  ``--photo-order``; else from the photos' positions, split where the track
  turns; else one strip in photo-name order), see :func:`strips_from_positions`;
* the image axis that points along the flight (``[images] flight_direction``)
  from the mean shift of the points between consecutive photos, reversing a
  strip whose photos move the other way, see :func:`decide_flight_direction`;
* which control points are full control and which are check points, see
  :func:`split_control`.

:func:`write_project` writes the result as a contract project
(``docs/project-file.md``): ``strip.toml``, ``image_points.csv``,
``control.csv`` and, where the source has them, ``gnss.csv`` and ``imu.csv``;
atomically (a temporary folder beside the target, then a rename), and never
over an existing folder without ``force``.

Conventions: image coordinates are kept in the source's units, either
millimetres in the sensor axes (x right, y up) or pixel column and row (rows
down); ids are strings; ground coordinates are in the project CRS with
pyproj's ``always_xy`` axis order.  Attitudes are rotation matrices mapping
sensor-axis image vectors ``(x, y, -c)`` to local east-north-up (or the site
axes of ``crs = "local"``); :func:`assemble` turns them into the flight axes
of the project.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from itertools import pairwise
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..errors import ConfigError

__all__ = [
    "Camera",
    "ControlTable",
    "Distortion",
    "ImageFrame",
    "ImageTable",
    "ImportOptions",
    "ImportedProject",
    "PhotoAttitudes",
    "PhotoPositions",
    "Rows",
    "Strip",
    "assemble",
    "attitudes_from_opk",
    "check_unique",
    "decide_flight_direction",
    "grid_convergence_deg",
    "line_floats",
    "matrix_from_opk_deg",
    "natural_key",
    "opk_deg_from_matrix",
    "photo_id",
    "project_toml",
    "read_text",
    "split_control",
    "split_rows",
    "strips_from_positions",
    "to_floats",
    "toml_value",
    "write_project",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
StrArray = NDArray[np.str_]
BoolArray = NDArray[np.bool_]

FLIGHT_DIRECTIONS = ("+x", "-x", "+y", "-y")
DEFAULT_TURN_DEG = 45.0

# --------------------------------------------------------------------------- reading text


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
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ConfigError(
            f"{path}:{line}: not valid UTF-8 (byte 0x{data[exc.start]:02x}); "
            "save the file as UTF-8"
        ) from None


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


# --------------------------------------------------------------------------- the data


def _ids(values: Iterable[str] | StrArray) -> StrArray:
    arr = np.asarray(list(values) if not isinstance(values, np.ndarray) else values, dtype=str)
    return arr.reshape(-1)


@dataclass(frozen=True)
class ImageTable:
    """Image observations of a source, in its own units and axes.

    Attributes
    ----------
    photo, point : ndarray of str, shape (K,)
    xy : ndarray, shape (K, 2)
        mm in the sensor axes (x right, y up) or pixel column and row (rows
        down), as the project's :class:`ImageFrame` says.
    sigma_mm : ndarray, shape (K,), optional
        Standard deviation of x and y in mm; NaN means the project default.
    """

    photo: StrArray
    point: StrArray
    xy: FloatArray
    sigma_mm: FloatArray | None = None

    def __post_init__(self) -> None:
        photo = _ids(self.photo)
        point = _ids(self.point)
        xy = np.asarray(self.xy, dtype=np.float64).reshape(-1, 2)
        if not (photo.shape[0] == point.shape[0] == xy.shape[0]):
            raise ValueError(
                f"Expected photo, point and xy of one length, got {photo.shape[0]}, "
                f"{point.shape[0]}, {xy.shape[0]}"
            )
        object.__setattr__(self, "photo", photo)
        object.__setattr__(self, "point", point)
        object.__setattr__(self, "xy", xy)
        if self.sigma_mm is not None:
            sigma = np.broadcast_to(np.asarray(self.sigma_mm, dtype=np.float64), photo.shape)
            object.__setattr__(self, "sigma_mm", sigma.copy())

    def __len__(self) -> int:
        return int(self.photo.shape[0])

    def take(self, index: IntArray | BoolArray) -> ImageTable:
        """The observations at ``index`` (integer or boolean)."""
        sigma = None if self.sigma_mm is None else self.sigma_mm[index]
        return ImageTable(self.photo[index], self.point[index], self.xy[index], sigma)

    @staticmethod
    def concat(tables: Sequence[ImageTable]) -> ImageTable:
        """The observations of every table, in order."""
        if not tables:
            return ImageTable(np.empty(0, str), np.empty(0, str), np.empty((0, 2)))
        sigma = None
        if any(t.sigma_mm is not None for t in tables):
            sigma = np.concatenate(
                [t.sigma_mm if t.sigma_mm is not None else np.full(len(t), np.nan) for t in tables]
            )
        return ImageTable(
            np.concatenate([t.photo for t in tables]),
            np.concatenate([t.point for t in tables]),
            np.concatenate([t.xy for t in tables]),
            sigma,
        )

    def rows_by_photo(self) -> dict[str, IntArray]:
        """Row indices of each photo's observations."""
        if len(self) == 0:
            return {}
        order = np.argsort(self.photo, kind="stable")
        photos, first = np.unique(self.photo[order], return_index=True)
        groups = np.split(order, first[1:])
        return {str(p): g for p, g in zip(photos, groups, strict=True)}


@dataclass(frozen=True)
class ImageFrame:
    """How the image coordinates of a project are given (``[images]``).

    Attributes
    ----------
    units : {"mm", "pixel"}
        ``"mm"``: x right, y up. ``"pixel"``: column and row, rows down.
    pixel_size_mm : float, optional
        Required with ``"pixel"``; with ``"mm"`` it only sets the default
        ``sigma_mm`` (one pixel).
    principal_point_px : (float, float), optional
        Column and row of the principal point, required with ``"pixel"``.
    sigma_mm : float, optional
        ``[images] sigma_mm``; None leaves the loader's default.
    """

    units: str = "mm"
    pixel_size_mm: float | None = None
    principal_point_px: tuple[float, float] | None = None
    sigma_mm: float | None = None

    def __post_init__(self) -> None:
        if self.units not in ("mm", "pixel"):
            raise ValueError(f'Expected units "mm" or "pixel", got {self.units!r}')
        if self.units == "pixel" and (
            self.pixel_size_mm is None or self.principal_point_px is None
        ):
            raise ValueError("Expected `pixel_size_mm` and `principal_point_px` for pixels")

    def sensor_mm(self, xy: FloatArray) -> FloatArray:
        """``xy`` in mm in the sensor axes (x right, y up), shape (K, 2).

        Pixels are reduced to the principal point, as the loader does; mm are
        returned as given.
        """
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if self.units == "mm":
            return xy
        s = float(self.pixel_size_mm)  # type: ignore[arg-type]
        c0, r0 = self.principal_point_px  # type: ignore[misc]
        return np.column_stack(((xy[:, 0] - c0) * s, -(xy[:, 1] - r0) * s))


@dataclass(frozen=True)
class Camera:
    """``[camera]``: principal distance and principal point, mm."""

    principal_distance_mm: float
    principal_point_mm: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        c = float(self.principal_distance_mm)
        if not (math.isfinite(c) and c > 0):
            raise ConfigError(f"the principal distance must be a positive number of mm, got {c!r}")
        object.__setattr__(self, "principal_distance_mm", c)


@dataclass(frozen=True)
class Distortion:
    """``[distortion]``: Brown's coefficients as ``docs/project-file.md`` defines them.

    The coefficients refer to the sensor axes (x right, y up); ``units`` and
    ``model`` have the meaning of the project file.
    """

    k1: float = 0.0
    k2: float = 0.0
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    units: str = "normalized"
    model: str = "projection"
    comment: str = ""

    @property
    def is_zero(self) -> bool:
        return not any((self.k1, self.k2, self.k3, self.p1, self.p2))


@dataclass(frozen=True)
class ControlTable:
    """Ground points of a source.

    Attributes
    ----------
    point : ndarray of str, shape (N,)
    xyz : ndarray, shape (N, 3)
        X, Y (``always_xy`` order) and H; NaN where the source has none.
    kind : ndarray of str, shape (N,)
        ``full``, ``plan``, ``height`` or ``check`` as the source says
        (``full`` when it says nothing).
    typed : bool
        True when the source itself tells control from check points (then the
        default split keeps its types).
    sigma_xy, sigma_h : ndarray, shape (N,), optional
        Standard deviations in m; NaN means the project default.
    """

    point: StrArray
    xyz: FloatArray
    kind: StrArray | None = None
    typed: bool = False
    sigma_xy: FloatArray | None = None
    sigma_h: FloatArray | None = None

    def __post_init__(self) -> None:
        point = _ids(self.point)
        xyz = np.asarray(self.xyz, dtype=np.float64).reshape(-1, 3)
        if xyz.shape[0] != point.shape[0]:
            raise ValueError("Expected one row of xyz per point")
        kind = (
            np.full(point.shape, "full", dtype="<U6")
            if self.kind is None
            else np.asarray(self.kind, dtype="<U6").reshape(-1)
        )
        object.__setattr__(self, "point", point)
        object.__setattr__(self, "xyz", xyz)
        object.__setattr__(self, "kind", kind)
        for name in ("sigma_xy", "sigma_h"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(
                    self, name, np.broadcast_to(np.asarray(value, float), point.shape).copy()
                )

    def __len__(self) -> int:
        return int(self.point.shape[0])

    def take(self, index: IntArray | BoolArray) -> ControlTable:
        def part(a: FloatArray | None) -> FloatArray | None:
            return None if a is None else a[index]

        return ControlTable(
            self.point[index],
            self.xyz[index],
            self.kind[index],  # type: ignore[index]
            self.typed,
            part(self.sigma_xy),
            part(self.sigma_h),
        )


@dataclass(frozen=True)
class PhotoPositions:
    """Projection centres (or any positions along the track), shape (M, 3)."""

    photo: StrArray
    xyz: FloatArray
    sigma_xy: FloatArray | None = None
    sigma_z: FloatArray | None = None

    def __post_init__(self) -> None:
        photo = _ids(self.photo)
        xyz = np.asarray(self.xyz, dtype=np.float64).reshape(-1, 3)
        if xyz.shape[0] != photo.shape[0]:
            raise ValueError("Expected one position per photo")
        object.__setattr__(self, "photo", photo)
        object.__setattr__(self, "xyz", xyz)

    def take(self, index: IntArray | BoolArray) -> PhotoPositions:
        def part(a: FloatArray | None) -> FloatArray | None:
            return None if a is None else a[index]

        return PhotoPositions(
            self.photo[index], self.xyz[index], part(self.sigma_xy), part(self.sigma_z)
        )


@dataclass(frozen=True)
class PhotoAttitudes:
    """Photo attitudes as rotation matrices, shape (M, 3, 3).

    ``matrix[i]`` maps image vectors ``(x, y, -c)`` in the **sensor** axes
    (x right, y up, z back) to local east-north-up at the projection centre
    (the site's X, Y, H axes for ``crs = "local"``).
    """

    photo: StrArray
    matrix: FloatArray

    def __post_init__(self) -> None:
        photo = _ids(self.photo)
        matrix = np.asarray(self.matrix, dtype=np.float64).reshape(-1, 3, 3)
        if matrix.shape[0] != photo.shape[0]:
            raise ValueError("Expected one matrix per photo")
        object.__setattr__(self, "photo", photo)
        object.__setattr__(self, "matrix", matrix)

    def take(self, index: IntArray | BoolArray) -> PhotoAttitudes:
        return PhotoAttitudes(self.photo[index], self.matrix[index])


@dataclass(frozen=True)
class Strip:
    """One strip: its name and its photos in flight order."""

    name: str
    photos: tuple[str, ...]


@dataclass(frozen=True)
class ImportOptions:
    """The choices every importer accepts (the CLI's shared options).

    Attributes
    ----------
    strips : tuple of int, optional
        1-based numbers of the strips to keep (in the order the strips are
        found); None keeps all.
    control_ids, check_ids : tuple of str, optional
        Override the control/check split (see :func:`split_control`).
    flight_direction : {"+x", "-x", "+y", "-y"}, optional
        The image axis along the flight; None decides it from the data.
    photo_order : tuple of tuple of str, optional
        The strips and their photos in flight order, given by the user.
    name : str, optional
        Project name; default from the source.
    sigma_mm : float, optional
        ``[images] sigma_mm``; default one pixel where the pixel size is known.
    turn_deg : float
        Heading change that ends a strip when the strips come from positions.
    """

    strips: tuple[int, ...] | None = None
    control_ids: tuple[str, ...] | None = None
    check_ids: tuple[str, ...] | None = None
    flight_direction: str | None = None
    photo_order: tuple[tuple[str, ...], ...] | None = None
    name: str | None = None
    sigma_mm: float | None = None
    turn_deg: float = DEFAULT_TURN_DEG

    def __post_init__(self) -> None:
        if self.flight_direction is not None and self.flight_direction not in FLIGHT_DIRECTIONS:
            raise ValueError(
                f"Expected flight_direction in {FLIGHT_DIRECTIONS}, got {self.flight_direction!r}"
            )


@dataclass(frozen=True)
class ImportedProject:
    """A project ready to be written (see :func:`write_project`).

    Attributes
    ----------
    source : str
        What it was imported from (format and files), for the header comment.
    name : str
    strips : tuple of Strip
        Photos in flight order; one strip gives a ``[strip]`` project, more a
        block of ``[[strips]]``.
    camera : Camera
    frame : ImageFrame
    flight_direction : str
    images : ImageTable
        Observations of the photos of ``strips`` only.
    control : ControlTable
        Observed control points; ``kind`` is the final type of each.
    crs : str
    distortion : Distortion, optional
    gnss : PhotoPositions, optional
    imu_opk_deg : (PhotoStrArray, ndarray (M, 3)), optional
        omega, phi, kappa in degrees in the flight axes (the ``imu.csv``
        convention).
    notes : tuple of str
        What the importer decided; written as comments at the top of strip.toml.
    warnings : tuple of str
        Doubtful things the user should see.
    inputs : tuple of Path
        The files read (never written; the output may not contain them).
    """

    source: str
    name: str
    strips: tuple[Strip, ...]
    camera: Camera
    frame: ImageFrame
    flight_direction: str
    images: ImageTable
    control: ControlTable
    crs: str
    distortion: Distortion | None = None
    gnss: PhotoPositions | None = None
    imu_opk_deg: tuple[StrArray, FloatArray] | None = None
    notes: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    inputs: tuple[Path, ...] = field(default_factory=tuple)

    @property
    def photo_ids(self) -> tuple[str, ...]:
        return tuple(p for s in self.strips for p in s.photos)

    def summary(self) -> str:
        """One line of counts."""
        assert self.control.kind is not None  # filled in by ControlTable
        kinds, counts = np.unique(self.control.kind, return_counts=True)
        parts = ", ".join(f"{int(n)} {k}" for k, n in zip(kinds, counts, strict=True))
        extra = ""
        if self.gnss is not None:
            extra += f", {len(self.gnss.photo)} GNSS centres"
        if self.imu_opk_deg is not None:
            extra += f", {len(self.imu_opk_deg[0])} IMU attitudes"
        return (
            f"{len(self.strips)} strip(s), {len(self.photo_ids)} photos, "
            f"{np.unique(self.images.point).size} points, {len(self.images)} observations, "
            f"{len(self.control)} control points ({parts}){extra}; "
            f"flight along image {self.flight_direction}"
        )


# --------------------------------------------------------------------------- rotations


def _rx(t: FloatArray) -> FloatArray:
    c, s = np.cos(t), np.sin(t)
    z, o = np.zeros_like(t), np.ones_like(t)
    return np.stack([o, z, z, z, c, -s, z, s, c], axis=-1).reshape(*t.shape, 3, 3)


def _ry(t: FloatArray) -> FloatArray:
    c, s = np.cos(t), np.sin(t)
    z, o = np.zeros_like(t), np.ones_like(t)
    return np.stack([c, z, s, z, o, z, -s, z, c], axis=-1).reshape(*t.shape, 3, 3)


def _rz(t: FloatArray) -> FloatArray:
    c, s = np.cos(t), np.sin(t)
    z, o = np.zeros_like(t), np.ones_like(t)
    return np.stack([c, -s, z, s, c, z, z, z, o], axis=-1).reshape(*t.shape, 3, 3)


def matrix_from_opk_deg(opk_deg: FloatArray) -> FloatArray:
    """``R = Rx(omega) Ry(phi) Rz(kappa)`` from degrees, shape (..., 3) -> (..., 3, 3).

    Image -> object, right-handed elementary rotations (docs/conventions.md).
    """
    a = np.deg2rad(np.asarray(opk_deg, dtype=np.float64))
    return _rx(a[..., 0]) @ _ry(a[..., 1]) @ _rz(a[..., 2])


def opk_deg_from_matrix(matrix: FloatArray) -> FloatArray:
    """Inverse of :func:`matrix_from_opk_deg`, degrees, shape (..., 3, 3) -> (..., 3).

    ``sin phi = r13``, ``tan omega = -r23/r33``, ``tan kappa = -r12/r11``;
    omega, kappa in [-180, 180], phi in [-90, 90].
    """
    r = np.asarray(matrix, dtype=np.float64)
    phi = np.arcsin(np.clip(r[..., 0, 2], -1.0, 1.0))
    omega = np.arctan2(-r[..., 1, 2], r[..., 2, 2])
    kappa = np.arctan2(-r[..., 0, 1], r[..., 0, 0])
    degrees: FloatArray = np.rad2deg(np.stack([omega, phi, kappa], axis=-1))
    return degrees


def flight_matrix(direction: str) -> FloatArray:
    """3 x 3 matrix taking sensor-axis image vectors to the flight axes (z kept).

    The rows of ``[images] flight_direction`` (docs/project-file.md): ``"+y"``
    gives x' = y, y' = -x.
    """
    m2 = {
        "+x": [[1.0, 0.0], [0.0, 1.0]],
        "-x": [[-1.0, 0.0], [0.0, -1.0]],
        "+y": [[0.0, 1.0], [-1.0, 0.0]],
        "-y": [[0.0, -1.0], [1.0, 0.0]],
    }[direction]
    out = np.eye(3)
    out[:2, :2] = m2
    return out


def grid_convergence_deg(crs: str, xy: FloatArray) -> FloatArray:
    """Meridian convergence of a projected CRS at ``xy`` (shape (M, 2)), degrees.

    The azimuth of grid north clockwise from true north (pyproj's
    ``Proj.get_factors(...).meridian_convergence``), so that a matrix to the
    grid axes is ``Rz(gamma) @ R_enu`` (docs/conventions.md).  Zero for
    ``crs = "local"``.

    Raises
    ------
    ConfigError
        For a geographic CRS (attitudes from a map grid are not defined there).
    """
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    if crs.strip().lower() == "local":
        return np.zeros(xy.shape[0])
    from pyproj import CRS, Proj, Transformer

    target = CRS.from_user_input(crs)
    if not target.is_projected:
        raise ConfigError(
            f"crs {crs!r} is not a projected CRS: omega, phi, kappa refer to a map grid, so "
            "the attitudes cannot be converted; use the projected CRS of the source"
        )
    to_geo = Transformer.from_crs(target, target.geodetic_crs, always_xy=True)
    lon, lat = to_geo.transform(xy[:, 0], xy[:, 1])
    factors = Proj(target).get_factors(np.asarray(lon), np.asarray(lat))
    return np.asarray(factors.meridian_convergence, dtype=np.float64).reshape(-1)


def attitudes_from_opk(
    photo: StrArray,
    opk_deg: FloatArray,
    xy: FloatArray,
    crs: str,
    where: str,
) -> PhotoAttitudes:
    """Attitudes from omega, phi, kappa of the PATB convention on a map grid.

    The source's angles give ``R_grid = Rx(omega) Ry(phi) Rz(kappa)`` mapping
    camera vectors in the PATB axes (x right, y up, z back; the camera looks
    along -z) to the map grid (grid east, grid north, up).  The local
    east-north-up matrix is ``Rz(-gamma) @ R_grid`` with the meridian
    convergence gamma at the photo (:func:`grid_convergence_deg`).

    Raises
    ------
    ConfigError
        When most cameras would look *up* with this reading (a source in
        another camera convention): converting them would be wrong.
    """
    grid = matrix_from_opk_deg(opk_deg)
    # the camera looks along its -z axis, whose up component is -r33: down when r33 > 0
    if np.median(grid[:, 2, 2]) <= 0.0:
        raise ConfigError(
            f"{where}: read as PATB omega, phi, kappa (camera x right, y up, looking along -z) "
            "most cameras would look up; the file uses another camera convention, so the "
            "attitudes are not converted (leave out the attitudes or export PATB angles)"
        )
    gamma = grid_convergence_deg(crs, xy)
    enu = _rz(np.deg2rad(-gamma)) @ grid
    return PhotoAttitudes(photo, enu)


# --------------------------------------------------------------------------- strips


def strips_from_positions(
    photos: Sequence[str],
    xyz: FloatArray,
    *,
    turn_deg: float = DEFAULT_TURN_DEG,
) -> tuple[list[tuple[str, ...]], list[str]]:
    """Split a photo track into strips at its turns.

    The photos, in photo-name order (:func:`natural_key`, taken as the order
    of capture), make a track of steps.  Consecutive steps whose headings stay
    within ``turn_deg`` of the mean heading of their run form one run; each
    run of two or more steps is a strip (a run of one step is a turn, unless
    no run is longer).  A photo at the corner of two runs stays in the first.

    Parameters
    ----------
    photos : sequence of str, length M
    xyz : array_like, shape (M, 3)
        Positions in any Cartesian frame (a projected CRS, a site or a model
        frame); only X, Y are used.
    turn_deg : float

    Returns
    -------
    strips : list of tuple of str
        Each strip's photos ordered along its direction of travel.
    dropped : list of str
        Photos in no strip (taken in a turn).

    Raises
    ------
    ConfigError
        When the positions cannot order the photos (all at one place).
    """
    order = sorted(range(len(photos)), key=lambda i: natural_key(photos[i]))
    names = [str(photos[i]) for i in order]
    xy = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)[order, :2]
    if len(names) < 2:
        raise ConfigError(f"cannot form a strip from {len(names)} photo(s)")
    step = np.diff(xy, axis=0)
    length = np.hypot(step[:, 0], step[:, 1])
    extent = float(np.max(np.hypot(*(xy - xy.mean(axis=0)).T)))
    if extent <= 1e-9 * max(1.0, float(np.max(np.abs(xy)))):
        raise ConfigError(
            f"cannot order the {len(names)} photos into strips: their positions all lie at "
            "one place; give the order with --photo-order FILE"
        )
    moving = length > 1e-6 * extent
    unit = np.zeros_like(step)
    unit[moving] = step[moving] / length[moving, None]
    cos_turn = math.cos(math.radians(turn_deg))
    runs: list[list[int]] = []  # [first step, last step, number of moving steps]
    heading = np.zeros(2)
    for i in range(step.shape[0]):  # a loop over the steps of the track: sequential
        if not moving[i]:
            if runs:
                runs[-1][1] = i
            continue
        if (
            runs
            and np.any(heading)
            and float(unit[i] @ (heading / np.linalg.norm(heading))) >= cos_turn
        ):
            runs[-1][1] = i
            runs[-1][2] += 1
            heading = heading + unit[i]
        else:
            runs.append([i if runs else 0, i, 1])  # standing photos before the first run join it
            heading = unit[i].copy()
    if not runs:
        raise ConfigError(
            f"cannot order the {len(names)} photos into strips: they do not move; give the "
            "order with --photo-order FILE"
        )
    min_steps = 2 if any(r[2] >= 2 for r in runs) else 1
    used: set[int] = set()
    strips: list[tuple[str, ...]] = []
    for first, last, count in runs:
        if count < min_steps:
            continue
        piece = [k for k in range(first, last + 2) if k not in used]
        if len(piece) < 2:
            continue
        used.update(piece)
        pts = xy[piece]
        direction = pts[-1] - pts[0]
        along = pts @ direction if np.any(direction) else np.arange(len(piece), dtype=float)
        strips.append(tuple(names[piece[k]] for k in np.argsort(along, kind="stable")))
    dropped = [names[k] for k in range(len(names)) if k not in used]
    if not strips:
        raise ConfigError(
            f"cannot order the {len(names)} photos into strips: the track turns by more than "
            f"{turn_deg:g} deg at every photo; give the order with --photo-order FILE"
        )
    return strips, dropped


def _strip_motion(
    sensor: FloatArray, by_photo: dict[str, IntArray], point: StrArray, photos: Sequence[str]
) -> FloatArray | None:
    """Mean motion of the camera in the sensor axes between consecutive photos.

    The points move in the image opposite to the camera, so the motion is
    minus the median shift of the common points of each pair, averaged over
    the pairs; None when no pair shares a point.
    """
    shifts = []
    for a, b in pairwise(photos):  # a loop over pairs, not points
        ia, ib = by_photo.get(a), by_photo.get(b)
        if ia is None or ib is None:
            continue
        _, ka, kb = np.intersect1d(point[ia], point[ib], assume_unique=True, return_indices=True)
        if ka.size:
            shifts.append(np.median(sensor[ib[kb]] - sensor[ia[ka]], axis=0))
    if not shifts:
        return None
    mean: FloatArray = -np.mean(shifts, axis=0)
    return mean


def decide_flight_direction(
    images: ImageTable,
    frame: ImageFrame,
    strips: Sequence[Strip],
    given: str | None = None,
) -> tuple[str, list[Strip], list[str], list[str]]:
    """The image axis along the flight, and the strips in the order it implies.

    The camera moves between consecutive photos by minus the mean shift of
    their common points in the image.  The axis (x or y) with the larger
    motion is the flight axis, its sign the direction; every strip must move
    along the same axis.  A strip whose photos move the other way along it
    (a strip flown back with the camera's heading kept) is listed in reverse,
    so that x points to the next photo in every strip.

    Parameters
    ----------
    given : {"+x", "-x", "+y", "-y"}, optional
        Use this direction instead of deciding it; strips that move against
        it are still reversed.

    Returns
    -------
    direction, strips, notes, warnings

    Raises
    ------
    ConfigError
        When nothing decides it (no point on two consecutive photos) and it is
        not given, or when strips move along different image axes.
    """
    notes: list[str] = []
    warnings: list[str] = []
    sensor = frame.sensor_mm(images.xy)
    by_photo = images.rows_by_photo()
    motions = [_strip_motion(sensor, by_photo, images.point, s.photos) for s in strips]
    known = [(s, m) for s, m in zip(strips, motions, strict=True) if m is not None]
    if given is None:
        if not known:
            raise ConfigError(
                "cannot decide the flight direction in the image: no point is observed on "
                "two consecutive photos of any strip; give --flight-direction"
            )
        axes = {s.name: int(np.argmax(np.abs(m))) for s, m in known}
        if len(set(axes.values())) > 1:
            along = ", ".join(f"{name}: image {'xy'[a]}" for name, a in axes.items())
            raise ConfigError(
                f"the strips move along different image axes ({along}); a project has one "
                "[images] flight_direction: import those strips separately (--strips)"
            )
        axis = next(iter(axes.values()))
        votes = sum(1 if m[axis] > 0 else -1 for _, m in known)
        sign = "+" if votes > 0 or (votes == 0 and known[0][1][axis] > 0) else "-"
        direction = f"{sign}{'xy'[axis]}"
        notes.append(
            f"flight direction {direction}: the photos move along image {direction} "
            "(minus the mean shift of the points common to consecutive photos)"
        )
    else:
        direction = given
        notes.append(f"flight direction {direction} (given)")
    axis = 0 if direction[1] == "x" else 1
    positive = direction[0] == "+"
    out: list[Strip] = []
    for strip, motion in zip(strips, motions, strict=True):
        if motion is None:
            warnings.append(
                f"strip {strip.name}: no point is seen on two consecutive photos; its photo "
                "order is kept as found"
            )
            out.append(strip)
            continue
        major, minor = abs(motion[axis]), abs(motion[1 - axis])
        if major <= minor:
            warnings.append(
                f"strip {strip.name}: its photos move along image {'xy'[1 - axis]} more than "
                f"along image {'xy'[axis]} (flight direction {direction})"
            )
        elif minor > math.tan(math.radians(30.0)) * major:
            angle = math.degrees(math.atan2(minor, major))
            warnings.append(
                f"strip {strip.name}: its photos move at {angle:.0f} deg to image axis "
                f"{'xy'[axis]}; the flight direction {direction} is the nearest axis"
            )
        if (motion[axis] > 0) != positive:
            out.append(Strip(strip.name, tuple(reversed(strip.photos))))
            notes.append(
                f"strip {strip.name}: photos listed in reverse order, so that image "
                f"{direction} points to the next photo"
            )
        else:
            out.append(strip)
    return direction, out, notes, warnings


# --------------------------------------------------------------------------- control / check


def _default_full(
    control: ControlTable, images: ImageTable, photos: Sequence[str], per_place: int = 2
) -> list[str]:
    """GCPs nearest the start, the middle and the end of one strip, one per side.

    Candidates are the ``full`` points seen on at least 3 photos of the strip
    (2 when fewer than 6 qualify), two of them consecutive: a point the strip
    cannot triangulate is never chosen as control (the samples' strips of
    five photos chose GCPs seen on one photo, half their control lost).
    Their ground X, Y are projected on
    their principal axis, oriented with the photo order; at each of the three
    places the nearest candidate on each side of the axis is chosen.
    """
    strip_photos = np.asarray(photos, dtype=str)
    position = {p: k for k, p in enumerate(photos)}
    full = control.point[control.kind == "full"]
    rows = np.isin(images.photo, strip_photos) & np.isin(images.point, full)
    if not rows.any():
        return []
    pts, inverse, counts = np.unique(images.point[rows], return_inverse=True, return_counts=True)
    index = np.fromiter(
        (position[p] for p in images.photo[rows]), dtype=np.float64, count=int(rows.sum())
    )
    mean_index = np.bincount(inverse, weights=index) / counts
    # on two consecutive photos of the strip: a pair of it triangulates the point
    seen = np.zeros((pts.size, len(photos) + 1), dtype=bool)
    seen[inverse, index.astype(np.intp)] = True
    paired = (seen[:, :-1] & seen[:, 1:]).any(axis=1)
    for need in (3, 2):
        keep = (counts >= need) & paired
        if keep.sum() >= 3 * per_place:
            break
    pts, mean_index = pts[keep], mean_index[keep]
    if pts.size <= 3 * per_place:
        return [str(p) for p in pts]
    lookup = {p: k for k, p in enumerate(control.point)}
    xy = control.xyz[[lookup[p] for p in pts], :2]
    centred = xy - xy.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    axis = vt[0]
    t = centred @ axis
    if np.ptp(mean_index) > 0 and np.ptp(t) > 0 and np.corrcoef(t, mean_index)[0, 1] < 0:
        t = -t  # the start of the strip is where its first photos see the ground
    side = centred @ np.array([-axis[1], axis[0]]) > 0
    chosen: list[int] = []
    for place in (t.min(), 0.5 * (t.min() + t.max()), t.max()):
        for want in (True, False):
            free = np.array([k not in chosen for k in range(pts.size)])
            pool = free & (side == want)
            if not pool.any():
                pool = free
            if not pool.any():
                break
            cand = np.flatnonzero(pool)
            chosen.append(int(cand[np.argmin(np.abs(t[cand] - place))]))
    return [str(pts[k]) for k in chosen]


def split_control(
    control: ControlTable,
    images: ImageTable,
    strips: Sequence[Strip],
    control_ids: Sequence[str] | None = None,
    check_ids: Sequence[str] | None = None,
) -> tuple[ControlTable, list[str]]:
    """The final type of every control point.

    * ``control_ids`` and ``check_ids`` both given: those types; every other
      point is left out.
    * ``control_ids`` alone: those keep their type (full, plan or height),
      every other point is a check point.
    * ``check_ids`` alone: those are check points, the others keep theirs.
    * neither: the source's own types when it has them (``typed``); else per
      strip the full points nearest its start, middle and end, one on each
      side of the strip axis (:func:`_default_full`), and every other point
      is a check point.

    Raises
    ------
    ConfigError
        An id that is not an observed control point, or an id in both lists.
    """
    notes: list[str] = []
    known = set(control.point.tolist())
    for option, ids in (("--control", control_ids), ("--check", check_ids)):
        for pid in ids or ():
            if pid not in known:
                listed = ", ".join(sorted(known, key=natural_key)[:12])
                raise ConfigError(
                    f"{option}: '{pid}' is not a control point observed on the imported "
                    f"photos (observed: {listed}{', ...' if len(known) > 12 else ''})"
                )
    both = set(control_ids or ()) & set(check_ids or ())
    if both:
        raise ConfigError(f"--control and --check both name {', '.join(sorted(both))}")
    assert control.kind is not None  # filled in by ControlTable
    kind = control.kind.copy()
    keep = np.ones(len(control), dtype=bool)
    if control_ids is not None or check_ids is not None:
        is_control = np.isin(control.point, list(control_ids or ()))
        is_check = np.isin(control.point, list(check_ids or ()))
        kind[is_control & (kind == "check")] = "full"
        kind[is_check] = "check"
        if control_ids is not None and check_ids is not None:
            keep = is_control | is_check
            if (~keep).any():
                notes.append(
                    f"{int((~keep).sum())} control point(s) in neither --control nor --check "
                    "left out"
                )
        elif control_ids is not None:
            kind[~is_control] = "check"
        notes.append("control and check points as given on the command line")
    elif control.typed:
        notes.append("control and check points as the source marks them")
    else:
        chosen: set[str] = set()
        for strip in strips:
            chosen.update(_default_full(control, images, strip.photos))
        is_full = np.isin(control.point, sorted(chosen))
        kind[(kind == "full") & ~is_full] = "check"
        listed = ", ".join(sorted(chosen, key=natural_key))
        notes.append(
            f"full control: {listed} (per strip the GCPs nearest its start, middle and end, "
            "one on each side of the strip axis, among those seen on 3 or more photos, "
            "2 when fewer qualify, two of them consecutive); "
            "every other GCP is a check point (change with --control / --check)"
        )
    table = control.take(np.flatnonzero(keep))
    return ControlTable(
        table.point, table.xyz, kind[keep], True, table.sigma_xy, table.sigma_h
    ), notes


# --------------------------------------------------------------------------- assembling


def _equirectangular(xyz: FloatArray) -> FloatArray:
    """Longitude, latitude (degrees) to metres on a sphere about their mean latitude."""
    lat0 = np.deg2rad(np.mean(xyz[:, 1]))
    metres = np.deg2rad(1.0) * 6371000.0
    return np.column_stack([xyz[:, 0] * metres * np.cos(lat0), xyz[:, 1] * metres, xyz[:, 2]])


def _check_ids(values: StrArray, what: str, source: str) -> None:
    empty = np.char.str_len(values) == 0 if values.size else np.zeros(0, bool)
    if empty.any():
        raise ConfigError(f"{source}: an empty {what} id")


def assemble(
    source: str,
    images: ImageTable,
    frame: ImageFrame,
    camera: Camera,
    control: ControlTable,
    crs: str,
    options: ImportOptions,
    *,
    inputs: Sequence[Path],
    default_name: str,
    distortion: Distortion | None = None,
    strips: Sequence[Strip] | None = None,
    track: PhotoPositions | None = None,
    track_crs: str | None = None,
    gnss: PhotoPositions | None = None,
    imu: PhotoAttitudes | None = None,
    notes: Sequence[str] = (),
    warnings: Sequence[str] = (),
) -> ImportedProject:
    """Decide strips, photo order, flight direction and control types; keep what they use.

    Length: every importer's decisions in the order they depend on each
    other (ids, strips, order, direction, control types, what is kept), each
    one a call or a few lines, written once for all formats.

    Parameters
    ----------
    source : str
        The format and its files, for messages and the header comment.
    images, frame, camera, control, crs
        What the importer read.
    options : ImportOptions
    inputs : sequence of Path
        Every file read.
    default_name : str
        Project name when ``options.name`` is None.
    distortion : Distortion, optional
    strips : sequence of Strip, optional
        Strips the source defines (else from ``options.photo_order``, else
        from ``track``, else one strip in photo-name order).
    track : PhotoPositions, optional
        Positions of the photos, to find the strips: in any Cartesian frame,
        or in ``track_crs``.
    track_crs : str, optional
        The CRS of ``track`` when it is the project's; longitude and latitude
        of a geographic CRS are scaled to metres first.
    gnss : PhotoPositions, optional
        Projection centres in ``crs`` (written as ``gnss.csv``).
    imu : PhotoAttitudes, optional
        Attitudes (written as ``imu.csv`` in the flight axes).

    Raises
    ------
    ConfigError
        Duplicated observations, unknown photo ids, nothing left to adjust,
        undecidable order or flight direction, or bad ``options``.
    """
    notes = list(notes)
    warnings = list(warnings)
    _check_ids(images.photo, "photo", source)
    _check_ids(images.point, "point", source)
    _check_ids(control.point, "control point", source)
    pair = np.char.add(np.char.add(images.photo, "\x00"), images.point)
    _, first, counts = np.unique(pair, return_index=True, return_counts=True)
    if (counts > 1).any():
        k = int(first[np.flatnonzero(counts > 1)[0]])
        raise ConfigError(
            f"{source}: point '{images.point[k]}' is observed twice on photo '{images.photo[k]}'"
        )
    names, counts = np.unique(control.point, return_counts=True)
    if (counts > 1).any():
        raise ConfigError(
            f"{source}: control point '{names[np.flatnonzero(counts > 1)[0]]}' is listed twice"
        )

    observed = np.unique(images.photo)
    turn_photos: set[str] = set()
    if options.photo_order is not None:
        listed = [p for s in options.photo_order for p in s]
        unknown = np.asarray(listed, dtype=str)[~np.isin(listed, observed)]
        if unknown.size:
            raise ConfigError(
                f"--photo-order: photo '{unknown[0]}' has no image observations in {source}"
            )
        strip_list = [Strip(str(k + 1), tuple(s)) for k, s in enumerate(options.photo_order)]
        notes.append("strips and photo order as given by --photo-order")
    elif strips is not None:
        strip_list = list(strips)
    elif track is not None and np.isin(observed, track.photo).all():
        rows = np.searchsorted(track.photo, observed, sorter=np.argsort(track.photo))
        xyz = track.xyz[np.argsort(track.photo)[rows]]
        if track_crs is not None and _is_geographic(track_crs):
            xyz = _equirectangular(xyz)
        found, dropped = strips_from_positions(observed.tolist(), xyz, turn_deg=options.turn_deg)
        strip_list = [Strip(str(k + 1), s) for k, s in enumerate(found)]
        notes.append(
            f"{len(strip_list)} strip(s) from the photo positions: the track (photos in "
            f"name order) split where its heading turns by more than {options.turn_deg:g} deg"
        )
        if dropped:
            turn_photos = set(dropped)
            warnings.append(
                f"photo(s) taken in turns left out (a strip needs 2 photos): {', '.join(dropped)}"
            )
    else:
        if track is not None:
            warnings.append("not every photo has a position: strips not found from positions")
        ordered = tuple(sorted(observed.tolist(), key=natural_key))
        strip_list = [Strip("1", ordered)]
        notes.append("one strip, photos in photo-name order (no positions to order them)")

    seen: dict[str, str] = {}
    for strip in strip_list:
        for p in strip.photos:
            if p in seen:
                raise ConfigError(f"photo '{p}' is in strips {seen[p]} and {strip.name}")
            seen[p] = strip.name
    has_obs = set(observed.tolist())
    missing = [p for s in strip_list for p in s.photos if p not in has_obs]
    if missing:
        warnings.append(f"photo(s) without image observations left out: {', '.join(missing)}")
        strip_list = [
            Strip(s.name, tuple(p for p in s.photos if p in has_obs)) for s in strip_list
        ]

    if options.strips is not None:
        bad = [n for n in options.strips if not 1 <= n <= len(strip_list)]
        if bad:
            raise ConfigError(
                f"--strips: no strip {bad[0]}; the source has {len(strip_list)} strip(s) "
                f"({', '.join(s.name for s in strip_list)})"
            )
        strip_list = [strip_list[n - 1] for n in dict.fromkeys(options.strips)]
    short = [s.name for s in strip_list if len(s.photos) < 2]
    if short:
        raise ConfigError(f"strip {short[0]} has fewer than 2 photos with image observations")

    in_strips = np.asarray([p for s in strip_list for p in s.photos], dtype=str)
    left_out = np.setdiff1d(observed, in_strips)
    left_out = left_out[~np.isin(left_out, sorted(turn_photos))]
    if left_out.size and options.strips is None:
        warnings.append(
            f"observations of {left_out.size} photo(s) in no strip left out: "
            f"{', '.join(left_out[:10].tolist())}{', ...' if left_out.size > 10 else ''}"
        )
    images = images.take(np.isin(images.photo, in_strips))

    direction, strip_list, more_notes, more_warnings = decide_flight_direction(
        images, frame, strip_list, options.flight_direction
    )
    notes += more_notes
    warnings += more_warnings

    seen_points = np.unique(images.point)
    observed_control = np.isin(control.point, seen_points)
    if not observed_control.any():
        raise ConfigError(
            f"{source}: none of the {len(control)} control point(s) is observed on the "
            "imported photos; a project needs control"
        )
    if (~observed_control).any():
        notes.append(
            f"{int((~observed_control).sum())} control point(s) not observed on the imported "
            "photos left out"
        )
    control = control.take(np.flatnonzero(observed_control))
    control, more_notes = split_control(
        control, images, strip_list, options.control_ids, options.check_ids
    )
    notes += more_notes
    n_full = int(np.sum(control.kind == "full"))
    if n_full < 4:
        notes.append(
            f"{n_full} full control point(s): the adjustment of every model at once (the "
            "default) needs two in plan and three in height and tests them only with more; "
            'J\'s polynomials (block = "strips") need more still (docs/ground.md)'
        )

    if gnss is not None:
        gnss = gnss.take(np.isin(gnss.photo, in_strips))
        if len(gnss.photo) == 0:
            warnings.append("no GNSS centre belongs to an imported photo: gnss.csv not written")
            gnss = None
    imu_opk = None
    if imu is not None:
        imu = imu.take(np.isin(imu.photo, in_strips))
        if len(imu.photo) == 0:
            warnings.append("no attitude belongs to an imported photo: imu.csv not written")
        else:
            flight = flight_matrix(direction)
            imu_opk = (imu.photo, opk_deg_from_matrix(imu.matrix @ flight.T))
            notes.append(
                "IMU attitudes: R = Rx(omega) Ry(phi) Rz(kappa) mapping image vectors in the "
                "flight axes to local east-north-up (docs/conventions.md)"
            )
    if options.sigma_mm is not None:
        frame = ImageFrame(
            frame.units, frame.pixel_size_mm, frame.principal_point_px, options.sigma_mm
        )
    return ImportedProject(
        source=source,
        name=options.name or default_name,
        strips=tuple(strip_list),
        camera=camera,
        frame=frame,
        flight_direction=direction,
        images=images,
        control=control,
        crs=crs,
        distortion=distortion,
        gnss=gnss,
        imu_opk_deg=imu_opk,
        notes=tuple(notes),
        warnings=tuple(warnings),
        inputs=tuple(Path(p) for p in inputs),
    )


# --------------------------------------------------------------------------- writing


def toml_string(text: str) -> str:
    """A TOML basic string."""
    out = []
    for ch in str(text):
        if ch in ('"', "\\"):
            out.append("\\" + ch)
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_value(value: object) -> str:
    """A TOML value for a str, bool, int, finite float or a list of them."""
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        f = float(value)
        if not math.isfinite(f):
            raise ValueError(f"TOML has no value for {f!r}")
        return repr(f)
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    raise TypeError(f"no TOML form for {type(value).__name__}")


def _toml_id_list(ids: Sequence[str], per_line: int = 6) -> str:
    items = [toml_string(i) for i in ids]
    if len(items) <= per_line:
        return "[" + ", ".join(items) + "]"
    lines = [", ".join(items[k : k + per_line]) for k in range(0, len(items), per_line)]
    return "[\n    " + ",\n    ".join(lines) + ",\n]"


def _comment(text: str) -> list[str]:
    return ["# " + line if line else "#" for line in str(text).splitlines()]


def project_toml(project: ImportedProject) -> str:
    """The text of ``strip.toml`` for ``project``."""
    p = project
    lines = [f"# Written by `stripaero import` from {p.source}."]
    lines += [f"# {s}" for s in (n.replace("\n", " ") for n in p.notes)]
    lines.append("")
    if len(p.strips) == 1:
        lines += ["[strip]", f"name = {toml_string(p.name)}"]
        lines.append(f"photos = {_toml_id_list(p.strips[0].photos)}")
    else:
        lines += ["[project]", f"name = {toml_string(p.name)}", ""]
        for strip in p.strips:
            lines += ["[[strips]]", f"name = {toml_string(strip.name)}"]
            lines.append(f"photos = {_toml_id_list(strip.photos)}")
    lines += [
        "",
        "[camera]",
        f"principal_distance_mm = {toml_value(p.camera.principal_distance_mm)}",
    ]
    if p.camera.principal_point_mm is not None:
        lines.append(f"principal_point_mm = {toml_value(list(p.camera.principal_point_mm))}")
    f = p.frame
    lines += ["", "[images]", 'file = "image_points.csv"']
    if f.units == "pixel" or (f.pixel_size_mm is not None and f.principal_point_px is not None):
        if f.units == "pixel":
            lines.append('units = "pixel"')
        else:
            lines.append("# where the mm origin lies in the pixels (for export odm)")
        lines += [
            f"pixel_size_mm = {toml_value(float(f.pixel_size_mm))}",  # type: ignore[arg-type]
            f"principal_point_px = {toml_value([float(v) for v in f.principal_point_px])}",  # type: ignore[union-attr]
        ]
    lines.append(f"flight_direction = {toml_string(p.flight_direction)}")
    sigma = f.sigma_mm if f.sigma_mm is not None else f.pixel_size_mm
    if sigma is not None:
        if f.sigma_mm is None:
            lines.append("# one pixel")
        lines.append(f"sigma_mm = {toml_value(float(sigma))}")
    d = p.distortion
    if d is not None and not d.is_zero:
        lines += ["", "[distortion]"]
        lines += _comment(d.comment) if d.comment else []
        for key in ("k1", "k2", "k3", "p1", "p2"):
            value = getattr(d, key)
            if value:
                lines.append(f"{key} = {toml_value(float(value))}")
        lines += [f"units = {toml_string(d.units)}", f"model = {toml_string(d.model)}"]
    lines += ["", "[control]", 'file = "control.csv"', f"crs = {toml_string(p.crs)}"]
    if p.gnss is not None or p.imu_opk_deg is not None:
        lines += [
            "",
            "[adjustment]",
            "# GNSS centres and IMU attitudes are observations of the bundle refinement",
            'refine = "bundle"',
        ]
    if p.gnss is not None:
        lines += ["", "[gnss]", 'file = "gnss.csv"']
    if p.imu_opk_deg is not None:
        lines += ["", "[imu]", 'file = "imu.csv"']
    return "\n".join(lines) + "\n"


def _csv_text(values: StrArray) -> StrArray:
    """Ids as CSV fields, quoted where a comma, a quote or a leading '#' needs it."""
    v = np.asarray(values, dtype=str)
    if v.size == 0:
        return v
    needs = (np.char.find(v, ",") >= 0) | (np.char.find(v, '"') >= 0) | np.char.startswith(v, "#")
    if needs.any():
        quoted = np.char.add(np.char.add('"', np.char.replace(v, '"', '""')), '"')
        v = np.where(needs, quoted, v)
    return v


def _numbers(values: FloatArray, fmt: str) -> StrArray:
    """``values`` formatted with ``fmt``; NaN gives an empty cell."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.size == 0:
        return np.empty(0, dtype=str)
    text = np.char.mod(fmt, np.where(np.isnan(arr), 0.0, arr))
    return np.where(np.isnan(arr), "", text)


def _join(columns: Sequence[StrArray]) -> list[str]:
    out = np.asarray(columns[0], dtype=str)
    for col in columns[1:]:
        out = np.char.add(np.char.add(out, ","), np.asarray(col, dtype=str))
    return [str(v) for v in out]


def _table(header: str, columns: Sequence[StrArray]) -> str:
    return "\n".join([header, *_join(columns)]) + "\n"


def _is_geographic(crs: str) -> bool:
    if crs.strip().lower() == "local":
        return False
    from pyproj import CRS

    try:
        return bool(CRS.from_user_input(crs).is_geographic)
    except Exception:  # the loader reports a bad CRS with its own message
        return False


def project_files(project: ImportedProject) -> dict[str, str]:
    """The text of every file of the project, by file name."""
    p = project
    files = {"strip.toml": project_toml(p)}
    img = p.images
    order = np.lexsort((img.point, img.photo))  # stable, reproducible output
    img = img.take(order)
    xy_fmt = "%.9f" if p.frame.units == "mm" else "%.6f"
    cols = [
        _csv_text(img.photo),
        _csv_text(img.point),
        _numbers(img.xy[:, 0], xy_fmt),
        _numbers(img.xy[:, 1], xy_fmt),
    ]
    header = "photo,point,x,y"
    if img.sigma_mm is not None and np.isfinite(img.sigma_mm).any():
        cols.append(_numbers(img.sigma_mm, "%.9f"))
        header += ",sigma"
    files["image_points.csv"] = _table(header, cols)

    c = p.control
    geographic = _is_geographic(p.crs)
    xy_fmt = "%.10f" if geographic else "%.6f"
    cols = [
        _csv_text(c.point),
        _numbers(c.xyz[:, 0], xy_fmt),
        _numbers(c.xyz[:, 1], xy_fmt),
        _numbers(c.xyz[:, 2], "%.6f"),
        np.asarray(c.kind, dtype=str),
    ]
    header = "point,X,Y,H,type"
    for name in ("sigma_xy", "sigma_h"):
        value = getattr(c, name)
        if value is not None and np.isfinite(value).any():
            cols.append(_numbers(value, "%.6f"))
            header += f",{name}"
    files["control.csv"] = _table(header, cols)

    if p.gnss is not None:
        g = p.gnss
        cols = [
            _csv_text(g.photo),
            _numbers(g.xyz[:, 0], xy_fmt),
            _numbers(g.xyz[:, 1], xy_fmt),
            _numbers(g.xyz[:, 2], "%.6f"),
        ]
        header = "photo,X,Y,Z"
        for name in ("sigma_xy", "sigma_z"):
            value = getattr(g, name)
            if value is not None and np.isfinite(value).any():
                cols.append(_numbers(value, "%.6f"))
                header += f",{name}"
        files["gnss.csv"] = _table(header, cols)
    if p.imu_opk_deg is not None:
        photo, opk = p.imu_opk_deg
        cols = [_csv_text(photo)] + [_numbers(opk[:, k], "%.9f") for k in range(3)]
        files["imu.csv"] = _table("photo,omega,phi,kappa", cols)
    return files


def _check_target(out: Path, inputs: Sequence[Path], force: bool) -> None:
    if out.is_symlink():
        raise ConfigError(f"output folder '{out}' is a symbolic link; give the real folder")
    target = out.resolve()
    for item in inputs:
        path = Path(item).resolve()
        if path == target or target in path.parents:
            raise ConfigError(
                f"output folder '{out}' contains the input file '{item}'; choose another --out"
            )
    cwd = Path.cwd().resolve()
    if cwd == target or target in cwd.parents:
        raise ConfigError(
            f"output folder '{out}' contains the current folder; choose another --out"
        )
    if out.exists():
        if not out.is_dir():
            raise ConfigError(f"output folder '{out}' is a file")
        if any(out.iterdir()) and not force:
            raise ConfigError(
                f"output folder '{out}' exists and is not empty; give --force to replace it"
            )


def write_project(project: ImportedProject, out_dir: str | Path, *, force: bool = False) -> Path:
    """Write ``project`` into ``out_dir`` atomically; return the path of strip.toml.

    The files are written into a hidden temporary folder beside ``out_dir``,
    which then replaces ``out_dir`` by renames; on any failure the temporary
    folder is removed and ``out_dir`` is left as it was.

    Raises
    ------
    ConfigError
        ``out_dir`` exists and is not empty and ``force`` is False; it is a
        file or a symbolic link; it contains an input file or the current
        folder.
    """
    out = Path(out_dir)
    _check_target(out, project.inputs, force)
    files = project_files(project)
    parent = out.resolve().parent
    parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=parent))
    old: Path | None = None
    try:
        for name, text in files.items():
            (tmp / name).write_text(text, encoding="utf-8", newline="\n")
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".old", dir=parent))
            old.rmdir()
            os.rename(out, old)
            try:
                os.rename(tmp, out)
            except BaseException:
                os.rename(old, out)
                old = None
                raise
        else:
            os.rename(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)
    return out / "strip.toml"
