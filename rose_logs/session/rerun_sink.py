"""The session's Rerun sink: one recording for every map topic, saved through a temporary ``.rrd``."""

from __future__ import annotations

import contextlib
import logging
from pathlib import Path

from rose.result import RoseResult
from rose.walls.segments import WallSet
from rose_logs.errors import LogWriteError
from rose_logs.snapshots import MapSnapshot

__all__ = ["RerunSink", "entity_root"]

_LOG = logging.getLogger(__name__)

_DECODABLE = {"ros1", "cdr"}


def entity_root(topic: str) -> str:
    return topic.strip("/").lower() or "map"


class RerunSink:
    """Rerun recording through :mod:`rose_logs.rerun_view`, saved via a temporary ``.rrd``."""

    def __init__(
        self, *, rrd_path: Path | None, spawn: bool, roots: tuple[str, ...], recording_id: str
    ) -> None:
        from rose_logs import rerun_view

        self.view = rerun_view
        self.rrd_path = rrd_path
        self.tmp = None if rrd_path is None else rrd_path.with_name(f".{rrd_path.name}.rose-tmp")
        try:
            self.recording = rerun_view.open_recording(
                rrd_path=self.tmp,
                spawn=spawn,
                application_id="rose_bag",
                recording_id=recording_id,
                entity_roots=roots,
            )
        except (ValueError, OSError, RuntimeError) as err:
            msg = f"{rrd_path}: cannot open the Rerun recording ({err})"
            raise LogWriteError(msg) from err

    def snapshot(
        self, snapshot: MapSnapshot, result: RoseResult, index: int, walls: WallSet | None
    ) -> None:
        self.view.log_snapshot(
            self.recording,
            snapshot,
            result,
            entity_root=entity_root(snapshot.topic),
            snapshot_index=index,
            walls=walls,
        )

    def event(self, snapshot: MapSnapshot, text: str, index: int) -> None:
        self.view.log_break_event(
            self.recording,
            snapshot,
            text,
            entity_root=entity_root(snapshot.topic),
            snapshot_index=index,
        )

    def close(self) -> None:
        self.view.close_recording(self.recording)
        if self.tmp is not None and self.rrd_path is not None:
            self.tmp.replace(self.rrd_path)

    def abort(self) -> None:
        try:
            self.view.close_recording(self.recording)
        except (RuntimeError, OSError):  # the file sink already failed (full disk): drop it
            with contextlib.suppress(RuntimeError, OSError):
                self.recording.disconnect()
        finally:
            if self.tmp is not None:
                self.tmp.unlink(missing_ok=True)
