"""Log records of a session's threads, held and said in log order.

A session analyses snapshots and scores breaks on threads that run ahead of its log order. What
they log (a topic's maps too fine for the walls cleaning or the break detector, ROSE found no
dominant direction), said as it came, came in another order from run to run, in ``rose-bag
batch``'s tables too. So it is held (:func:`held_log_records`, :func:`call_held`) and the session
says it (:func:`say_held`) when it takes the snapshot's results, in log order. While a progress
bar is drawn, what is said goes above it (:func:`said_above_bar`).
"""

from __future__ import annotations

import contextlib
import logging
import sys
import threading
from collections.abc import Callable, Iterator, Sequence
from contextvars import ContextVar
from typing import Any, TextIO, TypeVar

__all__ = [
    "ANALYSED_TOPIC",
    "call_held",
    "held_by",
    "held_log_records",
    "said_above_bar",
    "said_at_once",
    "say_held",
]

_T = TypeVar("_T")

#: The map topic this thread is analysing, so that the library's messages underneath (``ROSE found no
#: dominant direction ...``) can be said with it (``rose_logs.cli``'s log handler does).
ANALYSED_TOPIC: ContextVar[str | None] = ContextVar("rose_analysed_topic", default=None)

#: Where the records logged in this context go while :func:`held_log_records` holds them.
_HELD: ContextVar[list[logging.LogRecord] | None] = ContextVar(
    "rose_held_log_records", default=None
)

#: The hierarchies held: every logger of ``rose`` (the library underneath: the walls extraction,
#: the cleaning) and of ``rose_logs`` (the session, the reader, the break detector, ...).
_HELD_ROOTS = ("rose", "rose_logs")


class _Hold(logging.Filter):
    """Keeps a record back (in the list of its context) while :func:`held_log_records` holds them."""

    def filter(self, record: logging.LogRecord) -> bool:
        held = _HELD.get()
        if held is None:
            return True
        # Its message as it is now: formatted when said, arguments changed meanwhile (a list, an
        # object's state) were said as they had become. One that does not format is said as
        # logged (the handler reports the error, as it would have).
        with contextlib.suppress(Exception):
            record.msg, record.args = record.getMessage(), None
        held.append(record)
        return False


_HOLD = _Hold()
_HOLD_LOCK = threading.Lock()
_made_record = logging.getLogRecordFactory()


def _record_held_by_its_logger(*args: Any, **kwargs: Any) -> logging.LogRecord:
    """logging's record factory, putting the filter on a held hierarchy's logger before it handles
    a record made while records are held.

    A logger's filters see only the records logged on it, not those of its children propagating
    up: each logger needs its own. A list of names missed the loggers not on it, and those made
    later (a module imported on an analysis thread); the logger that makes a record is filtered
    here before it handles it, whichever it is."""
    record = _made_record(*args, **kwargs)
    # A record's name may be anything (logging.makeLogRecord({}) makes one named None).
    name = record.name
    if _HELD.get() is not None and isinstance(name, str) and name.partition(".")[0] in _HELD_ROOTS:
        logger = logging.getLogger(name)
        if _HOLD not in logger.filters:
            with _HOLD_LOCK:
                if _HOLD not in logger.filters:
                    # First, so that the logger's own filters see a held record once, as it is
                    # said: after them, they saw it twice (and one letting each message through
                    # once dropped it). A new list: a thread going through the old one is unmoved.
                    logger.filters = [_HOLD, *logger.filters]
    return record


logging.setLogRecordFactory(_record_held_by_its_logger)


@contextlib.contextmanager
def held_log_records() -> Iterator[list[logging.LogRecord]]:
    """Inside the block, what ``rose`` and ``rose_logs`` log in this context is kept in the list
    yielded instead of said: a session's threads run ahead of its log order, and their warnings (a
    topic's maps too fine for the walls cleaning or the break detector, ROSE found no dominant
    direction), said as they came, came in another order from run to run, in ``rose-bag batch``'s
    tables too. The session says them (:func:`say_held`) when it takes the snapshot's results, in
    log order; so too what it says itself while reading the messages after it."""
    held: list[logging.LogRecord] = []
    token = _HELD.set(held)
    try:
        yield held
    finally:
        _HELD.reset(token)


def call_held(call: Callable[[], _T]) -> tuple[_T, tuple[logging.LogRecord, ...]]:
    """``call()`` and what it logged, held (:func:`held_log_records`). If it raises, what it
    logged goes with the error (:func:`held_by`), to be said still."""
    with held_log_records() as held:
        try:
            value = call()
        except BaseException as err:
            err.held_log_records = tuple(held)  # type: ignore[attr-defined]
            raise
    return value, tuple(held)


def held_by(error: BaseException) -> tuple[logging.LogRecord, ...]:
    """What the call that raised ``error`` logged, held (:func:`call_held`)."""
    return getattr(error, "held_log_records", ())


def say_held(records: Sequence[logging.LogRecord], topic: str | None = None) -> None:
    """Say ``records`` kept back by :func:`held_log_records`, in order, as the analysis of ``topic``
    (the library's messages then name it, as when they are said at once; None: as logged outside
    any analysis). Said, not held again, inside a block that holds."""
    held = _HELD.set(None)
    analysed = ANALYSED_TOPIC.set(topic) if topic is not None else None
    try:
        for record in records:
            logging.getLogger(record.name).handle(record)
    finally:
        if analysed is not None:
            ANALYSED_TOPIC.reset(analysed)
        _HELD.reset(held)


@contextlib.contextmanager
def said_at_once() -> Iterator[None]:
    """Inside the block, records are said as they come, even inside a block that holds them."""
    token = _HELD.set(None)
    try:
        yield
    finally:
        _HELD.reset(token)


@contextlib.contextmanager
def said_above_bar(shown: bool) -> Iterator[None]:
    """While a progress bar is ``shown`` on the console, what ``rose`` and ``rose_logs`` log to
    standard output or error goes above it (tqdm's ``write``), the bar drawn again under it: said
    as it came, a line began where the bar's ended (``52%|...| 125/240 msg [...]warning: ...``).

    The handlers stay, only their stream is wrapped: tqdm's ``logging_redirect_tqdm`` put one
    handler of its own in their place, without their level, and (tqdm 4.66 and before) without their
    filters (``rose-bag``'s once per message: the library's lines said at every snapshot)."""
    handlers = [
        handler
        for handler in dict.fromkeys(  # (one handler may serve both)
            h for name in _HELD_ROOTS for h in logging.getLogger(name).handlers
        )
        if isinstance(handler, logging.StreamHandler) and handler.stream in (sys.stdout, sys.stderr)
    ]
    if not shown or not handlers:
        yield
        return
    streams = [handler.setStream(_AboveBar(handler.stream)) for handler in handlers]
    try:
        yield
    finally:
        for handler, stream in zip(handlers, streams, strict=True):
            handler.setStream(stream)


class _AboveBar:
    """A console stream whose lines are written above the progress bars drawn on it."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream

    def write(self, text: str) -> None:
        from tqdm import tqdm

        tqdm.write(text, file=self.stream, end="")  # the bars cleared, then drawn again

    def flush(self) -> None:
        self.stream.flush()
