"""Exceptions raised by ``rose_logs``; every message is one line for the user and names the file."""

from __future__ import annotations

import errno

from rose.limits import memory_short
from rose.signals import reraise_interrupt_behind

__all__ = [
    "EmptyMapError",
    "LogError",
    "LogReadError",
    "LogWriteError",
    "MapMessageError",
    "OutOfMemory",
    "as_memory_error",
    "reraise_unless_damage",
    "storage_failure",
]


class OutOfMemory(MemoryError):
    """Memory that ran out as a log was read, told from damage once (:func:`reraise_unless_damage`):
    asked again where the error is caught again, after the unwinding freed buffers, the answer
    could change."""


class LogError(Exception):
    """Base class of every error raised by ``rose_logs``."""


class LogReadError(LogError):
    """An input log is missing, truncated, corrupt, of an unsupported format or has no map topic."""


class LogWriteError(LogError):
    """An output log cannot be written: it exists, its folder is not writable, or the format is wrong."""


class MapMessageError(LogError):
    """One map message cannot be decoded (for example data length != width * height).

    The session logs a warning and copies the message through unprocessed.
    """


class EmptyMapError(MapMessageError):
    """A map message of no cells (width or height 0, no data): valid, but nothing to analyse.

    The session copies it through unprocessed and counts it apart from malformed messages.
    """


def as_memory_error(err: BaseException) -> BaseException:
    """``err`` as the MemoryError it is when it says the machine ran out of memory in other words
    (zstd's ``Allocation error : not enough memory``, an OSError ENOMEM from ``mmap``), which the
    commands say in one line ("out of memory"); any other error as it is."""
    if isinstance(err, OSError) and err.errno == errno.ENOMEM:
        return MemoryError(str(err))
    if type(err).__name__ == "ZstdError" and "not enough memory" in str(err):
        return MemoryError(str(err))
    return err


#: Errors of the storage or network under a file (a failing disk, a network file system that went
#: away), not of its content: never damage of a log, and worth trying again.
STORAGE_ERRNOS = frozenset(
    getattr(errno, name)
    for name in ("EIO", "ESTALE", "ETIMEDOUT", "ENOTCONN", "ECONNRESET", "EREMOTEIO")
    if hasattr(errno, name)
)


def storage_failure(err: BaseException) -> OSError | None:
    """The I/O error of the storage under a file (:data:`STORAGE_ERRNOS`) that ``err`` is or was
    raised from, None when there is none."""
    seen = set()
    cause: BaseException | None = err
    while cause is not None and id(cause) not in seen:  # (a chain may loop back)
        if isinstance(cause, OSError) and cause.errno in STORAGE_ERRNOS:
            return cause
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return None


#: Address space that must still be free for a failed allocation to be damage, not memory running
#: out: a length field damaged to terabytes makes a library ask for more than any machine has.
MEMORY_PROBE_BYTES = 256 * 2**20


def reraise_unless_damage(err: BaseException) -> None:
    """Raise what a library's failure to read a log is when it is not damage of the log: an
    interrupt that landed inside the library, or memory running out (``ulimit -v``, a small
    machine). Read as damage, memory running out was said "corrupt or truncated log", and
    ``--salvage`` skipped the chunk it happened in as damaged: a sound file called broken.

    A failed allocation with :data:`MEMORY_PROBE_BYTES` still free is damage (a damaged length,
    rosbags reading a record of 2**40 bytes): said "out of memory", it was misread the other way.
    """
    reraise_interrupt_behind(err)
    if isinstance(err, OutOfMemory | ImportError):
        # A library that cannot be loaded (``failed to map segment``) is no damage of the log.
        raise err
    if storage_failure(err) is not None:
        # A failing disk or network file system: said "corrupt or truncated", and ``--salvage``
        # skipped the chunk being read as damaged, a sound file called broken.
        raise err
    memory = as_memory_error(err)
    if isinstance(memory, MemoryError) and memory_short(MEMORY_PROBE_BYTES):
        raise OutOfMemory(str(memory)) from err
