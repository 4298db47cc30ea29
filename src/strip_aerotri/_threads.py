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

Worker threads: inside :func:`compute_workers` (the bundle adjustment and
refinement open it), the engine's kernels split work that falls into
independent pieces (blocks of rows, groups of points) over two threads
with :func:`split_map`: the calling thread and one worker, each taking the
next piece as it finishes the last, so that a thread the system holds back
takes fewer pieces and never holds the other up for more than one piece.
numpy releases the interpreter in its loops and BLAS in its products, so the
pieces run at once.  Each piece's result is computed whole by one thread
and the caller combines them in their order: the results are bit for bit
those of one thread.  Workers: ``min(2, os.cpu_count(), CPUs this process
may run on)``; one when the problem is small (the threads' hand-over, about
0.1 ms a call, would not pay), when the machine's other work already
takes the other core (:func:`machine_busy`: a second thread then only
splits this process's share, and waits for the other), or when
``STRIPAERO_WORKERS`` says so (a positive integer N: N threads at most two
and the CPUs, whatever the load; ``1`` one thread).  The worker lives only as
long as the block, so no thread outlives an adjustment (a run forks its
report process only when it is the only thread).

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
import itertools
import os
import threading
from collections.abc import Callable, Iterator, Sequence
from typing import Literal, ParamSpec, TypeVar

from ._signals import sigint_held
from .errors import ConfigError

__all__ = [
    "BLAS_THREADS_VARIABLE",
    "WORKERS_VARIABLE",
    "blas_thread_limit",
    "blas_threads",
    "compute_workers",
    "interruptible",
    "limit_blas_threads",
    "split_map",
    "worker_count",
]

BLAS_THREADS_VARIABLE = "STRIPAERO_BLAS_THREADS"
"""Environment variable: BLAS threads during the adjustments (default 1; ``auto``: no limit)."""

WORKERS_VARIABLE = "STRIPAERO_WORKERS"
"""Environment variable: most threads of the engine's kernels (default 2, ``1``: one)."""

#: Fewest image observations (or rows) for which a second thread pays.
MIN_PARALLEL_SIZE = 20_000

_P = ParamSpec("_P")
_R = TypeVar("_R")
_T = TypeVar("_T")


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

    with contextlib.ExitStack() as stack:
        # threadpoolctl finds the libraries through a ctypes callback, where a
        # KeyboardInterrupt is dropped: a Ctrl-C there is delivered after it
        # (and the limits, set by then, are restored on the way out)
        with sigint_held():
            stack.enter_context(threadpool_limits(limits=n, user_api="blas"))
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


def _usable_cores() -> int:
    """CPUs this process may run on (its affinity), at most ``os.cpu_count()``."""
    count = os.cpu_count() or 1
    affinity = getattr(os, "sched_getaffinity", None)
    if affinity is not None:
        with contextlib.suppress(OSError):
            count = min(count, len(affinity(0)))
    return max(count, 1)


def _busy_cores() -> float:
    """The machine's one-minute load average (0 where the system has none)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return 0.0


def _others_running() -> int | None:
    """Threads of the whole machine runnable at this moment besides the
    caller (``/proc/loadavg``'s fourth field, less one); None where the
    system does not say."""
    try:
        with open("/proc/loadavg", encoding="ascii") as f:
            running = int(f.read().split()[3].split("/")[0])
    except (OSError, ValueError, IndexError):
        return None
    return max(running - 1, 0)


def machine_busy(cores: int) -> bool:
    """True when the other cores are taken: the one-minute load average above
    ``cores - 1.25`` and, where the system says, another thread runnable at
    this moment (one CPU-bound process beside this one is enough).  The
    moment's count keeps the load of this process's own earlier work (a
    benchmark's loop) from counting as the others', and the load average a
    short process that happens to run at the moment."""
    if _busy_cores() <= cores - 1.25:
        return False
    others = _others_running()
    return others is None or others >= cores - 1


def worker_count(size: int) -> int:
    """Threads for the kernels of a problem of `size` image observations:
    ``min(2, os.cpu_count(), CPUs of this process)``; 1 below
    :data:`MIN_PARALLEL_SIZE`, or when the machine's other work takes the
    other core (:func:`machine_busy`); ``STRIPAERO_WORKERS`` sets the number
    instead (at most two and the CPUs of this process, whatever the load).

    Raises
    ------
    ConfigError
        When ``STRIPAERO_WORKERS`` is not a positive integer.
    """
    text = os.environ.get(WORKERS_VARIABLE, "").strip()
    cores = min(2, _usable_cores())
    if text:
        try:
            wanted = int(text)
        except ValueError:
            wanted = 0
        if wanted < 1:
            raise ConfigError(
                f"environment variable {WORKERS_VARIABLE}={text!r}: expected a positive "
                "number of threads (unset it for the default: two where a second core is free)"
            )
        cores = min(cores, wanted)
    if size < MIN_PARALLEL_SIZE:
        return 1
    if not text and cores > 1 and machine_busy(cores):
        return 1
    return cores


@contextlib.contextmanager
def compute_workers(size: int) -> Iterator[int]:
    """Worker threads for :func:`split_map` inside the block (see the module
    docstring); yields the number of threads.  Nested blocks use the
    outermost's; the worker ends with the block."""
    pool = getattr(_local, "pool", None)
    if pool is not None or getattr(_local, "open", False):
        yield 1 if pool is None else 2
        return
    n = worker_count(size)
    if n < 2:
        _local.open = True
        try:
            yield 1
        finally:
            _local.open = False
        return
    from concurrent.futures import ThreadPoolExecutor

    pool = ThreadPoolExecutor(max_workers=n - 1, thread_name_prefix="strip_aerotri-worker")
    _local.pool = pool
    try:
        yield n
    finally:
        _local.pool = None
        pool.shutdown(wait=True, cancel_futures=True)


def split_map(
    function: Callable[[_T], _R],
    items: Sequence[_T],
    combine: Callable[[_R], None] | None = None,
) -> list[_R]:
    """``[function(x) for x in items]``, the items shared between this thread
    and the worker of :func:`compute_workers` (if one is open here), each
    thread taking the next item when it has done its last.

    With `combine`, ``combine(function(x))`` is called for every item, one
    call at a time and in the items' order (a sum into one array is then
    the same as in one thread), and the list returned is empty: no result is
    held longer than its turn.  `function` must not write where another
    item's call reads or writes.  An exception is raised as from the loop
    (the other thread takes no further item).
    """
    pool = getattr(_local, "pool", None)
    n = len(items)
    if pool is None or n < 2:
        if combine is None:
            return [function(x) for x in items]
        for x in items:
            combine(function(x))
        return []
    results: list[_R | None] = [None] * n
    counter = itertools.count()  # next() is atomic: each item is taken once
    stop = threading.Event()
    turn = threading.Condition()
    done = [0]  # items combined so far

    def drain() -> None:
        try:
            for i in counter:
                if i >= n or stop.is_set():
                    return
                result = function(items[i])
                if combine is None:
                    results[i] = result
                    continue
                with turn:  # the items before this one are combined first
                    while done[0] != i:
                        if stop.is_set():
                            return
                        turn.wait()
                    combine(result)
                    done[0] += 1
                    turn.notify_all()
        except BaseException:
            with turn:
                stop.set()  # the other thread takes no further item
                turn.notify_all()
            raise

    future = pool.submit(drain)
    # A split_map inside an item runs serially here, as it does in the worker
    # (the pool is this thread's): queued behind this one it would never start.
    _local.pool = None
    try:
        drain()
        future.result()
    except BaseException:  # Ctrl-C while waiting for the worker: it stops too
        stop.set()
        raise
    finally:
        _local.pool = pool
    return [] if combine is not None else results  # type: ignore[return-value]


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
