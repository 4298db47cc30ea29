"""Ground coordinate systems and the local tangent frame of the geocentric route.

This module is the only place where strip_aerotri touches geodesy.  Every
datum, projection and ellipsoid step is delegated to pyproj; the module itself
only adds the local tangent frame of B(142)-(144), B(152) (a rotation and a
shift) and the earth-curvature correction of B(153).

Conventions
-----------
* Points are float64 rows, shape ``(N, 3)`` (any ``(..., 3)`` stack works).
* Coordinates of a :class:`GroundCRS` are in the axis order of pyproj's
  ``always_xy=True``: easting, northing for projected CRSs; longitude,
  latitude (in the CRS's angular unit, degrees for nearly every CRS) for
  geographic ones.  The third column is the ellipsoidal height in metres
  above the ellipsoid of the CRS's own datum.
* Geodetic coordinates are ``(latitude, longitude, height)`` in radians,
  radians, metres, longitude counted from the CRS's own prime meridian.
* "ECEF" means the geocentric Cartesian system of the CRS's own datum (no
  datum shift is ever implied); metres.
* Angles are radians; azimuths are clockwise from north.

See ``docs/geodesy.md`` for the two routes to the ground and the gotchas.
"""

from __future__ import annotations

import math
import os
from contextlib import closing
from typing import TYPE_CHECKING, Any, Literal, NamedTuple, overload

import numpy as np

from strip_aerotri.errors import ConfigError, GeometryError

if TYPE_CHECKING:
    from pyproj import CRS, Proj, Transformer

    from strip_aerotri._typing import ArrayLike, FloatArray

__all__ = [
    "grid_convergence_deg",
    "MEAN_EARTH_RADIUS",
    "EllipsoidParameters",
    "GroundCRS",
    "azimuth_from_local_enu",
    "earth_curvature_correction",
    "enu_rotation",
    "gaussian_mean_radius",
]

#: Mean radius R1 = (2a + b)/3 of the GRS 80 ellipsoid in metres (Moritz 2000,
#: "Geodetic Reference System 1980", J. Geodesy 74:128-133,
#: doi:10.1007/s001900050278).  A fallback earth radius for the projected
#: route when the ground system is ``"local"`` and has no ellipsoid.
MEAN_EARTH_RADIUS = 6371008.7714

_LOCAL_NAMES = frozenset({"local"})

_GEOCENTRIC_AXES = [
    {"name": "Geocentric X", "abbreviation": "X", "direction": "geocentricX", "unit": "metre"},
    {"name": "Geocentric Y", "abbreviation": "Y", "direction": "geocentricY", "unit": "metre"},
    {"name": "Geocentric Z", "abbreviation": "Z", "direction": "geocentricZ", "unit": "metre"},
]


class EllipsoidParameters(NamedTuple):
    """Defining parameters of an ellipsoid (as pyproj reports them).

    Attributes
    ----------
    semi_major_metre : float
        Semi-major axis a in metres.
    inverse_flattening : float
        1/f; ``0.0`` for a sphere (pyproj's convention).
    """

    semi_major_metre: float
    inverse_flattening: float

    @property
    def flattening(self) -> float:
        """Flattening f (0 for a sphere)."""
        return 0.0 if self.inverse_flattening == 0.0 else 1.0 / self.inverse_flattening

    @property
    def eccentricity_squared(self) -> float:
        """First eccentricity squared e² = f (2 − f)."""
        f = self.flattening
        return f * (2.0 - f)


# --------------------------------------------------------------------------- helpers


def _as_rows(values: ArrayLike, name: str, width: int | tuple[int, ...] = 3) -> FloatArray:
    """Coerce ``values`` to a float64 array whose last axis has ``width`` columns."""
    arr = np.asarray(values, dtype=np.float64)
    widths = (width,) if isinstance(width, int) else width
    if arr.ndim < 1 or arr.shape[-1] not in widths:
        expected = " or ".join(f"(..., {w})" for w in widths)
        raise ValueError(f"Expected `{name}` to have shape {expected}, got {arr.shape}.")
    return arr


def _angle(value: ArrayLike, name: str, degrees: bool) -> FloatArray:
    arr = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"Expected `{name}` to be finite, got {value!r}.")
    return np.radians(arr) if degrees else arr


