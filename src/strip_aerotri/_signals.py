"""Ctrl-C held back over steps it must not cut, and delivered after them.

Used where an interrupt would leave something half done (the swap of a
result folder, :mod:`strip_aerotri.report.files`) or would be lost:
threadpoolctl finds the loaded BLAS libraries through a ctypes callback
(``dl_iterate_phdr``), and a KeyboardInterrupt raised inside a ctypes
callback is printed ("Exception ignored on calling ctypes callback
function") and dropped, so a Ctrl-C landing there let the run go on to the
end (:func:`strip_aerotri._threads.blas_threads`).
"""

from __future__ import annotations

import signal
import threading

__all__ = ["sigint_held"]


class sigint_held:
    """Hold SIGINT back inside the block and deliver it at its end (to the
    handler it had: Python's raises KeyboardInterrupt there).

    Outside the main thread (where signals cannot be handled) it does nothing.
    """

    def __enter__(self) -> None:
        self._received = False
        self._previous: object = None
        if threading.current_thread() is not threading.main_thread():
            return

        def hold(signum: int, frame: object) -> None:
            self._received = True

        self._previous = signal.signal(signal.SIGINT, hold)

    def __exit__(self, *exc: object) -> None:
        if self._previous is None:
            return
        signal.signal(signal.SIGINT, self._previous)  # type: ignore[arg-type]
        if self._received and exc[0] is None:
            if callable(self._previous):
                self._previous(signal.SIGINT, None)
            elif self._previous == signal.SIG_DFL:
                raise KeyboardInterrupt
