"""The C heap during a fit in a process told to return memory at once (root helper).

Dask's nanny starts every worker with ``MALLOC_TRIM_THRESHOLD_=65536``. On glibc, fixing
that threshold also freezes the mmap threshold at 128 KiB, so every array above it (a
stage's Jacobian and Hessian products from a few hundred points on) is mapped and unmapped
at each use, and the heap's top goes back to the system after nearly every ``free``: a
page fault per 4 KiB touched. Measured on 64 fits of the batch benchmark in a 1-worker
Dask cluster: 6.8-7.4 s CPU and 550 000-640 000 page faults, against 5.0-5.4 s and about
1 000 with both thresholds raised for the fits, as in a plain process (4.9 s).

:func:`heap_kept` (entered by every :func:`freqid_casadi.fit`) raises them for the
duration of the fit, then restores the values the environment set, so the worker keeps the
memory behaviour its cluster asked for between tasks. The free heap the fit leaves goes
back to the system (``malloc_trim``) when it exceeds what the fit was allowed to keep
(:data:`_KEPT`, 32 MiB), or when glibc cannot say how much it is: a fit of a few hundred
points leaves about 2 MiB, and returning that after every fit cost the next fit 500 page
faults and 4-6 % of its CPU (40 fits of the batch benchmark: 20 000 faults and 2.43-2.52 s
CPU, against 90 and 2.34-2.36 s kept, as in a plain process). It does nothing off glibc, or
when the environment fixes no trim threshold or fixes the mmap threshold itself.
"""

import contextlib
import ctypes
import os
import sys
import threading

__all__ = ["heap_kept"]

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_GLIBC_MMAP_DEFAULT = 128 * 1024     # the mmap threshold glibc keeps once the trim one is set
_KEPT = 32 * 1024 * 1024             # glibc's largest dynamic mmap threshold on 64-bit

_lock = threading.Lock()
_users = 0


def _glibc():
    """The C library when it is glibc (``mallopt`` does what is said above), else None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None)
        libc.gnu_get_libc_version       # absent from musl and other C libraries
    except (OSError, AttributeError):
        return None
    return libc


class _Mallinfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks",
        "fordblks", "keepcost")]


def _free_heap(libc):
    """Bytes of free heap held by this process's arenas (glibc's ``mallinfo2``, all
    arenas), or None where glibc has no ``mallinfo2`` (before 2.33)."""
    try:
        info = libc.mallinfo2
    except AttributeError:
        return None
    info.restype = _Mallinfo2
    return int(info().fordblks)


def _fixed_trim():
    """The trim threshold the environment fixes, in bytes, or None (nothing to undo)."""
    if "MALLOC_MMAP_THRESHOLD_" in os.environ:
        return None                     # the user chose the mmap threshold: leave it
    try:
        return int(os.environ["MALLOC_TRIM_THRESHOLD_"])
    except (KeyError, ValueError):
        return None


@contextlib.contextmanager
def heap_kept():
    """Keep freed C heap in this process while the block runs (see the module's text);
    nested and concurrent blocks (threads of one worker) share one raise and one restore."""
    global _users
    trim = _fixed_trim()
    libc = _glibc() if trim is not None else None
    if libc is None:
        yield
        return
    with _lock:
        if _users == 0:
            libc.mallopt(_M_MMAP_THRESHOLD, _KEPT)
            libc.mallopt(_M_TRIM_THRESHOLD, _KEPT)
        _users += 1
    try:
        yield
    finally:
        with _lock:
            _users -= 1
            if _users == 0:
                libc.mallopt(_M_MMAP_THRESHOLD, _GLIBC_MMAP_DEFAULT)
                libc.mallopt(_M_TRIM_THRESHOLD, trim)
                free = _free_heap(libc)
                if free is None or free > _KEPT:
                    libc.malloc_trim(0)
