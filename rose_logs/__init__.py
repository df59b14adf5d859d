"""rose-bag: ROSE over robot logs (ROS 1 bags, ROS 2 bags, MCAP), Rerun views and cleaned output bags.

``process_log`` runs a whole session (read -> snapshots -> ``rose.analyze`` -> output log, Rerun,
report); ``LogReader`` and ``open_output`` read and write any supported log format. The Rerun view is
in ``rose_logs.rerun``, the CARMEN converter in ``rose_logs.carmen`` and the paper's
evaluation in ``rose_logs.evaluation``; they are imported on demand.
"""

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
