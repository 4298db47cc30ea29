"""The result tables: ``points.csv``, ``photos.csv`` and ``points.geojson``."""

from __future__ import annotations

import numpy as np

from ..export.geojson import GEOJSON_DECIMALS, point_features_text
from ..results import StripResult
from .files import format_photos_csv, format_points_csv
from .values import image_counts, point_roles, residual_columns


def points_csv(result: StripResult, *, roles: np.ndarray | None = None) -> str:
    """Text of ``points.csv`` (triangulated points only; see docs/outputs.md);
    ``roles``: :func:`.values.point_roles` of the result, if known."""
    points = np.asarray(result.points, dtype=np.float64)
    ok = np.isfinite(points).all(axis=1)
    ids = np.asarray(result.point_ids, dtype=str)
    roles = point_roles(result) if roles is None else roles
    n_det = np.asarray(result.strip.n_determinations, dtype=np.int64)
    n_img, _ = image_counts(result)
    resid = residual_columns(result)
    extra = {
        "role": roles[ok],
        "n_models": n_det[ok],
        "n_images": n_img[ok].astype(np.int64),
        "dE": resid[ok, 0],
        "dN": resid[ok, 1],
        "dH": resid[ok, 2],
    }
    return format_points_csv(
        ids[ok], points[ok], extra=extra, geographic=result.ground.crs.is_geographic
    )


def photos_csv(result: StripResult) -> str:
    """Text of ``photos.csv`` (see docs/outputs.md)."""
    _, n_img = image_counts(result)
    ids = np.asarray(result.photo_ids, dtype=str)
    extra = {
        "strip_index": np.arange(len(ids), dtype=np.int64),
        "n_points": n_img.astype(np.int64),
    }
    return format_photos_csv(
        ids,
        result.photo_centres,
        result.photo_opk,
        extra=extra,
        geographic=result.ground.crs.is_geographic,
    )


def points_geojson(result: StripResult, *, roles: np.ndarray | None = None) -> str | None:
    """Text of ``points.geojson``: RFC 7946 FeatureCollection in WGS 84 lon/lat.

    One Point feature per triangulated point, converted with
    :meth:`~strip_aerotri.geodesy.GroundCRS.to_wgs84_lonlat` (pyproj's best
    operation to WGS 84; display accuracy).  Properties: ``id``, ``role``,
    ``H`` (ellipsoidal height in metres on the control CRS's datum, as in
    points.csv), ``n_models``.  None for ``crs = "local"`` (no geodesy).
    ``roles``: :func:`.values.point_roles` of the result, if known.
    """
    crs = result.ground.crs
    if crs.is_local:
        return None
    points = np.asarray(result.points, dtype=np.float64)
    ok = np.isfinite(points).all(axis=1)
    lonlat = np.round(crs.to_wgs84_lonlat(points[ok]), GEOJSON_DECIMALS)
    ids = np.asarray(result.point_ids, dtype=object)[ok]
    properties = {
        "id": ids,
        "role": (point_roles(result) if roles is None else roles)[ok],
        "H": np.round(points[ok, 2], 4),
        "n_models": np.asarray(result.strip.n_determinations, dtype=np.int64)[ok],
    }
    features = point_features_text(ids, lonlat, properties)
    return '{"type":"FeatureCollection","features":[' + ",".join(features) + "]}"
