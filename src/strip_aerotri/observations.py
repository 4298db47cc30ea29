"""Image observations and ground control as plain arrays.

These two containers are what the numerical modules consume; :mod:`config`
and :mod:`io` build them from a project, :mod:`simulate` builds them from a
known truth.  Ids are kept as strings (leading zeros matter); numerical work
uses integer indices into ``photo_ids`` and ``point_ids``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import Enum
from functools import cached_property

import numpy as np

from ._typing import ArrayLike, BoolArray, FloatArray, Int8Array, IntArray
from .options import DEFAULT_IMAGE_SIGMA_MM, DEFAULT_LINE_WEIGHT

__all__ = [
    "ControlPoints",
    "ControlType",
    "GnssCentres",
    "ImageObservations",
    "ImuAttitudes",
    "LineSpec",
    "StripSpec",
]


@dataclass(frozen=True)
class ImageObservations:
    """Measured image coordinates of points on the photos of one strip.

    Attributes
    ----------
    photo_ids : tuple of str, length M
        Photos in strip (flight) order.
    point_ids : tuple of str, length P
        Every point id that occurs, in a fixed order.
    photo : ndarray of int, shape (K,)
        Index into ``photo_ids`` of each observation.
    point : ndarray of int, shape (K,)
        Index into ``point_ids`` of each observation.
    xy : ndarray, shape (K, 2)
        Image coordinates in millimetres, reduced to the principal point, in
        the image system of method.md section 2 (x along the flight, y to its
        left).
    sigma : ndarray, shape (K,)
        Standard deviation of each coordinate in millimetres (weights are
        ``1 / sigma**2``).
    principal_distance : float
        c in millimetres; the image vector of an observation is (x, y, -c).
    source_line : ndarray of int, shape (K,), optional
        Line number of each observation in its input file (0 when unknown), so
        that messages can name it.

    Observations are sorted by photo index, then by point index; use
    :meth:`from_ids` to build one from unsorted rows.
    """

    photo_ids: tuple[str, ...]
    point_ids: tuple[str, ...]
    photo: IntArray
    point: IntArray
    xy: FloatArray
    sigma: FloatArray
    principal_distance: float
    source_line: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))

    @classmethod
    def from_ids(
        cls,
        photo: ArrayLike,
        point: ArrayLike,
        xy: ArrayLike,
        principal_distance: float,
        *,
        photo_ids: ArrayLike | None = None,
        sigma: ArrayLike | float = DEFAULT_IMAGE_SIGMA_MM,
        source_line: ArrayLike | None = None,
    ) -> ImageObservations:
        """Build from one row per observation with string ids.

        Parameters
        ----------
        photo, point : array_like of str, shape (K,)
            Photo id and point id of each observation.
        xy : array_like, shape (K, 2)
            Image coordinates in mm reduced to the principal point.
        principal_distance : float
            c in mm.
        photo_ids : sequence of str, optional
            Strip order of the photos; default: order of first appearance.
            Observations on photos not listed are dropped.
        sigma : float or array_like, shape (K,)
            Image coordinate standard deviation in mm (default 5 µm).
        source_line : array_like of int, shape (K,), optional
            Input line numbers, for messages.
        """
        photo = np.asarray(photo, dtype=str)
        point = np.asarray(point, dtype=str)
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        k = photo.shape[0]
        if point.shape != (k,) or xy.shape[0] != k:
            raise ValueError(
                f"Expected photo, point and xy to have K rows, got {photo.shape}, "
                f"{point.shape}, {xy.shape}"
            )
        sigma_arr = np.broadcast_to(np.asarray(sigma, dtype=np.float64), (k,)).copy()
        lines = (
            np.zeros(k, dtype=np.intp)
            if source_line is None
            else np.asarray(source_line, dtype=np.intp).reshape(k)
        )
        if photo_ids is None:
            _, first = np.unique(photo, return_index=True)
            order_ids = tuple(str(p) for p in photo[np.sort(first)])
        else:
            order_ids = tuple(str(p) for p in np.asarray(photo_ids, dtype=str))
        lookup = {pid: i for i, pid in enumerate(order_ids)}
        names, inverse = np.unique(photo, return_inverse=True)
        name_index = np.array([lookup.get(str(n), -1) for n in names], dtype=np.intp)
        photo_index = name_index[inverse.reshape(-1)] if k else np.zeros(0, np.intp)
        keep = photo_index >= 0
        point_names, point_index = np.unique(point[keep], return_inverse=True)
        photo_index = photo_index[keep]
        order = np.lexsort((point_index, photo_index))
        return cls(
            photo_ids=order_ids,
            point_ids=tuple(str(p) for p in point_names),
            photo=photo_index[order],
            point=point_index.astype(np.intp)[order],
            xy=xy[keep][order],
            sigma=sigma_arr[keep][order],
            principal_distance=float(principal_distance),
            source_line=lines[keep][order],
        )

    @property
    def n_photos(self) -> int:
        return len(self.photo_ids)

    @property
    def n_points(self) -> int:
        return len(self.point_ids)

    def image_vectors(self, rows: IntArray | None = None) -> FloatArray:
        """Image vectors ``(x, y, -c)`` in mm, shape (K, 3), or of the
        observations ``rows`` only (int array, shape (n,)), shape (n, 3)."""
        xy = self.xy if rows is None else np.take(self.xy, rows, axis=0)
        out = np.empty((xy.shape[0], 3))
        out[:, :2] = xy
        out[:, 2] = -self.principal_distance
        return out

    def photo_slices(self) -> IntArray:
        """Start offsets of each photo's observations, shape (M + 1,)."""
        return np.searchsorted(self.photo, np.arange(self.n_photos + 1)).astype(np.intp)


