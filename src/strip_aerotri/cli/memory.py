"""The run's memory allocator: freed memory kept for reuse (glibc's ``mallopt``).

A run allocates and frees arrays of a few to some tens of MB hundreds of
times (the ground stage's rows, the normal equations of each iteration).
glibc's malloc gives such memory back to the system as soon as it is freed
(above 128 kB from the start, then as its dynamic thresholds follow), so the
next array of the same size is fresh memory again: every 4 kB page of it a
page fault, with the page zeroed by the kernel.  On the 1000-photo strip
the ground stage took 39 000-44 000 page faults (0.1-0.25 s of system time
on a virtual machine); with the memory kept (arrays up to 32 MB from the
heap, the heap's top given back only beyond 128 MB) 15 000.

:func:`keep_freed_memory` sets this for the ``stripaero`` process (a CLI
owns its process; the library does not change its caller's allocator).
"""

from __future__ import annotations

import os
import sys

__all__ = ["MMAP_THRESHOLD", "TRIM_THRESHOLD", "keep_freed_memory"]

#: Allocations above this come from their own mapping (given back when freed):
#: glibc's largest, 32 MB on 64-bit systems.
MMAP_THRESHOLD = 32 * 1024 * 1024
#: Free memory at the heap's top beyond this is given back to the system.
TRIM_THRESHOLD = 128 * 1024 * 1024

_M_TRIM_THRESHOLD = -1  # <malloc.h>
_M_MMAP_THRESHOLD = -3
_USER_SETTINGS = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_")


def keep_freed_memory() -> bool:
    """Set glibc's mmap and trim thresholds (:data:`MMAP_THRESHOLD`,
    :data:`TRIM_THRESHOLD`); True when set.

    Nothing on other systems or C libraries, and nothing when the
    environment sets glibc's own variables (``MALLOC_MMAP_THRESHOLD_``,
    ``MALLOC_TRIM_THRESHOLD_``, ``MALLOC_TOP_PAD_``): the user's choice
    stands.  Both thresholds go together: setting either one turns off
    glibc's adjustment of the other (the trim threshold alone kept every
    array above 128 kB in its own mapping: eight times the page faults).
    """
    if not sys.platform.startswith("linux") or any(k in os.environ for k in _USER_SETTINGS):
        return False
    try:
        libc_version = os.confstr("CS_GNU_LIBC_VERSION") or ""
    except (ValueError, OSError):  # not a glibc system
        return False
    if not libc_version.startswith("glibc"):
        return False
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    mallopt.restype = ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(
        mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD)
    )
