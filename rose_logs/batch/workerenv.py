"""Process settings for batch workers: glibc malloc thresholds and single-threaded BLAS.

Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``. Setting any malloc threshold turns
off glibc's dynamic mmap threshold, so every array above 128 KiB is mmapped and page-faulted afresh on
each allocation: ROSE's large temporary arrays then cost about twice the CPU (``bench_batch.py
--malloc``, 40 recordings: 11.3 s of task CPU with Dask's setting, 5.9 s with glibc's defaults, 4.4 s
with ours). We set both thresholds to values that keep arrays of a few MB on the heap
and still give memory back to the system beyond 64 MiB of free heap top. Workers share the cores, so
BLAS / OpenMP pools get one thread each.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os

__all__ = ["MALLOC_ENV", "THREAD_ENV", "tune_worker_process", "worker_environment"]

_LOG = logging.getLogger(__name__)

#: glibc malloc settings (environment form, read when a process starts).
MALLOC_ENV = {
    "MALLOC_TRIM_THRESHOLD_": str(64 * 2**20),
    "MALLOC_MMAP_THRESHOLD_": str(32 * 2**20),  # glibc's largest allowed value on 64-bit
}
#: One thread per worker for BLAS and OpenMP pools.
THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_tuned = False


def worker_environment() -> dict[str, str]:
    """Environment for local worker processes (Dask's ``distributed.nanny.pre-spawn-environ``)."""
    return {**MALLOC_ENV, **THREAD_ENV}


def tune_worker_process() -> None:
    """Apply the malloc thresholds and the one-thread pools to the running process (idempotent).

    For workers we did not start (an existing cluster): ``mallopt`` replaces the nanny's environment
    setting, ``threadpoolctl`` (when installed) limits pools that are already loaded.
    """
    global _tuned
    if _tuned:
        return
    _tuned = True
    for name, value in THREAD_ENV.items():
        os.environ.setdefault(name, value)
    library = ctypes.util.find_library("c")
    try:
        libc = ctypes.CDLL(library) if library else None
        mallopt = getattr(libc, "mallopt", None)
    except OSError:
        mallopt = None
    if mallopt is not None:  # glibc only
        mallopt(_M_MMAP_THRESHOLD, int(MALLOC_ENV["MALLOC_MMAP_THRESHOLD_"]))
        mallopt(_M_TRIM_THRESHOLD, int(MALLOC_ENV["MALLOC_TRIM_THRESHOLD_"]))
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return
    threadpool_limits(1)
