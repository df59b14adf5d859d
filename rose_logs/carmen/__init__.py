"""CARMEN laser logs -> ROS mapping sessions: parse FLASER lines, cast rays into log-odds grids, add seeded
odometry drift, and write the session (scans, poses, map snapshots) as a log.

``parse`` reads the log, ``raycast`` builds occupancy grids from scans, ``drift`` perturbs poses,
``session`` writes a session through :mod:`rose_logs.writer`.
"""

from rose_logs.carmen.drift import DriftParams, apply_drift
from rose_logs.carmen.parse import CarmenLog, FlaserScan, beam_angles, read_carmen_log
from rose_logs.carmen.raycast import BuilderParams, OccupancyGridBuilder, ScanBatch, crop_to_known
from rose_logs.carmen.session import SessionOptions, SessionSummary, write_carmen_session

__all__ = [
    "BuilderParams",
    "CarmenLog",
    "DriftParams",
    "FlaserScan",
    "OccupancyGridBuilder",
    "ScanBatch",
    "SessionOptions",
    "SessionSummary",
    "apply_drift",
    "beam_angles",
    "crop_to_known",
    "read_carmen_log",
    "write_carmen_session",
]
