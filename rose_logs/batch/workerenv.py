"""Process settings for batch workers: glibc malloc thresholds, one-thread BLAS and OpenCV, a tqdm lock.

Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``, which leaves every array above
128 KiB mmapped and page-faulted afresh on each allocation: ROSE's map-sized temporaries then cost
about twice the CPU. Workers get the thresholds of :mod:`rose_logs.malloc` instead (numbers there).
Workers share the cores, so BLAS / OpenMP pools and OpenCV's own thread pool get one thread each:
OpenCV otherwise runs every morphology and labelling call of the cleaning on all cores, and two
workers on two cores then spent 25 s of task CPU on a fleet that takes 18-20 s with one thread
each (``benchmarks/bench_batch.py``).
The workers' own warnings (an I/O error retried) are ``warning: ...`` lines on stderr, as the
command prints every other one.
"""

from __future__ import annotations

import logging
import os
import sys
import threading

from rose_logs.malloc import MALLOC_ENV, keep_arrays_on_heap

__all__ = ["THREAD_ENV", "tune_worker_process", "warnings_as_lines", "worker_environment"]

_LOG = logging.getLogger(__name__)

#: One thread per worker for BLAS, OpenMP and OpenCV pools.
THREAD_ENV = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OPENCV_FOR_THREADS_NUM": "1",
}

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
    keep_arrays_on_heap()
    _thread_lock_for_tqdm()
    warnings_as_lines()
    # OpenCV reads OPENCV_FOR_THREADS_NUM once, when it is imported: a worker that imported it
    # already (an existing cluster) is told directly.
    import cv2

    cv2.setNumThreads(1)
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return
    threadpool_limits(1)


def _thread_lock_for_tqdm() -> None:
    """Give tqdm a thread lock instead of the multiprocessing one it creates by default.

    ``process_log`` makes a (hidden) tqdm bar, and tqdm's first bar creates a named semaphore that
    the resource tracker counts: a worker stopped by a signal (Ctrl-C of a batch) then makes the
    tracker warn of "leaked semaphore objects" on stderr. Workers run one task thread, so a
    thread lock is all tqdm needs.
    """
    try:
        from tqdm import tqdm
    except ImportError:
        return
    tqdm.set_lock(threading.RLock())


class _StderrLines(logging.Handler):
    """Each record as one ``warning: ...`` line on the ``sys.stderr`` of the moment."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            sys.stderr.write(self.format(record) + "\n")
            sys.stderr.flush()
        except Exception:  # as logging's own handlers: a broken stream never ends the task
            self.handleError(record)


def warnings_as_lines() -> None:
    """``rose`` and ``rose_logs`` warnings of this process as the command prints them
    (``warning: <uri>: ... (attempt 1 of 3, retrying)``), where nothing else would handle them.

    A worker process has no handler for them: Python's last resort printed the bare message.
    A logger with a handler somewhere up its chain (a cluster's own logging) is left as it is.
    """
    from rose.cli import LevelFormatter  # the command's format: one definition

    for name in ("rose", "rose_logs"):
        logger = logging.getLogger(name)
        if logger.hasHandlers():
            continue
        handler = _StderrLines(logging.WARNING)
        handler.setFormatter(LevelFormatter())
        logger.addHandler(handler)
