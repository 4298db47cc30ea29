"""The ``stripaero`` console script: the command line's imports, then :func:`.main.main`.

Importing the command line (click, numpy and the modules a command needs
at start) takes about 0.15 s; a Ctrl-C meanwhile would end Python with a
traceback of the import.  This module imports nothing but the standard
library's ``sys`` (and the package's ``__init__``, which imports nothing
heavy), so the console script can import it at once and be told of a
Ctrl-C during the rest: exit code 130 and one line on stderr, as a Ctrl-C
during a command gives (:class:`.main.StripaeroGroup`).
"""

from __future__ import annotations

import sys

__all__ = ["INTERRUPTED_STARTING", "main"]

#: The line of a Ctrl-C while the command line is being imported.
INTERRUPTED_STARTING = (
    "stripaero: error: interrupted; the command had not started: nothing was written"
)


def main() -> None:
    """``stripaero`` (and ``python -m strip_aerotri``): import the command line
    and run it; a Ctrl-C during the import exits 130 with one line."""
    try:
        from .main import main as run_command_line
    except KeyboardInterrupt:
        sys.stderr.write(INTERRUPTED_STARTING + "\n")
        sys.stderr.flush()
        raise SystemExit(130) from None
    run_command_line()
