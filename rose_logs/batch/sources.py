"""Finding the recordings of a batch: files, folders, globs, object-store prefixes, lists."""

from __future__ import annotations

import hashlib
import logging
import os
import posixpath
import stat
import sys
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import fsspec

from rose.limits import short
from rose.outputs import (
    BAG_STORAGE_SUFFIXES,
    METADATA_PEEK_BYTES,
    enclosing_bag_folder,
    is_bag_folder,
    is_bag_metadata,
)
from rose_logs.batch.errors import BatchError
from rose_logs.batch.store import expand_user, filesystem, is_local, storage_errors
from rose_logs.formats import ACTIVE_BAG, FORMATS, processed_name

__all__ = [
    "LOG_SUFFIXES",
    "MAX_LIST_BYTES",
    "ListedInput",
    "Recording",
    "cleaned_log_name",
    "discover",
    "distinct_name",
    "printable",
    "read_list",
]

#: File suffixes searched for in folders (a ROS 2 bag folder is one recording). A
#: ``.bag.active`` is a recording ``rosbag record`` never closed: it shows as an error row (naming
#: ``rose-bag process --salvage``) instead of going unnoticed.
LOG_SUFFIXES = (".bag", ".mcap", ".db3", ".bag.active")
_GLOB_CHARS = "*?["
_LOG = logging.getLogger(__name__)


@dataclass(frozen=True, order=True)
class Recording:
    """One recording to process.

    Attributes
    ----------
    uri : str
        Full location: an absolute local path, or an fsspec URL (``s3://bucket/key``). Identifies the
        recording everywhere (tables, resume keys, Rerun recording id).
    name : str
        ``/``-separated name relative to the input it was found under (the input's own base name
        first), used to mirror outputs (``cleaned/<name>``, ``rrd/<name>.rrd``).
    is_dir : bool
        A ROS 2 bag folder (``metadata.yaml`` plus its storage files).
    size : int
        Bytes (all files of a folder).
    version : str
        Modification time in ns (local) or the ETag(s) (object stores): with ``size``, what tells a
        changed recording from the one already processed.
    """

    uri: str
    name: str
    is_dir: bool
    size: int
    version: str


