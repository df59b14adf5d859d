"""A local Dask cluster for a batch: worker processes with one thread each, our worker environment."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from typing import Any

from rose_logs.batch.workerenv import worker_environment

__all__ = ["local_client"]

_LOG = logging.getLogger(__name__)


@contextlib.contextmanager
def local_client(
    workers: int, *, memory_limit: str | float | None = None, retries: int = 2
) -> Iterator[Any]:
    """A ``distributed.Client`` on a new ``LocalCluster`` of ``workers`` processes on 127.0.0.1.

    Workers get one thread each, :func:`worker_environment` (malloc thresholds instead of Dask's
    ``MALLOC_TRIM_THRESHOLD_=65536``, one-thread BLAS) through ``distributed.nanny.pre-spawn-environ``,
    no dashboard, and ``allowed-failures = retries``: a recording whose worker dies more often than
    that is reported as failed instead of being retried forever.
    """
    import dask
    from distributed import Client, LocalCluster

    environ = {**dask.config.get("distributed.nanny.pre-spawn-environ", {}), **worker_environment()}
    settings = {
        "distributed.nanny.pre-spawn-environ": environ,
        "distributed.scheduler.allowed-failures": max(0, retries),
    }
    with dask.config.set(settings):
        cluster = LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            memory_limit="auto" if memory_limit is None else memory_limit,
            host="127.0.0.1",
            dashboard_address=None,
            silence_logs=logging.ERROR,
        )
        try:
            with Client(cluster) as client:
                yield client
        finally:
            cluster.close()