def _geocentric_of(geodetic: CRS) -> CRS:
    """The geocentric Cartesian CRS of the datum (or datum ensemble) of ``geodetic``.

    The registered one (PROJ's database: EPSG:4978 for WGS 84, EPSG:4936
    for ETRS89) where ``geodetic`` has an authority code: pyproj builds a
    transformer between registered CRSs in a few milliseconds, against
    15-30 ms for a CRS it has to identify first.  Otherwise pyproj's
    ``GeocentricCRS(datum=...)`` would reject datum ensembles (WGS 84,
    ETRS89), so the CRS is built from the PROJJSON of the geodetic CRS with its
    ellipsoidal coordinate system replaced by the geocentric X, Y, Z axes.
    Either way the datum is that of ``geodetic``: the conversion to it is
    the same PROJ pipeline (tests/test_geodesy_geocentric.py).
    """
    registered = _registered_geocentric(geodetic)
    return _geocentric_from_json(geodetic) if registered is None else registered


#: The geocentric CRSs of the datum of a registered geodetic CRS, EPSG's first.
_SAME_DATUM_GEOCENTRIC = (
    "SELECT g.auth_name, g.code FROM geodetic_crs AS s JOIN geodetic_crs AS g"
    " ON g.datum_auth_name = s.datum_auth_name AND g.datum_code = s.datum_code"
    " WHERE s.auth_name = ? AND s.code = ? AND g.type = 'geocentric' AND g.deprecated = 0"
    " ORDER BY g.auth_name != 'EPSG', g.auth_name, g.code"
)


def _registered_geocentric(geodetic: CRS) -> CRS | None:
    """The registered geocentric CRS of the datum of ``geodetic`` (same datum,
    X, Y, Z in metres) or None: no authority code, none in PROJ's database
    (the first ``proj.db`` along pyproj's data directories), or the database
    not readable."""
    import sqlite3
    from pathlib import Path

    from pyproj import CRS
    from pyproj.datadir import get_data_dir

    authority = geodetic.to_authority(min_confidence=100)
    if authority is None:
        return None
    # PROJ reads the first proj.db along its search path
    found = (Path(d) / "proj.db" for d in get_data_dir().split(os.pathsep) if d)
    database = next((path for path in found if path.is_file()), None)
    if database is None:
        return None
    try:
        with closing(sqlite3.connect(f"{database.as_uri()}?mode=ro", uri=True)) as db:
            rows = db.execute(_SAME_DATUM_GEOCENTRIC, authority).fetchall()
    except (sqlite3.Error, ValueError):
        return None
    # the same datum by the database's join (comparing pyproj's datum objects
    # costs 15-20 ms)
    for auth_name, code in rows:
        candidate = CRS.from_authority(auth_name, str(code))
        if _is_geocentric_metres(candidate):
            return candidate
    return None


def _is_geocentric_metres(crs: CRS) -> bool:
    """Whether ``crs`` is geocentric with the axes X, Y, Z in metres."""
    axes = crs.axis_info
    return crs.is_geocentric and [(a.direction.lower(), a.unit_name) for a in axes] == [
        ("geocentricx", "metre"),
        ("geocentricy", "metre"),
        ("geocentricz", "metre"),
    ]


def _geocentric_from_json(geodetic: CRS) -> CRS:
    """The geocentric CRS of the datum of ``geodetic``, built from its PROJJSON."""
    from pyproj import CRS

    description = geodetic.to_json_dict()
    for key in ("id", "ids", "usage", "usages", "scope", "area", "bbox", "remarks"):
        description.pop(key, None)
    description["type"] = "GeodeticCRS"
    description["name"] = f"{geodetic.name} (geocentric)"
    description["coordinate_system"] = {"subtype": "Cartesian", "axis": _GEOCENTRIC_AXES}
    return CRS.from_json_dict(description)


def _run(transformer: Transformer, columns: tuple[FloatArray, ...], what: str) -> FloatArray:
    """Apply ``transformer`` to column vectors; return the results stacked as columns."""
    from pyproj.exceptions import ProjError

    try:
        # the stubs overload transform() on two, three or four coordinate
        # arrays; an unpacked tuple of unknown length matches none of them
        out = transformer.transform(*columns, errcheck=True)  # type: ignore[call-overload]
    except ProjError as exc:
        raise GeometryError(f"pyproj could not {what}: {exc}") from exc
    return np.stack([np.asarray(o, dtype=np.float64) for o in out], axis=-1)


