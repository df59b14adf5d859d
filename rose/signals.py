"""Interrupts for the commands: SIGTERM and SIGHUP as :class:`Terminated` (a ``KeyboardInterrupt``), so
the same clean-up runs as for Ctrl-C; signals held while a block must not be cut
(:func:`signals_deferred`); the exit codes and the one line an interrupted run ends with.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator, Mapping
from types import FrameType
from typing import Any, NoReturn

__all__ = [
    "HeldSignals",
    "Terminated",
    "exit_after",
    "install_signal_handlers",
    "interrupt_behind",
    "report_interrupt",
    "reraise_interrupt_behind",
    "run_interruptible",
    "signal_handlers_kept",
    "signals_deferred",
]


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP arrived; raised in the main thread so every ``finally`` / abort runs."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum

    @property
    def exit_code(self) -> int:
        """The shell's convention: 128 + signal number."""
        return 128 + self.signum


def _raise_terminated(signum: int, _frame: FrameType | None) -> None:
    raise Terminated(signum)


def exit_after(code: int) -> NoReturn:
    """Exit a console script with ``code`` once its work is done and its outputs are committed.

    A SIGINT / SIGTERM / SIGHUP arriving from now on (during interpreter shutdown Python restores the
    default handlers) would turn a finished run into a killed one (exit -2, -15): ignore them.
    """
    _set_handlers(dict.fromkeys(_interrupt_signals(), signal.SIG_IGN))
    sys.exit(code)


def install_signal_handlers() -> None:
    """Turn SIGTERM and SIGHUP into :class:`Terminated` (main thread only; a no-op elsewhere).

    A signal the caller ignores stays ignored: ``nohup`` (SIGHUP) and a shell's background job.
    """
    signums = _interrupt_signals("SIGTERM", "SIGHUP")
    _set_handlers({s: _raise_terminated for s in signums if not _ignored(s)})


@contextlib.contextmanager
def signal_handlers_kept() -> Iterator[None]:
    """Put the SIGINT / SIGTERM / SIGHUP handlers back as they were when the block ends.

    For a command's ``main`` run in-process (a test, a notebook): it installs its own handlers
    (SIGTERM / SIGHUP raise :class:`Terminated`); its caller gets its own handlers back.
    """
    previous = {s: h for s in _interrupt_signals() if (h := signal.getsignal(s)) is not None}
    try:
        yield
    finally:
        _set_handlers(previous)


def _interrupt_signals(*names: str) -> list[int]:
    """The numbers of ``names`` (default SIGINT, SIGTERM, SIGHUP) that the platform has."""
    names = names or ("SIGINT", "SIGTERM", "SIGHUP")
    return [getattr(signal, n) for n in names if hasattr(signal, n)]


def _ignored(signum: int) -> bool:
    return signal.getsignal(signum) == signal.SIG_IGN


def _on_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def _set_handlers(handlers: Mapping[int, Any]) -> None:
    """Install several handlers as one step: no signal is handled between two of them.

    The signals are blocked meanwhile (one arriving then is delivered after, to the new handler; to
    nothing if that is SIG_IGN). Only the main thread installs handlers: elsewhere a no-op.
    """
    if not handlers or not _on_main_thread():
        return
    mask = getattr(signal, "pthread_sigmask", None)
    previous_mask = None if mask is None else mask(signal.SIG_BLOCK, set(handlers))
    try:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
    finally:
        if mask is not None and previous_mask is not None:
            mask(signal.SIG_SETMASK, previous_mask)


def _interrupt_for(signum: int) -> KeyboardInterrupt:
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated(signum)


class HeldSignals:
    """The signals :func:`signals_deferred` holds (numbers, in arrival order); true when any is held."""

    def __init__(self, *, second_ends: bool = False) -> None:
        self.signals: list[int] = []
        self._dropping = False
        self._second_ends = second_ends

    def __bool__(self) -> bool:
        return bool(self.signals)

    def hold(self, signum: int, _frame: FrameType | None) -> None:
        if self._dropping:
            return
        if self._second_ends and self.signals:  # the user insists: now, wherever it lands
            raise _interrupt_for(signum)
        self.signals.append(signum)

    def drop(self) -> None:
        """Forget the held signals, and any that arrives until the block ends (the work is done)."""
        self._dropping = True
        self.signals.clear()


@contextlib.contextmanager
def signals_deferred(*, second_ends: bool = False) -> Iterator[HeldSignals]:
    """Hold SIGINT / SIGTERM / SIGHUP for the block, then raise the first (KeyboardInterrupt / Terminated).

    For start-up, while the CLIs import their libraries: an interrupt raised inside a C extension's
    initialisation surfaces as ``ImportError: initialization failed``, not as the interrupt it was.
    Yields the :class:`HeldSignals`, so a block can see that one is waiting (e.g. to undo its work
    before it is raised). If the block fails, a held signal is raised instead of the failure (from
    it): the run was interrupted. Signals the caller ignores stay ignored; outside the main thread
    the block runs unguarded (Python handles signals in the main thread only). With
    ``second_ends``, a second signal is raised at once, wherever it lands (a block that waits on a
    slow read or write can be ended).
    """
    held = HeldSignals(second_ends=second_ends)
    previous = {
        s: h
        for s in _interrupt_signals()
        if (h := signal.getsignal(s)) not in (None, signal.SIG_IGN)
    }
    _set_handlers(dict.fromkeys(previous, held.hold))
    try:
        yield held
    except BaseException as err:
        _set_handlers(previous)
        if held.signals and not isinstance(err, KeyboardInterrupt):
            raise _interrupt_for(held.signals[0]) from err
        raise
    _set_handlers(previous)
    if held.signals:
        raise _interrupt_for(held.signals[0])


def run_interruptible(body: Callable[[], int]) -> int:
    """Run a command's ``body`` and return its exit code; an interrupt (Ctrl-C, SIGTERM, SIGHUP, or
    an import one of them broke) ends it with one line on stderr and 130 / 128 + signal."""
    try:
        return body()
    except Exception as err:  # e.g. ImportError: a library loaded on demand, interrupted
        interrupt = interrupt_behind(err)
        if interrupt is None:
            raise
        return report_interrupt(interrupt)
    except KeyboardInterrupt as err:
        return report_interrupt(err)


def report_interrupt(err: KeyboardInterrupt) -> int:
    """Say on stderr that the run was interrupted; return its exit code (130, or 128 + signal)."""
    print("error: interrupted, nothing written", file=sys.stderr)
    return err.exit_code if isinstance(err, Terminated) else 130


def reraise_interrupt_behind(err: BaseException) -> None:
    """Raise the interrupt that caused ``err``, if any: a signal that landed inside a library (an
    import, a class being created) comes back wrapped in that library's error."""
    interrupt = interrupt_behind(err)
    if interrupt is not None:
        raise interrupt


def interrupt_behind(err: BaseException) -> KeyboardInterrupt | None:
    """The interrupt that caused ``err`` (e.g. an ImportError of an interrupted import), if any."""
    seen: set[int] = set()
    cause: BaseException | None = err
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            return cause
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return None
