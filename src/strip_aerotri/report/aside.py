"""Work of the report done in a second process while this one goes on.

The report's figures cost more than everything else a run writes (matplotlib
is imported, then every figure laid out and drawn twice).  They depend only
on the result, which a forked process already holds (the memory is shared
copy-on-write, nothing is pickled on the way in), so :func:`aside` forks,
draws them there on the machine's second core and sends the PNGs back
through a pipe, while this process writes report.json and the tables
(docs/scaling.md).

What it guarantees:

* the same value as calling the function here: the child runs the same
  code on the same data, and any error in it is raised here by calling the
  function here again (so it is reported as it would have been, with the
  run's own one-line message or, with ``--debug``, its traceback);
* Ctrl-C stops both processes at once: the child takes SIGINT's default
  action (it ends silently), and this process kills and reaps it on any
  exception while waiting, KeyboardInterrupt included;
* nothing on disk: the child only writes to the pipe, and leaves by
  ``os._exit`` (no atexit handlers, no flushing of the parent's buffers);
* where forking is not safe or not possible (no ``os.fork``: Windows; other
  threads running in this process; ``STRIPAERO_FORK=0``), the function is
  called here, when its value is asked for.
"""

from __future__ import annotations

import os
import pickle
import signal
import threading
from collections.abc import Callable
from typing import Generic, TypeVar

__all__ = ["FORK_ENV", "Aside", "aside", "fork_allowed"]

FORK_ENV = "STRIPAERO_FORK"
"""Environment variable: ``0`` draws the report's figures in the run's own process."""

_T = TypeVar("_T")

#: The child's first byte: the value follows (pickled), or the function raised.
_VALUE, _FAILED = b"V", b"E"


def fork_allowed() -> bool:
    """Whether :func:`aside` forks: ``os.fork`` exists, this is the only
    thread (a fork copies locks other threads may hold) and
    ``STRIPAERO_FORK`` is not ``0``."""
    return (
        hasattr(os, "fork")
        and os.environ.get(FORK_ENV, "1").strip() != "0"
        and threading.active_count() == 1
    )


class Aside(Generic[_T]):
    """The pending value of a function called in a forked child (:func:`aside`).

    Use as a context manager, so that the child is killed and reaped however
    the block is left; :meth:`result` waits for the value.
    """

    def __init__(self, function: Callable[[], _T]) -> None:
        self._function = function
        self._pid: int | None = None
        self._read: int | None = None
        self._done = False
        self._value: _T | None = None
        if fork_allowed():
            self._start()

    def _start(self) -> None:
        import sys

        for stream in (sys.stdout, sys.stderr):  # nothing buffered is written twice
            stream.flush()
        read, write = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: never returns
            os.close(read)
            _child(self._function, write)
        os.close(write)
        self._pid, self._read = pid, read

    def result(self) -> _T:
        """The function's value: the child's, or the function called here when
        there is no child or the child failed (its error is raised here)."""
        if self._done:
            return self._value  # type: ignore[return-value]  # set with _done
        value: _T | None = None
        received = False
        if self._read is not None:
            with os.fdopen(self._read, "rb") as pipe:
                self._read = None
                data = pipe.read()  # until the child closes its end
            self._reap()
            if data[:1] == _VALUE:
                try:
                    value, received = pickle.loads(data[1:]), True
                except Exception:  # a truncated message: the child died writing
                    received = False
        if not received:
            value = self._function()  # no child, or it failed: here, as without one
        self._done, self._value = True, value
        return value  # type: ignore[return-value]  # the function's own value

    def _reap(self) -> None:
        if self._pid is not None:
            pid, self._pid = self._pid, None
            os.waitpid(pid, 0)

    def cancel(self) -> None:
        """Kill the child if it still runs, reap it and close the pipe."""
        if self._pid is not None:
            try:
                os.kill(self._pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            self._reap()
        if self._read is not None:
            os.close(self._read)
            self._read = None

    def __enter__(self) -> Aside[_T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.cancel()


def aside(function: Callable[[], _T]) -> Aside[_T]:
    """Start ``function()`` in a forked child; its value later by ``.result()``.

    The function's value must pickle; the function must not write files or
    print (its output would be the child's).  See the module's docstring.
    """
    return Aside(function)


def _child(function: Callable[[], object], write: int) -> None:
    """Run ``function`` in the forked child and send its value; exit."""
    code = 0
    try:
        signal.signal(signal.SIGINT, signal.SIG_DFL)  # Ctrl-C ends the child at once
        try:
            message = _VALUE + pickle.dumps(function(), protocol=pickle.HIGHEST_PROTOCOL)
        except BaseException:  # the parent calls the function again and reports it
            message, code = _FAILED, 1
        with os.fdopen(write, "wb") as pipe:
            pipe.write(message)
    except BaseException:  # the parent is gone (broken pipe): nothing to tell
        code = 1
    finally:
        os._exit(code)
