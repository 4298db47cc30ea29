"""Cartesian frames on the ground: the local tangent frame and the work frames.

:class:`LocalTangentFrame` is the intermediate local tangent system of the
geocentric route, B(142)-(144), B(152).  A *work frame* is the Cartesian
frame a ground stage adjusts in, with its way from and to the control CRS:

* :class:`TangentWorkFrame` -- a local tangent frame (the geocentric route,
  and the bundle refinement), or the site system itself for ``crs = "local"``;
* :class:`ProjectedWorkFrame` -- the map grid rotated by the strip's azimuth,
  heights on the tangent plane at the centre of the net with the
  earth-curvature term B(153) (the projected route).

Both map CRS coordinates (N, 3) to work coordinates (N, 3) in metres and back,
and give the rotation from a photo's work-frame attitude to local east,
north, up at its projection centre, the convention of ``photos.csv``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._rows import add_to_columns
from ._typing import ArrayLike, FloatArray
from .geodesy import (
    GroundCRS,
    _angle,
    _as_rows,
    azimuth_from_local_enu,
    enu_rotation,
    gaussian_mean_radius,
)
from .geometry.rotation import matrix_from_rotvec
from .options import Route

__all__ = [
    "LocalTangentFrame",
    "ProjectedWorkFrame",
    "TangentWorkFrame",
    "WorkFrame",
    "enu_residuals",
    "make_work_frame",
]


def _frame_rotation(latitude: float, longitude: float, azimuth: float) -> FloatArray:
    """Rows X, Y, Z of the B(143) frame in ECEF ([fix] signs of b1 and a2)."""
    east, north, up = enu_rotation(latitude, longitude)
    ca, sa = math.cos(azimuth), math.sin(azimuth)
    x_axis = north * ca + east * sa
    y_axis = north * sa - east * ca
    return np.stack([x_axis, y_axis, up])


@dataclass(frozen=True, eq=False)
class LocalTangentFrame:
    """The intermediate local tangent system of the geocentric route, B(142)-(144), B(152).

    Origin ``origin_ecef``; Z along the ellipsoid normal at (B0, L0); X
    horizontal at azimuth A0 (clockwise from north); Y = Z × X, i.e. to the
    left of X, like the photos' y.  With ``n``, ``e``, ``u`` the north, east,
    up unit vectors at (B0, L0):

    ``X = n cosA0 + e sinA0``, ``Y = n sinA0 − e cosA0``, ``Z = u``.

    The rows of :attr:`rotation` are X, Y, Z in ECEF, i.e. the rows are
    (a1, b1, c1), (a2, b2, c2), (a3, b3, c3) of B(143) with the [fix] of
    method.md §6.2 (signs of b1 and a2), so ``local = (ecef − origin) @ rotation.T``
    is B(144) and ``ecef = origin + local @ rotation`` is B(152).

    Parameters
    ----------
    origin_ecef : array_like, shape (3,)
        Geocentric origin in metres (need not lie on the ellipsoid: B(142)
        puts it at the mean of the control's geocentric coordinates).
    latitude, longitude : float
        B0, L0 in radians: the normal that defines Z.
    azimuth : float
        A0 in radians, direction of the frame's X axis clockwise from north.

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        ECEF → local rotation (rows X, Y, Z), computed; read-only.
    """

    origin_ecef: FloatArray
    latitude: float
    longitude: float
    azimuth: float
    rotation: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        origin = np.array(self.origin_ecef, dtype=np.float64)
        if origin.shape != (3,) or not np.all(np.isfinite(origin)):
            raise ValueError(
                "Expected `origin_ecef` to be finite with shape (3,), "
                f"got {np.shape(self.origin_ecef)}."
            )
        angles = {}
        for name in ("latitude", "longitude", "azimuth"):
            value = float(getattr(self, name))
            if not math.isfinite(value):
                raise ValueError(f"Expected `{name}` to be finite, got {value!r}.")
            angles[name] = value
        if abs(angles["latitude"]) > math.pi / 2:
            raise ValueError(f"Expected |latitude| <= pi/2 rad, got {angles['latitude']!r}.")
        origin.setflags(write=False)
        rotation = _frame_rotation(angles["latitude"], angles["longitude"], angles["azimuth"])
        rotation.setflags(write=False)
        object.__setattr__(self, "origin_ecef", origin)
        for name, value in angles.items():
            object.__setattr__(self, name, value)
        object.__setattr__(self, "rotation", rotation)

    # ----------------------------------------------------------- constructors

    @classmethod
    def at(
        cls,
        latitude: float,
        longitude: float,
        height: float,
        azimuth: float,
        *,
        crs: GroundCRS,
        degrees: bool = False,
    ) -> LocalTangentFrame:
        """Frame with its origin at a geodetic point of the CRS's datum.

        Parameters
        ----------
        latitude, longitude : float
            Origin's geodetic latitude and longitude (radians unless ``degrees``).
        height : float
            Origin's ellipsoidal height in metres.
        azimuth : float
            A0, X axis clockwise from north (radians unless ``degrees``).
        crs : GroundCRS
            Supplies the datum (ellipsoid); the origin is converted by pyproj.
        degrees : bool, optional
            Angles in degrees.

        Returns
        -------
        LocalTangentFrame
        """
        lat = float(_angle(latitude, "latitude", degrees))
        lon = float(_angle(longitude, "longitude", degrees))
        az = float(_angle(azimuth, "azimuth", degrees))
        origin = GroundCRS.from_user_input(crs).geodetic2ecef([lat, lon, float(height)])
        return cls(origin, lat, lon, az)

    @classmethod
    def from_ecef_centroid(
        cls, ecef: ArrayLike, azimuth: float, *, crs: GroundCRS, degrees: bool = False
    ) -> LocalTangentFrame:
        """Frame at the centroid of geocentric points, B(142).

        The origin is the mean of the geocentric coordinates; B0, L0 are the
        geodetic latitude and longitude of that mean point (B(142) averages
        the points' B and L instead; over a strip the two differ by far less
        than the control's accuracy).

        Parameters
        ----------
        ecef : array_like, shape (N, 3)
            Geocentric coordinates (metres) of the points, all finite, N >= 1.
        azimuth : float
            A0 (radians unless ``degrees``).
        crs : GroundCRS
            Supplies the datum for B0, L0.
        degrees : bool, optional
            ``azimuth`` in degrees.

        Returns
        -------
        LocalTangentFrame
        """
        arr = _as_rows(ecef, "ecef").reshape(-1, 3)
        if arr.shape[0] == 0:
            raise ValueError("Expected `ecef` to hold at least one point, got none.")
        if not np.all(np.isfinite(arr)):
            bad = int(np.count_nonzero(~np.all(np.isfinite(arr), axis=1)))
            raise ValueError(f"Expected `ecef` to be finite, got {bad} row(s) with NaN or inf.")
        origin = arr.mean(axis=0)
        lat, lon, _ = GroundCRS.from_user_input(crs).ecef2geodetic(origin)
        return cls(origin, float(lat), float(lon), float(_angle(azimuth, "azimuth", degrees)))

    def with_azimuth(self, azimuth: float, *, degrees: bool = False) -> LocalTangentFrame:
        """The same origin and normal with another X-axis azimuth."""
        return LocalTangentFrame(
            self.origin_ecef,
            self.latitude,
            self.longitude,
            float(_angle(azimuth, "azimuth", degrees)),
        )

    # ----------------------------------------------------------- mappings

    def ecef2local(self, ecef: ArrayLike) -> FloatArray:
        """Geocentric → frame coordinates, B(144): ``(ecef − origin) @ rotation.T``.

        Parameters
        ----------
        ecef : array_like, shape (..., 3)
            Geocentric coordinates in metres.

        Returns
        -------
        ndarray, shape (..., 3)
            X (along A0), Y (left of X), Z (up along the origin's normal), metres.
        """
        arr = np.array(_as_rows(ecef, "ecef"))  # a copy: the origin is taken off in place
        return add_to_columns(arr, -self.origin_ecef) @ self.rotation.T

    def local2ecef(self, local: ArrayLike) -> FloatArray:
        """Frame → geocentric coordinates, B(152): ``origin + local @ rotation``.

        Parameters
        ----------
        local : array_like, shape (..., 3)
            Frame coordinates in metres.

        Returns
        -------
        ndarray, shape (..., 3)
            Geocentric coordinates in metres.
        """
        arr = _as_rows(local, "local")
        return add_to_columns(arr @ self.rotation, self.origin_ecef)

    @property
    def enu2local(self) -> FloatArray:
        """Rotation (3, 3) from east, north, up at (B0, L0) to the frame: ``local = M @ enu``.

        Rows are X = (sinA0, cosA0, 0), Y = (−cosA0, sinA0, 0), Z = (0, 0, 1).
        """
        ca, sa = math.cos(self.azimuth), math.sin(self.azimuth)
        return np.array([[sa, ca, 0.0], [-ca, sa, 0.0], [0.0, 0.0, 1.0]])

    def azimuth_of(self, direction: ArrayLike) -> FloatArray:
        """Azimuth (rad, clockwise from north, [0, 2π)) of a direction given in the frame.

        Parameters
        ----------
        direction : array_like, shape (..., 2) or (..., 3)
            Frame components (X, Y[, Z]); Z is ignored.

        Returns
        -------
        ndarray, shape (...)
        """
        arr = _as_rows(direction, "direction", (2, 3))
        enu = arr[..., :2] @ self.enu2local[:2, :2]
        return azimuth_from_local_enu(enu)


# --------------------------------------------------------------------------- work frames


class WorkFrame:
    """A Cartesian frame of adjustment and its way to and from the control CRS.

    Attributes
    ----------
    crs : GroundCRS
    azimuth : float
        Azimuth (radians, clockwise from north) of the frame's X axis.
    frame : LocalTangentFrame or None
        The tangent frame, when the work frame is one.
    """

    crs: GroundCRS
    azimuth: float
    frame: LocalTangentFrame | None

    def to_work(self, xyh: FloatArray) -> FloatArray:
        """CRS coordinates (N, 3) -> work frame (N, 3), metres."""
        raise NotImplementedError

    def from_work(self, xyz: FloatArray) -> FloatArray:
        """Work frame (N, 3) -> CRS coordinates (N, 3)."""
        raise NotImplementedError

    def enu_from_work(self, vectors: FloatArray) -> FloatArray:
        """Difference vectors (N, 3) of the work frame along east, north, up
        at the frame's origin (grid east, north on the projected route)."""
        raise NotImplementedError

    def rotations_to_enu(self, rot_work: FloatArray, centres_xyh: FloatArray) -> FloatArray:
        """Image -> work rotations (M, 3, 3) of photos at ``centres_xyh`` (M, 3)
        as image -> local east-north-up rotations at each centre."""
        raise NotImplementedError

    def work_from_enu(self, centres_xyh: FloatArray) -> FloatArray:
        """Rotations (M, 3, 3) from local east-north-up at each centre to the work frame."""
        m = centres_xyh.shape[0]
        eye = np.broadcast_to(np.eye(3), (m, 3, 3))
        return np.swapaxes(self.rotations_to_enu(eye, centres_xyh), 1, 2)


class TangentWorkFrame(WorkFrame):
    """A local tangent frame as work frame (B(142)-(144), B(152)); with
    ``frame=None`` the site system of ``crs = "local"`` itself (X, Y, H).

    Parameters
    ----------
    crs : GroundCRS
    frame : LocalTangentFrame or None
    description : str
        How reports name the frame.
    """

    def __init__(self, crs: GroundCRS, frame: LocalTangentFrame | None, description: str = ""):
        if frame is None and not crs.is_local:
            raise ValueError('Expected a tangent frame unless the CRS is "local"')
        self.crs = crs
        self.frame = frame
        self.description = description
        self.azimuth = 0.0 if frame is None else frame.azimuth

    @classmethod
    def at_control(
        cls, crs: GroundCRS, control_xyh: FloatArray, azimuth: float
    ) -> TangentWorkFrame:
        """The tangent frame at the control's geocentric centroid, B(142), X at ``azimuth``."""
        frame = LocalTangentFrame.from_ecef_centroid(crs.to_ecef(control_xyh), azimuth, crs=crs)
        return cls(crs, frame, "local tangent frame at the control centroid")

    @property
    def curved(self) -> bool:
        """Whether the frame is a tangent plane of the curved earth (not a site system)."""
        return self.frame is not None

    def to_work(self, xyh: FloatArray) -> FloatArray:
        if self.frame is None:
            return np.array(xyh, dtype=np.float64)
        return self.frame.ecef2local(self.crs.to_ecef(xyh))

    def from_work(self, xyz: FloatArray) -> FloatArray:
        if self.frame is None:
            return np.array(xyz, dtype=np.float64)
        return self.crs.from_ecef(self.frame.local2ecef(xyz))

    def enu_from_work(self, vectors: FloatArray) -> FloatArray:
        if self.frame is None:
            return np.array(vectors, dtype=np.float64)
        return vectors @ self.frame.enu2local  # local = M enu, so enu rows = local rows @ M

    def rotations_to_enu(self, rot_work: FloatArray, centres_xyh: FloatArray) -> FloatArray:
        if self.frame is None:
            return np.array(rot_work, dtype=np.float64)
        llh = self.crs.to_geodetic(centres_xyh)
        return enu_rotation(llh[:, 0], llh[:, 1]) @ self.frame.rotation.T @ rot_work

    def work_from_enu(self, centres_xyh: FloatArray) -> FloatArray:
        m = centres_xyh.shape[0]
        if self.frame is None:
            return np.broadcast_to(np.eye(3), (m, 3, 3)).copy()
        llh = self.crs.to_geodetic(centres_xyh)
        return self.frame.rotation @ np.swapaxes(enu_rotation(llh[:, 0], llh[:, 1]), 1, 2)


class ProjectedWorkFrame(WorkFrame):
    """Map grid rotated by the strip's grid azimuth, heights on the tangent plane
    at the centre of the net (B(153)); no curvature for a local site system.

    Parameters
    ----------
    crs : GroundCRS
    control_xyh : ndarray, shape (N, 3)
        The control; the centre of the net is their mean plan position.
    azimuth : float
        Grid azimuth (radians) of the frame's X axis.
    """

    def __init__(self, crs: GroundCRS, control_xyh: FloatArray, azimuth: float):
        self.crs = crs
        self.frame = None
        self.description = "map grid rotated along the strip, heights on the tangent plane"
        self.azimuth = azimuth
        self.centre = np.nanmean(control_xyh[:, :2], axis=0)
        if crs.is_local:
            self.radius = np.inf
            self.grid_scale = 1.0
        else:
            centre = np.array([[*self.centre, 0.0]])
            llh = crs.to_geodetic(centre)
            self.radius = float(gaussian_mean_radius(llh[0, 0], crs))
            # Grid distances are k times ground distances (UTM: 0.9996 on the
            # central meridian); heights are not.  Reduce the grid to the ground
            # with k at the centre of the net; its variation over the net is left
            # to the polynomials (documented in docs/geodesy.md).
            self.grid_scale = float(crs.scale_factor(centre)[0])
        s, c = np.sin(azimuth), np.cos(azimuth)
        # columns: work X and Y axes in grid (east, north); X at azimuth A0, Y to its left
        self.grid_from_work: FloatArray = np.array([[s, -c, 0.0], [c, s, 0.0], [0.0, 0.0, 1.0]])

    def to_work(self, xyh: FloatArray) -> FloatArray:
        """Grid (E, N, H) -> tangent plane at the centre of the net.

        The grid is taken as the surface of a sphere of radius R mapped
        equidistantly about the centre; a point at distance D and height H is
        then at ``(R + H) sin(D/R)`` from the centre's vertical and
        ``(R + H) cos(D/R) − R`` above the tangent plane.  To second order the
        height is B(153), ``Z = H − D²/(2R)``; the plan term ``D·H/R`` is the
        same effect on elevated points (0.75 m at 4 km for a projection centre
        1200 m up).
        """
        d_en = (xyh[:, :2] - self.centre) / self.grid_scale
        if np.isinf(self.radius):
            grid: FloatArray = np.column_stack([d_en, xyh[:, 2]])
        else:
            r = self.radius
            dist = np.hypot(d_en[:, 0], d_en[:, 1])
            radial = (r + xyh[:, 2]) * np.sin(dist / r)
            with np.errstate(invalid="ignore", divide="ignore"):
                factor = np.where(dist > 0, radial / np.where(dist > 0, dist, 1.0), 1.0)
            z = (r + xyh[:, 2]) * np.cos(dist / r) - r
            grid = np.column_stack([d_en * factor[:, None], z])
        return grid @ self.grid_from_work

    def from_work(self, xyz: FloatArray) -> FloatArray:
        grid = xyz @ self.grid_from_work.T
        if not np.isinf(self.radius):
            r = self.radius
            radial = np.hypot(grid[:, 0], grid[:, 1])
            r_up = r + grid[:, 2]
            dist = r * np.arctan2(radial, r_up)
            grid[:, 2] = np.hypot(radial, r_up) - r
            with np.errstate(invalid="ignore", divide="ignore"):
                factor = np.where(radial > 0, dist / np.where(radial > 0, radial, 1.0), 1.0)
            factor *= self.grid_scale
            grid[:, 0] *= factor
            grid[:, 1] *= factor
        add_to_columns(grid[:, :2], self.centre)
        return grid

    def enu_from_work(self, vectors: FloatArray) -> FloatArray:
        return vectors @ self.grid_from_work.T

    def rotations_to_enu(self, rot_work: FloatArray, centres_xyh: FloatArray) -> FloatArray:
        rot_grid = self.grid_from_work @ rot_work
        gamma = (
            np.zeros(len(centres_xyh))
            if self.crs.is_local
            else self.crs.meridian_convergence(centres_xyh)
        )
        # Grid north lies at azimuth gamma from true north: R_enu = Rz(-gamma) R_grid.
        rz = matrix_from_rotvec(np.column_stack([np.zeros((len(gamma), 2)), -gamma]))
        # The vertical at the photo is tilted by D/R against the vertical at the
        # centre of the net (the tangent plane of the flat model).
        d_en = (centres_xyh[:, :2] - self.centre) / self.grid_scale
        tilt = np.column_stack([d_en[:, 1], -d_en[:, 0], np.zeros(len(d_en))]) / self.radius
        # tilt is built from grid offsets: apply it in the grid frame, then turn
        # grid north to true north.
        return rz @ matrix_from_rotvec(tilt) @ rot_grid


def make_work_frame(
    route: Route, crs: GroundCRS, control_xyh: FloatArray, azimuth: float
) -> WorkFrame:
    """The work frame of a route: a tangent frame at the control centroid
    (geocentric) or the rotated map grid (projected)."""
    if Route.create(route) is Route.GEOCENTRIC:
        return TangentWorkFrame.at_control(crs, control_xyh, azimuth)
    return ProjectedWorkFrame(crs, control_xyh, azimuth)


def enu_residuals(crs: GroundCRS, given_xyh: FloatArray, adjusted_xyh: FloatArray) -> FloatArray:
    """Given minus adjusted CRS coordinates (N, 3) along E, N, H in metres
    (rows with NaN give NaN).

    Projected CRSs and ``"local"``: differences of the CRS coordinates (grid
    metres).  Geographic CRSs: the ECEF difference rotated into east, north,
    up at the adjusted point.
    """
    if crs.is_local or not crs.is_geographic:
        return given_xyh - adjusted_xyh
    ok = np.all(np.isfinite(given_xyh), axis=1) & np.all(np.isfinite(adjusted_xyh), axis=1)
    out = np.full(given_xyh.shape, np.nan)
    if ok.any():
        d = crs.to_ecef(given_xyh[ok]) - crs.to_ecef(adjusted_xyh[ok])
        llh = crs.to_geodetic(adjusted_xyh[ok])
        out[ok] = np.einsum("nij,nj->ni", enu_rotation(llh[:, 0], llh[:, 1]), d)
    return out