# --------------------------------------------------------------------------- GroundCRS


class GroundCRS:
    """The ground coordinate reference system of a project (``[control] crs``).

    Build it with :meth:`from_user_input`.  Either ``"local"`` (a local
    Cartesian site system in metres, no geodesy) or a horizontal CRS that
    pyproj understands: projected or geographic.  Heights are always
    ellipsoidal heights in metres above the ellipsoid of the CRS's own datum;
    conversions to and from ECEF stay in that datum (no datum shift).

    pyproj transformers are built on first use and cached on the instance.
    Like pyproj's, they must not be shared between threads.

    Attributes
    ----------
    crs : pyproj.CRS or None
        The CRS as given (``None`` for ``"local"``).  A bound CRS (a PROJ
        string with ``+towgs84``) is kept as given; its source CRS is used for
        every conversion except :meth:`to_wgs84_lonlat`.
    name : str
        The CRS's name, or ``"local"``.
    is_local, is_geographic : bool
    """

    __slots__ = ("_base", "_cache", "crs", "name", "text")

    def __init__(self, crs: CRS | None, text: str = "") -> None:
        self.crs = crs
        self.text = text
        self._cache: dict[str, Any] = {}
        if crs is None:
            self._base = None
            self.name = "local"
            return
        base = crs.source_crs if crs.is_bound else crs
        if base is None or not (base.is_projected or base.is_geographic) or base.is_compound:
            raise ConfigError(
                f"[control] crs {(text or crs.name)!r} is a {crs.type_name}; a horizontal "
                "projected or geographic CRS is needed (heights are taken as ellipsoidal "
                'heights of its datum), or "local"'
            )
        self._base = base
        self.name = crs.name

    # ----------------------------------------------------------- construction

    @classmethod
    def from_user_input(cls, text: Any) -> GroundCRS:
        """Build from the ``[control] crs`` string of the project file.

        Parameters
        ----------
        text : str or pyproj.CRS
            ``"local"`` (any case) or anything :meth:`pyproj.CRS.from_user_input`
            accepts ("EPSG:32634", WKT, PROJ string, PROJJSON, a CRS object).

        Returns
        -------
        GroundCRS

        Raises
        ------
        ConfigError
            pyproj does not understand ``text``, or the CRS is not a horizontal
            projected or geographic CRS (geocentric, vertical, compound and
            engineering CRSs are refused).

        Examples
        --------
        >>> GroundCRS.from_user_input("EPSG:32634").name
        'WGS 84 / UTM zone 34N'
        >>> GroundCRS.from_user_input("Local").is_local
        True
        """
        from pyproj import CRS
        from pyproj.exceptions import CRSError

        if isinstance(text, GroundCRS):
            return text
        if isinstance(text, str) and text.strip().lower() in _LOCAL_NAMES:
            return cls(None, text.strip())
        try:
            crs = CRS.from_user_input(text.strip() if isinstance(text, str) else text)
        except CRSError as exc:
            raise ConfigError(
                f"[control] crs {text!r} is not a CRS pyproj understands: {exc}"
            ) from exc
        return cls(crs, text if isinstance(text, str) else crs.name)

    def __repr__(self) -> str:
        return f"GroundCRS({self.name!r})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, GroundCRS):
            return NotImplemented
        if self.crs is None or other.crs is None:
            return self.crs is None and other.crs is None
        return self.crs == other.crs

    def __hash__(self) -> int:
        return hash(None if self.crs is None else self.crs.to_wkt())

    # ----------------------------------------------------------- properties

    @property
    def is_local(self) -> bool:
        """True for the local Cartesian site system (no geodesy)."""
        return self.crs is None

    @property
    def is_geographic(self) -> bool:
        """True when X, Y are longitude, latitude."""
        return self._base is not None and bool(self._base.is_geographic)

    @property
    def ellipsoid(self) -> EllipsoidParameters | None:
        """Semi-major axis and inverse flattening of the datum's ellipsoid (None if local)."""
        if self._base is None:
            return None
        ell = self._base.ellipsoid
        assert ell is not None  # a projected or geographic CRS has one (__init__)
        return EllipsoidParameters(float(ell.semi_major_metre), float(ell.inverse_flattening))

    @property
    def wgs84_operation(self) -> str:
        """Description of the operation pyproj uses for :meth:`to_wgs84_lonlat`.

        When several operations are candidates, pyproj picks one per point at
        transformation time; this then names the one used last.
        """
        transformer = self._transformer("wgs84")
        return str(self._cache.get("_wgs84_last", transformer.description))

    # ----------------------------------------------------------- transformers

    def _require_geodesy(self) -> CRS:
        if self._base is None:
            raise GeometryError(
                'the ground system is "local" (no geodesy): the geocentric route and every '
                "conversion to ECEF, geodetic or WGS 84 coordinates need a real CRS in "
                '[control] crs (e.g. "EPSG:32634"); use the projected route instead'
            )
        return self._base

    @overload
    def _transformer(self, key: Literal["proj"]) -> Proj: ...

    @overload
    def _transformer(self, key: str) -> Transformer: ...

    def _transformer(self, key: str) -> Transformer:
        # Made here, in the process and thread that use them (30-50 ms for a
        # run's first ones, the PROJ database's first queries): a pyproj
        # Transformer is per thread (a thread-local PJ, re-made in any other
        # thread) and pickles as its from_crs recipe, made again when unpickled,
        # so neither a helper thread nor stripaero run's loading child can hand
        # one over; a pipeline string would, but from_crs may hold several
        # operations chosen point by point (datum shifts), which one would not.
        from pyproj import CRS, Proj, Transformer

        cached: Transformer | None = self._cache.get(key)
        if cached is not None:
            return cached
        base = self._require_geodesy()
        crs3d = base.to_3d()
        geodetic = crs3d.geodetic_crs
        assert geodetic is not None  # projected or geographic (__init__)
        geodetic3d = geodetic.to_3d()
        if key in ("geocentric", "geodetic2ecef"):
            geocentric = self._cache.get("_geocentric_crs")
            if geocentric is None:
                geocentric = _geocentric_of(geodetic3d)
                self._cache["_geocentric_crs"] = geocentric
        if key == "geocentric":
            transformer = Transformer.from_crs(crs3d, geocentric, always_xy=True)
        elif key == "geodetic":
            transformer = Transformer.from_crs(crs3d, geodetic3d, always_xy=True)
        elif key == "geodetic2ecef":
            transformer = Transformer.from_crs(geodetic3d, geocentric, always_xy=True)
        elif key == "wgs84":
            transformer = Transformer.from_crs(self.crs, CRS.from_epsg(4326), always_xy=True)
        elif key == "proj":
            transformer = Proj(base)
        else:  # pragma: no cover - internal keys only
            raise KeyError(key)
        self._cache[key] = transformer
        return transformer

    def _angle_unit(self) -> float:
        """Radians per unit of the geodetic CRS's angular axes (1 degree for most)."""
        factor = self._cache.get("_angle_unit")
        if factor is None:
            geodetic = self._require_geodesy().geodetic_crs
            assert geodetic is not None  # projected or geographic (__init__)
            axis = geodetic.axis_info[0]
            factor = float(axis.unit_conversion_factor)
            self._cache["_angle_unit"] = factor
        return factor

    # ----------------------------------------------------------- conversions

    def to_ecef(self, xyh: ArrayLike) -> FloatArray:
        """Ground coordinates → geocentric X, Y, Z of the same datum.

        Parameters
        ----------
        xyh : array_like, shape (..., 3)
            X, Y in the CRS's ``always_xy`` axis order (easting, northing in
            metres, or longitude, latitude in the CRS's angular unit), H the
            ellipsoidal height in metres.  NaN rows give NaN rows.

        Returns
        -------
        ndarray, shape (..., 3)
            Geocentric X, Y, Z in metres, in the CRS's own datum (no datum shift).

        Raises
        ------
        GeometryError
            The CRS is ``"local"``, or pyproj cannot convert a point.
        """
        arr = _as_rows(xyh, "xyh")
        return _run(
            self._transformer("geocentric"), tuple(np.moveaxis(arr, -1, 0)), "convert to ECEF"
        )

    def from_ecef(self, ecef: ArrayLike) -> FloatArray:
        """Geocentric X, Y, Z of the CRS's datum → ground X, Y, H (inverse of :meth:`to_ecef`).

        Parameters
        ----------
        ecef : array_like, shape (..., 3)
            Geocentric coordinates in metres.

        Returns
        -------
        ndarray, shape (..., 3)
            X, Y in ``always_xy`` order, H ellipsoidal height in metres.
        """
        arr = _as_rows(ecef, "ecef")
        return self._inverse("geocentric", arr, "convert from ECEF")

    def _inverse(self, key: str, arr: FloatArray, what: str) -> FloatArray:
        from pyproj.exceptions import ProjError

        transformer = self._transformer(key)
        try:
            # two or three unpacked columns: see _run
            out = transformer.transform(  # type: ignore[call-overload]
                *np.moveaxis(arr, -1, 0), direction="INVERSE", errcheck=True
            )
        except ProjError as exc:
            raise GeometryError(f"pyproj could not {what}: {exc}") from exc
        return np.stack([np.asarray(o, dtype=np.float64) for o in out], axis=-1)

    def to_geodetic(self, xyh: ArrayLike) -> FloatArray:
        """Ground coordinates → geodetic latitude, longitude, height in the CRS's datum.

        Parameters
        ----------
        xyh : array_like, shape (..., 3)
            Ground X, Y (``always_xy`` order), H ellipsoidal height in metres.

        Returns
        -------
        ndarray, shape (..., 3)
            Latitude (rad), longitude (rad, from the CRS's prime meridian),
            ellipsoidal height (m).
        """
        arr = _as_rows(xyh, "xyh")
        lon, lat, h = np.moveaxis(
            _run(self._transformer("geodetic"), tuple(np.moveaxis(arr, -1, 0)), "convert"),
            -1,
            0,
        )
        unit = self._angle_unit()
        return np.stack([lat * unit, lon * unit, h], axis=-1)

    def from_geodetic(self, llh: ArrayLike) -> FloatArray:
        """Geodetic latitude, longitude (rad), height (m) → ground X, Y, H.

        Parameters
        ----------
        llh : array_like, shape (..., 3)
            Latitude, longitude in radians, ellipsoidal height in metres.

        Returns
        -------
        ndarray, shape (..., 3)
            Ground X, Y (``always_xy`` order), H in metres.
        """
        arr = _as_rows(llh, "llh")
        unit = self._angle_unit()
        columns = (arr[..., 1] / unit, arr[..., 0] / unit, arr[..., 2])
        return self._inverse("geodetic", np.stack(columns, axis=-1), "convert from geodetic")

    def geodetic2ecef(self, llh: ArrayLike) -> FloatArray:
        """Geodetic latitude, longitude (rad), height (m) → geocentric X, Y, Z (same datum).

        Parameters
        ----------
        llh : array_like, shape (..., 3)

        Returns
        -------
        ndarray, shape (..., 3)
            Geocentric X, Y, Z in metres (method EPSG 9602, done by pyproj).
        """
        arr = _as_rows(llh, "llh")
        unit = self._angle_unit()
        columns = (arr[..., 1] / unit, arr[..., 0] / unit, arr[..., 2])
        return _run(self._transformer("geodetic2ecef"), columns, "convert geodetic to ECEF")

    def ecef2geodetic(self, ecef: ArrayLike) -> FloatArray:
        """Geocentric X, Y, Z (m) → geodetic latitude, longitude (rad), height (m), same datum.

        Parameters
        ----------
        ecef : array_like, shape (..., 3)

        Returns
        -------
        ndarray, shape (..., 3)
            Latitude, longitude in radians, ellipsoidal height in metres.
        """
        arr = _as_rows(ecef, "ecef")
        lon, lat, h = np.moveaxis(self._inverse("geodetic2ecef", arr, "convert ECEF"), -1, 0)
        unit = self._angle_unit()
        return np.stack([lat * unit, lon * unit, h], axis=-1)

    def to_wgs84_lonlat(self, xyh: ArrayLike) -> FloatArray:
        """Ground coordinates → WGS 84 longitude, latitude in degrees (RFC 7946 GeoJSON order).

        Unlike every other method, this one may apply a datum transformation:
        pyproj's default (best available) operation from the CRS to WGS 84
        (EPSG:4326), described by :attr:`wgs84_operation`.  Its accuracy is
        that operation's (metre level for a Helmert or ballpark shift), which
        is enough for display; never feed these values back into the
        adjustment.

        Parameters
        ----------
        xyh : array_like, shape (..., 2) or (..., 3)
            Ground X, Y (``always_xy`` order); a third column is ignored.

        Returns
        -------
        ndarray, shape (..., 2)
            Longitude, latitude in degrees.
        """
        from pyproj.exceptions import ProjError

        arr = _as_rows(xyh, "xyh", (2, 3))
        transformer = self._transformer("wgs84")
        lonlat = _run(transformer, (arr[..., 0], arr[..., 1]), "convert to WGS 84")
        try:
            self._cache["_wgs84_last"] = transformer.get_last_used_operation().description
        except ProjError:  # no single operation was used (e.g. no point transformed)
            pass
        return lonlat

    def meridian_convergence(self, xyh: ArrayLike) -> FloatArray:
        """Meridian convergence γ of the projection at ground points (from pyproj's factors).

        γ is the angle from true (geodetic) north to grid north, positive
        clockwise; it is positive east of the central meridian of a
        transverse Mercator zone in the northern hemisphere.  A direction's
        grid bearing is its geodetic azimuth minus γ (the arc-to-chord
        correction, which is below an arc second over a few km, aside).
        Zero for a geographic CRS.

        Parameters
        ----------
        xyh : array_like, shape (..., 2) or (..., 3)
            Ground X, Y (``always_xy`` order); a third column is ignored.

        Returns
        -------
        ndarray, shape (...)
            γ in radians.
        """
        arr = _as_rows(xyh, "xyh", (2, 3))
        base = self._require_geodesy()
        if base.is_geographic:
            return np.zeros(arr.shape[:-1])
        points = np.concatenate([arr[..., :2], np.zeros((*arr.shape[:-1], 1))], axis=-1)
        llh = self.to_geodetic(points)
        # Proj.get_factors takes degrees counted from the CRS's prime meridian.
        lon = np.degrees(llh[..., 1])
        lat = np.degrees(llh[..., 0])
        factors = self._transformer("proj").get_factors(lon, lat, errcheck=True)
        return np.radians(np.asarray(factors.meridian_convergence, dtype=np.float64))

    def scale_factor(self, xyh: ArrayLike) -> FloatArray:
        """Point scale factor k of the projection at ground points (pyproj's factors).

        Grid distance = k × ellipsoid distance near the point (for conformal
        projections k is the same in every direction; otherwise the square root
        of the areal scale is returned).  1 for a geographic CRS.

        Parameters
        ----------
        xyh : array_like, shape (..., 2) or (..., 3)
            Ground X, Y (``always_xy`` order); a third column is ignored.

        Returns
        -------
        ndarray, shape (...)
        """
        arr = _as_rows(xyh, "xyh", (2, 3))
        base = self._require_geodesy()
        if base.is_geographic:
            return np.ones(arr.shape[:-1])
        points = np.concatenate([arr[..., :2], np.zeros((*arr.shape[:-1], 1))], axis=-1)
        llh = self.to_geodetic(points)
        factors = self._transformer("proj").get_factors(
            np.degrees(llh[..., 1]), np.degrees(llh[..., 0]), errcheck=True
        )
        return np.sqrt(np.asarray(factors.areal_scale, dtype=np.float64))


