"""OpenDroneMap's ground control file, ``gcp_list.txt``: :func:`read_gcp_list`.

The layout of OpenDroneMap's documentation ("Ground Control Points", the GCP
file format): the first line is the CRS of the ground coordinates, a PROJ
string (``+proj=utm +zone=32 +datum=WGS84 +units=m +no_defs``), ``EPSG:nnnn``
or ``WGS84 UTM <zone><N|S>``; every following line is

    geo_x geo_y geo_z im_x im_y image_name [gcp_name [extra ...]]

separated by spaces or tabs, ``im_x``, ``im_y`` the pixel column and row of
the GCP on the image (origin top-left, rows down).  Without ``gcp_name`` the
lines with the same ``geo_x geo_y geo_z`` are one GCP (named ``gcp1``,
``gcp2``, ... in order of appearance).  Both the ODM importer
(:mod:`.odm`) and the COLMAP importer (``--gcps``, :mod:`.colmap`) read it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from .common import ControlTable, ImageTable, photo_id, read_text, split_rows, to_floats

__all__ = ["GcpList", "crs_from_odm", "read_gcp_list"]

_UTM = re.compile(r"^\s*WGS\s*-?\s*84\s+UTM\s+(\d{1,2})\s*([NS])\s*$", re.IGNORECASE)


def crs_from_odm(text: str, where: str) -> str:
    """The CRS of a gcp_list.txt header line, as pyproj understands it.

    ``WGS84 UTM 32N`` becomes ``EPSG:32632`` (``32S``: ``EPSG:32732``);
    anything else (a PROJ string, ``EPSG:nnnn``, WKT) is passed on after
    pyproj has read it.
    """
    text = text.strip()
    m = _UTM.match(text)
    if m:
        zone = int(m.group(1))
        if not 1 <= zone <= 60:
            raise ConfigError(f"{where}: UTM zone {zone} is not 1..60")
        return f"EPSG:{32600 + zone if m.group(2).upper() == 'N' else 32700 + zone}"
    from pyproj import CRS

    try:
        CRS.from_user_input(text)
    except Exception:
        raise ConfigError(
            f"{where}: the first line must be the CRS (a PROJ string, EPSG:nnnn or "
            f"'WGS84 UTM 32N'), got {text!r}"
        ) from None
    return text


@dataclass(frozen=True)
class GcpList:
    """What a gcp_list.txt holds."""

    crs: str
    images: ImageTable
    control: ControlTable
    notes: list[str] = field(default_factory=list)


def read_gcp_list(path: Path) -> GcpList:
    """Read an OpenDroneMap ``gcp_list.txt``.

    Raises
    ------
    ConfigError
        A bad CRS line, a line with fewer than 6 fields or a bad number, or a
        GCP name given with two different ground coordinates.
    """
    text = read_text(path, "OpenDroneMap GCP list")
    lines = text.splitlines()
    head = next(
        (k for k, line in enumerate(lines) if line.strip() and not line.lstrip().startswith("#")),
        None,
    )
    if head is None:
        raise ConfigError(f"{path}: empty (expected the CRS on the first line)")
    crs = crs_from_odm(lines[head], f"{path}:{head + 1}")
    rows = split_rows(path, "\n" * (head + 1) + "\n".join(lines[head + 1 :]))
    if not len(rows):
        raise ConfigError(f"{path}: no GCP observation after the CRS line")
    rows.require_fields(6, "geo_x geo_y geo_z im_x im_y image_name [gcp_name]")
    geo = np.column_stack(
        [
            to_floats(rows.column(k), rows, name)
            for k, name in enumerate(("geo_x", "geo_y", "geo_z"))
        ]
    )
    pix = np.column_stack(
        [to_floats(rows.column(k), rows, n) for k, n in ((3, "im_x"), (4, "im_y"))]
    )
    photos = photo_id(rows.column(5))
    counts = rows.counts()
    notes: list[str] = []
    if (counts >= 7).all():
        names = np.array([f[6] for f in rows.fields], dtype=str)
    elif (counts == 6).all():
        _, first, inverse = np.unique(geo, axis=0, return_index=True, return_inverse=True)
        rank = np.argsort(np.argsort(first))  # in order of appearance
        names = np.char.add("gcp", (rank[inverse.reshape(-1)] + 1).astype(str))
        notes.append(
            "GCPs without names: lines with equal coordinates are one GCP (gcp1, gcp2, ...)"
        )
    else:
        named = counts >= 7
        k = int(np.flatnonzero(named != named[0])[0])
        raise ConfigError(f"{rows.where(k)}: some lines name their GCP and some do not")
    uniq, first, inverse = np.unique(names, return_index=True, return_inverse=True)
    inverse = inverse.reshape(-1)
    differ = np.any(
        np.abs(geo - geo[first][inverse]) > 1e-9 * np.maximum(1.0, np.abs(geo)), axis=1
    )
    if differ.any():
        k = int(np.flatnonzero(differ)[0])
        raise ConfigError(
            f"{rows.where(k)}: GCP '{names[k]}' has other coordinates than at line "
            f"{int(rows.lines[first[inverse[k]]])}"
        )
    images = ImageTable(photos, names, pix)
    control = ControlTable(uniq, geo[first])
    return GcpList(crs, images, control, notes)
