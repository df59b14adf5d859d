"""The output files of one run: checked, staged under temporary names, committed together or not at all.

Every command of ``rose`` and ``rose-bag`` writes its outputs through one :class:`OutputSet`:

- **checks** (:meth:`OutputSet.stage`, before anything is computed): an output may not be, contain or lie
  inside any input (compared resolved, and by inode when both exist; a map's image counts as an input),
  nor another output of the same run; an existing output needs ``force``; a file output never replaces
  a directory, and a folder output (a ROS 2 bag) replaces an existing directory only if that directory
  is a ROS 2 bag itself (``metadata.yaml`` and no sub-folder), so ``-o SOME_DIR --force`` never deletes
  an unrelated folder; an existing *empty* folder holds nothing to overwrite, and a folder output
  fills it without ``force``; the current folder, or one that holds it, is never replaced.
- **staging**: each output is written inside its own hidden folder next to the target,
  ``.NAME.rose-tmp-<tag>-<pid>-<random>/NAME`` (:func:`process_tag`), unique per run (two concurrent runs never share a temporary);
  an output given as ``-``, or an existing non-regular target such as ``/dev/stdout``, ``/dev/null`` or
  a FIFO, is a *stream*: its bytes are kept in memory and written to it at commit (before any file is
  placed: a stream that fails leaves no file), never by rename. A
  symlink to a regular file is followed: its target is replaced and the link kept.
- **commit** (:meth:`OutputSet.commit`): existing targets (``force``) are moved aside, every staged output
  is renamed into place, then the old ones are deleted; if any rename fails, the new ones are removed and
  the old ones restored. Without ``force`` a file is linked into place (``os.link``, which never
  replaces), so of two concurrent runs one wins and the other fails cleanly.
- **abort** (:meth:`OutputSet.abort`, also on any exception inside ``with``): every staging folder is
  removed and the targets are left as they were.
- **stale temporaries**: staging any output removes the ``.*.rose-tmp-*`` / ``.*.rose-old-*`` entries
  of its directory left by runs that are gone (a run killed with SIGKILL or a power cut): at once
  for a dead process of this host and PID namespace, after a day unchanged for others
  (:func:`left_behind`).

Signals are :mod:`rose.signals`' (:func:`rose.signals.install_signal_handlers` turns SIGTERM and SIGHUP
into a ``KeyboardInterrupt``, so the same clean-up runs as for Ctrl-C), standard output
:mod:`rose.console`'s. :func:`json_text` is the one JSON encoder: strict JSON, every non-finite float
written as ``null``.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import math
import os
import re
import secrets
import select
import shutil
import socket
import stat
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextvars import ContextVar
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO, Self

from rose.errors import OutputError, StdoutError
from rose.limits import short
from rose.signals import signals_deferred

__all__ = [
    "BAG_STORAGE_SUFFIXES",
    "METADATA_PEEK_BYTES",
    "STDOUT",
    "OutputSet",
    "StagedOutput",
    "committed_outputs",
    "counted",
    "is_bag_folder",
    "is_bag_metadata",
    "is_stream",
    "json_safe",
    "json_text",
    "left_behind",
    "newest_change",
    "outputs_named",
    "process_alive",
    "process_tag",
    "refuse_closed_stdout",
    "refuse_output_in_bag_folder",
    "remove_stale_temporaries",
    "suffix_warning",
    "temporary_name",
]

STDOUT = "-"
"""The output name meaning standard output."""

#: A temporary of this version: ``.NAME.rose-<kind>-<process tag>-<pid>-<random>``.
_TEMP_RE = re.compile(r"^\..+\.rose-(?:tmp|old)-(?P<tag>[A-Za-z0-9._]+)-(?P<pid>\d+)-[0-9a-f]+$")
#: Seconds without a change after which any temporary goes, whoever made it (see
#: :func:`left_behind`).
STALE_IDLE_S = 24 * 3600.0
#: Longest :func:`process_tag`: 24 characters of host name, 8 of boot, ``_pidns`` and 10 digits.
_MAX_TAG_CHARS = 24 + 1 + 8 + 6 + 10
#: Longest output name, bytes: its temporary ``.NAME.rose-tmp-<tag>-<pid>-<8 hex>`` (pids up to
#: 2**22, seven digits) must stay within the 255 bytes most file systems allow.
_MAX_OUTPUT_NAME_BYTES = 255 - (len(".") + len(".rose-tmp-") + _MAX_TAG_CHARS + 1 + 7 + 1 + 8)
#: Whether os.access can ask with the effective user and group ids (faccessat's AT_EACCESS).
_EFFECTIVE_IDS = os.access in os.supports_effective_ids
#: The outputs committed inside :func:`committed_outputs` (None outside it).
_COMMITTED: ContextVar[list[Path] | None] = ContextVar("rose_committed_outputs", default=None)
#: A temporary of rose-bag 0.1 before the process tags: ``.NAME.rose-<kind>-<pid>-<random>``.
_OLD_TEMP_RE = re.compile(r"^\..+\.rose-(?:tmp|old)-\d+-[0-9a-f]+$")


# -- text ---------------------------------------------------------------------------------------------
@contextlib.contextmanager
def committed_outputs() -> Iterator[list[Path]]:
    """While the block runs, collect the outputs every :class:`OutputSet` commits, as the user
    named them (standard output left out). The commands print their summary after their files
    stand: a summary that cannot be written (``> /dev/full``) is an error whose line names these
    as complete (it read as if nothing had been written)."""
    committed: list[Path] = []
    token = _COMMITTED.set(committed)
    try:
        yield committed
    finally:
        _COMMITTED.reset(token)


def outputs_named(paths: list[Path], most: int = 4) -> str:
    """``a.yaml, a.pgm``: the first ``most`` of ``paths`` and how many more (a batch writes
    thousands), for a line that says what became of a run's outputs."""
    names = ", ".join(str(path) for path in paths[:most])
    return names + (f" and {len(paths) - most} more" if len(paths) > most else "")


