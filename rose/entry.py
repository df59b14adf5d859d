"""The console scripts ``rose`` and ``rose-bag`` (``[project.scripts]``), and their start-up.

The command modules take a tenth of a second or more to load (more on a busy machine), and their
``main`` installs the signal handlers only once loaded: a Ctrl-C meanwhile was Python's
``KeyboardInterrupt`` traceback from inside an import. So the console scripts start here, in a module
that loads nothing else: :func:`hold_start_signals` holds SIGINT / SIGTERM / SIGHUP while the
command loads, and the command's ``main`` ends the hold (:func:`raise_held_start_signal`) inside its
own handlers, where a held signal exits 130 / 143 / 129 like any other interrupt. ``python -m
rose_logs.cli`` / ``python -m rose.cli`` load the packages before the command's ``__main__``: the
package ``rose`` (loaded first in both) holds them as it loads, when the command is the module
run (:func:`run_as`).

Only the commands hold signals: a program that imports ``rose`` or ``rose_logs`` keeps its own
handlers (importing them, or this module, changes no handler).
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from types import FrameType

__all__ = [
    "blas_threads_within_address_limit",
    "hold_start_signals",
    "raise_held_start_signal",
    "rose",
    "rose_bag",
    "run_as",
]

#: The handlers the hold replaced (signal number -> handler), while it lasts.
_replaced: dict[int, Any] = {}
#: The signals that arrived during the hold, in order.
_held: list[int] = []


def _hold(signum: int, _frame: FrameType | None) -> None:
    _held.append(signum)


def hold_start_signals() -> None:
    """Hold SIGINT / SIGTERM / SIGHUP until :func:`raise_held_start_signal` (main thread only;
    signals ignored, e.g. under ``nohup``, stay ignored)."""
    import signal  # here: `import rose` stays as light as it was
    import threading

    if _replaced or threading.current_thread() is not threading.main_thread():
        return
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        signum = getattr(signal, name, None)
        if signum is None:
            continue
        handler = signal.getsignal(signum)
        if handler is None or handler == signal.SIG_IGN:
            continue
        _replaced[signum] = handler
        signal.signal(signum, _hold)


def raise_held_start_signal() -> None:
    """End the hold of :func:`hold_start_signals` (a no-op without one): each signal whose handler
    is still the hold's gets its handler back, then the first signal held is raised
    (``KeyboardInterrupt`` for SIGINT, :class:`rose.signals.Terminated` for the others)."""
    if not _replaced:
        return
    import signal

    for signum, handler in _replaced.items():
        if signal.getsignal(signum) is _hold:
            signal.signal(signum, handler)
    _replaced.clear()
    if _held:
        from rose.signals import Terminated

        signum = _held[0]
        _held.clear()
        raise KeyboardInterrupt if signum == signal.SIGINT else Terminated(signum)


def run_as(module: str) -> bool:
    """Whether this process is ``python -m module`` and is still loading it (``runpy`` imports a
    package before its ``__main__``; meanwhile ``sys.argv[0]`` is ``-m``)."""
    argv, orig = sys.argv, getattr(sys, "orig_argv", [])
    if not argv or argv[0] != "-m" or len(orig) < len(argv):
        return False
    return orig[-len(argv)] in (module, f"-m{module}")


def blas_threads_within_address_limit() -> None:
    """Under a limit of the address space (``ulimit -v``), OpenBLAS (numpy's, scipy's, OpenCV's)
    runs one thread, unless ``OPENBLAS_NUM_THREADS`` says otherwise; a command calls this before
    numpy loads (OpenBLAS reads it as it loads).

    As it loads, OpenBLAS starts a thread per core and maps a buffer for each: a thread that could
    not start made it raise SIGINT (the run said "interrupted", exit 130, where it was out of
    memory), and a buffer that could not be mapped made it retry for ever (the run hung, deaf to
    Ctrl-C and SIGTERM, at limits some hundreds of MB wide and wider with more cores). With one
    thread the commands run under lower limits, or say that they are out of memory (OpenBLAS can
    still hang where even its one buffer does not fit, see :func:`load_blas_before_work`). Without
    a limit nothing changes."""
    import os

    if address_space_limited():
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def address_space_limited() -> bool:
    """Whether this process runs under a limit of its address space (``ulimit -v``; never on
    Windows, which has none)."""
    try:
        import resource
    except ImportError:  # Windows
        return False
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    return bool(soft != resource.RLIM_INFINITY)


#: Address space that must be free for scipy's OpenBLAS to load (its buffer is 32 MiB).
BLAS_LOAD_BYTES = 64 * 2**20


def load_blas_before_work() -> None:
    """Under a limit of the address space, load scipy's OpenBLAS (a library of its own, beside
    numpy's) now, for a command about to analyse maps; MemoryError when it would not fit.

    Loaded on demand by the first analysis, with the log's buffers and the session's threads
    already mapped, its buffer did not fit, and OpenBLAS retried for ever: ``rose-bag process``
    hung at 100 % CPU (``ulimit -v 400000``, 1000 x 1000 maps). Loaded before the work, the run
    completes or says that it is out of memory. Only the commands that analyse call this: loaded
    by every command, it hung ``--version`` and ``info`` under limits where they ran."""
    from rose.limits import memory_short

    if not address_space_limited() or "scipy.special" in sys.modules:
        return
    if memory_short(BLAS_LOAD_BYTES):
        msg = "no room left to load scipy's OpenBLAS"
        raise MemoryError(msg)
    import scipy.fft  # noqa: F401  (scipy.special, which it loads, brings the OpenBLAS)


def rose() -> None:
    """The ``rose`` console script."""
    hold_start_signals()
    blas_threads_within_address_limit()
    from rose.cli import console

    console()


def rose_bag() -> None:
    """The ``rose-bag`` console script."""
    hold_start_signals()
    blas_threads_within_address_limit()
    from rose_logs.cli import console

    console()
