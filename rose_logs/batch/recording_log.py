"""The warnings of one recording of a batch, kept with its result instead of said as they come.

Said as they came, on a worker's stderr or among other recordings' lines, the warnings of ``rose``
and ``rose_logs`` named no recording. While a recording is processed, its warnings go to its own
:class:`RecordingWarnings` (its row, and a line naming its URI said by the batch); every other record
goes where it would have gone.

Logging is process-wide, so the routing is too: the first recording that starts puts a router in
front of the two loggers' handlers, the last one that ends takes it away, and each record goes to the
recording of the context it was logged in (a :mod:`contextvars` variable, which
:func:`rose_logs.session.process_log` hands on to its own threads). Recordings run side by side in
one process (threads of a Dask worker) therefore keep their warnings apart.
"""

from __future__ import annotations

import contextlib
import contextvars
import logging
import threading
from collections.abc import Iterator

__all__ = ["RecordingWarnings", "collecting"]

_CURRENT: contextvars.ContextVar[RecordingWarnings | None] = contextvars.ContextVar(
    "rose_batch_recording_warnings", default=None
)
_LOGGERS = ("rose", "rose_logs")


class RecordingWarnings:
    """Warning lines of one recording, in order, each said once (with a count when repeated).

    ``aliases`` maps text to replace in every line, e.g. a downloaded copy's path to the URI.
    """

    def __init__(self) -> None:
        self._counts: dict[str, int] = {}
        self.aliases: dict[str, str] = {}
        self._lock = threading.Lock()  # the session's threads add lines too

    def add(self, text: str) -> None:
        line = " ".join(text.split())
        with self._lock:
            self._counts[line] = self._counts.get(line, 0) + 1

    def lines(self) -> tuple[str, ...]:
        """One line per distinct warning, first-said order; ``(N times)`` when said N > 1 times."""
        with self._lock:
            counted = list(self._counts.items())
        out = []
        for line, count in counted:
            for old, new in self.aliases.items():
                line = line.replace(old, new)
            out.append(line if count == 1 else f"{line} ({count} times)")
        return tuple(out)


class _Router(logging.Handler):
    """Stands in for a logger's handlers: a warning logged inside a recording's context goes to that
    recording; anything else is handled as the logger would have (its handlers, then its parents'
    if it propagated)."""

    def __init__(self, logger: logging.Logger) -> None:
        super().__init__(logging.NOTSET)
        self.logger = logger
        self.replaced = logger.handlers[:]
        self.propagated = logger.propagate

    def emit(self, record: logging.LogRecord) -> None:
        target = _CURRENT.get()
        if target is not None and record.levelno >= logging.WARNING:
            target.add(record.getMessage())
            return
        for handler in self.replaced:
            if record.levelno >= handler.level:
                handler.handle(record)
        if self.propagated and self.logger.parent is not None:
            self.logger.parent.handle(record)

    def restore(self) -> None:
        self.logger.handlers = self.replaced
        self.logger.propagate = self.propagated


class _Routing:
    """The routers, installed while at least one recording collects (counted under a lock)."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.users = 0
        self.routers: list[_Router] = []

    def enter(self) -> None:
        with self.lock:
            if self.users == 0:
                for name in _LOGGERS:
                    logger = logging.getLogger(name)
                    router = _Router(logger)
                    logger.handlers = [router]
                    logger.propagate = False
                    self.routers.append(router)
            self.users += 1

    def leave(self) -> None:
        with self.lock:
            self.users -= 1
            if self.users == 0:
                for router in self.routers:
                    router.restore()
                self.routers = []


#: Process-wide, as the loggers it routes.
_ROUTING = _Routing()


@contextlib.contextmanager
def collecting(warnings: RecordingWarnings) -> Iterator[RecordingWarnings]:
    """Inside the block (and the threads it starts with its context), warnings of ``rose`` and
    ``rose_logs`` go to ``warnings`` instead of being said."""
    _ROUTING.enter()
    token = _CURRENT.set(warnings)
    try:
        yield warnings
    finally:
        _CURRENT.reset(token)
        _ROUTING.leave()