def printable(text: str) -> str:
    """``text`` as valid UTF-8 for tables, reports and ids: a local file name need not be UTF-8
    (Python keeps its undecodable bytes as surrogates, which Parquet, ``uuid5`` and a UTF-8
    terminal refuse); such bytes are written as ``\\xff`` escapes. Other text is unchanged."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    return text


#: Largest ``--from-list`` file read, bytes: millions of lines, and a device such as ``/dev/zero`` is
#: refused instead of read until memory runs out.
MAX_LIST_BYTES = 64 * 1024 * 1024


def read_list(path: str, storage_options: Mapping[str, Any] | None = None) -> list[str]:
    """Inputs listed in a text file (``-``: standard input), one per line; blank lines and ``#``
    comments are skipped.

    Raises
    ------
    BatchError
        If ``path`` is missing, not a regular file, larger than :data:`MAX_LIST_BYTES`, or a URL
        that is not UTF-8 text, of an unknown scheme or whose fsspec backend is not installed (a
        local list may hold local names that are not UTF-8).
    """
    if path == "-":  # find ... | rose-bag batch --from-list - -o OUT
        if sys.stdin is None:  # started with standard input closed (<&-)
            msg = "standard input: closed, no list of inputs to read (--from-list -)"
            raise BatchError(msg)
        data = sys.stdin.buffer.read(MAX_LIST_BYTES + 1)
        if len(data) > MAX_LIST_BYTES:
            msg = f"standard input: the list of inputs is larger than {MAX_LIST_BYTES >> 20} MiB"
            raise BatchError(msg)
        return _entries(data.decode("utf-8", "surrogateescape").splitlines(), "standard input")
    fs, fs_path = filesystem(path, _options(path, storage_options))
    try:
        if is_local(path):
            # stat, not fs.info: a FIFO or device must be refused before open() (which may block).
            status = Path(fs_path).stat()
            regular = stat.S_ISREG(status.st_mode)
            size = status.st_size
        else:
            info = fs.info(fs_path)
            regular = info.get("type") == "file"
            size = int(info.get("size") or 0)
        if not regular:
            msg = f"{path}: the list of inputs is not a regular file"
            raise BatchError(msg)
        if size > MAX_LIST_BYTES:
            msg = f"{path}: the list of inputs is larger than {MAX_LIST_BYTES >> 20} MiB"
            raise BatchError(msg)
        with fs.open(fs_path, "rb") as f:
            data = f.read(MAX_LIST_BYTES + 1)  # bounded even if the file grows meanwhile
        if len(data) > MAX_LIST_BYTES:
            msg = f"{path}: the list of inputs is larger than {MAX_LIST_BYTES >> 20} MiB"
            raise BatchError(msg)
        try:
            # A local list may name local files whose names are not UTF-8 (kept as the OS does).
            errors = "surrogateescape" if is_local(path) else "strict"
            lines = data.decode("utf-8", errors).splitlines()
        except UnicodeDecodeError as err:
            msg = f"{path}: the list of inputs is not UTF-8 text ({err.reason} at byte {err.start})"
            raise BatchError(msg) from err
    except FileNotFoundError as err:
        msg = f"{path}: the list of inputs does not exist"
        raise BatchError(msg) from err
    except OSError as err:
        msg = f"{path}: cannot read the list of inputs ({err.strerror or err})"
        raise BatchError(msg) from err
    return _entries(lines, path)


class ListedInput(str):
    """An input read from a list: the text of its line, and ``where`` it was (``todo.txt line 3``),
    for messages about it."""

    where: str

    def __new__(cls, text: str, where: str) -> ListedInput:
        entry = super().__new__(cls, text)
        entry.where = where
        return entry


def _entries(lines: list[str], source: str) -> list[str]:
    """A list's inputs: blank lines and ``#`` comments skipped. They are checked by discover(), with
    the other inputs: a line naming nothing (a missing file, an unknown URL scheme) stops the whole
    batch before anything runs, never an error row."""
    if lines and lines[0].startswith("\ufeff"):  # a byte-order mark (Windows editors)
        lines = [lines[0][1:], *lines[1:]]
    return [
        ListedInput(text, f"{source} line {number}")
        for number, text in enumerate((line.strip() for line in lines), start=1)
        if text and not text.startswith("#")
    ]


def discover(
    inputs: Sequence[str | Path], *, storage_options: Mapping[str, Any] | None = None
) -> tuple[Recording, ...]:
    """Every recording named by ``inputs``, sorted by URI, each once (local files by real path).

    Parameters
    ----------
    inputs : sequence of str or Path
        Log files (taken as they are, whatever their suffix), folders (searched recursively for
        ``*.bag``, ``*.bag.active``, ``*.mcap``, ``*.db3`` and ROS 2 bag folders; a bag folder is
        one recording), glob patterns (a search, as a folder: the folders they match are
        searched, of the files only logs and a bag's files are taken), and fsspec URLs of any of
        these (``s3://bucket/prefix/``).
    storage_options : mapping, optional
        fsspec options of remote inputs (``endpoint_url``, ``key``, ``secret``, ``anon``...).

    Raises
    ------
    BatchError
        If an input is empty or does not exist, a pattern matches no log file or folder, a URL's
        scheme is unknown or its fsspec backend not installed, or nothing at all is found. Inputs
        read from a list are inputs like any other: a bad line stops the batch before anything runs,
        as a missing file does (an error row is for a recording that exists but cannot be
        processed).
    """
    if isinstance(inputs, str | Path):  # one input, not its characters (as run_batch)
        inputs = [inputs]
    unique: dict[str, Recording] = {}
    problems: list[str] = []  # every input that names nothing, not only the first
    empty: list[str] = []  # folders searched in vain, said when other inputs hold recordings
    for item in inputs:
        try:
            with storage_errors(str(item)):
                expanded = list(_expand(str(item), storage_options))
        except BatchError as err:
            # which line of which list
            problems.append(f"{err} ({item.where})" if isinstance(item, ListedInput) else str(err))
            continue
        if not expanded:
            empty.append(f"{item} ({item.where})" if isinstance(item, ListedInput) else str(item))
        for recording in expanded:
            # One file under two spellings (``a/../a/x.mcap``, a symlink) is one recording: the
            # first spelling names it.
            unique.setdefault(_identity(recording.uri), recording)
    if problems:
        more = len(problems) - 1
        rest = f" (and {more} more: {short('; '.join(problems[1:]), 200)})" if more else ""
        raise BatchError(problems[0] + rest)
    found: dict[str, Recording] = {}
    names: dict[str, str] = {}
    # Complete recordings are named first: a salvaged x.bag.active, not the x.bag beside it, is
    # the one renamed, whatever the order of the inputs.
    for same, recording in sorted(unique.items(), key=lambda kv: _unclosed(kv[1].name)):
        name = recording.name
        # Two recordings with the same relative name, or whose cleaned logs would be one (x.bag and
        # the x.bag.active beside it): keep both, distinguishable.
        if name in names or cleaned_log_name(name) in names:
            name = distinct_name(name, recording)
        names[name] = names[cleaned_log_name(name)] = recording.uri
        found[same] = Recording(
            recording.uri, name, recording.is_dir, recording.size, recording.version
        )
    if not found:
        msg = f"no recording found in {', '.join(str(i) for i in inputs) or 'the inputs'}"
        raise BatchError(msg)
    for item in empty:  # (a folder of the wrong robot, a typo'd date went unnoticed)
        _LOG.warning("%s: no recording found in it", item)
    return tuple(sorted(found.values()))


def _unclosed(name: str) -> bool:
    return name.lower().endswith(ACTIVE_BAG)


def cleaned_log_name(name: str) -> str:
    """Name of a recording's cleaned log: its own, except that a ``.bag.active`` (a recording
    ``rosbag record`` never closed, salvaged) comes out as the complete ``.bag`` it now is."""
    return name[: -len(".active")] if _unclosed(name) else name


def distinct_name(name: str, recording: Recording) -> str:
    """``name`` with a digest of the recording's URI before its suffix (``run-1a2b3c4d.mcap``,
    ``x-1a2b3c4d.bag.active``; after a folder's name)."""
    digest = hashlib.sha256(recording.uri.encode("utf-8", "surrogateescape")).hexdigest()[:8]
    if recording.is_dir:
        return f"{name}-{digest}"
    folder, _, base = name.rpartition("/")
    known = next((s for s in LOG_SUFFIXES[::-1] if base.lower().endswith(s)), "")
    suffix = base[len(base) - len(known) :] if known else ""  # as spelled (.MCAP stays)
    if not suffix and "." in base:
        suffix = base[base.rindex(".") :]
    stem = base[: len(base) - len(suffix)] if suffix else base
    return f"{folder}/{stem}-{digest}{suffix}" if folder else f"{stem}-{digest}{suffix}"


def _identity(uri: str) -> str:
    """What tells two recordings apart: a local file by its inode (symlinks, ``..`` and hard links
    name one file), a local folder by its resolved path, else the URL."""
    if not is_local(uri):
        return uri
    path = os.path.realpath(uri.removeprefix("file://"))
    try:
        status = Path(path).stat()
    except OSError:
        return path
    return path if stat.S_ISDIR(status.st_mode) else f"inode {status.st_dev}:{status.st_ino}"


def _options(uri: str, storage_options: Mapping[str, Any] | None) -> dict[str, Any]:
    return {} if is_local(uri) else dict(storage_options or {})


def _without_dot_dot(path: str) -> str:
    """An absolute local ``path`` without '..': the part up to the last '..' resolved as the kernel
    resolves it (after following links: ``link/..`` is the parent of the link's target), the rest
    as written. A recording's name is its path below the input, the input's own name first:
    '../..' has none, and 'x/../y' put outputs outside cleaned/ and rrd/."""
    parts = path.split("/")
    if ".." not in parts:
        return os.path.normpath(path)  # '.' and doubled slashes only
    last = len(parts) - 1 - parts[::-1].index("..")
    head = os.path.realpath("/".join(parts[: last + 1]) or "/")
    return os.path.normpath("/".join([head, *parts[last + 1 :]]))


def _expand(item: str, storage_options: Mapping[str, Any] | None) -> Iterable[Recording]:
    given = item  # errors name the input as the user wrote it
    if not item:  # as a path, the current folder: discover([os.environ.get("FLEET", "")]) took it
        msg = "an empty input names no file or folder (the current folder is '.')"
        raise BatchError(msg)
    local = is_local(item)
    if local:
        item = _without_dot_dot(str(expand_user(item.removeprefix("file://")).absolute()))
    fs, path = filesystem(item, _options(item, storage_options))
    protocol = None if local else fsspec.utils.get_protocol(item)
    try:
        # A file or folder whose name holds a glob character (``run[1]``) is itself, as a quoted
        # name is to the shell: as a pattern it matched nothing ("matches no file or folder").
        if any(c in path for c in _GLOB_CHARS) and not fs.exists(path):
            matches = sorted(fs.glob(path))
            if not matches:
                msg = f"{given}: matches no file or folder"
                raise BatchError(msg)
            # A pattern is a search, as a folder is: of the files it matches only logs and a
            # bag's files are recordings (a README.md or a .png beside them were error rows). A
            # file named on its own is taken whatever its suffix.
            # Each match asked once whether it is a folder (a request per call on remote storage).
            folders = {m for m in matches if fs.isdir(m)}
            searched = [m for m in matches if m in folders or _searched_file(fs, m, protocol)]
            if not searched:
                msg = (
                    f"{given}: matches no log file or folder, only {len(matches)} other file(s) "
                    f"(first: {posixpath.basename(matches[0])}); name a file on its own to take "
                    "it whatever its suffix"
                )
                raise BatchError(msg)
            # Nor, as in a folder, a recording's process output matched with it (counted twice).
            logs = [m for m in searched if m.lower().endswith(LOG_SUFFIXES) and m not in folders]
            bag_dirs = [m for m in searched if m in folders and _is_bag_dir(fs, m, protocol)]
            theirs = _outputs_left_out(given, bag_dirs, logs)
            base = _glob_base(path)
            for match in searched:
                if match not in theirs:
                    yield from _expand_path(fs, match, protocol, base)
            return
        if not fs.exists(path):
            msg = f"{given}: no such file or folder"
            raise BatchError(msg)
        yield from _expand_path(fs, path, protocol, _parent(path))
    except OSError as err:
        msg = f"{given}: cannot list ({err})"
        raise BatchError(msg) from err


def _parent(path: str) -> str:
    """The folder an input's recordings are named below (the input's own name first). The root
    has no name and no parent: its recordings are named below it (``tmp/run.mcap``), not by their
    absolute paths (``''`` as the base)."""
    if path.startswith("/") and not path.strip("/"):
        return "/"
    return posixpath.dirname(path.rstrip("/"))


def _searched_file(fs: Any, path: str, protocol: str | None) -> bool:
    """Whether a file a pattern matches is one a folder search finds: a file with a log suffix,
    or a file of a ROS 2 bag folder (the bag is the recording). Folders matched are searched."""
    if path.lower().endswith(LOG_SUFFIXES):
        return True
    return _bag_of(fs, path, protocol) is not None


def _glob_base(pattern: str) -> str:
    """The folder above the first path component holding a glob character (``/`` for a
    pattern such as ``/*``, so that names stay relative)."""
    parts = pattern.split("/")
    for i, part in enumerate(parts):
        if any(c in part for c in _GLOB_CHARS):
            return "/".join(parts[:i]) or ("/" if pattern.startswith("/") else "")
    return posixpath.dirname(pattern)


def _expand_path(fs: Any, path: str, protocol: str | None, base: str) -> Iterable[Recording]:
    path = path.rstrip("/") or "/"  # the root stays itself: '' is no folder (os.walk: ENOENT)
    if not fs.isdir(path):
        bag = _bag_of(fs, path, protocol)
        if bag is not None:  # a bag's storage file or metadata: the whole bag is the recording
            folder = bag
            above = base if folder.startswith(base.rstrip("/") + "/") else posixpath.dirname(folder)
            yield _recording(fs, folder, protocol, above, is_dir=True)
            return
        yield _recording(fs, path, protocol, base, is_dir=False)
        return
    if _is_bag_dir(fs, path, protocol):
        yield _recording(fs, path, protocol, base, is_dir=True)
        return
    files = _local_files(path) if protocol is None else sorted(fs.find(path))
    # An earlier batch's OUT found inside a folder: its cleaned logs are no recordings of the fleet
    # (they would be counted twice). Named on their own (OUT/cleaned) they are inputs like others.
    found = set(files)
    outs = [
        posixpath.dirname(f)
        for f in files
        if posixpath.basename(f) == "summary.json"
        and posixpath.join(posixpath.dirname(f), "recordings.parquet") in found
    ]
    for out in outs:  # quietly, as the batch's own OUT (a re-run's OUT is one)
        _LOG.info(
            "%s: the output of an earlier batch; its cleaned logs are not read as recordings",
            out if protocol is None else f"{protocol}://{out}",
        )
    skipped = tuple(posixpath.join(out, "cleaned") + "/" for out in outs)
    files = [f for f in files if not f.startswith(skipped)] if skipped else files
    bag_dirs = sorted(
        folder
        for folder in {
            posixpath.dirname(f) for f in files if posixpath.basename(f) == "metadata.yaml"
        }
        if _is_bag_dir(fs, folder, protocol)
    )
    logs = [
        f
        for f in files
        if f.lower().endswith(LOG_SUFFIXES) and not any(f.startswith(b + "/") for b in bag_dirs)
    ]
    theirs = _outputs_left_out(path if protocol is None else f"{protocol}://{path}", bag_dirs, logs)
    for bag in bag_dirs:
        if bag not in theirs:
            yield _recording(fs, bag, protocol, base, is_dir=True)
    for f in logs:
        if f not in theirs:
            yield _recording(fs, f, protocol, base, is_dir=False)


def _local_files(root: str) -> list[str]:
    """Every file below the local folder ``root``, sorted, following symlinked folders (a fleet's
    day folders linked from other disks) but entering each real folder once, so that a link to a
    folder above it ends no search in a loop. Spelled through the links, as found."""

    def unreadable(err: OSError) -> None:
        if err.filename == root:  # the input itself: nothing to search
            raise err
        # One folder the user may not read (a disk's lost+found) does not stop the fleet's batch.
        _LOG.warning("%s: cannot list (%s), not searched", err.filename, err.strerror or err)

    seen: set[tuple[int, int]] = set()
    files: list[str] = []
    for folder, subfolders, names in os.walk(root, onerror=unreadable, followlinks=True):
        status = Path(folder).stat()
        if (status.st_dev, status.st_ino) in seen:  # reached again through a link
            subfolders.clear()
            continue
        seen.add((status.st_dev, status.st_ino))
        # Real folders before links to them, then by name: the walk's order decides which
        # spelling of a folder reached twice names its recordings.
        subfolders.sort(key=lambda name: (Path(folder, name).is_symlink(), name))
        files.extend(posixpath.join(folder, name) for name in names)
    return sorted(files)


def _outputs_left_out(where: str, bag_dirs: Sequence[str], logs: Sequence[str]) -> set[str]:
    """The bag folders and logs found in ``where`` (a folder, or a pattern) that are process
    outputs of others found with them (:func:`_process_outputs`), said in a warning: they are
    left out."""
    theirs = sorted(_process_outputs([*bag_dirs, *logs], bag_dirs, logs))
    if theirs:
        _LOG.warning(
            "%s: %d recording(s) named as `rose-bag process` names its output of a recording "
            "beside it are not read as recordings (first: %s); name them on their own to include "
            "them",
            where,
            len(theirs),
            theirs[0],
        )
    return set(theirs)


def _process_outputs(
    candidates: Sequence[str], bag_dirs: Sequence[str], logs: Sequence[str]
) -> set[str]:
    """The candidates named as ``rose-bag process`` names its output of a recording found beside
    them (:func:`rose_logs.formats.processed_name`: ``run.rose.mcap`` beside ``run.mcap``):
    processed copies of a recording in the fleet, which would be counted twice. Compared in any
    case, as process reads suffixes."""
    outputs = {
        posixpath.join(
            posixpath.dirname(r), processed_name(posixpath.basename(r), is_dir=d, fmt=fmt)
        ).lower()
        for group, d in ((bag_dirs, True), (logs, False))
        for r in group
        for fmt in (None, *FORMATS)  # process --format names its output by the format
    }
    return {c for c in candidates if c.lower() in outputs}


def _bag_of(fs: Any, path: str, protocol: str | None) -> str | None:
    """The ROS 2 bag folder the file ``path`` belongs to (its ``metadata.yaml``, or a storage file
    the metadata names), else None."""
    folder = posixpath.dirname(path)
    if posixpath.basename(path) == "metadata.yaml":
        return folder if _is_bag_dir(fs, folder, protocol) else None
    if protocol is None:  # locally also along symlinks (rose.outputs)
        bag = enclosing_bag_folder(Path(path))
        return None if bag is None else str(bag)
    if not path.lower().endswith(BAG_STORAGE_SUFFIXES):
        return None
    metadata = posixpath.join(folder, "metadata.yaml")
    if not fs.isfile(metadata):
        return None
    with fs.open(metadata, "rb") as f:
        names = f.read(64 * 1024).decode("utf-8", "replace")
    return folder if posixpath.basename(path) in names else None


def _is_bag_dir(fs: Any, path: str, protocol: str | None) -> bool:
    """Whether the folder ``path`` is a ROS 2 bag, by the test outputs are checked with
    (:func:`rose.outputs.is_bag_folder`): rosbag2's ``metadata.yaml``, or one naming a storage
    file beside it. A data set's own ``metadata.yaml`` makes no bag: its folder is searched as any
    other (taken as one recording, it was an error row, as ``process`` refuses it)."""
    if protocol is None:
        return is_bag_folder(path)
    metadata = posixpath.join(path, "metadata.yaml")
    if not fs.isfile(metadata):
        return False
    with fs.open(metadata, "rb") as f:
        text = f.read(METADATA_PEEK_BYTES).decode("utf-8", "replace")
    return is_bag_metadata(text, [posixpath.basename(p) for p in fs.ls(path, detail=False)])


def _recording(fs: Any, path: str, protocol: str | None, base: str, *, is_dir: bool) -> Recording:
    uri = path if protocol is None else f"{protocol}://{path}"
    name = posixpath.relpath(path, base) if base else path
    try:
        infos = [fs.info(f) for f in sorted(fs.find(path))] if is_dir else [fs.info(path)]
    except OSError:
        if protocol is not None:
            raise
        # A dangling link or a symlink loop (a log with its suffix, or a file of a bag folder):
        # its row says so, the reader naming what is wrong, instead of one moved file stopping
        # the whole fleet's batch.
        return Recording(uri=uri, name=name, is_dir=is_dir, size=0, version="")
    size = sum(int(i.get("size") or 0) for i in infos)
    return Recording(uri=uri, name=name, is_dir=is_dir, size=size, version=_version(infos))


def _version(infos: Sequence[Mapping[str, Any]]) -> str:
    """Modification time (local, ns) or ETag (object stores) of a file, or of a folder's files."""
    parts = []
    for info in infos:
        etag = info.get("ETag") or info.get("etag")
        if etag:
            parts.append(str(etag).strip('"'))
        elif "mtime" in info:
            parts.append(str(round(float(info["mtime"]) * 1e9)))
        else:
            parts.append(str(info.get("LastModified", "")))
    if len(parts) == 1:
        return parts[0]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()
