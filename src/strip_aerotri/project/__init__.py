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

The names of :mod:`.check` and :mod:`.run` are imported on first use (PEP
562): ``stripaero run`` needs the output folder's rules at once and the rest
of the run only after its forked child has begun loading the project (0.05 s
of imports moved out of the way, cli/loading.py).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from ..observations import LineSpec
from ..options import Construction, IntersectionMethod, RelativeOrientationMethod
from .loader import load_project
from .model import Camera, Project
from .output import DEFAULT_OUTPUT, check_output_directory, output_folder
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

if TYPE_CHECKING:
    from .check import CheckReport, check_project
    from .run import project_options, run_project

#: The names imported on first use, and their modules.
_LAZY = {
    "CheckReport": ".check",
    "check_project": ".check",
    "project_options": ".run",
    "run_project": ".run",
}


def __getattr__(name: str) -> object:
    """A name of :mod:`.check` or :mod:`.run`, imported on first use (PEP 562)."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})

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
