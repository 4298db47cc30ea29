"""Geodesy of the simulator (pyproj): plan, geodetic, geocentric, local ENU, CRS."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .._typing import ArrayLike, FloatArray

if TYPE_CHECKING:
    from pyproj import CRS, Transformer

_LOCAL = "local"
_WGS84 = (6378137.0, 298.257223563)  # semi-major axis (m), inverse flattening
_DEFAULT_LOCAL_CENTRE = (21.0, 52.0)  # lon, lat (deg) used when crs = "local"


class LocalFrame(NamedTuple):
    """The local ENU tangent frame of a simulation, in geocentric terms.

    ``local = ecef2enu @ (ecef - origin_ecef)`` (rows: east, north, up unit
    vectors in ECEF), both in metres on the datum of the simulation's CRS.

    Attributes
    ----------
    origin_ecef : ndarray, shape (3,)
        Geocentric coordinates of the origin in metres.
    ecef2enu : ndarray, shape (3, 3)
        Rotation ECEF -> local ENU.
    """

    origin_ecef: FloatArray
    ecef2enu: FloatArray

    def ecef2local(self, xyz: ArrayLike) -> FloatArray:
        """Geocentric (N, 3) m -> local ENU (N, 3) m."""
        xyz = np.asarray(xyz, dtype=np.float64)
        return (xyz - self.origin_ecef) @ self.ecef2enu.T

    def local2ecef(self, enu: ArrayLike) -> FloatArray:
        """Local ENU (N, 3) m -> geocentric (N, 3) m."""
        enu = np.asarray(enu, dtype=np.float64)
        return enu @ self.ecef2enu + self.origin_ecef


def _ecef2enu_matrix(lon_deg: ArrayLike, lat_deg: ArrayLike) -> FloatArray:
    """Rotation(s) ECEF -> ENU at geodetic longitude/latitude, shape (..., 3, 3)."""
    lam = np.radians(np.asarray(lon_deg, dtype=np.float64))
    phi = np.radians(np.asarray(lat_deg, dtype=np.float64))
    sl, cl, sp, cp = np.sin(lam), np.cos(lam), np.sin(phi), np.cos(phi)
    zero = np.zeros_like(sl)
    return np.stack(
        [
            np.stack([-sl, cl, zero], axis=-1),
            np.stack([-sp * cl, -sp * sl, cp], axis=-1),
            np.stack([cp * cl, cp * sl, sp], axis=-1),
        ],
        axis=-2,
    )


@dataclass(frozen=True)
class _Geodesy:
    """Transformers between plan (tmerc), geodetic, geocentric, local and CRS."""

    crs: CRS | None
    ellipsoid: tuple[float, float]
    centre_lonlat: tuple[float, float]
    plan2ecef: Transformer  # tmerc (e, n, h) <-> ECEF
    ecef2geodetic: Transformer  # ECEF <-> lon, lat (deg), h
    geodetic2crs: Transformer | None  # lon, lat (deg) <-> CRS X, Y
    frame: LocalFrame

    @classmethod
    def build(
        cls, crs_text: str, centre_lonlat: tuple[float, float] | None, h0: float
    ) -> _Geodesy:
        from pyproj import CRS, Transformer

        if crs_text == _LOCAL:
            crs = None
            ellipsoid = _WGS84
            geodetic2crs = None
            centre = _DEFAULT_LOCAL_CENTRE if centre_lonlat is None else centre_lonlat
        else:
            try:
                crs = CRS.from_user_input(crs_text)
            except Exception as exc:  # pyproj raises CRSError
                raise ValueError(
                    f"Expected `crs` to be a CRS pyproj knows, got {crs_text!r}"
                ) from exc
            if not (crs.is_projected or crs.is_geographic) or crs.is_compound:
                raise ValueError(
                    "Expected `crs` to be a horizontal projected or geographic CRS, "
                    f"got {crs_text!r}"
                )
            ell = crs.ellipsoid
            assert ell is not None  # a horizontal CRS has one
            ellipsoid = (float(ell.semi_major_metre), float(ell.inverse_flattening))
            geodetic2crs = Transformer.from_crs(crs.geodetic_crs, crs, always_xy=True)
            centre = _area_centre(crs) if centre_lonlat is None else centre_lonlat
        lon0, lat0 = (float(v) for v in centre)
        if not (-180.0 <= lon0 <= 360.0 and -89.0 <= lat0 <= 89.0):
            raise ValueError(
                f"Expected `centre_lonlat` within longitude [-180, 360] and latitude "
                f"[-89, 89] degrees, got {centre!r}"
            )
        a, rf = ellipsoid
        ell_txt = f"+a={a!r} +rf={rf!r}"
        plan2ecef = Transformer.from_pipeline(
            f"+proj=pipeline +step +inv +proj=tmerc +lat_0={lat0!r} +lon_0={lon0!r} +k=1 "
            f"+x_0=0 +y_0=0 {ell_txt} +step +proj=cart {ell_txt}"
        )
        ecef2geodetic = Transformer.from_pipeline(
            f"+proj=pipeline +step +inv +proj=cart {ell_txt} "
            "+step +proj=unitconvert +xy_in=rad +xy_out=deg"
        )
        ox, oy, oz = ecef2geodetic.transform(lon0, lat0, h0, direction="INVERSE")
        frame = LocalFrame(
            origin_ecef=np.array([ox, oy, oz], dtype=np.float64),
            ecef2enu=_ecef2enu_matrix(lon0, lat0),
        )
        return cls(crs, ellipsoid, (lon0, lat0), plan2ecef, ecef2geodetic, geodetic2crs, frame)

    def plan2local(self, enh: FloatArray) -> FloatArray:
        """Plan (tmerc east, north) + ellipsoidal height (N, 3) -> local ENU (N, 3)."""
        x, y, z = self.plan2ecef.transform(enh[:, 0], enh[:, 1], enh[:, 2])
        return self.frame.ecef2local(np.column_stack([x, y, z]))

    def local2plan(self, enu: FloatArray) -> FloatArray:
        """Local ENU (N, 3) -> plan (tmerc east, north) + ellipsoidal height (N, 3)."""
        ecef = self.frame.local2ecef(enu)
        e, n, h = self.plan2ecef.transform(ecef[:, 0], ecef[:, 1], ecef[:, 2], direction="INVERSE")
        return np.column_stack([e, n, h])

    def local2geodetic(self, enu: FloatArray) -> FloatArray:
        """Local ENU (N, 3) -> longitude, latitude (deg), ellipsoidal height (m)."""
        ecef = self.frame.local2ecef(enu)
        lon, lat, h = self.ecef2geodetic.transform(ecef[:, 0], ecef[:, 1], ecef[:, 2])
        return np.column_stack([lon, lat, h])

    def local2crs(self, enu: FloatArray) -> FloatArray:
        """Local ENU (N, 3) -> CRS X, Y (always_xy) and ellipsoidal height H."""
        if self.geodetic2crs is None:
            return np.array(enu, dtype=np.float64, copy=True)
        llh = self.local2geodetic(enu)
        x, y = self.geodetic2crs.transform(llh[:, 0], llh[:, 1])
        return np.column_stack([x, y, llh[:, 2]])


def _area_centre(crs: CRS) -> tuple[float, float]:
    """Centre (lon, lat) of a CRS's area of use, in degrees."""
    area = crs.area_of_use
    if area is None:
        raise ValueError(f"CRS {crs.name!r} has no area of use: give `centre_lonlat`")
    west, south, east, north = area.bounds
    if east < west:  # crosses the antimeridian
        east += 360.0
    lon = 0.5 * (west + east)
    if lon > 180.0:
        lon -= 360.0
    return lon, 0.5 * (south + north)
