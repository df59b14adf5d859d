"""The interface every write backend implements."""

from __future__ import annotations

from rose_logs.storage.records import Channel

__all__ = ["WriteBackend"]


class WriteBackend:
    """Storage-specific half of :class:`rose_logs.writer.LogWriter`: open, add connections, write, close."""

    def open(self) -> None: ...
    def add(self, channel: Channel) -> int: ...  # type: ignore[empty-body]
    def write(
        self, handle: int, log_time_ns: int, data: bytes | memoryview, publish_ns: int, seq: int
    ) -> None: ...
    def close(self) -> None: ...
    def abort(self) -> None: ...