# --------------------------------------------------------------------------- ENU, frame


def enu_rotation(
    latitude: ArrayLike, longitude: ArrayLike, *, degrees: bool = False
) -> FloatArray:
    """Rotation from geocentric (ECEF) directions to local east, north, up.

    ``enu = R @ (ecef - ecef_origin)``; the rows of ``R`` are the unit east,
    north and up vectors in ECEF:
    ``e = (−sinL, cosL, 0)``, ``n = (−sinB cosL, −sinB sinL, cosB)``,
    ``u = (cosB cosL, cosB sinL, sinB)`` (EPSG method 9836).

    Parameters
    ----------
    latitude, longitude : array_like, broadcastable, shape (...)
        Geodetic latitude B and longitude L (radians unless ``degrees``).
    degrees : bool, optional
        Angles in degrees.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Rows east, north, up.

    Examples
    --------
    >>> enu_rotation(0.0, 0.0).round(12)
    array([[-0.,  1.,  0.],
           [-0., -0.,  1.],
           [ 1.,  0.,  0.]])
    """
    b = _angle(latitude, "latitude", degrees)
    l_ = _angle(longitude, "longitude", degrees)
    b, l_ = np.broadcast_arrays(b, l_)
    sb, cb, sl, cl = np.sin(b), np.cos(b), np.sin(l_), np.cos(l_)
    zero = np.zeros_like(b)
    east = np.stack([-sl, cl, zero], axis=-1)
    north = np.stack([-sb * cl, -sb * sl, cb], axis=-1)
    up = np.stack([cb * cl, cb * sl, sb], axis=-1)
    return np.stack([east, north, up], axis=-2)


