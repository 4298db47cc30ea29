"""The points and the photo centres of a run as one GeoJSON file (docs/export.md).

An RFC 7946 ``FeatureCollection`` in WGS 84 longitude, latitude (degrees, 8
decimals), converted by pyproj's best operation from the project's CRS
(:meth:`~strip_aerotri.geodesy.GroundCRS.to_wgs84_lonlat`: a datum shift
may be applied, with that operation's accuracy: for display, never to be fed
back).  One ``Point`` feature per row of ``points.csv``, then one per row of
``photos.csv``; the properties are every column of the row (numbers as
numbers, an empty cell as ``null``) and ``feature`` (``"point"`` or
``"photo_centre"``).  Heights stay in the properties (``H``, ``Z``:
ellipsoidal heights on the project CRS's datum, not WGS 84 heights), so the
geometry is two-dimensional.  ``crs = "local"`` has no geodesy to WGS 84 and
is refused.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from ..errors import ConfigError
from ..geodesy import GroundCRS
from .tables import ResultTable, Value

__all__ = [
    "ANGLES",
    "GEOJSON_DECIMALS",
    "geojson_text",
    "point_feature",
    "point_features_text",
    "results_geojson",
]

GEOJSON_DECIMALS = 8
"""Decimals of longitude and latitude (1e-8 degree is about 1 mm), as in points.geojson."""

ANGLES = (
    "omega, phi, kappa in degrees as in photos.csv: R = Rx(omega) Ry(phi) Rz(kappa) maps "
    "image vectors (x along the flight, y to its left, z up) to local east-north-up at the "
    "projection centre (true north); docs/outputs.md"
)
"""The convention of the photo centres' angles, stated in the file."""


def point_feature(fid: str, lon: float, lat: float, properties: dict[str, Any]) -> dict[str, Any]:
    """One RFC 7946 ``Point`` feature (longitude, latitude in degrees); its
    geometry null where they are not finite.  The one writer of features:
    ``points.geojson`` of the result folder and ``stripaero export geojson``."""
    geometry = (
        {"type": "Point", "coordinates": [lon, lat]}
        if math.isfinite(lon) and math.isfinite(lat)
        else None
    )
    return {"type": "Feature", "id": fid, "geometry": geometry, "properties": properties}


def geojson_text(value: Any) -> str:
    """Compact JSON of a GeoJSON object (UTF-8 text, no NaN)."""
    return json.dumps(value, ensure_ascii=False, allow_nan=False, separators=(",", ":"))


def _json_tokens(values: np.ndarray) -> list[str]:
    """Each value of a column as the JSON :func:`geojson_text` writes for it:
    strings escaped by json's own encoder, floats by ``float.__repr__`` (null
    where not finite), integers by ``int.__repr__``."""
    if values.dtype.kind in "USO":
        encode = json.encoder.encode_basestring  # ensure_ascii=False's encoder (C)
        return list(map(encode, map(str, values.tolist())))
    if values.dtype.kind in "iu":
        return list(map(int.__repr__, values.astype(np.int64).tolist()))
    if values.dtype.kind == "f":
        column = values.astype(np.float64)
        tokens = list(map(float.__repr__, column.tolist()))
        for k in np.flatnonzero(~np.isfinite(column)).tolist():
            tokens[k] = "null"
        return tokens
    raise TypeError(f"Expected a column of str, int or float, got dtype {values.dtype}")


