"""Where the real data set lives: maps and CARMEN logs used by the evaluation, benchmarks and tests.

The data set is a folder laid out like ``maps/`` of the project's shared data (one folder per source:
``radish_carmen_corrected_logs/``, ``bormann_ipa_room_segmentation/``, ``rose2_aislabunimi/``, ...).
It is found, in this order:

1. the environment variable ``ROSE_DATA_DIR`` (used as given, even if the folder is missing, so that a
   typo is reported instead of silently falling back);
2. ``../shared/maps`` beside the source checkout this package was imported from (a folder ``shared``
   next to the repository folder), when that folder exists.

Nothing here knows any machine's absolute path. Functions take no hidden state: every call reads the
environment again, so tests can change it.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn

from rose_logs.errors import LogError

__all__ = [
    "ENV_VAR",
    "DataSetError",
    "checkout_data_dir",
    "data_dir",
    "data_path",
    "require_data_dir",
    "run_benchmark",
]

#: Environment variable naming the data-set folder.
ENV_VAR = "ROSE_DATA_DIR"
#: How to get the data set, appended to every "not found" message.
HOW_TO = (
    f"set {ENV_VAR} to the folder of the real maps and logs (see README.md, 'Data'), "
    "or put it at ../shared/maps beside the repository"
)


class DataSetError(LogError):
    """The real data set, or a file inside it, is not available."""


def checkout_data_dir() -> Path | None:
    """``../shared/maps`` beside the source checkout holding this package, if that exists.

    Returns
    -------
    Path or None
        None when the package is not imported from a source checkout (no ``pyproject.toml`` next to
        the package folder, e.g. an installed wheel) or when the folder does not exist.
    """
    repository = Path(__file__).resolve().parents[1]
    if not (repository / "pyproject.toml").is_file():
        return None
    candidate = repository.parent / "shared" / "maps"
    return candidate if candidate.is_dir() else None


def data_dir() -> Path | None:
    """The data-set folder: ``$ROSE_DATA_DIR``, else :func:`checkout_data_dir`, else None.

    Returns
    -------
    Path or None
        ``ROSE_DATA_DIR`` as given (``~`` expanded; not checked for existence), the checkout's
        ``../shared/maps`` when it exists, or None when neither applies.
    """
    value = os.environ.get(ENV_VAR, "").strip()
    if value:
        return Path(value).expanduser()
    return checkout_data_dir()


def require_data_dir() -> Path:
    """:func:`data_dir`, checked to be an existing folder.

    Raises
    ------
    DataSetError
        When no data-set folder is configured or the configured one does not exist.
    """
    root = data_dir()
    if root is None:
        msg = f"the real data set was not found: {HOW_TO}"
        raise DataSetError(msg)
    if not root.is_dir():
        what = "is a file, not a folder" if root.exists() else "does not exist"
        msg = f"{root}: data-set folder ({ENV_VAR}) {what}; {HOW_TO}"
        raise DataSetError(msg)
    return root


def data_path(relative: str | Path) -> Path:
    """A file or folder inside the data set, checked to exist.

    Parameters
    ----------
    relative : str or Path
        Path relative to the data-set folder, e.g.
        ``"rose2_aislabunimi/Freiburg_Building_079_partial/map15.yaml"``.

    Raises
    ------
    DataSetError
        When the data set or the path inside it is missing.
    """
    path = require_data_dir() / relative
    if not path.exists():
        msg = f"{path}: not in the data set; {HOW_TO}"
        raise DataSetError(msg)
    return path


def run_benchmark(main: Callable[[], int | None]) -> NoReturn:
    """Run a benchmark script's ``main`` and exit with its code; a missing data set is one line
    on stderr and exit code 1, not a traceback."""
    try:
        sys.exit(main())
    except DataSetError as err:
        sys.exit(f"error: {err}")
