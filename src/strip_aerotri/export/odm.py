"""Points as an OpenDroneMap ``gcp_list.txt`` (docs/export.md).

The first line is the CRS (``EPSG:nnnn`` when the CRS has an EPSG code,
else its PROJ string); every following line is

    geo_x geo_y geo_z im_x im_y image_name gcp_name

one per observation of a point: the point's adjusted coordinates in the
project's CRS and its measured pixel column and row on the image (origin
top-left, rows down), as OpenDroneMap reads ground control.  The pixels are
the project's own measurements (``[images] units = "pixel"``): a project
measured in millimetres has no pixel geometry to give and is refused.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .._typing import FloatArray
from ..errors import ConfigError

__all__ = ["crs_line", "gcp_list_text"]


def crs_line(crs: str) -> str:
    """The first line of the file: ``EPSG:nnnn`` or the CRS's PROJ string."""
    if crs.strip().lower() == "local":
        raise ConfigError(
            'crs = "local": a local site system has no CRS that OpenDroneMap could '
            "georeference with; export a project in a projected CRS"
        )
    from pyproj import CRS

    target = CRS.from_user_input(crs)
    code = target.to_epsg()
    if code is not None:
        return f"EPSG:{code}"
    proj: str = target.to_proj4()
    return proj


def gcp_list_text(
    crs: str,
    geo: FloatArray,
    pixels: FloatArray,
    images: Sequence[str],
    names: Sequence[str],
) -> str:
    """The file's text: ``geo`` (n, 3) ground coordinates, ``pixels`` (n, 2)
    column and row, ``images`` the image file names and ``names`` the points."""
    geo = np.asarray(geo, dtype=np.float64)
    pixels = np.asarray(pixels, dtype=np.float64)
    lines = [crs_line(crs)]
    lines += [
        f"{x:.4f} {y:.4f} {z:.4f} {c:.3f} {r:.3f} {image} {name}"
        for (x, y, z), (c, r), image, name in zip(geo, pixels, images, names, strict=True)
    ]
    return "\n".join(lines) + "\n"
