"""The data an importer reads (image observations, control, camera, positions,
attitudes) and what it gives: :class:`ImportOptions` and
:class:`ImportedProject`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from collections.abc import Sequence
from dataclasses import dataclass
from dataclasses import field
from pathlib import Path

import numpy as np

from .._typing import BoolArray, FloatArray, IntArray, StrArray
from ..errors import ConfigError
from ..options import FlightDirection

__all__ = [
    "Camera",
    "ControlTable",
    "DEFAULT_TURN_DEG",
    "Distortion",
    "FLIGHT_DIRECTIONS",
    "ImageFrame",
    "ImageTable",
    "ImportOptions",
    "ImportedProject",
    "PhotoAttitudes",
    "PhotoPositions",
    "Strip",
]


FLIGHT_DIRECTIONS = tuple(d.value for d in FlightDirection)
DEFAULT_TURN_DEG = 45.0


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
