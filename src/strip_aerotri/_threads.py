"""BLAS threads during the adjustments: one by default.

The adjustments do their algebra on many small matrices (3 x 3 to 7 x 7
blocks, one per point, model or photo) and on sparse or banded systems
whose dense pieces are small.  There, a multithreaded BLAS (OpenBLAS starts
one thread per core) spends more time waking and synchronising its threads
than it saves, and loses badly when other processes share the cores: a
1000-photo strip took 7.8-15 s with OpenBLAS's default threads on two cores
and 3.0 s with one thread (its point cofactors 7.2 s against 0.18 s).  So
every library entry point that adjusts (:func:`strip_aerotri.triangulate`,
``triangulate_block``, :func:`strip_aerotri.run_project`, ``form_strip_of``,
the bundle adjustment and refinement, J's ground stage) runs under
:func:`blas_threads`, which limits the BLAS libraries numpy and scipy load
(through threadpoolctl) to one thread and restores the caller's setting on
return.  A run is then never slower with two cores than with one; many
projects at once run as many processes (docs/scaling.md).

The environment variable ``STRIPAERO_BLAS_THREADS`` changes the limit: a
positive integer N lets BLAS use N threads during the adjustments, and
``auto`` leaves BLAS its own setting (``OPENBLAS_NUM_THREADS`` and the
like, or one thread per core).

Ctrl-C: Python runs its SIGINT handler (KeyboardInterrupt) in the main
thread between two of its own steps, so one long LAPACK call (the banded
Cholesky of a wide block takes seconds) delays it to the call's end.
:func:`interruptible` runs such a call in a worker thread (LAPACK releases
the interpreter) while the main thread waits in a way a signal interrupts:
Ctrl-C then acts at once, and the abandoned call ends with the process: if
it still runs when the interpreter exits, the process ends at once (exit
code 130 after Ctrl-C) without the libraries' teardown, which would free
OpenBLAS's buffers under the running call.
"""

from __future__ import annotations

import contextlib
import functools
import os
import threading
from collections.abc import Callable, Iterator
from typing import Literal, ParamSpec, TypeVar

from .errors import ConfigError

__all__ = [
    "BLAS_THREADS_VARIABLE",
    "blas_thread_limit",
    "blas_threads",
    "interruptible",
    "limit_blas_threads",
]

BLAS_THREADS_VARIABLE = "STRIPAERO_BLAS_THREADS"
"""Environment variable: BLAS threads during the adjustments (default 1; ``auto``: no limit)."""

_P = ParamSpec("_P")
_R = TypeVar("_R")


def blas_thread_limit() -> int | None:
    """The number of BLAS threads of the adjustments: 1 unless
    ``STRIPAERO_BLAS_THREADS`` says otherwise; None for ``auto`` (no limit).

    Raises
    ------
    ConfigError
        When the variable is neither a positive integer nor ``auto``.
    """
    text = os.environ.get(BLAS_THREADS_VARIABLE, "").strip()
    if not text:
        return 1
    if text.lower() == "auto":
        return None
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise ConfigError(
            f"environment variable {BLAS_THREADS_VARIABLE}={text!r}: expected a positive "
            "number of BLAS threads or 'auto' (unset it for the default, one thread)"
        )
    return value


@contextlib.contextmanager
def blas_threads(limit: int | None | Literal["env"] = "env") -> Iterator[None]:
    """Limit the BLAS threads of numpy's and scipy's libraries inside the block.

    Parameters
    ----------
    limit : int, None or "env"
        Threads allowed; None leaves BLAS as it is; "env" (the default) reads
        :func:`blas_thread_limit`.  The previous limits are restored on exit.
    """
    n = blas_thread_limit() if limit == "env" else limit
    if n is None:
        yield
        return
    entered = _entered_limits()
    if entered and entered[-1] == n:
        # an enclosing block of this thread set this very limit (the entry
        # points call each other: a run enters eight): nothing to set or
        # restore, and threadpoolctl's look at every loaded library and
        # OpenBLAS's resetting of its threads are saved
        yield
        return
    # scipy brings its own BLAS, loaded by scipy.linalg: load it first, or the
    # limit would miss it (threadpoolctl limits the libraries loaded so far).
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=n, user_api="blas"):
        entered.append(n)
        try:
            yield
        finally:
            entered.pop()


_local = threading.local()


def _entered_limits() -> list[int]:
    """The limits of the :func:`blas_threads` blocks this thread is in, innermost last."""
    limits: list[int] | None = getattr(_local, "limits", None)
    if limits is None:
        limits = _local.limits = []
    return limits


def limit_blas_threads(function: Callable[_P, _R]) -> Callable[_P, _R]:
    """Decorator: run ``function`` under :func:`blas_threads` (the default limit)."""

    @functools.wraps(function)
    def limited(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        with blas_threads():
            return function(*args, **kwargs)

    return limited


def interruptible(function: Callable[_P, _R], *args: _P.args, **kwargs: _P.kwargs) -> _R:
    """``function(*args, **kwargs)``, with Ctrl-C acting at once in the main thread.

    For long calls into compiled code that release the interpreter lock
    (LAPACK through scipy.linalg: the banded Cholesky of a wide block): the
    call runs in a daemon worker thread and the main thread waits for it in
    a join that KeyboardInterrupt breaks.  The result or the exception of the
    call is returned or raised as if it had been called directly.  Outside
    the main thread (where no signal arrives) the call is made directly.  On
    Ctrl-C the abandoned call keeps its core until it returns or the process
    ends.  Costs about 0.2 ms (a thread started and joined): for calls of
    more than a few milliseconds.
    """
    if threading.current_thread() is not threading.main_thread():
        return function(*args, **kwargs)
    results: list[_R] = []
    errors: list[BaseException] = []
    finished = threading.Event()  # set when the call returns (is_alive is not
    # reliable while the interpreter shuts down)

    def work() -> None:
        try:
            results.append(function(*args, **kwargs))
        except BaseException as exc:  # handed to the caller's thread
            errors.append(exc)
        finally:
            finished.set()

    worker = threading.Thread(target=work, name="strip_aerotri-compute", daemon=True)
    try:
        worker.start()  # Ctrl-C may land while start() waits for the thread
        while worker.is_alive():
            worker.join(0.1)  # a signal interrupts the wait
    except BaseException as exc:  # Ctrl-C: the call is abandoned, still running
        _exit_without_teardown(finished, exc)
        raise
    if errors:
        raise errors[0]
    return results[0]


def _exit_without_teardown(finished: threading.Event, exc: BaseException) -> None:
    """If the abandoned call has not ``finished`` when the interpreter exits,
    end the process at once with the exit code of ``exc`` (130 for Ctrl-C):
    the libraries' own teardown at exit (OpenBLAS frees its buffers) would
    pull the memory from under the running call and crash the process
    (SIGSEGV, seen in 2 of 12 interrupted runs before this)."""
    import atexit
    import sys

    if isinstance(exc, SystemExit):
        code = exc.code if isinstance(exc.code, int) else 1
    else:
        code = 130 if isinstance(exc, KeyboardInterrupt) else 1

    def exit_now() -> None:
        if not finished.is_set():
            for stream in (sys.stdout, sys.stderr):
                with contextlib.suppress(Exception):
                    stream.flush()
            os._exit(code)

    atexit.register(exit_now)  # the last registered runs first
