"""glibc malloc thresholds for processes that allocate map-sized arrays over and over.

glibc serves large allocations with fresh ``mmap`` pages, faulted in on first touch and unmapped on
free. ROSE allocates several map-sized temporaries per snapshot (1-8 MB each for a 1000 x 1000 map),
so with glibc's default (dynamic) threshold much of a run's time goes to page faults. Keeping arrays
up to 32 MiB on the heap, and up to 64 MiB of free heap before giving memory back:

- ``rose-bag batch --workers 1`` on the 40 recordings of ``benchmarks/bench_batch.py``: 19.0 s ->
  16.1 s, system time 5.0 s -> 1.4 s, peak memory 262 MB -> 316 MB;
- task CPU of that fleet (``bench_batch.py --malloc``): 27.9 s with glibc's defaults, 23.3 s with
  these, 51.2 s with Dask's ``MALLOC_TRIM_THRESHOLD_=65536`` (any fixed threshold turns the dynamic
  one off, leaving 128 KiB: every array mmapped).

A smaller trim threshold (8 MiB) gives the memory back and the page faults with it. A small mmap
threshold (2 MiB) instead: a 4 MB array then cost 2.1 ms to allocate and fill against 45 us on the
heap (numpy asks for transparent huge pages, which the kernel zeroes and compacts every time), for a
session peak within the noise of this one's.

Each thread that allocates gets its own arena, and each arena keeps up to the trim threshold of
free heap besides the holes between live arrays: the session's threads (reading, two analyses, the
cleaning's second thread, the break detector, Rerun's logging) share one arena. The one-hour
benchmark session (``benchmarks/bench_session.py --rrd``) peaked at 381 MB with two arenas instead
of 408-412 MB with glibc's default (8 per core), and 10-15 MB lower again with one, in the same
time (its arrays are few and large: the threads seldom wait for the arena's lock).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
from typing import Any

__all__ = ["MALLOC_ENV", "keep_arrays_on_heap", "release_free_heap"]

#: The thresholds in environment form (read by glibc when a process starts).
MALLOC_ENV = {
    "MALLOC_TRIM_THRESHOLD_": str(64 * 2**20),
    "MALLOC_MMAP_THRESHOLD_": str(32 * 2**20),  # glibc's largest allowed value on 64-bit
    "MALLOC_ARENA_MAX": "1",
}

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_M_ARENA_MAX = -8


def keep_arrays_on_heap() -> bool:
    """Apply :data:`MALLOC_ENV` to the running process with ``mallopt``; False when not on glibc.

    Process-wide, so only entry points call it (the ``rose-bag`` command, batch workers), never the
    library.
    """
    mallopt = _glibc_function("mallopt")
    if mallopt is None:  # not glibc (musl, macOS): nothing to tune
        return False
    mallopt(_M_MMAP_THRESHOLD, int(MALLOC_ENV["MALLOC_MMAP_THRESHOLD_"]))
    mallopt(_M_TRIM_THRESHOLD, int(MALLOC_ENV["MALLOC_TRIM_THRESHOLD_"]))
    mallopt(_M_ARENA_MAX, int(MALLOC_ENV["MALLOC_ARENA_MAX"]))  # threads made after this
    return True


def release_free_heap() -> bool:
    """Give the free pages of every malloc arena back to the system (``malloc_trim``); False when
    not on glibc.

    For the end of a phase whose arrays are gone while the process goes on: the trim threshold
    above keeps up to 64 MiB of free heap per arena, and free space below the heap's top is kept
    whatever the threshold. Unlike the thresholds, this changes no setting of the process, so
    library code may call it (the Rerun sink does, before writing the recording's footer).
    """
    malloc_trim = _glibc_function("malloc_trim")
    if malloc_trim is None:  # not glibc
        return False
    malloc_trim(0)
    return True


@functools.cache
def _glibc_function(name: str) -> Any:
    """The C library's function ``name``, None when it has none (musl, macOS lack glibc's). Looked
    up once: ``find_library`` runs ``ldconfig -p``."""
    library = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(library) if library else None
    except OSError:
        return None
    return getattr(libc, name, None)
