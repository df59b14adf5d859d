"""Rerun recordings of ROSE sessions: entity paths, layout, loggers, the session sink, screenshots.

- :mod:`~rose_logs.rerun.paths`: entity paths and timelines (the one definition).
- :mod:`~rose_logs.rerun.style`: colours, class ids, display constants.
- :mod:`~rose_logs.rerun.conversions`: numpy conversions to what the viewer draws (tested directly).
- :mod:`~rose_logs.rerun.arrow`: per-snapshot components as Arrow arrays of Rerun's own types.
- :mod:`~rose_logs.rerun.loggers`: one logger per stream; static data logged once.
- :mod:`~rose_logs.rerun.blueprint`: the default layout.
- :mod:`~rose_logs.rerun.sink`: :class:`RerunSink`, the session's recording (file and/or live viewer).
- :mod:`~rose_logs.rerun.viewer`: live viewers' addresses (``--connect``), and whether one listens.
- :mod:`~rose_logs.rerun.screenshots`: PNGs of a recording in Rerun's web viewer (headless Chromium).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rose.lazy import lazy_exports

if TYPE_CHECKING:
    from rose_logs.rerun.blueprint import TopicLayout, default_blueprint
    from rose_logs.rerun.loggers import TopicLogger, set_snapshot_time
    from rose_logs.rerun.paths import (
        SEQUENCE_TIMELINE,
        SESSION_TIMELINE,
        TIMELINE,
        EntityPaths,
        entity_root_for_topic,
    )
    from rose_logs.rerun.sink import APPLICATION_ID, RerunSink, recording_id_for
    from rose_logs.rerun.viewer import grpc_url

__all__ = [
    "APPLICATION_ID",
    "SEQUENCE_TIMELINE",
    "SESSION_TIMELINE",
    "TIMELINE",
    "EntityPaths",
    "RerunSink",
    "TopicLayout",
    "TopicLogger",
    "default_blueprint",
    "entity_root_for_topic",
    "grpc_url",
    "recording_id_for",
    "set_snapshot_time",
]

# Public names are imported on first use (PEP 562): the modules that need no Rerun (paths, style,
# conversions, viewer) load without it.
_LAZY = {
    "APPLICATION_ID": "rose_logs.rerun.sink",
    "SEQUENCE_TIMELINE": "rose_logs.rerun.paths",
    "SESSION_TIMELINE": "rose_logs.rerun.paths",
    "TIMELINE": "rose_logs.rerun.paths",
    "EntityPaths": "rose_logs.rerun.paths",
    "RerunSink": "rose_logs.rerun.sink",
    "TopicLayout": "rose_logs.rerun.blueprint",
    "TopicLogger": "rose_logs.rerun.loggers",
    "default_blueprint": "rose_logs.rerun.blueprint",
    "entity_root_for_topic": "rose_logs.rerun.paths",
    "grpc_url": "rose_logs.rerun.viewer",
    "recording_id_for": "rose_logs.rerun.sink",
    "set_snapshot_time": "rose_logs.rerun.loggers",
}

__getattr__, __dir__ = lazy_exports(__name__, _LAZY, __all__)
