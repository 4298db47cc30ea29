"""What every importer shares: reading text, the imported project, its strips, its writing.

An importer reads one source format into arrays (image observations, control
points, optional projection centres and attitudes) and calls :func:`assemble`.
:func:`assemble` decides what the source does not say and records each
decision as a note:

* the strips and the photo order in each (given by the importer or by
  ``--photo-order``; else from the photos' positions, split where the track
  turns; else one strip in photo-name order), see :func:`strips_from_positions`;
* the image axis that points along the flight (``[images] flight_direction``)
  from the mean shift of the points between consecutive photos, reversing a
  strip whose photos move the other way, see :func:`decide_flight_direction`;
* which control points are full control and which are check points, see
  :func:`split_control`.

:func:`write_project` writes the result as a contract project
(``docs/project-file.md``): ``strip.toml``, ``image_points.csv``,
``control.csv`` and, where the source has them, ``gnss.csv`` and ``imu.csv``;
atomically (a temporary folder beside the target, then a rename), and never
over an existing folder without ``force``.

Conventions: image coordinates are kept in the source's units, either
millimetres in the sensor axes (x right, y up) or pixel column and row (rows
down); ids are strings; ground coordinates are in the project CRS with
pyproj's ``always_xy`` axis order.  Attitudes are rotation matrices mapping
sensor-axis image vectors ``(x, y, -c)`` to local east-north-up (or the site
axes of ``crs = "local"``); :func:`assemble` turns them into the flight axes
of the project.
"""

from __future__ import annotations

from .._toml import toml_value
from .assemble import assemble
from .attitudes import attitudes_from_opk
from .control import split_control
from .strips import decide_flight_direction, strips_from_positions
from .tables import (
    Camera,
    ControlTable,
    Distortion,
    ImageFrame,
    ImageTable,
    ImportOptions,
    ImportedProject,
    PhotoAttitudes,
    PhotoPositions,
    Strip,
)
from .text import (
    Rows,
    check_unique,
    line_floats,
    natural_key,
    photo_id,
    read_text,
    split_rows,
    to_floats,
)
from .writer import project_toml, write_project

__all__ = [
    "Camera",
    "ControlTable",
    "Distortion",
    "ImageFrame",
    "ImageTable",
    "ImportOptions",
    "ImportedProject",
    "PhotoAttitudes",
    "PhotoPositions",
    "Rows",
    "Strip",
    "assemble",
    "attitudes_from_opk",
    "check_unique",
    "decide_flight_direction",
    "line_floats",
    "natural_key",
    "photo_id",
    "project_toml",
    "read_text",
    "split_control",
    "split_rows",
    "strips_from_positions",
    "to_floats",
    "toml_value",
    "write_project",
]
