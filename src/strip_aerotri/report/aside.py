"""Work of the report done in a second process while this one goes on.

The report's figures cost more than everything else a run writes (matplotlib
is imported, then every figure placed, drawn and encoded).  They depend only
on the result, which a forked process already holds (the memory is shared
copy-on-write, nothing is pickled on the way in), so :func:`aside` forks,
draws them there on the machine's second core and sends the PNGs back
through a pipe, while this process writes report.json and the tables
(docs/scaling.md).

:class:`Standby` goes one step further for ``stripaero run``: it forks
before the adjustment, so that the child imports matplotlib on the second
core while the run adjusts, and then draws from the figures' inputs, sent
to it pickled (:class:`.figures.StripFigureData`: plain arrays, a few MB;
never the result).

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
* the child's garbage collector leaves what it inherited alone
  (``gc.freeze``): the figures of a 1000-photo strip drawn by a child of
  the run took 0.42 s CPU with it walking the run's heap, 0.31 s without;
* where forking is not safe or not possible (anywhere but Linux: Windows has
  no fork, and macOS's system libraries are not safe in a forked child;
  other threads running in this process; ``STRIPAERO_FORK=0``), the
  function is called here, when its value is asked for.
"""

from __future__ import annotations

import contextlib
import gc
import os
import pickle
import signal
import sys
import threading
from collections.abc import Callable
from functools import partial
from typing import Generic, TypeVar

__all__ = ["FORK_ENV", "Aside", "Standby", "aside", "fork_allowed"]

FORK_ENV = "STRIPAERO_FORK"
"""Environment variable: ``0`` draws the report's figures in the run's own process."""

_T = TypeVar("_T")

#: The child's first byte: the value follows (pickled), or the function raised.
_VALUE, _FAILED = b"V", b"E"


def fork_allowed() -> bool:
    """Whether :func:`aside` forks: on Linux (macOS's system libraries,
    Accelerate's BLAS among them, are not safe to use in a forked child;
    Windows has no fork), when this is the only thread (a fork copies locks
    other threads may hold) and ``STRIPAERO_FORK`` is not ``0``."""
    return (
        sys.platform.startswith("linux")
        and hasattr(os, "fork")
        and os.environ.get(FORK_ENV, "1").strip() != "0"
        and threading.active_count() == 1
    )


def _fork(child: Callable[[], object], parent: Callable[[int], object]) -> None:
    """``os.fork()``: the child runs ``child`` (which ends by ``os._exit``),
    this process ``parent(pid)``, which must keep the pid.

    SIGINT is blocked across the fork: Python runs its at-fork hooks around
    the call, and a Ctrl-C landing inside one is lost ("Exception ignored"),
    so the run would go on.  Blocked, it is delivered to this process once
    ``parent`` has kept the pid, as a KeyboardInterrupt at the next line;
    the child takes SIGINT's default action (it ends at once) before it
    unblocks it.
    """
    for stream in (sys.stdout, sys.stderr):  # nothing buffered is written twice
        stream.flush()
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        pid = os.fork()
        if pid == 0:
            try:
                # what the child inherits is never garbage it must collect:
                # left out of its collections, which would walk the run's
                # whole heap (and copy its pages) while the figures are drawn
                gc.freeze()
                signal.signal(signal.SIGINT, signal.SIG_DFL)
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)
                child()
            finally:
                os._exit(1)  # never back into the parent's code
        parent(pid)
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


class Aside(Generic[_T]):
    """The pending value of a function called in a forked child (:func:`aside`).

    Use as a context manager: the child is forked when the block is entered,
    and killed and reaped however the block is left; :meth:`result` waits
    for the value (without a child, it calls the function here).
    """

    def __init__(
        self, function: Callable[[], _T], *, child: tuple[int, int] | None = None
    ) -> None:
        self._function = function
        self._pid: int | None = None
        self._read: int | None = None
        self._done = False
        self._value: _T | None = None
        if child is not None:  # a child already working on it (:class:`Standby`)
            self._pid, self._read = child

    def _start(self) -> None:
        read, write = os.pipe()

        def work() -> None:
            os.close(read)
            _child(self._function, write)

        def kept(pid: int) -> None:
            self._pid, self._read = pid, read
            os.close(write)

        try:
            _fork(work, kept)
        except OSError:  # no fork (no memory, too many processes): drawn here
            for fd in (read, write):
                with contextlib.suppress(OSError):
                    os.close(fd)
            self._pid = self._read = None

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
                    value, received = pickle.loads(memoryview(data)[1:]), True
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
            with contextlib.suppress(ProcessLookupError):
                os.kill(self._pid, signal.SIGKILL)
            self._reap()
        if self._read is not None:
            os.close(self._read)
            self._read = None

    def __enter__(self) -> Aside[_T]:
        if self._pid is None and not self._done and fork_allowed():
            try:
                self._start()
            except BaseException:  # Ctrl-C just after the fork: no child left behind
                self.cancel()
                raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.cancel()