def counted(n: int, noun: str) -> str:
    """``n`` and ``noun``, plural but for one: ``1 scan``, ``0 scans``, ``2 map snapshots``."""
    return f"{n} {noun}" + ("" if n == 1 else "s")


# -- strict JSON ------------------------------------------------------------------------------------
def json_safe(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None and numpy scalars / arrays made plain.

    Dict keys become strings; tuples and sets become lists (sets sorted).
    """
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, bool | int | str) or value is None:
        return value
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, set | frozenset):
        return [json_safe(v) for v in sorted(value)]
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    tolist = getattr(value, "tolist", None)  # numpy scalars and arrays
    if tolist is not None:
        return json_safe(tolist())
    if isinstance(value, int | float):
        return json_safe(float(value))
    msg = f"cannot write {type(value).__name__} as JSON"
    raise TypeError(msg)


def json_text(payload: Any, *, indent: int | None = 2) -> str:
    """``payload`` as strict JSON (RFC 8259: no NaN / Infinity; those become ``null``), newline-ended."""
    return json.dumps(json_safe(payload), indent=indent, allow_nan=False) + "\n"


def _twice(path: Path, other: Path) -> str:
    """The error for one file given for two outputs (``--rrd x --json x`` read "x: used for two
    outputs (also x)")."""
    if str(path) == str(other):
        return f"{path}: given for two outputs (each needs a file of its own)"
    return f"{path}: used for two outputs (also as {other})"


# -- temporary names ------------------------------------------------------------------------------------
def temporary_name(name: str, kind: str = "tmp") -> str:
    """``.NAME.rose-<kind>-<process tag>-<pid>-<random>``: hidden, unique per run, recognisable by
    a later run (:func:`process_tag`)."""
    return f".{name}.rose-{kind}-{process_tag()}-{os.getpid()}-{secrets.token_hex(4)}"


def process_tag() -> str:
    """Where this process's pid means something: the host's name (its first 24 characters), its
    boot and, on Linux, its PID namespace (letters, digits, dots and underscores, at most
    :data:`_MAX_TAG_CHARS`). A pid of another tag cannot be checked from here: a run in another
    container or on another host over a shared folder is not "dead" for being absent from this
    host's process table. The boot tells hosts of one name apart (every host's first PID
    namespace has the same number), and a pid of before a reboot from today's."""
    host = re.sub(r"[^A-Za-z0-9.]", "_", socket.gethostname())[:24] or "host"
    try:
        boot = Path("/proc/sys/kernel/random/boot_id").read_text(encoding="ascii").strip()
        namespace = Path("/proc/self/ns/pid").stat().st_ino
    except OSError:  # not Linux
        return host
    return f"{host}_{hashlib.sha256(boot.encode()).hexdigest()[:8]}_pidns{namespace}"


def process_alive(pid: int) -> bool:
    """Whether process ``pid`` of this host exists (one of another user's counts)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # EPERM: it exists, owned by someone else
        return True
    return True


def newest_change(path: Path) -> float:
    """The latest modification time of ``path`` and, for a folder, everything in it (seconds
    since the epoch; 0 when none can be read)."""
    newest = 0.0
    for item in (path, *path.rglob("*")) if path.is_dir() else (path,):
        with contextlib.suppress(OSError):
            newest = max(newest, item.lstat().st_mtime)
    return newest


def left_behind(path: Path, tag: str | None, pid: int | None, *, dead_idle_s: float = 0.0) -> bool:
    """Whether the temporary ``path``, made by process ``pid`` under :func:`process_tag` ``tag``
    (None: unknown, an older version's name), was left behind by a run that is gone.

    Gone: a process of this tag that no longer exists, its temporary unchanged for
    ``dead_idle_s``; or, made under another tag (whose pids cannot be checked from here), unchanged
    for :data:`STALE_IDLE_S` (a day). A live process's temporary of this tag never is.
    """
    if tag == process_tag() and pid is not None:
        if process_alive(pid):
            return False
        return dead_idle_s <= 0 or time.time() - newest_change(path) >= dead_idle_s
    return time.time() - newest_change(path) >= STALE_IDLE_S


def remove_stale_temporaries(directory: Path) -> list[Path]:
    """Remove the temporaries (:func:`temporary_name`) in ``directory`` left behind by runs that
    are gone (:func:`left_behind`); an older version's (``.NAME.rose-tmp-<pid>-<random>``) only
    after a day unchanged.

    Returns the removed paths. Unreadable directories and entries that vanish meanwhile are ignored.
    """
    removed: list[Path] = []
    try:
        entries = list(os.scandir(directory))
    except OSError:
        return removed
    for entry in entries:
        path = Path(entry.path)
        match = _TEMP_RE.match(entry.name)
        if match is not None:
            gone = left_behind(path, match["tag"], int(match["pid"]))
        elif _OLD_TEMP_RE.match(entry.name):
            gone = left_behind(path, None, None)
        else:
            continue
        if not gone:
            continue
        _remove_tree(path)
        if not os.path.lexists(path):
            removed.append(path)
    return removed


def _remove_tree(path: Path) -> None:
    with contextlib.suppress(OSError):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()


# -- one output ------------------------------------------------------------------------------------------
@dataclass
class StagedOutput:
    """One output of an :class:`OutputSet`.

    Attributes
    ----------
    path : Path
        The name the user gave.
    target : Path
        Where the output goes (``path`` with symlinks to regular files followed).
    temp : Path or None
        Where to write it now (inside ``stage``); None for a stream.
    stage : Path or None
        The hidden staging folder holding ``temp``.
    directory : bool
        The output is a folder (ROS 2 bag).
    stream : bool
        Written in place at commit (``-``, ``/dev/stdout``, a FIFO, a device); the bytes are in ``data``.
    """

    path: Path
    target: Path
    temp: Path | None
    stage: Path | None
    directory: bool
    stream: bool
    data: bytearray | None = None
    to_stdout: bool = False


def _write_all(stream: BinaryIO, data: bytes | bytearray) -> None:
    """Write all of ``data``. An unbuffered stream (``python -u``, ``PYTHONUNBUFFERED``) takes part
    of it when a pipe's reader leaves mid-write and reports the count, not an error (``--json - |
    head`` ended with exit 0 and the report cut): the next write raises ``BrokenPipeError``. A
    non-blocking one that can take nothing now (None) is waited for."""
    view = memoryview(data)
    while view:
        written = stream.write(view)
        if written is None:
            select.select([], [stream], [])
            continue
        if written == 0:  # no progress and no error: looping would never end
            raise OSError(errno.EIO, "the stream takes no more data")
        view = view[written:]


def refuse_closed_stdout(path: Path | str = STDOUT) -> None:
    """Raise :class:`StdoutError` if ``path`` is ``-`` (by default: what a command prints) and the
    process has no standard output (started with it closed, ``>&-``: Python's ``sys.stdout`` is
    None), before any work: writing an output at commit was an AttributeError traceback, and
    what a command prints was lost with exit 0. Both command-line tools call it first: every
    command prints its result, or a summary of the files it wrote."""
    if str(path) == STDOUT and sys.stdout is None:
        raise StdoutError("it is closed")


def _write_stdout(data: bytes | bytearray) -> None:
    """Write ``data`` to standard output: to its binary buffer, or, when a text stream without one
    stands in its place (``io.StringIO``, from a caller in Python), as UTF-8 text (a report is;
    anything else is a :class:`StdoutError`, not an AttributeError traceback after the work)."""
    sys.stdout.flush()
    buffer = getattr(sys.stdout, "buffer", None)
    if buffer is None:
        try:
            text = bytes(data).decode("utf-8")
        except UnicodeDecodeError:
            raise StdoutError("it takes text, and this output is binary") from None
        sys.stdout.write(text)
        sys.stdout.flush()
        return
    _write_all(buffer, data)
    buffer.flush()


def _is_stdout(path: Path) -> bool:
    if str(path) == STDOUT:
        return True
    try:
        return os.path.samestat(path.stat(), os.fstat(sys.stdout.fileno()))
    except (OSError, ValueError, AttributeError):
        return False


def is_stream(path: Path | str) -> bool:
    """Whether an output ``path`` is written as a stream, not a file: ``-`` (standard output) or
    an existing device or FIFO (``/dev/stdout``, ``/dev/null``, a named pipe)."""
    if str(path) == STDOUT:
        return True
    path = Path(path)
    return _is_stdout(path) or (path.exists() and not _is_regular_or_dir(path))


def suffix_warning(
    path: Path | str | None, suffix: str | tuple[str, ...], content: str
) -> str | None:
    """A warning line for a file output whose name lacks the suffix of what it holds (``--rrd
    run.txt``, which ``rerun`` will not open; ``--json report.rrd``), naming ``content`` ("a JSON
    report") and the ``suffix`` expected (".json", or one of several; any case); None for no
    output, standard output, a device or FIFO (streams keep their names), or an expected suffix."""
    if path is None or is_stream(path):
        return None
    path = Path(path)
    expected = (suffix,) if isinstance(suffix, str) else suffix
    found = path.suffix
    if found.lower() in expected:
        return None
    named = f"a '{found}' name" if found else "a name without a suffix"
    return f"warning: {path}: {content} written under {named} (expected {' or '.join(expected)})"


def _no_folder(path: Path | str, parent: Path) -> str:
    """The error for an output whose folder is not one: missing, or a file (a path such as
    ``notes.txt/out.mcap`` said the folder did not exist)."""
    if parent.exists():
        return f"{path}: {parent} is a file, not a folder"
    # A missing folder under a file (`evaluate run.mcap/a/report`) is not one to make: the file
    # is the problem, not the folder.
    above = next((p for p in parent.parents if os.path.lexists(p)), None)
    if above is not None and above.exists() and not above.is_dir():
        return f"{path}: {above} is a file, not a folder"
    return f"{path}: folder {parent} does not exist"


def _conflict(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` (resolved) are the same path, or one lies inside the other (a hard
    link to a file of folder ``b`` too: a bag folder's storage file linked from elsewhere)."""
    if a == b or a in b.parents or b in a.parents:
        return True
    try:
        if a.samefile(b):
            return True
        if b.is_dir() and a.is_file() and a.stat().st_nlink > 1:
            return any(e.is_file() and a.samefile(e.path) for e in os.scandir(b))
    except OSError:
        return False
    return False


def _bag_folder_extras(path: Path) -> list[str] | None:
    """What a ROS 2 bag folder holds besides ``metadata.yaml`` and the files it names (with
    SQLite's ``-wal`` / ``-shm`` / ``-journal`` beside a ``.db3``): notes, another log written into
    the folder, sub-folders, which replacing the bag would delete. None: not a bag folder."""
    try:
        entries = list(os.scandir(path))
        metadata = _metadata_text(Path(path))
    except OSError:
        return None
    # A bag by is_bag_folder's test: another tool's metadata.yaml lists its own files (a data
    # set's), which `-o DIR --force` then deleted as the bag's.
    if metadata is None or not is_bag_metadata(metadata, [e.name for e in entries]):
        return None
    extras = []
    for entry in entries:
        stored = re.sub(r"-(wal|shm|journal)$", "", entry.name)
        if entry.name != "metadata.yaml" and (
            entry.is_dir(follow_symlinks=False) or stored not in metadata
        ):
            extras.append(entry.name)
    return sorted(extras)


#: A ROS 2 bag's storage files, also compressed whole (rosbag2's file compression: ``.mcap.zstd``).
BAG_STORAGE_SUFFIXES = (".db3", ".mcap", ".db3.zstd", ".mcap.zstd")
#: Bytes of a ``metadata.yaml`` read to find a storage file's name (rosbag2 writes a few KB).
METADATA_PEEK_BYTES = 1 << 20


def _metadata_text(folder: Path) -> str | None:
    """The first MiB of ``folder``'s ``metadata.yaml`` as text; None when it has no such regular
    file. Opened without blocking and checked before reading: a FIFO named so (in a folder an
    output would replace, beside an input's storage file) hung the command for ever.

    Raises
    ------
    OSError
        If the file is there but cannot be read.
    """
    try:
        # (Windows has no O_NONBLOCK, and no FIFOs to block on.)
        fd = os.open(folder / "metadata.yaml", os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except (FileNotFoundError, NotADirectoryError):  # no such file, or ``folder`` is a file
        return None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        return f.read(METADATA_PEEK_BYTES).decode("utf-8", "replace")


def enclosing_bag_folder(path: Path) -> Path | None:
    """The ROS 2 bag folder a storage file belongs to, else None: an absolute folder whose
    ``metadata.yaml`` names the file (:data:`BAG_STORAGE_SUFFIXES`; also for a symlink's target).

    Reading ``bag/bag.db3`` alone is fine, but every file of the bag is the input: an output in
    that folder would overwrite its metadata or nest a bag inside it. A folder that merely holds
    some other ``metadata.yaml`` is no bag.
    """
    path = Path(path)
    if not path.name.lower().endswith(BAG_STORAGE_SUFFIXES) or not path.is_file():
        return None
    for candidate in _link_chain(path):
        try:
            names = _metadata_text(candidate.parent)
        except OSError:
            continue
        if names is not None and candidate.name in names:
            return candidate.parent
    return None


def is_bag_folder(folder: Path | str) -> bool:
    """Whether ``folder`` is a ROS 2 bag folder: it holds a ``metadata.yaml`` that is rosbag2's
    (``rosbag2_bagfile_information`` in its first MiB), or one that names a ``.db3`` / ``.mcap``
    storage file beside it (a bag whose metadata is damaged; :func:`enclosing_bag_folder`'s
    test). A folder whose ``metadata.yaml`` is another tool's (a data set's description, a web
    site's) is no recording."""
    folder = Path(folder)
    try:
        metadata = _metadata_text(folder)
        if metadata is None:
            return False
        if "rosbag2_bagfile_information" in metadata:  # (no listing needed)
            return True
        return is_bag_metadata(metadata, [e.name for e in os.scandir(folder)])
    except OSError:  # unreadable: taken as a bag
        return True


def is_bag_metadata(metadata: str, names: Iterable[str]) -> bool:
    """Whether ``metadata`` (a folder's ``metadata.yaml``, its first MiB) makes the folder holding
    the entries ``names`` a ROS 2 bag: rosbag2's own, or one naming a storage file
    (:data:`BAG_STORAGE_SUFFIXES`) among them (a bag whose metadata is damaged)."""
    return "rosbag2_bagfile_information" in metadata or any(
        name.lower().endswith(BAG_STORAGE_SUFFIXES) and name in metadata for name in names
    )


def refuse_output_in_bag_folder(
    path: Path | str | None,
    option: str = "-o",
    *,
    what: str = "output log",
    inputs: Iterable[Path | str] = (),
) -> None:
    """Raise :class:`OutputError` if the output ``path`` (a log, a Rerun recording, a report, a
    map: ``what`` says which) would be written inside an existing ROS 2 bag folder
    (:func:`is_bag_folder`; a symlink counts where it points). A bag folder is one recording: a
    storage file its ``metadata.yaml`` does not list is warned of by every later read of the bag,
    and any file put there goes wherever the bag goes, and with it (``-o bag --force`` replaces
    the whole folder). Replacing a bag folder itself (``-o bag --format db3 --force``) is not
    this: that is the output's own folder. ``option`` names the argument in the message. A bag
    folder that is or holds one of ``inputs`` is left to :class:`OutputSet`, which says "inside
    the input". A folder that does not exist yet counts as the one it would be made in (``evaluate
    bag/new/report`` makes ``bag/new``)."""
    if path is None or _is_stdout(Path(path)):
        return
    try:
        folder = Path(path).resolve().parent
        while not folder.exists() and folder != folder.parent:
            folder = folder.parent
    except (OSError, RuntimeError):  # the output checks say what is wrong with such a path
        return
    if is_bag_folder(folder) and not any(_holds_input(folder, Path(i)) for i in inputs):
        msg = (
            f"{path}: the {what} is inside the ROS 2 bag folder {folder} (it has "
            f"metadata.yaml): it would write into a recording; choose another {option}"
        )
        raise OutputError(msg)


def _holds_input(folder: Path, given: Path) -> bool:
    """Whether the (resolved) ``folder`` is the input ``given`` or holds it."""
    try:
        resolved = given.resolve()
    except (OSError, RuntimeError):
        return False
    return resolved == folder or folder in resolved.parents


def _link_chain(path: Path) -> list[Path]:
    """``path`` (absolute), every symlink hop after it, and the resolved file."""
    chain = [path.absolute()]
    for _ in range(40):  # the kernel's own limit on nested links
        if not chain[-1].is_symlink():
            break
        chain.append((chain[-1].parent / chain[-1].readlink()).absolute())
    chain.append(path.resolve())
    return chain


class OutputSet:
    """The outputs of one run, committed together (see the module docstring).

    Parameters
    ----------
    inputs : iterable of Path
        Files and folders the run reads; no output may touch them.
    force : bool, default False
        Replace existing outputs (only at commit, only by complete new ones).
    ends_run : bool, default False
        These are a command's outputs, and committing them ends its work: a signal during the
        commit's clean-up is dropped (a finished run is not "interrupted"). Otherwise it is raised
        once the outputs stand (a library caller, e.g. a loop over recordings, gets its Ctrl-C).
    clean_stale : bool, default True
        Remove temporaries of dead processes from the outputs' folders when staging. False for a
        folder that processes on other hosts write too (a batch's OUT on a shared file system):
        their temporaries cannot be judged by this host's process ids.

    Examples
    --------
    >>> with OutputSet(inputs=[src], force=False) as outputs:  # doctest: +SKIP
    ...     outputs.write_bytes(Path("a.json"), b"{}")
    ...     temp = outputs.stage(Path("b.mcap")).temp  # write the log there
    ... # both renamed into place here, or neither on an exception
    """

    def __init__(
        self,
        *,
        inputs: Iterable[Path | str] = (),
        force: bool = False,
        ends_run: bool = False,
        clean_stale: bool = True,
    ) -> None:
        self.force = force
        self.ends_run = ends_run
        self.clean_stale = clean_stale
        self._inputs: list[tuple[Path, Path]] = []
        self._outputs: list[StagedOutput] = []
        # Placed over an empty folder, with that folder's status (see commit).
        self._emptied: list[tuple[StagedOutput, os.stat_result]] = []
        # Folder outputs over a folder empty when staged: nothing there for --force to replace.
        self._empty_when_staged: set[Path] = set()
        # What each folder output's ``replaceable`` was, to check the folder again at commit.
        self._replaceable: dict[Path, Callable[[Path], bool] | None] = {}
        self._done = False
        for path in inputs:
            self.add_input(path)

    # -- registration --------------------------------------------------------------------------------
    def add_input(self, path: Path | str) -> None:
        """Protect ``path`` (and, if it is a symlink, what it points to) from every output; for a
        storage file of a ROS 2 bag, the whole bag folder (:func:`enclosing_bag_folder`)."""
        path = Path(path)
        try:
            resolved = path.resolve()
        except (OSError, RuntimeError):  # a symlink loop: reading the input says so, in one line
            resolved = path.absolute()
        self._inputs.append((path, resolved))
        bag = enclosing_bag_folder(path)
        if bag is not None:
            self._inputs.append((bag, bag.resolve()))

    @property
    def outputs(self) -> tuple[StagedOutput, ...]:
        """The staged outputs, in staging order."""
        return tuple(self._outputs)

    @property
    def uses_stdout(self) -> bool:
        """Whether an output goes to standard output (then the caller should print elsewhere)."""
        return any(o.to_stdout for o in self._outputs)

    def check(
        self,
        *paths: Path | str | None,
        directory: bool = False,
        replaceable: Callable[[Path], bool] | None = None,
    ) -> None:
        """Raise :class:`OutputError` now if :meth:`stage` would refuse any of ``paths`` (None skipped).

        Also refuses a path named twice. Nothing is created: a command calls this before it spends
        time computing its outputs.
        """
        seen: list[tuple[Path, Path]] = []
        for given in paths:
            if given is None:
                continue
            path = Path(given)
            target = self._target(path)
            for other, other_target in seen:
                if str(path) == str(other) == STDOUT or (
                    STDOUT not in (str(path), str(other)) and _conflict(target, other_target)
                ):
                    raise OutputError(_twice(path, other))
            seen.append((path, target))
            if _is_stdout(path) or (target.exists() and not _is_regular_or_dir(target)):
                if directory:
                    msg = f"{path}: a folder output cannot go to a stream or device"
                    raise OutputError(msg)
                refuse_closed_stdout(path)
                continue
            self._check_existing(path, target, directory=directory, replaceable=replaceable)
            if not target.parent.is_dir():
                raise OutputError(_no_folder(path, target.parent))
            if not os.access(target.parent, os.W_OK | os.X_OK, effective_ids=_EFFECTIVE_IDS):
                # Said now: staging found it only once the work was done (`rose clean` of a big map).
                # A read-only mount too. Asked as writing asks, with the effective ids: by the
                # real ones, access() refused a folder a process may write in (a non-root user
                # with CAP_DAC_OVERRIDE, a set-user-ID program).
                msg = f"{path}: folder {target.parent} is not writable"
                raise OutputError(msg)

    def stage(
        self,
        path: Path | str,
        *,
        directory: bool = False,
        replaceable: Callable[[Path], bool] | None = None,
    ) -> StagedOutput:
        """Check ``path`` and prepare its temporary; write the output to the returned ``temp``.

        Parameters
        ----------
        path : Path
            The output name; ``-`` is standard output.
        directory : bool, default False
            The output is a folder (a ROS 2 bag): ``temp`` does not exist yet, the writer creates it.
        replaceable : callable, optional
            For a folder output: whether an existing folder is one this command writes and ``--force``
            may replace (default: a ROS 2 bag folder). Other folders are never replaced.

        Raises
        ------
        OutputError
            If the output touches an input or another output, exists without ``force``, would replace
            a directory that is not a ROS 2 bag, is a stream for a folder output, or its folder is
            missing or not writable.
        """
        path = Path(path)
        target = self._target(path)
        stream = _is_stdout(path) or (
            target.exists() and not directory and not _is_regular_or_dir(target)
        )
        if stream:
            if directory:
                msg = f"{path}: a folder output cannot go to a stream or device"
                raise OutputError(msg)
            refuse_closed_stdout(path)
            staged = StagedOutput(
                path, target, None, None, directory, True, bytearray(), _is_stdout(path)
            )
            self._outputs.append(staged)
            return staged
        self._check_existing(path, target, directory=directory, replaceable=replaceable)
        if directory and _is_empty_folder(target):
            self._empty_when_staged.add(target)
        if directory:
            self._replaceable[target] = replaceable
        parent = target.parent
        if not parent.is_dir():
            raise OutputError(_no_folder(path, parent))
        if self.clean_stale:
            remove_stale_temporaries(parent)
        stage_dir = parent / temporary_name(target.name)
        staged = StagedOutput(path, target, stage_dir / target.name, stage_dir, directory, False)
        # Registered before the folder exists: a signal right after mkdir must find it to remove it.
        self._outputs.append(staged)
        try:
            stage_dir.mkdir()
        except OSError as err:
            self._outputs.remove(staged)
            msg = f"{path}: cannot write in {parent} ({err.strerror or err})"
            raise OutputError(msg) from err
        return staged

    def _target(self, path: Path) -> Path:
        if str(path) == STDOUT:
            return path
        try:
            target = path.resolve()
        except (OSError, RuntimeError) as err:  # symlink loops, over-long names
            msg = f"{path}: not a usable output path ({err})"
            raise OutputError(msg) from err
        if len(os.fsencode(target.name)) > _MAX_OUTPUT_NAME_BYTES:
            # Its temporary's name adds the process tag, pid and a random part (see temporary_name).
            msg = (
                f"{str(path)[:80]}...: output file name longer than {_MAX_OUTPUT_NAME_BYTES} bytes"
            )
            raise OutputError(msg)
        for given, resolved in self._inputs:
            if _conflict(target, resolved):
                if resolved in target.parents:
                    what = "inside the input"
                elif target in resolved.parents:
                    what = "a folder that holds the input"
                else:
                    what = "over the input"
                msg = f"{path}: refusing to write {what} {given}"
                raise OutputError(msg)
        for other in self._outputs:
            if other.stream and str(path) != STDOUT:
                continue
            if (str(path) == STDOUT and str(other.path) == STDOUT) or (
                str(path) != STDOUT and not other.stream and _conflict(target, other.target)
            ):
                raise OutputError(_twice(path, other.path))
        return target

    def _check_existing(
        self,
        path: Path,
        target: Path,
        *,
        directory: bool,
        replaceable: Callable[[Path], bool] | None = None,
    ) -> None:
        if not os.path.lexists(target):
            return
        # What --force would not replace either is said first (no advice to use it in vain).
        is_dir = target.is_dir()
        if directory and is_dir and _holds_working_folder(target):
            # A folder output replaces the folder by a rename: the shell's (and this process's)
            # current folder would be a deleted one, the output beside it under the same name.
            msg = f"{path}: is the current folder or holds it, not replacing it (cd out of it)"
            raise OutputError(msg)
        if directory and is_dir and os.path.ismount(target):
            # Replaced by a rename, which a mount point refuses (EBUSY) once the work is done.
            msg = f"{path}: is a mount point, not replacing it (give a new folder inside it)"
            raise OutputError(msg)
        if directory and is_dir and _is_empty_folder(target):
            # Nothing to overwrite (`mkdir out && rose-bag evaluate out`): no --force needed. But
            # filled by a rename, a folder this user may not write in would be written all the same.
            if not os.access(target, os.W_OK | os.X_OK):
                msg = f"{path}: folder not writable (permission denied)"
                raise OutputError(msg)
            return
        if is_dir and not directory:
            msg = f"{path}: is a directory, not replacing it with a file"
            raise OutputError(msg)
        extras = _bag_folder_extras(target) if is_dir and replaceable is None else []
        if extras is None:
            msg = f"{path}: is a directory that is not a ROS 2 bag, not replacing it"
            raise OutputError(msg)
        if extras:
            msg = (
                f"{path}: is a ROS 2 bag folder that holds other files too "
                f"({short(', '.join(extras), 120)}), not replacing it"
            )
            raise OutputError(msg)
        if is_dir and replaceable is not None and not replaceable(target):
            msg = f"{path}: is a directory this command did not write, not replacing it"
            raise OutputError(msg)
        if directory and not is_dir:
            msg = f"{path}: is a file, not replacing it with a folder"
            raise OutputError(msg)
        if not self.force:
            # A command's outputs (``ends_run``) are the command line's; others a Python caller's.
            how = "--force" if self.ends_run else "force=True"
            msg = f"{path}: exists already ({how} replaces it)"
            raise OutputError(msg)

    # -- writing -----------------------------------------------------------------------------------------
    def write_bytes(self, path: Path | str, data: bytes) -> StagedOutput:
        """Stage ``path`` and write ``data`` to its temporary (or keep it for the stream)."""
        staged = self.stage(path)
        self.fill(staged, data)
        return staged

    def write_json(self, path: Path | str, payload: Any) -> StagedOutput:
        """Stage ``path`` with ``payload`` as strict JSON (:func:`json_text`)."""
        return self.write_bytes(path, json_text(payload).encode("utf-8"))

    def fill(self, staged: StagedOutput, data: bytes) -> None:
        """Write ``data`` as the whole content of an already staged file output.

        Raises
        ------
        OutputError
            If the temporary cannot be written (full disk, I/O error).
        """
        if staged.data is not None:
            staged.data[:] = data
            return
        if staged.temp is None:
            msg = f"{staged.path}: not staged"
            raise OutputError(msg)
        try:
            with staged.temp.open("wb") as file:
                file.write(data)
        except OSError as err:
            msg = f"{staged.path}: cannot write ({err.strerror or err})"
            raise OutputError(msg) from err

    # -- commit / abort ------------------------------------------------------------------------------------
    def commit(self) -> None:
        """Move every staged output into place, all or none (see the module docstring).

        Streams (stdout, a device, a FIFO) are written first: they cannot be taken back, so a
        stream that fails (a full device, a closed pipe) leaves no file placed. Files that then
        cannot be placed leave the streams written.

        Raises
        ------
        OutputError
            If a staged output is missing, a stream cannot be written or a target cannot be
            replaced; no file is changed then (a stream written before a file failed to be placed
            stays written).
        """
        if self._done:
            return
        files = [o for o in self._outputs if not o.stream]
        for staged in files:
            if staged.temp is None or not os.path.lexists(staged.temp):
                self.abort()
                msg = f"{staged.path}: the output was not written"
                raise OutputError(msg)
        try:
            self._write_streams()
        except StdoutError as err:
            self.abort()
            if not files:
                raise
            # Said: a failing summary after the files reads the same, and those stand (see
            # committed_outputs).
            names = outputs_named([staged.path for staged in files])
            raise StdoutError(
                err.reason, after=f"; the outputs were not written ({names})"
            ) from err
        except BaseException:
            self.abort()
            raise
        # Signals held: one landing between a rename and its bookkeeping would leave a half-placed
        # set, a target moved aside for good, or staging folders. One that came while the outputs
        # were placed undoes them (as a failure does) and is raised then. Once all are placed, the
        # outputs stand: a later signal is raised after the clean-up, or, when this set ends the
        # run (``ends_run``), dropped, so a run that leaves outputs does not exit as interrupted,
        # and an interrupted one never leaves outputs.
        with signals_deferred() as held:
            backups: list[tuple[StagedOutput, Path]] = []
            placed: list[StagedOutput] = []
            # The output an error names (the rename's own file names are the hidden temporary's).
            placing: StagedOutput | None = None
            try:
                for staged in files:
                    placing = staged
                    if staged.directory and _is_empty_folder(staged.target):
                        # Replaced by the rename itself, which fails (ENOTEMPTY) if a file was put
                        # in it meanwhile: never moved aside and deleted with what it then holds.
                        # The folder made for the output (a group's shared one) keeps its mode.
                        status = staged.target.stat()
                        if staged.temp is not None:
                            _take_status(staged.temp, status)
                        try:
                            self._place(staged)
                        except OSError as err:
                            if err.errno not in (errno.ENOTEMPTY, errno.EEXIST):
                                raise
                            msg = f"{staged.path}: appeared while writing, not replacing it"
                            raise OutputError(msg) from err
                        placed.append(staged)
                        self._emptied.append((staged, status))
                        continue
                    if os.path.lexists(staged.target):
                        if staged.target in self._empty_when_staged:
                            # Its files are someone's, put there while the run wrote: --force
                            # replaces what was checked as replaceable, and an empty folder was.
                            msg = f"{staged.path}: got files while writing, not replacing it"
                            raise OutputError(msg)
                        if not self.force:
                            msg = f"{staged.path}: appeared while writing, not replacing it"
                            raise OutputError(msg)
                        if staged.directory:
                            # Checked when staged; files put in it since (a note, another log)
                            # would go with it: the same checks again, on what it holds now.
                            self._check_existing(
                                staged.path,
                                staged.target,
                                directory=True,
                                replaceable=self._replaceable.get(staged.target),
                            )
                        backup = staged.target.with_name(temporary_name(staged.target.name, "old"))
                        staged.target.rename(backup)
                        backups.append((staged, backup))
                    self._place(staged)
                    placed.append(staged)
            except BaseException as err:
                self._undo(placed, backups)
                if isinstance(err, OSError):
                    target = placing.path if placing is not None else err.filename or "output"
                    msg = f"{target}: cannot commit the outputs ({err.strerror or err})"
                    raise OutputError(msg) from err
                raise
            if held:  # interrupted while placing: undo; signals_deferred raises it on exit
                self._undo(placed, backups)
                return
            if self.ends_run:  # a late signal must not call a finished run "interrupted"
                held.drop()
            for _staged, backup in backups:
                _remove_tree(backup)
            for staged in files:
                if staged.stage is not None:
                    _remove_tree(staged.stage)
            self._done = True
            committed = _COMMITTED.get()
            if committed is not None:
                committed.extend(o.path for o in self._outputs if not o.to_stdout)

    def _undo(self, placed: list[StagedOutput], backups: list[tuple[StagedOutput, Path]]) -> None:
        for staged in placed:
            _remove_tree(staged.target)
            for emptied, status in self._emptied:
                if emptied is staged:  # the empty folder it replaced comes back, as it was
                    with contextlib.suppress(OSError):
                        staged.target.mkdir()
                        _take_status(staged.target, status)
        for staged, backup in backups:
            with contextlib.suppress(OSError):
                backup.rename(staged.target)
        self.abort()

    def _place(self, staged: StagedOutput) -> None:
        if staged.temp is None:
            return
        if staged.directory or self.force:
            staged.temp.rename(staged.target)
            return
        try:
            os.link(staged.temp, staged.target)  # never replaces: one winner among concurrent runs
        except FileExistsError as err:
            msg = f"{staged.path}: appeared while writing, not replacing it"
            raise OutputError(msg) from err
        except OSError:  # file systems without hard links
            if os.path.lexists(staged.target):
                raise
            staged.temp.rename(staged.target)

    def _write_streams(self) -> None:
        for staged in self._outputs:
            if not staged.stream or staged.data is None:
                continue
            try:
                if staged.to_stdout:
                    _write_stdout(staged.data)
                else:
                    with staged.target.open("ab") as stream:  # a device or FIFO: never truncated
                        _write_all(stream, staged.data)
            except BrokenPipeError:
                if staged.to_stdout:  # the reader went away (`| head`): the CLI exits quietly
                    raise
                msg = f"{staged.path}: cannot write (the reader closed the pipe)"
                raise OutputError(msg) from None
            except OSError as err:
                if staged.to_stdout:  # named as the command's own lines name it
                    raise StdoutError(err.strerror or str(err)) from err
                msg = f"{staged.path}: cannot write ({err.strerror or err})"
                raise OutputError(msg) from err

    def abort(self) -> None:
        """Remove every staging folder; the targets stay as they were. Idempotent."""
        for staged in self._outputs:
            if staged.stage is not None:
                _remove_tree(staged.stage)
        self._done = True

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.commit()
        else:
            self.abort()


def _take_status(path: Path, status: os.stat_result) -> None:
    """Gives the folder ``path`` the permission bits (setgid too) and, where allowed, the owner
    and group of ``status`` (an empty folder an output replaces): not its ACLs or attributes."""
    # Another user's folder: its group only; a group this user is not in: as made. Before the
    # mode: a change of owner or group clears the setgid bit.
    for owner in (status.st_uid, -1):
        try:
            os.chown(path, owner, status.st_gid)
            break
        except OSError:
            continue
    path.chmod(stat.S_IMODE(status.st_mode))


def _holds_working_folder(path: Path) -> bool:
    """Whether ``path`` (resolved) is this process's current folder or a folder that holds it."""
    try:
        cwd = Path.cwd().resolve()
    except OSError:  # the current folder was deleted: nothing to protect
        return False
    return path == cwd or path in cwd.parents


def _is_empty_folder(path: Path) -> bool:
    """Whether ``path`` is a directory (not a symlink to one) with no entry at all."""
    if not path.is_dir() or path.is_symlink():
        return False
    try:
        with os.scandir(path) as entries:
            return next(entries, None) is None
    except OSError:
        return False


def _is_regular_or_dir(path: Path) -> bool:
    try:
        mode = path.stat().st_mode
    except OSError:
        return True
    return stat.S_ISREG(mode) or stat.S_ISDIR(mode)
