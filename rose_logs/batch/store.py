"""The batch's output folder (local or any fsspec URL such as ``s3://bucket/prefix``): atomic writes.

Also :func:`filesystem`, the one way the batch opens an fsspec URL: an unknown scheme or a missing
backend package is a one-line :class:`BatchError`, not fsspec's ``ValueError`` / ``ImportError``.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import shutil
from collections.abc import Collection, Iterator, Mapping
from pathlib import Path
from typing import Any

import fsspec

from rose.errors import OutputError
from rose.outputs import OutputSet, left_behind, process_tag, temporary_name
from rose_logs.batch.errors import BatchError

__all__ = ["OutputStore", "expand_user", "filesystem", "is_local", "join_uri", "storage_errors"]

_LOG = logging.getLogger(__name__)


def is_local(uri: str) -> bool:
    """Whether ``uri`` is a local path (no protocol, or ``file://``).

    fsspec reads ``a::b`` as a chain of file systems (``simplecache::s3://...``), so a local name
    holding ``::`` (``runs/a::b.mcap``) would look like protocol ``runs/a``: a "protocol" that is
    no URL scheme, or a path that exists here, is local.
    """
    protocol = fsspec.utils.get_protocol(uri)
    if protocol in ("file", "local"):
        return True
    return "://" not in uri and (_SCHEME.fullmatch(protocol) is None or Path(uri).exists())


#: What a URL scheme may be made of (RFC 3986).
_SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*")


def expand_user(path: str) -> Path:
    """``path`` with a leading ``~`` or ``~user`` expanded, as a shell expands it; one naming no
    user (a folder named ``~old`` here, a list's line) stays as written, as in a shell
    (``Path.expanduser`` raised RuntimeError: a traceback)."""
    try:
        return Path(path).expanduser()
    except RuntimeError:
        return Path(path)


def join_uri(base: str, *parts: str) -> str:
    """``base`` and relative ``parts`` joined with ``/`` (URLs) or the OS separator (paths)."""
    if is_local(base):
        return str(Path(_strip_file(base), *parts))
    return "/".join([base.rstrip("/"), *(p.strip("/") for p in parts)])


def _strip_file(uri: str) -> str:
    return uri.removeprefix("file://")


def _protocols(uri: str) -> list[str]:
    """The fsspec protocols of ``uri``, outermost first (``simplecache::s3://b/k``: both)."""
    parts = uri.split("::")
    found = []
    for i, part in enumerate(parts):
        if "://" in part:
            found.append(part.split("://", 1)[0])
        elif i < len(parts) - 1:  # a bare protocol name in a chain; the last part is a path
            found.append(part)
    return [p for p in found if p not in ("file", "local")]


def _missing_package(err: ImportError) -> str:
    """What to install for a protocol whose backend fsspec could not import."""
    # fsspec raises its own ImportError ("Please install gcsfs to access Google Storage") from the
    # ModuleNotFoundError, which names the module: the pip name of its backends (gcsfs, adlfs...).
    name = getattr(err.__cause__, "name", None) or err.name
    if name and "." not in name:
        return f"needs the {name} package (pip install {name})"
    return f"needs a package that is not installed ({err})"


def filesystem(uri: str, storage_options: Mapping[str, Any] | None = None) -> tuple[Any, str]:
    """fsspec file system and path of ``uri`` (``storage_options`` passed on).

    Raises
    ------
    BatchError
        If a URL scheme is unknown to fsspec or its backend package is not installed.
    """
    if is_local(uri):
        return fsspec.filesystem("file"), _strip_file(uri)
    for protocol in _protocols(uri):
        try:
            fsspec.get_filesystem_class(protocol)
        except ValueError as err:  # "Protocol not known: foo"
            msg = f"{uri}: unsupported URL scheme {protocol!r}"
            raise BatchError(msg) from err
        except ImportError as err:
            msg = f"{uri}: {_missing_package(err)}"
            raise BatchError(msg) from err
    try:
        return fsspec.core.url_to_fs(uri, **dict(storage_options or {}))
    except (ValueError, ImportError) as err:  # e.g. a chain fsspec cannot build
        msg = f"{uri}: cannot open ({err})"
        raise BatchError(msg) from err
    except TypeError as err:  # an option the file system does not take, or of the wrong type
        msg = f"{uri}: cannot open with the storage options given ({err})"
        raise BatchError(msg) from err


#: Packages whose exceptions mean "the storage cannot be reached or refuses us" (no endpoint, no
#: credentials, a bad bucket name): fsspec's object-store backends raise their clients' own types,
#: not ``OSError``, for these.
_STORAGE_CLIENTS = (
    "botocore",
    "aiobotocore",
    "aiohttp",
    "s3fs",
    "gcsfs",
    "google",
    "adlfs",
    "azure",
)


@contextlib.contextmanager
def storage_errors(uri: str) -> Iterator[None]:
    """Turn a storage client's own exception inside the block into a one-line :class:`BatchError`
    naming ``uri`` (``OSError`` s and everything else pass unchanged)."""
    try:
        yield
    except BatchError:
        raise
    except Exception as err:
        if not _from_storage_client(err):
            raise
        text = " ".join(str(err).split()) or "no details"
        msg = f"{uri}: cannot use the storage ({type(err).__name__}: {text})"
        raise BatchError(msg) from err


def _from_storage_client(err: BaseException) -> bool:
    """Whether ``err`` is a storage client's: of its own type, or a ``TypeError`` raised inside
    one (an option it does not take, or of another type, from ``--storage-option``)."""
    if type(err).__module__.split(".")[0] in _STORAGE_CLIENTS:
        return True
    if not isinstance(err, TypeError):
        return False
    tb = err.__traceback__
    while tb is not None and tb.tb_next is not None:
        tb = tb.tb_next
    module = "" if tb is None else str(tb.tb_frame.f_globals.get("__name__", ""))
    # fsspec's own implementations pass the options on too (http: aiohttp.ClientSession(**kw)).
    return module.split(".")[0] in _STORAGE_CLIENTS or module.startswith("fsspec.implementations.")


def work_folder_prefix() -> str:
    """Prefix of a recording's work folder in the staging folder: this host and process, so that
    a later run can tell the folders of dead processes (:meth:`OutputStore.remove_dead_work`)."""
    return f"rose-batch-{process_tag()}-{os.getpid()}-"


#: Seconds without a change after which the work folder of a dead process of this host is
#: removed where the process tag is the host's name alone (no PID namespace: a process of another
#: container may have that pid); see :func:`_dead_work_idle_s`.
_DEAD_WORK_IDLE_S = 60.0


def _dead_work_idle_s() -> float:
    """Seconds a dead process's work folder must stay unchanged before it goes: none where
    :func:`rose.outputs.process_tag` names the PID namespace (Linux), whose dead pid is dead for
    good, so that an interrupted batch removes its workers' folders as it ends (they stayed, with
    their partial logs, until a run a minute later); :data:`_DEAD_WORK_IDLE_S` elsewhere."""
    return 0.0 if "_pidns" in process_tag() else _DEAD_WORK_IDLE_S


_WORK_RE = re.compile(r"^rose-batch-(?P<host>[A-Za-z0-9._]+)-(?P<pid>\d+)-[A-Za-z0-9_]+$")


class OutputStore:
    """Files under one output root; every write is atomic (temporary name + rename, or one PUT).

    Parameters
    ----------
    root : str
        A folder path or an fsspec URL (``s3://bucket/prefix``).
    storage_options : mapping, optional
        Passed to the fsspec filesystem (e.g. ``endpoint_url``, ``key``, ``secret``).
    """

    def __init__(self, root: str, storage_options: Mapping[str, Any] | None = None) -> None:
        self.local = is_local(str(root))
        # Absolute, so that workers with another working directory write to the same place.
        self.root = str(expand_user(_strip_file(str(root))).absolute()) if self.local else str(root)
        self.storage_options = dict(storage_options or {})
        if self.local:
            self.fs: Any = None
        else:
            self.fs, _ = filesystem(self.root, self.storage_options)

    def uri(self, relative: str) -> str:
        """Full path or URL of ``relative`` (``/``-separated) under the root."""
        return join_uri(self.root, *relative.split("/"))

    def prepare(self, folders: tuple[str, ...] = ()) -> None:
        """Create the root folder, its staging folder and ``folders`` below it (local: an existing
        folder we cannot write to, or a file where one of them goes, is refused here, not per
        recording), or check that the bucket exists (object stores: a mistyped bucket name must
        not create a new bucket) and create the root (other remotes)."""
        try:
            if self.local:
                root = Path(_strip_file(self.root))
                for folder in (root, *(root / f for f in folders)):
                    # (A dangling link is no folder either: writing into it failed later.)
                    if os.path.lexists(folder) and not folder.is_dir():
                        why = (
                            "the output of a batch is a folder"
                            if folder == root
                            else "the batch keeps each recording's result in this folder"
                        )
                        msg = f"{folder}: not a folder ({why})"
                        raise BatchError(msg)
                root.mkdir(parents=True, exist_ok=True)
                # A real write in the root (results/ and the tables go there): a staging folder
                # left by a killed run proves nothing.
                probe = root / temporary_name("write-probe")
                probe.touch()
                probe.unlink()
                self.staging_dir()
                self.remove_dead_work()
            else:
                with storage_errors(self.root):
                    self._prepare_remote()
        except OSError as err:
            reason = err.strerror or str(err)
            msg = f"{self.root}: cannot write to the output folder ({reason})"
            raise BatchError(msg) from err

    def _prepare_remote(self) -> None:
        split_path = getattr(self.fs, "split_path", None)  # object stores: bucket, key, version
        if split_path is None:
            self.fs.makedirs(self.root, exist_ok=True)
            return
        bucket = split_path(self.root)[0]
        try:
            # A listing, not exists(): s3fs's exists() reads "access denied" as "no such bucket".
            self.fs.ls(bucket, refresh=True)
        except FileNotFoundError as err:
            msg = f"{self.root}: the bucket {bucket!r} does not exist (it is not created for you)"
            raise BatchError(msg) from err
        except PermissionError as err:
            msg = f"{self.root}: access to the bucket {bucket!r} denied ({err})"
            raise BatchError(msg) from err

    def read_bytes(self, relative: str) -> bytes | None:
        """Content of ``relative``, None if it does not exist."""
        target = self.uri(relative)
        try:
            if self.local:
                return Path(target).read_bytes()
            return self.fs.cat_file(target)
        except FileNotFoundError:
            return None

    def write_bytes(self, relative: str, data: bytes) -> str:
        """Write ``data`` to ``relative`` atomically; returns its full path or URL.

        Raises
        ------
        OSError
            If it cannot be written; the message names the file (``cannot write (No space left on
            device)``), and the type stays that of the errno (callers retry or report ``OSError`` s).
        """
        target = self.uri(relative)
        try:
            self._write(target, data)
        except OSError as err:
            # file.write's ENOSPC carries no file name: without one the user reads only
            # "error: No space left on device".
            raise OSError(err.errno, f"cannot write ({err.strerror or err})", target) from err
        return target

    def _write(self, target: str, data: bytes) -> None:
        if not self.local:
            self.fs.pipe_file(target, data)  # one PUT: readers see the old or the new object
            return
        path = Path(target)
        path.parent.mkdir(parents=True, exist_ok=True)
        # Named like every temporary of ours (`rose_logs.batch` never removes others' temporaries
        # itself: workers on other hosts may share this folder, and their PIDs mean nothing here).
        tmp = path.with_name(temporary_name(path.name))
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        try:
            with os.fdopen(fd, "wb") as file:
                file.write(data)
            tmp.replace(path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise

    def write_set(self, files: Mapping[str, bytes]) -> list[str]:
        """Write every file of ``files`` (relative name: content), all or none; returns their URIs.

        Local roots go through :class:`rose.outputs.OutputSet`: each file is staged beside its target
        and all are renamed into place together, so a full disk or a signal leaves the previous files
        as they were. Object stores have no multi-object commit: the files are PUT one by one and,
        if one fails, those already written are restored from copies read beforehand (best effort:
        a store that fails again meanwhile is logged).

        Raises
        ------
        BatchError
            If a file cannot be written (the message names it); nothing is replaced then.
        """
        if self.local:
            self._write_set_local(files)
        else:
            self._write_set_remote(files)
        return [self.uri(relative) for relative in files]

    def _write_set_local(self, files: Mapping[str, bytes]) -> None:
        try:
            # force: a re-run replaces its own earlier tables. Not ends_run: run_batch is a library
            # call, and a Ctrl-C during the commit must reach it (raised once the tables stand).
            # Not clean_stale: hosts sharing OUT write their own temporaries there.
            with OutputSet(force=True, clean_stale=False) as outputs:
                for relative, data in files.items():
                    path = Path(self.uri(relative))
                    path.parent.mkdir(parents=True, exist_ok=True)
                    outputs.write_bytes(path, data)
        except OutputError as err:  # names the file: "<path>: cannot write (No space left ...)"
            raise BatchError(str(err)) from err
        except OSError as err:
            msg = f"{err.filename or self.root}: cannot write ({err.strerror or err})"
            raise BatchError(msg) from err

    def _write_set_remote(self, files: Mapping[str, bytes]) -> None:
        target, action = self.root, "read"
        written: list[str] = []
        previous: dict[str, bytes | None] = {}
        try:
            # Read first: restoring needs the old objects, and a store we cannot read fails here,
            # before anything is replaced.
            for relative in files:
                target = self.uri(relative)
                previous[relative] = self.read_bytes(relative)
            action = "write"
            for relative, data in files.items():
                target = self.uri(relative)
                self.fs.pipe_file(target, data)
                written.append(relative)
        except BaseException as err:
            self._restore(written, previous)
            if isinstance(err, OSError):
                msg = f"{target}: cannot {action} ({err.strerror or err})"
                raise BatchError(msg) from err
            raise

    def _restore(self, written: list[str], previous: Mapping[str, bytes | None]) -> None:
        """Put back what ``written`` replaced (remote roots; errors are logged, not raised)."""
        for relative in written:
            old = previous.get(relative)
            try:
                if old is None:
                    self.fs.rm_file(self.uri(relative))
                else:
                    self.fs.pipe_file(self.uri(relative), old)
            except OSError as err:
                _LOG.warning("%s: cannot restore the previous file (%s)", self.uri(relative), err)

    def iter_folder(
        self, relative: str, suffix: str, *, skip: Collection[str] = ()
    ) -> Iterator[bytes]:
        """Content of every file of the folder ``relative`` whose name ends with ``suffix`` and is
        not in ``skip`` (file names), in name order, one file at a time (a remote folder listed
        afresh: a worker process may have written files since this process last listed it; none
        when the folder does not exist)."""
        folder = self.uri(relative)
        if self.local:
            path = Path(_strip_file(folder))
            if not path.is_dir():
                return
            for entry in sorted(path.iterdir()):
                if entry.name.endswith(suffix) and entry.name not in skip and entry.is_file():
                    yield entry.read_bytes()
            return
        self.fs.invalidate_cache(folder)
        try:
            names = sorted(str(p) for p in self.fs.ls(folder, detail=False))
        except FileNotFoundError:
            return
        for name in names:
            if name.endswith(suffix) and name.rsplit("/", 1)[-1] not in skip:
                with contextlib.suppress(FileNotFoundError):
                    yield self.fs.cat_file(name)

    def has(self, uri: str) -> bool:
        """Whether the file or folder ``uri`` (a full path or URL under the root) exists."""
        if self.local:
            return Path(_strip_file(uri)).exists()
        return bool(self.fs.exists(uri))

    def size(self, uri: str) -> int | None:
        """Bytes of the file ``uri``, or of every file of the folder ``uri``; None if it is gone."""
        try:
            if self.local:
                path = Path(_strip_file(uri))
                if path.is_dir():
                    return sum(f.stat().st_size for f in sorted(path.rglob("*")) if f.is_file())
                return path.stat().st_size if path.exists() else None
            if not self.fs.exists(uri):
                return None
            return int(self.fs.du(uri, total=True))
        except OSError:
            return None

    def put(self, local: Path, relative: str) -> str:
        """Move (local root) or upload (remote root) the file or folder ``local`` to ``relative``."""
        target = self.uri(relative)
        if self.local:
            path = Path(target)
            path.parent.mkdir(parents=True, exist_ok=True)
            if path.is_dir():
                shutil.rmtree(path)
            Path(local).replace(path)  # same file system: the temporary lives beside the output
            return target
        self.fs.put(str(local), target, recursive=local.is_dir())
        return target

    def remove(self, relative: str) -> None:
        """Delete the file ``relative`` if it exists; one that cannot be deleted gets a warning
        (the outputs beside it are written by then)."""
        target = self.uri(relative)
        try:
            if self.local:
                Path(target).unlink(missing_ok=True)
            elif self.fs.exists(target):
                self.fs.rm_file(target)
        except OSError as err:
            _LOG.warning("%s: cannot remove (%s)", target, err.strerror or err)

    def remove_staging(self) -> None:
        """Remove the staging folder left by :meth:`staging_dir` when nothing is left in it but
        the work folders of dead processes (:meth:`remove_dead_work`)."""
        if self.local:
            self.remove_dead_work()
            with contextlib.suppress(OSError):
                (Path(_strip_file(self.root)) / ".staging").rmdir()

    def remove_dead_work(self) -> None:
        """Remove the work folders (:func:`work_folder_prefix`) in the staging folder that no
        process works in: a worker killed by a signal left its folder behind, and no later run
        removed it. A folder goes when its process, of this host, is gone (where the process tag
        names no PID namespace, also unchanged for a minute: :func:`_dead_work_idle_s`); or when
        nothing in it changed for a day (a folder of another host, of a process in another PID
        namespace, or of an older rose-bag: a live process's pid cannot be told from there, and a
        live batch's folder was deleted under it)."""
        staging = Path(_strip_file(self.root)) / ".staging"
        try:
            entries = [e for e in os.scandir(staging) if e.name.startswith("rose-batch-")]
        except OSError:
            return
        for entry in entries:
            match = _WORK_RE.match(entry.name)
            path = Path(entry.path)
            tag, pid = (match["host"], int(match["pid"])) if match else (None, None)
            if left_behind(path, tag, pid, dead_idle_s=_dead_work_idle_s()):
                with contextlib.suppress(OSError):
                    shutil.rmtree(path)

    def staging_dir(self) -> Path | None:
        """Folder for temporary outputs, on the same file system as the root (local), else None."""
        if not self.local:
            return None
        path = Path(_strip_file(self.root)) / ".staging"
        path.mkdir(parents=True, exist_ok=True)
        return path