def point_features_text(
    ids: np.ndarray, lonlat: np.ndarray, properties: dict[str, np.ndarray]
) -> list[str]:
    """The compact JSON of each :func:`point_feature` of a table, whole columns
    at a time: ``geojson_text(point_feature(id, lon, lat, row))`` for every
    row, character for character, without a dictionary per row.

    Parameters
    ----------
    ids : ndarray, shape (N,)
        Feature ids (str).
    lonlat : ndarray, shape (N, 2)
        Longitude, latitude in degrees; a row that is not finite has a null
        geometry.
    properties : dict of str to ndarray, shape (N,)
        The properties in their order: str, int or float columns (a float
        that is not finite is null).
    """
    lonlat = np.asarray(lonlat, dtype=np.float64).reshape(-1, 2)
    ids = np.asarray(ids)
    for name, column in properties.items():
        if np.shape(column) != ids.shape:
            raise ValueError(
                f"Expected property {name!r} of shape {ids.shape}, got {np.shape(column)}"
            )
    lon = map(float.__repr__, lonlat[:, 0].tolist())
    lat = map(float.__repr__, lonlat[:, 1].tolist())
    keys = [json.encoder.encode_basestring(str(k)).replace("%", "%%") for k in properties]
    head = '{"type":"Feature","id":%s,"geometry":'
    tail = ',"properties":{' + ",".join(f"{key}:%s" for key in keys) + "}}"
    # one % per row; the same array (the ids as a property) encoded once
    tokens: dict[int, list[str]] = {}
    for column in (ids, *properties.values()):
        if id(column) not in tokens:
            tokens[id(column)] = _json_tokens(np.asarray(column))
    id_tokens = tokens[id(ids)]
    columns = [tokens[id(column)] for column in properties.values()]
    point = (head + '{"type":"Point","coordinates":[%s,%s]}' + tail).__mod__
    rows = list(map(point, zip(id_tokens, lon, lat, *columns, strict=True)))
    unplaced = np.flatnonzero(~np.isfinite(lonlat).all(axis=1)).tolist()
    if unplaced:  # a null geometry
        null = (head + "null" + tail).__mod__
        for k in unplaced:
            rows[k] = null((id_tokens[k], *(column[k] for column in columns)))
    return rows


def _features(
    table: ResultTable, lonlat: np.ndarray, kind: str, extra: dict[str, Value]
) -> list[dict[str, Any]]:
    return [
        point_feature(
            f"{kind}/{pid}",
            float(lonlat[k, 0]),
            float(lonlat[k, 1]),
            {"feature": kind, **extra, **table.row(k)},
        )
        for k, pid in enumerate(table.ids)
    ]


def results_geojson(
    points: ResultTable, photos: ResultTable, crs: str, *, strip: str | None = None
) -> str:
    """The file's text: the points and the photo centres of a run.

    Parameters
    ----------
    points, photos : ResultTable
        ``points.csv`` and ``photos.csv`` of the run (:func:`.tables.read_results`).
    crs : str
        The project's ``[control] crs``.
    strip : str, optional
        The strip's name, given to photo centres as ``strip`` when
        ``photos.csv`` has no ``strip`` column (a single strip).

    Raises
    ------
    ConfigError
        ``crs = "local"``: a local site system has no geodesy to WGS 84.
    """
    ground = GroundCRS.from_user_input(crs)
    if ground.is_local:
        raise ConfigError(
            'crs = "local": a local site system has no geodesy to WGS 84, which GeoJSON '
            "requires (RFC 7946); export a project in a projected or geographic CRS, or use "
            "stripaero export gpkg (site coordinates without a CRS)"
        )
    lonlat = {
        name: np.round(ground.to_wgs84_lonlat(table.xyz[:, :2]), GEOJSON_DECIMALS)
        if len(table.ids)
        else np.zeros((0, 2))
        for name, table in (("points", points), ("photos", photos))
    }
    photo_extra: dict[str, Value] = {}
    if "strip" not in photos.columns and strip is not None:
        photo_extra["strip"] = strip
    head = {
        "type": "FeatureCollection",
        "stripaero": {
            "crs": crs,
            "crs_name": ground.name,
            "coordinates": "WGS 84 longitude, latitude in degrees (pyproj's best operation "
            "from the project's CRS: for display)",
            "heights": "H of points and Z of photo centres: ellipsoidal heights in metres "
            "on the project CRS's datum, not WGS 84 heights",
            "X_Y": "X, Y of the properties: as in points.csv and photos.csv, in the project's CRS",
            "angles": ANGLES,
        },
    }
    features = _features(points, lonlat["points"], "point", {}) + _features(
        photos, lonlat["photos"], "photo_centre", photo_extra
    )
    lines = [geojson_text(f) for f in features]  # one feature a line
    return geojson_text(head)[:-1] + ',"features":[\n' + ",\n".join(lines) + "\n]}\n"
