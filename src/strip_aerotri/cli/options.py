"""Options and output helpers shared by the ``stripaero`` commands.

The options ``-v/--verbose``, ``-q/--quiet`` and ``--debug`` are accepted both
by the group (``stripaero -q run ...``) and by each command (``stripaero run
... -q``); either place sets the same :class:`Settings` object of the
invocation.  Nothing here imports the numerical modules, so ``stripaero
--help`` stays fast.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import click

__all__ = [
    "DOCS_EPILOG",
    "Settings",
    "common_options",
    "debug_opt",
    "echo_error",
    "echo_progress",
    "echo_warning",
    "one_line",
    "project_arg",
    "quiet_opt",
    "settings",
    "verbose_opt",
]

PROG = "stripaero"

#: The function a click decorator takes and returns.
F = TypeVar("F", bound=Callable[..., Any])

DOCS_EPILOG = (
    "\b\n"
    "Documentation, installed with the package (stripaero docs lists every page):\n"
    "  stripaero docs cli              the commands and their options\n"
    "  stripaero docs project-file     strip.toml and the CSV files\n"
    "  stripaero docs outputs          the result folder\n"
    "  stripaero docs troubleshooting  the error messages"
)


@dataclass
class Settings:
    """Output settings of one invocation.

    Attributes
    ----------
    verbose : int
        Number of ``-v`` given (group and command together).
    quiet : int
        Number of ``-q`` given.
    debug : bool
        Show tracebacks of errors.
    interrupted : callable or None
        What the command's state is when Ctrl-C stops it (which result its
        output folder holds), for the one error line; None: nothing to say.
    """

    verbose: int = 0
    quiet: int = 0
    debug: bool = False
    interrupted: Callable[[], str] | None = None

    @property
    def level(self) -> int:
        """Verbosity: 0 normal, < 0 quieter, > 0 more detail."""
        return self.verbose - self.quiet

    @property
    def log_level(self) -> int:
        """The ``logging`` level of the verbosity (WARNING by default)."""
        return max(logging.DEBUG, min(logging.CRITICAL, logging.WARNING - 10 * self.level))


def settings(ctx: click.Context | None = None) -> Settings:
    """The :class:`Settings` of the current invocation (created if missing)."""
    ctx = ctx or click.get_current_context()
    found = ctx.find_object(Settings)
    if found is None:
        found = ctx.find_root().ensure_object(Settings)
    return found


def _add_count(name: str) -> Callable[[click.Context, click.Parameter, int], None]:
    def callback(ctx: click.Context, param: click.Parameter, value: int) -> None:
        if value:
            obj = settings(ctx)
            setattr(obj, name, getattr(obj, name) + int(value))
            logging.getLogger("strip_aerotri").setLevel(obj.log_level)

    return callback


def _set_debug(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    if value:
        settings(ctx).debug = True


verbose_opt = click.option(
    "-v",
    "--verbose",
    count=True,
    expose_value=False,
    callback=_add_count("verbose"),
    help="More detail (repeat for more).",
)
quiet_opt = click.option(
    "-q",
    "--quiet",
    count=True,
    expose_value=False,
    callback=_add_count("quiet"),
    help="No progress messages and no warnings (they stay in the report); -qq also "
    "hides the summary: errors only.",
)
debug_opt = click.option(
    "--debug",
    is_flag=True,
    expose_value=False,
    callback=_set_debug,
    help="Show the Python traceback of an error.",
)


def common_options(func: F) -> F:
    """Apply ``-v``, ``-q`` and ``--debug`` to a command."""
    return verbose_opt(quiet_opt(debug_opt(func)))


# Not ``exists=True``: a missing project file is bad input (exit 1, one line from
# the loader), not a usage error (exit 2), as docs/cli.md counts it.
project_arg = click.argument(
    "project_file",
    metavar="STRIP_TOML",
    type=click.Path(path_type=Path),
)


def one_line(text: object, *, items: bool = False, where: str = "") -> str:
    """``text`` as one line (line breaks become ``"; "``) without control
    characters, its middle left out beyond :data:`~strip_aerotri._text.MAX_LINE`
    characters (a message that echoes a huge value stays one readable line).

    With ``items`` a longer text is a list: it is cut after its last whole
    ``"; "``-separated item that fits, saying how many more ``where`` lists
    (:func:`~strip_aerotri._text.cut_at_items`)."""
    from .._text import MAX_LINE, cut_at_items, shorten

    parts = [part.strip() for part in str(text).splitlines() if part.strip()]
    if items:
        return cut_at_items("; ".join(parts), MAX_LINE, where=where)
    return shorten("; ".join(parts), MAX_LINE)


def echo_error(message: object) -> None:
    """``stripaero: error: <message>`` on stderr (always shown)."""
    click.echo(f"{PROG}: error: {one_line(message)}", err=True)


def echo_warning(message: object, *, where: str = "") -> None:
    """``stripaero: warning: <message>`` on stderr unless ``-q`` (the
    warnings stay in report.json and report.html).  A long warning is a
    list cut after a whole item, with how many more ``where`` (the file
    that keeps the whole text) lists; without ``where`` (nothing keeps the
    whole text) it is shortened in the middle, its head and its end kept."""
    if settings().level >= 0:
        line = one_line(message, items=bool(where), where=where)
        click.echo(f"{PROG}: warning: {line}", err=True)


def echo_progress(message: object, *, level: int = 0) -> None:
    """A progress message on stderr, shown when the verbosity is at least ``level``:
    at level 0 only when stderr is a terminal, so that a script or a CI log
    reading stderr sees a failing run's one error line alone (``-v`` shows
    the progress anywhere)."""
    shown = settings().level >= (level if _stderr_is_terminal() else max(level, 1))
    if shown:
        click.echo(f"{PROG}: {one_line(message)}", err=True)


def _stderr_is_terminal() -> bool:
    import sys

    try:
        return bool(sys.stderr.isatty())
    except (AttributeError, ValueError):  # a closed or replaced stream
        return False


def echo_result(message: str = "") -> None:
    """A line of the result summary on stdout unless ``-qq``."""
    if settings().level >= -1:
        click.echo(message)