class Standby:
    """A process forked before the run adjusts, that loads what a later job
    needs (``prepare``: importing matplotlib, 0.2-0.3 s) on the second core
    meanwhile, then does the one job :meth:`submit` sends it.

    With ``first``, the child calls it before it prepares and sends its
    value at once (:meth:`first_result`), then calls ``prepare`` with that
    value: ``stripaero run`` forks its one child at its start, when its
    process is small, and has the child load the project while it imports
    (the pages a child shares with this process are copied at this
    process's first write to each, for as long as the child lives: a child
    forked after the loading cost the adjustment 8 000-10 000 page faults).

    Use as a context manager: the child is forked when the block is entered,
    and killed and reaped however the block is left (a failed run, Ctrl-C),
    also when no job was sent.  Without a child (:func:`fork_allowed`
    false), :meth:`first_result` calls ``first`` here and :meth:`submit` is
    :func:`aside`.
    """

    def __init__(
        self, prepare: Callable[..., object], *, first: Callable[[], object] | None = None
    ) -> None:
        self._prepare = prepare
        self._first = first
        self._first_value: tuple[object] | None = None  # (value,) once known
        self._pid: int | None = None
        self._jobs: int | None = None  # write end: the job, then EOF
        self._replies: int | None = None  # read end: first's value, then the job's

    def _start(self) -> None:
        job_read, job_write = os.pipe()
        reply_read, reply_write = os.pipe()

        def work() -> None:
            os.close(job_write)
            os.close(reply_read)
            _standby_child(self._prepare, self._first, job_read, reply_write)

        def kept(pid: int) -> None:
            self._pid, self._jobs, self._replies = pid, job_write, reply_read
            os.close(job_read)
            os.close(reply_write)

        try:
            _fork(work, kept)
        except OSError:  # no fork: the job is done by aside() when submitted
            for fd in (job_read, job_write, reply_read, reply_write):
                with contextlib.suppress(OSError):
                    os.close(fd)
            self._pid = self._jobs = self._replies = None

    def first_result(self) -> object:
        """The value of ``first`` (given to the constructor): the child's, sent
        before it prepares, or ``first()`` called here when there is no
        child or the child failed (its error is raised here)."""
        if self._first is None:
            raise ValueError("this Standby was made without a first function")
        if self._first_value is None:
            value: tuple[object] | None = None
            if self._replies is not None:
                try:
                    if _read_exact(self._replies, 1) == _VALUE:
                        size = int.from_bytes(_read_exact(self._replies, 8), "little")
                        value = (pickle.loads(_read_exact(self._replies, size)),)
                except Exception:  # the child died before or while answering
                    value = None
            self._first_value = value if value is not None else (self._first(),)
        return self._first_value[0]

    def submit(self, function: Callable[..., _T], *args: object) -> Aside[_T]:
        """``function(*args)`` in the waiting child (both pickled: a function
        of a module and plain data); its value by ``.result()``, in a block
        of the returned :class:`Aside`."""
        call = partial(function, *args)
        if self._pid is None or self._jobs is None or self._replies is None:
            return aside(call)
        child = (self._pid, self._replies)
        jobs, self._jobs = self._jobs, None
        self._pid = self._replies = None  # the Aside owns the child now
        try:
            with os.fdopen(jobs, "wb") as pipe:
                pipe.write(pickle.dumps((function, args), protocol=pickle.HIGHEST_PROTOCOL))
        except (OSError, pickle.PicklingError, TypeError, AttributeError):
            pass  # the child gone, or a job that does not pickle: called here
        return Aside(call, child=child)

    def close(self) -> None:
        """Kill the child if no job was sent, reap it and close the pipes."""
        for fd in (self._jobs, self._replies):
            if fd is not None:
                os.close(fd)
        self._jobs = self._replies = None
        if self._pid is not None:
            pid, self._pid = self._pid, None
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)

    def __enter__(self) -> Standby:
        if self._pid is None and fork_allowed():
            try:
                self._start()
            except BaseException:  # Ctrl-C just after the fork: no child left behind
                self.close()
                raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def aside(function: Callable[[], _T]) -> Aside[_T]:
    """Start ``function()`` in a forked child; its value later by ``.result()``.

    The function's value must pickle; the function must not write files or
    print (its output would be the child's).  See the module's docstring.
    """
    return Aside(function)


def _standby_child(
    prepare: Callable[..., object], first: Callable[[], object] | None, jobs: int, write: int
) -> None:
    """The standby child: ``first`` and its value sent (when given), prepare
    (with that value), wait for the job (until EOF), do it, exit."""
    if first is None:
        with contextlib.suppress(Exception):
            prepare()  # a failure shows when the job runs (here or in the parent)
    else:
        try:
            value = first()
            data = pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL)
        except BaseException:  # the parent calls first() again and reports it
            _write_all(write, _FAILED)
        else:
            _write_all(write, _VALUE + len(data).to_bytes(8, "little"))
            _write_all(write, data)
            del data
            with contextlib.suppress(Exception):
                prepare(value)
            del value
    try:
        with os.fdopen(jobs, "rb") as pipe:
            data = pipe.read()
        function, args = pickle.loads(data)
    except BaseException:  # no job (the parent closed the pipe) or a broken one
        os.close(write)
        os._exit(0)
    _child(partial(function, *args), write)


def _child(function: Callable[[], object], write: int) -> None:
    """Run ``function`` in the forked child and send its value; exit."""
    code = 0
    try:
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


def _read_exact(fd: int, size: int) -> bytes:
    """``size`` bytes from ``fd``; EOFError if it ends before."""
    parts, left = [], size
    while left:
        part = os.read(fd, min(left, 1 << 20))
        if not part:
            raise EOFError(f"{left} of {size} bytes missing")
        parts.append(part)
        left -= len(part)
    return b"".join(parts)


def _write_all(fd: int, data: bytes) -> None:
    """Write all of ``data`` to ``fd``."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]
