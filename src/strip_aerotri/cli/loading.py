"""The project of ``stripaero run`` loaded by a forked process while this one
imports the modules of the run.

At its start a run has two things to do that do not depend on each other:
load the project (read and check strip.toml and the CSVs: about 0.15 s for a
1000-photo strip with 100 000 image points) and import what adjusts it and
writes its report (scipy.linalg and the package's own
stages: about 0.2 s).  Imports cannot be handed from one process to
another, a loaded project can: :func:`loaded` forks the run's one child
(:class:`..report.aside.Standby`) at the start, when this process is small;
the child loads the project and sends it back (5 MB pickled for that strip,
a few ms) while this process imports, then, for a strip, imports matplotlib
and waits to draw the report's figures.

The child changes nothing a user sees:

* an error of the project (a ConfigError with its file, line and column) is
  raised by loading it here again, so it reads exactly as without the child;
* the warnings of the loading are recorded in the child and handed to the
  caller as the :class:`warnings.WarningMessage` they would have been here;
* without fork (``STRIPAERO_FORK=0``, other systems, other threads) the
  project is loaded here, after the imports, as before.
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, cast

if TYPE_CHECKING:
    from ..project import Project
    from ..report.aside import Standby

__all__ = ["BEFORE_FORK", "RUN_MODULES", "load_recorded", "loaded"]

#: What every run imports after loading its project, imported meanwhile
#: (numerical libraries first: the longest).  A name here that a run did not
#: need would only cost its import; each is imported by the run anyway.
RUN_MODULES = (
    "scipy.linalg",
    "strip_aerotri.project.run",
    "strip_aerotri.report.summary",
    "strip_aerotri.report.html",
    "strip_aerotri.ground.check_precision",
    "threadpoolctl",
)

#: Imported here before the child is forked, so that both have it: what a
#: geodetic project (every real one) needs both to be loaded (its CRS checked)
#: and in its run (points.geojson); a local project's run imports it for
#: nothing (0.04 s), as the child would otherwise import it a second time.
BEFORE_FORK = ("pyproj",)

Loaded = tuple["Project", list[warnings.WarningMessage]]


def load_recorded(project_file: Path) -> Loaded:
    """:func:`..project.load_project` and the warnings it gave (recorded under the
    caller's filters), ready to be pickled (no ``source`` objects)."""
    from ..project import load_project

    with warnings.catch_warnings(record=True) as caught:
        project = load_project(project_file)
    for item in caught:
        item.source = None  # any object the warning was about: not needed, may not pickle
    return project, caught


def _prepare_for(loaded: Loaded) -> None:
    """In the child, once the project is sent: matplotlib made ready for a
    strip's figures (a block's page draws its own)."""
    from ..report.html import prepare_drawing

    if not loaded[0].is_block:
        prepare_drawing()


@contextmanager
def loaded(
    project_file: Path, caught: list[warnings.WarningMessage]
) -> Iterator[tuple[Project, Standby | None]]:
    """The project of ``project_file`` and the child that draws a strip's
    figures (None for a block), for the ``with`` block.

    The project is loaded in the child while the :data:`RUN_MODULES` are
    imported here; its warnings are appended to ``caught`` (the list of an
    enclosing ``warnings.catch_warnings(record=True)``).  The child is
    killed and reaped however the block is left.
    """
    from ..report.aside import Standby

    for name in BEFORE_FORK:
        importlib.import_module(name)
    with Standby(_prepare_for, first=partial(load_recorded, project_file)) as standby:
        for name in RUN_MODULES:
            importlib.import_module(name)
        project, seen = cast(Loaded, standby.first_result())
        caught.extend(seen)
        if project.is_block:
            standby.close()  # no figures to wait for: the child ends now
        yield project, None if project.is_block else standby
