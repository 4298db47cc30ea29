"""One run at a time into a result folder: a lock file in the folder's parent.

:class:`FolderLock` creates ``.<name>.lock`` beside the result folder
``<name>`` (exclusively: the operating system lets only one process create
it), writes the process id, host and time into it, and deletes it on exit.
A second run into the same folder is refused with one line naming the
holder and the file.  A lock left by a run that was killed (its process no
longer exists on this host) is stale: it is removed and taken over.
"""

from __future__ import annotations

import datetime as _dt
import os
import socket
import uuid
from pathlib import Path
from types import TracebackType

from .files import OutputError

__all__ = ["FolderLock", "lock_path"]

_UNREADABLE_GRACE_S = 60.0
"""A lock file without a readable holder is taken for one being written
for this long; older, it is stale."""


def lock_path(target: Path) -> Path:
    """The lock file of the result folder ``target``."""
    return target.parent / f".{target.name}.lock"


def _holder_text() -> str:
    now = _dt.datetime.now(_dt.UTC).replace(microsecond=0).isoformat()
    return f"{os.getpid()} {socket.gethostname()} {now}\n"


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # it exists, owned by another user
        return True
    return True


def _is_stale(path: Path, text: str) -> bool:
    """The holder of ``text`` is a process of this host that no longer runs,
    or the file has no readable holder and is older than the grace time."""
    parts = text.split()
    if len(parts) >= 2 and parts[0].isdigit():
        return parts[1] == socket.gethostname() and not _alive(int(parts[0]))
    try:
        age = _dt.datetime.now().timestamp() - path.stat().st_mtime
    except FileNotFoundError:
        return True
    return age > _UNREADABLE_GRACE_S


class FolderLock:
    """Hold the lock of the result folder ``target`` inside a ``with`` block.

    Raises
    ------
    OutputError
        Another live run holds the lock, or the lock file cannot be written.
    """

    def __init__(self, target: str | os.PathLike[str]) -> None:
        self.target = Path(target)
        self.path = lock_path(self.target)
        self._text: str | None = None

    def __enter__(self) -> FolderLock:
        self.acquire()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.release()

    def acquire(self) -> None:
        """Create the lock file, taking over a stale one."""
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(
                f"output folder '{self.target}': cannot create '{self.path.parent}': "
                f"{exc.strerror or exc}"
            ) from exc
        text = _holder_text()
        for _ in range(3):
            try:
                fd = os.open(self.path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                held = self._read()
                if held is not None and _is_stale(self.path, held):
                    self._remove_stale(held)
                    continue
                raise self._refusal(held) from None
            except OSError as exc:
                raise OutputError(
                    f"output folder '{self.target}': cannot create the lock file "
                    f"'{self.path}': {exc.strerror or exc}"
                ) from exc
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(text)
            self._text = text
            return
        raise self._refusal(self._read())

    def release(self) -> None:
        """Delete the lock file if it is still this run's."""
        if self._text is None:
            return
        if self._read() == self._text:
            self.path.unlink(missing_ok=True)
        self._text = None

    def _read(self) -> str | None:
        try:
            return self.path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return None
        except (OSError, UnicodeDecodeError):
            return ""

    def _remove_stale(self, held: str) -> None:
        """Move the stale lock aside and delete it; put it back if another run
        took it over in between (its text is then not the stale one)."""
        aside = self.path.with_name(f"{self.path.name}.stale-{uuid.uuid4().hex[:8]}")
        try:
            os.replace(self.path, aside)
        except FileNotFoundError:
            return
        try:
            moved = aside.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError):
            moved = ""
        if moved != held:
            try:
                os.link(aside, self.path)
            except OSError:
                pass
        aside.unlink(missing_ok=True)

    def _refusal(self, held: str | None) -> OutputError:
        parts = (held or "").split()
        who = (
            f"process {parts[0]} on {parts[1]}, since {parts[2]}"
            if len(parts) >= 3
            else "a process that is starting"
        )
        return OutputError(
            f"output folder '{self.target}' is being written by another stripaero run "
            f"({who}); wait for it to finish, or delete '{self.path}' if no run is going"
        )
