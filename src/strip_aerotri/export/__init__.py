"""Files for the tools users open next, written from a finished run.

- :mod:`.cameras`: the photos' projection centres and omega, phi, kappa in
  the PATB convention on the map grid, the text that Pix4D writes as its
  calibrated external camera parameters and that Metashape imports as
  reference (docs/export.md);
- :mod:`.odm`: points with their pixel measurements as OpenDroneMap's
  ``gcp_list.txt``.
"""

from .cameras import camera_rotations_grid, cameras_opk_text
from .odm import crs_line, gcp_list_text

__all__ = ["camera_rotations_grid", "cameras_opk_text", "crs_line", "gcp_list_text"]
