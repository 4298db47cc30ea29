"""The points and the photo centres of a run as a GeoPackage (docs/export.md).

Two layers of ``Point Z`` features in the project's own CRS (not WGS 84):
``points`` (one per row of ``points.csv``) and ``photo_centres`` (one per
row of ``photos.csv``), with every column of the row as a field (an empty
cell as NULL).  The geometry is X, Y, H (or Z) as in the CSVs: easting,
northing (or longitude, latitude in degrees for a geographic CRS) and the
ellipsoidal height on the CRS's datum.  ``crs = "local"``: the layers are
written in the site's metres without a CRS (GDAL's undefined SRS), which a
GIS shows as an unreferenced plan.

Writing needs pyogrio (``pip install 'strip_aerotri[gpkg]'``), imported when
a file is written, so that ``import strip_aerotri`` stays light.
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from .._atomic import atomic_file
from ..errors import MissingExtraError
from ..geodesy import GroundCRS
from .tables import ResultTable, Value

__all__ = ["GPKG_EXTRA", "LAYERS", "write_gpkg"]

GPKG_EXTRA = "pip install 'strip_aerotri[gpkg]'"
"""How to install what :func:`write_gpkg` needs."""

LAYERS = ("points", "photo_centres")
"""The layers written, in order."""


def _pyogrio_write() -> Any:
    try:
        from pyogrio.raw import write
    except ImportError:
        raise MissingExtraError(
            f"a GeoPackage is written with pyogrio, which is not installed: {GPKG_EXTRA}"
        ) from None
    return write


def _point_z(xyz: np.ndarray) -> np.ndarray:
    """ISO WKB ``Point Z`` of each row (None where X or Y is missing)."""
    out = np.empty(len(xyz), dtype=object)
    for k, (x, y, z) in enumerate(xyz.tolist()):
        finite = np.isfinite(x) and np.isfinite(y)
        out[k] = struct.pack("<BIddd", 1, 1001, x, y, z) if finite else None
    return out


def _field(values: list[Value]) -> np.ndarray:
    """A column as pyogrio takes it: int64 (integers, none missing), float64
    (numbers, NaN for missing: NULL in the file) or object (text, None)."""
    filled = [v for v in values if v is not None]
    if filled and all(isinstance(v, int) for v in filled) and len(filled) == len(values):
        return np.array(values, dtype=np.int64)
    if filled and all(isinstance(v, int | float) for v in filled):
        return np.array([np.nan if v is None else v for v in values], dtype=np.float64)
    return np.array([None if v is None else str(v) for v in values], dtype=object)


def write_gpkg(
    path: Path,
    points: ResultTable,
    photos: ResultTable,
    crs: str,
    *,
    strip: str | None = None,
) -> None:
    """Write the GeoPackage ``path`` whole or not at all.

    Parameters
    ----------
    path : Path
        The file (replaced if it exists).
    points, photos : ResultTable
        ``points.csv`` and ``photos.csv`` of the run (:func:`.tables.read_results`).
    crs : str
        The project's ``[control] crs``; ``"local"`` writes no CRS.
    strip : str, optional
        The strip's name, a ``strip`` field of the photo centres when
        ``photos.csv`` has none (a single strip).

    Raises
    ------
    MissingExtraError
        pyogrio is not installed.
    """
    write = _pyogrio_write()
    ground = GroundCRS.from_user_input(crs)
    wkt = None if ground.crs is None else ground.crs.to_wkt()
    photo_columns = dict(photos.columns)
    if "strip" not in photo_columns and strip is not None:
        photo_columns = {"strip": [strip] * len(photos.ids), **photo_columns}
    with atomic_file(path) as partial:  # a new file: GDAL would add to an existing one
        for layer, table, columns in (
            ("points", points, points.columns),
            ("photo_centres", photos, photo_columns),
        ):
            with warnings.catch_warnings():
                # pyogrio warns that no CRS is given: for "local" that is the point
                warnings.filterwarnings("ignore", message="'crs' was not provided")
                write(
                    str(partial),
                    _point_z(table.xyz),
                    [_field(v) for v in columns.values()],
                    list(columns),
                    layer=layer,
                    driver="GPKG",
                    crs=wkt,
                    geometry_type="Point Z",
                )
