"""Standard output of the commands: any file name printable, a buffer for an unbuffered stream,
write errors raised naming standard output (:class:`rose.errors.StdoutError`), and a reader that
went away (``| head``) ending the run quietly with :data:`EXIT_BROKEN_PIPE`.
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
from collections.abc import Iterable, Iterator
from typing import Any, TextIO

from rose.errors import StdoutError

__all__ = [
    "EXIT_BROKEN_PIPE",
    "buffer_unbuffered_stdout",
    "flush_stdout",
    "print_any_file_name",
    "stderr_discarded",
    "stderr_is_terminal",
    "stdout_closed",
    "stdout_discarded",
    "stdout_errors_named",
]


EXIT_BROKEN_PIPE = 141
"""Exit code when the reader of standard output went away (``| head``): 128 + SIGPIPE, what a
shell reports for a program that SIGPIPE ended."""


def print_any_file_name() -> None:
    """Let standard output print any file name.

    Linux file names are bytes; Python decodes the undecodable ones with surrogate escapes, which a
    strict UTF-8 stream refuses to print. Written back as the bytes they came from, they show as
    ``ls`` shows them. A stream that cannot hold a character (``café`` on an ASCII or Latin-1
    terminal, ``PYTHONIOENCODING=ascii``) gets it backslash-escaped, as stderr does, instead of a
    traceback after the outputs were written. The CLIs' ``main`` calls this once (process-wide,
    like their signal handlers).
    """
    import codecs

    codecs.register_error(_PRINTABLE, _printable)
    reconfigure = getattr(sys.stdout, "reconfigure", None)
    if reconfigure is not None:
        with contextlib.suppress(ValueError, OSError):  # not a text stream we may change
            reconfigure(errors=_PRINTABLE)


def buffer_unbuffered_stdout() -> None:
    """Give an unbuffered standard output (``python -u``, ``PYTHONUNBUFFERED``, common in
    containers and CI) a buffer, flushed at every line as unbuffered output is expected to show.
    Unbuffered, a pipe whose reader leaves mid-write takes part of a large write and reports the
    count, not an error, and the text layer drops the rest: ``rose score --json ... | head`` ended
    with exit 0 and the report cut. A buffer writes all it is given or raises. The console
    scripts call this (not ``main``: an in-process caller keeps its own stream); only a plain file
    descriptor is wrapped (a Windows console's stream encodes for its console itself)."""
    stream = sys.stdout
    raw = getattr(stream, "buffer", None)
    if type(raw) is not io.FileIO or not isinstance(stream, io.TextIOWrapper):
        return
    try:
        # A file of its own on the descriptor, which it never closes: the stream it replaces
        # (sys.__stdout__) keeps its file open when this one goes.
        own = io.FileIO(raw.fileno(), "w", closefd=False)
    except (OSError, ValueError):
        return
    sys.stdout = io.TextIOWrapper(
        io.BufferedWriter(own),
        encoding=stream.encoding,
        errors=stream.errors,
        line_buffering=True,
    )


#: The error handler :func:`print_any_file_name` gives standard output.
_PRINTABLE = "rose-printable"


def _printable(err: UnicodeError) -> tuple[str | bytes, int]:
    """Characters the stream cannot encode: a file name's undecodable bytes (surrogate escapes) as
    those bytes, anything else backslash-escaped."""
    if not isinstance(err, UnicodeEncodeError):
        raise err
    chunk = err.object[err.start : err.end]
    if all(0xDC80 <= ord(c) <= 0xDCFF for c in chunk):
        return bytes(ord(c) - 0xDC00 for c in chunk), err.end
    return chunk.encode("ascii", "backslashreplace").decode("ascii"), err.end


def stdout_closed(err: OSError) -> bool:
    """Whether ``err`` is a broken pipe on standard output (no file name: not one of our files).

    If so, standard output is pointed at ``/dev/null``, so that Python's flush at exit does not
    report the same broken pipe again; the caller then exits with :data:`EXIT_BROKEN_PIPE`, quietly.
    """
    if not isinstance(err, BrokenPipeError) or err.filename is not None:
        return False
    _discard_stdout()
    return True


def flush_stdout() -> int:
    """Flush standard output now; return 0, or the exit code of a failure said as every command
    says it: 1 after ``error: standard output: cannot write (<reason>)``, 141 quietly when the
    reader left (:data:`EXIT_BROKEN_PIPE`).

    For text printed outside a command's :func:`stdout_errors_named` block (argparse's ``--help``
    and ``--version``), which Python's flush at exit would report with a traceback-like
    ``Exception ignored`` and exit 120.
    """
    try:
        with stdout_errors_named():
            pass  # the block flushes what is buffered
    except StdoutError as err:
        print(f"error: {err}", file=sys.stderr)
        return 1
    except BrokenPipeError:
        _discard_stdout()
        return EXIT_BROKEN_PIPE
    return 0


def _discard_stdout() -> None:
    """Point standard output's descriptor at ``/dev/null``: what is still buffered goes nowhere."""
    with contextlib.suppress(OSError, ValueError, AttributeError):  # stdout may be no real file
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, sys.stdout.fileno())
        finally:
            os.close(devnull)


