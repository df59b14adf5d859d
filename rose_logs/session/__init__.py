"""A session: one pass over a log (log -> snapshots -> ROSE -> sinks: output log, Rerun, report).

:func:`process_log` is the loop; :mod:`.report` holds what it finds, :mod:`.topics` which topics it reads
and writes, :mod:`.analysis` the per-snapshot ROSE run with reuse, :mod:`rose_logs.rerun` the Rerun output.
"""

from rose.directions import FAILURE_LEVEL, TRUST_LEVEL
from rose_logs.session.breaks import BreakDetector, BreakParams, BreakScore, DetectedBreak
from rose_logs.session.loop import process_log
from rose_logs.session.report import BreakEvent, SessionReport, SnapshotRecord
from rose_logs.session.topics import default_output_path, find_map_topics, is_derived_topic

__all__ = [
    "FAILURE_LEVEL",
    "TRUST_LEVEL",
    "BreakDetector",
    "BreakEvent",
    "BreakParams",
    "BreakScore",
    "DetectedBreak",
    "SessionReport",
    "SnapshotRecord",
    "default_output_path",
    "find_map_topics",
    "is_derived_topic",
    "process_log",
]
