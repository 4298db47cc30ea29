"""Files for the tools users open next, written from a finished run.

- :mod:`.cameras`: the photos' projection centres and omega, phi, kappa in
  the PATB convention on the map grid, the text that Pix4D writes as its
  calibrated external camera parameters and that Metashape imports as
  reference (docs/export.md).
"""

from .cameras import camera_rotations_grid, cameras_opk_text

__all__ = ["camera_rotations_grid", "cameras_opk_text"]
