"""The batch's output folder (local or any fsspec URL such as ``s3://bucket/prefix``): atomic writes."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import fsspec

from rose.outputs import temporary_name
from rose_logs.batch.errors import BatchError

__all__ = ["OutputStore", "is_local", "join_uri"]


def is_local(uri: str) -> bool:
    """Whether ``uri`` is a local path (no protocol, or ``file://``)."""
    protocol = fsspec.utils.get_protocol(uri)
    return protocol in ("file", "local")


def join_uri(base: str, *parts: str) -> str:
    """``base`` and relative ``parts`` joined with ``/`` (URLs) or the OS separator (paths)."""
    if is_local(base):
        return str(Path(_strip_file(base), *parts))
    return "/".join([base.rstrip("/"), *(p.strip("/") for p in parts)])


def _strip_file(uri: str) -> str:
    return uri.removeprefix("file://")


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
        self.root = (
            str(Path(_strip_file(str(root))).expanduser().absolute()) if self.local else str(root)
        )
        self.storage_options = dict(storage_options or {})
        if self.local:
            self.fs: Any = None
        else:
            self.fs, _ = fsspec.core.url_to_fs(self.root, **self.storage_options)

    def uri(self, relative: str) -> str:
        """Full path or URL of ``relative`` (``/``-separated) under the root."""
        return join_uri(self.root, *relative.split("/"))

    def prepare(self) -> None:
        """Create the root folder (local) or check the bucket is reachable (remote)."""
        try:
            if self.local:
                Path(_strip_file(self.root)).mkdir(parents=True, exist_ok=True)
            else:
                self.fs.makedirs(self.root, exist_ok=True)
        except OSError as err:
            msg = f"{self.root}: cannot create the output folder ({err})"
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
        """Write ``data`` to ``relative`` atomically; returns its full path or URL."""
        target = self.uri(relative)
        if not self.local:
            self.fs.pipe_file(target, data)  # one PUT: readers see the old or the new object
            return target
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
        return target

    def put(self, local: Path, relative: str) -> str:
        """Move (local root) or upload (remote root) the file or folder ``local`` to ``relative``."""
        target = self.uri(relative)
        if self.local:
            path = Path(target)
            path.parent.mkdir(parents=True, exist_ok=True)
            if path.is_dir():
                import shutil

                shutil.rmtree(path)
            Path(local).replace(path)  # same file system: the temporary lives beside the output
            return target
        self.fs.put(str(local), target, recursive=local.is_dir())
        return target

    def remove_staging(self) -> None:
        """Remove the (empty) staging folder left by :meth:`staging_dir`."""
        if self.local:
            with contextlib.suppress(OSError):
                (Path(_strip_file(self.root)) / ".staging").rmdir()

    def staging_dir(self) -> Path | None:
        """Folder for temporary outputs, on the same file system as the root (local), else None."""
        if not self.local:
            return None
        path = Path(_strip_file(self.root)) / ".staging"
        path.mkdir(parents=True, exist_ok=True)
        return path