@contextlib.contextmanager
def stdout_errors_named() -> Iterator[None]:
    """Run a command with standard output's write errors raised as :class:`StdoutError`.

    A write error carries no file name, so the CLIs named their input for it (``rose score m.yaml >
    /dev/full``: ``m.yaml: No space left on device``). The text still buffered is flushed before
    the block ends, where the error is reported like any other: at exit Python would only print a
    traceback and exit 120. A broken pipe stays :class:`BrokenPipeError` (the reader left: the CLIs
    end quietly, :func:`stdout_closed`).
    """
    stream = sys.stdout
    if stream is None:  # no standard output at all (pythonw): nothing to name
        yield
        return
    named = _NamedStdout(stream)
    sys.stdout = named  # a TextIO in all but type: what it does not wrap, it passes on
    try:
        yield
        named.flush()
    except StdoutError:
        _discard_stdout()  # Python's flush at exit would fail again, and exit 120
        raise
    finally:
        if sys.stdout is named:
            sys.stdout = stream


def stderr_is_terminal() -> bool:
    """Whether standard error is a terminal (a progress bar is drawn there); False when the process
    has none (``pythonw``, ``2>&-``: ``sys.stderr`` is None)."""
    return sys.stderr is not None and sys.stderr.isatty()


@contextlib.contextmanager
def stdout_discarded() -> Iterator[None]:
    """Run a command that writes no result to standard output when the process has none
    (``pythonw``, or started with it closed, ``>&-``: ``sys.stdout`` is None): what it prints
    there (its summary) is discarded. ``print`` skips a missing stream, but a command that writes
    to it (``sys.stdout.write``) raised AttributeError after its files were written. Closed
    descriptors 1 and 2 are taken by /dev/null first, standard error's alone too (``2>&-``): Rerun's
    native warnings go to descriptor 2."""
    _occupy_closed_descriptors()
    with _discarded_if_missing("stdout"):
        yield


@contextlib.contextmanager
def stderr_discarded() -> Iterator[None]:
    """Run a command whose process has no standard error (``pythonw``, or started with it closed,
    ``2>&-``: ``sys.stderr`` is None) with what it says there discarded. ``print(..., file=None)``
    writes to standard output: its ``error:`` and ``warning:`` lines, and the summary that
    ``--json -`` sends off standard output, went into the data there (a report that no longer
    parsed). The CLIs' ``main`` wraps the whole run in it, the interrupt's line included."""
    with _discarded_if_missing("stderr"):
        yield


@contextlib.contextmanager
def _discarded_if_missing(name: str) -> Iterator[None]:
    """While the block runs, ``sys.<name>`` (``stdout``, ``stderr``) is a :class:`_Discarded`
    stream if it is None; None again afterwards (an in-process caller's as it was)."""
    if getattr(sys, name) is not None:
        yield
        return
    discard = _Discarded()
    setattr(sys, name, discard)
    try:
        yield
    finally:
        if getattr(sys, name) is discard:
            setattr(sys, name, None)


def _occupy_closed_descriptors() -> None:
    """Put ``/dev/null`` (``nul``) on file descriptors 1 and 2 where they are closed (``>&-``).

    A closed descriptor is the next one ``open`` hands out: the command's output log or report
    would become the process's standard output, into which a child (the spawned Rerun viewer, a
    batch worker) or native code writing to standard output would then write.
    """
    for fd in (1, 2):
        try:
            os.fstat(fd)
        except OSError:
            null = os.open(os.devnull, os.O_WRONLY)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)


class _Discarded(io.TextIOBase):
    """A text stream that takes everything and keeps nothing (no file descriptor: no output is
    ever mistaken for it)."""

    encoding = "utf-8"

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        return len(text)


class _NamedStdout:
    """Standard output whose write errors are :class:`StdoutError`; everything else is the stream's."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        with _named_write_errors():
            return self._stream.write(text)

    def writelines(self, lines: Iterable[str]) -> None:
        with _named_write_errors():
            self._stream.writelines(lines)

    def flush(self) -> None:
        with _named_write_errors():
            self._stream.flush()

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


@contextlib.contextmanager
def _named_write_errors() -> Iterator[None]:
    """An error of standard output's own (no file name) as :class:`StdoutError`."""
    try:
        yield
    except BrokenPipeError:
        raise
    except OSError as err:
        if err.filename is not None:  # not standard output's own error
            raise
        raise StdoutError(err.strerror or str(err)) from err
