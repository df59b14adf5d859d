"""Suite-wide hooks: the ``dataset`` marker for tests that need the full real data set.

``@pytest.mark.dataset("bormann_ipa_room_segmentation")`` (or ``pytestmark = ...`` on a module) skips
the test when that path is not in the data set (``ROSE_DATA_DIR``, see :mod:`rose_logs.datasets`), with
a reason saying how to get it; with ``ROSE_REQUIRE_DATA=1`` (CI) it fails instead. Helpers are in
``tests/real_data.py``.
"""

from __future__ import annotations

import logging
import signal
from collections.abc import Iterator

import pytest
from real_data import dataset


def pytest_configure(config: pytest.Config) -> None:
    # A shell starts a background job (`pytest &`, no job control) with SIGINT ignored, and Python
    # keeps it so; the tests of Ctrl-C handling (ours and of the commands they start) need it live.
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    config.addinivalue_line(
        "markers",
        "dataset(*paths): needs these paths inside the full real data set (ROSE_DATA_DIR); "
        "skipped without it, failed under ROSE_REQUIRE_DATA=1",
    )


@pytest.fixture(autouse=True)
def _signal_state_isolated() -> Iterator[None]:
    """Each test starts with the signal handlers and mask the previous one found: a test that runs a
    command in-process and leaves a handler behind must not change how later tests see signals (a
    child process inherits ignored or blocked signals)."""
    names = ("SIGINT", "SIGTERM", "SIGHUP")
    handlers = {name: signal.getsignal(getattr(signal, name)) for name in names}
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    yield
    for name, handler in handlers.items():
        if handler is not None:
            signal.signal(getattr(signal, name), handler)
    signal.pthread_sigmask(signal.SIG_SETMASK, mask)


@pytest.fixture(autouse=True)
def _logging_isolated() -> Iterator[None]:
    """Each test starts with our packages' loggers as Python leaves them, and the root logger as the
    previous test found it. A command run in-process (in a test or in a module-scoped fixture)
    points the ``rose_logs`` and ``rose`` loggers at the stderr of that moment (a captured stream,
    closed once the test ends) and stops them propagating: later tests' warnings would go to a
    closed file, and pytest's ``caplog`` would never see them."""

    def pristine() -> None:
        for name in ("rose_logs", "rose"):
            logger = logging.getLogger(name)
            logger.handlers[:] = []
            logger.setLevel(logging.NOTSET)
            logger.propagate = True

    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    pristine()
    yield
    pristine()
    root.handlers[:] = handlers
    root.setLevel(level)


def pytest_runtest_setup(item: pytest.Item) -> None:
    for marker in item.iter_markers("dataset"):
        for relative in marker.args:
            dataset(relative)