def azimuth_from_local_enu(vector: ArrayLike) -> FloatArray:
    """Azimuth of a horizontal direction given by its east, north components.

    Parameters
    ----------
    vector : array_like, shape (..., 2) or (..., 3)
        (east, north[, up]) components; the up component is ignored.

    Returns
    -------
    ndarray, shape (...)
        Azimuth in radians, clockwise from north, in [0, 2π).

    Raises
    ------
    ValueError
        A direction has no horizontal component.

    Examples
    --------
    >>> float(np.degrees(azimuth_from_local_enu([1.0, 0.0, 0.0])))
    90.0
    """
    arr = _as_rows(vector, "vector", (2, 3))
    east, north = arr[..., 0], arr[..., 1]
    if np.any(np.hypot(east, north) == 0.0) or not np.all(np.isfinite(arr[..., :2])):
        raise ValueError("Expected `vector` to have a finite, non-zero horizontal component.")
    return np.mod(np.arctan2(east, north), 2.0 * np.pi)


# --------------------------------------------------------------------------- curvature


def earth_curvature_correction(distance: ArrayLike, radius: ArrayLike) -> FloatArray:
    """Drop of the earth's surface below the tangent plane, D²/(2R), B(153).

    A point at horizontal distance D from the tangent point lies D²/(2R)
    below the tangent plane (the exact sagitta of a sphere is
    ``R − sqrt(R² − D²) = D²/(2R) + D⁴/(8R³) + …``).  So a flat model's
    height Z and the height H over the curved earth are related by

    ``H = Z + D²/(2R)`` (B(153), Z' = Z + D²/2R) and ``Z = H − D²/(2R)``.

    Sizes: 7.8 cm at 1 km, 7.8 m at 10 km (R = 6371 km).

    Parameters
    ----------
    distance : array_like, shape (...)
        D in metres (from the middle of the net).
    radius : float or array_like
        Earth radius R in metres, > 0 (e.g. :func:`gaussian_mean_radius`).

    Returns
    -------
    ndarray, shape (...)
        D²/(2R) in metres (>= 0).

    Examples
    --------
    >>> round(float(earth_curvature_correction(1000.0, 6371000.0)), 4)
    0.0785
    """
    d = np.asarray(distance, dtype=np.float64)
    r = np.asarray(radius, dtype=np.float64)
    if np.any(~(r > 0.0)):
        raise ValueError(f"Expected `radius` to be positive, got {radius!r}.")
    return d * d / (2.0 * r)


