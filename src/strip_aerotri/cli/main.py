"""The ``stripaero`` command group and the translation of errors into exit codes.

Exit codes (docs/cli.md): ``0`` success; ``1`` bad input or an adjustment that
cannot be done, with one line ``stripaero: error: <message>`` on stderr (the
message names the file, line or point and the rule broken); ``2`` usage
errors reported by click; ``130`` interrupted (Ctrl-C, SIGINT), with one
line saying what the output folder holds.  Exceptions are translated here only, at the
boundary; ``--debug`` adds the Python traceback.
"""

from __future__ import annotations

import traceback
import warnings
from collections.abc import Callable
from typing import Any, TextIO

import click

from .._version import __version__
from . import run as run_module  # the module; `run` below is its command
from .check import check
from .docs import docs
from .export import export
from .importer import import_group
from .options import DOCS_EPILOG, Settings, common_options, echo_error, settings
from .run import run
from .simulate import simulate

__all__ = ["cli", "main"]


class StripaeroGroup(click.Group):
    """A click group that gives each invocation fresh :class:`Settings` and
    turns exceptions into one line on stderr and exit code 1."""

    def make_context(
        self,
        info_name: str | None,
        args: list[str],
        parent: click.Context | None = None,
        **extra: Any,
    ) -> click.Context:
        extra.setdefault("obj", Settings())
        return super().make_context(info_name, args, parent=parent, **extra)

    def invoke(self, ctx: click.Context) -> Any:  # what the command returns, as in click
        try:
            with warnings.catch_warnings():
                # numpy's floating-point warnings (overflow, invalid value) are
                # not shown: input that makes them is refused in words, and a
                # failure prints its one error line alone.  Their filters stay
                # as they are (a test suite may turn them into errors).
                warnings.showwarning = _shown_unless_runtime(warnings.showwarning)
                return super().invoke(ctx)
        except (click.exceptions.ClickException, click.exceptions.Exit, click.exceptions.Abort):
            raise
        except KeyboardInterrupt:
            state = settings(ctx).interrupted
            echo_error("interrupted" + (f"; {state()}" if state is not None else ""))
            ctx.exit(130)
        except BrokenPipeError:
            # the reader of stdout went away (``stripaero run ... | head``): the
            # work is done, nothing more can be shown; no traceback at exit
            _silence_stdout()
            ctx.exit(0)
        except Exception as exc:  # the boundary: every other error becomes exit code 1
            report_exception(exc, settings(ctx).debug)
            ctx.exit(1)


def _shown_unless_runtime(show: Callable[..., None]) -> Callable[..., None]:
    """``warnings.showwarning`` that drops RuntimeWarnings and passes on the rest."""

    def showwarning(
        message: Warning | str,
        category: type[Warning],
        filename: str,
        lineno: int,
        file: TextIO | None = None,
        line: str | None = None,
    ) -> None:
        if not issubclass(category, RuntimeWarning):
            show(message, category, filename, lineno, file, line)

    return showwarning


def _silence_stdout() -> None:
    """Point stdout at the null device, so that Python's flush at exit raises no
    second BrokenPipeError (the Python docs' recipe, signal module)."""
    import os
    import sys

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # no real stdout (e.g. a test runner's buffer)
        pass


def report_exception(exc: BaseException, debug: bool) -> None:
    """Print ``exc`` as one error line (with the traceback first when ``debug``)."""
    from ..errors import StripAerotriError

    if debug:
        click.echo("".join(traceback.format_exception(exc)).rstrip(), err=True)
    if isinstance(exc, StripAerotriError):
        echo_error(str(exc))
    elif isinstance(exc, OSError) and exc.filename is not None:
        echo_error(f"{exc.filename}: {exc.strerror or exc}")
    elif isinstance(exc, MemoryError):
        echo_error(
            "out of memory: the project needs more memory than this machine can give "
            "(inputs are bounded in size, see 'stripaero docs project-file', but a very "
            "large block may still exceed it)"
        )
    else:
        hint = "" if debug else " (run with --debug for details)"
        echo_error(f"unexpected {type(exc).__name__}: {exc}{hint}")


@click.group(
    cls=StripaeroGroup,
    epilog=DOCS_EPILOG,
    context_settings={"help_option_names": ["-h", "--help"]},
)
@click.version_option(__version__, "--version", prog_name="stripaero")
@common_options
def cli() -> None:
    """Strip aerotriangulation by partially dependent models.

    Reads a project (strip.toml with image_points.csv and control.csv; one
    strip or a block of strips), forms each strip by dependent relative
    orientation, scale transfer and chaining, transforms it onto the ground
    control (by default every model its own similarity, all at once; or the
    whole strip with deformation polynomials) and writes points.csv,
    photos.csv, report.json and report.html.

    \b
    Examples:
      stripaero simulate film --out demo        # a ready project to try
      stripaero check demo/strip.toml           # validate without adjusting
      stripaero run demo/strip.toml             # adjust; results in demo/out
      stripaero docs                            # the documentation pages
    """


cli.add_command(run)
cli.add_command(check)
cli.add_command(simulate)
cli.add_command(import_group)
cli.add_command(export)
cli.add_command(docs)


def main() -> None:
    """The ``stripaero`` command, once imported (:func:`.entry.main`, the
    console script and ``python -m strip_aerotri``): :func:`cli`, then the
    process ends with its exit code at once.

    When a command has finished, its files are written and closed; what the
    interpreter's teardown would still do (free every object of the run one
    by one, unload the libraries: about 0.1-0.15 s after a 1000-photo run)
    changes nothing outside the process.  So the exit handlers are run
    (``atexit``: a coverage tool's, logging's), the output streams flushed,
    and the process ends by ``os._exit``.  Under a tracer or profiler, or
    while another non-daemon thread runs, it ends the ordinary way.
    """
    run_module.OWNS_PROCESS = True
    try:
        cli(prog_name="stripaero")
    except SystemExit as exc:
        _end_now(exc)
        raise


def _end_now(exc: SystemExit) -> None:
    """End the process with ``exc``'s status after the exit handlers, without
    the interpreter's teardown; return (to raise ``exc``) where that is not safe."""
    import atexit
    import os
    import sys
    import threading

    others = [t for t in threading.enumerate() if t is not threading.main_thread()]
    if sys.gettrace() is not None or sys.getprofile() is not None:
        return
    if any(not t.daemon and t.is_alive() for t in others):
        return
    code = exc.code
    if code is None:
        status = 0
    elif isinstance(code, int):
        status = code
    else:  # sys.exit("message"): printed, status 1
        print(code, file=sys.stderr)
        status = 1
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a reader gone (broken pipe), a closed stream
            pass
    os._exit(status)