class ControlType(str, Enum):
    """Role of a ground point: which coordinates enter the adjustment."""

    FULL = "full"
    PLAN = "plan"
    HEIGHT = "height"
    CHECK = "check"


_KIND_CODE = {key: code for code, kind in enumerate(ControlType) for key in (kind, kind.value)}


@dataclass(frozen=True)
class ControlPoints:
    """Ground control and check points.

    Attributes
    ----------
    point_ids : tuple of str, length N
    xyz : ndarray, shape (N, 3)
        X, Y, H in the control CRS (easting, northing or longitude, latitude in
        degrees, then ellipsoidal height in metres); NaN where not given.
    kind : tuple of ControlType, length N
    sigma_xy, sigma_h : ndarray, shape (N,)
        Standard deviations in metres.
    source_line : ndarray of int, shape (N,)
    """

    point_ids: tuple[str, ...]
    xyz: FloatArray
    kind: tuple[ControlType, ...]
    sigma_xy: FloatArray
    sigma_h: FloatArray
    source_line: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.intp))

    @cached_property
    def _kind_code(self) -> Int8Array:
        """``kind`` as small integers (the position in ControlType), read-only:
        the masks below are array comparisons, not a Python pass per point."""
        try:
            code = np.fromiter(map(_KIND_CODE.__getitem__, self.kind), np.int8, len(self.kind))
        except KeyError as exc:
            kinds = [k.value for k in ControlType]
            raise ValueError(f"Expected control kinds from {kinds}, got {exc}") from None
        code.setflags(write=False)
        return code

    @property
    def uses_xy(self) -> BoolArray:
        """True where X and Y enter the adjustment (full and plan points)."""
        code = self._kind_code
        mask: BoolArray = (code == _KIND_CODE[ControlType.FULL]) | (
            code == _KIND_CODE[ControlType.PLAN]
        )
        return mask

    @property
    def uses_h(self) -> BoolArray:
        """True where H enters the adjustment (full and height points)."""
        code = self._kind_code
        mask: BoolArray = (code == _KIND_CODE[ControlType.FULL]) | (
            code == _KIND_CODE[ControlType.HEIGHT]
        )
        return mask

    @property
    def is_check(self) -> BoolArray:
        mask: BoolArray = self._kind_code == _KIND_CODE[ControlType.CHECK]
        return mask


