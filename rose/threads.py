"""Thread pools that run their jobs in the caller's :mod:`contextvars` context."""

from __future__ import annotations

import contextvars
from concurrent.futures import ThreadPoolExecutor

__all__ = ["threads_in_this_context"]


def threads_in_this_context(workers: int, name: str) -> ThreadPoolExecutor:
    """A thread pool whose threads run in a copy of the caller's :mod:`contextvars` context, as of
    this call, so that what they log belongs to the caller's work (``rose-bag batch`` keeps each
    recording's warnings apart that way; a plain pool's threads start from an empty context)."""
    return ThreadPoolExecutor(
        workers,
        thread_name_prefix=name,
        initializer=_enter_context,
        initargs=(contextvars.copy_context(),),
    )


def _enter_context(context: contextvars.Context) -> None:
    for variable, value in context.items():
        variable.set(value)
