"""Importers: write a contract project (strip.toml and CSV files) from another program's files.

One module per source format reads its files into arrays and hands them to
:func:`~strip_aerotri.importers.common.assemble`, which decides the strips,
the photo order, the image axis along the flight and the control/check
split; :func:`~strip_aerotri.importers.common.write_project` writes the
project atomically.  See docs/import.md.

Example
-------
>>> from strip_aerotri.importers import ImportOptions, import_patb, write_project
>>> project = import_patb("block.im", "block.con", ImportOptions(strips=(1,)),
...                       focal_mm=153.2, crs="EPSG:25832")  # doctest: +SKIP
>>> write_project(project, "proj")  # doctest: +SKIP
"""

from __future__ import annotations

from .colmap import import_colmap
from .common import ImportedProject, ImportOptions, write_project
from .metashape import import_metashape
from .odm import PixelCamera, import_odm
from .patb import import_patb
from .pix4d import import_pix4d
from .uav_fc300x import import_uav_fc300x

__all__ = [
    "ImportOptions",
    "ImportedProject",
    "PixelCamera",
    "import_colmap",
    "import_metashape",
    "import_odm",
    "import_patb",
    "import_pix4d",
    "import_uav_fc300x",
    "write_project",
]
