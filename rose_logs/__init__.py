"""rose-bag: ROSE over robot logs (ROS 1 bags, ROS 2 bags, MCAP), Rerun views and cleaned output bags.

``process_log`` runs a whole session (read -> snapshots -> ``rose.analyze`` -> output log, Rerun,
report); ``LogReader`` and ``open_output`` read and write any supported log format. The Rerun view is
in ``rose_logs.rerun``, the CARMEN converter in ``rose_logs.carmen`` and the paper's
evaluation in ``rose_logs.evaluation``; they are imported on demand.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rose.lazy import lazy_exports

if TYPE_CHECKING:
    from rose_logs.errors import LogError, LogReadError, LogWriteError, MapMessageError
    from rose_logs.reader import LogReader
    from rose_logs.session import BreakEvent, SessionReport, SnapshotRecord, process_log
    from rose_logs.snapshots import MapSnapshot
    from rose_logs.writer import LogWriter, open_output

__all__ = [
    "BreakEvent",
    "LogError",
    "LogReadError",
    "LogReader",
    "LogWriteError",
    "LogWriter",
    "MapMessageError",
    "MapSnapshot",
    "SessionReport",
    "SnapshotRecord",
    "open_output",
    "process_log",
]
__version__ = "0.1.0"

# Public names are imported on first use (PEP 562), so `import rose_logs.cli` stays light.
_LAZY = {
    "BreakEvent": "rose_logs.session",
    "LogError": "rose_logs.errors",
    "LogReadError": "rose_logs.errors",
    "LogReader": "rose_logs.reader",
    "LogWriteError": "rose_logs.errors",
    "LogWriter": "rose_logs.writer",
    "MapMessageError": "rose_logs.errors",
    "MapSnapshot": "rose_logs.snapshots",
    "SessionReport": "rose_logs.session",
    "SnapshotRecord": "rose_logs.session",
    "open_output": "rose_logs.writer",
    "process_log": "rose_logs.session",
}


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, __all__)
