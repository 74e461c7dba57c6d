"""glibc's allocator, set for numpy's large, short-lived arrays.

By default glibc serves blocks above an adaptive threshold (128 KiB at start) with
``mmap`` and gives the top of the heap back to the system whenever more than twice that
is free. A prediction allocates and frees arrays of a few megabytes all the time (a
grid's cells, a signal's edges), so each fresh array is mapped anew and page-faulted in:
measured on a two-hour sweep scenario, 0.31 s with the defaults against 0.10 s with the
thresholds set here. A Dask nanny's ``MALLOC_TRIM_THRESHOLD_=65536`` is worse still (it
also freezes the adaptive threshold at 128 KiB). :func:`use_large_malloc_thresholds` sets
what the adaptive mode tends to on 64-bit, arrays below 32 MiB from the heap and up to
64 MiB of free heap kept; the command line and the sweep workers call it, a library user
may. Elsewhere than glibc it does nothing.
"""
from __future__ import annotations

import ctypes

M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD_BYTES = 32 * 1024 * 1024
TRIM_THRESHOLD_BYTES = 64 * 1024 * 1024

_done = False


def use_large_malloc_thresholds() -> bool:
    """Set glibc's mmap and trim thresholds (module docstring), once per process.
    True when they were set."""
    global _done
    if _done:
        return True
    try:
        libc = ctypes.CDLL("libc.so.6")
        ok = libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1 and \
            libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES) == 1
    except (OSError, AttributeError):
        return False                              # not glibc
    _done = ok
    return ok
