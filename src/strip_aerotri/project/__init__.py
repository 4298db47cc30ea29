"""Reading and checking a project: ``strip.toml`` and the CSV files it names.

This is the only package that reads TOML.  :func:`load_project` validates a
project strictly (every failure is one :class:`~strip_aerotri.errors.ConfigError`
line naming the file, the line or key, and the rule broken) and returns a
frozen :class:`Project` already in library units: image millimetres, ground
metres, radians.

- :mod:`.schema`: the valid tables, keys and CSV columns (:data:`PROJECT_KEYS`,
  ...), each key's type, unit, default and rule; validation,
  ``stripaero check`` and ``docs/project-file.md`` all follow it;
- :mod:`.csvfiles`: the strict CSV reader (line numbers, comments, ids as text);
- :mod:`.tables`: the image, fiducial, control, GNSS and IMU tables;
- :mod:`.model`: :class:`Camera` and :class:`Project`;
- :mod:`.loader`: :func:`load_project`;
- :mod:`.output`: the output folder's rules;
- :mod:`.check`: :func:`check_project`, the checks of ``stripaero check``;
- :mod:`.run`: :func:`run_project`, the pipeline on a loaded project.
"""

from ..observations import LineSpec
from ..options import Construction, IntersectionMethod, RelativeOrientationMethod
from .check import CheckReport, check_project
from .loader import load_project
from .model import Camera, Project
from .output import DEFAULT_OUTPUT, check_output_directory, output_folder
from .run import project_options, run_project
from .schema import (
    CONTROL_COLUMNS,
    FIDUCIAL_COLUMNS,
    GNSS_COLUMNS,
    IMAGE_COLUMNS,
    IMU_COLUMNS,
    PROJECT_KEYS,
    PROJECT_TABLES,
    ColumnSpec,
    KeySpec,
    TableSpec,
)

__all__ = [
    "CONTROL_COLUMNS",
    "DEFAULT_OUTPUT",
    "FIDUCIAL_COLUMNS",
    "GNSS_COLUMNS",
    "IMAGE_COLUMNS",
    "IMU_COLUMNS",
    "PROJECT_KEYS",
    "PROJECT_TABLES",
    "Block",
    "Camera",
    "CheckReport",
    "ColumnSpec",
    "Intersection",
    "KeySpec",
    "Project",
    "RelativeOrientation",
    "StraightLineSpec",
    "TableSpec",
    "check_output_directory",
    "check_project",
    "load_project",
    "output_folder",
    "project_options",
    "run_project",
]

# Former names of three option enums and of the line specification.
RelativeOrientation = RelativeOrientationMethod
Intersection = IntersectionMethod
Block = Construction
StraightLineSpec = LineSpec
