"""The batch's own error: bad inputs or an unusable output folder (one line, names the culprit)."""

from __future__ import annotations

from rose_logs.errors import LogError

__all__ = ["BatchError"]


class BatchError(LogError):
    """An input does not exist or matches nothing, the output folder is unusable, or bad options."""
