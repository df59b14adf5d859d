"""Log formats: their names, how a file's content tells its format, and what an output name implies.

- ``"ros1"``: ROS 1 bag v2.0 (``.bag``), plain or with bz2 / lz4 chunks;
- ``"db3"``: ROS 2 bag folder with sqlite3 storage, or a bare ``.db3`` file;
- ``"mcap-dir"``: ROS 2 bag folder with MCAP storage;
- ``"mcap"``: a bare MCAP file with the ``ros2`` (CDR) or ``ros1`` profile.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from rose_logs.errors import LogReadError

__all__ = ["FORMATS", "LogFormat", "detect_format", "format_from_path"]

LogFormat = Literal["ros1", "db3", "mcap", "mcap-dir"]
FORMATS: tuple[LogFormat, ...] = ("ros1", "db3", "mcap", "mcap-dir")

_ROS1_MAGIC = b"#ROSBAG V2.0\n"
_MCAP_MAGIC = b"\x89MCAP0\r\n"
_SQLITE_MAGIC = b"SQLite format 3\x00"


def detect_format(path: Path) -> LogFormat:
    """Storage format of ``path`` from its content (magic bytes, ``metadata.yaml``).

    Raises
    ------
    LogReadError
        If ``path`` does not exist, cannot be read or is no supported log.
    """
    path = Path(path)
    if not path.exists():
        msg = f"{path}: no such file or directory"
        raise LogReadError(msg)
    if path.is_dir():
        meta = path / "metadata.yaml"
        if not meta.is_file():
            msg = f"{path}: folder without metadata.yaml, not a ROS 2 bag"
            raise LogReadError(msg)
        try:
            text = meta.read_text(encoding="utf-8")
        except OSError as err:
            msg = f"{meta}: cannot read ({err.strerror})"
            raise LogReadError(msg) from err
        if "storage_identifier: mcap" in text:
            return "mcap-dir"
        return "db3"
    try:
        with path.open("rb") as f:
            head = f.read(16)
    except OSError as err:
        msg = f"{path}: cannot read ({err.strerror})"
        raise LogReadError(msg) from err
    if head.startswith(_ROS1_MAGIC):
        return "ros1"
    if head.startswith(_MCAP_MAGIC):
        return "mcap"
    if head.startswith(_SQLITE_MAGIC):
        return "db3"
    what = "empty file" if not head else "unrecognised header"
    msg = f"{path}: not a ROS 1 bag, ROS 2 bag or MCAP file ({what})"
    raise LogReadError(msg)


def format_from_path(path: Path) -> LogFormat | None:
    """Format implied by an output name: ``.bag`` -> ros1, ``.mcap`` -> mcap, ``.db3`` -> db3, else None."""
    return {".bag": "ros1", ".mcap": "mcap", ".db3": "db3"}.get(Path(path).suffix.lower())  # type: ignore[return-value]
