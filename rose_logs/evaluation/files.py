"""Every file of the evaluation report is written here, so that every write is checked and named.

``cv2.imwrite`` reports a failure (a full disk, a read-only folder) only by returning False, after
libpng has printed ``libpng error: Write Error``; an unchecked call left a report that links a
missing image. A full disk under ``open(...).write`` raises an ``OSError`` without the file's name.
Here every file (PNG, figure, CSV, markdown) is made in memory and written with one call that raises
:class:`ReportWriteError`: ``<file>: cannot write (<reason>)``, one line.
"""

from __future__ import annotations

import contextlib
import io
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from rose.errors import OutputError

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["ReportWriteError", "save_figure", "text_file", "write_bytes", "write_png"]


class ReportWriteError(OutputError):
    """A file of the report cannot be written; the message is ``<path>: cannot write (<reason>)``.

    Attributes
    ----------
    path : Path
        The file that was not written.
    reason : str
        Why, e.g. the operating system's ``No space left on device``.
    """

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(f"{path}: cannot write ({reason})")
        self.path = Path(path)
        self.reason = reason

    def relocated(self, written_in: Path, shown_as: Path) -> ReportWriteError:
        """The same error naming ``shown_as / <name>`` for a file of the folder ``written_in``.

        The report is written in a temporary folder (``rose.outputs.OutputSet``) that is gone once
        the run fails: the user should read the folder they asked for.
        """
        try:
            path = Path(shown_as) / self.path.relative_to(written_in)
        except ValueError:  # not in that folder: keep its name
            path = self.path
        return ReportWriteError(path, self.reason)


def write_bytes(path: Path, data: bytes) -> Path:
    """Write ``data`` to ``path``; returns ``path``.

    Raises
    ------
    ReportWriteError
        If the file cannot be written, with the operating system's reason.
    """
    try:
        Path(path).write_bytes(data)
    except OSError as err:
        raise ReportWriteError(path, err.strerror or str(err)) from err
    return Path(path)


@contextlib.contextmanager
def text_file(path: Path) -> Iterator[io.StringIO]:
    """A text buffer written to ``path`` (UTF-8) when the block ends without an error.

    For ``csv.writer`` and the like: ``with text_file(p) as fh: csv.writer(fh)...``; newlines are
    written as given (CSV's ``\\r\\n`` stays, as with ``open(path, "w", newline="")``).

    Raises
    ------
    ReportWriteError
        If the file cannot be written.
    """
    buffer = io.StringIO(newline="")
    yield buffer
    write_bytes(path, buffer.getvalue().encode("utf-8"))


def write_png(path: Path, image: npt.NDArray[np.uint8]) -> Path:
    """Write an OpenCV image (grey, or BGR channels) as a PNG file; returns ``path``.

    Raises
    ------
    ReportWriteError
        If the image cannot be encoded or the file cannot be written.
    """
    import cv2

    try:
        ok, encoded = cv2.imencode(".png", image)
    except cv2.error as err:  # an empty or oddly typed array: OpenCV raises instead of returning
        raise ReportWriteError(path, f"cannot encode the image: {str(err).strip()[:120]}") from err
    if not ok:
        raise ReportWriteError(path, "cannot encode the image")
    return write_bytes(path, np.asarray(encoded).tobytes())


def save_figure(fig: Figure, path: Path, *, dpi: int, **savefig: Any) -> Path:
    """Write a matplotlib figure as a PNG file and close it; returns ``path``.

    Rendered in memory first: a failed write then raises :class:`ReportWriteError` naming the file,
    where ``savefig`` to a path raised an ``OSError`` without a file name on a full disk.
    """
    import matplotlib.pyplot as plt

    try:
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=dpi, **savefig)
    finally:
        plt.close(fig)
    return write_bytes(path, buffer.getvalue())
