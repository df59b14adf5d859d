"""Log formats: their names, how a file's content tells its format, and what an output name implies.

- ``"ros1"``: ROS 1 bag v2.0 (``.bag``), plain or with bz2 / lz4 chunks;
- ``"db3"``: ROS 2 bag folder with sqlite3 storage, or a bare ``.db3`` file;
- ``"mcap-dir"``: ROS 2 bag folder with MCAP storage;
- ``"mcap"``: a bare MCAP file with the ``ros2`` (CDR) or ``ros1`` profile.
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import Any, Literal

from rose.limits import MAX_YAML_BYTES, load_yaml, short
from rose.outputs import is_bag_folder
from rose_logs.errors import LogReadError

__all__ = [
    "FORMATS",
    "MCAP_MAGIC",
    "BagMetadata",
    "LogFormat",
    "detect_format",
    "format_from_path",
    "mcap_cut_short",
    "processed_name",
    "read_format",
    "unknown_suffix_warning",
]

LogFormat = Literal["ros1", "db3", "mcap", "mcap-dir"]
FORMATS: tuple[LogFormat, ...] = ("ros1", "db3", "mcap", "mcap-dir")
#: The suffix of an output written in a format (ROS 2 bag folders have none).
_FORMAT_SUFFIX: dict[LogFormat, str] = {"ros1": ".bag", "mcap": ".mcap", "db3": "", "mcap-dir": ""}

_ROS1_MAGIC = b"#ROSBAG V2.0\n"
#: The bytes every MCAP file begins and, complete, ends with.
MCAP_MAGIC = b"\x89MCAP0\r\n"
_SQLITE_MAGIC = b"SQLite format 3\x00"


def mcap_cut_short(path: Path) -> bool:
    """Whether the MCAP file at ``path`` is cut short: it lacks the magic bytes that end every
    complete MCAP file (as they begin it), as a recording cut off by a crash or a full disk, or a
    copy that stopped, does. A file that cannot be read is not said to be."""
    try:
        with Path(path).open("rb") as f:
            size = f.seek(0, os.SEEK_END)
            if size < 2 * len(MCAP_MAGIC):  # not even room for both
                return True
            f.seek(size - len(MCAP_MAGIC))
            return f.read(len(MCAP_MAGIC)) != MCAP_MAGIC
    except OSError:
        return False


@dataclass(frozen=True)
class BagMetadata:
    """A ROS 2 bag folder's ``metadata.yaml`` as :func:`read_format` read and checked it, for every
    later use of it (the reader's checks, its storage files, ``custom_data``): parsing it is slow
    (a 3,000-topic bag's 0.8 MB: seconds), and read again it could be another file's."""

    data: bytes  # the file's bytes (at most :data:`~rose.limits.MAX_YAML_BYTES`)
    information: dict[str, Any]  # its ``rosbag2_bagfile_information``, parsed within the limits


def detect_format(path: Path) -> LogFormat:
    """Storage format of ``path`` from its content (magic bytes, ``metadata.yaml``).

    Raises
    ------
    LogReadError
        If ``path`` does not exist, cannot be read or is no supported log.
    """
    return read_format(path)[0]


def read_format(path: Path) -> tuple[LogFormat, BagMetadata | None]:
    """:func:`detect_format`'s format, and for a ROS 2 bag folder its ``metadata.yaml`` as read
    for it (None for a file): pass it on rather than read the file again.

    Raises
    ------
    LogReadError
        If ``path`` does not exist, cannot be read or is no supported log.
    """
    path = Path(path)
    mode = _mode(path)
    if stat.S_ISDIR(mode):
        return _folder_format(path)
    if not stat.S_ISREG(mode):
        msg = f"{path}: not a regular file (a FIFO, device or socket cannot be read as a log)"
        raise LogReadError(msg)
    try:
        with path.open("rb") as f:
            head = f.read(16)
    except OSError as err:
        msg = f"{path}: cannot read ({err.strerror})"
        raise LogReadError(msg) from err
    if head.startswith(_ROS1_MAGIC):
        return "ros1", None
    if head.startswith(MCAP_MAGIC):
        return "mcap", None
    if head.startswith(_SQLITE_MAGIC):
        return "db3", None
    what = "empty file" if not head else "unrecognised header"
    msg = f"{path}: not a ROS 1 bag, ROS 2 bag or MCAP file ({what})"
    carmen_words = (b"FLASER", b"ODOM", b"PARAM", b"ROBOTLASER", b"RAWLASER", b"TRUEPOS")
    if path.name.lower().endswith((".log", ".log.gz", ".clf", ".clf.gz")) or head.lstrip(
        b"\xef\xbb\xbf \t\r\n"
    ).startswith(carmen_words):
        msg += "; a CARMEN laser log becomes a session with 'rose-bag convert'"
    elif path.name == "metadata.yaml" and is_bag_folder(path.parent):
        msg += f"; a ROS 2 bag's metadata: give its folder, {path.parent}"
    elif path.name == "metadata.yaml":  # a data set's own: its folder is no bag either
        msg += "; nor a ROS 2 bag's metadata (no rosbag2_bagfile_information)"
    raise LogReadError(msg)


def _mode(path: Path) -> int:
    try:
        return path.stat().st_mode
    except FileNotFoundError as err:
        msg = f"{short(path, 200)}: no such file or directory"
        raise LogReadError(msg) from err
    except OSError as err:
        msg = f"{short(path, 200)}: cannot read ({err.strerror or err})"
        raise LogReadError(msg) from err


def _folder_format(path: Path) -> tuple[LogFormat, BagMetadata]:
    """A ROS 2 bag folder: every entry a regular file, ``metadata.yaml`` within the YAML limits."""
    meta = path / "metadata.yaml"
    try:
        entries = list(os.scandir(path))
    except OSError as err:
        msg = f"{path}: cannot list the folder ({err.strerror or err})"
        raise LogReadError(msg) from err
    if not any(e.name == "metadata.yaml" for e in entries):
        msg = f"{path}: folder without metadata.yaml, not a ROS 2 bag"
        raise LogReadError(msg)
    for entry in entries:
        if not entry.is_dir() and not entry.is_file():
            _mode(Path(entry.path))  # a dangling link: "no such file or directory"
            msg = f"{entry.path}: not a regular file (a FIFO, device or socket in a bag folder)"
            raise LogReadError(msg)
    if not meta.is_file():
        msg = f"{meta}: not a regular file"
        raise LogReadError(msg)
    try:
        with meta.open("rb") as file:
            text = file.read(MAX_YAML_BYTES + 1)
    except OSError as err:
        msg = f"{meta}: cannot read ({err.strerror or err})"
        raise LogReadError(msg) from err
    try:
        parsed = load_yaml(text)  # refuses alias bombs and deep nesting before rosbags parses it
    except ValueError as err:
        msg = f"{meta}: {err}"
        raise LogReadError(msg) from err
    info = parsed.get("rosbag2_bagfile_information") if isinstance(parsed, dict) else None
    if not isinstance(info, dict):
        msg = f"{meta}: no rosbag2_bagfile_information mapping, not a ROS 2 bag"
        raise LogReadError(msg)
    problem = _metadata_field_problem(info)
    if problem is not None:  # else rosbags' own words: "'>' not supported between 'str' and 'int'"
        msg = f"{meta}: {problem}"
        raise LogReadError(msg)
    # rosbags reads every entry (by its file name): one listed twice would be read twice over.
    names = [PurePath(f).name for f in info.get("relative_file_paths") or ()]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        msg = f"{path}: metadata.yaml lists the storage file {twice[0]} more than once"
        raise LogReadError(msg)
    fmt: LogFormat = "mcap-dir" if info.get("storage_identifier") == "mcap" else "db3"
    return fmt, BagMetadata(text, info)


#: Fields of ``rosbag2_bagfile_information`` that rosbags computes with, and their YAML types.
_METADATA_FIELDS: tuple[tuple[tuple[str, ...], type, str], ...] = (
    (("version",), int, "an integer"),
    (("storage_identifier",), str, "a name"),
    (("relative_file_paths",), list, "a list of file names"),
    (("starting_time", "nanoseconds_since_epoch"), int, "an integer"),
    (("duration", "nanoseconds"), int, "an integer"),
    (("message_count",), int, "an integer"),
    (("topics_with_message_count",), list, "a list"),
)


def _metadata_field_problem(info: dict[str, object]) -> str | None:
    """The first field of a ``metadata.yaml`` that is present with a type rosbags cannot use, in
    words (a string where a number belongs); None when all are usable or absent (absent ones
    are rosbags' to refuse)."""
    for keys, kind, words in _METADATA_FIELDS:
        value: object = info
        for key in keys:
            value = value.get(key) if isinstance(value, dict) else None
        if value is None:
            continue
        if not isinstance(value, kind) or isinstance(value, bool):
            return f"{'.'.join(keys)} should be {words}, not {short(repr(value), 60)}"
    files = info.get("relative_file_paths")
    if isinstance(files, list) and not all(isinstance(f, str) for f in files):
        return "relative_file_paths should be a list of file names"
    return None


def format_from_path(path: Path) -> LogFormat | None:
    """Format implied by an output name: ``.bag`` -> ros1, ``.mcap`` -> mcap, ``.db3`` -> db3, else None."""
    return {".bag": "ros1", ".mcap": "mcap", ".db3": "db3"}.get(Path(path).suffix.lower())  # type: ignore[return-value]


def unknown_suffix_warning(path: Path, written_as: str) -> str | None:
    """A warning line for an output name whose suffix names no log format (``out.txt``, the typo
    ``out.mcpa``), saying what is written instead; None for no suffix (a ROS 2 bag folder's usual
    name), a known one, or ``.rose`` (``process``'s own name for a bag folder: ``run.rose``)."""
    suffix = Path(path).suffix
    if not suffix or suffix == ".rose" or format_from_path(Path(path)) is not None:
        return None
    return (
        f"warning: {path}: '{suffix}' names no log format (.bag, .db3, .mcap): written "
        f"{written_as} (--format to choose)"
    )


def suffix_mismatch_warning(path: Path, fmt: str) -> str | None:
    """A warning line for an output written in ``fmt`` (``--format``) under a name whose suffix
    names another format (``--format ros1 -o out.mcap``: a ROS 1 bag that tools would open as
    MCAP), or a file format under a suffix that names none (``--format mcap -o out.mcpa``, a typo);
    None when the suffix agrees, or a bag folder has none of a file's (``.rose``, a date)."""
    implied = format_from_path(Path(path))
    suffix = Path(path).suffix
    wanted = _FILE_FORMATS.get(fmt)
    if implied is None and suffix and wanted is not None and suffix != wanted:
        return (
            f"warning: {path}: written as {fmt} (--format), but '{suffix}' names no log format "
            f"(tools look for {wanted})"
        )
    if implied is None or implied == fmt:
        return None
    return f"warning: {path}: written as {fmt} (--format), but '{suffix}' names {implied}"


#: Formats written as one file, and their suffix (the others are ROS 2 bag folders).
_FILE_FORMATS = {"ros1": ".bag", "mcap": ".mcap"}


#: The suffix ``rosbag record`` gives a bag while it records (left so when it is killed).
ACTIVE_BAG = ".bag.active"


def processed_name(name: str, *, is_dir: bool, fmt: LogFormat | None = None) -> str:
    """The name ``rose-bag process`` gives its output of the recording ``name`` by default:
    ``run.mcap`` -> ``run.rose.mcap``, ``run.bag`` (or ``run.bag.active``) -> ``run.rose.bag``, a bag
    folder ``run`` or a bare ``run.db3`` -> ``run.rose`` (a ROS 2 bag folder). With an output format
    ``fmt`` (``--format``) the suffix is that format's: ``run.bag`` as ``mcap`` -> ``run.rose.mcap``,
    as ``db3`` or ``mcap-dir`` -> the folder ``run.rose``."""
    lower = name.lower()
    if is_dir or lower.endswith(".db3"):
        stem = name[: -len(".db3")] if not is_dir else name
        own = ""
    elif lower.endswith(ACTIVE_BAG):  # a recording rosbag never closed
        stem, own = name[: -len(ACTIVE_BAG)], ".bag"
    else:
        before, dot, suffix = name.rpartition(".")
        stem, own = (before, f".{suffix}") if dot and before else (name, "")
    if fmt is not None:
        own = _FORMAT_SUFFIX[fmt]
    return f"{stem}.rose{own}"