def gaussian_mean_radius(
    latitude: ArrayLike, crs: GroundCRS, *, degrees: bool = False
) -> FloatArray:
    """Gaussian mean radius of curvature sqrt(M N) of the CRS's ellipsoid at a latitude.

    With a, f of the datum's ellipsoid (from pyproj) and e² = f(2 − f):
    ``M = a(1 − e²)/W³``, ``N = a/W``, ``W = sqrt(1 − e² sin²B)``, so
    ``sqrt(M N) = a sqrt(1 − e²)/W²``.

    Parameters
    ----------
    latitude : array_like, shape (...)
        Geodetic latitude (radians unless ``degrees``).
    crs : GroundCRS or str
        A non-local ground CRS (its ellipsoid).
    degrees : bool, optional

    Returns
    -------
    ndarray, shape (...)
        Radius in metres.

    Raises
    ------
    ValueError
        ``crs`` is ``"local"`` (no ellipsoid; use :data:`MEAN_EARTH_RADIUS`).
    """
    ground = GroundCRS.from_user_input(crs)
    ell = ground.ellipsoid
    if ell is None:
        raise ValueError(
            'Expected a CRS with an ellipsoid, got "local"; use MEAN_EARTH_RADIUS instead.'
        )
    b = _angle(latitude, "latitude", degrees)
    e2 = ell.eccentricity_squared
    w2 = 1.0 - e2 * np.sin(b) ** 2
    return ell.semi_major_metre * math.sqrt(1.0 - e2) / w2


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