@dataclass(frozen=True)
class StripSpec:
    """One strip of a block: its name and its photos in flight order.

    Attributes
    ----------
    name : str
    photo_ids : tuple of str
    """

    name: str
    photo_ids: tuple[str, ...]


@dataclass(frozen=True)
class LineSpec:
    """Points on one straight vertical plane along the strip (J(18)).

    Attributes
    ----------
    point_ids : tuple of str
        Ids of the points, each observed and none a control point.
    weight : float
        Weight of the line equations relative to control of weight 1.
    name : str
        Name for reports.
    """

    point_ids: tuple[str, ...]
    weight: float = DEFAULT_LINE_WEIGHT
    name: str = "line"


@dataclass(frozen=True)
class GnssCentres:
    """Observed projection centres (GNSS, reduced to the projection centre).

    Attributes
    ----------
    photo_ids : tuple of str, length G
    xyz : ndarray, shape (G, 3)
        X, Y, H in the control CRS (axis order as the control, H ellipsoidal
        height in metres).
    sigma_xy, sigma_z : ndarray, shape (G,)
        Standard deviations in metres, horizontal and vertical.
    """

    photo_ids: tuple[str, ...]
    xyz: FloatArray
    sigma_xy: FloatArray
    sigma_z: FloatArray

    def __post_init__(self) -> None:
        ids = tuple(str(p) for p in self.photo_ids)
        g = len(ids)
        xyz = np.asarray(self.xyz, dtype=np.float64)
        if xyz.shape != (g, 3):
            raise ValueError(f"Expected `xyz` to have shape {(g, 3)}, got {xyz.shape}")
        sxy = np.broadcast_to(np.asarray(self.sigma_xy, dtype=np.float64), (g,)).copy()
        sz = np.broadcast_to(np.asarray(self.sigma_z, dtype=np.float64), (g,)).copy()
        if not (np.all(sxy > 0) and np.all(sz > 0)):
            raise ValueError("Expected positive GNSS standard deviations `sigma_xy`, `sigma_z`")
        object.__setattr__(self, "photo_ids", ids)
        object.__setattr__(self, "xyz", xyz)
        object.__setattr__(self, "sigma_xy", sxy)
        object.__setattr__(self, "sigma_z", sz)


@dataclass(frozen=True)
class ImuAttitudes:
    """Observed photo attitudes (IMU, boresight-corrected).

    Attributes
    ----------
    photo_ids : tuple of str, length G
    opk : ndarray, shape (G, 3)
        omega, phi, kappa in radians, ``R = Rx(omega) Ry(phi) Rz(kappa)``
        mapping image vectors to local east-north-up at the projection centre
        (the convention of ``photos.csv``; X, Y, H axes for ``crs = "local"``).
    sigma : ndarray, shape (G,)
        Standard deviation of each of the three small rotations about the
        photo's own axes, radians.

    Use :meth:`from_degrees` for angles in degrees.
    """

    photo_ids: tuple[str, ...]
    opk: FloatArray
    sigma: FloatArray

    def __post_init__(self) -> None:
        ids = tuple(str(p) for p in self.photo_ids)
        g = len(ids)
        opk = np.asarray(self.opk, dtype=np.float64)
        if opk.shape != (g, 3):
            raise ValueError(f"Expected `opk` to have shape {(g, 3)}, got {opk.shape}")
        sig = np.broadcast_to(np.asarray(self.sigma, dtype=np.float64), (g,)).copy()
        if not np.all(sig > 0):
            raise ValueError("Expected positive IMU standard deviations `sigma`")
        object.__setattr__(self, "photo_ids", ids)
        object.__setattr__(self, "opk", opk)
        object.__setattr__(self, "sigma", sig)

    @classmethod
    def from_degrees(
        cls, photo_ids: Sequence[str], opk_deg: ArrayLike, sigma_deg: ArrayLike
    ) -> ImuAttitudes:
        """Build from omega, phi, kappa and their sigma in degrees."""
        return cls(
            tuple(photo_ids),
            np.radians(np.asarray(opk_deg, dtype=np.float64)),
            np.radians(np.asarray(sigma_deg, dtype=np.float64)),
        )
