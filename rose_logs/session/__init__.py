"""A session: one pass over a log (log -> snapshots -> ROSE -> sinks: output log, Rerun, report).

:func:`process_log` is the loop; :mod:`.report` holds what it finds, :mod:`.topics` which topics it reads
and writes, :mod:`.analysis` the per-snapshot ROSE run with reuse, :mod:`rose_logs.rerun` the Rerun output;
:mod:`.checks` checks the loop's arguments, :mod:`.sinks` opens its outputs and :mod:`.records` makes its
records.
"""

from __future__ import annotations

import pkgutil
from typing import TYPE_CHECKING

from rose.lazy import lazy_exports

if TYPE_CHECKING:
    from rose.directions import FAILURE_LEVEL, TRUST_LEVEL
    from rose_logs.session.breaks import (
        BreakDetector,
        BreakParams,
        BreakParamsError,
        BreakScore,
        DetectedBreak,
    )
    from rose_logs.session.loop import process_log
    from rose_logs.session.report import BreakEvent, SessionReport, SnapshotRecord
    from rose_logs.session.topics import default_output_path, find_map_topics, is_derived_topic

__all__ = [
    "FAILURE_LEVEL",
    "TRUST_LEVEL",
    "BreakDetector",
    "BreakEvent",
    "BreakParams",
    "BreakParamsError",
    "BreakScore",
    "DetectedBreak",
    "SessionReport",
    "SnapshotRecord",
    "default_output_path",
    "find_map_topics",
    "is_derived_topic",
    "process_log",
]

# Loaded on first use: ``rose-bag info`` needs the topics only, not the loop's ROSE and scipy.
__getattr__, __dir__ = lazy_exports(
    __name__,
    {
        "FAILURE_LEVEL": "rose.directions",
        "TRUST_LEVEL": "rose.directions",
        "BreakDetector": "rose_logs.session.breaks",
        "BreakParams": "rose_logs.session.breaks",
        "BreakParamsError": "rose_logs.session.breaks",
        "BreakScore": "rose_logs.session.breaks",
        "DetectedBreak": "rose_logs.session.breaks",
        "process_log": "rose_logs.session.loop",
        "BreakEvent": "rose_logs.session.report",
        "SessionReport": "rose_logs.session.report",
        "SnapshotRecord": "rose_logs.session.report",
        "default_output_path": "rose_logs.session.topics",
        "find_map_topics": "rose_logs.session.topics",
        "is_derived_topic": "rose_logs.session.topics",
    },
    __all__,
    # ``rose_logs.session.loop`` after a plain ``import rose_logs.session``, as before.
    tuple(module.name for module in pkgutil.iter_modules(__path__)),
)
