"""Writing files and folders whole or not at all: the one place of the
rename dance that every writer of the package uses (the result folder,
the imported project, the exported files).

A file is written to a hidden partial file beside it and renamed onto it
(:func:`atomic_file`); a folder is filled as a hidden temporary folder
beside it (:func:`folder_beside`) and swapped in (:func:`swap_folder`).  A
rename within one folder is atomic on POSIX and Windows file systems.
"""

from __future__ import annotations

import os
import shutil
import uuid
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_file", "folder_beside", "input_inside", "swap_folder"]


def _beside(target: Path, kind: str) -> Path:
    """A hidden name beside ``target`` that no other writer uses."""
    return target.parent / f".{target.name}.{kind}-{uuid.uuid4().hex[:12]}"


@contextmanager
def atomic_file(target: Path) -> Iterator[Path]:
    """A partial file to write instead of ``target``; renamed onto ``target``
    when the block ends normally, removed when it raises.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
    >>> with atomic_file(target) as partial:
    ...     _ = partial.write_text("whole")
    >>> target.read_text(), sorted(p.name for p in target.parent.iterdir())
    ('whole', ['a.txt'])
    """
    partial = _beside(target, "partial").with_suffix(target.suffix)
    try:
        yield partial
        os.replace(partial, target)
    finally:
        partial.unlink(missing_ok=True)


def folder_beside(target: Path) -> Path:
    """A new, empty hidden folder beside ``target`` (its parents created)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = _beside(target, "tmp")
    tmp.mkdir()
    return tmp


def swap_folder(tmp: Path, target: Path) -> None:
    """Put the folder ``tmp`` in the place of ``target`` (which may not exist).

    The old ``target`` is moved aside, ``tmp`` renamed onto it, and the old
    one removed; if the rename fails, the old ``target`` is put back and
    the OSError raised (``tmp`` is then still there for the caller to
    remove).
    """
    old = _beside(target, "old")
    moved = False
    try:
        if target.exists():
            os.replace(target, old)
            moved = True
        os.replace(tmp, target)
    except OSError:
        if moved and not target.exists():
            os.replace(old, target)
        raise
    if moved:
        shutil.rmtree(old, ignore_errors=True)


def input_inside(
    folder: Path, inputs: Iterable[os.PathLike[str] | str]
) -> os.PathLike[str] | str | None:
    """The first of ``inputs`` that is ``folder`` or lies inside it (paths
    resolved), which replacing the folder would destroy; None when none does.

    >>> import pathlib
    >>> input_inside(pathlib.Path("/data/out"), ["/data/strip.toml", "/data/out/a.csv"])
    '/data/out/a.csv'
    """
    resolved = folder.resolve()
    for item in inputs:
        path = Path(item).resolve()
        if path == resolved or resolved in path.parents:
            return item
    return None
