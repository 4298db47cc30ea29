"""Files for the tools users open next, written from a finished run.

- :mod:`.cameras`: the photos' projection centres and omega, phi, kappa in
  the PATB convention on the map grid, the text that Pix4D writes as its
  calibrated external camera parameters and that Metashape imports as
  reference (docs/export.md);
- :mod:`.odm`: points with their pixel measurements as OpenDroneMap's
  ``gcp_list.txt``;
- :mod:`.tables`: ``points.csv`` and ``photos.csv`` of a result folder, read
  back for the GIS exports;
- :mod:`.geojson`: the points and photo centres as GeoJSON (WGS 84);
- :mod:`.gpkg`: the points and photo centres as a GeoPackage in the
  project's CRS (needs the ``gpkg`` extra: pyogrio).
"""

from .cameras import camera_rotations_grid, cameras_opk_text
from .geojson import results_geojson
from .gpkg import write_gpkg
from .odm import crs_line, gcp_list_text
from .tables import ResultTable, read_results

__all__ = [
    "ResultTable",
    "camera_rotations_grid",
    "cameras_opk_text",
    "crs_line",
    "gcp_list_text",
    "read_results",
    "results_geojson",
    "write_gpkg",
]
