"""Real data for the tests: the small subset in ``tests/data`` and the full data set (``ROSE_DATA_DIR``).

``tests/data`` mirrors the data set's layout (see ``tests/data/README.md`` for sources and licences),
so a path relative to the data set names the same file in both. Tests that need files only the full
data set has use :func:`dataset` (or the ``dataset`` marker): they skip with a reason saying how to get
it, or fail when ``ROSE_REQUIRE_DATA=1`` (set by ``.ci/run``, where the data set is present).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from rose_logs.datasets import DataSetError, data_path

#: The small real data committed with the tests.
REPO_DATA = Path(__file__).resolve().parent / "data"
#: Set to 1 to turn "data set missing" skips into failures (CI).
REQUIRE_ENV = "ROSE_REQUIRE_DATA"
FR079_DIR = "rose2_aislabunimi/Freiburg_Building_079_partial"
BORMANN_DIR = "bormann_ipa_room_segmentation"
CARMEN_DIR = "radish_carmen_corrected_logs"


def data_required() -> bool:
    """True when missing data must fail the run instead of skipping (``ROSE_REQUIRE_DATA=1``)."""
    return os.environ.get(REQUIRE_ENV, "").strip() not in ("", "0")


def repo_data(relative: str) -> Path:
    """A file of ``tests/data`` (always present in a checkout)."""
    path = REPO_DATA / relative
    if not path.exists():
        msg = f"{path}: missing from the repository's test data"
        raise FileNotFoundError(msg)
    return path


def dataset(relative: str) -> Path:
    """A path inside the full data set; skips the test (fails under ``ROSE_REQUIRE_DATA=1``) if absent."""
    try:
        return data_path(relative)
    except DataSetError as err:
        if data_required():
            pytest.fail(f"{err} [{REQUIRE_ENV}=1: data-set tests must run]", pytrace=False)
        pytest.skip(f"needs the full data set: {err}")
