"""The output folder of a run: where it is, and what may never be replaced.

A result folder is never the project folder, never holds an input file, and
replaces only an empty folder or a previous result folder (one holding the
result marker); every refusal is one line naming the folder and the rule.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from .._atomic import input_inside
from ..errors import ConfigError

if TYPE_CHECKING:
    from .model import Project

__all__ = ["DEFAULT_OUTPUT", "check_output_directory", "check_writable", "output_folder"]

DEFAULT_OUTPUT = "out"
"""Result folder (inside the project folder) when neither --out nor [output] directory is given."""


def output_folder(project: Project, out: Path | None) -> Path:
    """The result folder of a run and its checks against the project's inputs.

    ``--out`` (relative to the current folder) wins over ``[output] directory``
    (relative to the project folder); without either the result goes to
    ``out`` beside ``strip.toml``.

    Raises
    ------
    ConfigError
        The folder is the project folder, holds an input file or is a file.
    OutputError
        The folder exists, is not empty and is not a previous result folder.
    """
    if out is not None:
        target = check_output_directory(out, project, source="--out")
    elif project.output_directory is not None:
        target = project.output_directory
    else:
        target = check_output_directory(
            project.path.parent / DEFAULT_OUTPUT, project, source="default output folder"
        )
    _check_replaceable(target, project.input_files)
    check_writable(target)
    return target


def check_writable(target: Path) -> None:
    """Refuse, before any work, a result folder whose parent cannot be written
    (a result is written beside it and renamed in): a folder is made and
    removed in the nearest existing one of its parents.

    Raises
    ------
    OutputError
        Naming the folder, the parent that cannot be written and why.
    """
    import tempfile

    from ..report.files import OutputError

    parent = target.absolute().parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    try:
        if not parent.is_dir():
            raise NotADirectoryError(20, "not a folder")
        probe = tempfile.mkdtemp(prefix=f".{target.name}.probe-", dir=parent)
        Path(probe).rmdir()
    except OSError as exc:
        raise OutputError(
            f"output folder '{target}' cannot be written: '{parent}': {exc.strerror or exc}; "
            "choose another --out (or [output] directory)"
        ) from exc


def _check_replaceable(target: Path, inputs: Sequence[Path]) -> None:
    """Refuse early (before adjusting) what :class:`~strip_aerotri.report.files.ResultFolder`
    refuses."""
    from ..report.files import RESULT_MARKER, OutputError

    if target.is_symlink():
        raise OutputError(f"output folder '{target}' is a symbolic link; give the real folder")
    if not target.exists():
        return
    if not target.is_dir():
        raise OutputError(f"output folder '{target}' is a file, not a folder")
    if not (target / RESULT_MARKER).is_file() and any(target.iterdir()):
        raise OutputError(
            f"output folder '{target}' is not empty and is not a stripaero result folder "
            f"(no {RESULT_MARKER} file); refusing to replace it: choose another --out or "
            "empty it"
        )
    item = input_inside(target, inputs)
    if item is not None:
        raise OutputError(
            f"output folder '{target}' contains the input file '{item}'; refusing to replace it"
        )


def _is_within(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def check_output_directory(
    directory: str | Path, project: Project, *, source: str = "--out"
) -> Path:
    """Check that results may be written to ``directory``.

    Parameters
    ----------
    directory : str or Path
        The result folder (relative paths are relative to the current folder,
        as for a command-line option).
    project : Project
        The loaded project, whose input files are protected.
    source : str
        Where the folder came from, for messages (e.g. ``"--out"``).

    Returns
    -------
    Path
        ``directory`` as a Path.

    Raises
    ------
    ConfigError
        If the folder is the project folder, contains an input file, or is a file.
    """
    return check_output(Path(directory), project.input_files, source)


def check_output(directory: Path, inputs: Sequence[Path], source: str) -> Path:
    target = directory.resolve()
    if target.exists() and not target.is_dir():
        raise ConfigError(f"{source}: output folder '{directory}' is a file")
    project_dir = inputs[0].resolve().parent
    if target == project_dir:
        raise ConfigError(
            f"{source}: output folder '{directory}' is the project folder; "
            'choose a folder of its own (e.g. "out")'
        )
    for item in inputs:
        if _is_within(item.resolve(), target):
            raise ConfigError(
                f"{source}: output folder '{directory}' contains the input file '{item}'; "
                "results replace the whole folder"
            )
    return directory
