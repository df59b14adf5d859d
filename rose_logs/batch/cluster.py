"""Dask clusters for a batch: a local one (worker processes with one thread each, our worker
environment), or the address of an existing one from its scheduler file."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import signal
import stat
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from rose.signals import signals_deferred
from rose_logs.batch.errors import BatchError
from rose_logs.batch.workerenv import worker_environment

__all__ = [
    "MAX_SCHEDULER_FILE_BYTES",
    "SCHEDULER_FILE_WAIT_S",
    "check_scheduler",
    "local_client",
    "max_local_workers",
    "scheduler_address",
]

_LOG = logging.getLogger(__name__)

#: Workers of a local cluster per CPU at most: more only add start-up time and memory (one Python
#: process each), and tens of thousands never finish starting.
WORKERS_PER_CPU = 4

#: Seconds to wait for a scheduler file that does not exist yet (a scheduler started just before).
SCHEDULER_FILE_WAIT_S = 10.0

#: A Dask scheduler file is a few hundred bytes; anything far larger is not one.
MAX_SCHEDULER_FILE_BYTES = 1024 * 1024


def max_local_workers() -> int:
    """Largest ``workers`` of a local cluster: :data:`WORKERS_PER_CPU` per CPU."""
    return WORKERS_PER_CPU * (os.cpu_count() or 1)


def scheduler_address(path: str | Path, *, wait_s: float | None = None) -> str:
    """The address in a Dask scheduler file (a JSON object with an ``"address"`` string).

    A missing file is waited for ``wait_s`` seconds (default :data:`SCHEDULER_FILE_WAIT_S`), since a
    scheduler started just before may not have written it yet; Dask itself would wait forever.

    Raises
    ------
    BatchError
        If the file does not appear, is not a regular file, cannot be read or is no scheduler file.
    """
    name = str(path)
    file_path = Path(name)
    wait_s = SCHEDULER_FILE_WAIT_S if wait_s is None else wait_s
    deadline = time.monotonic() + wait_s
    while True:
        try:
            status = file_path.stat()
            break
        except FileNotFoundError:
            if time.monotonic() >= deadline:
                msg = f"{name}: no such scheduler file (waited {wait_s:g} s for it)"
                raise BatchError(msg) from None
            time.sleep(0.1)
        except OSError as err:
            msg = f"{name}: cannot read the scheduler file ({err.strerror or err})"
            raise BatchError(msg) from err
    # A FIFO would block open(), a device never end: only regular files are read.
    if not stat.S_ISREG(status.st_mode):
        msg = f"{name}: the scheduler file is not a regular file"
        raise BatchError(msg)
    expected = 'not a Dask scheduler file (expected a JSON object with an "address" string)'
    if status.st_size > MAX_SCHEDULER_FILE_BYTES:
        msg = f"{name}: {expected}"
        raise BatchError(msg)
    for attempt in range(5):
        try:
            with file_path.open("rb") as file:
                payload = json.loads(file.read(MAX_SCHEDULER_FILE_BYTES + 1).decode("utf-8"))
        except OSError as err:
            msg = f"{name}: cannot read the scheduler file ({err.strerror or err})"
            raise BatchError(msg) from err
        except ValueError:  # not JSON (UnicodeDecodeError included), or not yet flushed
            payload = None
        address = payload.get("address") if isinstance(payload, dict) else None
        if isinstance(address, str) and address.strip():
            return address.strip()
        if attempt < 4:
            time.sleep(0.1)  # as Dask does: a scheduler may be writing it right now
    msg = f"{name}: {expected}"
    raise BatchError(msg)


def check_scheduler(address: str, *, timeout_s: float) -> None:
    """Connect to the Dask scheduler at ``address`` and back within ``timeout_s`` seconds.

    ``distributed.Client(address, timeout=...)`` waits forever for the handshake of a peer that
    accepts the connection and then says nothing (another service, a stopped process): this bounds
    it (at most 1.5 x ``timeout_s`` in all). Raises ``TimeoutError``, ``OSError`` or ``ValueError``
    (a malformed address).
    """
    from distributed.comm import connect

    async def handshake() -> None:
        comm = await connect(address, timeout=timeout_s)
        await comm.close()

    async def bounded() -> None:
        # Longer than connect's own timeout, so that "nobody listens" keeps Dask's message.
        limit = 1.5 * timeout_s
        try:
            await asyncio.wait_for(handshake(), limit)
        except TimeoutError:
            msg = f"no Dask handshake from {address} within {limit:g} s"
            raise TimeoutError(msg) from None

    # On a thread of its own: asyncio.run refuses to run inside a running event loop (a notebook).
    with ThreadPoolExecutor(1, thread_name_prefix="rose-scheduler-check") as pool:
        pool.submit(asyncio.run, bounded()).result()


@contextlib.contextmanager
def _sigint_blocked() -> Iterator[None]:
    """Block SIGINT in this thread for the block; threads started meanwhile keep it blocked.

    The cluster's event-loop thread starts in here, and the worker processes it spawns inherit its
    signal mask: a Ctrl-C at the terminal (SIGINT to the whole process group) then reaches only this
    process, which stops the workers itself, instead of each worker printing a traceback.
    """
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:  # not POSIX
        yield
        return
    # multiprocessing's resource tracker, when the cluster starts it, unblocks SIGINT in the thread
    # that started it (the event loop's): started here first, it leaves the mask alone later.
    from multiprocessing import resource_tracker

    resource_tracker.ensure_running()
    previous = mask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, previous)


@contextlib.contextmanager
def local_client(
    workers: int, *, memory_limit: str | float | None = None, retries: int = 2
) -> Iterator[Any]:
    """A ``distributed.Client`` on a new ``LocalCluster`` of ``workers`` processes on 127.0.0.1.

    Workers get one thread each, :func:`worker_environment` (malloc thresholds instead of Dask's
    ``MALLOC_TRIM_THRESHOLD_=65536``, one-thread BLAS) through ``distributed.nanny.pre-spawn-environ``,
    no dashboard, one queued recording per worker (``worker-saturation = 1.0``), and
    ``allowed-failures = retries``: a recording whose worker dies more often than
    that is reported as failed instead of being retried forever. Workers do not see a terminal's
    Ctrl-C (this process stops them); a signal during start-up is raised once the cluster is up,
    after which it is closed.
    """
    import dask
    from distributed import Client, LocalCluster

    environ = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}), **worker_environment()}
    settings = {
        "distributed.nanny.pre-spawn-environ": environ,
        "distributed.scheduler.allowed-failures": max(0, retries),
        # One recording per worker at a time (the default 1.1 queues a second one on a 1-thread
        # worker), so a worker killed by one recording's memory takes no bystander with it.
        "distributed.scheduler.worker-saturation": 1.0,
    }
    cluster = None
    try:
        with dask.config.set(settings):
            # A signal inside LocalCluster() would leave it half started (its atexit hook then
            # prints tracebacks): hold signals until it is up, then close it properly.
            with signals_deferred(), _sigint_blocked():
                cluster = LocalCluster(
                    n_workers=workers,
                    threads_per_worker=1,
                    processes=True,
                    memory_limit="auto" if memory_limit is None else memory_limit,
                    host="127.0.0.1",
                    dashboard_address=None,
                    # The scheduler serves its HTTP routes (health, metrics) even without the
                    # dashboard, on port 8787 by default: taken by another cluster or a notebook's,
                    # Dask warned on the user's terminal and moved. Any free port, said nowhere.
                    scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                    # What goes wrong is on the recording's row (a dead worker too); Dask's
                    # own ERROR lines (a worker's heartbeat to a scheduler closed by Ctrl-C)
                    # would be tracebacks on the user's terminal.
                    silence_logs=logging.CRITICAL,
                )
            client = Client(cluster)
            try:
                yield client
            finally:
                with _dask_quiet():
                    client.close()
    finally:
        if cluster is not None:
            with _dask_quiet():
                cluster.close()


@contextlib.contextmanager
def _dask_quiet() -> Iterator[None]:
    """This process's Dask and Tornado loggers at CRITICAL, and no "coroutine ... never awaited"
    warning, while a cluster is torn down (after Ctrl-C its comms close under it)."""
    import warnings

    # Every one of them: distributed.client and tornado.application set levels of their own.
    names = [
        name
        for name in ("distributed", "tornado", *logging.root.manager.loggerDict)
        if name.split(".")[0] in ("distributed", "tornado")
    ]
    loggers = [logging.getLogger(name) for name in dict.fromkeys(names)]
    levels = [logger.level for logger in loggers]
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "coroutine .* was never awaited", RuntimeWarning)
        for logger in loggers:
            logger.setLevel(logging.CRITICAL)
        try:
            yield
        finally:
            for logger, level in zip(loggers, levels, strict=True):
                logger.setLevel(level)
