"""``stripaero check``: validate a project without adjusting it.

The checks are :func:`strip_aerotri.project.check_project`'s; this command
loads the project, prints the problems (exit 1) or the warnings and the
summary (exit 0).
"""

from __future__ import annotations

from pathlib import Path

import click

from .options import (
    DOCS_EPILOG,
    common_options,
    echo_error,
    echo_progress,
    echo_result,
    echo_warning,
    project_arg,
)

__all__ = ["check"]


@click.command(epilog=DOCS_EPILOG, short_help="Validate a project without adjusting it.")
@project_arg
@click.option(
    "-o",
    "--out",
    type=click.Path(path_type=Path),
    default=None,
    help="Check this result folder instead of the project's.",
)
@common_options
def check(project_file: Path, out: Path | None) -> None:
    """Validate STRIP_TOML and its CSV files without adjusting.

    Reads the project like `stripaero run` and then checks the geometry by
    counting: at least five common points per pair, a tie point between
    consecutive models, enough control (two plan, three height points, not
    degenerate; the polynomial's minimum) and straight-line points measured
    on a pair. Exits with 0 and a summary when the project can be run; with
    1 and one line per problem otherwise (loading stops at the first
    problem, the geometric checks list all).

    \b
    Examples:
      stripaero check examples/film-strip/strip.toml
      stripaero check -v strip.toml          # with per-pair figures
    """
    import warnings

    from ..errors import StripAerotriWarning
    from ..project import check_project, load_project

    echo_progress(f"loading {project_file}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StripAerotriWarning)
        project = load_project(project_file)
    rep = check_project(project, out)
    if rep.problems:
        for message in rep.problems:
            echo_error(message)
        raise click.exceptions.Exit(1)
    shown: set[str] = set()
    for message in (*project.warnings, *rep.warnings, *(str(w.message) for w in caught)):
        if message not in shown:  # loading warns and lists in Project.warnings alike
            shown.add(message)
            echo_warning(message)
    for line in rep.summary:
        echo_result(line)
    from .options import settings

    if settings().level >= 1:
        for line in rep.details:
            echo_result("  " + line)
    echo_result("OK: the project can be run")
